"""`mbs run`: the options checked, the run made by the library, its summary printed.

`run_model` is the command; it returns the exit code and imports neither typer nor the kernels
until it needs them.  Its options are read by the typer command `app.run` or, for a plain command
line, by `run_options.plain_run` (both from the one table `run_options.RUN_OPTIONS`).  The work is
the library's: `run.simulation.simulate`, `run.study.run_until_settled`, the size of the outputs
(`run.output_size`), their names (`run.output_names`), the recording (`outputs.rerun_log`); this
module checks the options, calls them in order and prints.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import errno
import math
import os
import sys
import time
from pathlib import Path
from types import SimpleNamespace

from planar_mbs.errors import MbsError, ModelError, SimulationError
from planar_mbs.lazy import lazy
from planar_mbs.run.first_compile import announce_if_cold

from .common import (
    MAX_REVOLUTIONS,
    ExitCode,
    check_choice,
    check_number,
    check_output,
    fail_code,
    parse_sets,
    positive_time,
)
from .common import console as _console
from .common import internal_error, print_assembly, print_model_warnings, say

# Loaded once `announce_if_cold` has said that the solver compiles (lark, numpy, h5py come with the
# model), or only by the option that needs them (rerun, typer, the sweep's scan, rich's progress bar).
compiler = lazy("planar_mbs.mechanism.compile")
hdf5 = lazy("planar_mbs.results.hdf5")
analysis = lazy("planar_mbs.results.analysis")
output_names = lazy("planar_mbs.run.output_names")
output_size = lazy("planar_mbs.run.output_size")
settings_check = lazy("planar_mbs.run.settings_check")
simulation = lazy("planar_mbs.run.simulation")
study = lazy("planar_mbs.run.study")
scan = lazy("planar_mbs.sweep.scan")
rerun_log = lazy("planar_mbs.outputs.rerun_log")
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from . import plot_commands
    from . import static_command
    from . import wear_command
else:  # each loaded on its first use (see the comments: not on the light paths)
    plot_commands = lazy(".plot_commands", __package__)
    wear_command = lazy(".wear_command", __package__)  # a model whose joint wears
    static_command = lazy(".static_command", __package__)  # the kernels: only with --from-static
rich_progress = lazy("rich.progress")
rich_utils = lazy("typer.rich_utils")


def run_model(model: Path, output: Path | None = None, set_: list[str] | None = None, t_end: str | None = None,
              revolutions: float | None = None, output_step: str | None = None, per_rev: int | None = None,
              integrator: str | None = None, rtol: float | None = None, atol: float | None = None,
              step: str | None = None, quiet: bool = False, rerun: Path | None = None, magnify: float = 10.0,
              fps: float | None = None, view_: bool = False, rerun_signals: str = "envelope", force: bool = False,
              until_settled: bool = False, max_revolutions: int = 2000, keep: str | None = None,
              from_static: bool = False, overwrite: bool = False, allow_unphysical: bool = False,
              resume: bool = False, updates: int | None = None) -> int:
    """Simulate `model` with the options of `mbs run` (parameters named as in `run_options.RUN_OPTIONS`);
    the exit code."""
    o = SimpleNamespace(**locals(), out=output, m=None)  # the options, and what `_prepare` adds to them
    announce_if_cold()  # a first run says at once that it compiles the solver (before reading the model)
    try:
        _prepare(o)
        if o.wears:
            return wear_command.run_wear(o, _exit_now)
        res = _execute(o)
    except SimulationError as err:
        return _failed(o, err)
    except MbsError as err:
        return fail_code(err)
    except KeyboardInterrupt as err:  # simulation.RunInterrupted: SIGINT or SIGTERM
        kept = getattr(err, "results", None)
        if kept is not None:
            _print_summary(kept, o.out)
        _console(stderr=True).print(f"interrupted; results so far kept in {o.out} (marked incomplete)")
        return _exit_now(128 + getattr(err, "signum", ExitCode.INTERRUPTED - 128))
    _print_summary(res, o.out)
    return _record(o, res)


def _prepare(o: SimpleNamespace) -> None:
    """Every check before the run, in the order a user meets them: the options, the model, its
    settings, the outputs (names, places, size); sets ``o.m``, ``o.out``, ``o.changes``, ``o.signals``."""
    _needs_rerun(o.view_, o.rerun)
    sets = parse_sets(o.set_ or [])
    o.out = o.output or output_names.default_output(o.model, sets)
    o.m = m = compiler.load_model(o.model, sets)
    print_model_warnings(m)
    o.wears = bool(m.clearance_wear)  # a joint that wears: a wear run (`wear_command`)
    wear_command.refuse_options(o) if o.wears else wear_command.refuse_without_wear(o)
    if o.from_static:
        o.m = m = static_command.start_at_rest(m)
    o.changes = _changes(o, m)
    if o.wears:
        _check_settings(m, o.changes, o.model, False)
        return wear_command.check_files(o, _inputs(o, m))
    o.signals = _kept(m, o.keep, o.rerun, o.until_settled)
    o.rerun_signals = check_choice(o.rerun_signals, ("envelope", "full"), "--rerun-signals")
    check_number(o.magnify, "--magnify", low=0.0, low_ok=True, hint="e.g. `--magnify 10`")
    check_number(o.fps, "--fps", low=0.0, hint="frames per simulated second, e.g. `--fps 600`")
    inputs = _inputs(o, m)
    _check_settings(m, o.changes, o.model, o.until_settled)
    if o.output is None:
        o.out = _beside_another_run(o, m)
    make_folder = o.output is None and not o.out.parent.exists()  # results/, made once every check passed
    if not make_folder:
        check_output(o.out, "--output", inputs)
    if o.rerun is not None:
        _check_rerun(o.rerun, o.out, inputs, o.force)
    if not make_folder:
        hdf5.refuse_replacing(o.out, overwrite=o.overwrite, inputs=m.source_files)
    if not o.until_settled:  # too many rows or more disk than is free: refused before running
        output_size.check_output(output_size.estimate(m, simulation.run_settings(m, **o.changes)), o.out, str(o.model), force=o.force)
    if make_folder:
        output_names.make_results_folder(o.out.parent)
        check_output(o.out, "--output", inputs)


def _inputs(o: SimpleNamespace, m) -> list:
    """(what, path) of the model file and its includes: files no output may replace."""
    return [("the model file" if i == 0 else "a file the model includes", f)
            for i, f in enumerate(m.source_files or [o.model])]


def _changes(o: SimpleNamespace, m) -> dict:
    """The settings the options change (`simulate`'s keywords), each checked on its own and against the
    others (an end time or revolutions, not both)."""
    changes = dict(
        t_end=positive_time(o.t_end, "--t-end"),
        step=positive_time(o.step, "--step"),
        output_step=positive_time(o.output_step, "--output-step"),
        rtol=o.rtol,  # checked with the other settings (`_check_settings`), as `simulate` checks it
        atol=o.atol,
        integrator=o.integrator,
    )
    if o.t_end is not None and o.revolutions is not None:
        raise ModelError("give --t-end or --revolutions, not both", "--revolutions", hint="drop one of them")
    if o.output_step is not None and o.per_rev is not None:
        raise ModelError("give --output-step or --per-rev, not both", "--per-rev", hint="drop one of them")
    if (o.revolutions is not None or o.per_rev is not None) and analysis.driver_period(m) is None:
        raise ModelError(f"{'--revolutions' if o.revolutions is not None else '--per-rev'} needs a rotation "
                         "driver at constant speed", str(o.model), hint="give --t-end / --output-step instead")
    check_number(o.revolutions, "--revolutions", low=0.0, high=MAX_REVOLUTIONS, hint="e.g. `--revolutions 60`")
    changes.update(revolutions=o.revolutions, per_rev=o.per_rev)
    if o.integrator is not None:
        simulation.integrator_of(o.integrator, "--integrator")
    return changes


def _execute(o: SimpleNamespace):
    """The run itself, with a progress bar: `simulate`, or `run_until_settled` and its verdict printed."""
    if o.until_settled:
        return _run_until_settled(o)
    with _Progress(o.quiet) as progress:
        return simulation.simulate(o.m, output=o.out, progress=progress.update, max_rows=math.inf, signals=o.signals,
                        overwrite=o.overwrite, allow_unphysical=o.allow_unphysical, **o.changes)


def _failed(o: SimpleNamespace, err) -> int:
    """A failed run: the summary and the recording of what was computed, and why it failed (exit 3)."""
    if err.results is not None:
        _print_summary(err.results, o.out)
        _record(o, err.results)  # a recording that could not be written is said, then the failure
    if err.results is not None and err.results.attrs.get("status") == "not_physical":
        _console(stderr=True).print(f"error: {err.message}\nthe results to t = {err.time:.6g} s are kept in "
                                    f"{o.out}, marked incomplete (status not_physical); --allow-unphysical "
                                    "keeps such results as finished", markup=False)
    elif err.results is not None:
        _console(stderr=True).print(f"simulation failed: {err.message}\n"
                                    f"results up to t = {err.time:.6g} s kept in {o.out} (marked incomplete)",
                                    markup=False)
    else:  # failed before anything was written (`--until-settled` writes its file at the end)
        _console(stderr=True).print(f"simulation failed: {err.message}\nno results were written", markup=False)
    return int(ExitCode.SIMULATION_FAILED)


def _record(o: SimpleNamespace, res) -> int:
    """The --rerun recording of `res` (`outputs.rerun_log`), if asked for: 0, or the exit code of a
    recording that could not be written (the results are written; the recording is not)."""
    if o.rerun is None:
        return 0
    try:
        record_run(res, o.m, o.rerun, magnify=o.magnify, fps=o.fps, open_viewer=o.view_, signals=o.rerun_signals,
                   recording_id=_recording_key(o.out))
    except (MbsError, OSError) as err:
        return fail_code(err if isinstance(err, MbsError) else f"error: {err}")
    return 0


def _kept(model, keep: str | None, rerun: Path | None, until_settled: bool) -> list[str] | None:
    """The signal names of ``--keep`` (None: every signal), checked against the model before the run:
    full names (``slider.vx``) or entities (``slider``), as `mbs sweep --keep` reads them."""
    if keep is None:
        return None
    names = [k.strip() for k in keep.split(",") if k.strip()]
    if not names:
        raise ModelError("--keep names no signal", "--keep", hint="e.g. `--keep slider.x,slider.vx` or `--keep slider`")
    for other, flag in ((rerun is not None, "--rerun"), (until_settled, "--until-settled")):
        if other:
            raise ModelError(f"give --keep or {flag}, not both", "--keep",
                             hint=f"{flag} needs every signal (the mechanism's motion, the Poincaré section)")
    scan.kept_signals(model, names)
    return names


def record_run(*args, **kwargs):
    """`plot_commands.record_run` (typer and rerun load only when a recording is asked for)."""
    return plot_commands.record_run(*args, **kwargs)


def _needs_rerun(view_: bool, rerun: Path | None) -> None:
    """--open without --rerun cannot act: refused (exit 2) rather than ignored."""
    if view_ and rerun is None:
        raise ModelError("--open opens the viewer on the run's rerun recording, and no --rerun is given",
                         "--open", hint="add `--rerun FILE.rrd`, or later `mbs view RESULTS.h5 --open`")


def _check_rerun(rerun: Path, out: Path, inputs: list, force: bool) -> None:
    """The --rerun file: a writable place (missing folders are made) that holds no recording of other
    results, unless --force (`rerun_log.check_replace`)."""
    check_output(rerun, "--rerun", inputs, [("the results file (--output)", out)], make_parents=True)
    rerun_log.check_replace(rerun, rerun_log.recording_key(out), force, "--rerun")


def _recording_key(out: Path) -> str:
    return rerun_log.recording_key(out)


def _beside_another_run(o: SimpleNamespace, m) -> Path:
    """`run.output_names.beside_another_run` with the options given, said on stdout when it moves."""
    given = {"n": o.revolutions, "t-end": o.t_end, "per-rev": o.per_rev, "output-step": o.output_step,
             "integrator": o.integrator, "rtol": o.rtol, "atol": o.atol, "step": o.step}
    beside = output_names.beside_another_run(o.out, m, o.changes, given)
    if beside != o.out:
        _console().print(f"{o.out} holds a run with other settings: this one goes to {beside}", markup=False)
    return beside


def _check_settings(m, changes: dict, model: Path, until_settled: bool) -> None:
    """The run's settings through the validation `simulate` applies (`planar_mbs.run.settings_check`),
    worded for the command line."""
    given = {k: v for k, v in changes.items() if not (until_settled and k == "t_end")}
    settings = simulation.run_settings(m, **given)
    settings_check.check_settings(settings, given=settings_check.given_settings(given), style=settings_check.CLI,
                                  source=str(model))


def _run_until_settled(o: SimpleNamespace):
    """`run.study.run_until_settled` (the results written to ``o.out``), and its verdict printed as
    `mbs analyze` prints it."""
    changes = {k: v for k, v in o.changes.items() if k != "t_end" and v is not None}
    with _Progress(o.quiet, "revolution", "revolution {task.fields[t]:.0f}") as progress:
        run = study.run_until_settled(o.m, o.out, o.max_revolutions, lambda done, total: progress.update(done, total),
                                overwrite=o.overwrite, allow_unphysical=o.allow_unphysical, **changes)
    stop = ("stopped: the section settled on a periodic orbit" if run.settled_at is not None
            else "no periodic orbit found (--max-revolutions)")
    _console().print(f"{run.revolutions} revolutions run; {stop}", markup=False)
    for line in analysis.report(*analysis.analyze(run.results)):  # the verdict as `mbs analyze` gives it on the file
        _console().print(line, markup=False)
    return run.results


def _exit_now(code: int) -> int:
    """Leave at once after an interrupt (the results file is already closed): skip the
    interpreter's teardown, which takes about 2 s once the compiled kernels are loaded
    (native code, no Python frame), so that Ctrl-C/SIGTERM end a run within a second.
    Inside a test runner (no real stdout) it returns the code, to exit as usual."""
    try:
        sys.stdout.fileno()
        sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):
        return code
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def _print_summary(res, out: Path) -> None:
    a = res.attrs
    worst = (f"{hdf5.peak(res, 'system.position_error'):.3g}" if "system.position_error" in res.signals
             else "not kept (--keep)")
    state = "finished" if a.get("complete") else f"stopped ({a.get('status', '?')})"
    say(f"{state} at t = {a.get('t_reached', float('nan')):.6g} s → {out}", style="bold")
    say(f"  steps {a.get('n_steps', 0):,}   rejected {a.get('n_rejected', 0):,}   "
        f"rhs evaluations {a.get('n_rhs', 0):,}   contact events {a.get('n_contact_events', 0):,}")
    say(f"  time-loop wall time {a.get('wall_time', 0.0):.3f} s   "
        f"largest constraint error {worst}   outputs {hdf5.row_count(res):,}")
    print_assembly(list(a.get("assembly_changes", [])))
    for warning in a.get("warnings") or []:
        say(f"warning: {warning}", stderr=True, style="yellow")


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
            bars = rich_progress
            self.bar = bars.Progress(
                bars.TextColumn(self.what), bars.BarColumn(), bars.TextColumn(self.field),
                bars.TimeElapsedColumn(), bars.TimeRemainingColumn(), console=_console(stderr=True), transient=True,
            )
            self.bar.start()
            self.task = self.bar.add_task("run", total=t_end, t=t)
        self.bar.update(self.task, completed=t, t=t)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.stop()
        return False


class _PacifyFlush:
    """stdout/stderr after a broken pipe: flushing them again stays quiet (as typer does)."""

    def __init__(self, wrapped):
        self.wrapped = wrapped

    def flush(self) -> None:
        try:
            self.wrapped.flush()
        except OSError as exc:
            if exc.errno != errno.EPIPE:
                raise

    def __getattr__(self, attr):
        return getattr(self.wrapped, attr)


def run_plain(kwargs: dict) -> int:
    """`run_model(**kwargs)` ended as the typer command ends: Ctrl-C before the time loop exits
    130, a closed output pipe 1, an unexpected error one message (`common.internal_error`)."""
    try:
        try:
            return run_model(**kwargs)
        except KeyboardInterrupt:
            return int(ExitCode.INTERRUPTED)
        except EOFError:
            print(file=sys.stderr)
            rich_utils.rich_abort_error()
            return 1
        except OSError as exc:
            if exc.errno != errno.EPIPE:
                raise
            sys.stdout, sys.stderr = _PacifyFlush(sys.stdout), _PacifyFlush(sys.stderr)
            return 1
    except Exception as exc:  # noqa: BLE001  (as app.main: never a traceback)
        return internal_error(exc)
