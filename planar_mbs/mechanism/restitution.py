"""A law's own dissipation coefficient from the restitution it is to give (docs/contact.md).

The compiler calls these once per contact element, in plain Python (the kernel's `damping_factor`
through `planar_mbs.pykernel`, without numba):

* the laws F = K d^n (1 + chi d'/d'(-)): a free single impact rebounds with the e of
  chi (1 + e) = ln((1 + chi)/(1 - chi e)), whatever K, n, the mass and the impact speed (Gonthier,
  McPhee, Lange & Piedboeuf, Multibody Syst. Dyn. 11 (2004) 209-233); `dissipative_coefficient`
  finds the chi of a stated e, then the law's c_e with that chi;
* the Kelvin-Voigt law F = max(0, K d + c d'): with zeta = c / (2 sqrt(K m)) the linear oscillator
  without the clip rebounds at its half period with e = exp(-pi zeta / sqrt(1 - zeta^2))
  (`linear_zeta`); with the clip the contact ends where F = 0, i.e. where d'' = 0, earlier, and the
  rebound is `kelvin_voigt_restitution` (Schwager & Poeschel, "Coefficient of restitution and
  linear-dashpot model revisited", Granular Matter 9 (2007) 465-469); `kelvin_voigt_zeta` inverts it.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from .. import catalog
from ..lazy import lazy

optimize = lazy("scipy.optimize")  # loaded when a model states an effective restitution
if TYPE_CHECKING:  # the module itself, for type checkers and import-graph tools
    from ..pykernel import contact as pycontact
else:  # loaded on first use
    pycontact = lazy("..pykernel.contact", __package__)  # the kernel's damping_factor, without numba


def _root(f, lo: float, hi: float) -> float:
    return optimize.brentq(f, lo, hi, xtol=1e-300, rtol=1e-15, maxiter=500)


def chi_restitution(chi: float) -> float:
    """e of F = K d^n (1 + chi d'/d'(-)) in a free single impact: the root of
    chi (1 + e) = ln((1 + chi)/(1 - chi e)) in (0, min(1, 1/chi)) (1 for chi = 0), solved in
    s = -ln(1 - chi e), where g = chi (1 + e) - ln(1 + chi) - s falls from chi - ln(1 + chi) > 0."""
    if chi <= 0.0:
        return 1.0

    def g(s):
        return chi * (1 - math.expm1(-s) / chi) - math.log1p(chi) - s

    hi = chi + 1.0 if chi >= 1.0 else -math.log1p(-chi)  # e = 1/chi or e = 1: g < 0
    return -math.expm1(-_root(g, 0.0, hi)) / chi


def restitution_chi(e: float) -> float:
    """chi > 0 with chi (1 + e) = ln((1 + chi)/(1 - chi e)) for 0 < e < 1 (0 for e = 1).

    h = ln(1 + chi) - ln(1 - chi e) - chi (1 + e) is -(1 - e^2) chi^2/2 near 0 and -> +inf at
    chi = 1/e: one root between, solved in s = -ln(1 - chi e) (for a small e the root lies within
    exp(-1/e) of 1/e: chi = -expm1(-s)/e keeps it apart), h > 0 for s > (1 + e)/e."""
    if e >= 1.0:
        return 0.0

    def h(s):
        chi = -math.expm1(-s) / e
        return math.log1p(chi) + s - chi * (1 + e)

    lo = -math.log1p(-0.5 * (1 - e) * e)  # chi = (1 - e)/2, below the root (3 (1 - e^2)/(2 (1 + e^3)) to 2nd order)
    while h(lo) >= 0.0:
        lo *= 0.5
    return -math.expm1(-_root(h, lo, (1 + e) / e + 1.0)) / e


def dissipative_coefficient(law: int, e: float) -> float:
    """c_e of dissipative law `law` (a ContactLaw code) whose single impact rebounds with e: the
    law's chi(c_e), the kernel's `damping_factor`, decreasing from chi(0+) to chi(1) = 0, equals
    `restitution_chi(e)`.  ValueError when e is below the law's reach (chi(0+) too small)."""
    damping_factor = pycontact.damping_factor
    chi = restitution_chi(e)
    if chi == 0.0:
        return 1.0
    lo = 1e-12
    if damping_factor(law, lo) <= chi:
        floor = chi_restitution(damping_factor(law, lo))
        raise ValueError(f"law {catalog.LAWS[law].name} cannot rebound as slowly as {e:g}: its effective "
                         f"restitution is at least {floor:.4g} (its own restitution -> 0)")
    return _root(lambda ce: damping_factor(law, ce) - chi, lo, 1.0)


def linear_zeta(e: float) -> float:
    """zeta of the linear oscillator (no clip) rebounding at its half period pi / omega_d with e:
    e = exp(-zeta pi / sqrt(1 - zeta^2)), zeta = -ln e / sqrt(pi^2 + ln^2 e)."""
    le = math.log(e)
    return -le / math.sqrt(math.pi ** 2 + le * le)


def kelvin_voigt_restitution(zeta: float) -> float:
    """Rebound of m x'' = -max(0, K x + c x') from x = 0, x' = v (Schwager & Poeschel 2007): the
    contact force vanishes at t1, the first zero of x'' after 0, where x' = -v exp(-zeta w0 t1)
    (w0 = sqrt(K/m)); then the body leaves at that speed.  w0 t1 = theta / sqrt(1 - zeta^2),
    theta = atan2(2 zeta s, 2 zeta^2 - 1) with s = sqrt(1 - zeta^2); 2 at zeta = 1;
    ln((zeta + s)/(zeta - s)) / s with s = sqrt(zeta^2 - 1) above."""
    if zeta <= 0.0:
        return 1.0
    if zeta < 1.0:
        s = math.sqrt(1.0 - zeta * zeta)
        w0t1 = math.atan2(2.0 * zeta * s, 2.0 * zeta * zeta - 1.0) / s
    elif zeta == 1.0:
        w0t1 = 2.0
    else:
        s = math.sqrt(zeta * zeta - 1.0)
        w0t1 = math.log((zeta + s) / (zeta - s)) / s
    return math.exp(-zeta * w0t1)


def kelvin_voigt_zeta(e: float) -> float:
    """zeta whose clipped Kelvin-Voigt impact rebounds with e in (0, 1] (`kelvin_voigt_restitution`
    decreases from 1 at zeta = 0 to 0 as zeta -> inf)."""
    if e >= 1.0:
        return 0.0
    hi = 1.0
    while kelvin_voigt_restitution(hi) > e:
        hi *= 2.0
    return _root(lambda z: kelvin_voigt_restitution(z) - e, 0.0, hi)


def kelvin_voigt_damping(K: float, m_eff: float, restitution: float | None = None,
                         effective: float | None = None) -> float:
    """c = 2 zeta sqrt(K m_eff) of the Kelvin-Voigt law, zeta from the linear oscillator's `restitution`
    (`linear_zeta`, its unclipped half-period rebound) or from the `effective` rebound of the clipped law."""
    zeta = linear_zeta(restitution) if effective is None else kelvin_voigt_zeta(effective)
    return 2.0 * zeta * math.sqrt(K * m_eff)
