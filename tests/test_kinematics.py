"""Assembly of initial conditions (Muvengei et al. §III.A): Newton–Raphson onto the constraints."""
from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.mechanism.compile import compile_text
from planar_mbs.errors import ModelError
from planar_mbs.mechanism.kinematics import assemble, assembly_changes

MODELS = Path(__file__).resolve().parents[1] / "models"
OMEGA = 5000 * 2 * np.pi / 60
R, L = 0.05, 0.12

SLIDER_CRANK_ROUGH = """
param speed = 5000 rpm
body crank  { mass = 0.30 kg  inertia = 1e-5 kg*m^2    position = (0.024, 0.002)  angle = 2 deg }
body rod    { mass = 0.21 kg  inertia = 2.5e-4 kg*m^2  position = (0.113, -0.004) angle = -3 deg }
body slider { mass = 0.14 kg  inertia = 1e-4 kg*m^2    position = (0.168, 0.001) }
joint O = revolute(ground (0, 0), crank (-0.025, 0))
joint A = revolute(crank (0.025, 0), rod (-0.06, 0))
joint B = revolute(rod (0.06, 0), slider (0, 0))
joint S = translational(ground, slider, axis = (1, 0))
driver crank_speed = rotation(crank, speed = speed, initial = 0 deg)
"""


def test_rough_pose_is_pulled_onto_the_closed_form():
    model = compile_text(SLIDER_CRANK_ROUGH, "rough.mbs")
    q, qd = assemble(model)
    crank, rod, slider = q[0:3], q[3:6], q[6:9]
    np.testing.assert_allclose(crank, [R / 2, 0, 0], atol=1e-12)
    np.testing.assert_allclose(rod, [R + L / 2, 0, 0], atol=1e-12)
    np.testing.assert_allclose(slider[:2], [R + L, 0], atol=1e-12)
    # velocities at theta = 0 from the closed form: slider at rest, rod turns at -r w / l
    assert qd[2] == pytest.approx(OMEGA, rel=1e-12)
    assert qd[5] == pytest.approx(-R * OMEGA / L, rel=1e-10)
    assert abs(qd[6]) < 1e-10
    np.testing.assert_allclose(qd[3:5], [0, R * OMEGA / 2], atol=1e-10)


def test_clearance_journal_starts_centred():
    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    q, qd = assemble(model)
    k = model.kernel

    def point(b, s, q=q):
        x, y, phi = q[3 * b:3 * b + 3]
        c, si = np.cos(phi), np.sin(phi)
        return np.array([x + c * s[0] - si * s[1], y + si * s[0] + c * s[1]])

    (bi, bj), (si, sj) = k.clearance_body[0], k.clearance_point[0]
    np.testing.assert_allclose(point(bi, si), point(bj, sj), atol=1e-12)


def test_redundant_driver_is_named():
    text = SLIDER_CRANK_ROUGH + "driver again = rotation(crank, speed = speed, initial = 0 deg)\n"
    with pytest.raises(ModelError) as info:
        assemble(compile_text(text, "redundant.mbs"))
    msg = str(info.value)
    assert "redundant" in msg and "again" in msg
    assert "redundant.mbs:11:" in msg  # points at the driver's line


def test_mechanism_that_cannot_close_is_reported():
    text = SLIDER_CRANK_ROUGH.replace("joint S = translational(ground, slider, axis = (1, 0))",
                                      "joint S = revolute(ground (0.5, 0), slider (0, 0))")
    text = text.replace("driver crank_speed", "# no driver\n#")
    with pytest.raises(ModelError) as info:
        assemble(compile_text(text, "open.mbs"))
    assert "cannot be assembled" in str(info.value)


@pytest.mark.parametrize("name", ["slider_crank_clearance_ab.mbs", "four_bar_two_clearances.mbs"])
def test_plain_python_constraints_match_the_compiled_kernel(name):
    """Assembly runs the constraint kernels' source as plain Python (planar_mbs.pykernel, no numba);
    at a perturbed state it must give what the compiled kernel gives."""
    import numpy as np

    from planar_mbs import load_model
    from planar_mbs.kernel import constraint_eval as compiled
    from planar_mbs.mechanism.kinematics import assembly_kernel
    from planar_mbs.pykernel.constraints import constraint_eval as plain

    model = load_model(Path(__file__).resolve().parents[1] / "models" / name)
    km, owners = assembly_kernel(model)
    rng = np.random.default_rng(3)
    q, qd = model.q0 + 0.01 * rng.standard_normal(model.ncoord), rng.standard_normal(model.ncoord)
    out = []
    for fn in (plain, compiled):
        m = len(owners)
        arrays = (np.zeros(m), np.zeros((m, model.ncoord)), np.zeros(m), np.zeros(m))
        assert fn(km, q, qd, 0.01, *arrays) == 0
        out.append(arrays)
    for a, b in zip(*out):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-15)


FREE_JOURNAL = """
body journal {{ mass = 1 kg  inertia = 1e-3 kg*m^2  position = ({x}, {y})  velocity = ({vx}, {vy}) }}
joint J = clearance_revolute(ground (0, 0), journal) {{
    clearance = 0.1 mm  bearing_radius = 5 mm  stiffness = 1e9 N/m^1.5  law = hertz {extra}
}}
simulate {{ t_end = 12 ms  output_step = 0.5 ms  rtol = 1e-9  atol = 1e-13 }}
"""


def _point(q, b, s):
    c, si = np.cos(q[3 * b + 2]), np.sin(q[3 * b + 2])
    return q[3 * b:3 * b + 2] + np.array([c * s[0] - si * s[1], si * s[0] + c * s[1]])


def _point_velocity(q, qd, b, s):
    c, si = np.cos(q[3 * b + 2]), np.sin(q[3 * b + 2])
    arm = np.array([c * s[0] - si * s[1], si * s[0] + c * s[1]])
    return qd[3 * b:3 * b + 2] + qd[3 * b + 2] * np.array([-arm[1], arm[0]])


def test_journal_held_only_by_its_clearance_joint_keeps_its_velocity():
    """A free journal in a bearing on the ground given 10 mm/s keeps it (and its off-centre pose)
    until its first impact at t = c / v = 10 ms; nothing is reported as changed."""
    model = compile_text(FREE_JOURNAL.format(x="0.02 mm", y="0 m", vx="10 mm/s", vy="0 m/s", extra=""), "j.mbs")
    q, qd = assemble(model)
    np.testing.assert_array_equal(q, [2e-5, 0, 0])
    np.testing.assert_array_equal(qd, [0.01, 0, 0])
    assert assembly_changes(model, q, qd) == []
    res = mbs.simulate(model)
    t = res.time
    before = t < (1e-4 - 2e-5) / 0.01
    np.testing.assert_allclose(res["journal.x"][before], 2e-5 + 0.01 * t[before], rtol=0, atol=1e-15)
    np.testing.assert_allclose(res["journal.vx"][before], 0.01, rtol=1e-12)
    assert res.attrs["n_contact_events"] >= 1 and res["journal.vx"][-1] < 0  # it bounced


def test_offset_and_relative_velocity_of_a_loop_closing_joint_are_kept():
    """In the clearance slider-crank (joint A closes the loop) the stated journal offset and
    relative velocity (bearing frame: the crank's) are what the assembly produces; without
    them the journal starts centred and at rest relative to the bearing."""
    text = (MODELS / "slider_crank_clearance_a.mbs").read_text()
    text = text.replace("restitution = restitution\n}",
                        "restitution = restitution\n    offset = (0.1 mm, -0.05 mm)  relative_velocity = (20 mm/s, 10 mm/s)\n}")
    model = compile_text(text, str(MODELS / "a_offset.mbs"))
    q, qd = assemble(model)
    crank, rod = model.body_names.index("crank"), model.body_names.index("rod")
    c, s = np.cos(q[3 * crank + 2]), np.sin(q[3 * crank + 2])
    rot = np.array([[c, -s], [s, c]])
    e = _point(q, rod, (-0.06, 0)) - _point(q, crank, (0.025, 0))
    np.testing.assert_allclose(e, rot @ [1e-4, -5e-5], atol=1e-13)
    de = _point_velocity(q, qd, rod, (-0.06, 0)) - _point_velocity(q, qd, crank, (0.025, 0))
    np.testing.assert_allclose(de, rot @ [0.02, 0.01], atol=1e-12)
    plain = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    q, qd = assemble(plain)
    np.testing.assert_allclose(_point(q, rod, (-0.06, 0)) - _point(q, crank, (0.025, 0)), 0, atol=1e-13)
    np.testing.assert_allclose(_point_velocity(q, qd, rod, (-0.06, 0)) - _point_velocity(q, qd, crank, (0.025, 0)),
                               0, atol=1e-12)


def test_assembly_changes_are_reported():
    model = compile_text(SLIDER_CRANK_ROUGH, "rough.mbs")
    q, qd = assemble(model)
    changes = assembly_changes(model, q, qd)
    assert len(changes) == 1 and changes[0].startswith("assembly moved `crank` by")
    assert "`rod`" in changes[0] and "`slider`" in changes[0]
    # one unit per kind: the shift in mm and the turn in degrees, as computed here from the poses
    import re

    assert "(m or rad)" not in changes[0]
    b = model.body_names.index("rod")
    d = np.abs(q - model.q0)[3 * b:3 * b + 3]
    shown = re.search(r"`rod` by (\S+) mm and (\S+)°", changes[0])
    assert shown, changes[0]
    assert float(shown[1]) == pytest.approx(np.hypot(d[0], d[1]) * 1e3, rel=1e-2)
    assert float(shown[2]) == pytest.approx(np.degrees(d[2]), rel=1e-2)
    # a stated velocity the driver forbids is reported too
    stated = model.qd0.copy()
    stated[2] = 1.0  # the crank's angular velocity, which the driver sets to 5000 rpm
    model.qd0 = stated
    q, qd = assemble(model)
    changes = assembly_changes(model, q, qd)
    # 5000 rpm = 523.6 rad/s; the crank's centre, 25 mm from its pivot, then moves at 13.09 m/s
    assert changes[-1].startswith("assembly changed the stated velocity of `crank` by 13.1 m/s and 523 rad/s")


def test_offset_beyond_the_clearance_is_refused():
    with pytest.raises(ModelError, match="exceeds the clearance"):
        compile_text(FREE_JOURNAL.format(x="0 m", y="0 m", vx="0 m/s", vy="0 m/s", extra="offset = (0.2 mm, 0 m)"),
                     "j.mbs")
