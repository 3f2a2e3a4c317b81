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
