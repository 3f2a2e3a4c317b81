"""Expressions of loads and motions, and tables, against closed forms derived here and against the
equivalent built-in elements (docs/language.md, "Expressions and tables")."""
import math
import sys
from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.errors import ModelError, SimulationError

MBS = str(Path(sys.executable).with_name("mbs"))

FREE_MASS = """
param F0 = 3 N
param w = 20 rad/s
body mass {{ mass = 2 kg  inertia = 0.5 kg*m^2 }}
force push = expression(mass, {load})
simulate {{ t_end = 1 s  rtol = 1e-10  atol = 1e-12  output_step = 10 ms }}
"""


def test_mass_under_a_sine_force_follows_the_closed_form():
    """m x'' = F0 sin(w t), x(0) = x'(0) = 0: x = F0 / (m w^2) (w t - sin w t); the same in y and,
    as a torque, in phi (I phi'' = T0 sin(w t))."""
    load = "fx = F0 * sin(w * t), fy = -F0 * sin(w*t), torque = 0.1 m * F0 * sin(w*t)"
    res = mbs.simulate(mbs.compile_text(FREE_MASS.format(load=load)))
    t = res.time
    shape = 20 * t - np.sin(20 * t)
    np.testing.assert_allclose(res["mass.x"], 3 / (2 * 400) * shape, rtol=0, atol=1e-10)
    np.testing.assert_allclose(res["mass.y"], -3 / (2 * 400) * shape, rtol=0, atol=1e-10)
    np.testing.assert_allclose(res["mass.phi"], 0.3 / (0.5 * 400) * shape, rtol=0, atol=1e-10)
    np.testing.assert_allclose(res["mass.vx"], 3 / (2 * 20) * (1 - np.cos(20 * t)), rtol=0, atol=1e-9)


PENDULUM = """
gravity (0, -9.81 m/s^2)
body bob {{ mass = 0.4 kg  inertia = 2e-3 kg*m^2  position = (0.2, 0)  angle = 0 deg }}
joint O = revolute(ground (0, 0), bob (-0.2, 0))
{load}
simulate {{ t_end = 2 s  rtol = 1e-9  atol = 1e-12  output_step = 5 ms }}
"""


def test_pendulum_torque_expression_equals_the_rotational_spring_damper():
    spring = ("force s = rotational_spring_damper(ground, bob) "
              "{ stiffness = 3 N*m/rad  damping = 0.02 N*m*s/rad  angle = 0 deg }")
    expr = "force s = expression(bob, torque = -3 N*m/rad * bob.phi - 0.02 N*m*s/rad * bob.omega)"
    a = mbs.simulate(mbs.compile_text(PENDULUM.format(load=spring)))
    b = mbs.simulate(mbs.compile_text(PENDULUM.format(load=expr)))
    assert a.attrs["n_steps"] == b.attrs["n_steps"]
    for name in ("bob.phi", "bob.omega", "bob.x", "O.fx", "O.fy"):
        np.testing.assert_allclose(b[name], a[name], rtol=1e-12, atol=1e-13)
    assert np.ptp(a["bob.phi"]) > 0.2  # it does swing


CRANK = """
body crank {{ mass = 0.3 kg  inertia = 1e-4 kg*m^2  position = (0.025, 0) }}
body rod {{ mass = 0.2 kg  inertia = 2.5e-4 kg*m^2  position = (0.11, 0) }}
body slider {{ mass = 0.15 kg  inertia = 1e-4 kg*m^2  position = (0.17, 0) }}
joint O = revolute(ground (0, 0), crank (-0.025, 0))
joint A = revolute(crank (0.025, 0), rod (-0.06, 0))
joint B = revolute(rod (0.06, 0), slider)
joint S = translational(ground, slider, axis = (1, 0))
driver drive = rotation(crank, motion = {motion})
{extra}
simulate {{ t_end = 0.2 s  rtol = 1e-9  atol = 1e-12  output_step = 1 ms }}
"""
SIGNALS = ("crank.phi", "crank.omega", "crank.alpha", "slider.x", "slider.vx", "slider.ax", "drive.torque",
           "drive.power", "A.fx")


def test_motion_expression_equals_the_polynomial():
    poly = mbs.compile_text(CRANK.format(motion="polynomial(0, 40 rad/s, 300 rad/s^2, -500 rad/s^3)", extra=""))
    expr = mbs.compile_text(CRANK.format(
        motion="40 rad/s * t + 300 rad/s^2 * t^2 - 500 rad/s^3 * t*t*t", extra=""))
    a, b = mbs.simulate(poly), mbs.simulate(expr)
    for name in SIGNALS:
        np.testing.assert_allclose(b[name], a[name], rtol=1e-9, atol=1e-9 * np.max(np.abs(a[name])))


def test_motion_derivatives_are_exact():
    """phi = A sin(w t) exp(-t/tau) (+ atan2, sqrt, step inside): the driven crank's omega and alpha
    equal the derivatives written out here."""
    motion = "0.8 rad * sin(30 rad/s * t) * exp(-t / 0.1 s) + 0.2 * atan2(t, 0.05 s) + 0.1 rad * sqrt(1 + t / 1 s)"
    res = mbs.simulate(mbs.compile_text(CRANK.format(motion=motion, extra="")))
    t = res.time
    A, w, tau = 0.8, 30.0, 0.1
    e = np.exp(-t / tau)
    phi = A * np.sin(w * t) * e + 0.2 * np.arctan2(t, 0.05) + 0.1 * np.sqrt(1 + t)
    om = A * e * (w * np.cos(w * t) - np.sin(w * t) / tau) + 0.2 * 0.05 / (t**2 + 0.05**2) + 0.05 / np.sqrt(1 + t)
    al = (A * e * (-w * w * np.sin(w * t) - 2 * w * np.cos(w * t) / tau + np.sin(w * t) / tau**2)
          - 0.2 * 0.05 * 2 * t / (t**2 + 0.05**2) ** 2 - 0.025 * (1 + t) ** -1.5)
    np.testing.assert_allclose(res["crank.phi"], phi, rtol=0, atol=1e-9)  # integrated, rtol = 1e-9
    np.testing.assert_allclose(res["crank.omega"], om, rtol=0, atol=1e-8 * np.max(np.abs(om)))
    np.testing.assert_allclose(res["crank.alpha"], al, rtol=0, atol=1e-8 * np.max(np.abs(al)))


SLIDE = """
body block {{ mass = 1 kg  inertia = 1 kg*m^2 }}
joint rail = translational(ground, block, axis = (1, 0))
driver d = translation(block, axis = (1, 0), motion = {motion})
simulate {{ t_end = 1 s  rtol = 1e-9  atol = 1e-12  output_step = 10 ms }}
"""


def test_cubic_table_reproduces_a_cubic_with_its_derivatives():
    """The not-a-knot cubic spline through samples of a cubic is that cubic: a motion read from the
    table gives the cubic's position, velocity and acceleration (and the driver force m x'')."""
    def p(x):
        return 0.02 * x**3 - 0.05 * x**2 + 0.03 * x + 0.01

    knots = [0.0, 0.13, 0.3, 0.55, 0.7, 1.2]
    xs = ", ".join(f"{x} s" for x in knots)
    ys = ", ".join(f"{p(x)!r} m" for x in knots)
    res = mbs.simulate(mbs.compile_text(SLIDE.format(motion=f"table(x = t, xs = ({xs}), ys = ({ys}), "
                                                          "interpolation = cubic)")))
    t = res.time
    # x and x' are integrated (rtol 1e-9, atol 1e-12); x'' is the driver's f'' from the table
    np.testing.assert_allclose(res["block.x"], p(t), rtol=0, atol=1e-11)
    np.testing.assert_allclose(res["block.vx"], 0.06 * t**2 - 0.1 * t + 0.03, rtol=0, atol=1e-9 * 0.03)
    np.testing.assert_allclose(res["block.ax"], 0.12 * t - 0.1, rtol=0, atol=1e-10)
    np.testing.assert_allclose(res["d.force"], 0.12 * t - 0.1, rtol=0, atol=1e-10)


BANG = """
param F = 2 N
body mass {{ mass = 1 kg  inertia = 1 kg*m^2 }}
force push = expression(mass, fx = {load})
simulate {{ t_end = 1 s  rtol = 1e-8  atol = 1e-10  output_step = 10 ms }}
"""


def test_a_switching_load_is_located_as_an_event():
    """x'' = F/m while x < x1, then -F/m: the switch at t1 = sqrt(2 x1 m / F) is located on the dense
    output, so the trajectory keeps the integrator's accuracy and no step is rejected more than
    under a smooth load of the same size."""
    switching = mbs.simulate(mbs.compile_text(BANG.format(load="if(mass.x < 0.25 m, F, -F)")))
    smooth = mbs.simulate(mbs.compile_text(BANG.format(load="F * cos(9 rad/s * t)")))
    t = switching.time
    t1 = math.sqrt(2 * 0.25 / 2)
    ref = np.where(t < t1, t**2, 0.25 + 2 * t1 * (t - t1) - (t - t1) ** 2)
    np.testing.assert_allclose(switching["mass.x"], ref, rtol=0, atol=1e-10)
    assert switching.attrs["n_rejected"] <= smooth.attrs["n_rejected"]
    # without the event the same tolerance costs rejected steps: a step whose end fixes the branch
    assert switching.attrs["n_steps"] < 30


def test_step_is_adams_smooth_step():
    """step(t, 0.2 s, 0, 0.6 s, 2) as a force on a free mass: x'' = the cubic step, integrated here."""
    res = mbs.simulate(mbs.compile_text(BANG.format(load="1 N * step(t, 0.2 s, 0, 0.6 s, 2)")))
    t = res.time
    d = np.clip((t - 0.2) / 0.4, 0, 1)
    # v = int 2 d^2 (3 - 2 d) dt = 0.4 * 2 (d^3 - d^4 / 2) on the ramp, then 2 (t - 0.6) more
    v = 0.8 * (d**3 - d**4 / 2) + 2 * np.maximum(t - 0.6, 0)
    np.testing.assert_allclose(res["mass.vx"], v, rtol=0, atol=1e-9)


# ------------------------------------------------------------------ bad input
def _error(text, path="m.mbs"):
    with pytest.raises(ModelError) as info:
        mbs.compile_text(text, path)
    return info.value


def _where(err):
    return (err.line, err.column)


def test_wrong_dimension_is_reported_at_the_expression():
    text = FREE_MASS.format(load="fx = F0 * mass.vx")
    err = _error(text)
    assert "a force was expected" in err.message and "`fx`" in err.message
    line = text.splitlines().index(next(l for l in text.splitlines() if "expression(" in l)) + 1
    assert err.line == line and err.column == text.splitlines()[line - 1].index("F0 * mass") + 1


def test_adding_a_velocity_to_a_force_is_an_error():
    err = _error(FREE_MASS.format(load="fx = F0 + mass.vx"))
    assert "cannot add a force and a velocity" in err.message


def test_unknown_signal_is_an_error_with_a_suggestion():
    err = _error(FREE_MASS.format(load="fx = F0 * sin(mass.phii)"))
    assert "unknown signal `mass.phii`" in err.message and "phi" in err.hint
    err = _error(FREE_MASS.format(load="fx = F0 * sin(mas.phi)"))
    assert "no body or clearance joint `mas`" in err.message and "mass" in err.hint


def test_a_load_using_a_driver_effort_is_circular():
    err = _error(CRANK.format(motion="40 rad/s * t",
                              extra="force f = expression(slider, fx = -0.5 * drive.torque / 1 m)"))
    assert "circular dependency" in err.message and "drive.torque" in err.message
    assert "force `f`" in err.message


def test_a_division_by_zero_at_the_initial_state_is_an_error():
    text = FREE_MASS.format(load="fx = 2 N + 1 W / mass.vx")
    err = _error(text)
    assert "division by zero" in err.message and "initial state" in err.message
    line = text.splitlines()[err.line - 1]
    assert line[err.column - 1:].startswith("1 W / mass.vx")
    # guarded, the same division is accepted
    mbs.compile_text(FREE_MASS.format(load="fx = if(abs(mass.vx) > 1e-9 m/s, 1 W / mass.vx, 0 N)"))


def test_a_motion_may_not_read_the_state():
    err = _error(CRANK.format(motion="2 * crank.phi", extra=""))
    assert "function of time only" in err.message


def test_signals_and_comparisons_outside_expressions_are_errors():
    err = _error("param p = crank.phi\nbody crank { mass = 1 kg inertia = 1 kg*m^2 }\n")
    assert "only be used in an expression" in err.message


def test_tables_from_files_are_checked(tmp_path):
    model = tmp_path / "m.mbs"

    def compile_with(csv_text, name="gas.csv"):
        (tmp_path / "gas.csv").write_text(csv_text)
        model.write_text(FREE_MASS.format(
            load=f'fx = table("{name}", x = t, x_unit = "ms", y_unit = "kN", interpolation = akima)'))
        return mbs.load_model(model)

    m = compile_with("time_ms, force_kN\n0, 0\n1, 2\n2, 3\n4, 3.5\n")
    assert m.kernel.table_seg[3, 0] == pytest.approx(4e-3) and m.kernel.table_seg[3, 1] == pytest.approx(3500)
    with pytest.raises(ModelError) as info:
        compile_with("0, 0\n1, 2\n", name="missing.csv")
    assert "cannot read the table `missing.csv`" in info.value.message
    with pytest.raises(ModelError) as info:
        compile_with("0, 0\n1, 2\n# a comment\n1, 3\n")
    assert info.value.line == 4 and "must increase" in info.value.message and info.value.file.endswith("gas.csv")
    with pytest.raises(ModelError) as info:
        compile_with("0, 0\n1, nan\n")
    assert info.value.line == 2 and "not a finite number" in info.value.message
    with pytest.raises(ModelError) as info:
        compile_with("0, 0\n1, 2, 3\n")
    assert info.value.line == 2


def test_interpolations_against_their_definitions():
    from planar_mbs.mechanism.tables import evaluate, knots

    xs = np.array([0.0, 1.0, 2.5, 3.0, 4.0])
    ys = 2.0 * xs - 1.0
    for method in ("linear", "cubic", "akima"):  # each reproduces a straight line
        rows = knots(xs, ys, method, 0.0)
        for x in np.linspace(0, 4, 37):
            assert evaluate(rows, 0.0, x) == pytest.approx(2 * x - 1, abs=1e-12)
    rows = knots(xs, ys, "linear", 0.0)
    assert evaluate(rows, 0.0, -3.0) == -1.0 and evaluate(rows, 0.0, 9.0) == 7.0  # held outside
    # periodic: closed onto its first value, repeated with the period
    rows = knots(np.array([0.0, 1.0, 2.0]), np.array([0.0, 1.0, 0.5]), "linear", 3.0)
    assert evaluate(rows, 3.0, 2.5) == pytest.approx(0.25) and evaluate(rows, 3.0, 7.0) == pytest.approx(1.0)
    rows = knots(np.array([0.0, 1.0, 2.0, 3.0]), np.sin(2 * np.pi * np.array([0.0, 1.0, 2.0, 3.0]) / 4), "cubic", 4.0)
    # a periodic spline has equal slopes at both ends of the period
    assert rows[0, 2] == pytest.approx(rows[-2, 2] + 2 * rows[-2, 3] + 3 * rows[-2, 4])


@pytest.mark.parametrize("defaults", [False, True])
@pytest.mark.parametrize("joint", ["", "joint rail = translational(ground, mass, axis = (1, 0))\n"])
def test_a_nan_at_run_time_names_the_force_and_the_time(joint, defaults):
    """Also on a jointed body, where the NaN reaches the constraint solve first (it was blamed on the
    joint: "the constraint matrix became singular at joint `rail`"); also with the default tolerances."""
    text = FREE_MASS.format(load="fx = 1 N + 1 N/m^0.5 * sqrt(0.1 m - mass.x) * 0") + joint
    if defaults:
        text = text.replace("rtol = 1e-10  atol = 1e-12  ", "")
    with pytest.raises(SimulationError) as info:
        mbs.simulate(mbs.compile_text(text))
    message = str(info.value)
    assert "force `push`" in message and "NaN" in message
    t = float(message.split("at t = ")[1].split(" s")[0])
    assert t == pytest.approx(math.sqrt(2 * 0.1 * 2 / 1), rel=1e-3)  # x = t^2 / 4 reaches 0.1 m


def test_nan_exits_3_on_the_command_line(tmp_path):
    import subprocess
    import sys

    model = tmp_path / "nan.mbs"
    model.write_text(FREE_MASS.format(load="fx = 1 N + 1 N/m^0.5 * sqrt(0.1 m - mass.x) * 0"))
    p = subprocess.run([MBS, "run", str(model), "-o",
                        str(tmp_path / "r.h5")], capture_output=True, text=True)
    assert p.returncode == 3, p.stderr
    assert "force `push`" in p.stderr + p.stdout


def test_model_errors_exit_2_with_the_position(tmp_path):
    import subprocess
    import sys

    model = tmp_path / "bad.mbs"
    model.write_text(FREE_MASS.format(load="fx = F0 * mass.vx"))
    p = subprocess.run([MBS, "check", str(model)],
                       capture_output=True, text=True)
    assert p.returncode == 2
    assert f"{model}:5:" in p.stderr + p.stdout


def test_the_knots_of_a_table_are_located_as_events():
    """A force linear in t between knots (a kink at each): v and x are its exact piecewise integrals;
    the knots are events, so no step is rejected more than under a smooth force."""
    knots, values = [0.0, 0.3, 0.6, 1.0], [0.0, 2.0, -1.0, 1.0]
    load = ("table(x = t, xs = (" + ", ".join(f"{k} s" for k in knots) + "), ys = ("
            + ", ".join(f"{v} N" for v in values) + "))")
    res = mbs.simulate(mbs.compile_text(BANG.format(load=load)))
    smooth = mbs.simulate(mbs.compile_text(BANG.format(load="2 N * sin(6 rad/s * t)")))
    t = res.time
    v = np.zeros_like(t)
    x = np.zeros_like(t)
    v0 = x0 = 0.0
    for (ta, tb), (fa, fb) in zip(zip(knots, knots[1:]), zip(values, values[1:])):
        s = np.clip(t - ta, 0, tb - ta)  # time spent in this piece; F = fa + (fb - fa) s / (tb - ta)
        slope = (fb - fa) / (tb - ta)
        inside = (t > ta)
        v += np.where(inside, fa * s + slope * s**2 / 2, 0)
        x += np.where(inside, v0 * s + fa * s**2 / 2 + slope * s**3 / 6, 0)
        h = tb - ta
        x0 += v0 * h + fa * h**2 / 2 + slope * h**3 / 6
        v0 += fa * h + slope * h**2 / 2
    np.testing.assert_allclose(res["mass.vx"], v, rtol=0, atol=1e-10)
    np.testing.assert_allclose(res["mass.x"], x, rtol=0, atol=1e-10)
    assert res.attrs["n_rejected"] <= smooth.attrs["n_rejected"]


def test_t_is_time_not_a_unit_and_comparisons_need_units():
    m = mbs.compile_text(FREE_MASS.format(load="fx = F0 * sin(20 Hz*t)"))  # Hz*t is not `Hz` times tonnes
    assert m.kernel.expr_code.shape[0] > 0
    err = _error(FREE_MASS.format(load="fx = if(mass.vx < 0, F0, 0 N)"))
    assert "cannot compare a plain number and a velocity" in err.message and "0 m/s" in err.hint
    err = _error(FREE_MASS.format(load="fx = if(mass.vx < 0 m/s, F0, 0 N*m)"))
    assert "cannot choose between a force and a torque" in err.message


def test_set_load_refuses_an_expression_force():
    sim = mbs.Simulation(mbs.compile_text(FREE_MASS.format(load="fx = F0")))
    with pytest.raises(ModelError, match="expression force"):
        sim.set_load("push", 1.0)


def test_an_actuator_expression_equals_the_same_force_as_an_expression_load():
    """A spring-damper from a ground point on +x pulls the mass towards it: its actuator tension
    F0 sin(w t) is the force fx = F0 sin(w t) on the mass (the mass stays left of the anchor)."""
    spring = "force s = spring_damper(ground (5, 0), mass) {{ stiffness = 4 N/m  length = 5 m{act} }}"
    a = FREE_MASS.format(load="fx = F0 * sin(w * t)") + spring.format(act="")
    b = FREE_MASS.format(load="fx = 0 N") + spring.format(act="  actuator = F0 * sin(w * t)")
    ra, rb = (mbs.simulate(mbs.compile_text(text)) for text in (a, b))
    np.testing.assert_allclose(rb["mass.x"], ra["mass.x"], rtol=1e-12, atol=1e-14)
    assert np.ptp(ra["mass.x"]) > 0.01
    sim = mbs.Simulation(mbs.compile_text(b))
    with pytest.raises(ModelError, match="actuator of `s` is an expression"):
        sim.set_load("s", 1.0)


KINKED_CART = """
body cart {{ mass = 1 kg  inertia = 0.01 kg*m^2  position = (0.1, 0) }}
body bob  {{ mass = 0.5 kg  inertia = 0.001 kg*m^2  position = (0.1, -0.3) }}
joint rail = translational(ground, cart, axis = (1, 0))
joint pin  = revolute(cart (0, 0), bob (0, 0.3))
driver g = translation(cart, axis = (1, 0), motion = 0.1 m + {motion})
simulate {{ t_end = 0.05 s  output_step = 1 ms {extra} }}
"""


@pytest.mark.parametrize("projection", ["", "projection = on"])
def test_a_kink_in_a_motion_is_an_impulse(projection):
    """A cart at rest, then driven at 0.1 m/s from t = 10 ms (a kink: an infinite acceleration), with a
    pendulum hanging from it (no gravity).  At the kink the cart's velocity jumps; the pin's impulse P on
    the bob gives m dv = P, I dw = r x P with the pin's velocity the cart's: dv_bob = 0.1 m/s /
    (1 + m r^2 / I), w0 = -r m dv_bob / I (r = 0.3 m).  Then, in the cart's frame (inertial again), the
    bob turns about the pin at w0 with no torque: its vx is 0.1 m/s + r w0 cos(w0 (t - 10 ms)).  By
    default the run follows the motion exactly and says where it jumped; it used to step over the kink
    and lag 1.7 mm behind the motion until the drift check."""
    res = mbs.simulate(mbs.compile_text(KINKED_CART.format(motion="0.1 m/s * max(t - 10 ms, 0 s)",
                                                           extra=projection)))
    t = res.time
    assert np.abs(res["cart.x"] - (0.1 + 0.1 * np.maximum(t - 0.01, 0.0))).max() < 1e-9
    m, inertia, r = 0.5, 0.001, 0.3
    w0 = -r * m * (0.1 / (1 + m * r * r / inertia)) / inertia
    after = t > 0.01
    assert np.allclose(res["bob.omega"][after], w0, rtol=1e-6)
    assert np.allclose(res["bob.vx"][after], 0.1 + r * w0 * np.cos(w0 * (t[after] - 0.01)), rtol=1e-6, atol=1e-9)
    assert np.all(res["bob.vx"][t <= 0.01] == 0.0)
    jumped = [w for w in res.attrs["warnings"] if "motion jumps" in w]
    if projection:
        assert jumped == []  # projected after every step anyway
    else:
        assert len(jumped) == 1 and "t = 0.01 s" in jumped[0] and "driver `g`" in jumped[0]


@pytest.mark.parametrize("settings, error", [("", 1e-8), ("rtol = 1e-10  atol = 1e-13", 1e-9)])
def test_a_smooth_switch_of_a_motion_projects_nothing(settings, error):
    """A motion whose second derivative jumps (0.5 a t^2 from 10 ms) is followed without projection: the
    state is on the new motion at the switch, and the run says nothing of a jump; with the default
    tolerances (atol 1e-9) and tight ones."""
    res = mbs.simulate(mbs.compile_text(KINKED_CART.format(motion="0.5 m/s^2 * max(t - 10 ms, 0 s)^2",
                                                           extra=settings)))
    t = res.time
    assert np.abs(res["cart.x"] - (0.1 + 0.5 * np.maximum(t - 0.01, 0.0) ** 2)).max() < error
    assert not any("jumps" in w or "projected" in w for w in res.attrs["warnings"]), res.attrs["warnings"]


def test_a_load_switch_hides_no_drift():
    """The motor-driven slider-crank (a torque table of the flywheel's speed: a switch at every knot)
    by RK4 at 20 us drifts off its constraints and the drift check stops it; a switch of the load must
    not take that drift for a jumping motion and project it away (it did, at six knots)."""
    model = mbs.load_model(Path(__file__).resolve().parents[1] / "models" / "slider_crank_motor.mbs")
    with pytest.raises(SimulationError, match="drifted beyond"):
        mbs.simulate(model, t_end="50 ms", integrator="rk4", step="20 us")
