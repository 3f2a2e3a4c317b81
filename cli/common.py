"""What every `mbs` command shares: the exit codes, the console, user-facing errors,
`--set` pairs and values with units.  Imports nothing heavy (typer only in `fail`); the rest loads on use."""
from __future__ import annotations

from enum import IntEnum
from typing import Optional


class ExitCode(IntEnum):
    OK = 0
    BAD_MODEL = 2
    SIMULATION_FAILED = 3
    INTERRUPTED = 130  # 128 + SIGINT; SIGTERM gives 143


def console(stderr: bool = False):
    import sys

    from rich.console import Console

    stream = sys.stderr if stderr else sys.stdout
    width = None if stream.isatty() else 160  # no terminal (pipes, tests): do not cut names
    return Console(stderr=stderr, highlight=False, width=width)


def fail_code(err) -> int:
    """Print a user-facing error (never a traceback); return its exit code."""
    from planar_mbs.errors import MbsError

    code = err.exit_code if isinstance(err, MbsError) else ExitCode.BAD_MODEL
    console(stderr=True).print(str(err), markup=False, soft_wrap=True)  # never re-wrap: the caret must stay aligned
    return int(code)


def fail(err) -> None:
    """Print a user-facing error (never a traceback) and exit with its code."""
    import typer

    raise typer.Exit(fail_code(err))


def internal_error(exc: Exception) -> int:
    """A bug's one-line report instead of a traceback (exit code 1); MBS_TRACEBACK=1 raises it instead."""
    import os

    if os.environ.get("MBS_TRACEBACK"):
        raise exc
    console(stderr=True).print(f"internal error: {type(exc).__name__}: {exc}\n"
                               "hint: this is a bug in planar_mbs; please report it with the command "
                               "(MBS_TRACEBACK=1 shows where it happened)", markup=False)
    return 1


def parse_sets(sets: list[str]) -> dict[str, str]:
    """`--set NAME=VALUE` pairs (VALUE keeps its units, e.g. `speed=2500rpm`)."""
    from planar_mbs.errors import ModelError

    overrides = {}
    for item in sets:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise ModelError(
                f"`--set {item}` is not NAME=VALUE", "--set",
                hint="write e.g. `--set speed=2500rpm` or `--set \"clearance=0.1 mm\"`",
            )
        overrides[name.strip()] = value.strip()
    return overrides


def quantity(text: Optional[str], dimension: str, option: str) -> Optional[float]:
    if text is None:
        return None
    from planar_mbs.units import parse_quantity

    return parse_quantity(text, dimension, where=option)


# ---------------------------------------------------------------- option values, checked before anything runs
MAX_T_END = 1e6  # s of simulated time (11.6 days): beyond it a typo is far likelier than a wish
MAX_JOBS = 1024
MAX_REVOLUTIONS = 1e7  # driver periods of one run


def _option_error(option: str, message: str, hint: str):
    from planar_mbs.errors import ModelError

    return ModelError(message, option, hint=hint)


def check_number(value: Optional[float], option: str, *, low: Optional[float] = None, high: Optional[float] = None,
                 low_ok: bool = False, high_ok: bool = True, hint: str = "") -> Optional[float]:
    """`value` if it is a finite number in the interval (low, high] (``low_ok``/``high_ok``
    close or open either end); None passes.  Raises `ModelError` naming the option otherwise."""
    import math

    if value is None:
        return None
    text = f"{value:g}" if isinstance(value, float) else str(value)
    if isinstance(value, float) and not math.isfinite(value):
        raise _option_error(option, f"`{option} {text}` is not a finite number", hint)
    if low is not None and (value < low or (value == low and not low_ok)):
        raise _option_error(option, f"`{option} {text}` must be {'at least' if low_ok else 'greater than'} {low:g}",
                            hint)
    if high is not None and (value > high or (value == high and not high_ok)):
        raise _option_error(option, f"`{option} {text}` must be {'at most' if high_ok else 'less than'} {high:g}",
                            hint)
    return value


def positive_time(text: Optional[str], option: str, high: float = MAX_T_END) -> Optional[float]:
    """A time option with units (`60ms`, "0.06 s"): finite, > 0 and at most `high` seconds."""
    value = quantity(text, "time", option)
    return check_number(value, option, low=0.0, high=high,
                        hint=f"give a positive time with units, e.g. `{option} 60ms`"
                             + (f" (at most {high:g} s)" if high is not None else ""))


def check_rtol(value: Optional[float], option: str = "--rtol") -> Optional[float]:
    """A relative tolerance: 0 < rtol < 1."""
    return check_number(value, option, low=0.0, high=1.0, high_ok=False,
                        hint=f"a relative tolerance lies between 0 and 1, e.g. `{option} 1e-8`")


def check_choice(value: Optional[str], choices, option: str) -> Optional[str]:
    """`value` (lower-cased) if it is one of `choices`; else a `ModelError` with a did-you-mean."""
    if value is None:
        return None
    if value.lower() in choices:
        return value.lower()
    from planar_mbs.errors import did_you_mean

    close = did_you_mean(value, choices)
    raise _option_error(option, f"unknown {option} `{value}`",
                        (close + " " if close else "") + "choose " + ", ".join(choices))


# ---------------------------------------------------------------- files: never write over an input
def same_file(a, b) -> bool:
    """True if `a` and `b` are the same file: same inode (symlinks, hard links) or, for files
    that do not exist yet, the same path once symlinks in it are resolved."""
    import os

    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def check_output(path, option: str, inputs=(), others=(), folder: bool = False, make_parents: bool = False) -> None:
    """Refuse, before anything runs, an output that would overwrite an input (compared as files),
    that names the same file as another output, or that cannot be written: a folder (or, with
    `folder`, a file), a FIFO or device, a missing or read-only parent folder.

    ``inputs`` and ``others`` are (description, path) pairs; `make_parents`: missing folders are
    made by the command (as `results/`), so the first existing one is checked instead."""
    import os
    import stat
    from pathlib import Path

    path = Path(path)
    shown = f"{option} {path}"
    for what, other in inputs:
        if other is not None and os.path.lexists(path) and same_file(path, other):
            raise _option_error(option, f"`{shown}` is {what}: writing there would destroy it",
                                "choose another output file")
    for what, other in others:
        if other is not None and same_file(path, other):
            raise _option_error(option, f"`{shown}` is also {what}", "give each output its own file")
    try:
        info = os.stat(path)
    except FileNotFoundError:
        info = None
    except NotADirectoryError:
        raise _option_error(option, f"a part of the path `{shown}` is a file, not a folder",
                            "choose another output") from None
    except OSError as exc:
        raise _option_error(option, f"cannot use `{shown}`: {exc.strerror or exc}", "choose another output") from None
    if info is not None:
        if folder and not stat.S_ISDIR(info.st_mode):
            raise _option_error(option, f"`{shown}` exists and is not a folder", "give a folder for the figures")
        if not folder and stat.S_ISDIR(info.st_mode):
            raise _option_error(option, f"`{shown}` is a folder", f"give a file name, e.g. `{option} "
                                f"{path / 'results.h5'}`")
        if not folder and not stat.S_ISREG(info.st_mode):
            raise _option_error(option, f"`{shown}` is not a regular file", "give the name of a file to write")
        if not os.access(path, os.W_OK | (os.X_OK if folder else 0)):
            raise _option_error(option, f"`{shown}` is not writable", "choose another output, or change its mode")
        return
    parent = path.parent
    if folder or make_parents:  # folders created as needed: find the first one that exists
        while not os.path.lexists(parent) and parent != parent.parent:
            parent = parent.parent
    if not parent.exists():
        raise _option_error(option, f"the folder `{parent}` of `{shown}` does not exist",
                            f"create it first (`mkdir -p {parent}`) or choose another output")
    if not parent.is_dir():
        raise _option_error(option, f"`{parent}` in `{shown}` is not a folder", "choose another output")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise _option_error(option, f"cannot write in the folder `{parent}` of `{shown}` (read-only)",
                            "choose an output in a folder you can write")


def model_files(path) -> list:
    """The model file and every file it includes (resolved paths): the inputs an output may not
    overwrite.  Unreadable or broken models give [path] (their errors come when they load)."""
    from pathlib import Path

    from planar_mbs.errors import MbsError

    try:
        from planar_mbs.compile import MAX_MODEL_BYTES
        from planar_mbs.parse import decode_model, parse_model

        import os
        import stat

        if not stat.S_ISREG(os.stat(path).st_mode) or os.stat(path).st_size > MAX_MODEL_BYTES:
            return [Path(path)]
        spec = parse_model(decode_model(Path(path).read_bytes(), str(path)), str(path))
    except (OSError, MbsError):
        return [Path(path)]
    return [Path(path), *spec.include_files]
