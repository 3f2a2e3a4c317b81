"""Explicit Runge-Kutta steps with dense output, driven by the tableaux of `catalog.INTEGRATORS`.

A method is data (a Butcher tableau with its error weights, error rule and dense-output rows; the
catalog describes them, tests/test_kernel_integrators.py checks the order conditions and measures
the order of every one); this module turns them into arrays indexed by the method code and has one
trial step (`rk_trial`), one error norm (`solution_and_error`), one end stage (`end_stage`) and one
dense output (`dense_prepare`, `dense_eval`) for all of them.

Error norms and step-size control as in Hairer, Norsett & Wanner, *Solving ODEs I*, §II.4:
``sc_i = atol + rtol max(|y0_i|, |y1_i|)``; rule "rms" (code DOPRI5):
``err = sqrt(mean((h sum_j E_j k_j,i / sc_i)^2))``; rule "dop853" (code DOP853, a 5th- and a 3rd-order
estimate): ``err = |h| |err5|^2 / sqrt(N (|err5|^2 + 0.01 |err3|^2))``;
``h_new = h min(FAC_MAX, max(FAC_MIN, SAFETY err^(-1/(q+1))))`` with q the order of the estimate;
the initial step follows Hairer's ``hinit``.

Dense output: "hermite", the cubic Hermite interpolant of the end-point states and derivatives
(RK4, Bogacki-Shampine 3(2)); "rows", Hairer's form y0 + x (F_0 + (1 - x) (F_1 + x (F_2 + ...))) with
rows F_r = dy_r (y1 - y0) + h sum_j D_rj k_j - prev_r F_(r-1) (dopri5.f ``contd5``, dop853.f ``contd8``;
tests compare DOPRI5's with SciPy's ``RK45.P``).  Stages after the end stage that only the dense
output reads (DOP853's three) are evaluated lazily (`dense_prepare`), only for a step that has an
output time or a possible contact event in it.  A method without dense output, or an unknown code,
gets NaN from `dense_eval` and is refused by the time loop (Status.BAD_INPUT): never another
method's interpolant.
"""
from __future__ import annotations

import math

import numpy as np
from .jit import kernel

from .. import catalog
from ..mechanism.model import CFG_ATOL, CFG_RTOL, Status
from .dynamics import rhs, rhs_inlined
from .workspace import DN_H, DN_TA, FL_DENSE_METHOD, FL_DENSE_READY, N_DENSE_ROWS, N_STAGES

NONFINITE = int(Status.NONFINITE)

SAFETY = 0.9
FAC_MIN = 0.2
FAC_MAX = 10.0

ERR_NONE, ERR_RMS, ERR_DOP853 = (catalog.ERROR_RULES.index(r) for r in ("none", "rms", "dop853"))
DENSE_NONE, DENSE_HERMITE, DENSE_ROWS = (catalog.DENSE_RULES.index(r) for r in ("none", "hermite", "rows"))
BAD_METHOD = -2  # stats[ST_INFO] of a BAD_INPUT for an unknown method or one without dense output


def _tables(specs):
    """The catalog's tableaux as arrays indexed by method code (zero-padded to the largest)."""
    m = len(specs)
    ns = N_STAGES
    t = {"A": np.zeros((m, ns, ns)), "C": np.zeros((m, ns)), "B": np.zeros((m, ns)), "E": np.zeros((m, 2, ns)),
         "DW": np.zeros((m, N_DENSE_ROWS, ns)), "DJ": np.zeros((m, N_DENSE_ROWS, ns), dtype=np.int64),
         "DN": np.zeros((m, N_DENSE_ROWS), dtype=np.int64), "DY": np.zeros((m, N_DENSE_ROWS)),
         "DP": np.zeros((m, N_DENSE_ROWS)), "AW": np.zeros((m, ns, ns)),
         "AJ": np.zeros((m, ns, ns), dtype=np.int64), "AN": np.zeros((m, ns), dtype=np.int64)}
    for s in specs:
        for i, row in enumerate(s.a):
            t["A"][s.code, i, :len(row)] = row
            nz = [j for j, a in enumerate(row) if a != 0.0]  # zero terms skipped: the same sums
            t["AN"][s.code, i] = len(nz)
            t["AJ"][s.code, i, :len(nz)] = nz
            t["AW"][s.code, i, :len(nz)] = [row[j] for j in nz]
        t["C"][s.code, :s.stages] = s.c
        t["B"][s.code, :len(s.b)] = s.b
        for r, row in enumerate(s.error):
            t["E"][s.code, r, :len(row)] = row
        for r, row in enumerate(s.dense_rows):
            nz = [j for j, w in enumerate(row.k) if w != 0.0]  # zero terms skipped: the same sums
            t["DN"][s.code, r] = len(nz)
            t["DJ"][s.code, r, :len(nz)] = nz
            t["DW"][s.code, r, :len(nz)] = [row.k[j] for j in nz]
            t["DY"][s.code, r] = row.dy
            t["DP"][s.code, r] = row.prev
    return t


_T = _tables(catalog.INTEGRATORS)
RK_A, RK_C, RK_B, RK_E = _T["A"], _T["C"], _T["B"], _T["E"]
STAGE_W, STAGE_J, STAGE_NZ = _T["AW"], _T["AJ"], _T["AN"]  # each stage's non-zero A_sj and their j
DENSE_W, DENSE_J, DENSE_NZ, DENSE_DY, DENSE_PREV = _T["DW"], _T["DJ"], _T["DN"], _T["DY"], _T["DP"]
N_METHODS = len(catalog.INTEGRATORS)


def _per_method(f, dtype=np.int64):
    return np.array([f(s) for s in catalog.INTEGRATORS], dtype=dtype)


TRIAL_STAGES = _per_method(lambda s: len(s.b))  # stages of a trial step (k_1 included)
END_STAGE = _per_method(lambda s: s.end_stage)  # row of ws.K holding f at the end of the step (FSAL)
STAGES = _per_method(lambda s: s.stages)
EXTRA_STAGES = _per_method(lambda s: s.stages - max(len(s.b), s.end_stage + 1))  # read by the dense output only
ERROR_RULE = _per_method(lambda s: catalog.ERROR_RULES.index(s.error_rule))
DENSE_RULE = _per_method(lambda s: catalog.DENSE_RULES.index(s.dense))
DENSE_ROWS_OF = _per_method(lambda s: len(s.dense_rows))
ADAPTIVE = _per_method(lambda s: s.adaptive, np.bool_)
METHOD_ORDER = _per_method(lambda s: s.order)
# the step controller's exponent 1/(q+1) of an error estimate of order q
ERROR_EXPONENT = _per_method(lambda s: 1.0 / (s.error_order + 1) if s.adaptive else 0.0, np.float64)
RICHARDSON = _per_method(lambda s: 2.0 ** s.order - 1.0, np.float64)  # two half steps against one


@kernel
def method_ok(method):
    """A known method code with a dense output (the time loop refuses any other)."""
    return 0 <= method < N_METHODS and DENSE_RULE[method] != DENSE_NONE


@kernel
def rk_stages(method, km, cfg, t, h, contact, ws, stats, first, last, y0):
    """Stages first..last-1 of a step from (t, y0) into ws.K (stage arguments in ws.ys); for a trial
    step (first = 1) also k1 = ws.f before them and, after them, the new state ws.yb and the error
    norm (`solution_and_error`).  Returns (status, err).  The one place that evaluates stages, with
    the right-hand side inlined (`dynamics.rhs_inlined`: one copy to compile, no call per stage).  The
    trial step's work stays in one function: with the error norm outside it a DOPRI5 trial step on
    the double pendulum took 2.25 us instead of 1.91 us."""
    N = y0.shape[0]
    K = ws.K
    C = RK_C[method]
    if first == 1:
        for i in range(N):
            K[0, i] = ws.f[i]
        for i in range(ws.pw.shape[0]):  # the powers of each stage beside it (`kernel.work`)
            ws.pk[0, i] = ws.pf[i]
    ys = ws.ys
    for s in range(first, last):
        # sum_j A_sj k_j summed in ys, stage by stage over the whole state (contiguous), the zero
        # A_sj skipped (DOP853's rows are a third zeros): the same sums, bit for bit, for finite k_j
        for i in range(N):
            ys[i] = 0.0
        for n in range(STAGE_NZ[method, s]):
            a = STAGE_W[method, s, n]
            j = STAGE_J[method, s, n]
            for i in range(N):
                ys[i] += a * K[j, i]
        for i in range(N):
            ys[i] = y0[i] + h * ys[i]
        st = rhs_inlined(km, cfg, t + C[s] * h, ws.ys, contact, ws, stats, K[s])
        if st != 0:
            return st, math.inf
        for i in range(ws.pw.shape[0]):
            ws.pk[s, i] = ws.pw[i]
    if first != 1:
        return 0, 0.0
    return 0, solution_and_error(method, cfg, y0, h, ws)


@kernel(inline=True)
def rk_trial(method, km, cfg, t, y, h, contact, ws, stats):
    """One trial step of `method` from (t, y) with k1 = ws.f: its stages in ws.K, the new state in
    ws.yb.  Returns (status, err): err is the error norm of an adaptive method (inf when the trial
    produced NaN or infinity), 0 for a fixed-step one."""
    # `1 + 0 * method`, not a literal 1: numba compiles a function once more for each literal argument
    return rk_stages(method, km, cfg, t, h, contact, ws, stats, 1 + 0 * method, TRIAL_STAGES[method], y)


@kernel(inline=True)
def solution_and_error(method, cfg, y, h, ws):
    """ws.yb = y + h sum_j b_j k_j (the last stage's argument when it is the FSAL stage) and the
    method's error norm (module docstring; 0 for a fixed-step method, inf for NaN or infinity)."""
    N = y.shape[0]
    K = ws.K
    ns = TRIAL_STAGES[method]
    rule = ERROR_RULE[method]
    fsal = END_STAGE[method] < ns
    B = RK_B[method]
    E1 = RK_E[method, 0]
    E2 = RK_E[method, 1]
    rtol = cfg[CFG_RTOL]
    atol = cfg[CFG_ATOL]
    e1 = 0.0
    e2 = 0.0
    for i in range(N):
        acc = 0.0
        a1 = 0.0
        a2 = 0.0
        if rule == ERR_DOP853:  # one pass over the stages, a loop per case (no branch inside)
            for j in range(ns):
                k = K[j, i]
                acc += B[j] * k
                a1 += E1[j] * k
                a2 += E2[j] * k
        elif fsal:
            for j in range(ns):
                a1 += E1[j] * K[j, i]
        else:
            for j in range(ns):
                k = K[j, i]
                acc += B[j] * k
                a1 += E1[j] * k
        yb = ws.ys[i] if fsal else y[i] + h * acc
        ws.yb[i] = yb
        if rule == ERR_NONE:
            continue
        sc = atol + rtol * max(abs(y[i]), abs(yb))
        if rule == ERR_RMS:
            r = h * a1 / sc
            e1 += r * r
        else:
            e1 += (a1 / sc) ** 2
            e2 += (a2 / sc) ** 2
    if rule == ERR_NONE:
        return 0.0
    if rule == ERR_RMS:
        err = math.sqrt(e1 / N)
    else:
        if e1 == 0.0 and e2 == 0.0:
            return 0.0
        err = abs(h) * e1 / math.sqrt((e1 + 0.01 * e2) * N)
    if not (err < math.inf):
        err = math.inf
    return err


@kernel
def scaled_error(method, cfg, y, h, ws, i):
    """|h sum_j E_j k_j,i| / sc_i of state component i in the last trial step (the first error row)."""
    e = 0.0
    for j in range(TRIAL_STAGES[method]):
        e += RK_E[method, 0, j] * ws.K[j, i]
    return abs(h * e) / (cfg[CFG_ATOL] + cfg[CFG_RTOL] * max(abs(y[i]), abs(ws.yb[i])))


@kernel(inline=True)
def end_stage(method, km, cfg, t, h, contact, ws, stats):
    """The FSAL stage f(t + h, yb) of an accepted step when the trial step did not evaluate it."""
    ke = END_STAGE[method]
    if ke < TRIAL_STAGES[method]:
        return 0
    st = rhs(km, cfg, t + h, ws.yb, contact, ws, stats, ws.K[ke])
    for i in range(ws.pw.shape[0]):
        ws.pk[ke, i] = ws.pw[i]
    return st


@kernel
def fixed_step(method, km, cfg, t, y, h, contact, ws, stats):
    """One step of a fixed-step method: result in ws.yb, f(yb) in ws.K[END_STAGE].  Returns a Status
    code (NONFINITE on NaN/inf)."""
    st, err = rk_trial(method, km, cfg, t, y, h, contact, ws, stats)
    if st != 0:
        return st
    st = end_stage(method, km, cfg, t, h, contact, ws, stats)
    if st != 0:
        return st
    ke = END_STAGE[method]
    for i in range(y.shape[0]):
        if not (math.isfinite(ws.yb[i]) and math.isfinite(ws.K[ke, i])):
            return NONFINITE
    return 0


@kernel(inline=True)
def dense_pending(ws):
    """The last step's dense output still needs `dense_prepare` (stages only it reads, not yet done)."""
    method = ws.flags[FL_DENSE_METHOD]
    return ws.flags[FL_DENSE_READY] == 0 and 0 <= method < N_METHODS and EXTRA_STAGES[method] > 0


@kernel
def dense_prepare(km, cfg, contact, ws, stats):
    """The stages that only the dense output of the last accepted step reads (DOP853's three), and its
    rows ws.F; once per step (ws.flags[FL_DENSE_READY] = 1).  Methods without such stages leave their
    rows to `dense_eval`.  Returns a Status code."""
    method = ws.flags[FL_DENSE_METHOD]
    if ws.flags[FL_DENSE_READY] == 1 or not method_ok(method) or EXTRA_STAGES[method] == 0:
        return 0
    first = STAGES[method] - EXTRA_STAGES[method]
    st, err = rk_stages(method, km, cfg, ws.dense[DN_TA], ws.dense[DN_H], contact, ws, stats, first, STAGES[method],
                        ws.ya)
    if st != 0:
        return st
    dense_rows(method, ws)
    return 0


@kernel(inline=True)
def dense_rows(method, ws):
    """Rows F_r = dy_r (yb - ya) + h sum_j D_rj k_j - prev_r F_(r-1) of the dense output (module
    docstring) into ws.F; ws.flags[FL_DENSE_READY] = 1."""
    h = ws.dense[DN_H]
    K = ws.K
    F = ws.F
    N = ws.ya.shape[0]
    for r in range(DENSE_ROWS_OF[method]):
        # sum_j D_rj k_j summed in F[r] term by term over the whole state (contiguous, as `rk_stages`;
        # the same sums): component by component, with the terms' rows gathered, DOPRI5's time loop on
        # the clearance slider-crank was 1.04x that of its hand-written dense output
        for i in range(N):
            F[r, i] = 0.0
        for n in range(DENSE_NZ[method, r]):
            w = DENSE_W[method, r, n]
            j = DENSE_J[method, r, n]
            for i in range(N):
                F[r, i] += w * K[j, i]
        dyr = DENSE_DY[method, r]
        pr = DENSE_PREV[method, r]
        for i in range(N):
            prev = F[r - 1, i] if r > 0 else 0.0
            F[r, i] = dyr * (ws.yb[i] - ws.ya[i]) + h * F[r, i] - pr * prev
    ws.flags[FL_DENSE_READY] = 1


@kernel
def hermite_eval(ws, theta, out, kend):
    """Cubic Hermite interpolant of the last step from ya, yb, K[0] = f(ya) and
    K[kend] = f(yb): 4th order, no extra stage (event screening of DOP853)."""
    h = ws.dense[DN_H]
    th = theta
    h00 = (2.0 * th - 3.0) * th * th + 1.0
    h10 = ((th - 2.0) * th + 1.0) * th
    h01 = (3.0 - 2.0 * th) * th * th
    h11 = (th - 1.0) * th * th
    K = ws.K
    for i in range(out.shape[0]):
        out[i] = h00 * ws.ya[i] + h01 * ws.yb[i] + h * (h10 * K[0, i] + h11 * K[kend, i])


@kernel(inline=True)
def initial_step(km, cfg, t, y, contact, ws, stats, hmax, order):
    """Hairer's starting step (hinit) for a method of the given order from
    ws.f = f(t, y); uses ws.ys, ws.yt."""
    N = y.shape[0]
    rtol = cfg[CFG_RTOL]
    atol = cfg[CFG_ATOL]
    d0 = 0.0
    d1 = 0.0
    for i in range(N):
        sc = atol + rtol * abs(y[i])
        d0 += (y[i] / sc) ** 2
        d1 += (ws.f[i] / sc) ** 2
    d0 = math.sqrt(d0 / N)
    d1 = math.sqrt(d1 / N)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, hmax)
    for i in range(N):
        ws.ys[i] = y[i] + h0 * ws.f[i]
    st = rhs(km, cfg, t + h0, ws.ys, contact, ws, stats, ws.yt)
    if st != 0:
        return h0
    d2 = 0.0
    for i in range(N):
        sc = atol + rtol * abs(y[i])
        d2 += ((ws.yt[i] - ws.f[i]) / sc) ** 2
    d2 = math.sqrt(d2 / N) / h0
    dm = max(d1, d2)
    if not (dm < math.inf):
        return h0 * 1e-3
    if dm <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / dm) ** (1.0 / (order + 1.0))
    return min(100.0 * h0, h1, hmax)


@kernel
def dense_eval(ws, theta, out):
    """Dense output of the last accepted step at t = ta + theta h (ws.dense[0:2]) from ws.ya, ws.yb,
    ws.K and the rows ws.F (`dense_prepare` first for a method with dense-only stages); method code in
    ws.flags[FL_DENSE_METHOD].  NaN for a method without dense output or an unknown code."""
    method = ws.flags[FL_DENSE_METHOD]
    rule = DENSE_RULE[method] if 0 <= method < N_METHODS else DENSE_NONE
    if rule == DENSE_HERMITE:
        hermite_eval(ws, theta, out, END_STAGE[method])
        return
    if rule == DENSE_ROWS and ws.flags[FL_DENSE_READY] == 0 and EXTRA_STAGES[method] == 0:
        dense_rows(method, ws)
    if rule != DENSE_ROWS or ws.flags[FL_DENSE_READY] == 0:
        for i in range(out.shape[0]):
            out[i] = math.nan
        return
    F = ws.F
    nr = DENSE_ROWS_OF[method]
    x1 = 1.0 - theta
    for i in range(out.shape[0]):  # innermost row first: factor x for an even row, 1 - x for an odd one
        acc = 0.0
        r = nr - 1
        if r % 2 == 0:
            acc = (F[r, i] + 0.0) * theta
            r -= 1
        while r > 0:  # an odd row and the even one below it
            acc = ((F[r, i] + acc) * x1 + F[r - 1, i]) * theta
            r -= 2
        out[i] = ws.ya[i] + acc
