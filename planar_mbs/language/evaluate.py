"""Evaluate `.mbs` expressions with units: values, arithmetic, functions, field readers with
dimension checks.

Split out of `compile.py` so the compiler holds only its passes.  `Evaluator` walks the
expression trees (`spec.Expr`; never Python's eval), resolving params on demand and detecting
cycles; `Fields` and `scalar_si` / `vector_si` / `symbol_of` read an element's fields into SI
numbers or names.  Every user mistake raises `ModelError` at the expression's position.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from . import units as U
from ..errors import ModelError, as_warning, did_you_mean
from .spec import (
    BinOp,
    Call,
    Compare,
    Expr,
    Field,
    Name,
    Neg,
    Number,
    Pos,
    SignalRef,
    Statement,
    String,
    Vector,
)


# ------------------------------------------------------------------ values
@dataclass(frozen=True)
class Scalar:
    """A pint quantity; `plain` = written without any unit (taken in SI where a unit is expected)."""

    q: object
    plain: bool


@dataclass(frozen=True)
class Vec:
    items: tuple[Scalar, ...]


@dataclass(frozen=True)
class Symbol:
    """A bare name that is not a param: a body, material, law, integrator, ..."""

    name: str
    pos: Pos


@dataclass(frozen=True)
class CallVal:
    call: Call


# functions only an expression of a load or a motion may call (`expressions.py` compiles them)
EXPRESSION_FUNCTIONS = ("sin", "cos", "tan", "exp", "log", "sqrt", "abs", "atan2", "min", "max", "if", "step", "table")
FUNCTIONS = {"sqrt": 1, "sin": 1, "cos": 1, "tan": 1, "atan2": 2, "abs": 1}


class Evaluator:
    """Evaluates expression trees with units; params are resolved on demand, cycles detected."""

    def __init__(self, params: dict[str, Statement], overrides: dict[str, Expr], names: dict[str, str],
                 call_names: set[str]):
        if "t" in params:  # `t` is the time in every expression: a param would silently replace it
            st = params["t"]
            raise (st.name_pos or st.pos).error("the name `t` is reserved (the time)", hint="choose another name")
        self.params = params
        self.overrides = overrides
        self.names = names  # every element name -> its kind, for messages
        self.call_names = call_names  # every name that may be called in a model (the rest are unknown functions)
        self.values: dict[str, object] = {}
        self._stack: list[str] = []
        self.warnings: list[str] = []  # numbers without a unit taken in SI (`note_plain`), rendered, once each

    def note_plain(self, e: Expr, values: list | None, dim: U.Dim, field: str = "", label: str = "") -> None:
        """The one rule for a number written without a unit where `dim` (a dimension) is expected, in a
        field as in an expression: it is taken in SI, and a warning names the unit taken and shows the
        unit to write.  Zero needs no unit; a plain number in a sum with a unit is an error instead
        (`_arith`, `expressions.Programs`)."""
        if not dim.dimensionality or (values is not None and all(v == 0 for v in values)):
            return
        si = dim.si.replace("**", "^").replace("radian", "rad")
        unit = U.example_unit(dim.dimensionality)
        what = f"`{field} = {e.pos.text}`" if field else f"`{e.pos.text}`" + (f" ({label})" if label else "")
        if values is None:  # an expression of the state: its value is not known here
            message, hint = f"{what} has no unit: taken in {si}", f"give it its unit, e.g. `({e.pos.text}) * 1 {si}`"
        else:
            def written(u):
                text = ", ".join(f"{v:g} {u}" if v else "0" for v in values)
                return f"({text})" if len(values) > 1 else text

            taken = ", ".join(f"{v:g} {si}" for v in values)
            message = f"{what} has no unit: taken as " + (f"({taken})" if len(values) > 1 else taken)
            hint = (f"write `{written(si)}` if that is meant, or the unit meant, e.g. `{written(unit)}`" if unit != si
                    else f"write `{written(si)}` if that is meant, or the unit meant")
        text = as_warning(e.pos.error(message, hint=hint))
        if text not in self.warnings:
            self.warnings.append(text)

    # params
    def param(self, name: str):
        if name in self.values:
            return self.values[name]
        st = self.params[name]
        if name in self._stack:
            cycle = _chain(self._stack[self._stack.index(name):] + [name])
            raise st.name_pos.error(f"parameters depend on each other in a cycle: {cycle}",
                                    hint="give one of them a value that does not use the others")
        self._stack.append(name)
        try:
            expr = self.overrides.get(name, st.value)
            value = self.value(expr)
            if isinstance(value, CallVal) and value.call.name not in self.call_names:
                raise self.unknown_function(value.call)
            if isinstance(value, CallVal):
                raise expr.pos.error(f"param `{name}` must be a number, a vector or a name",
                                     hint=f"`{value.call.name}(...)` can be written where it is used")
        finally:
            self._stack.pop()
        self.values[name] = value
        return value

    # expressions
    def value(self, e: Expr):
        try:
            v = self._eval(e)
        except U.UnitError as err:
            raise e.pos.error(err.message, err.hint) from None
        except ZeroDivisionError:
            raise e.pos.error(f"division by zero in `{e.pos.text}`",
                              hint="check the divisor (a param that is zero?)") from None
        except OverflowError:
            raise e.pos.error(f"the result of `{e.pos.text}` is too large",
                              hint="numbers must stay below about 1.8e308") from None
        except (ValueError, ArithmeticError) as err:
            raise e.pos.error(f"cannot compute `{e.pos.text}` ({err})",
                              hint="check the operands and their units") from None
        if isinstance(v, Scalar):
            self._finite(v, e)
        return v

    def _finite(self, v: Scalar, e: Expr):
        m = v.q.magnitude
        if isinstance(m, complex) or not math.isfinite(m):
            raise e.pos.error(f"`{e.pos.text}` is not a finite real number",
                              hint="check for overflow or a fractional power of a negative number")

    def _eval(self, e: Expr):
        if isinstance(e, Number):
            return Scalar(U.quantity(e.value, e.unit), e.unit is None)
        if isinstance(e, Name):
            if e.name in self.params:
                return self.param(e.name)
            if e.name == "pi":
                return Scalar(U.quantity(math.pi, None), True)
            return Symbol(e.name, e.pos)
        if isinstance(e, Neg):
            v = self.value(e.operand)
            if isinstance(v, Vec):
                return Vec(tuple(Scalar(-s.q, s.plain) for s in v.items))
            s = self.number(v, e.operand)
            return Scalar(-s.q, s.plain)
        if isinstance(e, Vector):
            return Vec(tuple(self.number(self.value(i), i) for i in e.items))
        if isinstance(e, BinOp):
            return self._binop(e)
        if isinstance(e, Call):
            if e.name in FUNCTIONS:
                return self._function(e)
            return CallVal(e)
        if isinstance(e, (Compare, SignalRef, String)):
            raise self.expression_only(e)
        raise TypeError(f"unknown expression {e!r}")  # pragma: no cover

    def number(self, v, e: Expr) -> Scalar:
        """v as a Scalar, or a ModelError saying why it is not one."""
        if isinstance(v, Scalar):
            return v
        if isinstance(v, Vec):
            raise e.pos.error(f"a single value was expected, got a vector (`{e.pos.text}`)",
                              hint="use one component, or write a plain number with its unit")
        if isinstance(v, Symbol):
            raise self.not_a_number(v)
        if isinstance(v, CallVal) and v.call.name not in self.call_names:
            raise self.unknown_function(v.call)
        raise e.pos.error(f"a number was expected, got `{e.pos.text}`",
                          hint="write a number with its unit, e.g. `0.3 kg`, or the name of a param")

    def expression_only(self, e: Expr) -> ModelError:
        """A comparison, a signal or a quoted text where a constant is expected."""
        if isinstance(e, String):
            return e.pos.error("a quoted text is only used by `include` and as a table's file name",
                               hint='write names without quotes (`law = hertz`)')
        what = {Compare: "a comparison", SignalRef: f"the signal `{e.pos.text}`"}[type(e)]
        return e.pos.error(f"{what} can only be used in an expression of a load or a motion",
                           hint="write it in `force NAME = expression(body, fx = ..., fy = ..., torque = ...)` "
                                "or a driver's `motion = ...`; params are constants")

    def unknown_function(self, c: Call) -> ModelError:
        if c.name in EXPRESSION_FUNCTIONS:
            return c.name_pos.error(f"unknown function `{c.name}` here: it is a function of expressions",
                                    hint="write it in an expression of a load or a motion (docs/language.md, "
                                         "Expressions); params use " + ", ".join(FUNCTIONS))
        return c.name_pos.error(f"unknown function `{c.name}`",
                                hint=did_you_mean(c.name, FUNCTIONS) or "functions: " + ", ".join(FUNCTIONS))

    def not_a_number(self, s: Symbol) -> ModelError:
        if s.name in self.names:
            return s.pos.error(f"`{s.name}` is a {self.names[s.name]}, not a number",
                               hint="write a number with its unit here, or the name of a `param`")
        hint = did_you_mean(s.name, [*self.params, "pi"])
        try:
            U.parse_unit(s.name)
            hint = hint or f"`{s.name}` is a unit: write it right after a number without a space inside, e.g. `2.5e-4 kg*m^2`"
        except U.UnitError:
            pass
        return s.pos.error(f"unknown name `{s.name}`", hint=hint or "declare it with `param NAME = value`")

    def _binop(self, e: BinOp):
        return self._arith(e, e.op, self.value(e.left), self.value(e.right))

    def _arith(self, e: BinOp, op: str, a, b):
        """a op b for evaluated operands; vectors element-wise."""
        if isinstance(a, Vec) or isinstance(b, Vec):
            return self._vector_op(e, op, a, b)
        a, b = self.number(a, e.left), self.number(b, e.right)
        if op in "+-":
            if a.plain != b.plain:
                dim = b if a.plain else a
                if not dim.q.dimensionless:
                    unit = U.format_quantity(dim.q).split(" ", 1)[-1]
                    raise e.pos.error(
                        f"cannot add a plain number to {U.describe(dim.q.dimensionality)} (`{e.pos.text}`)",
                        hint=f"give the number a unit, e.g. `0.1 {unit}`")
            if a.q.dimensionality != b.q.dimensionality:
                word = "add" if op == "+" else "subtract"
                raise e.pos.error(f"cannot {word} {U.describe(a.q.dimensionality)} and "
                                  f"{U.describe(b.q.dimensionality)} (`{e.pos.text}`)",
                                  hint="both sides of `+` and `-` need the same dimension; check the units")
            q = a.q + b.q if op == "+" else a.q - b.q
            return Scalar(q, a.plain and b.plain)
        plain = a.plain and b.plain
        if op == "*":
            return Scalar(a.q * b.q, plain)
        if op == "/":
            if b.q.magnitude == 0:
                raise ZeroDivisionError
            return Scalar(a.q / b.q, plain)
        # power: the exponent is a plain number
        if not b.q.dimensionless:
            raise e.right.pos.error(f"an exponent must be a plain number, got `{e.right.pos.text}`",
                                    hint="e.g. `x^2` or `x^0.5`")
        x = float(b.q.to_base_units().magnitude)
        return Scalar(a.q ** x, a.plain)

    def _vector_op(self, e: BinOp, op: str, a, b):
        hint = "vectors can be added, subtracted, multiplied and divided by a number"
        if isinstance(a, Vec) and isinstance(b, Vec):
            if op not in "+-" or len(a.items) != len(b.items):
                raise e.pos.error(f"cannot compute `{e.pos.text}` with two vectors", hint=hint)
            return Vec(tuple(self._arith(e, op, x, y) for x, y in zip(a.items, b.items)))
        if isinstance(a, Vec) and op in "*/":
            s = self.number(b, e.right)
            return Vec(tuple(self._arith(e, op, x, s) for x in a.items))
        if isinstance(b, Vec) and op == "*":
            s = self.number(a, e.left)
            return Vec(tuple(self._arith(e, op, s, y) for y in b.items))
        raise e.pos.error(f"cannot compute `{e.pos.text}` with a vector", hint=hint)

    def _function(self, e: Call):
        n = FUNCTIONS[e.name]
        if e.kwargs or len(e.args) != n:
            raise e.pos.error(f"`{e.name}` takes {n} argument{'s' if n > 1 else ''}",
                              hint=f"e.g. `{e.name}({', '.join(['x', 'y'][:n])})`")
        xs = [self.number(self.value(a), a) for a in e.args]
        x = xs[0]
        if e.name == "sqrt":
            if x.q.magnitude < 0:
                raise e.pos.error(f"square root of a negative value (`{e.pos.text}`)",
                                  hint="check the sign of the argument (use `abs(...)` if intended)")
            return Scalar(x.q ** 0.5, x.plain)
        if e.name == "abs":
            return Scalar(abs(x.q), x.plain)
        if e.name == "atan2":
            y, x = xs
            if y.q.dimensionality != x.q.dimensionality and not (y.plain or x.plain):
                raise e.pos.error("`atan2(y, x)` needs y and x of the same dimension",
                                  hint="e.g. `atan2(3 mm, 4 mm)`")
            ym = y.q.magnitude if y.plain else y.q.to_base_units().magnitude
            xm = x.q.magnitude if x.plain else x.q.to_base_units().magnitude
            return Scalar(U.quantity(math.atan2(ym, xm), None), True)
        if not x.q.dimensionless:
            raise e.pos.error(f"`{e.name}` needs an angle, got {U.describe(x.q.dimensionality)}",
                              hint=f"e.g. `{e.name}(30 deg)` or `{e.name}(0.5)` (radians)")
        angle = float(x.q.to_base_units().magnitude)
        return Scalar(U.quantity(getattr(math, e.name)(angle), None), True)


# ------------------------------------------------------------------ fields of an element
_REQUIRED = object()


class Fields:
    """The `key = expr` fields of one element (block fields plus keyword arguments of its call)."""

    def __init__(self, ev: Evaluator, st: Statement, label: str, allowed: dict[str, str],
                 extra: tuple = ()):
        self.ev, self.st, self.label, self.allowed = ev, st, label, allowed
        self.items: dict[str, Field] = {}
        for f in [*extra, *st.fields]:
            if f.name not in allowed:
                hint = did_you_mean(f.name, allowed) or (
                    f"the fields of {label} are: {', '.join(allowed)}" if allowed else f"{label} has no fields")
                raise f.pos.error(f"unknown field `{f.name}` for {label}", hint=hint)
            if f.name in self.items:
                raise f.pos.error(f"`{f.name}` is given twice for {label}",
                                  hint=f"first given on line {self.items[f.name].pos.line}")
            self.items[f.name] = f

    def has(self, name: str) -> bool:
        return name in self.items

    def missing(self, name: str) -> ModelError:
        where = self.st.name_pos or self.st.pos
        return where.error(f"{self.label} needs `{name}`",
                           hint=f"add `{name} = ...` ({self.allowed[name]})")

    def scalar(self, name: str, dim: U.Dim, default=_REQUIRED, positive=False, nonneg=False) -> float:
        if name not in self.items:
            if default is _REQUIRED:
                raise self.missing(name)
            return default
        f = self.items[name]
        value = scalar_si(self.ev, f.value, dim, name)
        if (positive and not value > 0) or (nonneg and value < 0):
            raise self._sign_error(f, name, dim, positive)
        return value

    def _sign_error(self, f: Field, name: str, dim: U.Dim, positive: bool) -> ModelError:
        """`clearance` of ... must be positive, got -0.1 mm: the value (and where it came from when the
        field names a param, e.g. a `--set`), at the field, with an example of the right sign."""
        s = self.ev.number(self.ev.value(f.value), f.value)
        shown = U.format_quantity(s.q)
        if f.value.pos.text.strip() != shown:
            origin = f.value.pos.text
            if isinstance(f.value, Name) and f.value.name in self.ev.overrides:
                origin = f"`--set {f.value.name}={self.ev.overrides[f.value.name].pos.text}`"
            else:
                origin = f"`{origin}`"
            shown += f" (from {origin})"
        flipped = U.format_quantity(abs(s.q)) if s.q.magnitude < 0 else dim.example
        example = f"{name} = {flipped}"
        rule, word = ("must be positive", "greater than zero") if positive else ("must not be negative", "zero or more")
        return f.pos.error(f"`{name}` of {self.label} {rule}, got {shown}", hint=f"give a value {word}, e.g. `{example}`")

    def vector(self, name: str, dim: U.Dim, default=_REQUIRED) -> tuple[float, float]:
        if name not in self.items:
            if default is _REQUIRED:
                raise self.missing(name)
            return default
        return vector_si(self.ev, self.items[name].value, dim, name)

    def symbol(self, name: str, choices, default=_REQUIRED) -> str:
        if name not in self.items:
            if default is _REQUIRED:
                raise self.missing(name)
            return default
        return symbol_of(self.ev, self.items[name].value, choices, name)

    def expr(self, name: str) -> Expr | None:
        f = self.items.get(name)
        return f.value if f else None


def scalar_si(ev: Evaluator, e: Expr, dim: U.Dim, field: str = "", note: bool = True) -> float:
    s = ev.number(ev.value(e), e)
    try:
        value = U.to_si(s.q, s.plain, dim, e.pos.text, field)
    except U.UnitError as err:
        raise e.pos.error(err.message, err.hint) from None
    if s.plain and note:
        ev.note_plain(e, [value], dim, field)
    return value


def vector_si(ev: Evaluator, e: Expr, dim: U.Dim, field: str = "") -> tuple[float, float]:
    v = ev.value(e)
    if not isinstance(v, Vec) or len(v.items) != 2:
        what = f" for `{field}`" if field else ""
        raise e.pos.error(f"a vector `(x, y)` was expected{what}, got `{e.pos.text}`",
                          hint=f"e.g. `({dim.example}, 0)`")
    out = []
    for s in v.items:
        try:
            out.append(U.to_si(s.q, s.plain, dim, e.pos.text))
        except U.UnitError as err:
            raise e.pos.error(err.message, err.hint) from None
    plain = [x for s, x in zip(v.items, out) if s.plain]
    if plain and any(plain):
        ev.note_plain(e, out, dim, field)
    return out[0], out[1]


def symbol_of(ev: Evaluator, e: Expr, choices, field: str) -> str:
    v = ev.value(e)
    name = v.name if isinstance(v, Symbol) else v.call.name if isinstance(v, CallVal) else None
    if name is None:
        raise e.pos.error(f"`{field}` takes a name, one of: {', '.join(choices)}; got `{e.pos.text}`",
                          hint=f"e.g. `{field} = {choices[0]}`")
    if name not in choices:
        where = v.pos if isinstance(v, Symbol) and v.pos.file == "--set" else e.pos
        raise where.error(f"unknown {field} `{name}`",
                          hint=did_you_mean(name, choices) or f"choose one of: {', '.join(choices)}")
    return name


def _chain(names: list[str]) -> str:
    """`a` → `b` → `a`; a long chain shows its ends and how many are left out."""
    if len(names) > 9:
        names = [*names[:4], f"… {len(names) - 8} more …", *names[-4:]]
        return " → ".join(n if n.startswith("…") else f"`{n}`" for n in names)
    return " → ".join(f"`{n}`" for n in names)


def _format_value(v) -> str:
    if isinstance(v, Scalar):
        return U.format_quantity(v.q)
    if isinstance(v, Vec):
        return "(" + ", ".join(U.format_quantity(s.q) for s in v.items) + ")"
    if isinstance(v, Symbol):
        return v.name
    return "?"
