"""Extreme mass ratios with the default settings: open chains of bars whose masses alternate by 1e4 to
1e6, against the chain's equations in its joint angles derived here (a second method: minimal
coordinates, no constraints, no multipliers), solved by scipy at tight tolerances.

A bar k of length L, mass m_k and inertia I_k about its centre hangs from bar k - 1; with theta_i its
angle from the downward vertical, its centre is r_k = sum_{i<k} L e(theta_i) + (L/2) e(theta_k),
e(theta) = (sin theta, -cos theta), so

    T = 1/2 sum_ij a_ij cos(theta_i - theta_j) theta_i' theta_j' + 1/2 sum_k I_k theta_k'^2,
    a_ij = sum_k m_k l_ki l_kj,   l_ki = L (i < k), L/2 (i = k), 0 (i > k),
    V = -g sum_k m_k sum_i l_ki cos theta_i,

and Lagrange's equations are sum_j (a_ij cos(theta_i - theta_j) + I_i delta_ij) theta_j''
+ sum_j a_ij sin(theta_i - theta_j) theta_j'^2 + g sin(theta_i) sum_k m_k l_ki = 0.

The light bars make the Schur complement S = Cq M^-1 Cq^T ill-conditioned (pivots 1e-8 of its diagonal)
while the mechanism keeps its full rank; the solver used to treat that as a near-singular position
(regularised solve: 42 times the steps at a ratio of 1e4, a failure, "the constraints gave way", at 1e6).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import planar_mbs as mbs

L, G, HEAVY = 0.1, 9.81, 0.1  # m, m/s^2, kg
START = math.radians(30)


def masses(n, ratio):
    return np.array([HEAVY if k % 2 == 0 else HEAVY / ratio for k in range(n)])


def chain_text(n, ratio, t_end):
    """The chain as a model that names no solver setting: bars at 30 degrees from the vertical, at rest."""
    lines = [f"param L = {L} m\n"]
    for k, m in enumerate(masses(n, ratio).tolist()):
        cx, cy = (k + 0.5) * L * math.sin(START), -(k + 0.5) * L * math.cos(START)
        lines.append(f"body bar{k} {{ mass = {m!r} kg  inertia = {m * L * L / 12!r} kg*m^2  "
                     f"position = ({cx!r} m, {cy!r} m)  angle = {math.degrees(START) - 90!r} deg }}\n")
    lines.append("joint P0 = revolute(ground (0, 0), bar0 (-L/2, 0))\n")
    lines += [f"joint P{k} = revolute(bar{k - 1} (L/2, 0), bar{k} (-L/2, 0))\n" for k in range(1, n)]
    lines.append(f"gravity (0, -{G} m/s^2)\nsimulate {{ t_end = {t_end} s }}\n")
    return "".join(lines)


def angle_equations(n, ratio):
    m = masses(n, ratio)
    inertia = m * L * L / 12
    lev = np.array([[L if i < k else (L / 2 if i == k else 0.0) for i in range(n)] for k in range(n)])
    a = np.einsum("k,ki,kj->ij", m, lev, lev)
    weight = G * (m @ lev)

    def rhs(t, y):
        th, w = y[:n], y[n:]
        d = th[:, None] - th[None, :]
        M = a * np.cos(d) + np.diag(inertia)
        f = -(a * np.sin(d)) @ (w * w) - weight * np.sin(th)
        return np.concatenate([w, np.linalg.solve(M, f)])
    return rhs


def tip_reference(n, ratio, times):
    sol = solve_ivp(angle_equations(n, ratio), (0.0, times[-1]), np.r_[np.full(n, START), np.zeros(n)],
                    method="DOP853", rtol=1e-12, atol=1e-12, t_eval=times)
    th = sol.y[:n]
    return L * np.sin(th).sum(0), -L * np.cos(th).sum(0)


@pytest.mark.parametrize("n, ratio", [(10, 1e4), (20, 1e6)])
def test_alternating_mass_ratios_follow_the_angle_equations(n, ratio):
    """The chain's tip (its last bar's end) over 0.2 s, from the model's defaults, within 1e-6 of the
    chain's length (the default rtol) of the angle equations' solution; no rank loss reported, no
    projection, and at most 1.5 times the steps of the same chain with equal masses (the light bars
    change the motion little: it is as smooth)."""
    t_end = 0.2
    res = mbs.simulate(mbs.compile_text(chain_text(n, ratio, t_end)))
    assert res.attrs["status"] == "done", res.attrs["message"]
    assert not res.attrs["warnings"], res.attrs["warnings"]
    uniform = mbs.simulate(mbs.compile_text(chain_text(n, 1.0, t_end)), signals=["bar0.phi"])
    assert res.attrs["n_steps"] <= 1.5 * uniform.attrs["n_steps"], (res.attrs["n_steps"], uniform.attrs["n_steps"])
    t = np.asarray(res.time)
    phi = np.asarray(res[f"bar{n - 1}.phi"])
    tip_x = np.asarray(res[f"bar{n - 1}.x"]) + 0.5 * L * np.cos(phi)
    tip_y = np.asarray(res[f"bar{n - 1}.y"]) + 0.5 * L * np.sin(phi)
    ref_x, ref_y = tip_reference(n, ratio, t)
    err = np.hypot(tip_x - ref_x, tip_y - ref_y).max()
    assert err < 1e-6 * n * L, err


@pytest.mark.parametrize("coupler", [1e-4, 1e-6])
def test_light_couplers_pass_the_singular_positions_of_the_iftomm_chain(coupler):
    """The IFToMM chain of two four-bar windows with couplers 1e4 and 1e6 times lighter than the cranks:
    twenty singular passages and more, on its branch, the crank tip within 1e-8 m of the closed form
    (the energy equation with the couplers' mass) and the energy within 1e-8, as the uniform chain
    (tests/test_right_by_default.py).  Regularised in diag S, the passages combined with the mass ratio
    stopped the run at the second passage ("the constraints gave way"); regularised in the heaviest-mass
    metric only the geometry's vanishing direction is damped."""
    import chains

    N = 2
    text = chains.parallelogram_chain(N, integrator="dop853", rtol=1e-12, atol=1e-14, coupler_mass=coupler)
    res = mbs.simulate(mbs.compile_text(text))
    assert res.attrs["status"] == "done", res.attrs["message"]
    theta, _ = chains.crank_angle_reference(N, res.time, coupler_ratio=coupler)
    assert math.pi / 2 - theta[-1] > 20 * math.pi
    tips = [np.hypot(np.asarray(res[f"crank{i}.x"]) + 0.5 * np.cos(np.asarray(res[f"crank{i}.phi"])) - i
                     - np.cos(theta),
                     np.asarray(res[f"crank{i}.y"]) + 0.5 * np.sin(np.asarray(res[f"crank{i}.phi"])) - np.sin(theta))
            for i in range(N + 1)]
    assert max(float(d.max()) for d in tips) <= 1e-8
    E = np.asarray(res["system.total_energy"])
    assert np.abs(E - E[0]).max() <= 1e-8 * abs(E[0])
