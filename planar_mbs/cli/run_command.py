"""`mbs run`: simulate a model, write its results file, print a summary.

`run_model` is the command; it returns the exit code and imports neither typer nor the kernels
until it needs them.  The typer command `app.run` calls it, and so does `entry.main` for a
command line `plain_run` reads completely (only the run's own options, each once, with
plain values): typer's argument handling imports pydantic (about 0.06 s of a warm run);
every other command line (``--help``, a mistake, an unusual spelling) goes to typer unchanged.
"""
from __future__ import annotations

import math
import re
import time
from pathlib import Path

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


def run_model(model: Path, output: Path | None = None, set_: list[str] | None = None, t_end: str | None = None,
              revolutions: float | None = None, output_step: str | None = None, per_rev: int | None = None,
              integrator: str | None = None, rtol: float | None = None, atol: float | None = None,
              step: str | None = None, quiet: bool = False, rerun: Path | None = None, magnify: float = 10.0,
              fps: float | None = None, view_: bool = False, rerun_signals: str = "envelope", force: bool = False,
              until_settled: bool = False, max_revolutions: int = 2000, keep: str | None = None,
              overwrite: bool = False) -> int:
    """Simulate `model` with the options of `mbs run` (parameters named as `app.run`'s); the exit code."""
    from planar_mbs.run.first_compile import announce_if_cold

    announce_if_cold()  # a first run says at once that it compiles the solver (before reading the model)
    from planar_mbs import simulate
    from planar_mbs.mechanism.compile import load_model
    from planar_mbs.errors import MbsError, ModelError, SimulationError
    from planar_mbs.results.hdf5 import refuse_replacing
    from planar_mbs.run.simulation import integrator_of

    sets = {}
    out = output
    try:
        _needs_rerun(view_, rerun)
        sets = parse_sets(set_ or [])
        out = output or default_output(model, sets)
        m = load_model(model, sets)
        changes = dict(
            t_end=positive_time(t_end, "--t-end"),
            step=positive_time(step, "--step"),
            output_step=positive_time(output_step, "--output-step"),
            rtol=rtol,  # checked with the other settings (`_check_settings`), as `simulate` checks it
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
        signals = _kept(m, keep, rerun, until_settled)
        rerun_signals = check_choice(rerun_signals, ("envelope", "full"), "--rerun-signals")
        check_number(magnify, "--magnify", low=0.0, low_ok=True, hint="e.g. `--magnify 10`")
        check_number(fps, "--fps", low=0.0, hint="frames per simulated second, e.g. `--fps 600`")
        inputs = [("the model file" if i == 0 else "a file the model includes", f)
                  for i, f in enumerate(m.source_files or [model])]
        _check_settings(m, changes, model, until_settled)
        if output is None:
            out = _beside_another_run(out, m, changes, {
                "n": revolutions, "t-end": t_end, "per-rev": per_rev, "output-step": output_step,
                "integrator": integrator, "rtol": rtol, "atol": atol, "step": step})
        make_folder = output is None and not out.parent.exists()  # results/, made once every check passed
        if not make_folder:
            check_output(out, "--output", inputs)
        if rerun is not None:
            _check_rerun(rerun, out, inputs, force)
        if not make_folder:
            refuse_replacing(out, overwrite=overwrite, inputs=m.source_files)
        if not until_settled:
            _check_output_size(m, changes, out, model, force)
        if make_folder:
            _make_results_folder(out.parent)
            check_output(out, "--output", inputs)
        if until_settled:
            res = _run_until_settled(m, out, max_revolutions, quiet, changes, overwrite)
        else:
            with _Progress(quiet) as progress:
                res = simulate(m, output=out, progress=progress.update, max_rows=math.inf, signals=signals,
                               overwrite=overwrite, **changes)
    except SimulationError as err:
        if err.results is not None:
            _print_summary(err.results, out)
            if rerun is not None:
                try:
                    record_run(err.results, m, rerun, magnify=magnify, fps=fps, open_viewer=view_,
                               signals=rerun_signals, recording_id=_recording_key(out))
                except (MbsError, OSError) as rec_err:  # the viewer could not start: said, then the failure
                    fail_code(rec_err if isinstance(rec_err, MbsError) else f"error: {rec_err}")
        if err.results is not None and err.results.attrs.get("status") == "not_physical":
            _console(stderr=True).print(f"error: {err.message}\nthe results to t = {err.time:.6g} s are kept in "
                                        f"{out}, marked incomplete (status not_physical)", markup=False)
        else:
            _console(stderr=True).print(f"simulation failed: {err.message}\n"
                                        f"results up to t = {err.time:.6g} s kept in {out} (marked incomplete)",
                                        markup=False)
        return int(ExitCode.SIMULATION_FAILED)
    except MbsError as err:
        return fail_code(err)
    except KeyboardInterrupt as err:  # simulation.RunInterrupted: SIGINT or SIGTERM
        kept = getattr(err, "results", None)
        if kept is not None:
            _print_summary(kept, out)
        _console(stderr=True).print(f"interrupted; results so far kept in {out} (marked incomplete)")
        return _exit_now(128 + getattr(err, "signum", ExitCode.INTERRUPTED - 128))
    _print_summary(res, out)
    if rerun is not None:
        try:
            record_run(res, m, rerun, magnify=magnify, fps=fps, open_viewer=view_, signals=rerun_signals,
                       recording_id=_recording_key(out))
        except (MbsError, OSError) as err:  # the results are written; the recording is not
            return fail_code(err if isinstance(err, MbsError) else f"error: {err}")
    return 0




def _kept(model, keep: str | None, rerun: Path | None, until_settled: bool) -> list[str] | None:
    """The signal names of ``--keep`` (None: every signal), checked against the model before the run:
    full names (``slider.vx``) or entities (``slider``), as `mbs sweep --keep` reads them."""
    from planar_mbs.errors import ModelError

    if keep is None:
        return None
    names = [k.strip() for k in keep.split(",") if k.strip()]
    if not names:
        raise ModelError("--keep names no signal", "--keep", hint="e.g. `--keep slider.x,slider.vx` or `--keep slider`")
    for other, flag in ((rerun is not None, "--rerun"), (until_settled, "--until-settled")):
        if other:
            raise ModelError(f"give --keep or {flag}, not both", "--keep",
                             hint=f"{flag} needs every signal (the mechanism's motion, the Poincaré section)")
    from planar_mbs.sweep.scan import kept_signals

    kept_signals(model, names)
    return names


def record_run(*args, **kwargs):
    """`plot_commands.record_run` (typer and rerun load only when a recording is asked for)."""
    from .plot_commands import record_run as record

    return record(*args, **kwargs)


def _needs_rerun(view_: bool, rerun: Path | None) -> None:
    """--open without --rerun cannot act: refused (exit 2) rather than ignored."""
    from planar_mbs.errors import ModelError

    if view_ and rerun is None:
        raise ModelError("--open opens the viewer on the run's rerun recording, and no --rerun is given",
                         "--open", hint="add `--rerun FILE.rrd`, or later `mbs view RESULTS.h5 --open`")


def _check_rerun(rerun: Path, out: Path, inputs: list, force: bool) -> None:
    """The --rerun file: a writable place (missing folders are made) that holds no recording of other
    results, unless --force (`rerun_log.check_replace`)."""
    from planar_mbs.outputs.rerun_log import check_replace, recording_key

    check_output(rerun, "--rerun", inputs, [("the results file (--output)", out)], make_parents=True)
    check_replace(rerun, recording_key(out), force, "--rerun")


def _recording_key(out: Path) -> str:
    from planar_mbs.outputs.rerun_log import recording_key

    return recording_key(out)


def _driver_period(m):
    from planar_mbs.results.analysis import driver_period

    return driver_period(m)


def default_output(model: Path, sets: dict[str, str]) -> Path:
    """results/<model name>.h5, with the --set values in the name (results/a_speed=2500rpm.h5), so a
    run with other values never replaces the previous one; results/ is ignored by git."""
    import re

    tag = "".join(f"_{name}={re.sub(r'[^A-Za-z0-9.+-]', '', value)}" for name, value in sets.items())
    return Path("results") / f"{model.stem}{tag}.h5"
def _beside_another_run(out: Path, m, changes: dict, given: dict) -> Path:
    """The default output `out`; or, when it holds a run with other settings (another `-n`, `--t-end`,
    step or tolerance), a name beside it carrying the options given (results/a_n=100.h5), said on
    stdout: a default name never replaces the results of a run that differs in more than its time."""
    import dataclasses

    from planar_mbs.results.hdf5 import read_results
    from planar_mbs.run.simulation import run_settings

    if not out.is_file():
        return out
    try:
        before = dict(read_results(out).attrs.get("settings") or {})
    except Exception:  # noqa: BLE001  (not a results file: the checks of the output deal with it)
        return out
    settings = run_settings(m, **changes)
    now = {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}
    same = all(k in before and (before[k] == now[k] or (isinstance(now[k], float) and math.isclose(before[k], now[k])))
               for k in ("t_end", "output_step", "integrator", "rtol", "atol", "step"))
    if same:
        return out
    text = lambda v: f"{v:g}" if isinstance(v, float) else str(v)  # noqa: E731  (-n 100 -> n=100)
    tag = "".join(f"_{opt}={re.sub(r'[^A-Za-z0-9.+-]', '', text(v))}" for opt, v in given.items() if v is not None)
    beside = out.with_name(f"{out.stem}{tag or '_other'}{out.suffix}")
    _console().print(f"{out} holds a run with other settings: this one goes to {beside}", markup=False)
    return beside


def _check_output_size(m, changes: dict, out: Path, model: Path, force: bool) -> None:
    """Refuse (exit 2) before running what asks for too many rows or more disk than is free."""
    from planar_mbs.run.output_size import check_output, estimate
    from planar_mbs.run.simulation import run_settings

    check_output(estimate(m, run_settings(m, **changes)), out, str(model), force=force)


def _make_results_folder(folder: Path) -> None:
    """The default output's folder (results/), ignored by git; a folder that cannot be made is exit 2."""
    from planar_mbs.errors import ModelError

    try:
        folder.mkdir(parents=True)
        (folder / ".gitignore").write_text("# made by `mbs run`: outputs are not sources\n*\n")
    except OSError as exc:
        raise ModelError(f"cannot create the folder `{folder}` for the results: {exc.strerror or exc}",
                         "--output", hint="run from a folder you can write, or give an output with -o") from None


def _check_settings(m, changes: dict, model: Path, until_settled: bool) -> None:
    """The run's settings through the validation `simulate` applies (`planar_mbs.run.settings_check`),
    worded for the command line."""
    from planar_mbs.run.settings_check import CLI, check_settings, given_settings
    from planar_mbs.run.simulation import run_settings

    given = {k: v for k, v in changes.items() if not (until_settled and k == "t_end")}
    settings = run_settings(m, **given)
    check_settings(settings, given=given_settings(given), style=CLI, source=str(model))


def _run_until_settled(m, out: Path, max_revolutions: int, quiet: bool, changes: dict, overwrite: bool = False):
    """`planar_mbs.run.study.long_run` until the section settles; the results written to ``out``."""
    from planar_mbs.mechanism.model import ST_CONTACT_EVENTS, ST_REJECTED, ST_RHS, ST_STEPS
    from planar_mbs.results.hdf5 import write_beside
    from planar_mbs.run.study import long_run

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
    write_beside(out, res, overwrite=overwrite, inputs=m.source_files)
    from planar_mbs.results.analysis import analyze, report

    stop = ("stopped: the section settled on a periodic orbit" if run.settled_at is not None
            else "no periodic orbit found (--max-revolutions)")
    _console().print(f"{run.revolutions} revolutions run; {stop}", markup=False)
    for line in report(*analyze(res)):  # the verdict as `mbs analyze` gives it on the file
        _console().print(line, markup=False)
    return res


PER_REV_UNTIL_SETTLED = 90  # output samples per revolution of a run --until-settled


def _exit_now(code: int) -> int:
    """Leave at once after an interrupt (the results file is already closed): skip the
    interpreter's teardown, which takes about 2 s once the compiled kernels are loaded
    (native code, no Python frame), so that Ctrl-C/SIGTERM end a run within a second.
    Inside a test runner (no real stdout) it returns the code, to exit as usual."""
    import os
    import sys

    try:
        sys.stdout.fileno()
        sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):
        return code
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def _print_summary(res, out: Path) -> None:
    from planar_mbs.results.hdf5 import peak, row_count

    from .check_command import print_assembly

    a = res.attrs
    worst = (f"{peak(res, 'system.position_error'):.3g}" if "system.position_error" in res.signals
             else "not kept (--keep)")
    con = _console()
    state = "finished" if a.get("complete") else f"stopped ({a.get('status', '?')})"
    con.print(f"[bold]{state}[/] at t = {a.get('t_reached', float('nan')):.6g} s → {out}")
    con.print(
        f"  steps {a.get('n_steps', 0):,}   rejected {a.get('n_rejected', 0):,}   "
        f"rhs evaluations {a.get('n_rhs', 0):,}   contact events {a.get('n_contact_events', 0):,}"
    )
    con.print(f"  time-loop wall time {a.get('wall_time', 0.0):.3f} s   "
              f"largest constraint error {worst}   outputs {row_count(res):,}")
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


# ---------------------------------------------------------------- a plain `mbs run` command line, without typer
_FLOAT = re.compile(r"[0-9]+(\.[0-9]*)?([eE][+-]?[0-9]+)?|\.[0-9]+([eE][+-]?[0-9]+)?")
_INT = re.compile(r"[0-9]+")

# option -> (parameter of run_model, kind, lowest value allowed by the typer command)
_OPTIONS = {
    "--output": ("output", "path", None), "-o": ("output", "path", None),
    "--set": ("set_", "list", None), "-s": ("set_", "list", None),
    "--t-end": ("t_end", "str", None),
    "--revolutions": ("revolutions", "float", None), "-n": ("revolutions", "float", None),
    "--output-step": ("output_step", "str", None),
    "--per-rev": ("per_rev", "int", 1),
    "--integrator": ("integrator", "str", None),
    "--rtol": ("rtol", "float", None), "--atol": ("atol", "float", None),
    "--step": ("step", "str", None),
    "--quiet": ("quiet", "flag", None), "-q": ("quiet", "flag", None),
    "--rerun": ("rerun", "path", None),
    "--magnify": ("magnify", "float", 0.0),
    "--fps": ("fps", "float", None),
    "--open": ("view_", "flag", None), "--view": ("view_", "flag", None),  # --view: the old name
    "--rerun-signals": ("rerun_signals", "str", None),
    "--force": ("force", "flag", None),
    "--until-settled": ("until_settled", "flag", None),
    "--max-revolutions": ("max_revolutions", "int", 1),
    "--keep": ("keep", "str", None),
    "--overwrite": ("overwrite", "flag", None),
}


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
        token = argv[i]
        i += 1
        if not token.startswith("-"):
            if model is not None:
                return None
            model = token
            continue
        name, eq, value = token.partition("=") if token.startswith("--") else (token, "", "")
        spec = _OPTIONS.get(name)
        if spec is None:
            return None
        param, kind, low = spec
        if kind == "flag":
            if eq or param in kwargs:
                return None
            kwargs[param] = True
            continue
        if not eq:
            if i >= len(argv):
                return None
            value = argv[i]
            i += 1
        if not value or value.startswith("-") or (param in kwargs and kind != "list"):
            return None
        if kind == "list":
            kwargs.setdefault(param, []).append(value)
        elif kind == "path":
            kwargs[param] = Path(value)
        elif kind == "str":
            kwargs[param] = value
        else:
            if not (_INT if kind == "int" else _FLOAT).fullmatch(value):
                return None
            number = int(value) if kind == "int" else float(value)
            if (low is not None and number < low) or (kind == "float" and not math.isfinite(number)):
                return None
            kwargs[param] = number
    if not model:
        return None
    return dict(model=Path(model), **kwargs)


class _PacifyFlush:
    """stdout/stderr after a broken pipe: flushing them again stays quiet (as typer does)."""

    def __init__(self, wrapped):
        self.wrapped = wrapped

    def flush(self) -> None:
        import errno

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
    import errno
    import sys

    from .common import internal_error

    try:
        try:
            return run_model(**kwargs)
        except KeyboardInterrupt:
            return int(ExitCode.INTERRUPTED)
        except EOFError:
            from typer import rich_utils

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
