"""Units: one lazily created pint registry, unit parsing, dimension checks, SI conversion.

pint is imported only when a model is compiled.  Angles are radians and
dimensionless in pint, so `deg`, `rev` and `rpm` convert (``5000 rpm`` is
523.6 rad/s, ``5 rev`` is 10 pi).  A plain number (no unit) where a dimensional
value is expected is taken in SI.  Errors are `UnitError` (message + hint); the
compiler adds the position and turns them into `ModelError`.
"""
from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass

from .errors import did_you_mean

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
    import sys

    if "pint" in sys.modules or "dask" in sys.modules:
        return
    sys.modules["dask"] = None
    try:
        import pint  # noqa: F401
    finally:
        del sys.modules["dask"]


def registry():
    """The process-wide pint UnitRegistry (created on first use; `rev` added as alias of `turn`)."""
    global _REGISTRY
    if _REGISTRY is None:
        _import_pint()
        import pint

        try:
            ureg = pint.UnitRegistry(cache_folder=":auto:")
        except Exception:  # pragma: no cover - a read-only cache folder
            ureg = pint.UnitRegistry()
        ureg.define("@alias turn = rev")
        _REGISTRY = ureg
    return _REGISTRY


_FACTOR = re.compile(r"([*/]?)([^\W\d]\w*)(?:\^(-?\d+(?:\.\d+)?))?")


@functools.lru_cache(maxsize=4096)
def parse_unit(text: str):
    """`kg*m^2`, `m/s^2`, `N/m^1.5`, `1/s` → pint Unit, left to right; each name looked up alone.

    Cached: pint's own lookup costs ~0.1 ms, which a file with 20 000 params would pay each time."""
    import pint

    ureg = registry()
    unit = ureg.dimensionless
    invert_first = text.startswith("1/")
    pos = 2 if invert_first else 0
    while pos < len(text):
        m = _FACTOR.match(text, pos)
        if m is None:
            raise UnitError(f"cannot read the unit `{text}`", "write units like `kg*m^2` or `m/s^2`")
        op, name, exp = m.groups()
        try:
            u = ureg.parse_units(name)
        except (pint.errors.UndefinedUnitError, AttributeError, ValueError):
            hint = did_you_mean(name, COMMON_UNITS) or "common units: " + ", ".join(COMMON_UNITS)
            raise UnitError(f"unknown unit `{name}`", hint) from None
        if exp is not None:
            u = u ** float(exp)
        unit = unit / u if op == "/" or invert_first else unit * u
        invert_first = False
        pos = m.end()
    return unit


def quantity(value: float, unit_text: str | None):
    """A pint Quantity from a number and its unit text (None: dimensionless)."""
    ureg = registry()
    if unit_text is None:
        return ureg.Quantity(float(value))
    return ureg.Quantity(float(value), parse_unit(unit_text))


@dataclass(frozen=True)
class Dim:
    """An expected dimension: its words, its SI unit (pint syntax) and an example."""

    words: str
    si: str
    example: str

    @property
    def dimensionality(self):
        return registry().parse_units(self.si).dimensionality


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
STIFFNESS = Dim("a stiffness", "N/m", "1000 N/m")
DAMPING = Dim("a damping coefficient", "N*s/m", "5 N*s/m")
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
_DIMS = {"time": TIME, "length": LENGTH, "angular_velocity": ANGULAR_VELOCITY}


def parse_quantity(text: str, dimension: str, where: str = "") -> float:
    """A command-line value such as `24ms`, `"0.06 s"` or `1e-6` (SI) in SI units.

    Raises `ModelError` naming the option (`where`) on a bad number, unit or dimension.
    """
    from .errors import ModelError

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
