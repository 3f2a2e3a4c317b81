"""Friction models with stick (catalog.FRICTION_MODELS) against closed forms derived here.

The models hold no solver setting: the default tolerances must give the answer.  A "block" is a disc
whose angle a rotation driver holds (so it slides, one contact, no tipping), on a Kelvin-Voigt contact
(linear, so its static penetration is m g cos(theta) / K)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from scipy.linalg import expm
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from planar_mbs import Simulation, compile_text, simulate
from planar_mbs.errors import ModelError

from friction_blocks import SLOPE

G = 9.81
K = 1e7  # N/m, the contact's stiffness (the stuck contact's tangential one too: stick_stiffness = 1)


def slope_text(theta, friction, t_end, dt=1e-3, extra="", v0=0.0):
    """A block resting (or sliding down at v0) on a plane at angle theta, pressed to its static
    penetration m g cos(theta) / K."""
    n = np.array([-math.sin(theta), math.cos(theta)])
    down = -np.array([math.cos(theta), math.sin(theta)])
    c = n * (10e-3 - G * math.cos(theta) / K)
    return SLOPE.format(x0=c[0], y0=c[1], vx=v0 * down[0], vy=v0 * down[1], nx=n[0], ny=n[1], K=K,
                        friction=friction, extra=extra, t_end=t_end, dt=dt)


def slope(theta, friction, t_end, dt=1e-3, extra="", v0=0.0):
    """`slope_text` run: (results, unit vector down the slope, the static penetration)."""
    down = -np.array([math.cos(theta), math.sin(theta)])
    text = slope_text(theta, friction, t_end, dt, extra, v0)
    return simulate(compile_text(text)), down, G * math.cos(theta) / K


def along(res, down):
    return res["block.x"] * down[0] + res["block.y"] * down[1], res["block.vx"] * down[0] + res["block.vy"] * down[1]


def test_a_block_below_its_friction_angle_stays_put_for_ten_seconds():
    """tan(10 deg) = 0.18 < mu_s = 0.3: no slip at all; the block moves by the stuck contact's own
    compliance (m g sin(theta) / k_t, below the contact's penetration) and comes to rest."""
    theta = math.radians(10)
    res, down, d = slope(theta, "friction = 0.3", t_end=10.0, dt=0.01)
    s, v = along(res, down)
    assert np.max(np.abs(s - s[0])) <= G * math.sin(theta) / K * 1.001  # k_t = K: the spring's own stretch
    assert np.max(np.abs(s - s[0])) < d
    assert abs(v[-1]) < 1e-9
    assert res["plane.stick"].min() == 1.0


def test_a_block_above_its_friction_angle_slides_with_the_kinetic_coefficient():
    """tan(30 deg) = 0.58 > mu_s = 0.3: it breaks away at once and slides with a = g (sin - mu_k cos)."""
    theta, mk = math.radians(30), 0.2
    res, down, d = slope(theta, f"friction = {mk}  static_friction = 0.3", t_end=1.0)
    s, v = along(res, down)
    a = G * (math.sin(theta) - mk * math.cos(theta))
    late = res.time > 0.2
    measured = (v[late][-1] - v[late][0]) / (res.time[late][-1] - res.time[late][0])
    assert measured == pytest.approx(a, rel=1e-6)
    assert res["plane.stick"][late].max() == 0.0


def test_the_default_friction_model_lets_a_body_rest():
    """`friction = 0.3` alone: the block on a 10 deg slope stops after it was thrown down at 0.1 m/s,
    after v0 / (g (mu cos - sin)) of kinetic deceleration, and stays."""
    theta, mu, v0 = math.radians(10), 0.3, 0.1
    res, down, d = slope(theta, f"friction = {mu}", t_end=1.0, v0=v0)
    s, v = along(res, down)
    t_stop = v0 / (G * (mu * math.cos(theta) - math.sin(theta)))
    k = int(np.argmax(res["plane.stick"] > 0))
    assert res.time[k - 1] < t_stop <= res.time[k]
    assert np.max(np.abs(v[res.time > t_stop + 0.1])) < 1e-6
    assert s[-1] - s[0] == pytest.approx(v0 * t_stop / 2, rel=1e-3)


def test_ambrosio_model_keeps_todays_creep():
    """The model of before, by name: no friction below its threshold slip speed, so the block creeps."""
    theta = math.radians(10)
    res, down, d = slope(theta, "friction = 0.3  friction_model = ambrosio", t_end=0.5)
    s, v = along(res, down)
    assert s[-1] - s[0] > 1e-6
    with pytest.raises(KeyError):
        res["plane.stick"]


def stuck_ramp_force(t, a, m, k, c):
    """Force k x + c x' of the stuck contact's spring-damper on a block at rest at t = 0 pushed by a t:
    m x'' + c x' + k x = a t, solved exactly as a linear system of (x, x', t, 1) by its exponential."""
    A = np.array([[0.0, 1.0, 0.0, 0.0], [-k / m, -c / m, a / m, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0] * 4])
    x, v, *_ = expm(A * t) @ np.array([0.0, 0.0, 0.0, 1.0])
    return k * x + c * v


def test_a_ramp_force_breaks_a_block_away_when_the_stuck_force_reaches_mu_s_m_g():
    """F = a t on a block at rest on a level plane: the stuck contact (k_t = K, critically damped for
    the effective mass m_t = 1 / (1/m + R^2/I) along t) holds until its force reaches mu_s m g -- for a
    slow ramp at t* = mu_s m g / a, here (a t* of a stick period or less, where the default tolerances
    keep the normal force within 1e-9 a / mu_s) read with the stuck dynamics -- and the slip event is
    located there: stuck at t* - 1 ns, slipping at t* + 1 ns."""
    ms, m, R, I = 0.4, 1.0, 10e-3, 1e-3
    c = 2.0 * math.sqrt(K / (1.0 / m + R * R / I))
    for a in (2e4, 2e5):
        push = f"force push = expression(block, fx = {a} N/s * t)"
        text = slope_text(0.0, f"friction = 0.25  static_friction = {ms}", t_end=0.01, dt=1e-3, extra=push)
        t_star = brentq(lambda t: stuck_ramp_force(t, a, m, K, c) - ms * m * G, 1e-9, 0.01, xtol=1e-15)
        sim = Simulation(compile_text(text))
        sim.run_until(t_star - 1e-9)
        assert sim.latest("plane.stick") == 1.0
        sim.run_until(t_star + 1e-9)
        assert sim.latest("plane.stick") == 0.0


def belt_closed_form(m, k, v, ms, mk):
    """Stick-slip limit cycle of a mass on a belt at speed v held by a spring k (x from the spring's
    rest point): stuck, x grows at v up to x_s = mu_s m g / k; it slips from there at v, oscillating
    about x_k = mu_k m g / k with amplitude A = sqrt((x_s - x_k)^2 + (v / w)^2) until its speed is v
    again, at 2 x_k - x_s (symmetry).  Stick time 2 (x_s - x_k) / v, slip time (2 pi - 2 phi) / w with
    tan(phi) = w (x_s - x_k) / v; x swings between x_k - A and x_k + A."""
    w = math.sqrt(k / m)
    xs, xk = ms * m * G / k, mk * m * G / k
    A = math.hypot(xs - xk, v / w)
    phi = math.atan2(w * (xs - xk), v)
    return 2 * (xs - xk) / v, (2 * math.pi - 2 * phi) / w, xk - A, xk + A


BELT = """
gravity (0, -9.81 m/s^2)
body belt {{ mass = 10 kg  inertia = 1 kg*m^2 }}
joint guide = translational(ground (0, 0), belt (0, 0), axis = (1, 0))
driver run = translation(belt, axis = (1, 0), speed = {v} m/s)
body block {{ mass = {m} kg  inertia = 1e-4 kg*m^2  position = (0, {y0})  shape = circle(10 mm) }}
driver hold = rotation(block, speed = 0 rad/s)
joint on_belt = contact(belt (0, 0), block) {{
    shape = circle_on_line  normal = (0, 1)  radius = 10 mm
    law = kelvin_voigt  stiffness = {K} N/m  restitution = 0.5  {friction}
}}
force spring = spring_damper(ground (0, {y0}), block) {{ stiffness = {k} N/m  length = 0 m }}
simulate {{ t_end = {t_end} s  output_step = 0.1 ms }}
"""


def test_mass_on_a_moving_belt_has_the_closed_form_stick_slip_cycle():
    m, k, v, ms, mk = 1.0, 100.0, 0.05, 0.4, 0.25
    text = BELT.format(v=v, m=m, y0=10e-3 - m * G / K, K=K, k=k, t_end=5.0,
                       friction=f"friction = {mk}  static_friction = {ms}")
    res = simulate(compile_text(text))
    t_stick, t_slip, x_lo, x_hi = belt_closed_form(m, k, v, ms, mk)
    stick = res["on_belt.stick"]
    up = res.time[1:][np.diff(stick) > 0]
    down = res.time[1:][np.diff(stick) < 0]
    assert len(up) >= 4
    durations = [d - u for u in up[1:] for d in down[down > u][:1]]
    assert np.allclose(durations, t_stick, rtol=1e-3)
    slips = [u - d for d in down[1:] for u in up[up > d][:1]]
    assert np.allclose(slips, t_slip, rtol=1e-3)
    late = res.time > up[1]
    x = res["block.x"][late]
    assert x.max() == pytest.approx(x_hi, rel=1e-3)
    assert x.min() == pytest.approx(x_lo, rel=1e-3)


DISC = """
gravity (0, -9.81 m/s^2)
material steel {{ E = 207 GPa  nu = 0.3 }}
body disc {{ mass = 1 kg  inertia = {I} kg*m^2  position = (0, 60 mm)  omega = {w0} rad/s
            shape = circle(50 mm) }}
joint floor = contact(ground (0, 0), disc) {{
    shape = circle_on_line  normal = (0, 1)  radius = 50 mm  material = steel
    law = lankarani_nikravesh  restitution = 0.3  friction = 0.3
}}
simulate {{ t_end = 1 s  output_step = 1 ms }}
"""


def test_a_spinning_disc_landing_ends_rolling_with_the_rigid_answer():
    """Friction and the normal force act at the contact and gravity passes through it, so the angular
    momentum about the contact point, I w - m r vx, is kept: it ends rolling (vx = -w r) with
    w = I w0 / (I + m r^2)."""
    m, r, I, w0 = 1.0, 0.05, 1.25e-3, -20.0
    res = simulate(compile_text(DISC.format(I=I, w0=w0)))
    w_end = I * w0 / (I + m * r * r)
    assert res["disc.omega"][-1] == pytest.approx(w_end, rel=1e-4)
    assert res["disc.vx"][-1] == pytest.approx(-w_end * r, rel=1e-4)
    assert res["floor.stick"][-1] == 1.0


def test_friction_power_is_the_friction_force_times_the_slip_velocity():
    theta, mk = math.radians(30), 0.2
    res, down, d = slope(theta, f"friction = {mk}  static_friction = 0.3", t_end=0.3)
    P = res["plane.friction_power"]
    assert np.allclose(P, res["plane.friction_force"] * res["plane.slip_velocity"])
    slide = res.time > 0.05
    assert np.all(P[slide] < 0)


@pytest.mark.parametrize("fields, message", [
    ("friction = 0.3  static_friction = 0.2", "must not be below"),
    ("friction = 0.3  friction_model = coulomb  friction_velocity = 1e-4 m/s", "setting of friction_model"),
    ("friction = 0.3  stribeck_velocity = 1 mm/s", "setting of friction_model = stribeck"),
    ("friction = 0.3  friction_model = stribeck", "stribeck_velocity"),
    ("friction = 0.3  friction_model = lugre2", "unknown friction_model"),
])
def test_bad_friction_settings_are_refused_with_the_line(fields, message):
    with pytest.raises(ModelError, match=message):
        slope(0.0, fields, t_end=0.01)


def test_a_block_thrown_on_a_level_plane_slows_down_on_the_stribeck_curve():
    """Slipping, m v' = -(mu(v) m g + sigma_2 v), mu(v) = mu_k + (mu_s - mu_k) exp(-(v/v_s)^d): the run's
    speed against that 1-D equation integrated here, until it sticks."""
    mk, ms, vs, dlt, s2, v0 = 0.2, 0.4, 0.05, 2.0, 0.5, 0.3
    fr = (f"friction_model = stribeck  friction = {mk}  static_friction = {ms}  stribeck_velocity = {vs} m/s  "
          f"stribeck_exponent = {dlt}  viscous_friction = {s2} N*s/m")
    res, down, d = slope(0.0, fr, t_end=0.3, v0=v0)
    s, v = along(res, down)

    def rate(t, y):
        return [-(G * (mk + (ms - mk) * math.exp(-(y[0] / vs) ** dlt)) + s2 * y[0])]

    stop = lambda t, y: y[0] - 1e-9  # noqa: E731
    stop.terminal = True
    ref = solve_ivp(rate, (0, 1), [v0], rtol=1e-12, atol=1e-14, dense_output=True, events=stop)
    t_stop = ref.t_events[0][0]
    slide = res.time < t_stop - 0.005
    assert np.allclose(v[slide], ref.sol(res.time[slide])[0], rtol=1e-5, atol=1e-8)
    k = int(np.argmax(res["plane.stick"] > 0))
    assert res.time[k - 1] < t_stop + 1e-6 and t_stop - 1e-6 <= res.time[k]
    assert np.max(np.abs(v[res.time > t_stop + 0.01])) < 1e-6


GUIDE = """
gravity (0, -9.81 m/s^2)
body block {{ mass = 1 kg  inertia = 4e-4 kg*m^2  position = ({x0}, {y0}) }}
joint S = clearance_translational(ground (0, 0), block, axis = ({ux}, {uy})) {{
    clearance = 0.5 mm  length = 60 mm  width = 20 mm  law = kelvin_voigt  stiffness = {K} N/m  restitution = 0.5
    {friction}
}}
simulate {{ t_end = {t_end} s  output_step = 10 ms }}
"""


@pytest.mark.parametrize("deg, friction", [(10, "friction = 0.3"), (30, "friction = 0.2  static_friction = 0.3")])
def test_a_block_in_a_tilted_guide_holds_below_and_slides_above_its_friction_angle(deg, friction):
    """A translational clearance joint (a block on its two bottom corners, free to tilt) on a guide at
    theta: below the friction angle both corners stay stuck and the block moves by the corners'
    compliance only; above it slides with a = g (sin - mu_k cos) (the corners' normal forces sum to
    m g cos(theta) whatever the tilt moment shares them out)."""
    th = math.radians(deg)
    u, n = np.array([math.cos(th), math.sin(th)]), np.array([-math.sin(th), math.cos(th)])
    c = -n * (0.25e-3 + G * math.cos(th) / 2 / K)  # on the bottom surface, each corner carrying half
    res = simulate(compile_text(GUIDE.format(x0=c[0], y0=c[1], ux=u[0], uy=u[1], K=K, friction=friction,
                                             t_end=2.0 if deg == 10 else 0.5)))
    s = res["block.x"] * u[0] + res["block.y"] * u[1]
    v = res["block.vx"] * u[0] + res["block.vy"] * u[1]
    if deg == 10:
        assert np.max(np.abs(s - s[0])) < G * math.cos(th) / 2 / K  # below one corner's penetration
        assert res["S_rear_bottom.stick"].min() == 1.0 and res["S_front_bottom.stick"].min() == 1.0
        assert abs(v[-1]) < 1e-9
    else:
        late = res.time > 0.2
        a = (v[late][-1] - v[late][0]) / (res.time[late][-1] - res.time[late][0])
        assert a == pytest.approx(-G * (math.sin(th) - 0.2 * math.cos(th)), rel=1e-6)
