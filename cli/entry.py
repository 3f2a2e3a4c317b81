"""The `mbs` executable.

A plain ``mbs check MODEL [--set NAME=VALUE]...`` runs `check_command.check_model` without loading
typer: typer's argument handling imports pydantic, which costs more than parsing, compiling and
assembling a model.  Every other command line (another command, ``--help``, any other option, a
mistake) goes unchanged to the typer app in `app`, which owns usage, help and errors.

BLAS runs on one thread in this process (unless the user set it): its solves here are small dense
ones (assembly, Poincaré analysis), for which starting a thread pool per core costs more than it saves.
"""
from __future__ import annotations

import os
import sys

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def plain_check(argv: list[str]):
    """(model, [NAME=VALUE, ...]) if argv is exactly ``check MODEL`` with ``--set``/``-s`` options, else None."""
    if not argv or argv[0] != "check":
        return None
    model, sets, i = None, [], 1
    while i < len(argv):
        a = argv[i]
        if a in ("--set", "-s") and i + 1 < len(argv):
            sets.append(argv[i + 1])
            i += 2
        elif a.startswith("--set="):
            sets.append(a[len("--set="):])
            i += 1
        elif a.startswith("-") or model is not None:
            return None
        else:
            model = a
            i += 1
    return (model, sets) if model else None


def main() -> None:
    args = plain_check(sys.argv[1:])
    if args is None:
        from .app import main as app_main

        return app_main()
    from pathlib import Path

    from .check_command import check_model

    sys.exit(check_model(Path(args[0]), args[1]))
