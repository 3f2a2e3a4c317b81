"""Friction in ideal joints (revolute pins and translational slides) against closed forms and reference
integrations written here.

The models hold no solver setting: the default tolerances (rtol 1e-6) must give the answer.  A pin's
friction torque is mu r |lambda| against its relative rate, lambda its reaction; a slide's friction force
mu |lambda_n| (or with a block length, mu max(|lambda_n|, 2 |lambda_m| / l)) against its sliding rate."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from planar_mbs import Simulation, compile_text, simulate
from planar_mbs.errors import ModelError, SimulationError

G = 9.81
M, IC, L = 1.0, 0.01, 0.5  # the pendulum: mass, inertia about its centre of mass, pin to centre of mass
R_PIN, MU, MU_S = 50e-3, 0.2, 0.3
A0 = 0.6  # rad from hanging straight down

PENDULUM = """
gravity (0, -9.81 m/s^2)
body bob {{ mass = {m} kg  inertia = {ic} kg*m^2  position = ({x0} m, {y0} m)  angle = {phi0} }}
joint A = revolute(ground (0, 0), bob (-{L} m, 0)) {{ friction = {mu}  static_friction = {mus}  pin_radius = {r} m }}
simulate {{ t_end = {t_end} s  output_step = 10 ms {extra} }}
"""


def pendulum(t_end=6.0, extra="", a0=A0, mu=MU, mus=MU_S, r=R_PIN):
    phi0 = -math.pi / 2 + a0
    text = PENDULUM.format(m=M, ic=IC, L=L, x0=L * math.cos(phi0), y0=L * math.sin(phi0), phi0=phi0, mu=mu,
                           mus=mus, r=r, t_end=t_end, extra=extra)
    return simulate(compile_text(text))


def pin_acceleration(phi, w, mu, r, sign):
    """phi'' of the pendulum with the friction torque -mu r |lambda| sign, by fixed point to rounding:
    (I_c + m L^2) phi'' = -m g L cos(phi) + T, and the pin's force on the bob
    lambda = m (c'' - g) with c = L (cos phi, sin phi) (Newton for the centre of mass)."""
    io = IC + M * L * L
    a = -M * G * L * math.cos(phi) / io
    for _ in range(200):
        cx = -L * math.sin(phi) * a - L * math.cos(phi) * w * w
        cy = L * math.cos(phi) * a - L * math.sin(phi) * w * w + G
        t = -mu * r * M * math.hypot(cx, cy) * sign
        new = (-M * G * L * math.cos(phi) + t) / io
        if new == a:
            break
        a = new
    return a


def reference_swing(t_end):
    """The slow but obvious reference: the same one-degree-of-freedom equation by solve_ivp at rtol 1e-12,
    slipping one way until the first turning point (released at rest at A0, where gravity's moment exceeds
    the pin's static bound, it swings back towards phi' < 0: the friction opposes that from the start)."""
    y0 = [-math.pi / 2 + A0, 0.0]
    return solve_ivp(lambda t, y: [y[1], pin_acceleration(y[0], y[1], MU, R_PIN, -1.0)], (0, t_end), y0,
                     rtol=1e-12, atol=1e-14, dense_output=True)


def test_pendulum_swing_follows_the_reference_equation_with_its_own_reaction():
    """Until its first turning point the pendulum slips one way: the kernel's phi(t) is the solution of
    (I_c + m L^2) phi'' = -m g L cos(phi) - mu r |lambda(phi, phi', phi'')|, lambda from Newton's law
    for the centre of mass, solved for phi'' in each right-hand side (no step lag)."""
    res = pendulum(t_end=0.6)
    t = res.time
    sol = reference_swing(0.6)
    phi = sol.sol(t)[0]
    w = sol.sol(t)[1]
    keep = w < -0.05  # before the turning point
    assert keep.sum() > 30
    np.testing.assert_allclose(res["bob.phi"][keep], phi[keep], rtol=0, atol=2e-6)
    assert np.all(res["A.stick"][keep] == 0)
    # the torque the kernel reports is the reference's -mu r |lambda| at that state
    io = IC + M * L * L
    for p, v, T in zip(phi[keep], w[keep], res["A.friction_torque"][keep]):
        a = pin_acceleration(p, v, MU, R_PIN, -1.0)
        assert T == pytest.approx(io * a + M * G * L * math.cos(p), rel=1e-4)


def turning_points(res):
    """Angles from hanging (theta = phi + pi/2) at the sign changes of omega, interpolated, before the
    pendulum first sticks (then omega is zero to rounding)."""
    stuck = np.nonzero(res["A.stick"] == 1)[0]
    end = stuck[0] + 1 if len(stuck) else len(res.time)
    w = res["bob.omega"][:end]
    th = res["bob.phi"][:end] + math.pi / 2
    idx = np.nonzero((w[:-1] > 0) != (w[1:] > 0))[0]
    return np.array([th[i] - w[i] * (th[i + 1] - th[i]) / (w[i + 1] - w[i]) for i in idx])


def test_amplitude_falls_by_the_energy_of_the_pin_friction_each_swing():
    """A swing from amplitude A1 to A2 loses m g L (cos A2 - cos A1) = integral of mu r |lambda| |dtheta|;
    to first order in mu r / L, |lambda| = m g (3 cos theta - 2 cos A) (the frictionless radial load with
    L omega^2 = 2 g (cos theta - cos A)), so cos A2 - cos A1 = (mu r / L)(6 sin A - 4 A cos A), A the mean
    amplitude: the decrement to within its second-order error (mu r / L = 0.02: about 3 %)."""
    res = pendulum(t_end=4.0)
    amp = np.abs(turning_points(res))
    amp = np.concatenate([[A0], amp])
    assert len(amp) >= 5
    k = MU * R_PIN / L
    for a1, a2 in zip(amp[:-1], amp[1:]):
        a = 0.5 * (a1 + a2)
        predicted = k * (6 * math.sin(a) - 4 * a * math.cos(a))
        assert math.cos(a2) - math.cos(a1) == pytest.approx(predicted, rel=3 * k / 2 + 0.01)
    # and the decrement is nearly the constant 2 mu r / L of small swings (Coulomb's linear decay)
    assert np.diff(amp)[-1] == pytest.approx(-2 * k * (1 + amp[-1] ** 2 / 4), rel=0.1)


def test_friction_work_is_the_energy_lost_and_the_balance_closes():
    """integral T omega dt (the joint's friction work) = (T + V)(t) - (T + V)(0); the energy balance of the
    run stays zero to the integration's error while the pendulum swings, sticks and rests: within 10 rtol of
    the energy it loses at the default rtol 1e-6 (docs/signals.md allows 100), and 1e4 times closer at rtol
    1e-10 (the error is the integration's, not a friction a step late, which would not shrink so)."""
    for rtol, extra in ((1e-6, ""), (1e-10, "rtol = 1e-10  atol = 1e-13")):
        res = pendulum(t_end=12.0, extra=extra)
        E = res["system.kinetic_energy"] + res["system.potential_energy"]
        W = res["A.friction_work"]
        np.testing.assert_allclose(E - E[0], W, rtol=0, atol=10 * rtol * abs(W[-1]))
        assert np.max(np.abs(res["system.energy_balance"])) < 10 * rtol * abs(W[-1])
    assert np.all(res["A.friction_power"] <= 1e-12)
    # the power is T omega, with T = -mu r |lambda| while slipping
    slip = res["A.stick"] == 0
    np.testing.assert_allclose(res["A.friction_power"][slip], (res["A.friction_torque"] * res["bob.omega"])[slip],
                               rtol=1e-12, atol=1e-15)
    lam = np.hypot(res["A.fx"], res["A.fy"])
    np.testing.assert_allclose(np.abs(res["A.friction_torque"][slip]), MU * R_PIN * lam[slip], rtol=1e-9)


def test_pendulum_sticks_where_the_pin_can_hold_it():
    """It ends stuck at an angle theta with m g L sin|theta| <= mu_s r m g (the hold torque within the
    static bound at rest, |lambda| = m g), and stays there: omega = 0 and the friction torque holds gravity's
    moment, m g L sin(theta)."""
    res = pendulum(t_end=12.0)
    stuck = res["A.stick"] == 1
    assert stuck[-1] and stuck[np.argmax(stuck):].all() and res.time[np.argmax(stuck)] < 11.0
    th = res["bob.phi"][-1] + math.pi / 2
    assert abs(math.sin(th)) <= MU_S * R_PIN / L
    assert abs(res["bob.omega"][-1]) < 1e-9
    assert res["A.friction_torque"][-1] == pytest.approx(M * G * L * math.sin(th), rel=1e-6)
    # and it stuck at the first turning point within that bound, not before
    amp = np.abs(turning_points(res))
    assert abs(th) == pytest.approx(amp[-1], abs=1e-3)
    assert all(abs(math.sin(a)) > MU_S * R_PIN / L for a in amp[:-1])


def test_two_tolerances_agree_to_the_tolerance():
    """The friction is solved in each right-hand side: the answer depends on the tolerance only, never on
    the step a friction lags behind.  rtol 1e-6 (the default) and 1e-10 agree to about 1e-6."""
    a = pendulum(t_end=3.0)
    b = pendulum(t_end=3.0, extra="rtol = 1e-10  atol = 1e-12")
    np.testing.assert_allclose(a["bob.phi"], b["bob.phi"], rtol=0, atol=1e-5)
    np.testing.assert_allclose(a["A.friction_work"], b["A.friction_work"], rtol=0, atol=1e-5)


SLIDE = """
gravity (0, -9.81 m/s^2)
body block {{ mass = {m} kg  inertia = 1e-3 kg*m^2  position = (0, 0)  angle = {theta} }}
joint S = translational(ground (0, 0), block (0, 0), axis = ({ux}, {uy})) {{ {friction} }}
{extra}
simulate {{ t_end = {t_end} s  output_step = 10 ms }}
"""


def slide(theta, friction, t_end=1.0, extra="", m=2.0):
    text = SLIDE.format(m=m, theta=theta, ux=math.cos(theta), uy=math.sin(theta), friction=friction,
                        extra=extra, t_end=t_end)
    return simulate(compile_text(text))


def test_a_block_below_the_friction_angle_holds():
    """tan(10 deg) = 0.18 < mu_s = 0.3: the block stays stuck where it was laid, held by m g sin(theta)."""
    theta = math.radians(10)
    res = slide(theta, "friction = 0.2  static_friction = 0.3", t_end=2.0)
    assert np.all(res["S.stick"] == 1)
    assert np.max(np.abs(res["block.x"])) < 1e-12 and np.max(np.abs(res["block.y"])) < 1e-12
    np.testing.assert_allclose(res["S.friction_force"], 2.0 * G * math.sin(theta), rtol=1e-9)


def test_a_block_above_the_friction_angle_slides_with_the_kinetic_friction():
    """tan(30 deg) = 0.58 > mu_s = 0.3: it slides down at a = g (sin(theta) - mu_k cos(theta)), s = a t^2 / 2."""
    theta = math.radians(30)
    res = slide(theta, "friction = 0.2  static_friction = 0.3", t_end=1.0)
    a = G * (math.sin(theta) - 0.2 * math.cos(theta))
    s = res["block.x"] * math.cos(theta) + res["block.y"] * math.sin(theta)
    np.testing.assert_allclose(s, -0.5 * a * res.time ** 2, rtol=1e-9, atol=1e-12)
    assert np.all(res["S.stick"][1:] == 0)
    np.testing.assert_allclose(res["S.friction_force"][1:], 0.2 * 2.0 * G * math.cos(theta), rtol=1e-9)


def test_a_ramp_force_breaks_the_block_away_at_the_static_friction():
    """A force k t along a level slide: stuck until k t* = mu_s m g, then m x'' = k t - mu_k m g, so
    x = k (t^3 - t*^3)/(6 m) - k t*^2 (t - t*)/(2 m) - mu_k g (t - t*)^2 / 2 after t* (the located switch)."""
    k, m, mus, mu = 10.0, 2.0, 0.3, 0.2
    res = slide(0.0, f"friction = {mu}  static_friction = {mus}", t_end=1.0, m=m,
                extra=f"force push = expression(block (0, 0), fx = {k} N/s * t)")
    ts = mus * m * G / k
    t = res.time
    after = t > ts
    dt = t[after] - ts
    x = k * (t[after] ** 3 - ts ** 3) / (6 * m) - k * ts ** 2 * dt / (2 * m) - mu * G * dt ** 2 / 2
    np.testing.assert_allclose(res["block.x"][after], x, rtol=1e-7, atol=1e-12)
    assert np.all(res["S.stick"][~after] == 1) and np.all(res["S.stick"][after] == 0)
    np.testing.assert_allclose(res["S.friction_force"][~after], -k * t[~after], rtol=1e-9, atol=1e-12)


def test_a_slow_ramp_breaks_the_block_away_at_mu_s_m_g_over_a_located_to_a_nanosecond():
    """F = a t along a level slide: the rigid slide's normal reaction is m g exactly, so the stick holds
    until a t* = mu_s m g and the located switch sits at t* = mu_s m g / a: stuck at t* - 1 ns,
    slipping at t* + 1 ns, for a slow ramp (t* = 0.59 s, thousands of steps) and a fast one."""
    m, mus = 2.0, 0.3
    for a in (10.0, 1e3):
        text = SLIDE.format(m=m, theta=0.0, ux=1.0, uy=0.0, friction=f"friction = 0.2  static_friction = {mus}",
                            extra=f"force push = expression(block (0, 0), fx = {a} N/s * t)", t_end=1.0)
        t_star = mus * m * G / a
        sim = Simulation(compile_text(text))
        sim.run_until(t_star - 1e-9)
        assert sim.latest("S.stick") == 1.0
        sim.run_until(t_star + 1e-9)
        assert sim.latest("S.stick") == 0.0


def test_a_push_high_on_a_short_block_wedges_it():
    """The drawer effect: a push F at height h above the centre of a block of length l loads its ends with
    m g / 2 -+ F h / l; with block_length the friction bound is mu max(m g, 2 F h / l), which grows with F
    faster than F when 2 mu_s h / l > 1: the block never moves.  With h = 0 it breaks away at mu_s m g."""
    k, m, mus = 10.0, 2.0, 0.3
    wedge = slide(0.0, f"friction = 0.2  static_friction = {mus}  block_length = 0.1 m", t_end=2.0, m=m,
                  extra=f"force push = expression(block (0, 0.2 m), fx = {k} N/s * t)")
    assert np.all(wedge["S.stick"] == 1) and np.max(np.abs(wedge["block.x"])) < 1e-12
    # the load is 2 F h / l once above m g
    F = k * wedge.time
    np.testing.assert_allclose(np.abs(wedge["S.moment"]), F * 0.2, rtol=1e-9, atol=1e-12)
    low = slide(0.0, f"friction = 0.2  static_friction = {mus}  block_length = 0.1 m", t_end=1.0, m=m,
                extra=f"force push = expression(block (0, 0), fx = {k} N/s * t)")
    moved = low.time[low["S.stick"] == 0]
    assert moved[0] == pytest.approx(mus * m * G / k, abs=0.011)


def test_a_frictionless_joint_has_no_friction_signals_and_bad_settings_are_refused():
    res = slide(math.radians(30), "", t_end=0.1)
    assert "S.friction_force" not in res.signals
    with pytest.raises(ModelError, match="pin radius"):
        compile_text(PENDULUM.format(m=1, ic=0.01, L=0.5, x0=0, y0=-0.5, phi0=-1.57, mu=0.1, mus=0.1, r=0,
                                     t_end=1, extra=""))
    with pytest.raises(ModelError, match="below its kinetic friction"):
        compile_text(PENDULUM.format(m=1, ic=0.01, L=0.5, x0=0, y0=-0.5, phi0=-1.57, mu=0.3, mus=0.1, r=0.01,
                                     t_end=1, extra=""))


# a double pendulum of very unequal links with friction in both pins: not a shipped model
M1, I1, L1 = 1.0, 0.02, 0.3  # body 1: pinned to ground at (-L1, 0) of its frame, body 2 at (L1, 0)
M2, I2, L2 = 0.05, 1e-4, 0.2  # body 2: pinned at (-L2, 0)
RA, RB, MU2 = 20e-3, 5e-3, 0.25
DOUBLE = """
gravity (0, -9.81 m/s^2)
body one {{ mass = {m1} kg  inertia = {i1} kg*m^2  position = ({x1} m, {y1} m)  angle = {p1}
           velocity = ({vx1} m/s, {vy1} m/s)  omega = {w1} rad/s }}
body two {{ mass = {m2} kg  inertia = {i2} kg*m^2  position = ({x2} m, {y2} m)  angle = {p2}
           velocity = ({vx2} m/s, {vy2} m/s)  omega = {w2} rad/s }}
joint A = revolute(ground (0, 0), one (-{l1} m, 0)) {{ friction = {mu}  pin_radius = {ra} m }}
joint B = revolute(one ({l1} m, 0), two (-{l2} m, 0)) {{ friction = {mu}  pin_radius = {rb} m }}
simulate {{ t_end = {t_end} s  output_step = 5 ms {extra} }}
"""


def _e(p):
    return np.array([math.cos(p), math.sin(p)]), np.array([-math.sin(p), math.cos(p)])


def double_pendulum(p1, p2, w1, w2, t_end, extra=""):
    e1, n1 = _e(p1)
    e2, n2 = _e(p2)
    c1, v1 = L1 * e1, L1 * w1 * n1
    c2, v2 = 2 * L1 * e1 + L2 * e2, 2 * L1 * w1 * n1 + L2 * w2 * n2
    text = DOUBLE.format(m1=M1, i1=I1, m2=M2, i2=I2, l1=L1, l2=L2, x1=c1[0], y1=c1[1], x2=c2[0], y2=c2[1],
                         p1=p1, p2=p2, vx1=v1[0], vy1=v1[1], vx2=v2[0], vy2=v2[1], w1=w1, w2=w2, mu=MU2, ra=RA,
                         rb=RB, t_end=t_end, extra=extra)
    return simulate(compile_text(text))


def double_accelerations(p1, p2, w1, w2, dA, dB):
    """Newton-Euler for both links with the pin forces F_A (ground on one), F_B (one on two) and the
    frictions T_A = -mu r_A |F_A| dA on one, T_B = -mu r_B |F_B| dB on two (-T_B on one): six linear
    equations for (a1, a2, F_A, F_B) at given frictions, the frictions by fixed point to rounding."""
    e1, n1 = _e(p1)
    e2, n2 = _e(p2)

    A = np.zeros((6, 6))
    # unknowns x = (a1, a2, FAx, FAy, FBx, FBy); m1 c1'' = F_A - F_B + m1 g, m2 c2'' = F_B + m2 g
    A[0:2, 0] = M1 * L1 * n1
    A[0:2, 2:4] = -np.eye(2)
    A[0:2, 4:6] = np.eye(2)
    A[2:4, 0] = M2 * 2 * L1 * n1
    A[2:4, 1] = M2 * L2 * n2
    A[2:4, 4:6] = -np.eye(2)
    # I1 a1 = (-L1 e1) x F_A + (L1 e1) x (-F_B) + T_A - T_B;  I2 a2 = (-L2 e2) x F_B + T_B
    A[4, 0] = I1
    A[4, 2:4] = [-L1 * e1[1], L1 * e1[0]]  # -(-L1 e1) x F_A = L1 (e1x FAy - e1y FAx)
    A[4, 4:6] = [-L1 * e1[1], L1 * e1[0]]  # -(L1 e1) x (-F_B)
    A[5, 1] = I2
    A[5, 4:6] = [-L2 * e2[1], L2 * e2[0]]  # -(-L2 e2) x F_B
    g = np.array([0.0, -G])
    b0 = np.concatenate([M1 * (L1 * w1 ** 2 * e1) + M1 * g,
                         M2 * (2 * L1 * w1 ** 2 * e1 + L2 * w2 ** 2 * e2) + M2 * g, [0.0, 0.0]])
    TA = TB = 0.0
    for _ in range(200):
        x = np.linalg.solve(A, b0 + np.array([0, 0, 0, 0, TA - TB, TB]))
        nA = -MU2 * RA * math.hypot(x[2], x[3]) * dA
        nB = -MU2 * RB * math.hypot(x[4], x[5]) * dB
        if nA == TA and nB == TB:
            break
        TA, TB = nA, nB
    return x[0], x[1]


def reference_double(y0, t_end):
    """The chain by solve_ivp at rtol 1e-12 in slipping segments: a pin whose relative rate crosses zero
    slips on the other way (the run below never sticks: its hold torques exceed mu r |lambda| at every
    reversal, which the kernel decides and the comparison confirms).  Returns the segments' solutions."""
    y = list(y0)
    d = [math.copysign(1.0, y[2]), math.copysign(1.0, y[3] - y[2])]
    t, segments = 0.0, []
    while t < t_end:
        def f(t, y):
            a1, a2 = double_accelerations(y[0], y[1], y[2], y[3], d[0], d[1])
            return [y[2], y[3], a1, a2]
        turn = [lambda t, y: y[2], lambda t, y: y[3] - y[2]]
        for k, ev in enumerate(turn):
            ev.terminal, ev.direction = True, -d[k]
        sol = solve_ivp(f, (t, t_end), y, rtol=1e-12, atol=1e-13, dense_output=True, events=turn)
        segments.append(sol)
        if sol.status != 1:
            break
        k = 0 if len(sol.t_events[0]) else 1
        d[k] = -d[k]
        t, y = sol.t[-1], list(sol.y[:, -1])
    return segments


def test_a_double_pendulum_with_two_frictional_pins_follows_newton_euler():
    """Two coupled frictions (each pin's reaction depends on both torques, a light second link, 1:20 in
    mass): the kernel's solve against Newton-Euler of both links written here, through the reversals."""
    p1, p2, w1, w2 = -math.pi / 2 + 0.7, -math.pi / 2 + 0.2, 1.0, 2.5
    res = double_pendulum(p1, p2, w1, w2, t_end=1.0)
    segments = reference_double([p1, p2, w1, w2], 1.0)
    assert len(segments) >= 4
    for sol in segments:
        keep = (res.time >= sol.t[0]) & (res.time <= sol.t[-1])
        ref = sol.sol(res.time[keep])
        np.testing.assert_allclose(res["one.phi"][keep], ref[0], rtol=0, atol=1e-5)
        np.testing.assert_allclose(res["two.phi"][keep], ref[1], rtol=0, atol=1e-5)
    assert np.all(res["A.stick"] == 0) and np.all(res["B.stick"] == 0)


def test_the_double_pendulums_balance_closes_through_sticks_and_slips():
    """A long run of the chain: each pin's friction power <= 0, and (T + V) lost = -(W_A + W_B) to
    10 rtol of the energy lost while the pins reverse many times."""
    res = double_pendulum(-math.pi / 2 + 0.7, -math.pi / 2 + 0.2, 1.0, 2.5, t_end=8.0)
    assert np.all(res["A.friction_power"] <= 1e-12) and np.all(res["B.friction_power"] <= 1e-12)
    E = res["system.kinetic_energy"] + res["system.potential_energy"]
    W = res["A.friction_work"] + res["B.friction_work"]
    np.testing.assert_allclose(E - E[0], W, rtol=0, atol=1e-5 * abs(W[-1]))
    assert np.max(np.abs(res["system.energy_balance"])) < 1e-5 * abs(W[-1])
    for j in "AB":  # the pins reverse many times
        assert np.count_nonzero(np.diff(np.sign(res[f"{j}.slip_rate"]))) >= 6


def test_a_pin_whose_friction_outgrows_its_own_load_stops_the_run_with_a_message():
    """mu r = 0.8 m on a pendulum whose pin load changes by m L per unit phi'': each sweep of the solve
    multiplies an error by mu r m L / (I_c + m L^2) = 1.5 > 1, so no friction is found: SimulationError (exit
    3) naming the joint, never a wrong answer."""
    text = PENDULUM.format(m=1, ic=0.01, L=0.5, x0=0.0, y0=-0.5, phi0=-math.pi / 2, mu=0.8, mus=0.8, r=1.0,
                           t_end=1, extra="")
    text = text.replace("angle = -1.5707963267948966", "angle = -1.5707963267948966  omega = 3 rad/s  "
                        "velocity = (1.5 m/s, 0)")
    with pytest.raises(SimulationError, match="friction of joint `A` found no torque"):
        simulate(compile_text(text))


CRANK = """
gravity (0, -9.81 m/s^2)
body crank  { mass = 0.30 kg  inertia = 1e-5 kg*m^2    position = (0.025 m, 0) }
body rod    { mass = 0.21 kg  inertia = 2.5e-4 kg*m^2  position = (0.110 m, 0) }
body slider { mass = 0.14 kg  inertia = 1e-4 kg*m^2    position = (0.170 m, 0) }
joint O = revolute(ground (0, 0), crank (-0.025 m, 0)) { friction = 0.1  pin_radius = 6 mm }
joint A = revolute(crank (0.025 m, 0), rod (-0.06 m, 0)) { friction = 0.15  pin_radius = 4 mm }
joint B = revolute(rod (0.06 m, 0), slider (0, 0))
joint S = translational(ground, slider, axis = (1, 0)) { friction = 0.2  static_friction = 0.3 }
driver turn = rotation(crank, speed = 600 rpm)
simulate { t_end = 0.3 s  output_step = 1 ms }
"""


def test_a_driven_slider_crank_pays_its_joints_friction_through_its_driver():
    """At constant crank speed the motion is periodic (0.1 s), so over whole revolutions the driver's work is
    the friction the joints dissipated; a joint whose slip the driver fixes (the slide at its dead centres,
    the crank pin) never sticks, it reverses.  The slide's friction is -mu_k |lambda_n| sign(v)."""
    res = simulate(compile_text(CRANK))
    t = res.time
    i0, i1 = np.searchsorted(t, [0.1 - 1e-9, 0.3 - 1e-9])
    Wd = res["turn.work"][i1] - res["turn.work"][i0]
    Wf = sum(res[f"{j}.friction_work"][i1] - res[f"{j}.friction_work"][i0] for j in "OAS")
    assert Wd > 0 and Wd == pytest.approx(-Wf, rel=1e-5)
    assert np.all(res["S.stick"] == 0) and np.all(res["A.stick"] == 0)
    v = res["slider.vx"]
    moving = np.abs(v) > 1e-3
    np.testing.assert_allclose(res["S.friction_force"][moving], -0.2 * np.abs(res["S.fy"][moving]) * np.sign(v[moving]),
                               rtol=1e-9, atol=1e-12)
    # the balance closes to the integration's error: within the documented 100 rtol of the input work, and
    # 1000 times closer at rtol 1e-9
    W = res["turn.work"][-1]
    assert np.max(np.abs(res["system.energy_balance"])) < 100 * 1e-6 * W
    tight = simulate(compile_text(CRANK.replace("output_step = 1 ms", "output_step = 1 ms  rtol = 1e-9  atol = 1e-12")))
    assert np.max(np.abs(tight["system.energy_balance"])) < 100 * 1e-9 * W
