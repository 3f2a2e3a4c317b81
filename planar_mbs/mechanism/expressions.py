"""Expressions of loads and motions compiled to programs of `model.ExprOp` rows (docs/language.md,
"Expressions").

A load ``expression(slider, fx = if(slider.vx < 0 m/s, -800 N, 0 N))`` or a motion
``motion = 30 deg * sin(2 pi 1 Hz t)`` is checked here once, when the model is compiled: every
name resolved (time ``t``, params, signals of the state), every dimension checked, constants
folded, and the value at the initial state computed, so a division by zero there is an error at
its position rather than a NaN later.  The result is rows of ``km.expr_code`` that the one shared
interpreter (`kernel.expressions`) runs inside the time loop: a model's expressions need no
compilation of their own.  Tables (`tables.py`) become piecewise cubics in ``km.table_seg``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..language import units as U
from ..errors import did_you_mean
from ..language.evaluate import EXPRESSION_FUNCTIONS, Evaluator, Scalar, Symbol
from .model import BQ_OMEGA, BQ_PHI, BQ_VX, BQ_VY, BQ_X, BQ_Y, ExprOp
from ..language.spec import BinOp, Call, Compare, Expr, Name, Neg, Number, Pos, SignalRef, String, Vector
from .tables import table_node

ONE = U.Dimensionality((0.0,) * 7)
FUNCTIONS = EXPRESSION_FUNCTIONS
BODY_SIGNALS = {"x": (BQ_X, U.LENGTH), "y": (BQ_Y, U.LENGTH), "phi": (BQ_PHI, U.ANGLE),
                "vx": (BQ_VX, U.VELOCITY), "vy": (BQ_VY, U.VELOCITY), "omega": (BQ_OMEGA, U.ANGULAR_VELOCITY)}
CLEARANCE_SIGNALS = ("ex", "ey", "e", "penetration")
_UNARY = {"sin": ExprOp.SIN, "cos": ExprOp.COS, "tan": ExprOp.TAN, "exp": ExprOp.EXP, "log": ExprOp.LOG}
_PY = {ExprOp.SIN: math.sin, ExprOp.COS: math.cos, ExprOp.TAN: math.tan, ExprOp.EXP: math.exp,
       ExprOp.LOG: math.log, ExprOp.SQRT: math.sqrt, ExprOp.ABS: abs}


def dim_mul(a, b, sign=1.0):
    return U.Dimensionality(x + sign * y for x, y in zip(a, b))


def dim_pow(a, p):
    return U.Dimensionality(x * p for x in a)


@dataclass
class Node:
    """A compiled subexpression: its row (None while it is a folded constant), dimension, whether it
    was written without any unit, its value at the initial state, and the first problem met in
    computing that value (position, message), raised if the value is used."""

    row: int | None
    dim: U.Dimensionality
    plain: bool
    value: float
    fault: tuple | None = None

    @property
    def const(self) -> bool:
        return self.row is None


@dataclass
class Context:
    """What an expression may name: the model's bodies (id, initial state), clearance joints
    (bodies and points), element kinds, and which load or motion it belongs to."""

    body_id: dict
    q0: np.ndarray
    qd0: np.ndarray
    clearance: dict  # name -> (bi, (sx, sy), bj, (sx, sy))
    kinds: dict  # element name -> kind
    label: str = ""
    state: bool = True  # signals of the state allowed (loads); a motion depends on t only


class Programs:
    """Every program of one model: their rows, constants and tables, as KernelModel arrays."""

    def __init__(self, ev: Evaluator, ctx: Context):
        self.ev, self.ctx = ev, ctx
        self.code: list[tuple[int, int, int, int]] = []
        self.consts: list[float] = []
        self.progs: list[tuple[int, int]] = []
        self.tables: list = []  # (knot rows (n, 5), period)
        self.table_files: dict[str, bytes] = {}  # path -> bytes of every table file read (`Model.source_tables`)
        self.loads = (0, 0)  # first and end row of the loads' programs
        self._start = 0

    # ---------------------------------------------------------------- entry points
    def program(self, e: Expr, dim: U.Dim, label: str, state: bool = True) -> int:
        """Compile `e` as a program giving `dim`; returns its index.  Errors at `e`'s positions."""
        self.ctx.label, self.ctx.state = label, state
        self._start = len(self.code)
        node = self.node(e)
        if not node.plain and node.dim != dim.dimensionality:
            raise e.pos.error(f"{dim.words} was expected for {label}, got {U.describe(node.dim)} (`{e.pos.text}`)",
                              hint=f"write {dim.words} with a matching unit, e.g. `{dim.example}`")
        if node.plain:  # the rule of fields: taken in SI, with a warning (`Evaluator.note_plain`)
            self.ev.note_plain(e, [node.value] if node.const else None, dim, label=label)
        if node.fault is not None:
            pos, message = node.fault
            raise pos.error(f"{message} at the initial state (t = 0) in {label}",
                            hint="guard it, e.g. `if(abs(x) > 1e-9 m, y / x, 0 N)`, or change the initial state")
        r = self.row(node)
        if r != len(self.code) - 1:  # the result is the program's last row
            self._emit(ExprOp.ADD, r, self.row(self.const(0.0, ONE, True)))
        self.progs.append((self._start, len(self.code)))
        if state:  # a load: its rows join the loads' block, run once per right-hand side
            if self.loads[1] not in (0, self._start):
                raise RuntimeError("the loads' programs must be compiled one after another")  # pragma: no cover
            self.loads = (self.loads[0] if self.loads[1] else self._start, len(self.code))
        return len(self.progs) - 1

    def constant_or_program(self, e: Expr, dim: U.Dim, label: str) -> tuple[float, int | None]:
        """(value, None) when `e` is a constant (checked as `program` checks), else (0, its program)."""
        start, consts = len(self.code), len(self.consts)
        node = self.node(e)
        if node.const:
            if not node.plain and node.dim != dim.dimensionality:
                raise e.pos.error(f"{dim.words} was expected for {label}, got {U.describe(node.dim)} "
                                  f"(`{e.pos.text}`)", hint=f"e.g. `{dim.example}`")
            if node.plain:
                self.ev.note_plain(e, [node.value], dim, label=label)
            del self.code[start:], self.consts[consts:]
            return node.value, None
        del self.code[start:], self.consts[consts:]
        return 0.0, self.program(e, dim, label)

    def result_row(self, prog: int) -> int:
        """The row holding program prog's value."""
        return self.progs[prog][1] - 1

    def arrays(self) -> dict:
        """The KernelModel fields of these programs and tables."""
        seg = [rows for rows, _ in self.tables]
        info, first = [], 0
        for rows in seg:
            info.append((first, len(rows)))
            first += len(rows)
        compares = (int(ExprOp.LT), int(ExprOp.LE), int(ExprOp.TABLE))  # switches: located as events
        switches = [(row, k) for k, (first, end) in enumerate(self.progs) for row in range(first, end)
                    if self.code[row][0] in compares]
        return dict(
            expr_code=np.array(self.code, dtype=np.int64).reshape(-1, 4),
            expr_const=np.array(self.consts, dtype=np.float64),
            expr_prog=np.array(self.progs, dtype=np.int64).reshape(-1, 2),
            expr_loads=np.array(self.loads, dtype=np.int64),
            expr_switch=np.array(switches, dtype=np.int64).reshape(-1, 2),
            table_info=np.array(info, dtype=np.int64).reshape(-1, 2),
            table_period=np.array([p for _, p in self.tables], dtype=np.float64),
            table_seg=np.concatenate(seg).astype(np.float64) if seg else np.zeros((0, 5)),
        )

    # ---------------------------------------------------------------- rows
    def _emit(self, op, a=0, b=0, c=0) -> int:
        self.code.append((int(op), int(a), int(b), int(c)))
        return len(self.code) - 1

    def row(self, n: Node) -> int:
        """n's row; a folded constant gets its CONST row now."""
        if n.row is None:
            self.consts.append(float(n.value))
            n.row = self._emit(ExprOp.CONST, len(self.consts) - 1)
        return n.row

    def const(self, value, dim, plain, fault=None) -> Node:
        return Node(None, dim, plain, value, fault)

    def op(self, op, args: list[Node], dim, plain, value, fault=None, extra=0) -> Node:
        """A row `op` over `args` (folded when they are all constant and nothing went wrong)."""
        fault = fault or next((a.fault for a in args if a.fault), None)
        if all(a.const for a in args) and op not in (ExprOp.TABLE,):
            return Node(None, dim, plain, value, fault)
        rows = [self.row(a) for a in args] + [0] * (3 - len(args))
        if op in (ExprOp.POW, ExprOp.TABLE):
            rows[1] = extra
        return Node(self._emit(op, *rows[:3]), dim, plain, value, fault)

    # ---------------------------------------------------------------- the tree
    def node(self, e: Expr) -> Node:
        if isinstance(e, Number):
            q = U.quantity(e.value, e.unit)
            return self.const(float(q.to_base_units().magnitude), q.dimensionality, e.unit is None)
        if isinstance(e, Name):
            return self.name(e)
        if isinstance(e, SignalRef):
            return self.signal(e)
        if isinstance(e, Neg):
            a = self.node(e.operand)
            return self.op(ExprOp.NEG, [a], a.dim, a.plain, -a.value)
        if isinstance(e, BinOp) and e.op == "^":
            return self.power(e, self.node(e.left), self.node(e.right))
        if isinstance(e, BinOp):
            return self.binop(e.pos, e.op, self.node(e.left), self.node(e.right))
        if isinstance(e, Compare):
            return self.compare(e, e.op, self.node(e.left), self.node(e.right))
        if isinstance(e, Call):
            return self.call(e)
        if isinstance(e, Vector):
            raise e.pos.error(f"a single value was expected, got a vector (`{e.pos.text}`)",
                              hint="give each component its own field (`fx = ...  fy = ...`)")
        if isinstance(e, String):
            raise e.pos.error("a quoted text is only a table's file name here",
                              hint='e.g. `table("gas.csv", x = crank.phi, x_unit = "deg", y_unit = "N")`')
        raise e.pos.error(f"cannot use `{e.pos.text}` in an expression")  # pragma: no cover

    def name(self, e: Name) -> Node:
        if e.name in self.ev.params:
            v = self.ev.param(e.name)
            if isinstance(v, Scalar):
                return self.const(float(v.q.to_base_units().magnitude), v.q.dimensionality, v.plain)
            if isinstance(v, Symbol):
                return self.name(Name(e.pos, v.name))
            raise e.pos.error(f"param `{e.name}` is not a single number", hint="use one of its components")
        if e.name == "t":
            return Node(self._emit(ExprOp.TIME), U.TIME.dimensionality, False, 0.0)
        if e.name == "pi":
            return self.const(math.pi, ONE, True)
        if e.name in self.ctx.kinds:
            example = f"{e.name}.phi" if self.ctx.kinds[e.name] == "body" else f"{e.name}.<signal>"
            raise e.pos.error(f"`{e.name}` is a {self.ctx.kinds[e.name]}, not a number",
                              hint=f"name one of its signals, e.g. `{example}`")
        hint = did_you_mean(e.name, [*self.ev.params, "t", "pi"])
        raise e.pos.error(f"unknown name `{e.name}`",
                          hint=hint or "expressions name `t`, params and signals such as `crank.phi`")

    def signal(self, e: SignalRef) -> Node:
        ctx = self.ctx
        if not ctx.state:
            raise e.pos.error(f"a motion is a function of time only; `{e.pos.text}` is a signal of the state",
                              hint="write the motion with `t`, params and constants (a load may use signals)")
        kind = ctx.kinds.get(e.entity)
        if e.entity in ctx.body_id:
            if e.quantity in BODY_SIGNALS:
                which, dim = BODY_SIGNALS[e.quantity]
                b = ctx.body_id[e.entity]
                value = (ctx.q0 if which < 3 else ctx.qd0)[3 * b + which % 3]
                return Node(self._emit(ExprOp.BODY, b, which), dim.dimensionality, False, float(value))
            if e.quantity in ("ax", "ay", "alpha"):
                raise self._circular(e, f"the acceleration `{e.pos.text}`")
            raise self._unknown_signal(e, list(BODY_SIGNALS))
        if e.entity in ctx.clearance:
            if e.quantity in CLEARANCE_SIGNALS:
                return self.eccentricity(e)
            raise self._unknown_signal(e, list(CLEARANCE_SIGNALS))
        if kind in ("driver", "joint"):
            raise self._circular(e, f"the {'effort' if kind == 'driver' else 'reaction'} `{e.pos.text}` "
                                 f"of {kind} `{e.entity}`")
        if kind is not None:
            raise e.pos.error(f"`{e.entity}` is a {kind}; expressions read the signals of bodies and clearance "
                              "joints", hint=f"e.g. `crank.omega`, `A.e`")
        raise e.pos.error(f"unknown signal `{e.pos.text}`: no body or clearance joint `{e.entity}`",
                          hint=did_you_mean(e.entity, [*ctx.body_id, *ctx.clearance]) or
                          "signals: BODY.x y phi vx vy omega, CLEARANCE.ex ey e penetration")

    def _circular(self, e: SignalRef, what: str):
        return e.pos.error(f"circular dependency: {self.ctx.label} uses {what}, which depends on every "
                           f"applied load, {self.ctx.label} included",
                           hint="write the load with positions, velocities and time (`crank.omega`, `t`)")

    def _unknown_signal(self, e: SignalRef, choices):
        return e.pos.error(f"unknown signal `{e.pos.text}`",
                           hint=did_you_mean(e.quantity, choices) or f"`{e.entity}` has: {', '.join(choices)}")

    def eccentricity(self, e: SignalRef) -> Node:
        """ex, ey, e or penetration of a clearance joint: journal centre minus bearing centre."""
        bi, si, bj, sj, clearance = self.ctx.clearance[e.entity]
        comps = []
        for axis in (0, 1):
            comps.append(self.binop(e.pos, "-", self._point(bj, sj, axis, e.pos), self._point(bi, si, axis, e.pos)))
        if e.quantity in ("ex", "ey"):
            return comps[0 if e.quantity == "ex" else 1]
        sq = [self.binop(e.pos, "*", c, c) for c in comps]
        r = self.unary(e.pos, ExprOp.SQRT, self.binop(e.pos, "+", *sq))
        if e.quantity == "e":
            return r
        return self.binop(e.pos, "-", r, self.const(clearance, U.LENGTH.dimensionality, False))

    def _point(self, b: int, s, axis: int, where: Pos) -> Node:
        """x (axis 0) or y of a body's point, P = r + A s, as nodes."""
        L = U.LENGTH.dimensionality
        if b < 0:
            return self.const(float(s[axis]), L, False)
        q0 = self.ctx.q0
        pos = Node(self._emit(ExprOp.BODY, b, BQ_X + axis), L, False, float(q0[3 * b + axis]))
        phi = Node(self._emit(ExprOp.BODY, b, BQ_PHI), ONE, False, float(q0[3 * b + 2]))
        c = Node(self._emit(ExprOp.COS, phi.row), ONE, False, math.cos(phi.value))
        sn = Node(self._emit(ExprOp.SIN, phi.row), ONE, False, math.sin(phi.value))
        # x: c sx - s sy;  y: s sx + c sy
        k1, k2 = (s[0], -s[1]) if axis == 0 else (s[1], s[0])
        lin = [self._scale(c, k1), self._scale(sn, k2)]
        return self.binop(where, "+", pos, self.binop(where, "+", *lin))

    def _scale(self, n: Node, k: float) -> Node:
        kn = self.const(float(k), U.LENGTH.dimensionality, False)
        return self.op(ExprOp.MUL, [n, kn], U.LENGTH.dimensionality, False, n.value * k)

    # ---------------------------------------------------------------- operators
    def _same_dim(self, pos: Pos, what: str, a: Node, b: Node) -> None:
        """a and b must have one dimension (a plain number goes with a plain number or an angle)."""
        if a.plain != b.plain:
            dim = b if a.plain else a
            if dim.dim:
                number = a if a.plain else b  # the number written without a unit
                value = f"{number.value:g}" if number.const else "0"
                example = f"{value} {U.example_unit(dim.dim)}"
                raise pos.error(f"cannot {what} a plain number and {U.describe(dim.dim)} (`{pos.text}`)",
                                hint=f"give the number a unit, e.g. `{example}`")
        if a.dim != b.dim:
            raise pos.error(f"cannot {what} {U.describe(a.dim)} and {U.describe(b.dim)} (`{pos.text}`)",
                            hint="both need the same dimension; check the units")

    def binop(self, pos: Pos, op: str, a: Node, b: Node) -> Node:
        plain = a.plain and b.plain
        if op in "+-":
            self._same_dim(pos, "add" if op == "+" else "subtract", a, b)
            value, fault = self.finite(pos, lambda: a.value + b.value if op == "+" else a.value - b.value, [a, b])
            return self.op(ExprOp.ADD if op == "+" else ExprOp.SUB, [a, b], a.dim, plain, value, fault)
        if op == "*":
            value, fault = self.finite(pos, lambda: a.value * b.value, [a, b])
            return self.op(ExprOp.MUL, [a, b], dim_mul(a.dim, b.dim), plain, value, fault)
        fault = None
        if b.value == 0.0:
            if b.const:
                raise pos.error(f"division by zero in `{pos.text}`", hint="check the divisor")
            fault = (pos, f"division by zero: `{pos.text}` divides by 0")
            value = math.nan
        else:
            value, fault = self.finite(pos, lambda: a.value / b.value, [a, b])
        return self.op(ExprOp.DIV, [a, b], dim_mul(a.dim, b.dim, -1.0), plain, value, fault)

    def finite(self, pos: Pos, compute, args: list[Node]) -> tuple[float, tuple | None]:
        """(value, fault) of ``compute()``: beyond the range of a float, an error at ``pos`` when
        every argument is constant (folded), else a fault (raised if the initial value is used)."""
        try:
            value = compute()
        except OverflowError:
            value = math.inf
        if math.isfinite(value) or not all(math.isfinite(a.value) for a in args):
            return value, None
        message = f"`{pos.text}` overflows: its value is beyond ±1.8e308"
        if all(a.const for a in args):
            raise pos.error(message, hint="check the magnitudes and the units of its numbers")
        return value, (pos, message)

    def power(self, e: BinOp, a: Node, b: Node) -> Node:
        if not b.const or b.dim:
            raise e.right.pos.error(f"an exponent must be a constant plain number, got `{e.right.pos.text}`",
                                    hint="e.g. `x^2` or `x^0.5`; write exp(y * log(x)) for a varying one")
        p = b.value
        fault = None
        if (a.value < 0 and p != math.floor(p)) or (a.value == 0 and p < 0):
            if a.const:
                raise e.pos.error(f"`{e.pos.text}` has no real value", hint="check the base and the exponent")
            fault = (e.pos, f"`{e.pos.text}` has no real value")
            value = math.nan
        else:
            value, fault = self.finite(e.pos, lambda: a.value ** p, [a])
        self.consts.append(p)
        return self.op(ExprOp.POW, [a], dim_pow(a.dim, p), a.plain, value, fault, extra=len(self.consts) - 1)

    def compare(self, e: Expr, op: str, a: Node, b: Node) -> Node:
        """a < b, a <= b (and > >= by swapping): 1 or 0, a plain number."""
        self._same_dim(e.pos, "compare", a, b)
        if op in (">", ">="):
            a, b, op = b, a, {">": "<", ">=": "<="}[op]
        value = float(a.value < b.value if op == "<" else a.value <= b.value)
        return self.op(ExprOp.LT if op == "<" else ExprOp.LE, [a, b], ONE, True, value)

    def unary(self, pos: Pos, op, a: Node) -> Node:
        """sin, cos, tan, exp, log (of a plain number or an angle), sqrt, abs."""
        dim = dim_pow(a.dim, 0.5) if op == ExprOp.SQRT else a.dim if op == ExprOp.ABS else ONE
        bad = (op == ExprOp.SQRT and a.value < 0) or (op == ExprOp.LOG and a.value <= 0)
        fault = None
        if bad:
            if a.const:
                raise pos.error(f"`{pos.text}` has no real value", hint="check the sign of the argument")
            fault = (pos, f"`{pos.text}` has no real value")
        if bad:
            value = math.nan
        else:
            value, fault = self.finite(pos, lambda: _PY[ExprOp(op)](a.value), [a])
        return self.op(op, [a], dim, a.plain, value, fault)

    def select(self, c: Node, a: Node, b: Node) -> Node:
        """if(c, a, b): a where c is not 0, else b."""
        chosen = a if c.value != 0.0 else b
        if c.const:
            return chosen
        fault = c.fault or chosen.fault
        n = Node(None, a.dim, a.plain and b.plain, chosen.value, fault)
        n.row = self._emit(ExprOp.IF, self.row(c), self.row(a), self.row(b))
        return n

    # ---------------------------------------------------------------- functions
    def call(self, e: Call) -> Node:
        if e.name == "table":
            return table_node(self, e)
        if e.name not in FUNCTIONS:
            raise e.name_pos.error(f"unknown function `{e.name}`",
                                   hint=did_you_mean(e.name, FUNCTIONS) or "functions: " + ", ".join(FUNCTIONS))
        counts = {"atan2": 2, "min": 2, "max": 2, "if": 3, "step": 5}
        n = counts.get(e.name, 1)
        if e.kwargs or len(e.args) != n:
            names = {"if": "condition, then, else", "step": "x, x0, h0, x1, h1", "atan2": "y, x"}
            raise e.pos.error(f"`{e.name}` takes {n} argument{'s' if n > 1 else ''}",
                              hint=f"`{e.name}({names.get(e.name, ', '.join('ab'[:n]) if n > 1 else 'x')})`")
        args = [self.node(a) for a in e.args]
        if e.name in _UNARY:
            if args[0].dim:
                raise e.args[0].pos.error(f"`{e.name}` needs a plain number or an angle, got "
                                          f"{U.describe(args[0].dim)} (`{e.args[0].pos.text}`)",
                                          hint=f"e.g. `{e.name}(2 * pi * 5 Hz * t)`")
            return self.unary(e.pos, _UNARY[e.name], args[0])
        if e.name in ("sqrt", "abs"):
            return self.unary(e.pos, ExprOp.SQRT if e.name == "sqrt" else ExprOp.ABS, args[0])
        if e.name == "atan2":
            y, x = args
            self._same_dim(e.pos, "take atan2 of", y, x)
            value = math.atan2(y.value, x.value)
            return self.op(ExprOp.ATAN2, [y, x], ONE, y.plain and x.plain, value)
        if e.name in ("min", "max"):
            a, b = args
            self._same_dim(e.pos, f"take the {e.name} of", a, b)
            less = self.compare(e, "<", a, b)
            return self.select(less, a, b) if e.name == "min" else self.select(less, b, a)
        if e.name == "if":
            return self.conditional(e, *args)
        return self.step(e, *args)

    def conditional(self, e: Call, c: Node, a: Node, b: Node) -> Node:
        if c.dim:
            raise e.args[0].pos.error(f"the condition of `if` must be a comparison or a plain number, got "
                                      f"{U.describe(c.dim)}", hint="e.g. `if(slider.vx < 0 m/s, -800 N, 0 N)`")
        self._same_dim(e.pos, "choose between", a, b)
        return self.select(c, a, b)

    def step(self, e: Call, x: Node, x0: Node, h0: Node, x1: Node, h1: Node) -> Node:
        """Adams' STEP: h0 for x <= x0, h1 for x >= x1, between them the cubic
        h0 + (h1 - h0) d^2 (3 - 2 d), d = (x - x0) / (x1 - x0) (continuous slope, a jump in curvature)."""
        self._same_dim(e.pos, "step over", x, x0)
        self._same_dim(e.pos, "step over", x, x1)
        self._same_dim(e.pos, "step between", h0, h1)
        if x0.const and x1.const and not x1.value > x0.value:
            raise e.args[3].pos.error("`step(x, x0, h0, x1, h1)` needs x1 > x0",
                                      hint="the step rises from h0 at x0 to h1 at x1")
        p = e.pos
        d = self.binop(p, "/", self.binop(p, "-", x, x0), self.binop(p, "-", x1, x0))
        three = self.const(3.0, ONE, True)
        two = self.const(2.0, ONE, True)
        s = self.binop(p, "*", self.binop(p, "*", d, d), self.binop(p, "-", three, self.binop(p, "*", two, d)))
        inner = self.binop(p, "+", h0, self.binop(p, "*", self.binop(p, "-", h1, h0), s))
        upper = self.select(self.compare(e, "<=", x1, x), h1, inner)
        return self.select(self.compare(e, "<=", x, x0), h0, upper)
