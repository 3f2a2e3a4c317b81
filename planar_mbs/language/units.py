"""Units: our own unit table (pint for anything else), unit parsing, dimension checks, SI conversion.

pint is imported only for a unit name our table does not hold.  Angles are radians and
dimensionless in pint, so `deg`, `rev` and `rpm` convert (``5000 rpm`` is
523.6 rad/s, ``5 rev`` is 10 pi).  A plain number (no unit) where a dimensional
value is expected is taken in SI.  Errors are `UnitError` (message + hint); the
compiler adds the position and turns them into `ModelError`.
"""
from __future__ import annotations

import functools
import math
import re
import sys
from dataclasses import dataclass

from ..errors import ModelError, did_you_mean
from ..lazy import lazy

pint = lazy("pint")  # 0.1-0.5 s: only for a unit name our table does not hold

_REGISTRY = None

COMMON_UNITS = (
    "m", "mm", "cm", "um", "km", "kg", "g", "s", "ms", "us", "min", "h", "N", "kN", "Pa",
    "kPa", "MPa", "GPa", "rad", "deg", "rev", "rpm", "Hz", "J", "W", "kW",
)


class UnitError(Exception):
    def __init__(self, message: str, hint: str = ""):
        super().__init__(message)
        self.message = message
        self.hint = hint


def _import_pint():
    """Import pint without its optional dask support: pint's `compat` imports dask
    whenever it is installed (0.11 s, and dask is a heavy import no model needs).
    A ``None`` entry in sys.modules makes pint's ``import dask`` fail as if absent;
    a process that already imported dask (sweeps) is left alone."""
    if "pint" in sys.modules or "dask" in sys.modules:
        return
    sys.modules["dask"] = None
    try:
        pint.UnitRegistry  # the first access imports pint, here with dask hidden
    finally:
        del sys.modules["dask"]


def registry():
    """The process-wide pint UnitRegistry (created on first use; `rev` added as alias of `turn`)."""
    global _REGISTRY
    if _REGISTRY is None:
        _import_pint()

        try:
            ureg = pint.UnitRegistry(cache_folder=":auto:")
        except Exception:  # pragma: no cover - a read-only cache folder
            ureg = pint.UnitRegistry()
        ureg.define("@alias turn = rev")
        _REGISTRY = ureg
    return _REGISTRY


# ------------------------------------------------------------------ our own unit table
# A model names a handful of units; importing pint and building its registry costs 0.1-0.5 s, far more
# than compiling the model.  So units are resolved from this table (SI scale and dimension exponents)
# and pint is asked only for a name the table does not hold (then cached).  pint stays the authority:
# tests/test_units.py checks every entry of the table against pint.
DIMENSIONS = ("[length]", "[mass]", "[time]", "[current]", "[temperature]", "[substance]", "[luminosity]")


class Dimensionality(tuple):
    """Exponents of the SI base dimensions (angles are dimensionless, as in pint); false when all are 0."""

    def __bool__(self) -> bool:
        return any(self)

    def __str__(self) -> str:
        num = [f"{d}" + (f" ** {e:g}" if e != 1 else "") for d, e in zip(DIMENSIONS, self) if e > 0]
        den = [f"{d}" + (f" ** {-e:g}" if e != -1 else "") for d, e in zip(DIMENSIONS, self) if e < 0]
        text = " * ".join(num) or "1"
        return text + "".join(f" / {d}" for d in den) if den else text

    __repr__ = __str__


def _dims(length=0, mass=0, time=0) -> Dimensionality:
    return Dimensionality((float(length), float(mass), float(time), 0.0, 0.0, 0.0, 0.0))


_L, _M, _T, _ONE = _dims(1), _dims(mass=1), _dims(time=1), _dims()
_PREFIXES = {"G": 1e9, "M": 1e6, "k": 1e3, "": 1.0, "c": 1e-2, "m": 1e-3, "u": 1e-6, "µ": 1e-6, "n": 1e-9}
_PREFIXED = {  # symbol: (SI scale, dimension); each also with the prefixes above
    "m": (1.0, _L), "g": (1e-3, _M), "s": (1.0, _T), "N": (1.0, _dims(1, 1, -2)), "Pa": (1.0, _dims(-1, 1, -2)),
    "J": (1.0, _dims(2, 1, -2)), "W": (1.0, _dims(2, 1, -3)), "Hz": (1.0, _dims(time=-1)),
}
TABLE: dict[str, tuple[float, Dimensionality]] = {
    p + name: (f * scale, dim) for name, (scale, dim) in _PREFIXED.items() for p, f in _PREFIXES.items()
}
TABLE.update({
    "rad": (1.0, _ONE), "radian": (1.0, _ONE), "deg": (math.pi / 180, _ONE), "degree": (math.pi / 180, _ONE),
    "rev": (2 * math.pi, _ONE), "turn": (2 * math.pi, _ONE), "revolution": (2 * math.pi, _ONE),
    "rpm": (2 * math.pi / 60, _dims(time=-1)), "min": (60.0, _T), "minute": (60.0, _T), "h": (3600.0, _T),
    "hour": (3600.0, _T), "meter": (1.0, _L), "metre": (1.0, _L), "second": (1.0, _T), "kilogram": (1.0, _M),
    "gram": (1e-3, _M), "newton": (1.0, _dims(1, 1, -2)), "pascal": (1.0, _dims(-1, 1, -2)),
    "joule": (1.0, _dims(2, 1, -2)), "watt": (1.0, _dims(2, 1, -3)), "hertz": (1.0, _dims(time=-1)),
    "dimensionless": (1.0, _ONE),
})


@functools.lru_cache(maxsize=None)
def lookup(name: str) -> tuple[float, Dimensionality]:
    """(SI scale, dimensionality) of one unit name: from TABLE, else from pint (imported then)."""
    if name in TABLE:
        return TABLE[name]

    try:
        q = registry().Quantity(1.0, registry().parse_units(name))
        base = q.to_base_units()
        twice = registry().Quantity(2.0, registry().parse_units(name)).to_base_units().magnitude
    except (pint.errors.UndefinedUnitError, AttributeError, ValueError):
        hint = did_you_mean(name, COMMON_UNITS) or "common units: " + ", ".join(COMMON_UNITS)
        raise UnitError(f"unknown unit `{name}`", hint) from None
    dims = dict(base.dimensionality)
    if any(k not in DIMENSIONS for k in dims) or not math.isclose(twice, 2 * base.magnitude, rel_tol=1e-12):
        raise UnitError(f"the unit `{name}` cannot be used here (an offset or non-SI dimension)",
                        "use SI or common units (" + ", ".join(COMMON_UNITS) + ")")
    return float(base.magnitude), Dimensionality(float(dims.get(d, 0)) for d in DIMENSIONS)


@dataclass(frozen=True)
class Unit:
    """A product of named units with exponents, in the order written; `scale` is its value in SI."""

    factors: tuple[tuple[str, float], ...]
    scale: float
    dimensionality: Dimensionality

    def _combine(self, other: "Unit", sign: float) -> "Unit":
        exps = dict(self.factors)
        for name, e in other.factors:
            exps[name] = exps.get(name, 0.0) + sign * e
        return Unit(tuple((n, e) for n, e in exps.items() if e != 0),
                    self.scale * other.scale ** sign,
                    Dimensionality(a + sign * b for a, b in zip(self.dimensionality, other.dimensionality)))

    def __mul__(self, other: "Unit") -> "Unit":
        return self._combine(other, 1.0)

    def __truediv__(self, other: "Unit") -> "Unit":
        return self._combine(other, -1.0)

    def __pow__(self, x: float) -> "Unit":
        return Unit(tuple((n, e * x) for n, e in self.factors if e * x != 0), self.scale ** x,
                    Dimensionality(a * x for a in self.dimensionality))

    def __format__(self, spec: str) -> str:
        """`kg * m ** 2`, `m / s ** 2` (pint's layout; ``format_quantity`` shortens it)."""
        def one(n, e):
            return n if e == 1 else f"{n} ** {e:g}"
        num = [one(n, e) for n, e in self.factors if e > 0]
        den = [one(n, -e) for n, e in self.factors if e < 0]
        if not num and not den:
            return ""
        text = " * ".join(num) or "1"
        return text + "".join(f" / {d}" for d in den)

    __str__ = __format__


ONE = Unit((), 1.0, _ONE)


class Quantity:
    """A number with a `Unit` (the part of pint's Quantity the compiler uses)."""

    __slots__ = ("magnitude", "units")

    def __init__(self, magnitude, units: Unit = ONE):
        self.magnitude = magnitude
        self.units = units

    @property
    def dimensionality(self) -> Dimensionality:
        return self.units.dimensionality

    @property
    def dimensionless(self) -> bool:
        return not self.units.dimensionality

    def to_base_units(self) -> "Quantity":
        return Quantity(self.magnitude * self.units.scale, Unit((), 1.0, self.units.dimensionality))

    def _same(self, other) -> float:
        """other's magnitude in self's units (same dimension: the caller checks)."""
        o = other if isinstance(other, Quantity) else Quantity(other)
        if o.dimensionality != self.dimensionality:
            raise ValueError(f"cannot add or subtract {self.dimensionality} and {o.dimensionality}")
        return o.magnitude * (o.units.scale / self.units.scale)

    def __add__(self, other):
        return Quantity(self.magnitude + self._same(other), self.units)

    def __sub__(self, other):
        return Quantity(self.magnitude - self._same(other), self.units)

    def __mul__(self, other):
        if isinstance(other, Quantity):
            return Quantity(self.magnitude * other.magnitude, self.units * other.units)
        return Quantity(self.magnitude * other, self.units)

    __rmul__ = __mul__

    def __truediv__(self, other):
        if isinstance(other, Quantity):
            return Quantity(self.magnitude / other.magnitude, self.units / other.units)
        return Quantity(self.magnitude / other, self.units)

    def __rtruediv__(self, other):
        return Quantity(other / self.magnitude, ONE / self.units)

    def __pow__(self, x):
        return Quantity(self.magnitude ** x, self.units ** float(x))

    def __neg__(self):
        return Quantity(-self.magnitude, self.units)

    def __abs__(self):
        return Quantity(abs(self.magnitude), self.units)

    def __repr__(self) -> str:
        return f"<Quantity({self.magnitude}, '{self.units}')>"


_FACTOR = re.compile(r"([*/]?)([^\W\d]\w*)(?:(?:\^|\*\*)(-?\d+(?:\.\d+)?))?")


@functools.lru_cache(maxsize=4096)
def parse_unit(text: str) -> Unit:
    """`kg*m^2`, `m/s^2`, `N/m^1.5`, `1/s` (also pint's `**`) → `Unit`, left to right; each name
    looked up alone (`lookup`)."""
    unit = ONE
    invert_first = text.startswith("1/")
    pos = 2 if invert_first else 0
    while pos < len(text):
        m = _FACTOR.match(text, pos)
        if m is None:
            raise UnitError(f"cannot read the unit `{text}`", "write units like `kg*m^2` or `m/s^2`")
        op, name, exp = m.groups()
        scale, dims = lookup(name)
        u = Unit(((name, 1.0),), scale, dims)
        if exp is not None:
            u = u ** float(exp)
        unit = unit / u if op == "/" or invert_first else unit * u
        invert_first = False
        pos = m.end()
    return unit


def quantity(value: float, unit_text: str | None) -> Quantity:
    """A Quantity from a number and its unit text (None: dimensionless)."""
    if unit_text is None:
        return Quantity(float(value))
    return Quantity(float(value), parse_unit(unit_text))


@dataclass(frozen=True)
class Dim:
    """An expected dimension: its words, its SI unit (pint syntax) and an example."""

    words: str
    si: str
    example: str

    @property
    def dimensionality(self) -> Dimensionality:
        return parse_unit(self.si).dimensionality


MASS = Dim("a mass", "kg", "0.3 kg")
LENGTH = Dim("a length", "m", "5 mm")
TIME = Dim("a time", "s", "10 ms")
INERTIA = Dim("a moment of inertia", "kg*m**2", "2.5e-4 kg*m^2")
ANGLE = Dim("an angle", "radian", "30 deg")
NUMBER = Dim("a plain number", "dimensionless", "0.3")
ANGULAR_VELOCITY = Dim("an angular velocity", "radian/s", "5000 rpm")
RATE = Dim("a rate (1/time)", "1/s", "5 1/s")
FREQUENCY = Dim("a frequency", "Hz", "2 Hz")
VELOCITY = Dim("a velocity", "m/s", "0.5 m/s")
ACCELERATION = Dim("an acceleration", "m/s**2", "9.81 m/s^2")
FORCE = Dim("a force", "N", "10 N")
TORQUE = Dim("a torque", "N*m", "2 N*m")
PRESSURE = Dim("a pressure (modulus)", "Pa", "207 GPa")
DENSITY = Dim("a density", "kg/m**3", "7800 kg/m^3")
VISCOSITY = Dim("a dynamic viscosity", "Pa*s", "0.04 Pa*s")
STIFFNESS = Dim("a stiffness", "N/m", "1000 N/m")
DAMPING = Dim("a damping coefficient", "N*s/m", "5 N*s/m")
PER_LENGTH = Dim("an inverse length (a stiffness per unit normal force)", "1/m", "1e5 1/m")
TIME_PER_LENGTH = Dim("a time per length (a damping per unit normal force)", "s/m", "600 s/m")
ROT_STIFFNESS = Dim("a rotational stiffness", "N*m/radian", "10 N*m/rad")
ROT_DAMPING = Dim("a rotational damping coefficient", "N*m*s/radian", "0.1 N*m*s/rad")

_DESCRIBE = (MASS, LENGTH, TIME, INERTIA, NUMBER, ANGULAR_VELOCITY, VELOCITY, ACCELERATION,
             FORCE, TORQUE, PRESSURE, DENSITY, STIFFNESS, DAMPING, ROT_DAMPING)


def contact_stiffness(exponent: float) -> Dim:
    """N/m^n: the stiffness K of F = K d^n (Muvengei et al. eq. 17)."""
    return Dim(f"a contact stiffness (N/m^{exponent:g})", f"N/m**{exponent!r}", f"4e10 N/m^{exponent:g}")


def describe(dimensionality) -> str:
    """Words for a dimensionality: 'a length', 'a mass', or the raw dimension."""
    if not dimensionality:
        return "a plain number (or an angle)"
    if dimensionality == ANGULAR_VELOCITY.dimensionality:
        return "an angular velocity or frequency"
    for d in _DESCRIBE:
        if d.dimensionality == dimensionality:
            return d.words
    return f"a quantity of dimension {dimensionality}"


def example_unit(dimensionality) -> str:
    """A unit of that dimension to show in a hint: the one of the common quantities (`mm` for a length,
    `rpm` for an angular velocity, `N` for a force), else the SI base units (`kg*m/s^3`)."""
    for d in (ANGULAR_VELOCITY, *_DESCRIBE):
        if d.dimensionality == dimensionality and d is not NUMBER:
            return d.example.split(" ", 1)[1]
    order = (1, 0, 2, 3, 4, 5, 6)  # kg*m^2/s^3
    names = [("m", "kg", "s", "A", "K", "mol", "cd")[i] for i in order]
    exps = [dimensionality[i] for i in order]
    num = [n + (f"^{e:g}" if e != 1 else "") for n, e in zip(names, exps) if e > 0]
    den = [n + (f"^{-e:g}" if e != -1 else "") for n, e in zip(names, exps) if e < 0]
    return ("*".join(num) or "1") + "".join("/" + d for d in den)


def format_quantity(q) -> str:
    """`5000 rpm`, `0.3 mm`, `0.9`: a value with its units, short."""
    mag = f"{q.magnitude:.15g}"
    units = f"{q.units:~}".replace(" ** ", "^").replace(" * ", "*").replace(" / ", "/")
    return f"{mag} {units}" if units else mag


def to_si(q, plain: bool, dim: Dim, what: str, field: str = "") -> float:
    """Magnitude of q in SI base units after checking it has the dimension `dim`.

    A plain number (no unit) is already SI.  `what` is the quoted expression,
    used in the error ("a mass was expected, got a length (3 m)"); `field`
    names the field in the hint.
    """
    if plain:
        value = float(q.magnitude)
    else:
        if q.dimensionality != dim.dimensionality:
            got = describe(q.dimensionality)
            example = f"{field} = {dim.example}" if field else dim.example
            raise UnitError(f"{dim.words} was expected, got {got} ({what})",
                            f"write {dim.words} with a matching unit, e.g. `{example}`")
        value = float(q.to_base_units().magnitude)
        if math.isfinite(value):
            value = float(f"{value:.15g}")  # 10 us -> 1e-05, not 9.999999999999999e-06
    if not math.isfinite(value):
        raise UnitError(f"the value is not finite ({what})", "check the arithmetic for overflow")
    return value


_CLI_QUANTITY = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(\S*)\s*$")
_DIMS = {"time": TIME, "length": LENGTH, "angular_velocity": ANGULAR_VELOCITY, "frequency": FREQUENCY}


def parse_quantity(text: str, dimension: str, where: str = "") -> float:
    """A command-line value such as `24ms`, `"0.06 s"` or `1e-6` (SI) in SI units.

    Raises `ModelError` naming the option (`where`) on a bad number, unit or dimension.
    """
    dim = _DIMS[dimension]
    m = _CLI_QUANTITY.match(text)
    if m is None:
        raise ModelError(f"`{text}` is not a number with an optional unit", where,
                         hint=f"write {dim.words}, e.g. `{dim.example.replace(' ', '')}`")
    number, unit = m.groups()
    try:
        return to_si(quantity(float(number), unit or None), not unit, dim, text)
    except UnitError as err:
        raise ModelError(err.message, where, hint=err.hint) from None
