"""Static equilibrium and modes (`run/static.py`, `run/modes.py`) against closed forms derived here:
a journal resting on its bearing, a pendulum, a chain of masses and springs, a damped oscillator, a
four-bar held by a spring (the energy method), and the state matrix against its analytic Jacobian."""
from __future__ import annotations

import math

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.run import static

G = 9.81
EPS = np.finfo(float).eps

JOURNAL = """
param K = {K} N/m^{n}
body journal {{ mass = {m} kg  inertia = 1e-4 kg*m^2 }}
joint slide = translational(ground, journal, axis = (0, 1))
joint J = clearance_revolute(ground (0, 0), journal (0, 0)) {{
    clearance = 0.1 mm  bearing_radius = 5 mm  law = hertz  stiffness = K  exponent = {n} }}
gravity (0, -{g} m/s^2)
"""


def journal(K=1e9, m=0.5, n=1.5):
    return mbs.compile_text(JOURNAL.format(K=K, m=m, n=n, g=G), path="journal.mbs")


@pytest.mark.parametrize("n", [1.5, 1.0, 2.2])
def test_a_journal_rests_at_the_closed_form_penetration_and_vibrates_at_its_linear_frequency(n):
    """Under its weight W = m g a journal on a vertical slide sinks into its bearing until K d^n = W:
    d0 = (W/K)^(1/n); about there its stiffness is dF/dd = n K d0^(n-1), so w = sqrt(n K d0^(n-1) / m).
    The step rule's truncation error of the stiffness is (h/d0)^2 |(n-1)(n-2)|/6 with h = (eps L d0^2)^(1/3),
    and its rounding eps L / h: about 1e-7 here, so the frequency is held to 1e-6."""
    K, m = 1e9, 0.5
    model = journal(K, m, n)
    eq = mbs.equilibrium(model)
    d0 = (m * G / K) ** (1.0 / n)
    assert -eq.gaps[0] == pytest.approx(d0, rel=1e-9)
    assert eq.q[1] == pytest.approx(-(1e-4 + d0), rel=1e-12)
    assert eq.stable()
    # the slide carries no vertical load: the contact holds the weight
    (name, body, f), = eq.reactions()
    assert (name, body) == ("slide", "journal") and abs(f[1]) < 1e-9 * m * G
    lin = mbs.linearize(model, eq)
    (mode,) = lin.modes()
    w = math.sqrt(n * K * d0 ** (n - 1) / m)
    assert mode.kind == "oscillating"
    assert mode.omega == pytest.approx(w, rel=1e-6)
    assert abs(mode.damping_ratio) < 1e-8
    assert np.allclose(mode.shape, [0, 1, 0], atol=1e-12)


PENDULUM = """
body bob {{ mass = {m} kg  inertia = {I} kg*m^2  position = (0.3, -0.1)  angle = 0.4 }}
joint pin = revolute(ground (0, 0), bob ({sx}, {sy}))
gravity (0, -{g} m/s^2)
"""


def test_a_pendulum_hangs_below_its_pin_and_swings_at_the_compound_pendulum_frequency():
    """Body point s = (sx, sy) pinned at the origin: at rest the centre of mass hangs below the pin at
    distance L = |s|; w^2 = m g L / (I + m L^2); the mode moves the centre of mass along the circle,
    d(x, y) = dphi (L, 0) at the bottom, to 1e-8."""
    m, I, sx, sy = 1.3, 0.02, -0.1, 0.3
    model = mbs.compile_text(PENDULUM.format(m=m, I=I, sx=sx, sy=sy, g=G), path="pendulum.mbs")
    eq = mbs.equilibrium(model)
    L = math.hypot(sx, sy)
    assert eq.q[:2] == pytest.approx([0.0, -L], abs=1e-12)
    (name, body, f), = eq.reactions()
    assert f[:2] == pytest.approx([0.0, m * G], rel=1e-12, abs=1e-12)  # the pin holds the weight
    (mode,) = mbs.linearize(model, eq).modes()
    assert mode.omega == pytest.approx(math.sqrt(m * G * L / (I + m * L * L)), rel=1e-8)
    assert np.allclose(mode.shape / mode.shape[2], [L, 0.0, 1.0], atol=1e-8)


def chain_model(masses, k):
    """Masses on horizontal slides joined by springs of stiffness k, the outer ones to the walls."""
    lines = []
    for i, m in enumerate(masses):
        lines.append(f"body m{i} {{ mass = {m} kg  inertia = 1e-3 kg*m^2  position = ({0.1 * (i + 1)}, 0) }}")
        lines.append(f"joint s{i} = translational(ground, m{i}, axis = (1, 0))")
    ends = ["ground (0, 0)"] + [f"m{i}" for i in range(len(masses))] + [f"ground ({0.1 * (len(masses) + 1)}, 0)"]
    for i in range(len(ends) - 1):
        lines.append(f"force k{i} = spring_damper({ends[i]}, {ends[i + 1]}) {{ stiffness = {k} N/m }}")
    return mbs.compile_text("\n".join(lines), path="chain.mbs")


def test_a_chain_of_equal_masses_has_the_closed_form_frequencies_and_shapes():
    """N equal masses between two walls, N + 1 equal springs: w_j = 2 sqrt(k/m) sin(j pi / (2 (N + 1))),
    shape x_i = sin(i j pi / (N + 1)); to 1e-8."""
    m, k, N = 0.7, 2000.0, 3
    lin = mbs.linearize(chain_model([m] * N, k))
    shown = lin.modes()
    assert [s.kind for s in shown] == ["oscillating"] * N
    for j, mode in enumerate(shown, start=1):
        assert mode.omega == pytest.approx(2 * math.sqrt(k / m) * math.sin(j * math.pi / (2 * (N + 1))), rel=1e-8)
        x = np.real(mode.shape[0::3])
        expect = np.sin(np.arange(1, N + 1) * j * math.pi / (N + 1))
        x, expect = x / np.linalg.norm(x), expect / np.linalg.norm(expect)
        assert np.allclose(x * np.sign(x @ expect), expect, atol=1e-8)
        assert np.allclose(mode.shape[1::3], 0, atol=1e-12) and np.allclose(mode.shape[2::3], 0, atol=1e-12)


def test_two_unequal_masses_against_the_eigenvalues_of_m_inverse_k():
    """m1, m2 with three springs k: the roots of det(K - w^2 M) = 0 written out, and their shapes."""
    m1, m2, k = 0.4, 1.1, 500.0
    lin = mbs.linearize(chain_model([m1, m2], k))
    # (2k - w^2 m1)(2k - w^2 m2) - k^2 = 0: m1 m2 w^4 - 2k (m1 + m2) w^2 + 3 k^2 = 0
    a, b, c = m1 * m2, -2 * k * (m1 + m2), 3 * k * k
    w2 = sorted([(-b - math.sqrt(b * b - 4 * a * c)) / (2 * a), (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)])
    for mode, w in zip(lin.modes(), w2):
        assert mode.omega ** 2 == pytest.approx(w, rel=1e-8)
        ratio = (2 * k - w * m1) / k  # x2 / x1 from the first row
        assert np.real(mode.shape[3] / mode.shape[0]) == pytest.approx(ratio, rel=1e-8)


def test_a_damped_oscillator_has_its_damping_ratio_and_damped_frequency():
    """m on a slide, spring k and damper c to a wall: lambda = -zeta w_n +- i w_n sqrt(1 - zeta^2),
    zeta = c / (2 sqrt(k m)); to 1e-8."""
    m, k, c = 0.8, 3000.0, 9.0
    text = f"""
body block {{ mass = {m} kg  inertia = 1e-3 kg*m^2  position = (0.2, 0) }}
joint s = translational(ground, block, axis = (1, 0))
force kd = spring_damper(ground (0, 0), block) {{ stiffness = {k} N/m  damping = {c} N*s/m }}
"""
    (mode,) = mbs.linearize(mbs.compile_text(text, path="damped.mbs")).modes()
    wn, zeta = math.sqrt(k / m), c / (2 * math.sqrt(k * m))
    assert mode.damping_ratio == pytest.approx(zeta, rel=1e-8)
    assert mode.omega == pytest.approx(wn, rel=1e-8)
    assert mode.damped_frequency * 2 * math.pi == pytest.approx(wn * math.sqrt(1 - zeta * zeta), rel=1e-8)


def test_the_state_matrix_at_a_moving_state_matches_its_analytic_jacobian():
    """A pendulum with a torsional spring-damper, at a displaced and moving state: in the chart's
    coordinate z = zeta(theta) = P (q(theta) - q0) the motion is z'' = zeta' theta'' + zeta'' theta'^2 with
    theta'' = F(theta, theta') = (-m g L cos theta - k (theta - theta0) - c theta') / (I + m L^2); its
    derivatives at fixed z' (theta' = z' / zeta') are written out here.  Checked to 1e-8."""
    m, I, L, k, c, th0 = 1.1, 0.03, 0.4, 2.0, 0.05, -1.2
    text = f"""
body bob {{ mass = {m} kg  inertia = {I} kg*m^2  position = ({L}, 0) }}
joint pin = revolute(ground (0, 0), bob (-{L}, 0))
force tk = rotational_spring_damper(ground, bob) {{ stiffness = {k} N*m/rad  damping = {c} N*m*s/rad  angle = {th0} }}
gravity (0, -{G} m/s^2)
"""
    model = mbs.compile_text(text, path="pendulum_kc.mbs")
    th, thd = 0.7, 2.3
    q = np.array([L * math.cos(th), L * math.sin(th), th])
    qd = thd * np.array([-L * math.sin(th), L * math.cos(th), 1.0])
    lin = mbs.linearize(model, (q, qd))
    P = lin.projection[0]
    J = I + m * L * L
    F = (-m * G * L * math.cos(th) - k * (th - th0) - c * thd) / J
    F_th, F_thd = (m * G * L * math.sin(th) - k) / J, -c / J
    z1 = P @ [-L * math.sin(th), L * math.cos(th), 1.0]
    z2 = P @ [-L * math.cos(th), -L * math.sin(th), 0.0]
    z3 = P @ [L * math.sin(th), -L * math.cos(th), 0.0]
    dFt_th = z2 * F + z1 * F_th + z3 * thd ** 2
    dFt_thd = z1 * F_thd + 2 * z2 * thd
    a10 = (dFt_th - dFt_thd * thd * z2 / z1) / z1
    a11 = dFt_thd / z1
    assert lin.state_matrix[0] == pytest.approx([0.0, 1.0], abs=1e-15)
    assert lin.state_matrix[1] == pytest.approx([a10, a11], rel=1e-8)


def four_bar_pose(theta, a, b, c, d):
    """(A, B, phi_coupler, phi_rocker) of the four-bar with crank angle theta (the open branch)."""
    A = a * np.array([math.cos(theta), math.sin(theta)])
    B0 = np.array([d, 0.0])
    e = B0 - A
    r = math.hypot(*e)
    x = (b * b - c * c + r * r) / (2 * r)
    h = math.sqrt(b * b - x * x)
    B = A + x * e / r + h * np.array([-e[1], e[0]]) / r
    return A, B, math.atan2(*(B - A)[::-1]), math.atan2(*(B - B0)[::-1])


def test_a_four_bar_held_by_a_spring_has_the_energy_method_frequency():
    """Crank a, coupler b, rocker c (uniform bars), ground pivots d apart, gravity, a torsional spring k on
    the crank: V(theta) = sum m g y + k (theta - theta_s)^2 / 2 and T = J(theta) theta'^2 / 2, J = sum m |dr/dtheta|^2
    + I (dphi/dtheta)^2, both from the closed-form loop closure; the equilibrium is V' = 0 and
    w^2 = V''(theta_e) / J(theta_e) (derivatives by five-point differences of the closed form)."""
    a, b, c, d, ms, k, ths = 0.05, 0.12, 0.09, 0.1, (0.2, 0.4, 0.3), 1.5, 1.4
    Is = [m * L * L / 12 for m, L in zip(ms, (a, b, c))]

    def parts(theta):
        A, B, p2, p3 = four_bar_pose(theta, a, b, c, d)
        return [(A / 2, theta), ((A + B) / 2, p2), ((B + np.array([d, 0.0])) / 2, p3)]

    def V(theta):
        return sum(m * G * r[1] for m, (r, _) in zip(ms, parts(theta))) + 0.5 * k * (theta - ths) ** 2

    def D(f, x, h):
        return (f(x - 2 * h) - 8 * f(x - h) + 8 * f(x + h) - f(x + 2 * h)) / (12 * h)

    def dV(x):
        return D(V, x, 1e-4)

    th = ths
    for _ in range(30):  # Newton on V'(theta) = 0
        th -= dV(th) / D(dV, th, 1e-3)
    Jeff = 0.0
    for i, (m, I) in enumerate(zip(ms, Is)):
        dr = D(lambda x: parts(x)[i][0], th, 1e-4)
        dphi = D(lambda x: parts(x)[i][1], th, 1e-4)
        Jeff += m * dr @ dr + I * dphi * dphi
    w2 = D(lambda x: D(V, x, 1e-3), th, 1e-3) / Jeff
    A, B, p2, p3 = four_bar_pose(1.0, a, b, c, d)
    text = f"""
body crank   {{ mass = {ms[0]} kg  inertia = {Is[0]} kg*m^2  position = ({A[0] / 2}, {A[1] / 2})  angle = 1.0 }}
body coupler {{ mass = {ms[1]} kg  inertia = {Is[1]} kg*m^2  position = ({(A + B)[0] / 2}, {(A + B)[1] / 2})  angle = {p2} }}
body rocker  {{ mass = {ms[2]} kg  inertia = {Is[2]} kg*m^2  position = ({(B[0] + d) / 2}, {B[1] / 2})  angle = {p3} }}
joint O2 = revolute(ground (0, 0), crank (-{a / 2}, 0))
joint A = revolute(crank ({a / 2}, 0), coupler (-{b / 2}, 0))
joint B = revolute(coupler ({b / 2}, 0), rocker ({c / 2}, 0))
joint O4 = revolute(ground ({d}, 0), rocker (-{c / 2}, 0))
force spring = rotational_spring_damper(ground, crank) {{ stiffness = {k} N*m/rad  angle = {ths} }}
gravity (0, -{G} m/s^2)
"""
    model = mbs.compile_text(text, path="four_bar_spring.mbs")
    eq = mbs.equilibrium(model)
    assert eq.q[2] == pytest.approx(th, abs=1e-9)
    (mode,) = mbs.linearize(model, eq).modes()
    assert mode.omega ** 2 == pytest.approx(w2, rel=1e-7)


def test_a_driver_is_held_and_carries_the_gravity_moment():
    """A crank driven at constant speed, under gravity: held at its angle theta0 at t = 0, its driver
    carries the moment of the weight about the pivot, m g (L/2) cos theta0; the pin the weight."""
    m, Lc, th0 = 0.3, 0.05, 0.6
    text = f"""
body crank {{ mass = {m} kg  inertia = 1e-5 kg*m^2  position = ({Lc / 2 * math.cos(th0)}, {Lc / 2 * math.sin(th0)})  angle = {th0} }}
joint O = revolute(ground (0, 0), crank (-{Lc / 2}, 0))
driver spin = rotation(crank, speed = 300 rpm)
gravity (0, -{G} m/s^2)
"""
    eq = mbs.equilibrium(mbs.compile_text(text, path="crank.mbs"))
    assert eq.q[2] == pytest.approx(th0, abs=1e-12) and eq.iterations == 0
    reactions = {name: f for name, _, f in eq.reactions()}
    assert reactions["O"][:2] == pytest.approx([0.0, m * G], abs=1e-12)
    # moments about the centre of mass: the driver's and the pin force's arm sum to the weight's moment
    # about the pivot; the driver alone gives the torque m g (L/2) cos theta0 about the pivot
    assert reactions["spin"][2] == pytest.approx(m * G * Lc / 2 * math.cos(th0), rel=1e-12)


def test_a_free_journal_is_not_unique_and_an_unresisted_load_has_no_equilibrium():
    """A frictionless journal free in its bearing turns with no restoring moment: not unique, named.
    A block on a slide pushed by a constant force: no equilibrium, named."""
    free = JOURNAL.format(K=1e9, m=0.5, n=1.5, g=G).replace(
        "joint slide = translational(ground, journal, axis = (0, 1))", "")
    with pytest.raises(static.StaticError, match=r"not unique: body `journal` angle"):
        mbs.equilibrium(mbs.compile_text(free, path="free.mbs"))
    push = """
body block { mass = 1 kg  inertia = 1e-3 kg*m^2 }
joint s = translational(ground, block, axis = (1, 0))
force f = constant(block, force = (2 N, 0))
"""
    with pytest.raises(static.StaticError, match=r"no equilibrium found .* body `block` x"):
        static.equilibrium(mbs.compile_text(push, path="push.mbs"), max_iterations=30)


def test_an_unstable_equilibrium_at_the_start_is_kept_and_reported():
    """A pendulum assembled exactly upside down is at rest there: found at once, unstable, a growing mode
    at rate sqrt(m g L / (I + m L^2))."""
    m, I, L = 1.0, 0.01, 0.2
    text = f"""
body bob {{ mass = {m} kg  inertia = {I} kg*m^2  position = (0, {L}) }}
joint pin = revolute(ground (0, 0), bob (0, -{L}))
gravity (0, -{G} m/s^2)
"""
    model = mbs.compile_text(text, path="inverted.mbs")
    eq = mbs.equilibrium(model)
    assert eq.iterations == 0 and not eq.stable()
    lin = mbs.linearize(model, eq)
    growing = [md for md in lin.modes() if md.kind == "growing"]
    assert len(growing) == 1 and growing[0].omega == pytest.approx(math.sqrt(m * G * L / (I + m * L * L)), rel=1e-8)
    assert not lin.stable


def test_a_run_from_the_equilibrium_stays_there_and_a_small_vibration_rings_at_the_mode_frequency():
    """From the equilibrium (`at_rest`) the time loop keeps the journal at rest: its velocity stays at
    rounding level.  Lifted by 2 % of d0 and let go, it rings at w = sqrt(n K d0^(n-1) / m) (an
    amplitude that small shifts the frequency by O(a^2)): the FFT peak (results/spectrum.py, flat-top
    window, read between bins to 0.1 % of the amplitude) lies within one bin of w / 2 pi."""
    from planar_mbs.results import spectrum

    K, m, n = 1e9, 0.5, 1.5
    model = journal(K, m, n)
    eq = mbs.equilibrium(model)
    rest = static.at_rest(model, eq)
    res = mbs.simulate(rest, t_end="20 ms", output_step="1 ms", rtol=1e-10, atol=1e-14)
    assert np.max(np.abs(res["journal.vy"])) < 1e-9
    assert np.max(np.abs(res["journal.y"] - eq.q[1])) < 1e-13
    d0 = (m * G / K) ** (1.0 / n)
    rest.q0[1] += 0.02 * d0
    res = mbs.simulate(rest, t_end="0.5 s", output_step="50 us", rtol=1e-10, atol=1e-14)
    spec = spectrum.spectrum(res, "journal.y", "amplitude", window="flattop")
    (f_peak, amp), = spec.peaks(1)
    f = math.sqrt(n * K * d0 ** (n - 1) / m) / (2 * math.pi)
    assert abs(f_peak - f) <= spec.resolution
    assert amp == pytest.approx(0.02 * d0, rel=0.05)
    (mode,) = mbs.linearize(model, eq).modes()
    assert abs(f_peak - mode.frequency) <= spec.resolution


def test_the_commands_print_write_and_refuse(tmp_path):
    """`mbs static` and `mbs modes` print, write HDF5 and a figure; no equilibrium or one not unique is
    exit 3 with its cause; `mbs run --from-static` starts at rest."""
    import h5py
    from typer.testing import CliRunner

    from planar_mbs.cli.app import app

    run = CliRunner()
    model = tmp_path / "journal.mbs"
    model.write_text(JOURNAL.format(K=1e9, m=0.5, n=1.5, g=G), encoding="utf-8")
    r = run.invoke(app, ["static", str(model), "-o", str(tmp_path / "eq.h5")])
    assert r.exit_code == 0, r.output
    assert "penetration 2.88686e-06 m" in r.output and "stable" in r.output
    r = run.invoke(app, ["modes", str(model), "-o", str(tmp_path / "m.h5"), "--plot", str(tmp_path / "m.png")])
    assert r.exit_code == 0, r.output
    assert "mode 1: f = 359.3" in r.output
    with h5py.File(tmp_path / "m.h5") as f:
        assert f["modes/frequency"][0] == pytest.approx(359.3, rel=1e-3)
        assert f["static/gaps"][0] < 0 and "model_source" in f.attrs
    assert (tmp_path / "m.png").stat().st_size > 0
    r = run.invoke(app, ["static", str(model), "-o", str(model)])
    assert r.exit_code == 2 and "model file" in r.output
    free = tmp_path / "free.mbs"
    free.write_text(model.read_text().replace("joint slide = translational(ground, journal, axis = (0, 1))", ""))
    r = run.invoke(app, ["static", str(free)])
    assert r.exit_code == 3 and "not unique" in r.output and "Traceback" not in r.output
    r = run.invoke(app, ["run", str(model), "--from-static", "-q", "--t-end", "5ms", "-o", str(tmp_path / "r.h5")])
    assert r.exit_code == 0 and "starting from the static equilibrium" in r.output, r.output
    res = mbs.read_results(tmp_path / "r.h5")
    assert np.max(np.abs(res["journal.vy"])) < 1e-9


def test_the_numbers_of_the_studies_page_are_the_programs():
    """docs/studies.md shows `mbs static` and `mbs modes` on docs/studies/resting_journal.mbs: the
    penetration, the journal's load, the frequencies and the damping ratio it states are what the
    program gives today."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    text = (root / "docs" / "studies.md").read_text(encoding="utf-8")
    path = root / "docs" / "studies" / "resting_journal.mbs"
    eq = mbs.equilibrium(mbs.load_model(path))
    stated = float(re.search(r"clearance element A: penetration (\S+) m", text)[1])
    assert -eq.gaps[0] == pytest.approx(stated, rel=1e-5)
    load = float(re.search(r"B on slider: 0, -(\S+), 0", text)[1])
    assert {n: f for n, b, f in eq.reactions()}["S"][1] > 0 and load == pytest.approx(
        -[f for n, b, f in eq.reactions() if (n, b) == ("B", "slider")][0][1], rel=1e-5)
    hertz = mbs.linearize(mbs.load_model(path, law="hertz")).modes()
    shown = [float(f) for f in re.findall(r"mode \d: f = (\S+) Hz", text)]
    assert shown == pytest.approx([m.frequency for m in hertz], rel=1e-5)
    zeta = float(re.search(r"`--impact-velocity 0.1` its contact mode has\s+ζ = (\S+);", text)[1])
    ln = mbs.linearize(mbs.load_model(path), impact_velocity=0.1).modes()
    assert ln[1].damping_ratio == pytest.approx(zeta, rel=1e-3)
    assert [m.kind for m in mbs.linearize(mbs.load_model(path)).modes()][1:] == ["decaying", "decaying"]


def test_a_resting_contact_damps_its_mode_by_the_hysteresis_of_its_law():
    """Lankarani-Nikravesh, F = K d^n (1 + chi d'/v), chi = 3 (1 - ce^2) / 4, v the impact velocity: about
    the rest d0 the contact is a spring n K d0^(n-1) and a dashpot chi K d0^n / v = chi W / v, so
    zeta = chi W / (v 2 sqrt(n K d0^(n-1) m)); the frequency is the elastic one."""
    K, m, n, ce, v = 1e9, 0.5, 1.5, 0.8, 0.05
    text = JOURNAL.format(K=K, m=m, n=n, g=G).replace("law = hertz", f"law = lankarani_nikravesh  restitution = {ce}")
    model = mbs.compile_text(text, path="journal_ln.mbs")
    (mode,) = mbs.linearize(model, impact_velocity=v).modes()
    d0 = (m * G / K) ** (1.0 / n)
    k = n * K * d0 ** (n - 1)
    chi = 3 * (1 - ce * ce) / 4
    assert mode.damping_ratio == pytest.approx(chi * m * G / v / (2 * math.sqrt(k * m)), rel=1e-6)
    assert mode.omega == pytest.approx(math.sqrt(k / m), rel=1e-6)


def test_modes_about_the_assembled_state_and_a_driver_held_at_a_later_time(tmp_path):
    """`--at assembled`: about the pose as assembled (here a pendulum released at theta0 from the
    vertical, not at rest: theta'' = -w0^2 sin theta, so A = [[0, 1], [-w0^2 cos theta0, 0]] and the
    eigenvalues are +- i w0 sqrt(cos theta0)).  `--time`: a crank driven at speed w is held where it is
    at that time, theta0 + w t."""
    from typer.testing import CliRunner

    from planar_mbs.cli.app import app

    m, I, L, th0 = 1.0, 0.01, 0.2, 0.5
    text = f"""
body bob {{ mass = {m} kg  inertia = {I} kg*m^2  position = ({L * math.sin(th0)}, {-L * math.cos(th0)})  angle = {th0} }}
joint pin = revolute(ground (0, 0), bob (0, {L}))
gravity (0, -{G} m/s^2)
"""
    model = tmp_path / "released.mbs"
    model.write_text(text, encoding="utf-8")
    w0 = math.sqrt(m * G * L / (I + m * L * L))
    (mode,) = mbs.linearize(mbs.load_model(model), "assembled").modes()
    assert mode.omega == pytest.approx(w0 * math.sqrt(math.cos(th0)), rel=1e-8)
    r = CliRunner().invoke(app, ["modes", str(model), "--at", "assembled"])
    assert r.exit_code == 0 and f"omega_n = {mode.omega:.6g} rad/s" in r.output, r.output
    crank = tmp_path / "crank.mbs"
    crank.write_text("""
body crank { mass = 0.3 kg  inertia = 1e-5 kg*m^2  position = (0.025, 0) }
joint O = revolute(ground (0, 0), crank (-0.025, 0))
driver spin = rotation(crank, speed = 60 rpm)
gravity (0, -9.81 m/s^2)
""", encoding="utf-8")
    eq = mbs.equilibrium(mbs.load_model(crank), t=0.125)
    assert eq.q[2] == pytest.approx(2 * math.pi * 0.125, abs=1e-12)
    r = CliRunner().invoke(app, ["static", str(crank), "--time", "125ms"])
    assert r.exit_code == 0 and "crank: " in r.output and ", 45\n" in r.output, r.output
