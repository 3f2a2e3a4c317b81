"""The compiler: arrays of the shipped models, every class of user error, overrides (planar_mbs.mechanism.compile)."""
import math
from pathlib import Path

import numpy as np
import pytest

from planar_mbs.mechanism.compile import compile_text, load_model
from planar_mbs.errors import ModelError
from planar_mbs.mechanism.model import (
    CP_CLEARANCE, CP_EXPONENT, CP_LENGTH, CP_R_BEARING, CP_R_JOURNAL, CP_RESTITUTION, CP_SIGMA_SUM,
    CP_STIFFNESS, JP_LENGTH, JP_PHI0, ContactLaw, DriverType, ForceType, Integrator, JointType,
    MotionType, N_CLEARANCE_PARAM,
)

MODELS = Path(__file__).resolve().parent.parent / "models"

BASE = """param speed = 5000 rpm
param clearance = 0.3 mm
material steel { E = 207 GPa  nu = 0.3 }
body crank { mass = 0.3 kg  inertia = 1e-5 kg*m^2  position = (0.025, 0) }
body rod { mass = 0.21 kg  inertia = 2.5e-4 kg*m^2  position = (0.11, 0) }
joint O = revolute(ground (0, 0), crank (-0.025, 0))
"""


def err(extra, base=BASE, **kw) -> ModelError:
    with pytest.raises(ModelError) as e:
        compile_text(base + extra, "t.mbs", **kw)
    return e.value


# ----------------------------------------------------------------- shipped models
@pytest.mark.parametrize("name", ["slider_crank", "slider_crank_clearance_a", "slider_crank_clearance_b",
                                  "four_bar"])
def test_shipped_models_compile(name):
    m = load_model(MODELS / f"{name}.mbs")
    k = m.kernel
    for arr in k:
        assert arr.flags.c_contiguous and arr.dtype in (np.float64, np.int64)
    assert m.q0.shape == m.qd0.shape == (3 * m.nbody,)
    assert m.source_text.startswith("#") and m.source_path.endswith(f"{name}.mbs")


def test_slider_crank_arrays():
    m = load_model(MODELS / "slider_crank.mbs")
    k = m.kernel
    assert m.body_names == ["crank", "rod", "slider"]
    assert m.joint_names == ["O", "A", "B", "S"] and m.driver_names == ["crank_speed"]
    assert m.nclearance == 0 and m.nforce == 0
    assert k.body_mass.tolist() == [0.30, 0.21, 0.14]
    assert k.body_inertia.tolist() == [1e-5, 2.5e-4, 1e-4]
    np.testing.assert_allclose(k.minv, [1 / .3, 1 / .3, 1e5, 1 / .21, 1 / .21, 4e3, 1 / .14, 1 / .14, 1e4])
    assert k.joint_type.tolist() == [JointType.REVOLUTE] * 3 + [JointType.TRANSLATIONAL]
    assert k.joint_body.tolist() == [[-1, 0], [0, 1], [1, 2], [-1, 2]]
    # rows in the fill-reducing order (planar_mbs.mechanism.ordering): two per joint, one for the driver, all used once
    rows = sorted(k.joint_row.tolist() + (k.joint_row + 1).tolist() + k.driver_row.tolist())
    assert rows == list(range(9))
    np.testing.assert_allclose(k.joint_point[1], [[0.025, 0], [-0.06, 0]])
    np.testing.assert_allclose(k.joint_axis[3], [1, 0])
    assert k.joint_param[3, JP_PHI0] == 0
    assert k.driver_type[0] == DriverType.ANGLE and k.driver_body[0].tolist() == [-1, 0]
    assert k.driver_motion[0] == MotionType.CONSTANT_SPEED
    np.testing.assert_allclose(k.driver_motion_param[0, :2], [0, 5000 * 2 * math.pi / 60])
    np.testing.assert_allclose(m.q0, [0.025, 0, 0, 0.11, 0, 0, 0.17, 0, 0])
    assert k.gravity.tolist() == [0, 0]
    assert m.dof == 0 and m.nconstraint == 9
    assert m.settings.integrator == Integrator.DOPRI5
    assert m.settings.t_end == pytest.approx(2 * 60 / 5000) and m.settings.output_step == 1e-5
    assert m.parameters == {"speed": "5000 rpm"}
    assert m.body_geometry[2] == {"kind": "box", "width": 0.03, "height": 0.015}
    line = next(i for i, t in enumerate(m.source_text.splitlines(), 1) if t.startswith("joint A"))
    assert m.joint_source[1].line == line and m.joint_source[1].file.endswith("slider_crank.mbs")
    assert k.clearance_param.shape == (0, N_CLEARANCE_PARAM) and k.clearance_point.shape == (0, 2, 2)
    assert k.force_param.shape == (0, 5) and k.force_body.shape == (0, 2)


def test_clearance_a_arrays_and_eq18_stiffness():
    m = load_model(MODELS / "slider_crank_clearance_a.mbs")
    k = m.kernel
    assert m.joint_names == ["O", "B", "S"] and m.clearance_names == ["A"]
    rows = sorted(k.joint_row.tolist() + (k.joint_row + 1).tolist() + k.driver_row.tolist())
    assert rows == list(range(7)) and m.dof == 2
    assert k.clearance_body.tolist() == [[0, 1]]
    np.testing.assert_allclose(k.clearance_point[0], [[0.025, 0], [-0.06, 0]])
    assert k.clearance_law[0] == ContactLaw.LANKARANI_NIKRAVESH
    p = k.clearance_param[0]
    assert p[CP_CLEARANCE] == pytest.approx(3e-4) and p[CP_R_BEARING] == 5e-3
    assert p[CP_R_JOURNAL] == pytest.approx(4.7e-3) and p[CP_LENGTH] == 0.02
    assert p[CP_RESTITUTION] == 0.9 and p[CP_EXPONENT] == 1.5
    # eq. 18 by hand: sigma = (1 - 0.3^2) / 207e9 for both parts
    sigma = 0.91 / 207e9
    hand = 4 / (3 * 2 * sigma) * math.sqrt(0.005 * 0.0047 / 0.0003)
    assert p[CP_SIGMA_SUM] == pytest.approx(2 * sigma, rel=1e-12)
    assert p[CP_STIFFNESS] == pytest.approx(hand, rel=1e-12)
    assert 4.24e10 < p[CP_STIFFNESS] < 4.25e10
    assert m.settings.t_end == pytest.approx(0.06) and m.settings.rtol == 1e-8 and m.settings.atol == 1e-11
    assert m.parameters["law"] == "lankarani_nikravesh" and m.parameters["clearance"] == "0.3 mm"
    line = next(i for i, t in enumerate(m.source_text.splitlines(), 1) if t.startswith("override joint A"))
    assert m.clearance_source[0].line == line


def test_clearance_b_puts_bearing_in_rod():
    m = load_model(MODELS / "slider_crank_clearance_b.mbs")
    assert m.clearance_names == ["B"] and m.kernel.clearance_body.tolist() == [[1, 2]]
    assert m.joint_names == ["O", "A", "S"]


# ----------------------------------------------------------------- overrides
def test_overrides_speed_clearance_law():
    m = load_model(MODELS / "slider_crank_clearance_a.mbs",
                   {"speed": "2500rpm", "clearance": "0.1 mm", "law": "hertz"})
    k = m.kernel
    assert k.driver_motion_param[0, 1] == pytest.approx(2500 * 2 * math.pi / 60)
    assert k.clearance_param[0, CP_CLEARANCE] == pytest.approx(1e-4)
    assert k.clearance_param[0, CP_R_JOURNAL] == pytest.approx(4.9e-3)
    assert k.clearance_law[0] == ContactLaw.HERTZ
    assert m.settings.t_end == pytest.approx(0.12)  # t_end = 5 rev / speed follows the override
    assert m.parameters["speed"] == "2500rpm" and m.parameters["law"] == "hertz"


def test_override_without_the_unit_of_the_param_is_refused():
    """The model's `clearance` is 0.3 mm: `--set clearance=0.0001` (no unit) names the unit instead of
    taking 0.1 mm, or 0.1 m, silently; zero needs no unit."""
    with pytest.raises(ModelError) as e:
        load_model(MODELS / "slider_crank_clearance_a.mbs", {"clearance": "0.0001"})
    assert e.value.file == "--set" and "has no unit" in e.value.message and "clearance=0.0001mm" in e.value.hint
    m = load_model(MODELS / "slider_crank_clearance_a.mbs", {"clearance": "0.1 mm", "restitution": "0.5"})
    assert m.kernel.clearance_param[0, CP_CLEARANCE] == pytest.approx(1e-4)


def test_override_unknown_name():
    with pytest.raises(ModelError) as e:
        load_model(MODELS / "slider_crank_clearance_a.mbs", {"speeed": "1 rpm"})
    assert e.value.file == "--set" and "did you mean `speed`?" in e.value.hint


@pytest.mark.parametrize("name, value, words", [
    ("speed", "3 mm", "was expected, got a length"),
    ("speed", "3 +", "ends too early"),
    ("law", "3", "is a name"),
    ("law", "herz", "unknown law `herz`"),
    ("speed", "2500 rpmm", "unknown unit `rpmm`"),
])
def test_bad_override_values(name, value, words):
    with pytest.raises(ModelError) as e:
        load_model(MODELS / "slider_crank_clearance_a.mbs", {name: value})
    assert e.value.file == "--set" and words in e.value.message


# ----------------------------------------------------------------- errors
def test_wrong_dimension():
    e = err("body x { mass = 3 m  inertia = 1 }")
    assert e.message == "a mass was expected, got a length (3 m)"
    assert (e.file, e.line, e.column, e.width) == ("t.mbs", 7, 17, 3) and "kg" in e.hint
    assert "    body x { mass = 3 m  inertia = 1 }\n                    ^^^" in str(e)


@pytest.mark.parametrize("extra, words", [
    ("body x { mass = -3 kg  inertia = 1 }", "`mass` of body `x` must be positive"),
    ("body x { mass = 3 kg  inertia = 0 }", "`inertia` of body `x` must be positive"),
    ("body x { mass = 3 kg }", "body `x` needs `inertia`"),
])
def test_body_checks(extra, words):
    assert words in err(extra).message


def test_unknown_field_did_you_mean():
    e = err("body x { mas = 3 kg  inertia = 1 }")
    assert e.message == "unknown field `mas` for body `x`" and e.hint == "did you mean `mass`?"


def test_unknown_body_did_you_mean():
    e = err("joint J = revolute(crnk (0, 0), rod (0, 0))")
    assert e.message == "unknown body `crnk`" and "`crank`" in e.hint and e.column == 20


def test_unknown_param_did_you_mean():
    e = err("driver d = rotation(crank, speed = speeed)")
    assert e.message == "unknown name `speeed`" and "`speed`" in e.hint


def test_unit_written_with_spaces_gets_a_hint():
    e = err("param x = 2.5e-4 kg * m^2")
    assert e.message == "unknown name `m`" and "without a space" in e.hint


def test_duplicate_name():
    e = err("joint O = revolute(crank, rod)")
    assert "`O` is already defined (a joint at t.mbs:6)" in e.message and "override" in e.hint


def test_names_share_one_namespace():
    assert "already defined" in err("joint crank = revolute(crank, rod)").message


@pytest.mark.parametrize("extra, words", [
    ("body ground { mass = 1 kg  inertia = 1 }", "`ground` is reserved"),
    ("param system = 1", "`system` is reserved"),
    ("body force { mass = 1 kg  inertia = 1 }", "`force` is a keyword"),
])
def test_reserved_names(extra, words):
    assert words in err(extra).message


def test_param_cycle():
    e = err("param a = b + 1\nparam b = 2 * c\nparam c = a")
    assert "cycle: `a` → `b` → `c` → `a`" in e.message and e.line == 7


def test_params_resolve_in_dependency_order():
    m = compile_text(BASE + "param late = 2 * early\nparam early = 3 mm\n"
                     "body x { mass = 1 kg  inertia = 1  position = (late, 0) }", "t.mbs")
    assert m.q0[6] == pytest.approx(6e-3) and m.parameters["late"] == "6 mm"


def test_plain_number_plus_dimension_is_an_error():
    e = err("param x = clearance + 0.1")
    assert "cannot add a plain number to a length" in e.message and "0.1 mm" in e.hint


def test_unknown_unit():
    e = err("param x = 3 mmm")
    assert e.message == "unknown unit `mmm`" and "`mm`" in e.hint


@pytest.mark.parametrize("extra, words", [
    ("param x = 1/0", "division by zero"),
    ("param x = 10^1000", "too large"),
    ("param x = (-8)^0.5", "not a finite real number"),
    ("param x = sqrt(-1)", "square root of a negative"),
])
def test_arithmetic_errors(extra, words):
    assert words in err(extra).message


def test_override_of_unknown_element():
    e = err("override joint Q = revolute(crank, rod)")
    assert "`override` of joint `Q`, which is not defined before" in e.message


def test_override_changes_kind():
    e = err("override body O { mass = 1 kg  inertia = 1 }")
    assert "`O` is a joint" in e.message


def test_override_replaces_in_place():
    m = compile_text(BASE + "joint A = revolute(crank (0.025, 0), rod (-0.06, 0))\n"
                     "override joint O = weld(ground, crank (-0.025, 0))", "t.mbs")
    assert m.joint_names == ["O", "A"] and m.kernel.joint_type.tolist() == [JointType.WELD, JointType.REVOLUTE]
    assert m.kernel.joint_row.tolist() == [0, 3]


def test_second_simulate_needs_override():
    assert "a second `simulate`" in err("simulate { t_end = 1 s }\nsimulate { t_end = 2 s }").message


def clearance(fields, law="lankarani_nikravesh"):
    return ("joint A = clearance_revolute(crank (0.025, 0), rod (-0.06, 0)) {"
            f" {fields} law = {law} }}")


@pytest.mark.parametrize("fields, law, words", [
    ("journal_radius = 6 mm  bearing_radius = 5 mm  material = steel restitution = 0.9", "hertz",
     "must be smaller than the bearing"),
    ("clearance = 0.3 mm  journal_radius = 6 mm  bearing_radius = 5 mm  material = steel", "hertz",
     "differs from `clearance`"),
    ("clearance = -0.3 mm  bearing_radius = 5 mm  material = steel", "hertz", "must be positive"),
    ("clearance = 0.3 mm  material = steel", "hertz", "needs two of"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  length = 0 mm  material = steel", "hertz", "must be positive"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  material = steal", "hertz", "unknown material `steal`"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  material = steel", "lankarani_nikravesh",
     "needs one of `restitution` or `effective_restitution`"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  material = steel  restitution = 0.9  effective_restitution = 0.9",
     "flores", "give `restitution` or `effective_restitution` to law flores, not both"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  material = steel  effective_restitution = 0", "gonthier",
     "restitution must lie in (0, 1]"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  material = steel  effective_restitution = 0.9", "hertz",
     "law hertz takes no `effective_restitution`"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  material = steel  restitution = 1.5",
     "lankarani_nikravesh", "restitution must lie in (0, 1]"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm", "hertz", "needs `material` (or `stiffness`)"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  material = steel", "esdu78035",
     "law esdu78035 of clearance joint `A` needs the bearing `length`"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  length = 20 mm", "dubowsky_freudenstein",
     "needs `material`"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  length = 20 mm  material = steel  stiffness = 1e9 N/m^1.5",
     "esdu78035", "takes no `stiffness`"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  material = steel  restitution = 0.9  friction = 0.1"
     "  friction_velocity = 2e-4 m/s  friction_velocity_full = 1e-4 m/s", "hertz", "must exceed"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  material = steel", "lankarani", "unknown law `lankarani`"),
    ("clearance = 0.3 mm  bearing_radius = 5 mm  stiffness = 4e10 N/m", "hertz", "a contact stiffness"),
])
def test_clearance_joint_errors(fields, law, words):
    assert words in err(clearance(fields, law)).message


def test_all_law_names_are_known():
    from planar_mbs.mechanism.model import CONTACT_LAW_NAMES

    for law, name in CONTACT_LAW_NAMES.items():
        linear = "  stiffness = 1e8 N/m" if name == "kelvin_voigt" else ""  # no default K of F = K d
        m = compile_text(BASE + clearance("clearance = 0.3 mm  bearing_radius = 5 mm  length = 20 mm"
                                          "  material = steel  restitution = 0.7" + linear, name), "t.mbs")
        assert m.kernel.clearance_law[0] == law


def test_clearance_with_explicit_stiffness_and_law_call():
    m = compile_text(BASE + "joint A = clearance_revolute(crank (0.025, 0), rod (-0.06, 0)) {"
                     " bearing_radius = 5 mm  journal_radius = 4.7 mm"
                     " law = lankarani_nikravesh(restitution = 0.8, stiffness = 1e9 N/m^1.5) friction = 0.1 }",
                     "t.mbs")
    p = m.kernel.clearance_param[0]
    assert p[CP_STIFFNESS] == 1e9 and p[CP_RESTITUTION] == 0.8 and p[CP_CLEARANCE] == pytest.approx(3e-4)
    assert p[CP_SIGMA_SUM] == 0


def test_two_materials():
    m = compile_text(BASE + "material bronze { E = 110 GPa  nu = 0.34 }\n" + clearance(
        "clearance = 0.3 mm  bearing_radius = 5 mm  bearing_material = bronze  journal_material = steel", "hertz"),
        "t.mbs")
    s = (1 - 0.34 ** 2) / 110e9 + (1 - 0.09) / 207e9
    assert m.kernel.clearance_param[0, CP_SIGMA_SUM] == pytest.approx(s)


def test_every_element_kind():
    src = BASE + """
body b { mass = 1 kg  inertia = 1 kg*m^2  position = (3, 2)  angle = 30 deg  velocity = (1 m/s, 0)  omega = 60 rpm }
joint t = translational(crank (0.5, 0), b, axis = (0, 2))
joint w = weld(rod, b)
joint rr = revolute_revolute(crank (0, 0.5), b (0.1, 0))
joint rt = revolute_translational(rod, b (1, 0), axis = (1, 1))
driver d1 = translation(b (0.1, 0), axis = (1, 0), polynomial(0.1, 0.2 m/s, 0.3 m/s^2))
driver d2 = rotation(b, relative_to = rod, harmonic(amplitude = 10 deg, frequency = 2 Hz, phase = 90 deg))
driver d3 = translation(b, relative_to = rod (1, 0), axis = (0, 1), speed = 2 m/s, initial = 5 cm)
driver d4 = rotation(crank, ramp(speed = 100 rpm, time = 0.1 s))
force f = constant(rod (0.06, 0), force = (1 N, -2 N))
force t2 = torque(crank, 2 N*m)
force s = spring_damper(crank (0.025, 0), rod (0.06, 0)) { stiffness = 100 N/m  damping = 1 N*s/m }
force r = rotational_spring_damper(crank, rod) { stiffness = 1 N*m/rad  actuator = 0.5 N*m }
gravity (0, -9.81 m/s^2)
simulate { integrator = rk4  step = 1 us  projection = on  max_steps = 1e6  alpha = 10 1/s  beta = 10 }
"""
    m = compile_text(src, "t.mbs")
    k = m.kernel
    assert k.joint_type.tolist() == [0, 1, 2, 3, 4]
    # rows 2, 2, 3, 1, 1 per joint and one per driver, each element's rows together, every row once
    size = [2, 2, 3, 1, 1]
    rows = sorted([k.joint_row[j] + i for j in range(5) for i in range(size[j])] + k.driver_row.tolist())
    assert rows == list(range(13))
    assert k.joint_param[1, JP_PHI0] == pytest.approx(math.radians(30))
    np.testing.assert_allclose(k.joint_axis[1], [0, 1])
    np.testing.assert_allclose(k.joint_axis[4], [math.sqrt(.5)] * 2)
    pi_w = np.array([0.025, 0.5]); pj_w = np.array([3, 2]) + np.array([math.cos(math.pi / 6), 0.5]) * 0.1
    assert k.joint_param[3, JP_LENGTH] == pytest.approx(np.linalg.norm(pj_w - pi_w))
    assert k.driver_motion.tolist() == [MotionType.POLYNOMIAL, MotionType.HARMONIC,
                                        MotionType.CONSTANT_SPEED, MotionType.RAMP]
    np.testing.assert_allclose(k.driver_motion_param[0, :3], [0.1, 0.2, 0.3])
    np.testing.assert_allclose(k.driver_motion_param[1, :4], [math.radians(30), math.radians(10), 2, math.pi / 2])
    np.testing.assert_allclose(k.driver_motion_param[2, :2], [0.05, 2])
    np.testing.assert_allclose(k.driver_motion_param[3, :3], [0, 100 * 2 * math.pi / 60, 0.1])
    assert k.driver_body.tolist() == [[-1, 2], [1, 2], [1, 2], [-1, 0]]
    assert k.driver_type.tolist() == [DriverType.POSITION, DriverType.ANGLE, DriverType.POSITION, DriverType.ANGLE]
    assert k.force_type.tolist() == [ForceType.CONSTANT_FORCE, ForceType.CONSTANT_TORQUE,
                                     ForceType.SPRING_DAMPER, ForceType.ROTATIONAL_SPRING_DAMPER]
    assert k.force_body.tolist() == [[1, -1], [0, -1], [0, 1], [0, 1]]
    np.testing.assert_allclose(k.force_param[0, :2], [1, -2])
    np.testing.assert_allclose(k.force_param[2], [100, 1, 0.12, 0, 0])  # free length: (0.05, 0) to (0.17, 0)
    np.testing.assert_allclose(k.force_param[3], [1, 0, 0, 0.5, 0])  # p4: no expression actuator
    np.testing.assert_allclose(k.gravity, [0, -9.81])
    np.testing.assert_allclose(m.qd0[6:], [1, 0, 2 * math.pi])
    s = m.settings
    assert (s.integrator, s.step, s.projection, s.max_steps, s.alpha, s.beta) == (Integrator.RK4, 1e-6, "on",
                                                                                   10 ** 6, 10, 10)
    assert m.force_names == ["f", "t2", "s", "r"]


@pytest.mark.parametrize("extra, words", [
    ("joint J = hinge(crank, rod)", "unknown joint type `hinge`"),
    ("joint J = revolute(crank, crank)", "to itself"),
    ("joint J = revolute(crank)", "connects two bodies"),
    ("joint J = translational(crank, rod)", "needs `axis`"),
    ("joint J = translational(crank, rod, axis = (0, 0))", "zero vector"),
    ("joint J = revolute(steel, rod)", "`steel` is a material, not a body"),
    ("driver d = rotation(crank, speed = 3 m/s)", "an angular velocity was expected"),
    ("driver d = rotation(crank)", "needs one motion"),
    ("driver d = rotation(ground, speed = 1 rpm)", "cannot be driven"),
    ("driver d = spin(crank, speed = 1 rpm)", "unknown driver `spin`"),
    ("driver d = rotation(crank, jerk(1))", "unknown motion `jerk`"),
    ("driver d = translation(rod, axis = (1, 0), polynomial(0.1, 0.2 m/s, 0.3 m/s))", "per second^2"),
    ("force f = constant(crank, force = 3 N)", "a vector `(x, y)` was expected"),
    ("force f = push(crank)", "unknown force `push`"),
    ("gravity (0, -9.81 m/s)", "an acceleration was expected, got a velocity"),
    ("simulate { t_end = 1 m }", "a time was expected, got a length"),
    ("simulate { integrator = rk45 }", "unknown integrator `rk45`"),
    ("simulate { max_steps = 1.5 }", "whole number"),
    ("simulate { output_step = 0 s }", "must be positive"),
    ("body x { mass = 1 kg  inertia = 1  shape = hexagon(3) }", "unknown shape `hexagon`"),
    ("body x { mass = 1 kg  inertia = 1  shape = box(3 mm) }", "needs `height`"),
    ("body x { mass = 1 kg  inertia = 1  position = (1, 2, 3) }", "a vector `(x, y)` was expected"),
    ("body x { mass = 1 kg  inertia = 1  angle = crank }", "`crank` is a body, not a number"),
    ("material m2 { E = 1 GPa  nu = 0.7 }", "Poisson's ratio"),
])
def test_element_errors(extra, words):
    assert words in err(extra).message


def test_no_bodies():
    e = err("param x = 1", base="")
    assert "no bodies" in e.message


def test_include_and_error_in_included_file(tmp_path):
    (tmp_path / "base.mbs").write_text(BASE + "body bad { mass = 1 m  inertia = 1 }\n")
    (tmp_path / "main.mbs").write_text('include "base.mbs"\n')
    with pytest.raises(ModelError) as e:
        load_model(tmp_path / "main.mbs")
    assert e.value.file.endswith("base.mbs") and e.value.line == 7
    assert "body bad { mass = 1 m" in str(e.value)


def test_include_cycle_is_a_model_error(tmp_path):
    (tmp_path / "a.mbs").write_text('include "a.mbs"\n')
    with pytest.raises(ModelError, match="include cycle"):
        load_model(tmp_path / "a.mbs")


def test_missing_file():
    with pytest.raises(ModelError, match="cannot read the model file"):
        load_model("/nonexistent/model.mbs")


def test_only_model_errors_escape():
    """Garbage of many kinds yields ModelError and nothing else."""
    for text in ["}", "param", "param x = ((((", "body x { mass = 1e308 kg * 1e308 inertia = 1 }",
                 "param x = 2 ^ (1 m)", "param x = sin(1 m)", "param x = (1, 2) * (3, 4)",
                 "param x = atan2(1 m, 1 s)", "param x = box(1)", "\x00", "param x = 1 rpm + 1 m"]:
        with pytest.raises(ModelError):
            compile_text(text, "t.mbs")


def test_a_second_body_written_as_a_drivers_argument_is_named_with_relative_to():
    """`rotation(a, b, speed = ...)` is a reference body in the wrong place, not a second motion: the
    message says so at `b` and shows `relative_to`; written that way, the driver moves a relative to b."""
    base = ("body a { mass = 1 kg  inertia = 1 kg*m^2 }\n"
            "body b { mass = 1 kg  inertia = 1 kg*m^2  position = (1 m, 0) }\n"
            "joint pa = revolute(ground (0, 0), a (0, 0))\njoint pb = revolute(ground (1 m, 0), b (0, 0))\n")
    with pytest.raises(ModelError) as err:
        compile_text(base + "driver d = rotation(a, b, speed = 0 rad/s)\n")
    text = err.value.render()
    assert "`b` is a body, not a motion" in text and "relative_to = b" in text
    assert (err.value.line, err.value.column) == (5, 24)
    m = compile_text(base + "driver d = rotation(a, relative_to = b, speed = 0 rad/s)\n")
    assert list(m.kernel.driver_body[0]) == [1, 0]
