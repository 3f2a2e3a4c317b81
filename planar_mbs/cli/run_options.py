"""The options of `mbs run`, written once: name, flags, kind, default and help of each.

Both readers of a `mbs run` command line are generated from `RUN_OPTIONS`: the typer command
(`app.run`, its help and checks) and `plain_run`, the typer-free reader of a plain command line
that `entry.main` tries first (typer's argument handling imports pydantic, about 0.06 s of a warm
run).  `plain_run` reads only what typer would read to the same values and leaves anything else
(``--help``, a mistake, an unusual spelling) to typer, which owns usage, help and errors.  No typer
here: this module is on the fast path.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

from planar_mbs import catalog


class Opt:
    """One option: `param` (the keyword of `run_command.run_model`), its `flags`, its `kind` (path,
    list, str, float, int or flag), its `default`, its `help`, typer's `show_default`, the lowest
    value allowed (`low`), `hidden` (an old name), and `into`: the parameter an old name sets."""

    __slots__ = ("param", "flags", "kind", "default", "help", "show_default", "low", "hidden", "into")

    def __init__(self, param: str, flags: tuple[str, ...], kind: str, help: str, default=None,
                 show_default: bool | str = True, low: float | None = None, hidden: bool = False,
                 into: str | None = None):
        self.param, self.flags, self.kind, self.default, self.help = param, flags, kind, default, help
        self.show_default, self.low, self.hidden, self.into = show_default, low, hidden, into


SET_HELP = ("Override a `param` of the model: NAME=VALUE with units, e.g. speed=2500rpm, \"clearance=0.1 mm\", "
            "law=hertz. Repeatable.")
SIMULATE_BLOCK = "the model's simulate block"

RUN_OPTIONS = (
    Opt("output", ("--output", "-o"), "path", "HDF5 results file.",
        show_default="results/<model name>.h5, with the --set values in the name; when that file holds a run with "
                     "other settings, beside it with the options given in the name (results/a_n=100.h5)"),
    Opt("set_", ("--set", "-s"), "list", SET_HELP, show_default=False),
    Opt("t_end", ("--t-end",), "str", "End time, with units (\"0.06 s\", 60ms).", show_default=SIMULATE_BLOCK),
    Opt("revolutions", ("--revolutions", "-n"), "float",
        "End time as a number of periods of the crank's driver (instead of --t-end).", show_default=False),
    Opt("output_step", ("--output-step",), "str",
        "Time between stored samples, with units (100us); a coarser step keeps files small.",
        show_default=SIMULATE_BLOCK),
    Opt("per_rev", ("--per-rev",), "int",
        "Stored samples per period of the crank's driver (instead of --output-step).", low=1, show_default=False),
    Opt("integrator", ("--integrator",), "str", "; ".join(f"{s.name}: {s.summary}" for s in catalog.INTEGRATORS) + ".",
        show_default=f"{SIMULATE_BLOCK}, else dopri5"),
    Opt("rtol", ("--rtol",), "float",
        "Relative tolerance of the adaptive integrator (floor: 10 x machine epsilon, 2.2e-15).",
        show_default=f"{SIMULATE_BLOCK}, else 1e-6"),
    Opt("atol", ("--atol",), "float", "Absolute tolerance of the adaptive integrator (> 0; SI units of each "
        "coordinate, e.g. 1e-3 x rtol).", show_default=f"{SIMULATE_BLOCK}, else 1e-9"),
    Opt("step", ("--step",), "str", "Fixed step of rk4 (first trial step of dopri5), with units (1us).",
        show_default=f"{SIMULATE_BLOCK}, else 1us"),
    Opt("quiet", ("--quiet", "-q"), "flag", "No progress bar.", default=False),
    Opt("rerun", ("--rerun",), "path", "Also write a rerun recording of the run (.rrd): the moving mechanism, "
        "forces, every signal.", show_default=False),
    Opt("magnify", ("--magnify",), "float", "Clearance magnification in the rerun drawing.", default=10.0, low=0.0),
    Opt("fps", ("--fps",), "float", "rerun frames per simulated second.",
        show_default="90 per revolution of the driven body"),
    Opt("view_", ("--open",), "flag", "Open the rerun viewer on the --rerun recording (as `mbs view --open`).",
        default=False),
    Opt("view_old", ("--view",), "flag", "The old name of --open.", default=False, hidden=True, into="view_"),
    Opt("rerun_signals", ("--rerun-signals",), "str", "envelope: per frame the first, smallest and largest "
        "sample of each signal (peaks kept); full: every output sample.", default="envelope"),
    Opt("force", ("--force",), "flag", "Run even when the estimated output is beyond 10^8 rows or larger than the "
        "free disk space (the run then stops cleanly if the disk fills); replace a --rerun file that is not a "
        "recording of these results.", default=False),
    Opt("until_settled", ("--until-settled",), "flag", "Run revolution by revolution until the Poincaré points "
        "have settled on a periodic orbit (checked every 50 revolutions), at most --max-revolutions; see "
        "docs/sweeps.md.", default=False),
    Opt("max_revolutions", ("--max-revolutions",), "int", "Upper bound of --until-settled.", default=2000, low=1),
    Opt("keep", ("--keep",), "str", "Comma-separated signals to store (slider.vx); an entity name (slider) keeps "
        "all its signals.  Fewer signals make smaller files and cheaper output rows (no accelerations computed "
        "unless kept).", show_default="all"),
    Opt("from_static", ("--from-static",), "flag", "Start from the static equilibrium (`mbs static`) instead of "
        "the assembled pose: at rest, every clearance joint where its load puts it; the drivers then move.",
        default=False),
    Opt("allow_unphysical", ("--allow-unphysical",), "flag", "Keep results that are not physical (a journal "
        "sunk deeper than its clearance: a contact too soft for it) as a finished run, exit 0, instead of exit 3; "
        "the warning stays and the file records allow_unphysical (the ideal-limit study of docs/contact.md).",
        default=False),
    Opt("resume", ("--resume",), "flag", "Continue the wear run in the output file (-o, or the default name) from "
        "its last update, to --updates or the model's total; the model must be the one it was made from "
        "(docs/wear.md).", default=False),
    Opt("updates", ("--updates",), "int", "Profile updates of a wear run in all (a model whose joint declares "
        "`wear`), counted from its start.", low=1, show_default="the model's `wear = archard(..., updates = N)`"),
    Opt("overwrite", ("--overwrite",), "flag", "Replace the output even when it is not the results of a run (a "
        "sweep file, any other file); never the model or its includes.", default=False),
)


def merged(kwargs: dict) -> dict:
    """`run_model`'s keyword arguments from the options read: an old name's value joins its new one's
    (``--view`` is ``--open``)."""
    kwargs = dict(kwargs)
    for opt in RUN_OPTIONS:
        if opt.into is not None and opt.param in kwargs:
            old = kwargs.pop(opt.param)
            kwargs[opt.into] = kwargs.get(opt.into, False) or old
    return kwargs


_FLOAT = re.compile(r"[0-9]+(\.[0-9]*)?([eE][+-]?[0-9]+)?|\.[0-9]+([eE][+-]?[0-9]+)?")
_INT = re.compile(r"[0-9]+")
_BY_FLAG = {flag: opt for opt in RUN_OPTIONS for flag in opt.flags}


def plain_run(argv: list[str]) -> dict | None:
    """`run_model`'s keyword arguments if argv is ``run MODEL`` with options of `mbs run` that typer
    would read to the same values, else None (typer then reads it, and words any mistake).

    Read here: ``--opt VALUE``, ``--opt=VALUE``, ``-o VALUE`` (not ``-oVALUE`` or ``-qo``), each
    option at most once except ``--set``/``-s``; numbers as plain decimals within the option's range;
    values that do not start with ``-``; one model path."""
    if not argv or argv[0] != "run":
        return None
    kwargs: dict = {}
    model, i = None, 1
    while i < len(argv):
        token, i = argv[i], i + 1
        if not token.startswith("-"):
            if model is not None:
                return None
            model = token
            continue
        name, eq, value = token.partition("=") if token.startswith("--") else (token, "", "")
        opt = _BY_FLAG.get(name)
        if opt is None or (opt.param in kwargs and opt.kind != "list"):
            return None
        if opt.kind == "flag":
            if eq:
                return None
            kwargs[opt.param] = True
            continue
        if not eq:
            if i >= len(argv):
                return None
            value, i = argv[i], i + 1
        read = _value(opt, value)
        if read is None:
            return None
        kwargs[opt.param] = kwargs.get(opt.param, []) + [read] if opt.kind == "list" else read
    return merged(dict(model=Path(model), **kwargs)) if model else None


def _value(opt: Opt, text: str):
    """The value of `opt` written as `text`, when typer would read it the same (None: leave it to typer)."""
    if not text or text.startswith("-"):
        return None
    if opt.kind == "path":
        return Path(text)
    if opt.kind in ("str", "list"):
        return text
    if not (_INT if opt.kind == "int" else _FLOAT).fullmatch(text):
        return None
    number = int(text) if opt.kind == "int" else float(text)
    if (opt.low is not None and number < opt.low) or (opt.kind == "float" and not math.isfinite(number)):
        return None
    return number
