"""Tables in expressions: ``table("gas.csv", x = crank.phi, x_unit = "deg", y_unit = "kN",
interpolation = akima, periodic = 720 deg)`` or written inline (``xs = (...)``, ``ys = (...)``).

A table is read and checked when the model is compiled (the file exists, every line holds two
finite numbers, x strictly increases: otherwise an error at the file's line) and stored as a
piecewise cubic, one row per knot ``(x_k, c0, c1, c2, c3)`` (`kernel.expressions.table_eval`):

* ``linear``: straight segments;
* ``cubic``: the cubic spline with not-a-knot ends (periodic ends for a periodic table), which
  reproduces any cubic exactly (de Boor, "A Practical Guide to Splines", ch. IV);
* ``akima``: Akima's local spline (H. Akima, "A new method of interpolation and smooth curve fitting
  based on local procedures", J. ACM 17, 1970), no overshoot near steps.

Outside its knots a table holds its end values; a periodic one repeats with its period (its
knots must span at most one period; the last knot is closed onto the first).
"""
from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import math
import os
import stat
from pathlib import Path

import numpy as np

from ..language import units as U
from ..errors import ModelError, did_you_mean
from .model import ExprOp
from ..language.spec import Call, Expr, KwArg, Name, String, Vector
from ..lazy import lazy

interpolate = lazy("scipy.interpolate")  # scipy: only for a cubic or Akima table

INTERPOLATIONS = ("linear", "cubic", "akima")
TABLE_ARGS = ("x", "x_unit", "y_unit", "xs", "ys", "interpolation", "periodic")
MAX_TABLE_BYTES = 16 << 20


def table_node(progs, e: Call):
    """The node of a `table(...)` call: its argument x compiled, its data checked and stored."""
    kw = {k.name: k for k in e.kwargs}
    for k in e.kwargs:
        if k.name not in TABLE_ARGS:
            raise k.pos.error(f"unknown argument `{k.name}` of `table`",
                              hint=did_you_mean(k.name, TABLE_ARGS) or "arguments: " + ", ".join(TABLE_ARGS))
    if "x" not in kw:
        raise e.pos.error("`table(...)` needs `x = ...`, the value it is looked up at",
                          hint='e.g. `table("gas.csv", x = crank.phi, x_unit = "deg", y_unit = "N")`')
    x = progs.node(kw["x"].value)
    if len(e.args) > 1 or (e.args and not isinstance(e.args[0], String)):
        raise e.pos.error("`table` takes one quoted file name, or `xs = (...)` and `ys = (...)`",
                          hint='e.g. `table("gas.csv", x = crank.phi, x_unit = "deg", y_unit = "N")`')
    if e.args:
        xs, ys, xdim, ydim = _from_file(progs, e, kw)
    else:
        xs, ys, xdim, ydim = _inline(progs, e, kw)
    if x.dim != xdim and not x.plain:
        raise kw["x"].value.pos.error(f"the table's x column is {U.describe(xdim)}, its argument "
                                      f"{U.describe(x.dim)} (`{kw['x'].value.pos.text}`)",
                                      hint="declare the column's unit with `x_unit`, or look the table up "
                                           "at a matching signal")
    period = _period(progs, kw, xdim, xs, ys, e)
    method = _interpolation(progs.ev, kw)
    rows = _checked_knots(e, xs, ys, method, period)
    progs.tables.append((rows, period))
    k = len(progs.tables) - 1
    value, fault = progs.finite(e.pos, lambda: evaluate(rows, period, x.value), [x])
    return progs.op(ExprOp.TABLE, [x], ydim, False, value, fault, extra=k)


def _checked_knots(e: Call, xs, ys, method: str, period: float) -> np.ndarray:
    """`knots`, refused at the call when its values (in SI units) or its interpolation leave the
    range of a float (values near 1.8e308, knots 1e-320 apart): an error, never a numpy warning."""
    rows = None
    if np.isfinite(xs).all() and np.isfinite(ys).all():
        try:
            with np.errstate(over="raise", divide="raise", invalid="raise", under="ignore"):
                rows = knots(xs, ys, method, period)
        except (FloatingPointError, ValueError, ZeroDivisionError):
            rows = None
    if rows is None or not np.isfinite(rows).all():
        raise e.pos.error("the table's values or the spacing of its x leave the range of a float (±1.8e308) "
                          f"in SI units{'' if method == 'linear' else f' or in its {method} interpolation'}",
                          hint="rescale the table or its units; keep neighbouring x apart")
    return rows


def _interpolation(ev, kw) -> str:
    if "interpolation" not in kw:
        return "linear"
    v = kw["interpolation"].value
    name = v.name if isinstance(v, Name) else None
    if name in ev.params:  # a param naming the method (`--set interpolation=cubic`)
        value = ev.param(name)
        name = getattr(value, "name", None)
    if name not in INTERPOLATIONS:
        raise v.pos.error(f"unknown interpolation `{v.pos.text}`",
                          hint=did_you_mean(str(name), INTERPOLATIONS) or "choose " + ", ".join(INTERPOLATIONS))
    return name


def _unit(kw, key: str, e: Call):
    """(SI scale, dimension) of a column unit given as a quoted text (`"deg"`, `"kN*m"`, `"1"`)."""
    if key not in kw:
        raise e.pos.error(f"a table read from a file needs `{key}`, the unit of its "
                          f"{'first' if key == 'x_unit' else 'second'} column",
                          hint=f'e.g. `{key} = "{"deg" if key == "x_unit" else "N"}"` (`"1"` for a plain number)')
    v = kw[key].value
    if not isinstance(v, String):
        raise v.pos.error(f"`{key}` is a unit in quotes", hint=f'e.g. `{key} = "mm"`')
    if v.value.strip() in ("1", ""):
        return 1.0, U.Dimensionality((0.0,) * 7)
    try:
        u = U.parse_unit(v.value.strip())
    except U.UnitError as err:
        raise v.pos.error(err.message, err.hint) from None
    return u.scale, u.dimensionality


_PROVIDED: contextvars.ContextVar[dict | None] = contextvars.ContextVar("tables_provided", default=None)


@contextlib.contextmanager
def provided(files: dict[str, bytes]):
    """Compile with the tables ``files`` ({`table_path` text: bytes}) instead of reading them."""
    token = _PROVIDED.set(dict(files))
    try:
        yield
    finally:
        _PROVIDED.reset(token)


def table_path(name: String) -> Path:
    """Where the table file named by ``name`` is: relative to the folder of the model that names it."""
    folder = Path(name.pos.file).parent if name.pos.file not in ("<string>", "--set") else Path.cwd()
    return folder / name.value


def read_table_file(path: Path) -> bytes:
    """Up to MAX_TABLE_BYTES + 1 bytes of a regular file, opened without blocking (a FIFO or a
    device is an `OSError`, never read)."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(0, "not a regular file")
        with os.fdopen(fd, "rb", closefd=False) as f:
            return f.read(MAX_TABLE_BYTES + 1)
    finally:
        os.close(fd)


def table_files(spec) -> dict[str, bytes]:
    """{`table_path` text: bytes} of every table file a parsed model names that can be read."""
    out: dict[str, bytes] = {}
    for st in spec.statements:
        for node in _calls([st.value, *(f.value for f in st.fields)]):
            if node.name == "table" and node.args and isinstance(node.args[0], String):
                path = table_path(node.args[0])
                try:
                    out.setdefault(str(path), read_table_file(path))
                except OSError:
                    pass  # the compile says so, at the place
    return out


def _calls(items):
    """Every `Call` in the expressions ``items``, nested ones too."""
    stack = list(items)
    while stack:
        x = stack.pop()
        if isinstance(x, (list, tuple)):
            stack.extend(x)
        elif isinstance(x, KwArg):
            stack.append(x.value)
        elif dataclasses.is_dataclass(x) and isinstance(x, Expr):
            if isinstance(x, Call):
                yield x
            stack.extend(getattr(x, f.name) for f in dataclasses.fields(x) if f.name != "pos")


def _from_file(progs, e: Call, kw):
    name: String = e.args[0]
    path = table_path(name)
    given = _PROVIDED.get()
    try:
        data = given[str(path)] if given and str(path) in given else read_table_file(path)
    except OSError as err:
        raise name.pos.error(f"cannot read the table `{name.value}` ({err.strerror or err})",
                             hint=f"the path is relative to the model's folder ({path.parent})") from None
    if len(data) > MAX_TABLE_BYTES:
        raise name.pos.error(f"the table `{name.value}` is larger than {MAX_TABLE_BYTES >> 20} MB")
    progs.table_files[str(path)] = data  # part of the model: stored with its results
    xscale, xdim = _unit(kw, "x_unit", e)
    yscale, ydim = _unit(kw, "y_unit", e)
    xs, ys = read_csv(data.decode("utf-8", errors="replace").removeprefix("\ufeff"), str(path))
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):  # `_checked_knots` refuses inf
        return xs * xscale, ys * yscale, xdim, ydim


def read_csv(text: str, path: str) -> tuple[np.ndarray, np.ndarray]:
    """Two columns of numbers, comma (or space, or semicolon) separated; `#` comments and one
    header line of words (no cell a number) allowed first.  Errors name the file's line."""
    xs, ys, lines = [], [], text.splitlines()
    first = True
    for i, raw in enumerate(lines, 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        cells = [c for c in line.replace(";", ",").replace("\t", ",").replace(" ", ",").split(",") if c]

        def fail(message, hint=""):
            return ModelError(message, path, i, 1, hint=hint, source_line=raw, width=max(1, len(raw)))
        header, first = first and not any(map(is_number, cells)), False
        if header:
            continue
        try:
            values = [float(c) for c in cells]
        except ValueError:
            bad = next(c for c in cells if not is_number(c))
            raise fail(f"a table line must hold two numbers (x, y); `{bad}` is not a number",
                       "e.g. `90, 1250.5`; only the first line may be a header of words") from None
        if len(values) != 2:
            raise fail(f"a table line must hold two numbers (x, y), this one holds {len(values)}")
        if not all(math.isfinite(v) for v in values):
            raise fail("the table holds a value that is not a finite number (NaN or infinity)",
                       "fill in the missing value or remove the line")
        if xs and not values[0] > xs[-1]:
            raise fail(f"the table's x must increase from line to line: {values[0]:g} follows {xs[-1]:g}",
                       "sort the table by its first column; remove repeated x")
        xs.append(values[0])
        ys.append(values[1])
    if len(xs) < 2:
        raise ModelError("a table needs at least two lines of numbers", path, 1, 1,
                         source_line=lines[0] if lines else "", hint="x, y on each line")
    return np.array(xs), np.array(ys)


def is_number(cell: str) -> bool:
    """Does a CSV cell read as a float (a header's words do not)?"""
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _inline(progs, e: Call, kw):
    cols = []
    for key in ("xs", "ys"):
        if key not in kw:
            raise e.pos.error("give the table's file name, or `xs = (...)` and `ys = (...)`",
                              hint="e.g. `table(x = t, xs = (0 s, 1 s, 2 s), ys = (0 N, 5 N, 0 N))`")
        v = kw[key].value
        if not isinstance(v, Vector):
            raise v.pos.error(f"`{key}` is a list of values in parentheses", hint=f"e.g. `{key} = (0 s, 1 s, 2 s)`")
        nodes = [progs.node(item) for item in v.items]
        for item, n in zip(v.items, nodes):
            if not n.const:
                raise item.pos.error("a table's values are constants", hint="use numbers and params")
            if n.dim != nodes[0].dim:
                raise item.pos.error(f"the values of `{key}` need one dimension: {U.describe(nodes[0].dim)} "
                                     f"first, then {U.describe(n.dim)}")
        values = np.array([n.value for n in nodes])
        if key == "xs" and not np.all(np.diff(values) > 0):
            bad = int(np.argmin(np.diff(values) > 0)) + 1
            raise v.items[bad].pos.error("the table's x must increase", hint="sort xs; remove repeated values")
        cols.append((values, nodes[0].dim))
    if len(cols[0][0]) != len(cols[1][0]):
        raise kw["ys"].value.pos.error(f"`xs` holds {len(cols[0][0])} values, `ys` {len(cols[1][0])}")
    return cols[0][0], cols[1][0], cols[0][1], cols[1][1]


def _period(progs, kw, xdim, xs, ys, e):
    if "periodic" not in kw:
        return 0.0
    v = kw["periodic"].value
    n = progs.node(v)
    if not n.const or (n.dim != xdim and not n.plain):
        raise v.pos.error(f"`periodic` is the period of x, a constant of its dimension ({U.describe(xdim)})",
                          hint="e.g. `periodic = 720 deg`")
    span = xs[-1] - xs[0]
    if not n.value > 0 or span > n.value * (1 + 1e-12):
        raise v.pos.error(f"the table spans {span:g} (SI), more than its period {n.value:g}",
                          hint="give the knots of one period")
    if math.isclose(span, n.value, rel_tol=1e-12) and not math.isclose(ys[-1], ys[0], rel_tol=1e-12, abs_tol=0.0):
        raise v.pos.error("a periodic table spanning one whole period must end with its first value",
                          hint="make the last y equal the first, or leave the last line out")
    return float(n.value)


def knots(xs, ys, method: str, period: float) -> np.ndarray:
    """Rows (x_k, c0, c1, c2, c3) of the piecewise cubic through (xs, ys); the last row is the last
    knot (its value only).  A periodic table gets its closing knot x0 + period."""
    xs, ys = np.asarray(xs, float), np.asarray(ys, float)
    if period > 0:
        if math.isclose(xs[-1] - xs[0], period, rel_tol=1e-12):
            xs = xs.copy()
            xs[-1] = xs[0] + period
            ys = ys.copy()
            ys[-1] = ys[0]
        else:
            xs, ys = np.append(xs, xs[0] + period), np.append(ys, ys[0])
    n = len(xs)
    rows = np.zeros((n, 5))
    rows[:, 0], rows[:, 1] = xs, ys
    if method == "linear" or n == 2:
        rows[:-1, 2] = np.diff(ys) / np.diff(xs)
        return rows

    if method == "cubic":
        pp = interpolate.CubicSpline(xs, ys, bc_type="periodic" if period > 0 else "not-a-knot")
        c = pp.c
    elif period > 0:  # Akima over the table repeated on both sides, its middle copy kept
        w = 3
        ext_x = np.concatenate([xs[-w - 1:-1] - period, xs, xs[1:w + 1] + period])
        ext_y = np.concatenate([ys[-w - 1:-1], ys, ys[1:w + 1]])
        c = interpolate.Akima1DInterpolator(ext_x, ext_y).c[:, w:w + n - 1]
    else:
        c = interpolate.Akima1DInterpolator(xs, ys).c
    rows[:-1, 2], rows[:-1, 3], rows[:-1, 4] = c[2], c[1], c[0]
    return rows


def evaluate(rows: np.ndarray, period: float, x: float) -> float:
    """The table at x, as `kernel.expressions.table_eval` computes it (the value at the initial state)."""
    x0, xn = rows[0, 0], rows[-1, 0]
    if period > 0:
        x = x - period * math.floor((x - x0) / period)
    elif x < x0:
        return float(rows[0, 1])
    elif x > xn:
        return float(rows[-1, 1])
    k = min(int(np.searchsorted(rows[:, 0], x, side="right")) - 1, len(rows) - 2)
    d = x - rows[k, 0]
    return float(rows[k, 1] + d * (rows[k, 2] + d * (rows[k, 3] + d * rows[k, 4])))
