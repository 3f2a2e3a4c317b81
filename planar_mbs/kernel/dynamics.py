"""Accelerations of the constrained system (Muvengei et al. eqs. 1-2, Nikravesh).

``M q'' + Cq^T lam = Qe``, ``Cq q'' = gamma - 2 alpha (Cq q' + Ct) - beta^2 C``.
M is diagonal (``km.minv``) for rigid bodies; a beam (`kernel/beam.py`) adds its constant block, whose
inverse the compiler formed once (``km.beam_minv``); with the Schur complement
``S = Cq M^-1 Cq^T`` (m x m, symmetric positive semi-definite):

    S lam = Cq M^-1 Qe - gamma_b,   q'' = M^-1 (Qe - Cq^T lam).

Structure is used, never a dense m x n product: each constraint row touches
at most two bodies (the row-sparse Jacobian ``ws.J (m, 2, 3)`` with the bodies
in ``ws.rowbody``), so ``S[r, c]`` is non-zero only when rows r and c share a
body.  ``ws.first[r]`` is the first such row; S is stored and factored in this
*envelope* (profile) form: an envelope Cholesky has no fill outside it, so a
chain of N bodies (block-tridiagonal S, rows in the order of
`planar_mbs.mechanism.ordering`) costs O(N) per factorisation instead of the O(N^3) of a
dense one, and small mechanisms lose nothing.  The envelope is packed row by row
into one array (entry (r, c) at ``ws.ptr[r] + c - first[r]``): a dense m x m array
held the same entries one row of m apart, 7 MB at 321 bodies, and the rows'
cache misses made the cost per right-hand side grow faster than N.

S loses rank at a singular position (for an instant) and with redundant joints
(for good).  S is factored as it is while every pivot stays above TAU of its
diagonal (one solve, exact to rounding: today's mechanisms pay nothing more), or
when the small pivot is only its masses' (`scaled_by_masses`: the same complement
in the heaviest-mass metric factors healthily); otherwise ``S + REG D`` is factored (D the
diagonal of that complement, `regularise`; diag S with equal masses), which stays positive
definite, and the system is solved by iterated Tikhonov regularisation
(`multipliers`): exact to rounding for the well-conditioned part, the
minimum-norm multipliers for redundant rows, and a soft constraint (a penalty of
relative stiffness 1/REG) in the directions that vanish at a singular position,
so the mechanism passes it on its momentum instead of being thrown onto another
assembly branch by huge forces; the kinetic energy that the withheld force lets
escape is given back after the velocity projection (`restore_kinetic_energy`).
Only a pivot of the regularised factor at or below WITHHELD of its diagonal counts as a loss of rank
(`withholds`: reported, and with `projection = auto` projected from then on): a long chain's regular
rows have pivots far below TAU (1e-3 of the diagonal at 800 bars) that the iterated solve resolves
exactly, and are not one.  Only a row without any Jacobian (or a NaN) still gives Status.SINGULAR (row in
stats[ST_INFO]).  docs/numerics.md says why.
"""
from __future__ import annotations

import math

from .jit import kernel

from ..mechanism.model import (CFG_ALPHA, CFG_BETA, CT_ANCHOR, CT_FRICTION, CT_SLIP_DIRECTION, JP_FRICTION,
                               JP_STATIC_FRICTION, SLIP, ST_INFO, ST_RHS, STICK, WL_JFRICTION, Status, work_layout)
from .beam import beam_constraint_force, beam_minv_mul, beam_row, beam_schur_assemble
from .constraints import body_trig, constraint_rows_eval
from .contact import add_clearance_forces
from .forces import applied_forces
from .joint_friction import friction_load, slip_row, small_solve
from .workspace import FL_RANK_LOST, FL_REG_SEEN, FL_SCHUR_REG, FL_STEP_REG  # REG, REFINE, ...: workspace.solver_settings
from .workspace import JW_A0, JW_FREE, JW_LIMIT, JW_S, JW_T, JW_TARGET, JW_V

SINGULAR = 4
EXACT_PIVOT = 1e-12  # relative pivot above which S is factored exactly when only its masses make it badly scaled
DRIFT = 8
JOINT_FRICTION = int(Status.JOINT_FRICTION)
FRICTION_ITER = 100  # fixed-point sweeps of the friction joints' solve (each contracts by about mu r / L)
FRICTION_RTOL = 1e-15  # ... until a sweep changes no friction by more than this, relative: rounding
_work_layout = kernel(work_layout)  # the work channels' first indices, compiled


@kernel
def schur_assemble(minv, J, rb, first, ptr, S, sdiag, reg):
    """S = Cq M^-1 Cq^T from the row-sparse Jacobian J (bodies rb) inside the
    envelope (lower triangle, rows r: columns first[r]..r, packed: (r, c) at
    ptr[r] + c - first[r]), its diagonal kept in sdiag, then S_rr *= 1 + reg.  (Arrays, not the workspace, as arguments: a
    call that numba does not inline passes every array of a tuple.)  A model with beams has its own,
    `beam.beam_schur_assemble`."""
    for r in range(J.shape[0]):
        s = 0.0
        br = ptr[r] - first[r]
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
            S[br + c] = s
        sdiag[r] = s
        S[br + r] = s * (1.0 + reg)


@kernel
def cholesky(S, first, ptr, lastrow, sdiag, tau):
    """Envelope Cholesky of the packed S in place (no fill outside the envelope).
    Returns -1, or the first row j whose pivot is not above tau * sdiag[j]
    (the factor is then incomplete)."""
    for j in range(first.shape[0]):
        fj = first[j]
        bj = ptr[j] - fj
        d = S[bj + j]
        for k in range(fj, j):
            d -= S[bj + k] * S[bj + k]
        if not (d > tau * sdiag[j]) or not (sdiag[j] > 0.0):
            return j
        d = math.sqrt(d)
        S[bj + j] = d
        for i in range(j + 1, lastrow[j] + 1):
            fi = first[i]
            if fi > j:
                continue
            bi = ptr[i] - fi
            s = S[bi + j]
            for k in range(max(fi, fj), j):
                s -= S[bi + k] * S[bj + k]
            S[bi + j] = s / d
    return -1


@kernel(inline=True)
def schur_factor(km, ws, stats):
    """Factor S exactly when every pivot is healthy (above TAU of its diagonal: S is
    well conditioned, one solve is exact to rounding), or when only its masses make a pivot small
    (`scaled_by_masses`); otherwise factor S + REG D for the iterated Tikhonov solve of `multipliers`
    (ws.flags[FL_SCHUR_REG] = 1), D the diagonal of S in the heaviest-mass metric (`regularise`; diag S
    itself with equal masses or beams).  In an eigendirection of relative size s the regularised answer
    is off by (REG / (s + REG))^(REFINE + 1), below rounding for s > TAU: switching is seamless.
    Only a row with no Jacobian at all (or a NaN) fails: SINGULAR."""
    beams = km.beam_info.shape[0] > 0
    if beams:
        beam_schur_assemble(km.minv, ws.J, ws.rowbody, ws.first, ws.ptr, ws.S, ws.sdiag, 0.0,
                            km.body_beam, km.beam_info, km.beam_minv)
    else:
        schur_assemble(km.minv, ws.J, ws.rowbody, ws.first, ws.ptr, ws.S, ws.sdiag, 0.0)
    if cholesky(ws.S, ws.first, ws.ptr, ws.lastrow, ws.sdiag, ws.solver[3]) < 0:
        ws.flags[FL_SCHUR_REG] = 0
        return 0
    if ws.solver[7] != 0.0 and not beams and km.unit_minv.shape[0] > 0:
        if scaled_by_masses(km, ws):
            ws.flags[FL_SCHUR_REG] = 0
            return 0
        schur_assemble(km.minv, ws.J, ws.rowbody, ws.first, ws.ptr, ws.S, ws.sdiag, 0.0)
        regularise(ws, ws.solver[0])
    elif beams:
        beam_schur_assemble(km.minv, ws.J, ws.rowbody, ws.first, ws.ptr, ws.S, ws.sdiag, ws.solver[0],
                            km.body_beam, km.beam_info, km.beam_minv)
    else:
        schur_assemble(km.minv, ws.J, ws.rowbody, ws.first, ws.ptr, ws.S, ws.sdiag, ws.solver[0])
    j = cholesky(ws.S, ws.first, ws.ptr, ws.lastrow, ws.sdiag, 0.0)
    if j >= 0:
        stats[ST_INFO] = j
        return SINGULAR
    ws.flags[FL_SCHUR_REG] = 1
    ws.flags[FL_REG_SEEN] = 1
    ws.flags[FL_STEP_REG] = 1
    if ws.flags[FL_RANK_LOST] == 0 and withholds(ws.S, ws.first, ws.ptr, ws.sdiag, ws.solver[6]):
        ws.flags[FL_RANK_LOST] = 1
    return 0


@kernel(inline=True)
def scaled_by_masses(km, ws):
    """S has a pivot below TAU of its diagonal: is that the mechanism's geometry (a singular position,
    redundant joints, a long chain: then it is regularised) or only its masses (light bodies beside heavy
    ones: pivots down to about the mass ratio of the diagonal, however regular the mechanism)?  The same
    Schur complement in the heaviest-mass metric (km.unit_minv: every body at the heaviest one's mass)
    tells: when it factors with healthy pivots, S is factored exactly (pivots above EXACT_PIVOT, far above
    rounding) and used; returns whether it was.  Its diagonal stays in ws.rdiag for `regularise`.
    (The iterated Tikhonov solve converges by REG / (s + REG) per sweep: at a mass ratio of 1e6 the
    relative eigenvalues s of S come near REG, and it neither converged nor kept the constraints.)"""
    schur_assemble(km.unit_minv, ws.J, ws.rowbody, ws.first, ws.ptr, ws.S, ws.sdiag, 0.0)
    for r in range(ws.rdiag.shape[0]):
        ws.rdiag[r] = ws.sdiag[r]
    if cholesky(ws.S, ws.first, ws.ptr, ws.lastrow, ws.sdiag, ws.solver[3]) >= 0:
        return False
    schur_assemble(km.minv, ws.J, ws.rowbody, ws.first, ws.ptr, ws.S, ws.sdiag, 0.0)
    return cholesky(ws.S, ws.first, ws.ptr, ws.lastrow, ws.sdiag, EXACT_PIVOT) < 0


@kernel(inline=True)
def regularise(ws, reg):
    """S_rr += reg D_rr, D = ws.rdiag (the diagonal in the heaviest-mass metric), written as
    S_rr (1 + reg D_rr / S_rr): with equal masses D = diag S and this is S_rr (1 + reg), bit for bit.
    Regularised in this metric, a direction of S that is small only through light bodies (relative to
    diag S) is not small against D: the sweeps solve it exactly; only the geometry's vanishing directions
    (a singular position, redundant joints) are damped."""
    for r in range(ws.sdiag.shape[0]):
        k = ws.ptr[r] - ws.first[r] + r
        s = ws.sdiag[r]
        ws.S[k] = s * (1.0 + reg * (ws.rdiag[r] / s)) if s > 0.0 else s + reg * ws.rdiag[r]


@kernel
def withholds(L, first, ptr, sdiag, tol):
    """Whether the regularised factor L has a pivot L_jj^2 at or below tol S_jj: a direction
    the iterated solve may leave damped, i.e. the constraints lost rank (a singular position or redundant
    joints).  Rows of a regular mechanism whose pivots are merely small (long chains) are not."""
    for j in range(first.shape[0]):
        d = L[ptr[j] - first[j] + j]
        if d * d <= tol * sdiag[j]:
            return True
    return False


@kernel
def schur_solve(L, first, ptr, x):
    """Solve L L^T x = x in place with the packed envelope factor L of `cholesky`."""
    m = x.shape[0]
    for i in range(m):
        bi = ptr[i] - first[i]
        s = x[i]
        for k in range(first[i], i):
            s -= L[bi + k] * x[k]
        x[i] = s / L[bi + i]
    for i in range(m - 1, -1, -1):
        bi = ptr[i] - first[i]
        xi = x[i] / L[bi + i]
        x[i] = xi
        for k in range(first[i], i):
            x[k] -= L[bi + k] * xi


@kernel(inline=True)
def multipliers(km, ws, x):
    """Solve S x = x in place with the factor of `schur_factor`: one solve when S
    was factored exactly, else iterated Tikhonov regularisation
    (x += (S + REG D)^-1 (b - S x), D = diag S; Riley 1955, the dual form of the
    augmented-Lagrangian iteration of Bayo, Garcia de Jalon and Serna, "A modified
    Lagrangian formulation for the dynamic analysis of constrained mechanical systems").
    Converges to the solution of least sum_r D_rr x_r^2 (the minimum-norm split for
    dependent rows); directions with eigenvalue below ~REG D stay damped (a singular
    position)."""
    if ws.flags[FL_SCHUR_REG] == 0:
        schur_solve(ws.S, ws.first, ws.ptr, x)
    else:
        refine(km, ws, x)


@kernel(inline=True)
def refine(km, ws, x):
    """The iterated Tikhonov solve of `multipliers` (ws.b, ws.res, ws.v as scratch): REFINE
    sweeps, then more while each shrinks the residual by at least RATE (up to 64).  A
    direction of relative eigenvalue s converges by REG / (s + REG) per sweep: those that keep
    their rank, however small the mass ratio makes them, converge to rounding (the residual
    then stalls); only those with s below ~REG / RATE (a singular position) stay damped."""
    m = x.shape[0]
    minv = km.minv
    bnorm = 0.0
    for r in range(m):
        ws.b[r] = x[r]
        bnorm = max(bnorm, abs(x[r]) / math.sqrt(ws.sdiag[r]))
    schur_solve(ws.S, ws.first, ws.ptr, x)
    rold = math.inf
    for it in range(64):
        for k in range(ws.v.shape[0]):
            ws.v[k] = 0.0
        for r in range(m):  # v = M^-1 Cq^T x
            for a in range(2):
                b = ws.rowbody[r, a]
                if b >= 0:
                    k = 3 * b
                    for i in range(3):
                        ws.v[k + i] += minv[k + i] * ws.J[r, a, i] * x[r]
        if km.beam_info.shape[0] > 0:
            beam_constraint_force(ws, x, beam_row(ws, 0))
            beam_minv_mul(km, ws, beam_row(ws, 0), -1.0, ws.v)
        rnorm = 0.0
        for r in range(m):
            ws.res[r] = ws.b[r] - jac_dot(ws, r, ws.v)
            rnorm = max(rnorm, abs(ws.res[r]) / math.sqrt(ws.sdiag[r]))
        if not (rnorm > ws.solver[2] * bnorm) or (it >= ws.solver[1] and not (rnorm <= ws.solver[5] * rold)):
            break
        rold = rnorm
        schur_solve(ws.S, ws.first, ws.ptr, ws.res)
        for r in range(m):
            x[r] += ws.res[r]


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


@kernel(inline=True)
def accelerations(km, cfg, t, q, qd, contact, ws, stats):
    """Fill ws.qdd and ws.lam (and ws.Qe, ws.C, ws.J, ws.Ct, ws.gam, ws.cs) at (t, q, q'), and the
    powers of the loads, drivers and clearance elements in ws.pw (`model.work_layout`).

    Returns a Status code: 0, SINGULAR (stats[ST_INFO] = row), BAD_INPUT."""
    body_trig(q, ws.cs)
    st = applied_forces(km, ws, t, q, qd)
    if st != 0:
        return st
    nf = km.force_type.shape[0]
    nd = km.driver_type.shape[0]
    if km.clearance_body.shape[0] > 0:
        st = add_clearance_forces(km, q, qd, ws.cs, contact, ws.z, ws.zd, ws.Qe, stats, ws.pw, nf + 1 + nd)
        if st != 0:
            return st
    n = q.shape[0]
    m = ws.C.shape[0]
    minv = km.minv
    beams = km.beam_info.shape[0] > 0
    if m == 0:
        for k in range(n):
            ws.qdd[k] = minv[k] * ws.Qe[k]
        if beams:
            beam_minv_mul(km, ws, ws.Qe, 1.0, ws.qdd)
        return 0
    st = constraint_rows_eval(km, q, qd, t, ws.cs, ws.C, ws.J, ws.Ct, ws.gam, ws.xreg, ws.xmode)
    if st != 0:
        return st
    alpha = cfg[CFG_ALPHA]
    beta = cfg[CFG_BETA]
    # ws.qdd first holds M^-1 Qe
    for k in range(n):
        ws.qdd[k] = minv[k] * ws.Qe[k]
    if beams:
        beam_minv_mul(km, ws, ws.Qe, 1.0, ws.qdd)
    for r in range(m):
        cd = ws.Ct[r] + jac_dot(ws, r, qd)
        gb = ws.gam[r] - 2.0 * alpha * cd - beta * beta * ws.C[r]
        ws.lam[r] = jac_dot(ws, r, ws.qdd) - gb
    st = schur_factor(km, ws, stats)
    if st != 0:
        return st
    multipliers(km, ws, ws.lam)
    for r in range(m):
        jac_t_sub(ws, r, ws.lam[r], minv, 1.0, ws.qdd)
    if beams:
        beam_constraint_force(ws, ws.lam, beam_row(ws, 0))
        beam_minv_mul(km, ws, beam_row(ws, 0), 1.0, ws.qdd)
    if km.joint_friction.shape[0] > 0:
        st = joint_friction(km, cfg, q, qd, contact, ws, stats)
        if st != 0:
            return st
    for d in range(nd):  # a driver's power: its row's constraint force -J_r^T lam_r times q'
        r = km.driver_row[d]
        ws.pw[nf + 1 + d] = -ws.lam[r] * jac_dot(ws, r, qd)
    return 0


@kernel
def joint_friction(km, cfg, q, qd, contact, ws, stats):
    """The friction of the ideal joints (`kernel.joint_friction`), solved with the multipliers it changes.

    ws.lam and ws.qdd hold the frictionless solution.  A friction T_f adds J_f^T T_f to Qe, so lambda and
    q'' are linear in the frictions: lambda = lambda_0 + sum U_f T_f, q'' = q''_0 + sum D_f T_f (one Schur
    solve per friction joint on the factor already made).  A slipping joint's friction is
    -mu_k load(lambda) d, d its slip direction; a stuck joint's holds its slip acceleration at
    -2 alpha s' - beta^2 (s - anchor) (the Baumgarte feedback of the joints: it stays at its anchor).  Fixed-point
    sweeps, each solving the stuck joints' small linear system exactly, until no friction changes by more
    than rounding: the friction is that of the reaction it makes, never one step late.  Returns 0, or
    JOINT_FRICTION (stats[ST_INFO] = the friction joint) when the sweeps do not converge."""
    nfj = km.joint_friction.shape[0]
    nc = km.clearance_body.shape[0]
    alpha = cfg[CFG_ALPHA]
    beta = cfg[CFG_BETA]
    for f in range(nfj):
        s, v, gam = slip_row(km, f, q, qd, ws.cs, ws.fJ)
        ws.fs[f, JW_S] = s
        ws.fs[f, JW_V] = v
        a0, free = _friction_response(km, ws, f, gam)
        ws.fs[f, JW_A0] = a0
        ws.fs[f, JW_FREE] = free
        ws.fs[f, JW_T] = 0.0
        ws.fs[f, JW_TARGET] = -2.0 * alpha * v - beta * beta * (s - contact[nc + f, CT_ANCHOR])
    for f in range(nfj):
        for k in range(nfj):
            ws.fG[f, k] = _slip_dot(km, ws, f, ws.fD[k])
    nslip = 0
    for f in range(nfj):
        if int(contact[nc + f, CT_FRICTION]) == SLIP:
            nslip += 1
    for it in range(FRICTION_ITER):
        change = _friction_sweep(km, contact, ws)
        if change < 0.0:
            return _friction_failed(stats, -change - 1.0)
        if not (change < math.inf):  # diverged (each sweep multiplies an error by more than one)
            return _friction_failed(stats, 0.0)
        tmax = 0.0
        for f in range(nfj):
            tmax = max(tmax, abs(ws.fs[f, JW_T]))
        if nslip == 0 or (it > 0 and not (change > FRICTION_RTOL * tmax)):
            break
        if it == FRICTION_ITER - 1:
            return _friction_failed(stats, 0.0)
    _friction_apply(km, ws, nc)
    return 0


@kernel
def _friction_failed(stats, f):
    """JOINT_FRICTION, with friction joint f in stats[ST_INFO]."""
    stats[ST_INFO] = int(f)
    return JOINT_FRICTION


@kernel
def _friction_response(km, ws, f, gam):
    """ws.fD[f] = M^-1 (J_f^T - Cq^T U_f) and ws.fU[f] = U_f = S^-1 Cq M^-1 J_f^T; returns (the slip
    acceleration J_f q''_0 - gamma without friction, J_f M^-1 J_f^T)."""
    minv = km.minv
    D = ws.fD[f]
    U = ws.fU[f]
    for k in range(D.shape[0]):
        D[k] = 0.0
    a0 = -gam
    free = 0.0
    jt = km.joint_friction[f]
    for a in range(2):
        b = km.joint_body[jt, a]
        if b >= 0:
            for i in range(3):
                g = ws.fJ[f, a, i]
                D[3 * b + i] = minv[3 * b + i] * g
                a0 += g * ws.qdd[3 * b + i]
                free += g * minv[3 * b + i] * g
    for r in range(U.shape[0]):
        U[r] = jac_dot(ws, r, D)
    multipliers(km, ws, U)
    for r in range(U.shape[0]):
        jac_t_sub(ws, r, U[r], minv, 1.0, D)
    return a0, free


@kernel
def _slip_dot(km, ws, f, x):
    """J_f x: the rate of friction joint f's slip coordinate for the coordinate rates x."""
    jt = km.joint_friction[f]
    s = 0.0
    for a in range(2):
        b = km.joint_body[jt, a]
        if b >= 0:
            for i in range(3):
                s += ws.fJ[f, a, i] * x[3 * b + i]
    return s


@kernel
def _friction_rows(km, ws, f):
    """The multipliers (l0, l1) of friction joint f's two rows at the frictions ws.fs[:, JW_T]."""
    r = km.joint_row[km.joint_friction[f]]
    l0 = ws.lam[r]
    l1 = ws.lam[r + 1]
    for k in range(km.joint_friction.shape[0]):
        t = ws.fs[k, JW_T]
        l0 += ws.fU[k, r] * t
        l1 += ws.fU[k, r + 1] * t
    return l0, l1


@kernel
def _friction_sweep(km, contact, ws):
    """One sweep: each slipping joint's friction from its load now, then the stuck joints' frictions that
    meet their targets.  Returns the largest change, or -(1 + f) when stuck joint f's slip is already
    fixed by the other constraints (no friction can hold it)."""
    nfj = km.joint_friction.shape[0]
    nc = km.clearance_body.shape[0]
    change = 0.0
    ns = 0
    for f in range(nfj):
        mode = int(contact[nc + f, CT_FRICTION])
        if mode == SLIP:
            l0, l1 = _friction_rows(km, ws, f)
            jt = km.joint_friction[f]
            t = -km.joint_param[jt, JP_FRICTION] * friction_load(km, f, l0, l1) * contact[nc + f, CT_SLIP_DIRECTION]
            change = max(change, abs(t - ws.fs[f, JW_T]))
            ws.fs[f, JW_T] = t
        elif mode == STICK:
            ws.fi[ns] = f
            ns += 1
    if ns == 0:
        return change
    A = ws.fA
    for a in range(ns):
        f = ws.fi[a]
        rhs_f = ws.fs[f, JW_TARGET] - ws.fs[f, JW_A0]
        for k in range(nfj):
            if int(contact[nc + k, CT_FRICTION]) != STICK:
                rhs_f -= ws.fG[f, k] * ws.fs[k, JW_T]
        for b in range(ns):
            A[a, b] = ws.fG[f, ws.fi[b]]
        A[a, ns] = rhs_f
    bad = small_solve(A, ns, ws.fs, ws.fi, JW_FREE)
    if bad >= 0:
        return -(1.0 + ws.fi[bad])
    for a in range(ns):
        f = ws.fi[a]
        change = max(change, abs(A[a, ns] - ws.fs[f, JW_T]))
        ws.fs[f, JW_T] = A[a, ns]
    return change


@kernel
def _friction_apply(km, ws, nc):
    """lambda and q'' with the frictions found; each joint's bound mu_s load(lambda) and its power."""
    nfj = km.joint_friction.shape[0]
    for k in range(nfj):
        t = ws.fs[k, JW_T]
        for r in range(ws.lam.shape[0]):
            ws.lam[r] += ws.fU[k, r] * t
        for i in range(ws.qdd.shape[0]):
            ws.qdd[i] += ws.fD[k, i] * t
    w0 = _work_layout(km.force_type.shape[0], km.driver_type.shape[0], nc, nfj)[WL_JFRICTION]
    for f in range(nfj):
        r = km.joint_row[km.joint_friction[f]]
        jt = km.joint_friction[f]
        ws.fs[f, JW_LIMIT] = km.joint_param[jt, JP_STATIC_FRICTION] * friction_load(km, f, ws.lam[r], ws.lam[r + 1])
        ws.pw[w0 + f] = ws.fs[f, JW_T] * ws.fs[f, JW_V]


@kernel
def rhs(km, cfg, t, y, contact, ws, stats, ydot):
    """First-order form y = (q, q', z): ydot = (q', q'', z'), z the contact elements' own states
    (LuGre's bristles, sigma_0 z: `contact.bristle_rate`; none in most models). Returns a Status code."""
    n = km.minv.shape[0]
    nz = ws.z.shape[0]
    for j in range(nz):
        ws.z[j] = y[2 * n + j]
    st = accelerations(km, cfg, t, y[:n], y[n:2 * n], contact, ws, stats)
    stats[ST_RHS] += 1
    if st != 0:
        return st
    for k in range(n):
        ydot[k] = y[n + k]
        ydot[n + k] = ws.qdd[k]
    for j in range(nz):
        ydot[2 * n + j] = ws.zd[j]
    return 0


# largest kinetic energy (relative) that `project` gives back: the losses at a singular
# passage measured 6e-12 (parallelogram chains N = 2 and 10); a larger loss is not a
# passage on momentum (e.g. a mechanism near rest) and stays removed
RESTORE_BOUND = 1e-6


@kernel
def kinetic_energy2(minv, qd):
    """2 T = q'^T M q' with the diagonal M = 1 / minv."""
    s = 0.0
    for k in range(qd.shape[0]):
        if minv[k] > 0.0:
            s += qd[k] * qd[k] / minv[k]
    return s


@kernel
def restore_kinetic_energy(minv, qd, before, Ct):
    """Scale q' back to the kinetic energy `before` (2T) it had before the velocity
    projection, when the constraints do no work (Ct = 0: no moving driver) and the loss is
    below RESTORE_BOUND.  Ideal workless constraint forces turn the velocity, never shorten
    it: the loss is what a force withheld by the regularised solve near a singular position
    let escape (an energy-preserving projection, Hairer, Lubich and Wanner, "Geometric
    Numerical Integration", IV.4, applied to that loss only)."""
    for r in range(Ct.shape[0]):
        if Ct[r] != 0.0:
            return
    after = kinetic_energy2(minv, qd)
    if not (after > 0.0) or not (before > after) or before > after * (1.0 + RESTORE_BOUND):
        return
    c = math.sqrt(before / after)
    for k in range(qd.shape[0]):
        qd[k] *= c


@kernel
def project(km, t, y, ws, stats):
    """Project q onto C = 0 (Newton: q -= M^-1 Cq^T S^-1 C, a few iterations),
    then q' onto Cq q' + Ct = 0 (mass-orthogonally).  When a factor since the last
    projection was regularised (a singular position's force withheld), the kinetic energy
    the velocity projection removed is given back (`restore_kinetic_energy`).
    Returns a Status code."""
    n = km.minv.shape[0]
    m = ws.C.shape[0]
    if m == 0:
        return 0
    q = y[:n]
    qd = y[n:2 * n]
    minv = km.minv
    for it in range(4):
        body_trig(q, ws.cs)
        st = constraint_rows_eval(km, q, qd, t, ws.cs, ws.C, ws.J, ws.Ct, ws.gam, ws.xreg, ws.xmode)
        if st != 0:
            return st
        err = 0.0
        for r in range(m):
            err = max(err, abs(ws.C[r]))
            ws.dl[r] = ws.C[r]
        if err <= 1e-15 or (it > 0 and err <= 1e-14):
            break
        st = schur_factor(km, ws, stats)
        if st != 0:
            return st
        multipliers(km, ws, ws.dl)
        for r in range(m):
            jac_t_sub(ws, r, ws.dl[r], minv, 1.0, q)
        if km.beam_info.shape[0] > 0:
            beam_constraint_force(ws, ws.dl, beam_row(ws, 0))
            beam_minv_mul(km, ws, beam_row(ws, 0), 1.0, q)
    body_trig(q, ws.cs)
    st = constraint_rows_eval(km, q, qd, t, ws.cs, ws.C, ws.J, ws.Ct, ws.gam, ws.xreg, ws.xmode)
    if st != 0:
        return st
    for r in range(m):
        ws.dl[r] = ws.Ct[r] + jac_dot(ws, r, qd)
    st = schur_factor(km, ws, stats)
    if st != 0:
        return st
    multipliers(km, ws, ws.dl)
    restore = ws.flags[FL_REG_SEEN] == 1 and ws.solver[4] != 0.0
    before = kinetic_energy2(minv, qd) if restore else 0.0
    for r in range(m):
        jac_t_sub(ws, r, ws.dl[r], minv, 1.0, qd)
    if km.beam_info.shape[0] > 0:
        beam_constraint_force(ws, ws.dl, beam_row(ws, 0))
        beam_minv_mul(km, ws, beam_row(ws, 0), 1.0, qd)
    if restore:
        restore_kinetic_energy(minv, qd, before, ws.Ct)
    ws.flags[FL_REG_SEEN] = 0
    return 0


DRIFT_POSITION = 1e-6  # m or rad: bound on |C_r| for fixed-step RK4
DRIFT_VELOCITY = 1e-4  # m/s or rad/s: bound on |Cq q' + Ct|_r for fixed-step RK4


@kernel
def drift_check(ws, qd, stats, pbound, vbound):
    """Constraint residuals at the state of the last right-hand side (ws.C, ws.J, ws.Ct):
    DRIFT (stats[ST_INFO] = row) when a position residual exceeds pbound or a velocity
    residual vbound.  Fixed-step RK4 (DRIFT_*) has no error control: this stops a run
    that has left its constraints (a too long step) instead of returning wrong results.
    (The adaptive methods' check, scaled to the mechanism, is `loop.lost_check`.)"""
    for r in range(ws.C.shape[0]):
        if not (abs(ws.C[r]) <= pbound) or not (abs(ws.Ct[r] + jac_dot(ws, r, qd)) <= vbound):
            stats[ST_INFO] = r
            return DRIFT
    return 0


# `rhs` inlined at the one stage call site of every integrator (`integrators.rk_stages`): one more copy of
# the right-hand side to compile, not one per caller (kernel/jit.py says what was measured)
rhs_inlined = kernel(rhs.py_func, inline=True)
