"""The `mbs` command line: thin typer commands over library functions.

Exit codes (one table, also in README and `mbs --help`):

====  ==========================================================
0     success
2     bad model file, bad `--set` value or bad command-line usage
3     the simulation failed (results up to the failure are kept)
130   interrupted by Ctrl-C (143: by SIGTERM); results so far kept
====  ==========================================================
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Annotated, Optional

import typer

from planar_mbs import catalog

from .common import (MAX_REVOLUTIONS, ExitCode, check_choice, check_number, check_output, check_rtol, parse_sets,
                     positive_time)
from .common import console as _console
from .common import fail as _fail

_INTEGRATOR_HELP = "; ".join(f"{s.name}: {s.summary}" for s in catalog.INTEGRATORS) + "."
EPILOG = ("Exit codes: 0 success · 2 bad model or usage · 3 the simulation failed (results kept) · "
          "130/143 interrupted by Ctrl-C/SIGTERM (results kept).")


app = typer.Typer(
    name="mbs",
    help=(
        "planar_mbs: planar multibody dynamics with revolute clearance joints.\n\n"
        "Describe a mechanism in a .mbs file, check it, run it and keep the results in HDF5:\n\n"
        "  mbs check models/slider_crank_clearance_a.mbs\n\n"
        "  mbs run models/slider_crank_clearance_a.mbs -o a.h5 --set speed=2500rpm"
    ),
    epilog=EPILOG,
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode="rich",
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        from planar_mbs import __version__

        print(f"mbs (planar_mbs) {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[bool, typer.Option("--version", help="Print the version and exit.", callback=_version,
                                          is_eager=True)] = False,
) -> None:
    """planar_mbs: planar multibody dynamics with revolute clearance joints."""


ModelArg = Annotated[Path, typer.Argument(help="The .mbs model file.", show_default=False)]
SetOpt = Annotated[
    Optional[list[str]],
    typer.Option("--set", "-s", help="Override a `param` of the model: NAME=VALUE with units, e.g. speed=2500rpm, "
                 "\"clearance=0.1 mm\", law=hertz. Repeatable.", show_default=False),
]


_CHECK_HELP = (
    "Compile a model and print its bodies, coordinates, constraints, degrees of freedom and clearance "
    "joints (or its errors, with file:line:col).\n\n"
    f"Joint types: {', '.join(catalog.names(catalog.JOINTS) + [catalog.CLEARANCE_JOINT])}.\n\n"
    f"Contact laws: {', '.join(catalog.names(catalog.LAWS))}.\n\n"
    f"Integrators: {', '.join(catalog.names(catalog.INTEGRATORS))}.")


@app.command(help=_CHECK_HELP)
def check(model: ModelArg, set_: SetOpt = None) -> None:
    """Compile a model and print it (help text: _CHECK_HELP, from the catalog)."""
    from .check_command import check_model

    code = check_model(model, set_ or [])
    if code:
        raise typer.Exit(code)


@app.command()
def run(
    model: ModelArg,
    output: Annotated[Optional[Path], typer.Option(
        "--output", "-o", help="HDF5 results file.",
        show_default="results/<model name>.h5, with the --set values in the name")] = None,
    set_: SetOpt = None,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="End time, with units (\"0.06 s\", 60ms).",
                     show_default="the model's simulate block")] = None,
    revolutions: Annotated[Optional[float], typer.Option(
        "--revolutions", "-n", help="End time as a number of periods of the crank's driver (instead of --t-end).",
        show_default=False)] = None,
    output_step: Annotated[Optional[str], typer.Option(
        "--output-step", help="Time between stored samples, with units (100us); a coarser step keeps files small.",
        show_default="the model's simulate block")] = None,
    per_rev: Annotated[Optional[int], typer.Option(
        "--per-rev", help="Stored samples per period of the crank's driver (instead of --output-step).", min=1,
        show_default=False)] = None,
    integrator: Annotated[Optional[str], typer.Option(help=_INTEGRATOR_HELP,
                          show_default="the model's simulate block, else dopri5")] = None,
    rtol: Annotated[Optional[float], typer.Option(help="Relative tolerance of the adaptive integrator "
                    "(floor: 10 x machine epsilon, 2.2e-15).",
                    show_default="the model's simulate block, else 1e-6")] = None,
    atol: Annotated[Optional[float], typer.Option(help="Absolute tolerance of the adaptive integrator (> 0; "
                    "SI units of each coordinate, e.g. 1e-3 x rtol).",
                    show_default="the model's simulate block, else 1e-9")] = None,
    step: Annotated[Optional[str], typer.Option(help="Fixed step of rk4 (first trial step of dopri5), with units "
                    "(1us).", show_default="the model's simulate block, else 1us")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
    rerun: Annotated[Optional[Path], typer.Option("--rerun", help="Also write a rerun recording of the run "
                     "(.rrd): the moving mechanism, forces, every signal.", show_default=False)] = None,
    magnify: Annotated[float, typer.Option(help="Clearance magnification in the rerun drawing.", min=0.0)] = 10.0,
    fps: Annotated[Optional[float], typer.Option(help="rerun frames per simulated second.",
                   show_default="90 per revolution of the driven body")] = None,
    view_: Annotated[bool, typer.Option("--view", help="Open the rerun viewer on the recording.")] = False,
    rerun_signals: Annotated[str, typer.Option("--rerun-signals", help="envelope: per frame the first, smallest "
                             "and largest sample of each signal (peaks kept); full: every output sample.")]
    = "envelope",
    force: Annotated[bool, typer.Option("--force", help="Run even when the estimated output is beyond 10^8 rows "
                     "or larger than the free disk space (the run then stops cleanly if the disk fills).")] = False,
    until_settled: Annotated[bool, typer.Option("--until-settled", help="Run revolution by revolution until the "
                             "Poincaré points have settled on a periodic orbit (checked every 50 revolutions), at "
                             "most --max-revolutions; see docs/sweeps.md.")] = False,
    max_revolutions: Annotated[int, typer.Option("--max-revolutions", help="Upper bound of --until-settled.",
                               min=1)] = 2000,
) -> None:
    """Simulate a model and write its signals to an HDF5 file; print a summary.

    Example: mbs run models/slider_crank_clearance_a.mbs --revolutions 60 --per-rev 720 --set speed=2500rpm
    """
    from planar_mbs import simulate
    from planar_mbs.compile import load_model
    from planar_mbs.errors import MbsError, ModelError, SimulationError
    from planar_mbs.simulation import integrator_of

    sets = {}
    out = output
    try:
        sets = parse_sets(set_ or [])
        out = output or default_output(model, sets)
        m = load_model(model, sets)
        changes = dict(
            t_end=positive_time(t_end, "--t-end"),
            step=positive_time(step, "--step"),
            output_step=positive_time(output_step, "--output-step"),
            rtol=check_rtol(rtol),
            atol=atol,
            integrator=integrator,
        )
        if t_end is not None and revolutions is not None:
            raise ModelError("give --t-end or --revolutions, not both", "--revolutions", hint="drop one of them")
        if output_step is not None and per_rev is not None:
            raise ModelError("give --output-step or --per-rev, not both", "--per-rev", hint="drop one of them")
        if (revolutions is not None or per_rev is not None) and _driver_period(m) is None:
            raise ModelError(f"{'--revolutions' if revolutions is not None else '--per-rev'} needs a rotation "
                             "driver at constant speed", str(model), hint="give --t-end / --output-step instead")
        check_number(revolutions, "--revolutions", low=0.0, high=MAX_REVOLUTIONS, hint="e.g. `--revolutions 60`")
        changes.update(revolutions=revolutions, per_rev=per_rev)
        if integrator is not None:
            integrator_of(integrator, "--integrator")
        rerun_signals = check_choice(rerun_signals, ("envelope", "full"), "--rerun-signals")
        check_number(magnify, "--magnify", low=0.0, low_ok=True, hint="e.g. `--magnify 10`")
        check_number(fps, "--fps", low=0.0, hint="frames per simulated second, e.g. `--fps 600`")
        inputs = [("the model file" if i == 0 else "a file the model includes", f)
                  for i, f in enumerate(m.source_files or [model])]
        make_folder = output is None and not out.parent.exists()  # results/, made once every check passed
        if not make_folder:
            check_output(out, "--output", inputs)
        if rerun is not None:
            check_output(rerun, "--rerun", inputs, [("the results file (--output)", out)])
        if not until_settled:
            _check_output_size(m, changes, out, model, force)
        if make_folder:
            out.parent.mkdir(parents=True)
            (out.parent / ".gitignore").write_text("# made by `mbs run`: outputs are not sources\n*\n")
            check_output(out, "--output", inputs)
        if until_settled:
            res = _run_until_settled(m, out, max_revolutions, quiet, changes)
        else:
            with _Progress(quiet) as progress:
                res = simulate(m, output=out, progress=progress.update, max_rows=math.inf, **changes)
    except SimulationError as err:
        if err.results is not None:
            _print_summary(err.results, out)
            if rerun is not None:
                record_run(err.results, m, rerun, magnify=magnify, fps=fps, open_viewer=view_,
                           signals=rerun_signals)
        _console(stderr=True).print(f"simulation failed: {err.message}\n"
                                    f"results up to t = {err.time:.6g} s kept in {out} (marked incomplete)",
                                    markup=False)
        raise typer.Exit(ExitCode.SIMULATION_FAILED)
    except MbsError as err:
        _fail(err)
    except KeyboardInterrupt as err:  # simulation.RunInterrupted: SIGINT or SIGTERM
        kept = getattr(err, "results", None)
        if kept is not None:
            _print_summary(kept, out)
        _console(stderr=True).print(f"interrupted; results so far kept in {out} (marked incomplete)")
        _exit_now(128 + getattr(err, "signum", ExitCode.INTERRUPTED - 128))
    _print_summary(res, out)
    if rerun is not None:
        record_run(res, m, rerun, magnify=magnify, fps=fps, open_viewer=view_, signals=rerun_signals)


def _driver_period(m):
    from planar_mbs.analysis import driver_period

    return driver_period(m)


def default_output(model: Path, sets: dict[str, str]) -> Path:
    """results/<model name>.h5, with the --set values in the name (results/a_speed=2500rpm.h5), so a
    run with other values never replaces the previous one; results/ is ignored by git."""
    import re

    tag = "".join(f"_{name}={re.sub(r'[^A-Za-z0-9.+-]', '', value)}" for name, value in sets.items())
    return Path("results") / f"{model.stem}{tag}.h5"
def _check_output_size(m, changes: dict, out: Path, model: Path, force: bool) -> None:
    """Refuse (exit 2) before running what asks for too many rows or more disk than is free."""
    from planar_mbs.output_size import check_output, estimate
    from planar_mbs.simulation import run_settings

    check_output(estimate(m, run_settings(m, **changes)), out, str(model), force=force)


def _run_until_settled(m, out: Path, max_revolutions: int, quiet: bool, changes: dict):
    """`planar_mbs.study.long_run` until the section settles; the results written to ``out``."""
    from planar_mbs.model import ST_CONTACT_EVENTS, ST_REJECTED, ST_RHS, ST_STEPS
    from planar_mbs.results import write_results
    from planar_mbs.study import long_run

    changes = {k: v for k, v in changes.items() if k != "t_end" and v is not None}
    with _Progress(quiet, "revolution", "revolution {task.fields[t]:.0f}") as progress:
        run = long_run(m, max_revolutions, PER_REV_UNTIL_SETTLED, until_settled=True,
                       progress=lambda done, total: progress.update(done, total), **changes)
    res = run.results
    stats = run.stepper.stats
    res.attrs.update(t_reached=float(res.time[-1]), revolutions=run.revolutions, wall_time=run.wall_time,
                     settled_at=run.settled_at if run.settled_at is not None else -1,
                     n_steps=int(stats[ST_STEPS]), n_rejected=int(stats[ST_REJECTED]), n_rhs=int(stats[ST_RHS]),
                     n_contact_events=int(stats[ST_CONTACT_EVENTS]))
    out.unlink(missing_ok=True)
    write_results(str(out), res)
    text = (f"settled on a periodic orbit at revolution {run.settled_at}" if run.settled_at is not None
            else f"not settled on a periodic orbit after {run.revolutions} revolutions")
    _console().print(f"{text}; {run.revolutions} revolutions run", markup=False)
    return res


PER_REV_UNTIL_SETTLED = 90  # output samples per revolution of a run --until-settled


def _exit_now(code: int) -> None:
    """Leave at once after an interrupt (the results file is already closed): skip the
    interpreter's teardown, which takes about 2 s once the compiled kernels are loaded
    (native code, no Python frame), so that Ctrl-C/SIGTERM end a run within a second.
    Inside a test runner (no real stdout) it raises typer.Exit as usual."""
    import os
    import sys

    try:
        sys.stdout.fileno()
        sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):
        raise typer.Exit(code) from None
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def _print_summary(res, out: Path) -> None:
    from planar_mbs.results import peak, row_count

    from .check_command import print_assembly

    a = res.attrs
    worst = peak(res, "system.position_error") if "system.position_error" in res.signals else float("nan")
    con = _console()
    state = "finished" if a.get("complete") else f"stopped ({a.get('status', '?')})"
    con.print(f"[bold]{state}[/] at t = {a.get('t_reached', float('nan')):.6g} s → {out}")
    con.print(
        f"  steps {a.get('n_steps', 0):,}   rejected {a.get('n_rejected', 0):,}   "
        f"rhs evaluations {a.get('n_rhs', 0):,}   contact events {a.get('n_contact_events', 0):,}"
    )
    con.print(f"  time-loop wall time {a.get('wall_time', 0.0):.3f} s   "
              f"largest constraint error {worst:.3g}   outputs {row_count(res):,}")
    print_assembly(list(a.get("assembly_changes", [])))
    for warning in a.get("warnings") or []:
        _console(stderr=True).print(f"warning: {warning}", markup=False, style="yellow")


class _Progress:
    """A rich progress bar that appears only once a run has taken about a second."""

    DELAY = 1.0

    def __init__(self, quiet: bool, what: str = "simulating", field: str = "t = {task.fields[t]:.4g} s"):
        self.quiet, self.what, self.field = quiet, what, field
        self.start = time.perf_counter()
        self.bar = None
        self.task = None

    def __enter__(self):
        return self

    def update(self, t: float, t_end: float) -> None:
        if self.quiet:
            return
        if self.bar is None:
            if time.perf_counter() - self.start < self.DELAY:
                return
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

            self.bar = Progress(
                TextColumn(self.what), BarColumn(), TextColumn(self.field),
                TimeElapsedColumn(), TimeRemainingColumn(), console=_console(stderr=True), transient=True,
            )
            self.bar.start()
            self.task = self.bar.add_task("run", total=t_end, t=t)
        self.bar.update(self.task, completed=t, t=t)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.stop()
        return False


from .plot_commands import plot, record_run, view  # noqa: E402  (light: imports only typer)
from .sweep_commands import analyze, sweep  # noqa: E402  (light: imports only typer)

app.command()(plot)
app.command()(view)
app.command()(sweep)
app.command()(analyze)


def main() -> None:
    """The `mbs` entry point.  Every expected failure is reported by the commands themselves;
    anything else (a bug) still ends with one message instead of a traceback, unless
    MBS_TRACEBACK=1 asks for it."""
    import os
    import sys

    try:
        app()
    except Exception as exc:  # noqa: BLE001  (the last line of defence: never a traceback)
        if os.environ.get("MBS_TRACEBACK"):
            raise
        _console(stderr=True).print(f"internal error: {type(exc).__name__}: {exc}\n"
                                    "hint: this is a bug in planar_mbs; please report it with the command "
                                    "(MBS_TRACEBACK=1 shows where it happened)", markup=False)
        sys.exit(1)
