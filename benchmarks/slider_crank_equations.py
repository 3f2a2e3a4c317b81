"""Muvengei et al.'s slider-crank with a clearance joint at A, written out by hand twice.

Both functions implement exactly the equations planar_mbs builds from
`models/slider_crank_clearance_a.mbs` (Nikravesh body coordinates, Baumgarte
alpha = beta = 5, Lankarani-Nikravesh contact with the located impact velocity):

* `rhs_hand` — the **yardstick**: a numba function that hard-codes this one
  mechanism (every Jacobian entry, gamma term and Schur-complement entry is a
  written-out formula from the known sparsity, the 7x7 Cholesky runs on local
  scratch; no type codes, no loops over joints).  It is what one would write in
  C for this model alone.  `rhs_hand_numpy`-free: it never allocates.
* `rhs_numpy` — the **scipy baseline's** right-hand side: the same equations in
  plain numpy (`Cq` built as a dense array, `np.linalg.solve` on the Schur
  complement), as one would write them for `scipy.integrate.solve_ivp`.

Coordinates q = (x1, y1, phi1, x2, y2, phi2, x3, y3, phi3): crank, rod, slider.
Rows: O (crank on ground, 2), B (rod-slider, 2), S (slider on the x axis, 2),
driver phi1 = omega t (1).  The clearance joint A (bearing on the crank at
(+a, 0), journal on the rod at (-b, 0)) is a force element: with e = P_J - P_B,
delta = |e| - c, n = e/|e|, F = K delta^1.5 (1 + 3(1 - ce^2)/4 delta'/v_imp),
clipped at F >= 0, -F n on the journal at P_J + R_J n and +F n on the bearing at
P_B + R_B n, applied only in contact mode.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from slider_crank_numpy import (  # noqa: F401 - re-exported: the numpy baseline's half
    NPAR, P_A, P_ALPHA, P_B, P_BETA, P_C, P_CE, P_I1, P_I2, P_I3, P_K, P_M1, P_M2, P_M3, P_N, P_OMEGA, P_RB, P_RJ,
    normal_velocity, penetration, rhs_numpy,
)


def parameters(model) -> np.ndarray:
    """The parameter vector of a compiled clearance slider-crank (read from its arrays)."""
    from planar_mbs.mechanism.model import CP_CLEARANCE, CP_EXPONENT, CP_R_BEARING, CP_R_JOURNAL, CP_RESTITUTION, CP_STIFFNESS

    k = model.kernel
    p = np.zeros(NPAR)
    p[P_A] = k.clearance_point[0, 0, 0]
    p[P_B] = -k.clearance_point[0, 1, 0]
    for b in range(3):
        p[P_M1 + 2 * b] = k.body_mass[b]
        p[P_I1 + 2 * b] = k.body_inertia[b]
    p[P_OMEGA] = k.driver_motion_param[0, 1]
    p[P_ALPHA] = model.settings.alpha
    p[P_BETA] = model.settings.beta
    cp = k.clearance_param[0]
    p[P_C], p[P_RB], p[P_RJ] = cp[CP_CLEARANCE], cp[CP_R_BEARING], cp[CP_R_JOURNAL]
    p[P_K], p[P_N], p[P_CE] = cp[CP_STIFFNESS], cp[CP_EXPONENT], cp[CP_RESTITUTION]
    assert abs(k.joint_point[1, 0, 0] - p[P_B]) < 1e-15  # B sits at (+b, 0) on the rod
    return p


@njit(cache=True, fastmath=False, error_model="numpy")
def contact_force_hand(p, q, qd, mode, vimp):
    """(F, nx, ny, arms...) of the clearance joint; F = 0 in free flight."""
    a = p[P_A]
    b = p[P_B]
    c1 = math.cos(q[2])
    s1 = math.sin(q[2])
    c2 = math.cos(q[5])
    s2 = math.sin(q[5])
    # bearing centre on the crank, journal centre on the rod
    a1x = a * c1
    a1y = a * s1
    a2x = -b * c2
    a2y = -b * s2
    ex = q[3] + a2x - q[0] - a1x
    ey = q[4] + a2y - q[1] - a1y
    e = math.sqrt(ex * ex + ey * ey)
    if mode < 0.5 or e - p[P_C] <= 0.0:
        return 0.0, 1.0, 0.0, a1x, a1y, a2x, a2y
    nx = ex / e
    ny = ey / e
    vx = qd[3] - qd[5] * a2y - qd[0] + qd[2] * a1y
    vy = qd[4] + qd[5] * a2x - qd[1] - qd[2] * a1x
    vn = vx * nx + vy * ny
    d = e - p[P_C]
    F = p[P_K] * d ** p[P_N] * (1.0 + 0.75 * (1.0 - p[P_CE] ** 2) * vn / vimp)
    if F < 0.0:
        F = 0.0
    return F, nx, ny, a1x, a1y, a2x, a2y


@njit(cache=True, error_model="numpy")
def rhs_hand(t, y, p, mode, vimp, S, r, ydot):
    """ydot = (q', q'') of the slider-crank with clearance; S (7, 7) and r (7,) are scratch."""
    q = y[:9]
    qd = y[9:]
    a = p[P_A]
    b = p[P_B]
    w = p[P_OMEGA]
    al = p[P_ALPHA]
    be2 = p[P_BETA] * p[P_BETA]
    i1 = 1.0 / p[P_M1]
    j1 = 1.0 / p[P_I1]
    i2 = 1.0 / p[P_M2]
    j2 = 1.0 / p[P_I2]
    i3 = 1.0 / p[P_M3]
    j3 = 1.0 / p[P_I3]
    c1 = math.cos(q[2])
    s1 = math.sin(q[2])
    c2 = math.cos(q[5])
    s2 = math.sin(q[5])
    w1 = qd[2]
    w2 = qd[5]
    # applied forces: the contact only (no gravity in model of Muvengei et al.)
    F, nx, ny, a1x, a1y, a2x, a2y = contact_force_hand(p, q, qd, mode, vimp)
    fx = -F * nx  # on the journal (rod)
    fy = -F * ny
    RB = p[P_RB]
    RJ = p[P_RJ]
    Q0 = -fx
    Q1 = -fy
    Q2 = -((a1x + RB * nx) * fy - (a1y + RB * ny) * fx)
    Q3 = fx
    Q4 = fy
    Q5 = (a2x + RJ * nx) * fy - (a2y + RJ * ny) * fx
    # Jacobian entries (the nonzeros of Cq), constraint values C, gamma, Ct
    # O: x1 - a c1 = 0, y1 - a s1 = 0
    o2x = a * s1
    o2y = -a * c1
    # B: x2 + b c2 - x3 = 0, y2 + b s2 - y3 = 0
    b5x = -b * s2
    b5y = b * c2
    C0 = q[0] - a * c1
    C1 = q[1] - a * s1
    C2 = q[3] + b * c2 - q[6]
    C3 = q[4] + b * s2 - q[7]
    C4 = q[8]
    C5 = q[7]
    C6 = q[2] - w * t
    # Cq q' + Ct
    D0 = qd[0] + o2x * w1
    D1 = qd[1] + o2y * w1
    D2 = qd[3] + b5x * w2 - qd[6]
    D3 = qd[4] + b5y * w2 - qd[7]
    D4 = qd[8]
    D5 = qd[7]
    D6 = w1 - w
    g0 = -a * c1 * w1 * w1
    g1 = -a * s1 * w1 * w1
    g2 = b * c2 * w2 * w2
    g3 = b * s2 * w2 * w2
    # right side Cq M^-1 Qe - (gamma - 2 alpha C' - beta^2 C)
    r[0] = i1 * Q0 + o2x * j1 * Q2 - (g0 - 2.0 * al * D0 - be2 * C0)
    r[1] = i1 * Q1 + o2y * j1 * Q2 - (g1 - 2.0 * al * D1 - be2 * C1)
    r[2] = i2 * Q3 + b5x * j2 * Q5 - (g2 - 2.0 * al * D2 - be2 * C2)
    r[3] = i2 * Q4 + b5y * j2 * Q5 - (g3 - 2.0 * al * D3 - be2 * C3)
    r[4] = 0.0 - (-2.0 * al * D4 - be2 * C4)
    r[5] = 0.0 - (-2.0 * al * D5 - be2 * C5)
    r[6] = j1 * Q2 - (-2.0 * al * D6 - be2 * C6)
    # Schur complement S = Cq M^-1 Cq^T, written from the sparsity (lower triangle)
    S[0, 0] = i1 + o2x * o2x * j1
    S[1, 0] = o2x * o2y * j1
    S[1, 1] = i1 + o2y * o2y * j1
    S[2, 0] = 0.0
    S[2, 1] = 0.0
    S[2, 2] = i2 + b5x * b5x * j2 + i3
    S[3, 0] = 0.0
    S[3, 1] = 0.0
    S[3, 2] = b5x * b5y * j2
    S[3, 3] = i2 + b5y * b5y * j2 + i3
    S[4, 0] = 0.0
    S[4, 1] = 0.0
    S[4, 2] = 0.0
    S[4, 3] = 0.0
    S[4, 4] = j3
    S[5, 0] = 0.0
    S[5, 1] = 0.0
    S[5, 2] = 0.0
    S[5, 3] = -i3
    S[5, 4] = 0.0
    S[5, 5] = i3
    S[6, 0] = o2x * j1
    S[6, 1] = o2y * j1
    S[6, 2] = 0.0
    S[6, 3] = 0.0
    S[6, 4] = 0.0
    S[6, 5] = 0.0
    S[6, 6] = j1
    # Cholesky and the two triangular solves, in place
    for j in range(7):
        d = S[j, j]
        for k in range(j):
            d -= S[j, k] * S[j, k]
        d = math.sqrt(d)
        S[j, j] = d
        for i in range(j + 1, 7):
            s = S[i, j]
            for k in range(j):
                s -= S[i, k] * S[j, k]
            S[i, j] = s / d
    for i in range(7):
        s = r[i]
        for k in range(i):
            s -= S[i, k] * r[k]
        r[i] = s / S[i, i]
    for i in range(6, -1, -1):
        s = r[i]
        for k in range(i + 1, 7):
            s -= S[k, i] * r[k]
        r[i] = s / S[i, i]
    # q'' = M^-1 (Qe - Cq^T lam)
    for k in range(9):
        ydot[k] = qd[k]
    ydot[9] = i1 * (Q0 - r[0])
    ydot[10] = i1 * (Q1 - r[1])
    ydot[11] = j1 * (Q2 - o2x * r[0] - o2y * r[1] - r[6])
    ydot[12] = i2 * (Q3 - r[2])
    ydot[13] = i2 * (Q4 - r[3])
    ydot[14] = j2 * (Q5 - b5x * r[2] - b5y * r[3])
    ydot[15] = i3 * r[2]
    ydot[16] = i3 * (r[3] - r[5])
    ydot[17] = -j3 * r[4]
