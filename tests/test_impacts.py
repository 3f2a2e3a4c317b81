"""Single journal impacts after a long free flight: every damped law's restitution, for every
adaptive method of the catalog over rtol 1e-4 ... 1e-10 and impact speeds 1e-3 ... 1e-1 m/s, against a
reference integrated here (scipy solve_ivp of the 1-D contact ODE m d'' = -F(d, d')); and
grazing contacts far shallower than a free-flight step is long."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import kernel_models as K
from planar_mbs import catalog
from planar_mbs.mechanism.model import ContactLaw, Integrator, Status, frozen

# every adaptive integrator of the catalog (no hand list): each locates contact events on its dense output
ADAPTIVE = [Integrator(s.code) for s in catalog.INTEGRATORS if s.adaptive]

L = ContactLaw
DAMPED = [L.LANKARANI_NIKRAVESH, L.HUNT_CROSSLEY, L.FLORES, L.GONTHIER]
CHI = {  # chi(ce) of F = K d^n (1 + chi d'/d'(-)), from each law's paper (docs/contact.md)
    L.LANKARANI_NIKRAVESH: lambda ce: 0.75 * (1 - ce ** 2),
    L.HUNT_CROSSLEY: lambda ce: 1.5 * (1 - ce),
    L.FLORES: lambda ce: 1.6 * (1 - ce) / ce,
    L.GONTHIER: lambda ce: (1 - ce ** 2) / ce,
}
M, KC, N, C, CE = 0.21, 1e10, 1.5, 3e-4, 0.8  # journal mass, stiffness, exponent, clearance, restitution


def reference_restitution(law, v):
    """Rebound over impact speed of m d'' = -max(0, K d^n (1 + chi d'/v)), d(0) = 0, d'(0) = v."""
    chi = CHI[law](CE)

    def f(t, y):
        d, dd = y
        F = KC * max(d, 0.0) ** N * (1 + chi * dd / v) if d > 0 else 0.0
        return [dd, -max(F, 0.0) / M]

    def out(t, y):
        return y[0]

    out.terminal, out.direction = True, -1
    tau = (2.5 * M * v * v / (2 * KC)) ** 0.4 / v
    sol = solve_ivp(f, (0, 100 * tau), [0.0, v], method="DOP853", rtol=1e-12, atol=1e-20, events=out,
                    first_step=1e-3 * tau)
    assert sol.t_events[0].size == 1
    return -sol.y_events[0][0, 1] / v


def impact(law, v, method, rtol):
    """(restitution, contact events) of a journal starting centred in a bearing on the ground at
    speed v: free flight over the clearance (long steps), one impact, then free flight back."""
    km, q0, qd0 = K.free_journal(m=M, I=1e-3, clearance=C, K=KC, n=N, law=law, restitution=CE, v0=(v, 0.0))
    t_end = 1.5 * C / v  # the rebound crosses the bearing in > 2 C / v: no second impact
    st, t, rows, y, stats, _ = K.run(km, q0, qd0, K.cfg(integrator=method, rtol=rtol, atol=1e-7 * rtol,
                                                           output_step=t_end), t_end)
    assert st == Status.DONE
    return -y[3] / v, int(stats[3])


@pytest.mark.parametrize("law", DAMPED, ids=lambda x: x.name.lower())
@pytest.mark.parametrize("v", [1e-3, 1e-2, 1e-1])
def test_restitution_of_a_single_impact(law, v):
    ref = reference_restitution(law, v)
    for method in ADAPTIVE:
        for rtol in (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
            e, events = impact(law, v, method, rtol)
            assert events == 1
            assert e == pytest.approx(ref, rel=1e-2), (method.name, rtol)


def grazing_journal(apex, x0=1.5e-4, g=9.81):
    """A journal thrown upwards inside a bearing on the ground, off-centre by x0, whose parabola
    reaches a penetration `apex` at its top (|e| = c + apex there): (km, q0, qd0, apex time)."""
    km, q0, qd0 = K.free_journal(m=M, I=1e-3, clearance=C, K=KC, n=N, law=L.HERTZ, v0=(0.0, 0.0),
                                 offset=(x0, 0.0))
    km = frozen(km._replace(gravity=np.array([0.0, -g])))
    y_top = math.sqrt((C + apex) ** 2 - x0 ** 2)
    vy = math.sqrt(2 * g * y_top)
    qd0 = np.array([0.0, vy, 0.0])
    return km, q0, qd0, vy / g


@pytest.mark.parametrize("method", ADAPTIVE, ids=lambda m: m.name.lower())
def test_grazing_contact_is_detected_at_every_rtol(method):
    """A 0.3 µm apex penetration inside one long free-flight step (gravity alone: the step grows
    until it spans the apex) is found at every rtol; with the apex 0.3 µm short of the wall there
    is no contact."""
    for rtol in (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
        for apex, expected in ((3e-7, True), (-3e-7, False)):
            km, q0, qd0, t_top = grazing_journal(apex)
            st, t, rows, y, stats, _ = K.run(km, q0, qd0, K.cfg(integrator=method, rtol=rtol, atol=1e-7 * rtol,
                                                                   output_step=2 * t_top), 1.5 * t_top)
            assert st == Status.DONE
            assert (stats[3] >= 1) == expected, (rtol, apex, stats[3])
            if not expected:
                assert stats[0] < 40  # long steps: the apex lies inside one of them
