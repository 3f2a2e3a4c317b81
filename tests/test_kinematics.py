"""Assembly of initial conditions (Muvengei et al. §III.A): Newton–Raphson onto the constraints."""
from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.compile import compile_text
from planar_mbs.errors import ModelError
from planar_mbs.kinematics import assemble

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
    from planar_mbs.kinematics import assembly_kernel
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
