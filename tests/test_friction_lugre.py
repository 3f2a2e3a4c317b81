"""LuGre friction (`friction_model = lugre`) against closed forms derived here.

Canudas de Wit, Olsson, Åström & Lischinsky, "A new model for control of systems with friction" (1995),
with the bristle stiffness and damping per unit normal force:

    dz/dt = v - sigma_0 |v| z / g(v),   g(v) = mu_k + (mu_s - mu_k) exp(-(|v|/v_s)^d),
    F_T = -F_N (sigma_0 z + sigma_1 dz/dt) - sigma_2 v.

The models hold no solver setting (the defaults, rtol 1e-6 and atol 1e-9, must give the answer).  A "block"
is a disc whose angle a rotation driver holds, on a Kelvin-Voigt contact started at its static
penetration m g / K, so the normal force is m g throughout."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from planar_mbs import compile_text, load_model, simulate
from planar_mbs.errors import ModelError
from planar_mbs.mechanism.model import Settings

from friction_blocks import SLOPE

G = 9.81
K = 1e7  # N/m, the normal contact's stiffness
RTOL, ATOL = Settings().rtol, Settings().atol

BLOCK = SLOPE.replace("{friction}", "friction_model = lugre  {friction}")


def block(friction, t_end, dt, theta=0.0, v0=0.0, extra="", lift=0.0, vy=0.0):
    """A block on a plane at angle theta, at its static penetration (raised by `lift`), sliding down
    the slope at v0 (falling at vy): (results, unit vector down the slope)."""
    n = np.array([-math.sin(theta), math.cos(theta)])
    down = -np.array([math.cos(theta), math.sin(theta)]) if theta else np.array([1.0, 0.0])
    c = n * (10e-3 - G * math.cos(theta) / K + lift)
    text = BLOCK.format(x0=c[0], y0=c[1], vx=v0 * down[0], vy=v0 * down[1] + vy, nx=n[0], ny=n[1], K=K,
                        friction=friction, extra=extra, t_end=t_end, dt=dt)
    return simulate(compile_text(text)), down


def stribeck(v, mk, ms, vs, d):
    return mk + (ms - mk) * np.exp(-(np.abs(v) / vs) ** d)


BELT = """
gravity (0, -9.81 m/s^2)
body belt {{ mass = 10 kg  inertia = 1 kg*m^2 }}
joint guide = translational(ground (0, 0), belt (0, 0), axis = (1, 0))
driver run = translation(belt, axis = (1, 0), speed = {v} m/s)
body block {{ mass = 1 kg  inertia = 1e-4 kg*m^2  position = (0, {y0})  shape = circle(10 mm) }}
joint post = translational(ground (0, {y0}), block (0, 0), axis = (0, 1))
joint on_belt = contact(belt (0, 0), block) {{
    shape = circle_on_line  normal = (0, 1)  radius = 10 mm
    law = kelvin_voigt  stiffness = {K} N/m  restitution = 0.5
    friction_model = lugre  friction = {mk}  static_friction = {ms}  stribeck_velocity = {vs} m/s
    stribeck_exponent = {d}  viscous_friction = {s2} N*s/m  bristle_stiffness = {s0} 1/m
    bristle_damping = {s1} s/m
}}
simulate {{ t_end = {t_end} s  output_step = 0.5 ms }}
"""


@pytest.mark.parametrize("v", [-0.2, 0.004, 0.02, 0.05, 0.3])
def test_steady_sliding_friction_is_the_stribeck_curve(v):
    """A block held above a belt running at v slides at the constant slip speed -v: from z = 0 the
    bristles follow z(t) = (g/sigma_0) sign(v_T) (1 - exp(-sigma_0 |v_T| t / g)) (the linear ODE at
    constant v_T, solved), and the force settles on F_N g(v_T) sign(v_T) + sigma_2 v_T against the slip
    (the relaxation rate sigma_0 |v| / g is above 1e3 / s: after 60 ms nothing of the transient is left).
    The explicit integrator steps at the stability limit of that fast relaxation, so the state sigma_0 z
    (about g) is as exact as its error control makes it, rtol g: the force to 10 rtol of F_N g."""
    mk, ms, vs, d, s0, s1, s2 = 0.2, 0.35, 0.02, 2.0, 1e5, 0.0, 0.8
    text = BELT.format(v=v, y0=10e-3 - G / K, K=K, mk=mk, ms=ms, vs=vs, d=d, s0=s0, s1=s1, s2=s2, t_end=0.06)
    res = simulate(compile_text(text))
    vt = res["on_belt.slip_velocity"]
    assert np.allclose(vt, -v, rtol=1e-12, atol=0)
    g = stribeck(-v, mk, ms, vs, d)
    fn = res["on_belt.contact_force"]  # m g, to the noise of the stiff normal contact at its stability limit
    expected = -(fn[-1] * g * np.sign(-v) + s2 * -v)
    assert res["on_belt.friction_force"][-1] == pytest.approx(expected, abs=10 * RTOL * fn[-1] * g)
    z = (g / s0) * np.sign(-v) * (1.0 - np.exp(-s0 * abs(v) * res.time / g))
    assert np.max(np.abs(res["on_belt.bristle"] - z)) <= 10 * RTOL * g / s0


def test_a_small_force_deflects_the_bristles_by_f_over_sigma0_n():
    """A resting block pushed by F = mu N / 2 (mu_s = mu_k = mu: g = mu), bristles overdamped: it comes to
    rest with sigma_0 z N = F, z = F / (sigma_0 N), having moved (dz/dx = 1 - sigma_0 z / mu while
    v > 0) x = -(mu / sigma_0) ln(1 - sigma_0 z / mu) = ln(2) mu / sigma_0 -- the presliding
    displacement, 1.39 z, not z: the bristles' own nonlinearity."""
    mu, s0, s1 = 0.3, 1e4, 300.0
    N = G
    F = 0.5 * mu * N
    fr = f"friction = {mu}  stribeck_velocity = 0.01 m/s  bristle_stiffness = {s0} 1/m  bristle_damping = {s1} s/m"
    res, down = block(fr, t_end=1.0, dt=1e-3, extra=f"force push = expression(block, fx = {F} N)")
    x = res["block.x"] - res["block.x"][0]
    assert np.min(res["block.vx"]) > -10 * ATOL  # monotone (to the velocities' own noise): the closed form holds
    z_end = res["plane.bristle"][-1]
    assert z_end == pytest.approx(F / (s0 * N), rel=1e-9)
    assert x[-1] == pytest.approx(-(mu / s0) * math.log(1 - s0 * z_end / mu), abs=10 * ATOL)
    assert abs(res["block.vx"][-1]) < 10 * ATOL


def test_a_block_below_its_friction_angle_stays_put():
    """tan(10 deg) = 0.18 < mu_k = 0.25 < mu_s = 0.3: the block sinks into its bristles until
    sigma_0 |z| F_N = m g sin(theta), z = -tan(theta) / sigma_0 (t points up the slope), and stays there for ten seconds (no
    creep under a constant load).  Its displacement lies between the bounds of dz/dx = 1 - sigma_0 z/g(v)
    with mu_k <= g <= mu_s: -(mu_s/sigma_0) ln(1 - sigma_0 z/mu_s) and the same with mu_k."""
    theta, mk, ms, s0 = math.radians(10), 0.25, 0.3, 1e4
    s1 = 2.0 * 2.0 * math.sqrt(s0 / (G * math.cos(theta)))  # twice critical for the bristles' stiffness sigma_0 m g cos
    fr = (f"friction = {mk}  static_friction = {ms}  stribeck_velocity = 1 mm/s  bristle_stiffness = {s0} 1/m  "
          f"bristle_damping = {s1} s/m")
    res, down = block(fr, t_end=10.0, dt=0.01, theta=theta)
    s = (res["block.x"] - res["block.x"][0]) * down[0] + (res["block.y"] - res["block.y"][0]) * down[1]
    z = math.tan(theta) / s0
    assert res["plane.bristle"][-1] == pytest.approx(-z, rel=1e-9)
    lo = -(ms / s0) * math.log(1 - s0 * z / ms)
    hi = -(mk / s0) * math.log(1 - s0 * z / mk)
    assert lo - 10 * ATOL <= s[-1] <= hi + 10 * ATOL
    settled = res.time > 1.0
    assert np.ptp(s[settled]) < 10 * ATOL
    assert np.max(np.abs(res["block.vx"][settled])) < 10 * ATOL


def test_a_thrown_block_stops_where_its_bristles_energy_says():
    """Thrown at v0 on a level plane (mu_s = mu_k = mu, sigma_1 = sigma_2 = 0): while v > 0,
    z(x) = (mu/sigma_0)(1 - exp(-sigma_0 x/mu)) and F_T = -N sigma_0 z, so the block first stops at d with
    m v0^2 / 2 = N mu (d - (mu/sigma_0)(1 - exp(-sigma_0 d/mu))) -- Coulomb's v0^2 / (2 mu g) plus
    mu / sigma_0.  The friction power is F_T v_T, its integral the contact's work (the normal force does
    none at the static penetration), and the energy balance closes to 12 rtol of the energy."""
    mu, s0, v0 = 0.3, 1e4, 0.1
    N = G
    fr = f"friction = {mu}  stribeck_velocity = 0.01 m/s  bristle_stiffness = {s0} 1/m"
    res, down = block(fr, t_end=0.05, dt=1e-5, v0=v0)
    x = res["block.x"] - res["block.x"][0]
    v = res["block.vx"]
    first = int(np.argmax(v < 0.0))
    assert first > 0
    d = brentq(lambda d: N * mu * (d - mu / s0 * (1 - math.exp(-s0 * d / mu))) - 0.5 * v0 ** 2, 1e-6, 1.0, xtol=1e-15)
    assert d == pytest.approx(v0 ** 2 / (2 * mu * G) + mu / s0, rel=1e-6)
    assert np.max(x[:first + 1]) == pytest.approx(d, abs=10 * ATOL)
    ft, vt = res["plane.friction_force"], res["plane.slip_velocity"]
    assert np.array_equal(res["plane.friction_power"], ft * vt)
    P = res["plane.friction_power"]
    trapz = np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1]) * np.diff(res.time))])
    assert np.max(np.abs(res["plane.work"] - trapz)) <= 1e-4 * 0.5 * v0 ** 2
    scale = 0.5 * v0 ** 2
    assert np.max(np.abs(res["system.energy_balance"])) <= 12 * RTOL * scale


def test_the_bristles_reset_when_the_contact_opens():
    """A block thrown down onto the plane while sliding bounces: its bristles are 0 in every flight
    (reset at each separation), deflected while it touches."""
    fr = "friction = 0.3  stribeck_velocity = 0.01 m/s  bristle_stiffness = 1e4 1/m  bristle_damping = 20 s/m"
    res, down = block(fr, t_end=0.1, dt=1e-5, v0=0.2, lift=1e-4, vy=-0.3)
    touching = res["plane.in_contact"] == 1.0
    assert touching.any() and (~touching[1:]).any() and np.any(np.diff(touching.astype(int)) < 0)
    assert np.all(res["plane.bristle"][~touching] == 0.0)
    assert np.max(np.abs(res["plane.bristle"][touching])) > 0.0


def test_lugre_needs_its_kinetic_coefficient_and_its_own_settings():
    with pytest.raises(ModelError, match="needs `friction` > 0"):
        block("stribeck_velocity = 0.01 m/s  bristle_stiffness = 1e4 1/m", t_end=0.01, dt=1e-3)
    with pytest.raises(ModelError, match="bristle_stiffness"):
        block("friction = 0.3  stribeck_velocity = 0.01 m/s", t_end=0.01, dt=1e-3)
    text = BLOCK.replace("friction_model = lugre", "").format(
        x0=0, y0=0.01, vx=0, vy=0, nx=0, ny=1, K=K, friction="friction = 0.3  bristle_stiffness = 1e4 1/m",
        extra="", t_end=0.01, dt=1e-3)
    with pytest.raises(ModelError, match="setting of friction_model = lugre"):
        compile_text(text)


def test_a_slider_crank_with_lugre_at_its_journal_and_its_slider_corners(tmp_path):
    """Five LuGre contacts in one mechanism (the revolute clearance A and the four corners of the
    translational clearance S): five states after (q, q'), each bounded by LuGre's |z| <= mu_s / sigma_0
    (from z = 0, dz/dt has the sign of -z wherever |z| > g(v) / sigma_0), 0 wherever its contact is open,
    and the energy balance closed to 12 rtol of the run's energy scale (the run's own rtol)."""
    mu, ms, s0 = 0.1, 0.15, 1e4
    lugre = (f"friction_model = lugre  friction = {mu}  static_friction = {ms}  stribeck_velocity = 0.01 m/s  "
             f"bristle_stiffness = {s0} 1/m  bristle_damping = 5 s/m")
    models = Path(__file__).resolve().parents[1] / "models"
    path = tmp_path / "lugre_crank.mbs"
    path.write_text(f'include "{models / "slider_crank_clearance_as.mbs"}"\n'
                    "override joint A = clearance_revolute(crank (0.025 m, 0), rod (-0.06 m, 0)) {\n"
                    "    clearance = clearance_a  bearing_radius = 5 mm  length = 20 mm  material = steel\n"
                    f"    law = law  restitution = restitution  {lugre}\n}}\n"
                    "override joint S = clearance_translational(ground (0, 0), slider (0, 0), axis = (1, 0)) {\n"
                    "    clearance = clearance  length = 30 mm  width = 15 mm  corner_radius = 1 mm\n"
                    f"    material = steel  law = law  restitution = restitution  {lugre}\n}}\n"
                    "override simulate { t_end = 20 ms  rtol = 1e-8  atol = 1e-11  output_step = 10 us }\n")
    model = load_model(path)
    assert model.nstate == 5
    res = simulate(model)
    names = [s for s in res.signals if s.endswith(".bristle")]
    assert len(names) == 5
    for name in names:
        element = name[: -len(".bristle")]
        z = res[name]
        assert np.max(np.abs(z)) <= ms / s0 * (1 + 1e-6)
        assert np.all(z[res[f"{element}.in_contact"] == 0.0] == 0.0)
    assert np.max(np.abs(res["A.bristle"])) > 0.0
    scale = max(np.max(res["system.kinetic_energy"]), np.max(np.abs(res["system.input_work"])),
                np.max(np.abs(res["system.dissipated"])))
    assert np.max(np.abs(res["system.energy_balance"])) <= 12 * 1e-8 * scale
