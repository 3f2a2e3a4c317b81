"""The interpreter of expression programs: loads and motions written as expressions of time,
parameters and the state (`planar_mbs.mechanism.expressions` compiles them, docs/language.md).

A program is a run of rows of ``km.expr_code`` (``model.ExprOp``, three operands); row ``i``
writes register ``reg[i]`` (the run's `Workspace.xreg`: per run, never in the model), so a program is evaluated in one pass in order, with no stack
and no allocation.  Every model shares these kernels: a model's expressions are data, compiled
once with the kernels, never per model.

* `expr_value`: the value at (t, q, q') -- loads, evaluated inside every right-hand side;
* `expr_dual`: value, d/dt and d2/dt2 by forward-mode dual numbers (truncated Taylor arithmetic,
  Griewank & Walther, "Evaluating Derivatives", ch. 13) -- prescribed motions, which depend on t
  only, so their driver rows get f' and f'' exactly, not by finite differences;
* `table_eval`: a table's piecewise cubic and its first two derivatives at x.

Comparisons are switches (as a clearance joint's contact mode): during a step each holds the value
frozen in ``modes`` (the run's `Workspace.xmode`), so both sides of ``if`` stay smooth inside a step; the time loop locates
where a comparison changes on the step's dense output (`events.locate_switch`), ends the step
there and flips it (`flip_switch`).  A table's piece is a switch of the same kind: within a step
the piece's cubic is continued, and the knot is located as an event.  A discontinuous load costs
no rejected steps.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel

from ..mechanism.model import BQ_OMEGA, BQ_PHI, BQ_VX, BQ_VY, BQ_X, ExprOp

CONST = int(ExprOp.CONST)
TIME = int(ExprOp.TIME)
BODY = int(ExprOp.BODY)
ADD = int(ExprOp.ADD)
SUB = int(ExprOp.SUB)
MUL = int(ExprOp.MUL)
DIV = int(ExprOp.DIV)
NEG = int(ExprOp.NEG)
POW = int(ExprOp.POW)
SIN = int(ExprOp.SIN)
COS = int(ExprOp.COS)
EXP = int(ExprOp.EXP)
SQRT = int(ExprOp.SQRT)
ABS = int(ExprOp.ABS)
ATAN2 = int(ExprOp.ATAN2)
LT = int(ExprOp.LT)
LE = int(ExprOp.LE)
IF = int(ExprOp.IF)
TABLE = int(ExprOp.TABLE)
LOG = int(ExprOp.LOG)
TAN = int(ExprOp.TAN)
LIVE = -1.0e18  # modes[row] of a switch computed afresh (not frozen)


@kernel
def table_piece(tinfo, tperiod, tseg, k, x):
    """The piece of table k that holds x: -1 before its first knot, n - 1 after its last; a periodic
    table's pieces are counted on over its periods (piece + (n - 1) * period number), so that
    passing from one period to the next is a switch too."""
    first = tinfo[k, 0]
    n = tinfo[k, 1]
    seg = tseg
    x0 = seg[first, 0]
    period = tperiod[k]
    m = 0.0
    if period > 0.0:  # its knots span exactly one period (the compiler closes it)
        m = math.floor((x - x0) / period)
        x = x - period * m
    elif x < x0:
        return -1.0
    elif x >= seg[first + n - 1, 0]:
        return float(n - 1)
    lo = first
    hi = first + n - 1
    while hi - lo > 1:  # bisection: seg[lo, 0] <= x < seg[hi, 0]
        mid = (lo + hi) // 2
        if seg[mid, 0] <= x:
            lo = mid
        else:
            hi = mid
    return float(lo - first) + m * (n - 1)


@kernel
def table_eval(tinfo, tperiod, tseg, k, x, mode):
    """(y, dy/dx, d2y/dx2) of table k at x on its piece ``mode`` (frozen during a step: that piece's
    cubic continued past its knots), or on the piece holding x when mode is LIVE.  Outside its
    knots a table holds its end values; a periodic one repeats."""
    first = tinfo[k, 0]
    n = tinfo[k, 1]
    seg = tseg
    piece = table_piece(tinfo, tperiod, tseg, k, x) if mode == LIVE else mode
    period = tperiod[k]
    j = int(piece)
    if period > 0.0:
        m = math.floor(piece / (n - 1))
        j = int(piece - m * (n - 1))
        x = x - period * m
    elif j < 0:
        return seg[first, 1], 0.0, 0.0
    elif j >= n - 1:
        if mode == LIVE and x == seg[first + n - 1, 0] and n > 1:
            j = n - 2  # at the last knot: its end segment's derivatives
        else:
            return seg[first + n - 1, 1], 0.0, 0.0
    r = first + j
    d = x - seg[r, 0]
    c1 = seg[r, 2]
    c2 = seg[r, 3]
    c3 = seg[r, 4]
    return seg[r, 1] + d * (c1 + d * (c2 + d * c3)), c1 + d * (2.0 * c2 + 3.0 * d * c3), 2.0 * c2 + 6.0 * d * c3


@kernel
def body_quantity(q, qd, b, which):
    """x, y, phi, vx, vy or omega (BQ_*) of body b."""
    k = 3 * b + which % 3
    if which < 3:
        return q[k]
    return qd[k]


@kernel(inline=True)
def expr_value(km, reg, modes, prog, t, q, qd):
    """The value of program ``prog`` at (t, q, q').  Inlined: the call below passes eight arrays,
    not the whole KernelModel (numba passes every array of a tuple at a call that is not inlined)."""
    return run_rows(km.expr_code, km.expr_const, reg, modes, km.table_info,
                    km.table_period, km.table_seg, km.expr_prog[prog, 0], km.expr_prog[prog, 1], t, q, qd)


@kernel
def run_rows(code, consts, reg, modes, tinfo, tperiod, tseg, first, end, t, q, qd):
    """Rows first..end-1 at (t, q, q'); returns the last one's value.  The loads' programs lie
    together (``km.expr_loads``), so one call per right-hand side evaluates every expression load."""
    for i in range(first, end):
        op = code[i, 0]
        a = code[i, 1]
        b = code[i, 2]
        if op == CONST:
            v = consts[a]
        elif op == BODY:
            v = body_quantity(q, qd, a, b)
        elif op == TIME:
            v = t
        elif op == ADD:
            v = reg[a, 0] + reg[b, 0]
        elif op == SUB:
            v = reg[a, 0] - reg[b, 0]
        elif op == MUL:
            v = reg[a, 0] * reg[b, 0]
        elif op == DIV:
            v = reg[a, 0] / reg[b, 0]
        elif op == NEG:
            v = -reg[a, 0]
        elif op == LT or op == LE:
            v = modes[i]
            if v == LIVE:
                v = _compare(op, reg[a, 0], reg[b, 0])
        elif op == IF:
            v = reg[b, 0] if reg[a, 0] != 0.0 else reg[code[i, 3], 0]
        else:
            v = _function_value(op, reg[a, 0], reg[b, 0], b, modes[i], consts, tinfo, tperiod, tseg)
        reg[i, 0] = v
    return reg[end - 1, 0]


@kernel
def _compare(op, x, y):
    """1.0 or 0.0: x < y (LT) or x <= y (LE)."""
    if op == LT:
        return 1.0 if x < y else 0.0
    return 1.0 if x <= y else 0.0


@kernel
def live_switch(km, reg, modes, s, t, q, qd):
    """The value switch s would have at (t, q, q') if it were not frozen: a comparison's 0 or 1, a
    table's piece (`table_piece`)."""
    row = km.expr_switch[s, 0]
    frozen = modes[row]
    modes[row] = LIVE
    expr_value(km, reg, modes, km.expr_switch[s, 1], t, q, qd)
    modes[row] = frozen
    if km.expr_code[row, 0] == TABLE:
        return table_piece(km.table_info, km.table_period, km.table_seg, km.expr_code[row, 2],
                           reg[km.expr_code[row, 1], 0])
    return reg[row, 0]


@kernel
def init_switches(km, reg, modes, fault, t, y):
    """At the start of a run: every comparison frozen at its value in (t, y); no fault recorded."""
    n = km.minv.shape[0]
    fault[0] = -1.0
    for s in range(km.expr_switch.shape[0]):
        modes[km.expr_switch[s, 0]] = LIVE
    for s in range(km.expr_switch.shape[0]):
        modes[km.expr_switch[s, 0]] = live_switch(km, reg, modes, s, t, y[:n], y[n:2 * n])


@kernel
def _function_value(op, x, y, b, mode, consts, tinfo, tperiod, tseg):
    """The value of a function row (sin, ..., a table); x, y: its operands' values; mode: a table's
    frozen piece (LIVE: the piece holding x)."""
    if op == SIN:
        return math.sin(x)
    if op == COS:
        return math.cos(x)
    if op == EXP:
        return math.exp(x)
    if op == SQRT:
        return math.sqrt(x) if x >= 0.0 else math.nan
    if op == ABS:
        return abs(x)
    if op == ATAN2:
        return math.atan2(x, y)
    if op == POW:
        return _pow(x, consts[b])
    if op == TABLE:
        v, _, _ = table_eval(tinfo, tperiod, tseg, b, x, mode)
        return v
    if op == LOG:
        return math.log(x) if x > 0.0 else math.nan
    if op == TAN:
        return math.tan(x)
    return math.nan


@kernel
def _pow(x, p):
    """x^p for a constant p; NaN (not an exception) for a negative x and a fractional p."""
    if x < 0.0 and p != math.floor(p):
        return math.nan
    if x == 0.0 and p < 0.0:
        return math.inf
    return x ** p


@kernel(inline=True)
def expr_dual(km, reg, modes, prog, t):
    """(f, f', f'') of program ``prog`` (a function of t only) by truncated Taylor arithmetic."""
    return run_dual(km.expr_code, km.expr_const, km.expr_prog, reg, modes, km.table_info,
                    km.table_period, km.table_seg, prog, t)


@kernel
def run_dual(code, consts, progs, reg, modes, tinfo, tperiod, tseg, prog, t):
    """`expr_dual` over the program arrays."""
    end = progs[prog, 1]
    for i in range(progs[prog, 0], end):
        op = code[i, 0]
        a = code[i, 1]
        b = code[i, 2]
        v = 0.0
        d1 = 0.0
        d2 = 0.0
        if op == CONST:
            v = consts[a]
        elif op == TIME:
            v = t
            d1 = 1.0
        elif op == ADD or op == SUB:
            s = 1.0 if op == ADD else -1.0
            v = reg[a, 0] + s * reg[b, 0]
            d1 = reg[a, 1] + s * reg[b, 1]
            d2 = reg[a, 2] + s * reg[b, 2]
        elif op == MUL:
            v = reg[a, 0] * reg[b, 0]
            d1 = reg[a, 1] * reg[b, 0] + reg[a, 0] * reg[b, 1]
            d2 = reg[a, 2] * reg[b, 0] + 2.0 * reg[a, 1] * reg[b, 1] + reg[a, 0] * reg[b, 2]
        elif op == DIV:
            v = reg[a, 0] / reg[b, 0]
            d1 = (reg[a, 1] - v * reg[b, 1]) / reg[b, 0]
            d2 = (reg[a, 2] - 2.0 * d1 * reg[b, 1] - v * reg[b, 2]) / reg[b, 0]
        elif op == NEG:
            v = -reg[a, 0]
            d1 = -reg[a, 1]
            d2 = -reg[a, 2]
        elif op == LT or op == LE:
            v = modes[i]
            if v == LIVE:
                v = _compare(op, reg[a, 0], reg[b, 0])
        elif op == IF:
            src = b if reg[a, 0] != 0.0 else code[i, 3]
            v = reg[src, 0]
            d1 = reg[src, 1]
            d2 = reg[src, 2]
        elif op == ATAN2:
            v, d1, d2 = _atan2_dual(reg[a, 0], reg[a, 1], reg[a, 2], reg[b, 0], reg[b, 1], reg[b, 2])
        else:  # a function of one argument: chain rule with its first two derivatives
            x = reg[a, 0]
            v, g1, g2 = _function_dual(op, x, b, modes[i], consts, tinfo, tperiod, tseg)
            d1 = g1 * reg[a, 1]
            d2 = g2 * reg[a, 1] * reg[a, 1] + g1 * reg[a, 2]
        reg[i, 0] = v
        reg[i, 1] = d1
        reg[i, 2] = d2
    return reg[end - 1, 0], reg[end - 1, 1], reg[end - 1, 2]


@kernel
def _function_dual(op, x, b, mode, consts, tinfo, tperiod, tseg):
    """(g(x), g'(x), g''(x)) of a function row of one argument."""
    if op == SIN:
        s = math.sin(x)
        c = math.cos(x)
        return s, c, -s
    if op == COS:
        s = math.sin(x)
        c = math.cos(x)
        return c, -s, -c
    if op == EXP:
        e = math.exp(x)
        return e, e, e
    if op == SQRT:
        if x < 0.0:
            return math.nan, math.nan, math.nan
        r = math.sqrt(x)
        return r, 0.5 / r, -0.25 / (r * x)
    if op == ABS:
        return abs(x), 1.0 if x >= 0.0 else -1.0, 0.0
    if op == POW:
        p = consts[b]
        return _pow(x, p), p * _pow(x, p - 1.0), p * (p - 1.0) * _pow(x, p - 2.0)
    if op == TABLE:
        return table_eval(tinfo, tperiod, tseg, b, x, mode)
    if op == LOG:
        if x <= 0.0:
            return math.nan, math.nan, math.nan
        return math.log(x), 1.0 / x, -1.0 / (x * x)
    if op == TAN:
        tn = math.tan(x)
        sec2 = 1.0 + tn * tn
        return tn, sec2, 2.0 * tn * sec2
    return math.nan, math.nan, math.nan


@kernel
def _atan2_dual(y, y1, y2, x, x1, x2):
    """atan2(y, x) with its first two time derivatives: u' = (x y' - y x') / r2."""
    r2 = x * x + y * y
    num = x * y1 - y * x1
    d1 = num / r2
    dnum = x * y2 - y * x2  # (x y' - y x')' = x y'' - y x''
    d2 = (dnum * r2 - num * 2.0 * (x * x1 + y * y1)) / (r2 * r2)
    return math.atan2(y, x), d1, d2


@kernel(inline=True)
def flip_switch(km, reg, modes, s, t, y):
    """Switch s takes its value at (t, y), on its new side (at an event)."""
    n = km.minv.shape[0]
    modes[km.expr_switch[s, 0]] = live_switch(km, reg, modes, s, t, y[:n], y[n:2 * n])


def expression_scratch(km):
    """Fresh per-run registers, switch modes (all live) and fault record of `km`'s programs
    (`Workspace.xreg`, `xmode`, `xfault`; the Python callers' own copies)."""
    n = km.expr_code.shape[0]
    return np.zeros((max(n, 1), 3)), np.full(n, LIVE), np.full(2, -1.0)
