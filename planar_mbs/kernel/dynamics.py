"""Accelerations of the constrained system (Muvengei et al. eqs. 1-2, Nikravesh).

``M q'' + Cq^T lam = Qe``, ``Cq q'' = gamma - 2 alpha (Cq q' + Ct) - beta^2 C``.
M is diagonal (``km.minv``), so with the Schur complement
``S = Cq M^-1 Cq^T`` (m x m, symmetric positive definite for independent rows):

    lam = S^-1 (Cq M^-1 Qe - gamma_b),   q'' = M^-1 (Qe - Cq^T lam).

Structure is used, never a dense m x n product: each constraint row touches
at most two bodies (the row-sparse Jacobian ``ws.J (m, 2, 3)`` with the bodies
in ``ws.rowbody``), so ``S[r, c]`` is non-zero only when rows r and c share a
body.  ``ws.first[r]`` is the first such row; S is stored and factored in this
*envelope* (profile) form: an envelope Cholesky has no fill outside it, so a
chain of N bodies (block-tridiagonal S) costs O(N) per factorisation instead
of the O(N^3) of a dense one, and small mechanisms lose nothing.  A pivot <=
PIVOT_TOL times its original diagonal entry means dependent (redundant or
singular) rows: Status.SINGULAR with the row index in stats[ST_INFO].
"""
from __future__ import annotations

import math

from .jit import kernel

from ..model import CFG_ALPHA, CFG_BETA, ST_INFO, ST_RHS
from .constraints import body_trig, constraint_rows_eval
from .contact import add_clearance_forces
from .forces import applied_forces

PIVOT_TOL = 1e-12
SINGULAR = 4


@kernel
def schur_factor(km, ws, stats):
    """S = Cq M^-1 Cq^T from ws.J inside the envelope, Cholesky-factored in place
    (lower triangle, rows r: columns first[r]..r)."""
    J = ws.J
    S = ws.S
    rb = ws.rowbody
    first = ws.first
    minv = km.minv
    m = J.shape[0]
    for r in range(m):
        for c in range(first[r], r + 1):
            s = 0.0
            for a1 in range(2):
                b = rb[r, a1]
                if b < 0:
                    continue
                for a2 in range(2):
                    if rb[c, a2] == b:
                        k = 3 * b
                        s += (J[r, a1, 0] * minv[k] * J[c, a2, 0] + J[r, a1, 1] * minv[k + 1] * J[c, a2, 1]
                              + J[r, a1, 2] * minv[k + 2] * J[c, a2, 2])
            S[r, c] = s
        ws.sdiag[r] = S[r, r]
    for j in range(m):
        fj = first[j]
        d = S[j, j]
        for k in range(fj, j):
            d -= S[j, k] * S[j, k]
        if not (d > PIVOT_TOL * ws.sdiag[j]) or not (d > 0.0):
            stats[ST_INFO] = j
            return SINGULAR
        d = math.sqrt(d)
        S[j, j] = d
        for i in range(j + 1, ws.lastrow[j] + 1):
            fi = first[i]
            if fi > j:
                continue
            s = S[i, j]
            for k in range(max(fi, fj), j):
                s -= S[i, k] * S[j, k]
            S[i, j] = s / d
    return 0


@kernel
def schur_solve(ws, x):
    """Solve S x = x in place with the envelope factor in ws.S."""
    L = ws.S
    first = ws.first
    m = x.shape[0]
    for i in range(m):
        s = x[i]
        for k in range(first[i], i):
            s -= L[i, k] * x[k]
        x[i] = s / L[i, i]
    for i in range(m - 1, -1, -1):
        xi = x[i] / L[i, i]
        x[i] = xi
        for k in range(first[i], i):
            x[k] -= L[i, k] * xi


@kernel
def jac_dot(ws, r, v):
    """(Cq v)[r] from the row-sparse Jacobian."""
    s = 0.0
    for a in range(2):
        b = ws.rowbody[r, a]
        if b >= 0:
            k = 3 * b
            s += ws.J[r, a, 0] * v[k] + ws.J[r, a, 1] * v[k + 1] + ws.J[r, a, 2] * v[k + 2]
    return s


@kernel
def jac_t_sub(ws, r, lam_r, minv, scale, out):
    """out -= scale * M^-1 Cq[r]^T lam_r (scale = 1 / 0 chooses M^-1 or not)."""
    for a in range(2):
        b = ws.rowbody[r, a]
        if b >= 0:
            k = 3 * b
            for i in range(3):
                f = minv[k + i] if scale > 0.0 else 1.0
                out[k + i] -= f * ws.J[r, a, i] * lam_r


@kernel
def accelerations(km, cfg, t, q, qd, contact, ws, stats):
    """Fill ws.qdd and ws.lam (and ws.Qe, ws.C, ws.J, ws.Ct, ws.gam, ws.cs) at (t, q, q').

    Returns a Status code: 0, SINGULAR (stats[ST_INFO] = row), BAD_INPUT."""
    body_trig(q, ws.cs)
    st = applied_forces(km, q, qd, ws.cs, ws.Qe)
    if st != 0:
        return st
    if km.clearance_body.shape[0] > 0:
        st = add_clearance_forces(km, q, qd, ws.cs, contact, ws.Qe, stats)
        if st != 0:
            return st
    n = q.shape[0]
    m = ws.C.shape[0]
    minv = km.minv
    if m == 0:
        for k in range(n):
            ws.qdd[k] = minv[k] * ws.Qe[k]
        return 0
    st = constraint_rows_eval(km, q, qd, t, ws.cs, ws.C, ws.J, ws.Ct, ws.gam)
    if st != 0:
        return st
    alpha = cfg[CFG_ALPHA]
    beta = cfg[CFG_BETA]
    # ws.qdd first holds M^-1 Qe
    for k in range(n):
        ws.qdd[k] = minv[k] * ws.Qe[k]
    for r in range(m):
        cd = ws.Ct[r] + jac_dot(ws, r, qd)
        gb = ws.gam[r] - 2.0 * alpha * cd - beta * beta * ws.C[r]
        ws.lam[r] = jac_dot(ws, r, ws.qdd) - gb
    st = schur_factor(km, ws, stats)
    if st != 0:
        return st
    schur_solve(ws, ws.lam)
    for r in range(m):
        jac_t_sub(ws, r, ws.lam[r], minv, 1.0, ws.qdd)
    return 0


@kernel
def rhs(km, cfg, t, y, contact, ws, stats, ydot):
    """First-order form y = (q, q'): ydot = (q', q''). Returns a Status code."""
    n = y.shape[0] // 2
    st = accelerations(km, cfg, t, y[:n], y[n:], contact, ws, stats)
    stats[ST_RHS] += 1
    if st != 0:
        return st
    for k in range(n):
        ydot[k] = y[n + k]
        ydot[n + k] = ws.qdd[k]
    return 0


@kernel
def project(km, t, y, ws, stats):
    """Project q onto C = 0 (Newton: q -= M^-1 Cq^T S^-1 C, a few iterations),
    then q' onto Cq q' + Ct = 0.  Returns a Status code."""
    n = y.shape[0] // 2
    m = ws.C.shape[0]
    if m == 0:
        return 0
    q = y[:n]
    qd = y[n:]
    minv = km.minv
    for it in range(4):
        body_trig(q, ws.cs)
        st = constraint_rows_eval(km, q, qd, t, ws.cs, ws.C, ws.J, ws.Ct, ws.gam)
        if st != 0:
            return st
        err = 0.0
        for r in range(m):
            err = max(err, abs(ws.C[r]))
            ws.b[r] = ws.C[r]
        if err <= 1e-15 or (it > 0 and err <= 1e-14):
            break
        st = schur_factor(km, ws, stats)
        if st != 0:
            return st
        schur_solve(ws, ws.b)
        for r in range(m):
            jac_t_sub(ws, r, ws.b[r], minv, 1.0, q)
    body_trig(q, ws.cs)
    st = constraint_rows_eval(km, q, qd, t, ws.cs, ws.C, ws.J, ws.Ct, ws.gam)
    if st != 0:
        return st
    for r in range(m):
        ws.b[r] = ws.Ct[r] + jac_dot(ws, r, qd)
    st = schur_factor(km, ws, stats)
    if st != 0:
        return st
    schur_solve(ws, ws.b)
    for r in range(m):
        jac_t_sub(ws, r, ws.b[r], minv, 1.0, qd)
    return 0
