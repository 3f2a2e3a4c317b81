"""One validation of a run's settings for the command line and the Python API.

`mbs run`, `mbs sweep`, `simulate` and `Simulation` all call `check_settings` on the settings a
run will use, so the same value is refused everywhere with the same sentence; only the name of
the setting follows its origin (``--t-end 0`` on the command line, ``t_end = 0`` from Python,
``t_end = 0`` in the model's simulate block with the model's path).  `check_number` words every
range error of an option (the command line's other options use it too).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import os

from .. import catalog
from ..errors import ModelError
from ..mechanism.model import Model
from ..lazy import lazy

# numpy: `mbs --help` and `mbs check` read this module's bounds (`MAX_T_END`) without loading it
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from ..results import hdf5
    from . import output_size
else:  # each loaded on its first use (see the comments: not on the light paths)
    hdf5 = lazy("..results.hdf5", __package__)
    output_size = lazy(".output_size", __package__)

MAX_T_END = 1e6  # s of simulated time (11.6 days): beyond it a typo is far likelier than a wish
CLI, API = "cli", "api"


def shown(option: str) -> str:
    """How a setting's name is written before its value: ``--t-end 0`` or ``t_end = 0``."""
    return option if option.startswith("-") else f"{option} ="


def check_number(value, option: str, *, low=None, high=None, low_ok: bool = False, high_ok: bool = True,
                 hint: str = "", where: str | None = None):
    """`value` if it is a finite number in the interval (low, high] (``low_ok``/``high_ok``
    close or open either end); None passes.  Raises `ModelError` naming the option otherwise
    (``where``: the error's location, the option by default)."""
    if value is None:
        return None
    text = f"{value:g}" if isinstance(value, float) else str(value)
    head = f"`{shown(option)} {text}`" if option.startswith("-") else f"`{option} = {text}`"
    where = option if where is None else where
    if isinstance(value, float) and not math.isfinite(value):
        raise ModelError(f"{head} is not a finite number", where, hint=hint)
    if low is not None and (value < low or (value == low and not low_ok)):
        raise ModelError(f"{head} must be {'at least' if low_ok else 'greater than'} {low:g}", where, hint=hint)
    if high is not None and (value > high or (value == high and not high_ok)):
        raise ModelError(f"{head} must be {'at most' if high_ok else 'less than'} {high:g}", where, hint=hint)
    return value


def label(name: str, style: str) -> str:
    """The name of setting `name` as its origin writes it (``--t-end``, ``t_end``)."""
    return "--" + name.replace("_", "-") if style == CLI else name


def check_settings(settings, given=(), style: str = API, source: str = "") -> None:
    """Refuse (`ModelError`, exit 2) settings no run can use: times that are not positive and
    finite, an rtol outside (0, 1), h_min above h_max, and a fixed-step run that cannot reach
    t_end within max_steps (known before it starts).  ``given``: the settings the caller set
    (named as ``style`` writes them); the others came from the model file ``source``."""
    def name(n):
        return label(n, style) if n in given else n

    def where(n):
        if n in given:
            return name(n) if style == CLI else f"simulate({n}=...)"
        return source or "simulate block"

    def number(n, **bounds):
        check_number(getattr(settings, n), name(n), where=where(n), **bounds)

    for n in ("t_end", "output_step", "step"):
        high = MAX_T_END if n == "t_end" else None
        number(n, low=0.0, high=high, hint=f"give a positive time with units, e.g. {_example(n, style, given)}"
               + (f" (at most {high:g} s)" if high else ""))
    # an rtol outside (0, 1) is a mistake wherever it is given; one in the model file matters where it is used
    # (a fixed-step method uses no tolerance); the floor of double precision and atol: `simulation.check_tolerances`
    if _method(settings).adaptive or "rtol" in given:
        number("rtol", low=0.0, high=1.0, high_ok=False,
               hint=f"a relative tolerance lies between 0 and 1, e.g. {_example('rtol', style, given)}")
    for n in ("h_min", "h_max", "alpha", "beta"):
        number(n, low=0.0, low_ok=True, hint="zero or a positive value")
    if settings.max_steps < 1:
        raise ModelError(f"`max_steps = {settings.max_steps}` must be at least 1", where("max_steps"),
                         hint="e.g. max_steps = 1e8")
    if settings.h_max > 0 and settings.h_min > settings.h_max:
        raise ModelError(f"`h_min = {settings.h_min:g} s` is larger than `h_max = {settings.h_max:g} s`: no step "
                         "can be taken", where("h_min" if "h_min" in given else "h_max"),
                         hint="give h_min below h_max (h_max = 0: no largest step)")
    _check_fixed_step(settings, name, where)


def _method(settings) -> catalog.IntegratorSpec:
    return catalog.INTEGRATORS[int(settings.integrator)]


def _check_fixed_step(settings, name, where) -> None:
    """A fixed-step method takes t_end / step steps: more than max_steps is refused before the run, not after it."""
    method = _method(settings)
    if method.adaptive:
        return
    steps = settings.t_end / settings.step
    if steps > settings.max_steps:
        raise ModelError(f"{method.name.upper()} with `{shown(name('step'))} {settings.step:g} s` needs {steps:.3g} steps to reach "
                         f"t_end = {settings.t_end:g} s, more than max_steps = {settings.max_steps:,}",
                         where("step"), hint=f"a step of at least {settings.t_end / settings.max_steps:.3g} s "
                         "(a unit typo?), or a larger max_steps")


def _example(n: str, style: str, given) -> str:
    examples = {"t_end": "60ms", "output_step": "10us", "step": "1us", "rtol": "1e-8"}
    if style == CLI and n in given:
        return f"`--{n.replace('_', '-')} {examples[n]}`"
    return f"`{n} = \"{examples[n]}\"`" if n != "rtol" else "`rtol = 1e-8`"


def check_memory(model, settings, what: str = "Simulation") -> None:
    """A run that keeps every row in memory (`Simulation`) is refused when its rows to t_end
    would not fit in half of the physical memory -- known before it starts."""
    est = output_size.estimate(model, settings)
    if est.bytes > hdf5.memory_budget():
        raise ModelError(f"{what} keeps every output row in memory: {est.describe()} to t_end = "
                         f"{settings.t_end:g} s would not fit ({hdf5.memory_budget() / 2**30:.1f} GiB allowed)",
                         f"{what}(...)", hint="a larger output_step, a shorter t_end, or `simulate(..., "
                         "output=...)`, which streams its rows to a file")


def given_settings(changes: dict) -> set:
    """The settings a `simulate`/`Simulation` caller set (``revolutions``/``per_rev`` set t_end and
    output_step)."""
    given = {k for k, v in changes.items() if v is not None}
    if "revolutions" in given:
        given.add("t_end")
    if "per_rev" in given:
        given.add("output_step")
    return given


def check_stop(t_stop: float, t_end: float, what: str = "run_until") -> None:
    """A `Simulation` advances up to its t_end, not past it (its rows and its file are sized by it)."""
    if not math.isfinite(t_stop) or t_stop > t_end * (1 + 1e-12):
        raise ModelError(f"`{what}({t_stop:g} s)` is past the end of this Simulation, t_end = {t_end:g} s",
                         f"{what}(...)", hint="create the Simulation with a later t_end "
                         f"(Simulation(model, t_end=...)); `run()` runs to t_end")


def check_arguments(model, signals, what: str) -> None:
    """The API's arguments refused with the CLI's kind of message (ModelError, exit 2 from the CLI) before
    they reach the run: a model that is not a compiled one (a path, None), signal names that are not text."""
    from_path = isinstance(model, (str, os.PathLike))
    if not isinstance(model, Model):
        raise ModelError(f"{what} runs a compiled model, not {type(model).__name__} {model!r:.60}", f"{what}(...)",
                         hint=("load it first: `mbs.load_model(path)`" if from_path else
                               "`mbs.load_model(path)` or `mbs.compile_text(text)` gives one"))
    if signals is None or isinstance(signals, str):
        return
    try:
        names = list(signals)
    except TypeError:
        names = [signals]
    bad = [n for n in names if not isinstance(n, str)]
    if bad:
        raise ModelError(f"signals are named by text (`slider.x`, or a whole entity `slider`), not {bad[0]!r}",
                         f"{what}(signals=...)", hint="e.g. signals=[\"slider.x\", \"A\"]")


def seconds_value(value, name: str) -> float:
    """A finite number of seconds from a plain number (a 1-element array too), refused otherwise."""
    try:
        seconds = float(value.item() if hasattr(value, "item") and getattr(value, "size", 1) == 1 else value)
    except (TypeError, ValueError):
        raise ModelError(f"`{name}` takes a time (seconds, or text with units), not {value!r:.60}", f"{name}=",
                         hint=f"e.g. {name}=\"1 ms\"") from None
    if not math.isfinite(seconds):
        raise ModelError(f"`{name}` must be a finite time, not {seconds}", f"{name}=", hint=f"e.g. {name}=\"1 ms\"")
    return seconds
