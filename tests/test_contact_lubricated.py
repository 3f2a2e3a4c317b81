"""The lubricated revolute joint against the short-bearing theory derived here independently.

A journal spun at a constant speed in a fixed bearing under a constant load settles where the film
carries the load.  The reference integrates Reynolds' short-bearing pressure (Ocvirk; Pinkus and
Sternlicht) numerically over the positive-pressure half of the film (Gümbel's condition), so it shares
no formula with the kernel's closed form (Flores, Ambrósio, Claro, Lankarani, "A study on dynamics of
mechanical systems including joints with clearance and lubrication", Mech. Mach. Theory 2006)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from planar_mbs import compile_text, simulate

MU, R, L, C, OMEGA = 0.04, 10e-3, 10e-3, 50e-6, 2000 * 2 * math.pi / 60


def reynolds_force(eps, omega=OMEGA):
    """(F along the line of centres, F across it) on the journal: p(psi, z) from
    d/dz(h^3 dp/dz) = 6 mu omega dh/dpsi, h = c (1 - eps cos psi), p = 0 at z = +-L/2, negative
    pressures dropped; the force is minus the pressure integrated over the journal's surface."""
    def P(psi):  # pressure integrated over the length: -mu L^3 A / h^3, A = (omega/2) dh/dpsi
        h = C * (1 - eps * math.cos(psi))
        return max(0.0, -MU * L ** 3 * 0.5 * omega * C * eps * math.sin(psi) / h ** 3)
    fr = -R * quad(lambda s: P(s) * math.cos(s), -math.pi, math.pi, limit=200, points=[0.0])[0]
    ft = -R * quad(lambda s: P(s) * math.sin(s), -math.pi, math.pi, limit=200, points=[0.0])[0]
    return fr, ft


def steady_state(load):
    """Eccentricity ratio where the film carries `load`, and the direction of the eccentricity."""
    eps = brentq(lambda e: math.hypot(*reynolds_force(e)) - load, 1e-3, 0.99, xtol=1e-12)
    fr, ft = reynolds_force(eps)
    # the film force (fr e_hat + ft t_hat) balances the load (0, -W): it points up, +y
    angle_e = math.pi / 2 - math.atan2(ft, fr)
    return eps, angle_e


def model_text(load, speed="2000 rpm", breakdown=0.95):
    return f"""
body journal {{ mass = 0.1 kg  inertia = 1e-5 kg*m^2 }}
joint J = lubricated_revolute(ground (0, 0), journal) {{
    clearance = {C * 1e6} um  journal_radius = {R * 1e3} mm  length = {L * 1e3} mm
    viscosity = {MU} Pa*s  breakdown = {breakdown}  law = hertz  stiffness = 1e10
}}
driver spin = rotation(journal, speed = {speed})
force load = constant(journal, force = (0, -{load} N))
simulate {{ t_end = 0.15 s  rtol = 1e-9  atol = 1e-13  output_step = 1 ms }}
"""


@pytest.mark.parametrize("load", [10.0, 40.0, 120.0])
def test_journal_settles_at_the_short_bearing_eccentricity_and_attitude(load):
    eps, angle = steady_state(load)
    res = simulate(compile_text(model_text(load)))
    ex, ey = res["J.ex"][-1], res["J.ey"][-1]
    assert abs(res["J.ex"][-1] - res["J.ex"][-20]) < 1e-4 * C  # settled
    assert math.hypot(ex, ey) / C == pytest.approx(eps, abs=2e-4)
    got = math.atan2(ey, ex)
    assert abs(math.remainder(got - angle, 2 * math.pi)) < 2e-3
    # the attitude angle between the load line and the eccentricity: tan phi = pi sqrt(1 - eps^2) / (4 eps)
    phi = math.atan2(math.pi * math.sqrt(1 - eps * eps), 4 * eps)
    assert abs(math.remainder(got + math.pi / 2, 2 * math.pi)) == pytest.approx(phi, abs=2e-3)
    assert res["J.in_contact"][-1] == 0  # the film carries it: no dry contact
    assert res["J.film_pressure"][-1] > load / (2 * R * L)  # the peak exceeds the mean pressure


def test_reversed_rotation_mirrors_the_attitude():
    eps, angle = steady_state(40.0)
    res = simulate(compile_text(model_text(40.0, speed="-2000 rpm")))
    got = math.atan2(res["J.ey"][-1], res["J.ex"][-1])
    mirrored = math.pi - angle  # mirror image in the load line (the y axis)
    assert abs(math.remainder(got - mirrored, 2 * math.pi)) < 2e-3


def test_film_breaks_down_into_dry_contact_past_the_stated_ratio():
    """A load beyond what the film carries at the breakdown ratio brings the dry law in: the journal
    then rests with dry contact, past eps_b (an onset located as an event)."""
    eps_b = 0.6
    carried = math.hypot(*reynolds_force(eps_b))
    res = simulate(compile_text(model_text(3 * carried, breakdown=eps_b)))
    assert res["J.in_contact"][-1] == 1
    assert res["J.e"][-1] / C > eps_b
    assert res["J.penetration"][-1] > 0


@pytest.mark.parametrize("eps, epsd", [(0.3, 2.0), (0.7, -5.0), (0.9, 1.0)])
def test_film_force_wedge_and_squeeze_terms_are_the_pi_film_integral(eps, epsd):
    """The kernel's closed form (wedge and squeeze terms) against Reynolds' short-bearing pressure with
    the whole wedge-plus-squeeze term A, integrated over the pi-film the wedge fixes (psi in (-pi, 0)),
    while the wedge dominates (|eps w| = 100 |eps'|, where the kernel's s is within 1e-4 of 1)."""
    from planar_mbs.kernel.contact import film_force
    from planar_mbs.mechanism.model import (CP_BREAKDOWN, CP_CLEARANCE, CP_KIND, CP_LENGTH, CP_R_JOURNAL, CP_VISCOSITY,
                                  N_CLEARANCE_PARAM, PairKind)

    w = 100 * abs(epsd) / eps
    p = np.zeros(N_CLEARANCE_PARAM)
    p[CP_CLEARANCE], p[CP_R_JOURNAL], p[CP_LENGTH], p[CP_VISCOSITY] = C, R, L, MU
    p[CP_BREAKDOWN], p[CP_KIND] = 0.99, int(PairKind.LUBRICATED)
    Fr, Ft = film_force(p, eps * C, epsd * C, 0.0, w)

    def P(s):
        A = 0.5 * w * C * eps * math.sin(s) - C * epsd * math.cos(s)
        return -MU * L ** 3 * A / (C * (1 - eps * math.cos(s))) ** 3
    fr = -R * quad(lambda s: P(s) * math.cos(s), -math.pi, 0, limit=200)[0]
    ft = -R * quad(lambda s: P(s) * math.sin(s), -math.pi, 0, limit=200)[0]
    assert Fr == pytest.approx(fr, rel=1e-9)
    assert Ft == pytest.approx(ft, rel=1e-3)
