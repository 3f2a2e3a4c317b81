"""Contact between body outlines (`contact` elements) against closed forms and a 1-D integration
derived here: a bouncing disc, a spinning disc landing with friction, a disc cam and its follower."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from planar_mbs import compile_text, simulate

G = 9.81


def law_impact(m, v, K, n=1.5, ce=1.0, chi=None, g=0.0):
    """(restitution, contact duration) of a mass m hitting a fixed wall at speed v with
    F = K d^n (1 + chi d'/v), integrated in 1-D (chi = Lankarani-Nikravesh's 3 (1 - ce^2) / 4 by default),
    pressed on by a weight m g during the contact."""
    chi = 0.75 * (1 - ce * ce) if chi is None else chi

    def f(t, y):
        d, dd = y
        F = max(0.0, K * max(d, 0.0) ** n * (1 + chi * dd / v))
        return [dd, g - F / m]

    ev = lambda t, y: y[0] if t > 0 else 1.0  # noqa: E731
    ev.terminal, ev.direction = True, -1
    s = solve_ivp(f, (0, 1.0), [0.0, v], events=ev, rtol=1e-11, atol=1e-16, max_step=1e-5)
    return -s.y_events[0][0][1] / v, s.t_events[0][0]


DISC = """
param r = 50 mm
body disc {{ mass = 1 kg  inertia = 1.25e-3 kg*m^2  position = (0, {y0})  velocity = ({vx}, 0)  omega = {w}
             shape = circle(r) }}
gravity (0, -9.81)
joint floor = contact(ground (0, 0), disc) {{
    shape = circle_on_line  normal = (0, 1)  radius = r  stiffness = {K}
    law = {law}  {extra}
}}
simulate {{ t_end = {t_end} s  rtol = 1e-10  atol = 1e-13  output_step = {dt} s }}
"""


def onsets(res, name):
    c = res[f"{name}.in_contact"]
    i = np.flatnonzero((c[1:] == 1) & (c[:-1] == 0)) + 1
    return res.time[i]


def test_disc_bounces_with_the_law_restitution_and_closed_form_flight_time():
    h, K, ce = 0.2, 1e8, 0.8
    text = DISC.format(y0=0.05 + h, vx=0, w=0, K=K, law="lankarani_nikravesh", extra=f"restitution = {ce}",
                       t_end=0.6, dt=1e-5)
    res = simulate(compile_text(text))
    v1 = math.sqrt(2 * G * h)
    e, tc = law_impact(1.0, v1, K, ce=ce, g=G)
    t = onsets(res, "floor")
    assert len(t) >= 2
    assert t[0] == pytest.approx(math.sqrt(2 * h / G), abs=2e-5)
    # flight between the bounces: 2 e v / g, plus the first contact's duration
    assert t[1] - t[0] == pytest.approx(tc + 2 * e * v1 / G, abs=3e-5)
    # the apex after the first bounce: (e v)^2 / 2g above the touching height
    k = (res.time > t[0] + tc) & (res.time < t[1])
    apex = res["disc.y"][k].max() - 0.05
    assert apex == pytest.approx((e * v1) ** 2 / (2 * G), rel=2e-3)


@pytest.mark.parametrize("w0, vx0", [(40.0, 0.5), (-5.0, 0.1)])
def test_spinning_disc_landing_with_friction_leaves_with_the_rigid_impact_answer(w0, vx0):
    """Short impact (stiff Hertz contact, e = 1): normal impulse 2 m v; Coulomb friction either slides
    through the impact (tangential impulse mu P_n) or brings the contact point to rest (sticking)."""
    m, I, r, mu, h, K = 1.0, 1.25e-3, 0.05, 0.3, 0.05, 1e12
    v = math.sqrt(2 * G * h)
    text = DISC.format(y0=0.05 + h, vx=vx0, w=w0, K=K, law="hertz",
                       extra=f"friction = {mu}  friction_velocity = 1e-5", t_end=0.13, dt=1e-5)
    res = simulate(compile_text(text))
    Pn = 2 * m * v
    u0 = vx0 + w0 * r  # slip of the contact point (below the centre) before the impact
    w_inv = 1 / m + r * r / I
    Pt = -math.copysign(mu * Pn, u0) if abs(u0) > mu * Pn * w_inv else -u0 / w_inv
    t = onsets(res, "floor")
    after = res.time > t[0] + 2e-3
    i = np.flatnonzero(after)[0]
    assert res["disc.vx"][i] == pytest.approx(vx0 + Pt / m, abs=3e-3 * abs(Pt / m) + 1e-4)
    assert res["disc.omega"][i] == pytest.approx(w0 + r * Pt / I, abs=3e-3 * abs(r * Pt / I) + 1e-3)
    assert res["floor.contact_y"][res["floor.in_contact"] == 1] == pytest.approx(0.0, abs=1e-4)


CAM = """
param e = 10 mm
param Rc = 30 mm
body cam {{ mass = 1 kg  inertia = 1e-3 kg*m^2  position = (e, 0)  shape = circle(Rc) }}
body follower {{ mass = {m} kg  inertia = 1e-3 kg*m^2  position = (0, Rc - {d0} m)  velocity = (0, {v0})
                 shape = box(width = 40 mm, height = 10 mm) }}
joint pivot = revolute(ground (0, 0), cam (-e, 0))
joint guide = translational(ground, follower, axis = (0, 1))
driver spin = rotation(cam, speed = {speed} rad/s)
force ret = spring_damper(ground (0, 0.2), follower) {{ stiffness = {k} N/m  length = {free} m }}
joint touch = contact(follower (0, 0), cam) {{
    shape = circle_on_line  normal = (0, -1)  radius = Rc  law = hertz  stiffness = {K}
}}
simulate {{ t_end = {t_end} s  rtol = 1e-10  atol = 1e-13  output_step = 0.1 ms }}
"""


def cam_run(speed, m=0.2, k=500.0, preload=20.0):
    # spring from (0, 0.2) to the follower at y: tension pulls the follower up when stretched, so the
    # follower must be pushed down: free length longer than the span gives compression (push down)
    span0 = 0.2 - 0.03  # follower at y = Rc at angle 0 (cam centre at (e, 0) -> lift 0 at angle 0)
    free = span0 + (preload + k * 0.01) / k  # compression preload at the lowest lift (y = Rc - e)
    K = 1e10  # starts pressed by the spring's static push P + k e: (P + k e) / K = d0^1.5
    d0 = ((preload + k * 0.01) / K) ** (1 / 1.5)
    text = CAM.format(m=m, speed=speed, k=k, free=free, t_end=4 * 2 * math.pi / speed, v0=0.01 * speed, K=K, d0=d0)
    return simulate(compile_text(text))


def test_cam_follower_follows_the_lift_and_leaves_at_the_closed_form_speed():
    """Flat-faced follower on an eccentric disc cam: lift y = Rc + e sin(theta), so y'' = -e w^2 sin;
    the spring pushes down with P + k (y - (Rc - e)); contact holds while
    N = P + k e (1 + sin) - m e w^2 sin > 0, i.e. up to w* = sqrt((P + 2 k e) / (m e))."""
    m, k, P, e, Rc = 0.2, 500.0, 20.0, 0.01, 0.03
    w_star = math.sqrt((P + 2 * k * e) / (m * e))
    below = cam_run(0.95 * w_star)
    theta = below["cam.phi"]
    lift = Rc + e * np.sin(theta)
    pen = below["touch.penetration"]
    assert below["touch.in_contact"].min() == 1
    assert np.max(np.abs(below["follower.y"] - lift + pen)) < 1e-9  # follows the profile: y = lift - penetration
    assert np.max(pen) < 2e-5  # the contact tolerance: the Hertz compliance at the peak force
    above = cam_run(1.05 * w_star)
    assert above["touch.in_contact"].min() == 0  # the follower jumps
    first = np.flatnonzero(above["touch.in_contact"] == 0)[0]
    # it leaves where N first reaches 0: sin(theta) = (P + k e) / (e (m w^2 - k))
    w = 1.05 * w_star
    s = (P + k * e) / (e * (m * w * w - k))
    assert math.sin(above["cam.phi"][first]) == pytest.approx(s, abs=0.02)


def test_check_reports_what_touches_at_the_start():
    """`mbs check`'s gaps (kinematics.start_gaps, without numba) against the geometry: a disc 3 mm above
    the floor, a ball pressed 2 um into a socket's wall, two circles 1 mm apart."""
    from planar_mbs.mechanism.kinematics import assemble, start_gaps

    text = """
body disc { mass = 1 kg  inertia = 1e-3 kg*m^2  position = (0.01, 0.053)  angle = 30 deg }
body ball { mass = 1 kg  inertia = 1e-3 kg*m^2  position = (1, 0.001002) }
body pin  { mass = 1 kg  inertia = 1e-3 kg*m^2  position = (2.031, 0) }
gravity (0, -9.81)
joint floor = contact(ground (0, 0), disc) { shape = circle_on_line  normal = (0, 1)  radius = 50 mm
                                             stiffness = 1e9  law = hertz }
joint socket = contact(ground (1, 0), ball) { shape = circle_in_circle  first_radius = 6 mm  radius = 5 mm
                                              stiffness = 1e9  law = hertz }
joint pair = contact(ground (2, 0), pin) { shape = circle_on_circle  first_radius = 10 mm  radius = 20 mm
                                           stiffness = 1e9  law = hertz }
"""
    m = compile_text(text)
    q, qd = assemble(m)
    assert start_gaps(m, q) == pytest.approx([0.003, -2e-6, 0.001], abs=1e-12)


@pytest.mark.parametrize("fields, message", [
    ("shape = square  radius = 1 mm  law = hertz  stiffness = 1e9", "shape"),
    ("shape = circle_on_line  normal = (0, 1)  law = hertz", "sharp corner"),
    ("shape = circle_on_line  normal = (0, 1)  first_radius = 1 mm  stiffness = 1e9  law = hertz", "takes no"),
    ("shape = circle_in_circle  first_radius = 1 mm  radius = 2 mm  stiffness = 1e9  law = hertz", "smaller"),
    ("shape = circle_on_line  normal = (0, 1)  radius = 1 mm  stiffness = 1e9  law = esdu78035", "bearing"),
])
def test_bad_contacts_are_refused_with_the_line(fields, message):
    from planar_mbs.errors import ModelError

    text = f"body d {{ mass = 1 kg  inertia = 1 kg*m^2 }}\ngravity (0, -9.81)\njoint J = contact(ground, d) {{ {fields} }}\n"
    with pytest.raises(ModelError) as err:
        compile_text(text, "bad.mbs")
    assert err.value.line == 3 and message in str(err.value)
