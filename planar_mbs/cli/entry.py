"""The `mbs` executable.

A plain ``mbs check MODEL [--set NAME=VALUE]...`` runs `check_command.check_model` without loading
typer: typer's argument handling imports pydantic, which costs more than parsing, compiling and
assembling a model.  Likewise a plain ``mbs run MODEL [OPTIONS]`` that `run_options.plain_run` reads
completely runs `run_command.run_model`.  Every other command line (another command, ``--help``, an
unusual spelling of an option, a mistake) goes unchanged to the typer app in `app`, which owns usage,
help and errors.  ``mbs sweep`` on several cores first starts the fork server of its workers
(`planar_mbs.sweep.server`), so that they load the kernels while typer reads the command line.

BLAS runs on one thread in this process (unless the user set it): its solves here are small dense
ones (assembly, Poincaré analysis), for which starting a thread pool per core costs more than it saves.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import os
import signal
import sys
import threading
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# after BLAS is set to one thread (above): nothing below loads numpy when imported
from planar_mbs.lazy import lazy  # noqa: E402

from .common import Stopping, guard_streams, stream_failure  # noqa: E402
from .run_options import plain_run  # noqa: E402

# loaded by the command that needs them, so that `mbs --help` and `mbs check` stay light
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from . import app
    from . import check_command
    from . import run_command
else:  # each loaded on its first use (see the comments: not on the light paths)
    app = lazy(".app", __package__)  # typer and pydantic
    check_command = lazy(".check_command", __package__)  # lark, numpy
    run_command = lazy(".run_command", __package__)  # the run's checks and printing
sweep_server = lazy("planar_mbs.sweep.server")  # multiprocessing: only `mbs sweep` on several cores


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


# Modules whose exit handlers must run (rerun flushes its recording, dask closes its client).
NEEDS_TEARDOWN = ("rerun", "distributed")


def leave(code, printed_only: bool = False) -> None:
    """Exit with `code`.  Once numba's compiled kernels are loaded the interpreter's teardown
    takes 0.5-2 s of native finalisers and writes nothing of ours (results files are closed by
    then), so the process ends at once after flushing its output.  So does a sweep whose pool came
    from `planar_mbs.sweep.server` (no numba here, yet 0.2 s of teardown; the server and its
    workers end with this process), and a command that only printed (``printed_only``: `mbs
    check`, a help text), for which the teardown of numpy's, rich's and typer's modules is
    about a tenth of the process and finishes nothing.  A process
    that loaded a module in NEEDS_TEARDOWN, or whose output is not a real file (a test runner),
    exits as usual."""
    if code is None:
        code = 0
    elif not isinstance(code, int):
        print(code, file=sys.stderr)
        code = 1
    lost = stream_failure()
    if lost and code == 0:  # the work is done and its files are whole; what it printed is not
        print(f"error: {lost}", file=sys.stderr)
        code = 1
    pool = "planar_mbs.sweep.server" in sys.modules and sys.modules["planar_mbs.sweep.server"].started()
    if not (printed_only or pool or "numba" in sys.modules) or any(m in sys.modules for m in NEEDS_TEARDOWN):
        sys.exit(code)
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        sys.stdout.fileno()
        sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):
        sys.exit(code)
    os._exit(code)


def _terminate(signum, frame) -> None:
    """SIGTERM ends a command by an exception rather than at once, so its `finally` blocks run (a
    figure or a recording being written is removed, never left half-written beside its name; files
    are closed) and it exits with 128 + the signal, 143.  `mbs run`'s time loop and `mbs sweep`
    install their own handlers while they work (results kept, a sentence saying so).  The signal is
    noted first: code that turns the exit into another error still ends with 143 (`internal_error`)."""
    Stopping.signum = signum
    raise SystemExit(128 + signum)


def _terminate_again(report) -> None:
    """sys.unraisablehook while `_terminate` is installed: Python drops an exception raised inside a
    weakref or garbage-collector callback (printing "Exception ignored"), which would let SIGTERM pass
    unnoticed.  The signal is sent again 10 ms later instead, from a thread (sent from here, its
    handler would run inside this hook and be dropped in turn), and then ends the command."""
    if isinstance(report.exc_value, SystemExit) and report.exc_value.code == 128 + signal.SIGTERM:
        again = threading.Timer(0.01, os.kill, (os.getpid(), signal.SIGTERM))
        again.daemon = True
        again.start()
    else:
        sys.__unraisablehook__(report)


def stop_cleanly_on_sigterm() -> None:
    """Install `_terminate` for SIGTERM (and `_terminate_again`), unless the user's shell ignores
    SIGTERM: then it stays ignored."""
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _terminate)
        sys.unraisablehook = _terminate_again


def _working_folder() -> None:
    """A command started in a folder that was deleted meanwhile: exit 2 with a sentence (every
    relative path, the default output among them, would fail later in its own way)."""
    try:
        os.getcwd()
    except OSError as exc:
        print(f"error: the working folder is gone ({exc.strerror}): it was deleted or is no longer reachable\n"
              "hint: cd into an existing folder and run the command again", file=sys.stderr)
        leave(2, printed_only=True)


def _numba_enabled() -> None:
    """NUMBA_DISABLE_JIT=1 (a debugging switch of numba) leaves the time loop's kernels as plain Python
    functions, which the kernels' own dispatch cannot call: exit 2 with a sentence, before any work."""
    if sys.argv[1:2] in (["run"], ["sweep"]) and os.environ.get("NUMBA_DISABLE_JIT", "0").strip() not in ("", "0"):
        print("error: NUMBA_DISABLE_JIT is set: the time loop runs only as numba-compiled code\n"
              "hint: unset NUMBA_DISABLE_JIT (`env -u NUMBA_DISABLE_JIT mbs ...`)", file=sys.stderr)
        leave(2, printed_only=True)


def main() -> None:
    guard_streams()
    _working_folder()
    _numba_enabled()
    # figures are drawn on matplotlib's Agg canvas, never in a window: a backend named in the
    # environment is not used, and an unknown one (MPLBACKEND=nonsense) would stop matplotlib's import
    os.environ.pop("MPLBACKEND", None)
    stop_cleanly_on_sigterm()
    if sys.argv[1:2] == ["sweep"]:
        if sweep_server.wanted(sys.argv[2:], os.cpu_count()):
            sweep_server.start()  # the workers' kernels load on another core while typer reads the command
    args = plain_check(sys.argv[1:])
    if args is None and sys.argv[1:2] == ["run"]:
        kwargs = plain_run(sys.argv[1:])
        if kwargs is not None:
            leave(run_command.run_plain(kwargs))
    if args is None:
        help_only = not sys.argv[1:] or "--help" in sys.argv[1:] or sys.argv[1:] == ["--version"]
        try:
            app.main()
        except SystemExit as done:
            leave(done.code, printed_only=help_only)
        leave(0, printed_only=help_only)
    leave(check_command.check_model(Path(args[0]), args[1]), printed_only=True)
