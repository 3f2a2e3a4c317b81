"""The scipy baseline's right-hand side of the clearance slider-crank: numpy only (no numba), so the
baseline as a whole process (`scipy_baseline.py`) imports what a scipy user's script would.

The equations and their parameter vector are described in `slider_crank_equations`.
"""
from __future__ import annotations

import math

import numpy as np

# parameters: [a, b, m1, I1, m2, I2, m3, I3, omega, alpha, beta, c, RB, RJ, K, n, ce]
P_A, P_B, P_M1, P_I1, P_M2, P_I2, P_M3, P_I3, P_OMEGA, P_ALPHA, P_BETA = range(11)
P_C, P_RB, P_RJ, P_K, P_N, P_CE = range(11, 17)
NPAR = 17


def penetration(y, p):
    """delta = |P_J - P_B| - c at state y (event function of solve_ivp)."""
    q = y[:9]
    ex = q[3] - p[P_B] * math.cos(q[5]) - q[0] - p[P_A] * math.cos(q[2])
    ey = q[4] - p[P_B] * math.sin(q[5]) - q[1] - p[P_A] * math.sin(q[2])
    return math.hypot(ex, ey) - p[P_C]


def normal_velocity(y, p):
    q, qd = y[:9], y[9:]
    a, b = p[P_A], p[P_B]
    a1x, a1y = a * math.cos(q[2]), a * math.sin(q[2])
    a2x, a2y = -b * math.cos(q[5]), -b * math.sin(q[5])
    ex, ey = q[3] + a2x - q[0] - a1x, q[4] + a2y - q[1] - a1y
    e = math.hypot(ex, ey)
    vx = qd[3] - qd[5] * a2y - qd[0] + qd[2] * a1y
    vy = qd[4] + qd[5] * a2x - qd[1] - qd[2] * a1x
    return (vx * ex + vy * ey) / e


def rhs_numpy(t, y, p, mode, vimp):
    """The same equations, written the straightforward numpy way (dense Cq, np.linalg.solve)."""
    q, qd = y[:9], y[9:]
    a, b, w = p[P_A], p[P_B], p[P_OMEGA]
    al, be = p[P_ALPHA], p[P_BETA]
    minv = 1.0 / np.array([p[P_M1], p[P_M1], p[P_I1], p[P_M2], p[P_M2], p[P_I2], p[P_M3], p[P_M3], p[P_I3]])
    c1, s1, c2, s2 = np.cos(q[2]), np.sin(q[2]), np.cos(q[5]), np.sin(q[5])
    Qe = np.zeros(9)
    a1 = np.array([a * c1, a * s1])
    a2 = np.array([-b * c2, -b * s2])
    e = q[3:5] + a2 - q[0:2] - a1
    emag = np.linalg.norm(e)
    if mode and emag - p[P_C] > 0:
        n = e / emag
        v = qd[3:5] + qd[5] * np.array([-a2[1], a2[0]]) - qd[0:2] - qd[2] * np.array([-a1[1], a1[0]])
        vn = v @ n
        F = max(0.0, p[P_K] * (emag - p[P_C]) ** p[P_N] * (1 + 0.75 * (1 - p[P_CE] ** 2) * vn / vimp))
        f = -F * n
        rb, rj = a1 + p[P_RB] * n, a2 + p[P_RJ] * n
        Qe[0:2] -= f
        Qe[2] -= rb[0] * f[1] - rb[1] * f[0]
        Qe[3:5] += f
        Qe[5] += rj[0] * f[1] - rj[1] * f[0]
    Cq = np.zeros((7, 9))
    Cq[0, [0, 2]] = 1, a * s1
    Cq[1, [1, 2]] = 1, -a * c1
    Cq[2, [3, 5, 6]] = 1, -b * s2, -1
    Cq[3, [4, 5, 7]] = 1, b * c2, -1
    Cq[4, 8] = 1
    Cq[5, 7] = 1
    Cq[6, 2] = 1
    C = np.array([q[0] - a * c1, q[1] - a * s1, q[3] + b * c2 - q[6], q[4] + b * s2 - q[7], q[8], q[7],
                  q[2] - w * t])
    Ct = np.array([0, 0, 0, 0, 0, 0, -w])
    gamma = np.array([-a * c1 * qd[2] ** 2, -a * s1 * qd[2] ** 2, b * c2 * qd[5] ** 2, b * s2 * qd[5] ** 2,
                      0, 0, 0])
    rhs_b = gamma - 2 * al * (Cq @ qd + Ct) - be * be * C
    CM = Cq * minv
    lam = np.linalg.solve(CM @ Cq.T, CM @ Qe - rhs_b)
    qdd = minv * (Qe - Cq.T @ lam)
    return np.concatenate([qd, qdd])
