"""The flexible connecting rod of models/slider_crank_flexible_rod.mbs against a second method derived
here: the kineto-elastodynamic model of an elastic connecting rod (small deflections of a pinned-pinned
Euler-Bernoulli beam carried by the rigid mechanism's motion, one Galerkin mode), as in the linear
analyses of the elastic slider-crank (e.g. I.G. Tadjbakhsh and C.J. Younis, "Dynamic stability of the
flexible connecting rod of a slider crank mechanism", J. Mech. Trans. Autom. Des. 108 (1986)).

The rod's chord A-B moves as the rigid rod does (its length changes only by the axial strain, ~1e-5):
with the crank turning at a constant rate w, crank pin A = r (cos phi, sin phi), the slider's pin B on the
x axis, the chord's angle theta with sin theta = -r sin phi / L.  The deflection v(s, t) from the chord,
in the chord's frame, obeys

    rho A (v_tt - theta'^2 v) + EI v_ssss - (N v_s)_s = -rho A a_n(s),     v = v_ss = 0 at s = 0, L,

a_n(s) = a_A . n + s theta'' the rigid rod's acceleration normal to the chord and N(s) the axial force
that carries the rod's own axial inertia and the slider's (the slider pushes B along the guide with
m_s x_B'').  With v = q(t) sin(pi s / L):

    q'' + [omega_1^2 - theta'^2 + (2 / (rho A L)) int N (pi/L)^2 cos^2(pi s/L) ds] q
        = -(2/L) int a_n sin(pi s/L) ds = -(4/pi) a_A . n - (2 L / pi) theta'',

q(0) = q'(0) = 0 (the beam starts straight with the rigid rod's velocities), and the midpoint deflection
is q.  Its neglected parts are the higher modes (the load's projection falls as 1/k and the response as
1/k^4: mode 3 adds below 0.5 % of mode 1's static share) and the terms of second order in v.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import planar_mbs as mbs

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "scripts"))
from flexible_clearance import midpoint_deflection  # noqa: E402

# models/slider_crank_flexible_rod.mbs, read back from the compiled model where it says them
R, L = 0.05, 0.12  # m: crank, rod
E, RHO, WIDTH, HEIGHT = 207e9, 7800.0, 0.010, 0.003  # the rod's steel and section (height in the plane)
SLIDER_MASS = 0.14
SPEED = 3000 * 2 * math.pi / 60


def chord_motion(t):
    """The rigid rod's chord at times t: theta, theta', theta'', the crank pin's acceleration normal and
    along the chord, and the slider's acceleration (closed forms of the slider-crank's kinematics)."""
    phi = SPEED * t
    s = -R * np.sin(phi) / L
    c = np.sqrt(1.0 - s * s)
    theta = np.arcsin(s)
    dth = -R * SPEED * np.cos(phi) / (L * c)  # d/dt of sin theta = -r sin(phi)/L
    ddth = (R * SPEED ** 2 * np.sin(phi) / L + dth ** 2 * s) / c  # d/dt of cos(theta) theta' = -r w cos(phi)/L
    aA = -SPEED ** 2 * R * np.stack([np.cos(phi), np.sin(phi)])
    tang = np.stack([np.cos(theta), np.sin(theta)])
    norm = np.stack([-np.sin(theta), np.cos(theta)])
    # B = A + L (cos theta, sin theta): its x acceleration
    aBx = aA[0] - L * (ddth * np.sin(theta) + dth ** 2 * np.cos(theta))
    return dth, ddth, (aA * norm).sum(0), (aA * tang).sum(0), aBx, tang


def modal_midpoint(t_end, t_eval, slider_mass=SLIDER_MASS):
    """The one-mode kineto-elastodynamic midpoint deflection q(t) (m), positive to the chord's left."""
    area, inertia = WIDTH * HEIGHT, WIDTH * HEIGHT ** 3 / 12.0
    rho_a = RHO * area
    w1sq = E * inertia / rho_a * (math.pi / L) ** 4

    def rhs(t, y):
        dth, ddth, aAn, aAt, aBx, tang = chord_motion(np.array([t]))
        # N(s) = F_B . t - rho A int_s^L a_t ds', a_t(s') = a_A . t - s' theta'^2, with F_B the slider's
        # force on the rod: along x, -m_s x_B''; normal to the chord, what turns the rod about A,
        # F_B . n = I_A theta'' / L + (m / 2) a_A . n, I_A = m L^2 / 3 (the cable has no rotary inertia)
        m = rho_a * L
        fbx = -slider_mass * aBx[0]
        fbn = m * L * ddth[0] / 3.0 + 0.5 * m * aAn[0]
        ct, st = tang[0, 0], tang[1, 0]
        fby = (fbn + fbx * st) / ct
        fbt = fbx * ct + fby * st
        axial = fbt - rho_a * (aAt[0] * (L - SQ) - dth[0] ** 2 * (L * L - SQ * SQ) / 2.0)
        geo = (2.0 / (rho_a * L)) * (math.pi / L) ** 2 * np.sum(WQ * axial * np.cos(math.pi * SQ / L) ** 2)
        load = -(4.0 / math.pi) * aAn[0] - (2.0 * L / math.pi) * ddth[0]
        return [y[1], load - (w1sq - dth[0] ** 2 + geo) * y[0]]

    sol = solve_ivp(rhs, (0.0, t_end), [0.0, 0.0], method="DOP853", rtol=1e-10, atol=1e-14, t_eval=t_eval)
    return sol.y[0]


# Gauss-Legendre points on [0, L] for the axial force's integral
_X, _W = np.polynomial.legendre.leggauss(24)
SQ, WQ = 0.5 * L * (_X + 1.0), 0.5 * L * _W


def simulate_rod(elements, revolutions):
    text = (ROOT / "models" / "slider_crank_flexible_rod.mbs").read_text(encoding="utf-8")
    model = mbs.compile_text(text.replace("elements = 4", f"elements = {elements}"),
                             path=ROOT / "models" / "slider_crank_flexible_rod.mbs")
    nodes = [f"rod_node{k}" for k in range(elements + 1)]
    return mbs.simulate(model, revolutions=revolutions, per_rev=2000, signals=["crank.phi", *nodes])


def test_the_model_says_what_the_second_method_assumes():
    text = (ROOT / "models" / "slider_crank_flexible_rod.mbs").read_text(encoding="utf-8")
    for needle in ("param speed = 3000 rpm", "E = 207 GPa", "density = 7800 kg/m^3", "length = 0.12 m",
                   "section = rectangle(width = 10 mm, height = 3 mm)", "mass = 0.14 kg", "elements = 4",
                   "(-0.025 m, 0)", "(0.025 m, 0), rod (start)"):
        assert needle in text, needle
    assert "gravity" not in text  # no weight: the second method has none


def test_midpoint_deflection_follows_the_kineto_elastodynamic_mode():
    """Over one crank revolution the shipped rod's (4 elements) midpoint deflection follows the one-mode
    model: its peak (0.39 mm) within 2 % and the whole history within 4 % of the peak (both carry the rod's
    free vibration at its first frequency, excited by the start).  Measured when written: peak 0.6 %,
    history 2.4 % with 4 elements and 2.2 % with 8 (what is left is the one-mode model's own error, the
    terms it neglects); the model without the slider's axial load (the rod's geometric stiffness) is more
    than 10 % off (28 % measured), so the comparison sees the axial force's coupling."""
    elements = 4
    res = simulate_rod(elements, revolutions=1)
    t = np.asarray(res.time)
    ours = midpoint_deflection(res)
    ref = modal_midpoint(float(t[-1]), t)
    peak = np.abs(ref).max()
    print(f"peak ours {np.abs(ours).max():.4e}  modal {peak:.4e}  largest difference {np.abs(ours - ref).max():.3e}")
    assert np.abs(ours).max() == pytest.approx(peak, rel=0.02)
    assert np.abs(ours - ref).max() < 0.04 * peak
    unloaded = modal_midpoint(float(t[-1]), t, slider_mass=0.0)  # the comparison sees the axial force
    assert np.abs(ours - unloaded).max() > 0.1 * peak


def test_the_cost_section_of_the_beams_page_is_the_benchmark_s():
    """docs/beams.md "Cost" shows the tables `benchmarks/beam_cost.py` renders from its JSON, and what the
    page says of them holds: each element count within 2 % of the fitted line, the rigid rod's steps a
    revolution, thousands of times the rigid rod's steps with 8 elements."""
    import json

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import beam_cost

    data = json.loads((ROOT / "docs" / "beam_cost.json").read_text(encoding="utf-8"))
    page = (ROOT / "docs" / "beams.md").read_text(encoding="utf-8")
    assert beam_cost.markdown(data) in page
    assert data["machine"].split(",")[0] in page.split("## Cost")[1].split("|")[0]
    assert max(abs(r["fit_deviation"]) for r in data["per_step"]) < 0.02
    assert [r["elements"] for r in data["per_step"]] == list(beam_cost.ELEMENTS)
    text = " ".join(page.split())
    assert f"{data['ratio']['rigid']['steps'] // 2} steps a revolution" in text
    assert "costs thousands of times the rigid one" in text and 1000 < data["ratio"]["steps_ratio"] < 10000
