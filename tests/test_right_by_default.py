"""Right by default: mechanisms written as a new user would (no `projection` line, the model's
defaults), each against a reference derived here and independent of the solver: the reduced
(minimal) coordinates of the mechanism integrated by scipy at rtol 1e-13, or its energy equation.

Singular positions (a parallelogram whose bars line up, an isosceles slider-crank folding), redundant
joints and a light cart under a heavy pendulum; a driver pushed past a limit position and a fixed
RK4 step too long for a passage stop with exit 3 instead of going on wrong.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from typer.testing import CliRunner

import chains
import planar_mbs as mbs
from planar_mbs.cli.app import app
from planar_mbs.mechanism.compile import compile_text

MODELS = Path(__file__).resolve().parents[1] / "models"
G = 9.81
runner = CliRunner()


def simulate(text, name="m.mbs"):
    """Run a model with its defaults; it must finish."""
    assert "projection" not in text
    res = mbs.simulate(compile_text(text, name))
    assert res.attrs["complete"], res.attrs["message"]
    return res


def reduced(rhs, y0, t):
    """Reference: the reduced equations integrated by scipy (DOP853, rtol 1e-13)."""
    sol = solve_ivp(rhs, (0.0, float(t[-1])), y0, t_eval=t, method="DOP853", rtol=1e-13, atol=1e-13)
    assert sol.success
    return sol.y


def crank_tip(res, crank="crank0"):
    phi = res[f"{crank}.phi"]
    return np.stack([res[f"{crank}.x"] + 0.5 * np.cos(phi), res[f"{crank}.y"] + 0.5 * np.sin(phi)])


def tip_error(res, theta):
    return float(np.max(np.hypot(*(crank_tip(res) - np.stack([np.cos(theta), np.sin(theta)])))))


def one_dof(inertia, torque):
    """theta'' = torque(theta, theta') / inertia: the reduced equation of a one-degree-of-freedom chain."""
    return lambda t, y: [y[1], torque(y[0], y[1]) / inertia]


# ---------------------------------------------------------------- regular, but badly scaled
CARTPOLE = """
body cart { mass = 1e-6 kg  inertia = 1e-6 kg*m^2  position = (0, 0) }
body tip { mass = 1 kg  inertia = 1e-6 kg*m^2  position = (0.8660254037844386 m, -0.5 m) }
joint rail = translational(ground (0, 0), cart (0, 0), axis = (1, 0))
joint pole = revolute_revolute(cart (0, 0), tip (0, 0)) { length = 1 m }
gravity (0, -9.81 m/s^2)
simulate { t_end = 2 s  integrator = dop853  rtol = 1e-12  atol = 1e-14  output_step = 0.01 s }
"""


def test_light_cart_pendulum_is_exact_whatever_the_mass_ratio():
    """IFToMM's light-cart cart-pole: 1e-6 kg cart, 1 kg tip, massless 1 m pole (a distance joint).
    Its Schur pivots are 1e-6 of the diagonal because of the mass ratio, not a singularity: the
    solve must be as exact as a plain factorisation (two regularised sweeps left 3e-2 rad here)."""
    res = simulate(CARTPOLE, "cartpole.mbs")
    mc, mt = 1e-6, 1.0

    def rhs(_, s):
        x, th, xd, thd = s
        a = np.linalg.solve([[mc + mt, mt * math.cos(th)], [mt * math.cos(th), mt]],
                            [mt * math.sin(th) * thd ** 2, -mt * G * math.sin(th)])
        return [xd, thd, a[0], a[1]]

    x, th, _, _ = reduced(rhs, [0.0, math.radians(60), 0.0, 0.0], res.time)
    angle = np.arctan2(res["tip.x"] - res["cart.x"], res["cart.y"] - res["tip.y"])
    assert np.abs(angle - th).max() <= 1e-8
    assert np.abs(res["cart.x"] - x).max() <= 1e-8


# ---------------------------------------------------------------- parallelogram chains
def test_iftomm_chain_keeps_its_branch_and_energy_by_default():
    N = 2
    res = simulate(chains.parallelogram_chain(N, integrator="dop853", rtol=1e-12, atol=1e-14), "chain2.mbs")
    theta, _ = chains.crank_angle_reference(N, res.time)
    assert math.pi / 2 - theta[-1] > 20 * math.pi  # twenty singular positions and more
    assert tip_error(res, theta) <= 1e-8
    E = res["system.total_energy"]
    assert np.abs(E - E[0]).max() <= 1e-8 * abs(E[0])
    assert any("projection = auto" in w for w in res.attrs["warnings"])  # said, with its time


def test_iftomm_chain_with_no_solver_setting_at_all():
    """The same chain with nothing but its duration and samples in `simulate` (the default method and
    tolerances, rtol 1e-6): still on its branch through twenty passages (the old code ended on another
    one, 0.94 m off) and its energy within a thousand rtol.  The position bound is the branch's, a hundredth
    of a link: the default tolerance's phase error over 64 rad of crank travel is millimetres (2.6 mm
    measured); the 1e-8 m claims are the rtol 1e-12 tests above."""
    N = 2
    text = chains.parallelogram_chain(N).split("simulate {")[0] + "simulate { t_end = 20 s  output_step = 0.01 s }\n"
    assert "rtol" not in text and "integrator" not in text
    res = simulate(text, "chain2_defaults.mbs")
    rtol, L = 1e-6, 1.0  # the language's default rtol (docs/language.md), the links' length
    theta, _ = chains.crank_angle_reference(N, res.time)
    assert math.pi / 2 - theta[-1] > 20 * math.pi
    assert tip_error(res, theta) <= 1e-2 * L
    E = res["system.total_energy"]
    assert np.abs(E - E[0]).max() <= 1e3 * rtol * abs(E[0])


@pytest.mark.slow
def test_iftomm_chain_of_forty_keeps_its_branch_by_default():
    N = 40
    res = simulate(chains.parallelogram_chain(N, integrator="dop853", rtol=1e-12, atol=1e-14, t_end=10.0),
                   "chain40.mbs")
    theta, _ = chains.crank_angle_reference(N, res.time)
    assert tip_error(res, theta) <= 1e-6


def test_shipped_parallelogram_chain_without_its_projection_line(tmp_path):
    text = (MODELS / "parallelogram_chain.mbs").read_text()
    assert " projection = on" in text
    path = tmp_path / "chain.mbs"
    path.write_text(text.replace(" projection = on", "").replace("t_end = 20.0 s", "t_end = 8 s"))
    res = runner.invoke(app, ["run", str(path), "-o", str(tmp_path / "c.h5")])
    assert res.exit_code == 0, res.output
    out = mbs.read_results(tmp_path / "c.h5")
    theta, _ = chains.crank_angle_reference(3, out.time)
    assert tip_error(out, theta) <= 1e-8
    E = out["system.total_energy"]
    assert np.abs(E - E[0]).max() <= 1e-8 * abs(E[0])


def _single(extra="", speed=1.0, angle=90.0, t_end=10.0):
    """The N = 1 parallelogram of `chains` (crank0 at the origin, crank1 at (1, 0), coupler0),
    started at crank angle `angle` (deg) turning at -speed rad/s, with `extra` lines."""
    a = math.radians(angle)
    c, s = math.cos(a), math.sin(a)
    w = -speed
    v = (-s * w, c * w)
    lines = ["param L = 1 m\nparam m = 1 kg\n"]
    for i in range(2):
        lines.append(f"body crank{i} {{ mass = m  inertia = m*L^2/12  position = ({i + 0.5 * c!r} m, {0.5 * s!r} m)  "
                     f"angle = {angle!r} deg  velocity = ({0.5 * v[0]!r} m/s, {0.5 * v[1]!r} m/s)  omega = {w!r} rad/s }}\n")
    lines.append(f"body coupler0 {{ mass = m  inertia = m*L^2/12  position = ({0.5 + c!r} m, {s!r} m)  "
                 f"velocity = ({v[0]!r} m/s, {v[1]!r} m/s) }}\n")
    lines.append("joint O0 = revolute(ground (0, 0), crank0 (-L/2, 0))\n"
                 "joint O1 = revolute(ground (1 m, 0), crank1 (-L/2, 0))\n"
                 "joint A0 = revolute(crank0 (L/2, 0), coupler0 (-L/2, 0))\n"
                 "joint B0 = revolute(coupler0 (L/2, 0), crank1 (L/2, 0))\n")
    lines.append(extra)
    lines.append("gravity (0, -9.81 m/s^2)\n")
    lines.append(f"simulate {{ t_end = {t_end} s  integrator = dop853  rtol = 1e-12  atol = 1e-14  output_step = 0.01 s }}\n")
    return "".join(lines)


# two cranks (m L^2 / 3 about their pins) and a translating coupler (m L^2): 5/3; gravity 2 m g L cos
INERTIA1 = 2 / 3 + 1


def test_damped_parallelogram_matches_its_reduced_equation():
    c = 0.1  # N*m*s/rad on the first crank: it goes over the top a few times, then swings through both
    res = simulate(_single("force D = rotational_spring_damper(ground, crank0) { damping = 0.1 N*m*s/rad }\n"),
                   "damped.mbs")
    th, _ = reduced(one_dof(INERTIA1, lambda q, qd: -2 * G * math.cos(q) - c * qd), [math.pi / 2, -1.0], res.time)
    passes = np.count_nonzero(np.diff(np.floor(th / math.pi)))
    assert passes >= 8  # singular positions: horizontal bars
    assert tip_error(res, th) <= 1e-8


def test_parallelogram_turning_back_just_short_of_its_singular_position():
    """Rising from the bottom with the energy to reach 1e-6 rad below the horizontal (the singular
    position), over and over: it must turn back there, not cross onto another branch."""
    margin = 1e-6
    w0 = math.sqrt(2 * 2 * G * (math.sin(-margin) + 1) / INERTIA1)
    res = simulate(_single(speed=-w0, angle=-90.0, t_end=6.0), "short.mbs")
    th, _ = reduced(one_dof(INERTIA1, lambda q, qd: -2 * G * math.cos(q)), [-math.pi / 2, w0], res.time)
    assert th.max() < 0 and th.max() > -1e-5
    assert tip_error(res, th) <= 1e-8
    assert np.abs(res["coupler0.phi"]).max() < 1e-9  # the coupler never turns: no other branch


def test_redundant_double_parallelogram_keeps_its_energy():
    """One 2 m coupler on three cranks (the middle crank is redundant: rank lost for good)."""
    L = "param L = 1 m\nparam m = 1 kg\n"
    bodies = "".join(f"body crank{i} {{ mass = m  inertia = m*L^2/12  position = ({i} m, L/2)  angle = 90 deg  "
                     "velocity = (0.5 m/s, 0 m/s)  omega = -1 rad/s }\n" for i in range(3))
    bodies += ("body coupler { mass = 2 kg  inertia = 2 kg*(2 m)^2/12  position = (1 m, L)  "
               "velocity = (1 m/s, 0 m/s) }\n")
    joints = "".join(f"joint O{i} = revolute(ground ({i} m, 0), crank{i} (-L/2, 0))\n"
                     f"joint A{i} = revolute(crank{i} (L/2, 0), coupler ({i - 1} m, 0))\n" for i in range(3))
    text = (L + bodies + joints + "gravity (0, -9.81 m/s^2)\n"
            "simulate { t_end = 10 s  integrator = dop853  rtol = 1e-12  atol = 1e-14  output_step = 0.01 s }\n")
    res = simulate(text, "double.mbs")
    inertia = 3 / 3 + 2  # three cranks about their pins, a 2 kg coupler translating
    torque = -(3 * 0.5 + 2) * G  # times cos(theta)
    th, _ = reduced(one_dof(inertia, lambda q, qd: torque * math.cos(q)), [math.pi / 2, -1.0], res.time)
    assert math.pi / 2 - th[-1] > 10 * math.pi
    assert tip_error(res, th) <= 1e-8
    E = res["system.total_energy"]
    assert np.abs(E - E[0]).max() <= 1e-8 * abs(E[0])


def test_parallelogram_with_a_spring_loaded_slider_on_its_coupler():
    """Two degrees of freedom: crank angle theta and the slider's place s along the coupler."""
    ms, k, l0, s0 = 0.5, 50.0, 2.1, 0.1  # the spring's anchor 2 m behind the coupler's centre: l = s + 2 > 0
    extra = (f"body slider {{ mass = {ms} kg  inertia = 0.01 kg*m^2  position = ({0.5 + s0} m, 1 m)  "
             "velocity = (1 m/s, 0 m/s) }\n"
             "joint S = translational(coupler0 (0, 0), slider (0, 0), axis = (1, 0))\n"
             f"force K = spring_damper(coupler0 (-2 m, 0), slider (0, 0)) {{ stiffness = {k} N/m  length = {l0} m }}\n")
    res = simulate(_single(extra, t_end=8.0), "slider.mbs")
    I1 = INERTIA1

    def rhs(_, y):
        th, s, thd, sd = y
        M = [[I1 + ms, -ms * math.sin(th)], [-ms * math.sin(th), ms]]
        f = [-(2 + ms) * G * math.cos(th), ms * math.cos(th) * thd ** 2 - k * (s + 2 - l0)]
        a = np.linalg.solve(M, f)
        return [thd, sd, a[0], a[1]]

    th, s, _, _ = reduced(rhs, [math.pi / 2, s0, -1.0, 0.0], res.time)
    assert np.count_nonzero(np.diff(np.floor(th / math.pi))) >= 4  # singular positions passed
    assert tip_error(res, th) <= 1e-8
    assert np.abs(res["slider.x"] - (0.5 + np.cos(th) + s)).max() <= 1e-8
    assert np.abs(s).max() < 1.5
    E = res["system.total_energy"]
    assert np.abs(E - E[0]).max() <= 1e-8 * abs(E[0])


def test_isosceles_slider_crank_with_a_flywheel():
    """Crank and rod of equal length r: at theta = 90 deg they fold onto each other (the slider at
    the pin), where the slider could stay; the flywheel carries it through.  No gravity: the
    energy equation gives theta' = sqrt(2 E / I(theta))."""
    r, J, mr, Ir, msl, w0 = 0.1, 0.05, 0.2, 0.2 * 0.01 / 12, 0.3, 20.0
    text = f"""
body crank {{ mass = 1 kg  inertia = {J} kg*m^2  position = (0, 0)  omega = {w0} rad/s }}
body rod {{ mass = {mr} kg  inertia = {Ir!r} kg*m^2  position = ({1.5 * r} m, 0)  velocity = (0, {0.5 * r * w0} m/s)
           omega = {-w0} rad/s }}
body slider {{ mass = {msl} kg  inertia = 1e-4 kg*m^2  position = ({2 * r} m, 0) }}
joint O = revolute(ground (0, 0), crank (0, 0))
joint A = revolute(crank ({r} m, 0), rod ({-r / 2} m, 0))
joint B = revolute(rod ({r / 2} m, 0), slider (0, 0))
joint S = translational(ground (0, 0), slider (0, 0), axis = (1, 0))
simulate {{ t_end = 2 s  integrator = dop853  rtol = 1e-12  atol = 1e-14  output_step = 0.002 s }}
"""
    res = simulate(text, "isosceles.mbs")

    def inertia(th):
        s, c = math.sin(th), math.cos(th)
        return J + mr * r * r * (2.25 * s * s + 0.25 * c * c) + Ir + msl * 4 * r * r * s * s

    E = 0.5 * inertia(0.0) * w0 ** 2
    th = reduced(lambda t, y: [math.sqrt(2 * E / inertia(y[0]))], [0.0], res.time)[0]
    assert th[-1] > 10 * math.pi  # twenty foldings
    assert np.abs(res["slider.x"] - 2 * r * np.cos(th)).max() <= 1e-8
    pin = np.stack([res["rod.x"] - 0.5 * r * np.cos(res["rod.phi"]), res["rod.y"] - 0.5 * r * np.sin(res["rod.phi"])])
    assert np.hypot(*(pin - r * np.stack([np.cos(th), np.sin(th)]))).max() <= 1e-8
    Et = res["system.total_energy"]
    assert np.abs(Et - Et[0]).max() <= 1e-8 * Et[0]



def test_samples_near_a_passage_are_as_accurate_as_the_steps():
    """Output samples inside a step across a singular position came from a dense output no error
    estimate controls (DOP853: crank rate 2.6e-5 rad/s off at rtol 1e-9); the step after a regularised
    one now ends on the next output time.  Reference: the energy equation's rate."""
    N = 2
    text = chains.parallelogram_chain(N, integrator="dop853", rtol=1e-9, atol=1e-11, t_end=10.0, output_step=0.001)
    res = simulate(text, "dense.mbs")
    th, _ = chains.crank_angle_reference(N, res.time)
    k = (2 * G) * ((N + 1) / 2 + N) / ((N + 1) / 3 + N)
    rate = -np.sqrt(1 + k * (1 - np.sin(th)))
    assert np.abs(np.angle(np.exp(1j * (res["crank0.phi"] - th)))).max() <= 1e-6
    assert np.abs(res["crank0.omega"] - rate).max() <= 1e-6

# ---------------------------------------------------------------- no silent wrong answer
def _rocker_limits(a, b, c, d):
    """Rocker angles (from +x at its ground pin (d, 0)) at the two limit positions of a crank-rocker."""
    return [math.acos((rr * rr - d * d - c * c) / (2 * d * c)) for rr in (a + b, b - a)]


def test_driver_past_a_limit_position_stops_with_exit_3(tmp_path):
    """The rocker of a crank-rocker driven 0.001 deg past its limit position: no pose exists there.
    The run must stop naming the time and the joint (it used to finish with joints 8 mm open)."""
    a, b, c, d = 0.1, 0.35, 0.3, 0.4
    lo, hi = _rocker_limits(a, b, c, d)
    mid, amp = 0.5 * (lo + hi), 0.5 * (hi - lo) + math.radians(0.001)
    Bx, By = d + c * math.cos(mid), c * math.sin(mid)
    # the crank's pin A: on the circle of radius a about the origin, at distance b from B (upper branch)
    rB = math.hypot(Bx, By)
    ang = math.atan2(By, Bx) - math.acos((a * a + rB * rB - b * b) / (2 * a * rB))
    Ax, Ay = a * math.cos(ang), a * math.sin(ang)
    text = f"""
body crank {{ mass = 0.2 kg  inertia = 2e-4 kg*m^2  position = ({Ax / 2!r} m, {Ay / 2!r} m)  angle = {math.degrees(ang)!r} deg }}
body coupler {{ mass = 0.5 kg  inertia = 5e-3 kg*m^2  position = ({(Ax + Bx) / 2!r} m, {(Ay + By) / 2!r} m)
               angle = {math.degrees(math.atan2(By - Ay, Bx - Ax))!r} deg }}
body rocker {{ mass = 0.4 kg  inertia = 3e-3 kg*m^2  position = ({(d + Bx) / 2!r} m, {By / 2!r} m)  angle = {math.degrees(mid)!r} deg }}
joint O2 = revolute(ground (0, 0), crank ({-a / 2} m, 0))
joint A = revolute(crank ({a / 2} m, 0), coupler ({-b / 2} m, 0))
joint B = revolute(coupler ({b / 2} m, 0), rocker ({c / 2} m, 0))
joint O4 = revolute(ground ({d} m, 0), rocker ({-c / 2} m, 0))
driver swing = rotation(rocker, harmonic(amplitude = {math.degrees(amp)!r} deg, frequency = 1 Hz))
simulate {{ t_end = 2 s  output_step = 1 ms }}
"""
    path = tmp_path / "overshoot.mbs"
    path.write_text(text)
    res = runner.invoke(app, ["run", str(path), "-o", str(tmp_path / "o.h5")])
    assert res.exit_code == 3, res.output
    out = " ".join(res.output.split())
    assert "at t = " in out and ("joint `" in out or "driver `" in out)
    t = float(out.split("at t = ")[1].split()[0])
    assert 0.2 < t < 0.3  # the first limit position: sin(2 pi t) = 1 at t = 0.25 s


def test_rk4_step_too_long_for_a_passage_stops_with_exit_3(tmp_path):
    """RK4 at 1 ms through the singular positions of a damped parallelogram (with projection the old
    code went on with exit 0 and ended 7.2e-7 m off, at rtol 1e-12): stop, or be right."""
    c = 0.1
    damper = "force D = rotational_spring_damper(ground, crank0) { damping = 0.1 N*m*s/rad }\n"
    text = _single(damper, t_end=10.0).replace("integrator = dop853", "integrator = rk4  step = 1 ms")
    path = tmp_path / "rk4.mbs"
    path.write_text(text)
    res = runner.invoke(app, ["run", str(path), "-o", str(tmp_path / "r.h5")])
    if res.exit_code == 0:  # or correct
        out = mbs.read_results(tmp_path / "r.h5")
        th, _ = reduced(one_dof(INERTIA1, lambda q, qd: -2 * G * math.cos(q) - c * qd), [math.pi / 2, -1.0],
                        out.time)
        assert tip_error(out, th) <= 1e-8  # with projection = on the old code ended 7.2e-7 m off
    else:
        assert res.exit_code == 3, res.output
        out = " ".join(res.output.split())
        assert "singular position" in out and "at t = " in out


# ---------------------------------------------------------------- mbs check
@pytest.mark.parametrize("name", ["slider_crank_clearance_a.mbs", "slider_crank_clearance_ab.mbs",
                                  "four_bar_two_clearances.mbs"])
def test_check_counts_clearance_joints_as_forces(name):
    """A clearance joint's rows are forces, not constraints: `mbs check` gives the Python API's count
    (every body's 3 coordinates less the ideal joints' and drivers' rows, all independent here)."""
    model = mbs.load_model(MODELS / name)
    res = runner.invoke(app, ["check", str(MODELS / name)])
    assert res.exit_code == 0, res.output
    first = " ".join(res.output.split("\n")[0].split())
    assert f"{model.nconstraint} constraints, {model.dof} degree" in first, first
    assert model.dof == 3 * model.nbody - model.nconstraint > 0 and "(rank" not in first


def test_check_says_a_singular_initial_pose_is_one(tmp_path):
    """A parallelogram assembled with its bars in line: the rank is lost at that pose only; no
    joint is redundant and the mechanism has one degree of freedom."""
    text = chains.parallelogram_chain(1, t_end=0.5)
    text = (text.replace("position = (0 m, L/2)  angle = 90 deg", "position = (0.5 m, 0 m)  angle = 0 deg")
            .replace("position = (1 m, L/2)  angle = 90 deg", "position = (1.5 m, 0 m)  angle = 0 deg")
            .replace("position = (0.5 m, L)", "position = (1.5 m, 0 m)"))
    path = tmp_path / "flat.mbs"
    path.write_text(text)
    res = runner.invoke(app, ["check", str(path)])
    assert res.exit_code == 0, res.output
    out = " ".join(res.output.split())
    assert "1 degree of freedom" in out and "singular position" in out and "redundant at the initial pose" not in out


@pytest.mark.parametrize("step, warned", [("0.15 s", True), ("1 ms", False)])
def test_energy_drift_of_a_workless_mechanism_is_reported(step, warned):
    """A mass on an undamped spring (omega = 10 rad/s) by RK4: at h omega = 1.5 the scheme loses
    energy each step (conservation is the reference); the run says so, and not at a fine step."""
    text = ("body bob { mass = 1 kg  inertia = 1e-3 kg*m^2  position = (0.1, 0) }\n"
            "force spring = spring_damper(ground (-1, 0), bob (0, 0)) { stiffness = 100 N/m  length = 1 m }\n"
            f"simulate {{ t_end = 6 s  integrator = rk4  step = {step}  output_step = 0.15 s }}\n")
    res = simulate(text, "spring.mbs")
    E = res["system.total_energy"]
    assert (abs(E[-1] - E[0]) > 1e-3 * E[0]) == warned
    assert any("total energy" in w for w in res.attrs["warnings"]) == warned


@pytest.mark.parametrize("load", ["force push = expression(bob, fx = 1 N)",
                                  "force push = expression(bob, torque = 0.01 N*m)",
                                  "force strut = spring_damper(ground (0, 0), bob (0, 0)) { actuator = 0.5 N*(1 + t/1 s) }"])
def test_a_load_that_does_work_is_no_energy_drift(load):
    """The mass on its spring, pushed by a load without a potential (an expression, an actuator given
    by an expression): its energy grows by the work done, which is no fault of the integration."""
    text = ("body bob { mass = 1 kg  inertia = 1e-3 kg*m^2  position = (0.1, 0) }\n"
            "force spring = spring_damper(ground (-1, 0), bob (0, 0)) { stiffness = 100 N/m  length = 1 m }\n"
            f"{load}\nsimulate {{ t_end = 2 s  output_step = 10 ms }}\n")
    res = simulate(text, "pushed.mbs")
    E = res["system.total_energy"]
    assert abs(E[-1] - E[0]) > 1e-3 * abs(E).max()  # the load did work
    assert not any("total energy" in w for w in res.attrs["warnings"]), res.attrs["warnings"]


def test_driven_crank_rocker_next_to_a_change_point():
    """A crank-rocker 0.1 µm from a change-point linkage (a + d = b + c): once a turn, with the crank
    pointing away from the rocker's pivot, coupler and rocker lie almost in line and the two
    assemblies come within 1e-4 m of each other.  Driven, it has no freedom: the rocker's pin is the
    intersection of two circles, on the side it started (position analysis in closed form)."""
    a, b, c, d = 0.1, 0.25, 0.2, 0.35 - 1e-7
    w = 2 * math.pi

    def pin_b(th, side):
        A = np.array([a * np.cos(th), a * np.sin(th)])
        O4 = np.array([d, 0.0])
        u = O4[:, None] - A
        r = np.hypot(*u)
        along = (b * b - c * c + r * r) / (2 * r)
        h = np.sqrt(np.maximum(b * b - along * along, 0.0))
        e = u / r
        return A + along * e + side * h * np.array([-e[1], e[0]])

    th0 = 0.0
    B = [float(x) for x in pin_b(np.array([th0]), 1.0)[:, 0]]
    A = [a, 0.0]
    cpl = math.atan2(B[1] - A[1], B[0] - A[0])
    rck = math.atan2(B[1], B[0] - d)
    text = f"""
body crank {{ mass = 0.2 kg  inertia = 2e-4 kg*m^2  position = ({a / 2} m, 0)  angle = 0 deg }}
body coupler {{ mass = 0.5 kg  inertia = 3e-3 kg*m^2  position = ({(A[0] + B[0]) / 2!r} m, {(A[1] + B[1]) / 2!r} m)
               angle = {math.degrees(cpl)!r} deg }}
body rocker {{ mass = 0.4 kg  inertia = 1.5e-3 kg*m^2  position = ({(d + B[0]) / 2!r} m, {B[1] / 2!r} m)  angle = {math.degrees(rck)!r} deg }}
joint O2 = revolute(ground (0, 0), crank ({-a / 2} m, 0))
joint A = revolute(crank ({a / 2} m, 0), coupler ({-b / 2} m, 0))
joint B = revolute(coupler ({b / 2} m, 0), rocker ({c / 2} m, 0))
joint O4 = revolute(ground ({d!r} m, 0), rocker ({-c / 2} m, 0))
driver motor = rotation(crank, speed = 60 rpm)
gravity (0, -9.81 m/s^2)
simulate {{ t_end = 3 s  integrator = dop853  rtol = 1e-12  atol = 1e-14  output_step = 1 ms }}
"""
    res = simulate(text, "change_point.mbs")
    th = th0 + w * res.time
    exact = pin_b(th, 1.0)
    phi = res["rocker.phi"]
    pin = np.stack([res["rocker.x"] + 0.5 * c * np.cos(phi), res["rocker.y"] + 0.5 * c * np.sin(phi)])
    assert np.hypot(*(pin - exact)).max() <= 1e-8
    other = pin_b(th, -1.0)
    assert np.hypot(*(exact - other)).min() < 1e-3  # it does come close to the other assembly
