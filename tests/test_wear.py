"""Worn bearings (kernel/wear.py) and Archard wear coupled to the motion (run/wear.py), against closed forms
derived here: a uniformly worn bearing is a larger circle; an elliptical bearing's nearest point and normal;
the spline's fourth-order convergence; a journal spinning under a constant load wears V = k_d W s / L with
the Winkler overlap's shape; halving the extrapolation step; no wear runs the unworn code bit for bit."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from planar_mbs import compile_text
from planar_mbs.mechanism.model import CT_WEAR_NODES, N_CONTACT_STATE
from planar_mbs.pykernel import contact as pycontact
from planar_mbs.pykernel import wear as pywear
from planar_mbs.run.stepper import Stepper
from planar_mbs.run.wear import Archard, WearRun, halving_check, profile_columns, spline_at, with_profile


def _contact(depth, nc=1, k=0):
    return with_profile(np.zeros((nc, N_CONTACT_STATE)), k, np.asarray(depth, dtype=float))


# ----------------------------------------------------------------------------- geometry of the profile
def test_a_zero_profile_is_the_circle_and_takes_the_unworn_path():
    assert profile_columns(np.zeros(64))[0] == 0.0
    c = _contact(np.zeros(64))
    assert not pywear.worn(c, 0) and not pywear.worn(np.zeros((1, N_CONTACT_STATE)), 0)
    assert pywear.worn(_contact(np.full(64, 1e-6)), 0)


def test_a_uniformly_worn_bearing_is_a_larger_circle():
    """Depth w0 everywhere: the bearing of radius R_B + w0, so delta = |p| - (R_B + w0 - R_J), n = p/|p|."""
    rb, rj, w0 = 5e-3, 4.9e-3, 3e-6
    c = _contact(np.full(90, w0))
    for ang in np.linspace(-3, 3, 13):
        e = 1.02e-4
        px, py = e * math.cos(ang), e * math.sin(ang)
        d, nx, ny, cx, cy, th = pywear.worn_contact(c, 0, rb, rj, px, py)
        assert d == pytest.approx(e - (rb + w0 - rj), abs=1e-15)
        assert nx == pytest.approx(math.cos(ang), abs=1e-12) and ny == pytest.approx(math.sin(ang), abs=1e-12)


def _ellipse_nearest(a, b, px, py):
    """Nearest point of the ellipse (a cos t, b sin t) to p: the root of d/dt |x(t) - p|^2 / 2 near p's angle."""
    g = lambda t: (a * math.cos(t) - px) * (-a * math.sin(t)) + (b * math.sin(t) - py) * (b * math.cos(t))
    t0 = math.atan2(py * a, px * b)
    t = brentq(g, t0 - 0.3, t0 + 0.3, xtol=1e-15)
    return a * math.cos(t), b * math.sin(t)


def test_an_elliptical_bearing_gives_the_ellipse_s_nearest_point_and_normal():
    """Profile r(theta) of the ellipse x^2/a^2 + y^2/b^2 = 1 on 720 nodes: penetration, contact point and
    normal against the ellipse's own nearest point and gradient, to the spline's accuracy."""
    a, b, rj = 5e-3, 4.98e-3, 4.9e-3
    th = 2 * math.pi * np.arange(720) / 720
    r = a * b / np.sqrt((b * np.cos(th)) ** 2 + (a * np.sin(th)) ** 2)
    c = _contact(r - a)
    for ang in (0.3, 1.1, 2.0, 2.9, 4.0, 5.5):
        e = 1.2e-4
        px, py = e * math.cos(ang), e * math.sin(ang)
        qx, qy = _ellipse_nearest(a, b, px, py)
        d, nx, ny, cx, cy, t = pywear.worn_contact(c, 0, a, rj, px, py)
        # r is interpolated to 5/384 h^4 |r| ~ 1e-14 m, its slope to ~h^3 |r| / 24 ~ 4e-13: the
        # penetration (stationary in theta) to ~1e-14, the point along the surface to R_B^2 dr' / f'' ~ 2e-11 m
        # with f'' ~ R_B (R_B - R_J) (a conformal contact: its point is ill-conditioned, its depth is not)
        assert (cx, cy) == pytest.approx((qx, qy), abs=5e-11)
        assert d == pytest.approx(rj - math.hypot(qx - px, qy - py), abs=1e-13)
        gx, gy = qx / a ** 2, qy / b ** 2  # the ellipse's outward normal (unit below)
        gx, gy = gx / math.hypot(gx, gy), gy / math.hypot(gx, gy)
        assert nx * gy - ny * gx == pytest.approx(0.0, abs=1e-8) and nx * gx + ny * gy > 0


def test_the_periodic_spline_converges_at_fourth_order():
    f = lambda t: 1e-6 * (np.cos(3 * t) + 0.5 * np.sin(5 * t))
    t = np.linspace(0, 2 * math.pi, 1001)
    errs = [np.max(np.abs(spline_at(f(2 * math.pi * np.arange(n) / n), t) - f(t))) for n in (64, 128, 256)]
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(orders > 3.8), orders


def test_worn_kinematics_rates_are_the_time_derivatives_on_a_rotating_bearing():
    """A bearing on a turning, moving body, a bumpy worn profile: vn is d delta/dt (central differences
    along the motion), vt the tangential relative velocity of the material points at the contact."""
    model = compile_text("""
body b { mass = 1 kg  inertia = 1e-3 kg*m^2 }
body j { mass = 1 kg  inertia = 1e-3 kg*m^2 }
joint A = clearance_revolute(b, j) { clearance = 0.1 mm  bearing_radius = 5 mm  stiffness = 1e9 N/m^1.5  law = hertz }
""")
    km = model.kernel
    th = 2 * math.pi * np.arange(180) / 180
    c = _contact(2e-5 * np.exp(-((th - 1.0) / 0.4) ** 2) + 5e-6 * np.cos(3 * th))
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = np.array([1e-3, -2e-3, rng.uniform(-3, 3), 1e-3, -2e-3, 0.0])
        ang = rng.uniform(-3, 3)
        q[3:5] += 1.1e-4 * np.array([math.cos(ang), math.sin(ang)])
        qd = rng.normal(size=6) * np.array([0.1, 0.1, 50, 0.1, 0.1, 50])
        kin = pycontact.pair_kinematics(km, 0, q, qd, c)
        eps = 1e-8
        dp = pycontact.pair_kinematics(km, 0, q + eps * qd, qd, c)[3]
        dm = pycontact.pair_kinematics(km, 0, q - eps * qd, qd, c)[3]
        assert kin[6] == pytest.approx((dp - dm) / (2 * eps), rel=1e-6, abs=1e-9)
        ex, ey, e, d, nx, ny, vn, vt, rix, riy, rjx, rjy = kin
        vi = qd[0:2] + qd[2] * np.array([-riy, rix])  # material point velocities at the two contact points
        vj = qd[3:5] + qd[5] * np.array([-rjy, rjx])
        assert vt == pytest.approx((vj - vi) @ np.array([-ny, nx]), rel=1e-12, abs=1e-12)


# ----------------------------------------------------------------------------- Archard on a spinning journal
SPIN = """
param omega = 100 rad/s
body journal {{ mass = 1 kg  inertia = 1e-4 kg*m^2 }}
joint J = clearance_revolute(ground (0, 0), journal) {{
    clearance = 0.1 mm  bearing_radius = 5 mm  length = 10 mm  law = {law} {extra}
    offset = (0, {y})
}}
driver spin = rotation(journal, speed = omega)
gravity (0, -10 m/s^2)
simulate {{ t_end = 1 s  rtol = 1e-10  atol = 1e-13  output_step = 0.5 ms }}
"""
W, K, C, RB, RJ, L, OMEGA = 10.0, 1e9, 1e-4, 5e-3, 4.9e-3, 1e-2, 100.0
DELTA0 = (W / K) ** (1 / 1.5)  # Hertz equilibrium under the weight


def _spin(law="hertz", extra="stiffness = 1e9 N/m^1.5"):
    return compile_text(SPIN.format(y=f"{-C} m", law=law, extra=extra), "spin.mbs")


def _at_rest(model, delta0=DELTA0, **settings):
    """A trajectory with the journal at rest at its equilibrium straight below the centre, e = c + delta_0
    (an offset may not exceed the clearance: the state is set before the first step)."""
    st = Stepper(model, **settings)
    st.y[1] = -(C + delta0)
    return st


def test_a_journal_spinning_under_a_constant_load_wears_archard_s_volume_and_the_winkler_shape():
    """Fixed profile (one update), load W at rest on the bottom: V = k_d W s / L with s = R_J omega T, and
    the depth at each node the Winkler overlap of the journal at e = c + delta_0 straight below,
    delta(psi) = e cos psi + sqrt(R_J^2 - e^2 sin^2 psi) - R_B, scaled to that volume."""
    kd, T = 1e-12, 0.05
    model = _spin()
    h = WearRun(model, "J", Archard(kd, T, nodes=360), stepper=_at_rest(model)).run()
    V = kd * W * (RJ * OMEGA * T) / L
    assert h.volume() == pytest.approx(V, rel=1e-6)
    th = h.theta
    psi = th - 1.5 * math.pi
    e = C + DELTA0
    overlap = np.maximum(e * np.cos(psi) + np.sqrt(RJ ** 2 - (e * np.sin(psi)) ** 2) - RB, 0.0)
    expected = V * overlap / (RB * (2 * math.pi / 360) * overlap.sum())
    np.testing.assert_allclose(h.depths[-1], expected, rtol=0, atol=1e-6 * expected.max())
    # the patch's edge: delta(psi) = 0, near arccos(c / e) = 17.1 degrees (the first-order e cos psi - c)
    edge = math.degrees(brentq(lambda x: e * math.cos(x) + math.sqrt(RJ ** 2 - (e * math.sin(x)) ** 2) - RB, 0, 1))
    assert abs(edge - math.degrees(math.acos(C / e))) < 1.5
    worn = np.degrees(np.abs(psi[h.depths[-1] > 0]))
    assert worn.max() < edge < worn.max() + 1.0  # the last node inside, at 1 degree spacing
    assert h.max_angle() == pytest.approx(1.5 * math.pi)


def test_zero_wear_runs_the_unworn_code_bit_for_bit():
    """coefficient 0: the profile stays the circle and every row equals a plain segmented run's."""
    model = _spin()
    run = WearRun(model, "J", Archard(0.0, 0.01, factor=10, updates=3, nodes=90))
    plain = Stepper(model)
    for _ in range(3):
        t0 = run.stepper.t
        a = run.stepper.run_to(t0 + 0.01)
        b = plain.run_to(t0 + 0.01)
        assert run.stepper.contact[0, CT_WEAR_NODES] == 0.0
        np.testing.assert_array_equal(a[1], b[1])


def test_halving_the_extrapolation_step_changes_the_wear_little_and_converges_at_first_order():
    """The same worn time (0.4 s, the groove's depth about 0.35 delta_0, so the patch widens as it wears)
    with factors 10, 5, 2.5 on a Kelvin-Voigt contact (damped: the journal settles into the new groove
    within each interval; output every 0.1 ms): the worn volume stays V = k_d W s / L (the mean contact force is W); the
    maximum depth changes by under 1.5 % at the last halving, and each change is about half the last
    (first order in the extrapolation step)."""
    kd, d0 = 2e-11, 5e-6  # d0 = W / K
    model = _spin("kelvin_voigt", "stiffness = 2e6 N/m  restitution = 0.05")
    start = lambda: _at_rest(model, d0, output_step="0.1 ms")
    first = halving_check(model, "J", Archard(kd, 0.01, factor=10, updates=4, nodes=360), start)
    second = halving_check(model, "J", Archard(kd, 0.01, factor=5, updates=8, nodes=360), start)
    V = kd * W * RJ * OMEGA * 0.4 / L
    for v in first["volume"] + second["volume"]:
        # the rectangle rule on the output grid errs during the settling after each update, in proportion
        # to the output step (1.4e-3 at 0.5 ms, 3.3e-4 at 0.1 ms for the factor 10)
        assert v == pytest.approx(V, rel=5e-4)
    c1, c2 = first["depth_change"], second["depth_change"]
    assert c2 < 0.015 and 1.6 < c1 / c2 < 2.6, (c1, c2)
    assert second["max_depth"][1] < first["max_depth"][0]  # the wider patch wears more slowly at its peak


# ----------------------------------------------------------------------------- the language
WORN = """
param speed = 600 rpm
body b {{ mass = 1 kg  inertia = 1e-3 kg*m^2 }}
joint J = clearance_revolute(ground (0, 0), b) {{ clearance = 0.1 mm  bearing_radius = 5 mm  {length}
    stiffness = 1e9 N/m^1.5  law = hertz  wear = {wear} }}
"""


def test_a_joint_writes_its_wear_and_k_d_is_k_over_h():
    m = compile_text(WORN.format(length="length = 10 mm", wear="archard(coefficient = 1e-4, hardness = 2 GPa, "
                                 "update = 2 rev / speed, factor = 50, updates = 3, nodes = 180)"))
    w = Archard.of(m, "J")
    assert w.coefficient == pytest.approx(1e-4 / 2e9, rel=1e-15)
    assert w.interval == pytest.approx(2 / 10.0, rel=1e-15)  # 2 revolutions at 10 rev/s
    assert (w.factor, w.updates, w.nodes) == (50.0, 3, 180)


@pytest.mark.parametrize("length, wear, message", [
    ("length = 10 mm", "archard(coefficient = 1e-4, update = 1 s)", "needs `hardness`"),
    ("length = 10 mm", "archard(coefficient = 1e-4, hardness = 2 GPa, update = 1 m)", "update"),
    ("length = 10 mm", "archard(coefficient = -1, hardness = 2 GPa, update = 1 s)", "must be >= 0"),
    ("length = 10 mm", "archard(coefficient = 1e-4, hardness = 2 GPa, update = 1 s, nodes = 4)", "at least 8"),
    ("length = 10 mm", "archad(coefficient = 1e-4, hardness = 2 GPa, update = 1 s)", "did you mean|archard"),
    ("", "archard(coefficient = 1e-4, hardness = 2 GPa, update = 1 s)", "needs `length`"),
])
def test_bad_wear_settings_are_model_errors_at_their_place(length, wear, message):
    from planar_mbs.errors import ModelError
    with pytest.raises(ModelError, match=message) as info:
        compile_text(WORN.format(length=length, wear=wear), "w.mbs")
    assert "w.mbs:" in str(info.value)


# ----------------------------------------------------------------------------- file, resume, figure
def test_a_wear_run_saved_and_resumed_goes_on_as_one_run(tmp_path):
    """4 updates in one go against 2, stopped, resumed from the file to 4: the same history (the resumed
    integrator restarts its step, so equal to the integration's tolerance, not bit for bit)."""
    from planar_mbs.run.wear import load_history
    model = _spin("kelvin_voigt", "stiffness = 2e6 N/m  restitution = 0.05")
    wear = Archard(2e-11, 0.01, factor=10, updates=4, nodes=180)
    whole = WearRun(model, "J", wear, _at_rest(model, 5e-6)).run(output=tmp_path / "a.h5")
    part = WearRun(model, "J", Archard(2e-11, 0.01, factor=10, updates=2, nodes=180), _at_rest(model, 5e-6))
    part.run(output=tmp_path / "b.h5")
    assert len(load_history(tmp_path / "b.h5").depths) == 3
    resumed = WearRun.resume(model, tmp_path / "b.h5", updates=4).run(output=tmp_path / "b.h5")
    back = load_history(tmp_path / "a.h5")
    assert len(back.depths) == len(resumed.depths) == 5
    np.testing.assert_array_equal(back.depths[-1], whole.depths[-1])
    np.testing.assert_allclose(resumed.depths[-1], whole.depths[-1], rtol=0, atol=1e-6 * whole.max_depth())
    assert resumed.worn_times[-1] == pytest.approx(0.4)


def test_the_polar_figure_draws_each_chosen_profile():
    from planar_mbs.outputs.wear_plot import wear_figure
    model = _spin()
    h = WearRun(model, "J", Archard(1e-12, 0.01, factor=5, updates=3, nodes=90), stepper=_at_rest(model)).run()
    fig = wear_figure(h, period=2 * math.pi / OMEGA, curves=3)
    polar = fig.axes[0]
    assert len(polar.lines) == 3
    r = polar.lines[-1].get_ydata()
    assert r.max() == pytest.approx(h.max_depth() * 1e6)


def test_a_chain_with_two_clearance_joints_wears_the_chosen_one_by_archard_s_volume():
    """A double pendulum hanging by two clearance joints (the second bearing on the swinging first bar),
    with friction (so the slip velocity is a signal): only the second wears, and its worn volume per unit
    width is k_d sum(F |v_T| dt) / L over the samples whatever the distribution over the nodes."""
    model = compile_text("""
body a { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0.1 m, 0) }
body b { mass = 0.5 kg  inertia = 0.005 kg*m^2  position = (0.3 m, 0) }
joint O = clearance_revolute(ground (0, 0), a (-0.1 m, 0)) { clearance = 0.1 mm  bearing_radius = 5 mm
    length = 10 mm  stiffness = 1e10 N/m^1.5  law = lankarani_nikravesh  restitution = 0.8  friction = 0.1 }
joint P = clearance_revolute(a (0.1 m, 0), b (-0.1 m, 0)) { clearance = 0.1 mm  bearing_radius = 5 mm
    length = 10 mm  stiffness = 1e10 N/m^1.5  law = lankarani_nikravesh  restitution = 0.8  friction = 0.1 }
gravity (0, -9.81 m/s^2)
simulate { t_end = 1 s  rtol = 1e-9  atol = 1e-12  output_step = 0.1 ms }
""", "chain.mbs")
    kd = 1e-12
    run = WearRun(model, "P", Archard(kd, 0.15, factor=1, updates=2, nodes=180))
    st = run.stepper
    volumes = []
    for _ in range(2):
        dh = run.step()
        volumes.append(float(dh.sum()) * 5e-3 * 2 * math.pi / 180)
    assert run.history.volume() > 0 and not np.any(st.contact[0, CT_WEAR_NODES:])
    assert st.contact[1, CT_WEAR_NODES] == 180
    # the second interval again, from the same start, on a plain trajectory with the same profile: the signals
    again = WearRun(model, "P", Archard(kd, 0.15, factor=1, updates=2, nodes=180))
    again.step()
    t0 = again.stepper.t
    times, rows = again.stepper.run_to(t0 + 0.15)
    sig = again.stepper.signals(rows)
    dt = np.diff(np.concatenate([[t0], times]))
    expected = kd * np.sum(sig["P.contact_force"] * np.abs(sig["P.slip_velocity"]) * dt) / 1e-2
    assert volumes[1] == pytest.approx(expected, rel=1e-12)


def test_the_numbers_of_the_wear_page_are_the_script_s():
    """docs/wear.md quotes docs/wear_slider_crank.json (written by docs/scripts/wear_slider_crank.py)."""
    import json
    from pathlib import Path
    docs = Path(__file__).resolve().parents[1] / "docs"
    page = (docs / "wear.md").read_text(encoding="utf-8")
    facts = json.loads((docs / "wear_slider_crank.json").read_text())
    for speed, f in facts.items():
        assert f"{f['max_depth_um']} µm at {f['max_angle_deg']:.0f}°" in page, speed
        assert f"{f['mean_depth_um']} µm" in page and f"{f['clearance_max_mm']:.3f} mm" in page
        assert f"{f['share_50_circumference'] * 100:.1f} % / {f['share_90_circumference'] * 100:.1f} %" in page
        assert f"{f['halving_depth_change'] * 100:.2f} %" in page
        assert f"{f['cycles_worn']:,} cycles".replace(",", " ") in page


def test_a_depth_step_updates_the_profile_every_stated_worn_depth():
    """`depth_step`: each update's deepest increment is the step, and the first update stands for the time
    the Winkler peak needs to wear it at the closed-form rate k_d (W/L) R_J omega max(delta)/(R_B dtheta
    sum(delta)) (the journal at e = c + delta_0 under W)."""
    model = _spin()
    step = 2e-7
    h = WearRun(model, "J", Archard(1e-12, 0.01, updates=3, nodes=360, depth_step=step), _at_rest(model)).run()
    for i in range(1, 4):
        assert np.max(h.depths[i] - h.depths[i - 1]) == pytest.approx(step, rel=1e-12)
    psi = h.theta - 1.5 * math.pi
    e = C + DELTA0
    overlap = np.maximum(e * np.cos(psi) + np.sqrt(RJ ** 2 - (e * np.sin(psi)) ** 2) - RB, 0.0)
    rate = 1e-12 * W / L * RJ * OMEGA * overlap.max() / (RB * (2 * math.pi / 360) * overlap.sum())
    assert h.worn_times[1] == pytest.approx(step / rate, rel=1e-6)
    m = compile_text(WORN.format(length="length = 10 mm", wear="archard(coefficient = 1e-4, hardness = 2 GPa, "
                                 "update = 1 s, depth_step = 2 um)"))
    assert Archard.of(m, "J").depth_step == pytest.approx(2e-6)


def test_the_million_cycles_of_the_wear_page_are_the_benchmark_s():
    """docs/wear.md, "A million cycles", quotes docs/wear_million_cycles.json (benchmarks/wear_million_cycles.py):
    its table row by row, and the changes on halving the depth step."""
    import json
    from pathlib import Path
    docs = Path(__file__).resolve().parents[1] / "docs"
    page = (docs / "wear.md").read_text(encoding="utf-8")
    facts = json.loads((docs / "wear_million_cycles.json").read_text())
    for r in facts["runs"]:
        row = (f"| {r['depth_step_um']:g} µm | {r['updates']} | {r['wall_s']:.1f} s | {r['update_over_motion']:.3f} | "
               f"{r['max_depth_um']:.1f} µm | {r['volume_mm2']:.4f} mm² | {r['clearance_max_mm']:.3f} mm |")
        assert row in page, row
    for key in ("halving_depth_change", "second_halving_depth_change"):
        assert f"{facts[key] * 100:.1f} %" in page, key
    assert facts["machine"] in page
