"""`mbs sweep` and `mbs analyze`: thin typer commands over `planar_mbs.sweep.scan` and
`planar_mbs.results.analysis`.

Registered in `app.py` with ``app.command()(sweep)`` and ``app.command()(analyze)``.
Exit codes as everywhere: 0 success, 2 bad model / usage / a sweep file from
another model, 3 at least one case failed (its results up to the failure are kept),
130 interrupted, 143 stopped by SIGTERM (finished cases are kept; rerunning the command resumes).
"""
import logging
import math
import os
import signal
import sys
import threading
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.table import Table
from rich.text import Text

from planar_mbs import catalog, load_model, read_results
from planar_mbs.errors import MbsError, ModelError
from planar_mbs.lazy import lazy
from planar_mbs.sweep.progress import ProgressTally

from .common import ExitCode
from .spectrum_options import KindOpt, ResolutionOpt, WindowOpt
from .study_options import CasesOpt, SampleOpt, SamplerOpt, SeedOpt, SobolOpt
from .common import console as _console
from .common import fail as _fail
from .common import parse_sets as _sets
from .common import (
    MAX_JOBS,
    MAX_REVOLUTIONS,
    check_number,
    check_output,
    check_rtol,
    model_files,
    positive_time,
)

# numpy, h5py, numba, lark: loaded when a command runs, never by `mbs --help` (which imports this module)
sweep_scan = lazy("planar_mbs.sweep.scan")
simulation = lazy("planar_mbs.run.simulation")
hdf5 = lazy("planar_mbs.results.hdf5")
analysis = lazy("planar_mbs.results.analysis")
spectrum_command = lazy("planar_mbs.cli.spectrum_command")
study_command = lazy("planar_mbs.cli.study_command")
server = lazy("planar_mbs.sweep.server")  # multiprocessing: only when a sweep ends
rich_progress = lazy("rich.progress")  # only on a terminal, once the first case finishes
# dask.distributed (optional, slow to import): only with --scheduler
distributed = lazy("distributed")
distributed_security = lazy("distributed.security")


def _check_sweep_files(model: Path, output: Path, sets: list[str], keep: Optional[list[str]]) -> None:
    """Before any case runs: the output is not the model or a file it includes and can be written;
    every `--keep` name is a signal or an entity of the model."""
    inputs = [("the model file" if i == 0 else "a file the model includes", f)
              for i, f in enumerate(model_files(model))]
    check_output(output, "--output", inputs)
    if keep:
        # signal or entity names, as the sweep reads them
        sweep_scan.kept_signals(load_model(model, **_sets(sets)), keep)


def _pair(text: Optional[str]) -> Optional[list[str]]:
    if text is None:
        return None
    x, sep, y = text.partition(":")
    if not sep or not x.strip() or not y.strip():
        raise ModelError(f"`--poincare {text}` is not X:Y", "--poincare", hint="e.g. `--poincare slider.vx:slider.ax`")
    return [x.strip(), y.strip()]


def _angle(text: Optional[str]) -> Optional[float]:
    """An angle with units (`90deg`, `1.2rad`; plain numbers are degrees)."""
    if text is None:
        return None
    parsed = sweep_scan.parameter_number(text)
    if parsed is None or parsed[1] not in ("", "deg", "rad", "°"):
        raise ModelError(f"`--angle {text}` is not an angle", "--angle", hint="e.g. `--angle 90deg`")
    value, unit = parsed
    return value if unit == "rad" else math.radians(value)


def _section_options(poincare, period, angle, transient, clock, no_section) -> Optional[dict]:
    if no_section:
        return None
    check_number(transient, "--transient", low=0.0, low_ok=True, high=MAX_REVOLUTIONS,
                 hint="driver periods dropped before the section, e.g. `--transient 1`")
    opts: dict = {"transient": transient}
    if poincare:
        opts["signals"] = _pair(poincare)
    if period is not None:
        opts["period"] = positive_time(period, "--period")
    if angle is not None:
        opts["angle"] = check_number(_angle(angle), "--angle", hint="e.g. `--angle 90deg`")
    if clock:
        opts["clock"] = clock
    return opts


PoincareOpt = Annotated[Optional[str], typer.Option(
    "--poincare", "-p", help="Signals of the Poincaré section X:Y: by default along the slider's axis (vy:ay "
    "on a vertical guide), without a slider the output link's phi:omega.", show_default="the slider's vx:ax")]
PeriodOpt = Annotated[Optional[str], typer.Option(
    "--period", help="A stroboscopic section every PERIOD (with units).",
    show_default="once per revolution of the clock body")]
AngleOpt = Annotated[Optional[str], typer.Option(
    "--angle", help="Section at this angle of the clock body (90deg, 1.5rad) instead of once per period.",
    show_default=False)]
TransientOpt = Annotated[float, typer.Option(
    "--transient", help="Section crossings (revolutions) dropped at the start; where the motion settles "
    "is then found from the points.", min=0)]
ClockOpt = Annotated[Optional[str], typer.Option(
    "--clock", help="Body whose angle clocks the section.",
    show_default="the driven body, else the body that turns most")]


SpectrumOpt = Annotated[Optional[str], typer.Option(
    "--spectrum", help="Print the spectrum of this signal instead of the verdict (e.g. slider.ax).",
    show_default="none: the verdict")]
FromOpt = Annotated[Optional[str], typer.Option(
    "--from", help="With --spectrum: drop the transient before this time (0.1s).", show_default="the start")]
ToOpt = Annotated[Optional[str], typer.Option(
    "--to", help="With --spectrum: the last time used.", show_default="the end")]


ParamOpt = Annotated[Optional[list[str]], typer.Option(
    "--param", "-P", help="NAME=VALUES: a list (speed=800rpm,1200rpm), a linear range with a count "
    "(clearance=0.1mm..0.5mm:5) or names (law=hertz,lankarani_nikravesh). Repeatable; the sweep is the "
    "cartesian product.", show_default="none: --sample")]
SweepKeepOpt = Annotated[Optional[str], typer.Option(
    "--keep", help="Comma-separated signals to store per case besides its Poincaré section, verdict and "
    "summary statistics (extrema and RMS of every signal); an entity name (slider) keeps all its "
    "signals; --keep all stores every signal of every sample (large: `mbs sweep replay` reruns any "
    "case instead).", show_default="none")]
SchedulerOpt = Annotated[Optional[str], typer.Option(
    "--scheduler", help="Address of a running dask.distributed scheduler (tcp://host:8786): the cases run on "
    "its workers instead of local processes. Workers need planar_mbs installed; the model's text (with its "
    "includes) is sent to them. Only this process writes the HDF5 file.", show_default=False)]
WorkerTimeoutOpt = Annotated[float, typer.Option(
    "--worker-timeout", help="With --scheduler: stop (keeping the finished cases) once the cluster has had no "
    "worker, or no scheduler, for this many seconds.", min=1.0)]
SweepForceOpt = Annotated[bool, typer.Option(
    "--force", help="Run even when a case asks for more than 10^8 output rows or the cases do not fit on the "
    "free disk space (the sweep stops cleanly if the disk fills).")]
SweepUnphysicalOpt = Annotated[bool, typer.Option(
    "--allow-unphysical", help="Keep a case whose results are not physical (a journal sunk deeper than its "
    "clearance) as finished instead of failed; the warning stays and the file records allow_unphysical "
    "(the ideal-limit study of docs/contact.md).")]


def sweep(
    model: Annotated[Path, typer.Argument(help="The .mbs model file.", show_default=False)],
    output: Annotated[Path, typer.Option("--output", "-o", help="The sweep's HDF5 file.", show_default=False)],
    param: ParamOpt = None,
    sample: SampleOpt = None,
    cases: CasesOpt = None,
    sampler: SamplerOpt = "lhs",
    seed: SeedOpt = 0,
    sobol_indices: SobolOpt = False,
    set_: Annotated[Optional[list[str]], typer.Option(
        "--set", "-s", help="Fixed override of a `param` for every case, NAME=VALUE. Repeatable.",
        show_default=False)] = None,
    jobs: Annotated[Optional[int], typer.Option("--jobs", "-j", help="Parallel processes.",
                                                min=1, show_default="the number of cores")] = None,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="End time of every case, with units.",
                                                 show_default="the model's simulate block")] = None,
    revolutions: Annotated[Optional[float], typer.Option(
        "--revolutions", "-n", help="End time as a number of driver periods (scales with a swept speed).",
        show_default=False)] = None,
    per_rev: Annotated[Optional[int], typer.Option(
        "--per-rev", help="Output samples per driver period (the output step divides the period, so the "
        "Poincaré section is sampled without interpolation).", min=1, show_default=False)] = None,
    output_step: Annotated[Optional[str], typer.Option("--output-step", help="Output step with units.",
                                                       show_default="the model's simulate block")] = None,
    integrator: Annotated[Optional[str], typer.Option(help=catalog.choices(catalog.INTEGRATORS) + ".",
                                                      show_default="the model's simulate block, else dopri5")] = None,
    rtol: Annotated[Optional[float], typer.Option(help="Relative tolerance.",
                                                    show_default="the model's simulate block, else 1e-6")] = None,
    atol: Annotated[Optional[float], typer.Option(help="Absolute tolerance (> 0).",
                                                    show_default="the model's simulate block, else 1e-9")] = None,
    keep: SweepKeepOpt = None,
    poincare: PoincareOpt = None,
    period: PeriodOpt = None,
    angle: AngleOpt = None,
    transient: TransientOpt = 1.0,
    clock: ClockOpt = None,
    no_section: Annotated[bool, typer.Option("--no-section", help="Store no Poincaré section.")] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Start the file afresh.")] = False,
    retry_failed: Annotated[bool, typer.Option("--retry-failed", help="Run failed cases again.")] = False,
    scheduler: SchedulerOpt = None,
    worker_timeout: WorkerTimeoutOpt = 60.0,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
    force: SweepForceOpt = False,
    allow_unphysical: SweepUnphysicalOpt = False,
) -> None:
    """Run a model for every combination of parameter values, in parallel, into one HDF5 file.

    Each case is stored under /cases/<k>/ with its Poincaré section and the verdict on its motion
    (periodic, quasi-periodic or chaotic) under /cases/<k>/poincare, the extrema and RMS of every
    signal under /cases/<k>/summary and the signals named with --keep; the table of cases is
    /cases_table. `mbs sweep replay FILE K -o case.h5` reruns case K with every signal; `mbs sweep
    merge A B -o ALL` merges scans. Rerunning the same command resumes: finished cases are not run
    again, and a killed sweep loses no finished case.

    With --sample instead of --param, a sampled study (docs/studies.md), read by `mbs sweep stats`.
    Example: mbs sweep models/slider_crank_clearance_a.mbs -P speed=800rpm..6000rpm:27 -n 101 --per-rev 720 -o a.h5
    """
    try:
        study, axes = study_command.design(param, sample, cases, sampler, seed, sobol_indices, output)
        settings = _sweep_settings(integrator, t_end, output_step, rtol, atol, revolutions, jobs)
        section = _section_options(poincare, period, angle, transient, clock, no_section)
        keep_list = _keep_list(keep)
        _check_sweep_files(model, output, set_ or [], keep_list)
        workers = None if scheduler else jobs or os.cpu_count() or 1  # a cluster's: unknown here
        with _interruptible(), _SweepProgress(quiet, workers) as bar, _cluster(scheduler) as executor:
            summary = study_command.start(study, model, axes, output, sets=_sets(set_ or []), settings=settings,
                                revolutions=revolutions, per_rev=per_rev, keep=keep_list, section=section, jobs=jobs,
                                executor=executor, overwrite=overwrite, retry_failed=retry_failed, force=force,
                                progress=bar.update, worker_timeout=worker_timeout, allow_unphysical=allow_unphysical)
    except MbsError as err:
        _fail(err)
    except KeyboardInterrupt as err:
        _console(stderr=True).print(f"interrupted; finished cases are kept in {output}: run the same command "
                                    "again to resume")
        raise typer.Exit(128 + _interruptible.signum(err))
    finally:
        server.remove_temp_folder()  # the fork server's socket folder (the command ends without multiprocessing's finalizers)
    study_command.report(summary, output) if study else _report_sweep(summary, [a.name for a in axes],
                                                                      section is not None)


def _keep_list(keep: str | None) -> list[str] | None:
    """The signals `--keep` names (None: `all`; none by default)."""
    if keep is not None and keep.strip() == "all":
        return None
    return [k.strip() for k in (keep or "").split(",") if k.strip()]


def _sweep_settings(integrator, t_end, output_step, rtol, atol, revolutions, jobs) -> dict:
    """The settings of every case that the options give (None: the model's), each checked."""
    if integrator is not None:
        simulation.integrator_of(integrator, "--integrator")
    settings = {k: v for k, v in dict(
        t_end=positive_time(t_end, "--t-end"), output_step=positive_time(output_step, "--output-step"),
        rtol=check_rtol(rtol), atol=atol, integrator=integrator.lower() if integrator else None).items()
        if v is not None}
    check_number(revolutions, "--revolutions", low=0.0, high=MAX_REVOLUTIONS,
                 hint="the number of driver periods to simulate, e.g. `-n 101`")
    check_number(jobs, "--jobs", low=1, low_ok=True, high=MAX_JOBS, hint="e.g. `-j 4`")
    if t_end is not None and revolutions is not None:
        raise ModelError("give --t-end or --revolutions, not both", "--revolutions")
    return settings


def _report_sweep(summary, names: list[str], section: bool = True) -> None:
    """The table of cases, each failure in a sentence, why verdicts are blank, the counts; exit 3 when
    a case failed."""
    _print_table(summary.rows, names)
    if section:
        _why_no_verdict(summary.rows)
    for r in summary.rows:
        if r["index"] in summary.failed and r.get("message"):
            vals = ", ".join(f"{k}={v}" for k, v in r["values"].items())
            _console(stderr=True).print(f"case {r['index']} ({vals}) failed: {r['message']}", markup=False,
                                        soft_wrap=True)
    # failed cases of an earlier call stay in the file (skipped unless --retry-failed): they count too
    earlier = [r["index"] for r in summary.rows if r["status"] == "failed" and r["index"] not in summary.ran]
    note = f" ({len(earlier)} from an earlier run: --retry-failed runs them again)" if earlier else ""
    _console().print(f"{len(summary.ran)} case(s) run, {len(summary.skipped)} already in the file, "
                     f"{len(summary.failed) + len(earlier)} failed{note} → {summary.path}  "
                     f"({summary.wall_time:.1f} s)")
    if summary.failed or earlier:
        raise typer.Exit(ExitCode.SIMULATION_FAILED)


NO_SECTION = "; no Poincaré section: "


def _why_no_verdict(rows) -> None:
    """Say why finished cases have blank verdict columns (their section could not be taken) and how to
    get one: the section's reason, then a hint that is never empty."""
    blank = [r for r in rows if r["status"] != "failed" and not r.get("verdict")]
    if not blank:
        return
    reason = str(blank[0].get("message") or "").partition(NO_SECTION)[2] or "the case stored no Poincaré section"
    if "`-p" in reason:
        hint = "sweep again with the section's signals named, " + reason[reason.index("`-p"):].split(";")[0]
    elif "period" in reason:
        hint = "sweep again with `--period T` (a stroboscopic section) or `--clock BODY`"
    else:
        hint = "sweep again naming the section's signals (`-p X:Y`) and its clock (`--clock BODY`)"
    cases = ", ".join(str(r["index"]) for r in blank[:10]) + (", …" if len(blank) > 10 else "")
    err = _console(stderr=True)
    err.print(f"no verdict for case {cases} (blank columns): {reason}", markup=False, soft_wrap=True)
    err.print(f"hint: {hint}", markup=False, soft_wrap=True)


class _interruptible:
    """Ctrl-C (SIGINT) and SIGTERM stop a sweep the same way: finished cases kept, the pool's case
    files removed, the sentence that says how to resume, exit 128 + the signal (130, 143), as for
    `mbs run`.  The handler is installed even when the shell started the sweep with SIGINT ignored
    (a script without job control, `nohup`), where Python leaves it ignored.  It raises
    KeyboardInterrupt at once and notes the signal (`sweep.note_interrupt`), so that an interrupt
    Python drops (raised inside a weakref or garbage-collector callback) is raised again at the
    sweep's next wait or, in one process, before its next case, instead of being printed as
    "Exception ignored" while the sweep ran on to its end.  (SIGTERM used to end the process where
    it stood, leaving the folder of case files.)"""

    SIGNALS = ("SIGINT", "SIGTERM")

    def __enter__(self):
        def interrupt(signum, frame):
            sweep_scan.note_interrupt(signum)
            raise KeyboardInterrupt

        def unraisable(report):
            if not (isinstance(report.exc_value, KeyboardInterrupt) and sweep_scan.PENDING_INTERRUPTS):
                self.hook(report)  # a dropped interrupt is raised again, not printed as "Exception ignored"

        self.previous = {}
        sweep_scan.PENDING_INTERRUPTS.clear()
        self.hook, sys.unraisablehook = sys.unraisablehook, unraisable
        if threading.current_thread() is threading.main_thread():
            for name in self.SIGNALS:
                sig = getattr(signal, name)
                self.previous[sig] = signal.signal(sig, interrupt)
        return self

    def __exit__(self, *exc):
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)
        sys.unraisablehook = self.hook
        return False

    @staticmethod
    def signum(err: KeyboardInterrupt) -> int:
        """The signal that stopped the sweep: the run's own (`simulation.RunInterrupted`, a case run
        in this process), else the last one noted, else SIGINT."""
        pending = sweep_scan.PENDING_INTERRUPTS
        return int(getattr(err, "signum", 0) or (pending[-1] if pending else 2))


class _cluster:
    """A dask.distributed executor on the scheduler at `address` (None: no executor, local processes)."""

    def __init__(self, address: Optional[str]):
        self.address = address
        self.client = None

    def __enter__(self):
        if self.address is None:
            return None
        try:
            Client = distributed.Client
        except ImportError:
            raise ModelError("--scheduler needs dask.distributed", "--scheduler",
                             hint="pip install 'dask[distributed]'") from None
        # distributed logs a lost scheduler with tracebacks, and a callback that fails then on its event
        # loop is logged by asyncio ("Exception in callback ..."); the sweep reports it in one sentence
        # (distributed's logging config gives some children levels of their own, tornado.application
        # among them: every such logger is silenced by name, not only the parents)
        names = {"distributed", "tornado", "tornado.application", "asyncio"}
        names |= {n for n in logging.root.manager.loggerDict if n.split(".")[0] in ("distributed", "tornado")}
        for name in names:
            logging.getLogger(name).setLevel(logging.CRITICAL + 1)
        _check_tls(self.address)
        try:
            self.client = Client(self.address, timeout="10s")
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            raise ModelError(f"cannot reach the dask scheduler at {self.address}: {exc}", "--scheduler",
                             hint="start one with `dask scheduler` and workers with `dask worker ADDRESS`") from None
        return self.client.get_executor()

    def __exit__(self, *exc):
        if self.client is not None:
            try:
                self.client.close(timeout=5)
            except Exception:  # a scheduler that died: nothing to close cleanly, and nothing to lose
                pass
        return False


TLS_SETTINGS = ("DASK_DISTRIBUTED__COMM__TLS__CA_FILE", "DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT",
                "DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY")


def _check_tls(address: str) -> None:
    """A tls:// scheduler needs the client's certificates from dask's configuration (docs/sweeps.md,
    "Trust"); without them dask fails with a TypeError about an ssl_context: say what to set."""
    if not address.lower().startswith("tls://"):
        return
    sec = distributed_security.Security()  # reads distributed.comm.tls.* (files in ~/.config/dask or DASK_ variables)
    if not (sec.tls_ca_file and sec.tls_client_cert):
        raise ModelError(f"--scheduler {address}: a TLS scheduler needs this client's certificates, and dask's "
                         "configuration names none", "--scheduler",
                         hint="set " + ", ".join(TLS_SETTINGS) + " (files: the CA certificate, this client's "
                         "certificate and key), as docs/sweeps.md shows")


def _print_table(rows, params) -> None:
    t = Table(title_justify="left")
    for col in ["case", *params, "status", "verdict", "K", "λ/T", "D2"]:
        t.add_column(col)
    fmt = lambda v: "" if v != v else f"{v:.2f}"  # noqa: E731  (NaN -> "")
    for r in rows:
        t.add_row(str(r["index"]), *[r["values"].get(p, "") for p in params], r["status"], r.get("verdict", ""),
                  fmt(r.get("K", math.nan)), fmt(r.get("lyapunov", math.nan)), fmt(r.get("dimension", math.nan)))
    _console().print(t)


class _SweepProgress:
    """The progress line of a sweep (`sweep.progress.ProgressTally`: cases done and failed, the CPU the
    cases get, the time left) with a bar and the last case's verdict on a terminal; elsewhere (a log
    file, `nohup`) the same line as cases finish, at most once a minute."""

    EVERY = 60.0  # seconds between two lines when stderr is not a terminal

    def __init__(self, quiet: bool, workers=None):
        self.quiet = quiet
        self.tally = ProgressTally(workers)
        self.bar = None
        self.task = None
        self.printed = None

    def __enter__(self):
        return self

    def update(self, done: int, total: int, outcome) -> None:
        self.tally.update(done, total, outcome)
        if self.quiet:
            return
        console = _console(stderr=True)
        if not console.is_terminal:
            now = self.tally.elapsed()
            if now - (self.printed or 0.0) >= self.EVERY or (done == total and self.printed is not None):
                console.print(f"sweep: {self.tally.line()}", markup=False, highlight=False, soft_wrap=True)
                self.printed = now
            return
        if self.bar is None:
            # drawn at every refresh: the clock and the time left move between cases
            class Tally(rich_progress.ProgressColumn):
                def render(column, task):
                    return Text(self.tally.line())

            # twice a second, not rich's default 10: over a 58-minute scan of 969 cases the sweep's process
            # used 45 CPU s where its own work is about 3 s (benchmarks/scan_phases.py); the rest is the redraws
            rp = rich_progress
            self.bar = rp.Progress(rp.TextColumn("sweep"), rp.BarColumn(), Tally(), rp.TextColumn("{task.fields[last]}"),
                                   console=console, transient=True, refresh_per_second=2)
            self.bar.start()
            self.task = self.bar.add_task("sweep", total=total, completed=done, last="")
        last = ""
        if outcome is not None:
            vals = ", ".join(f"{k}={v}" for k, v in outcome.values.items())
            last = f"  last: {vals}: {outcome.status}" + (f", {outcome.verdict.headline()}" if outcome.verdict else "")
        self.bar.update(self.task, completed=done, last=last)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.stop()
        return False


def analyze(
    results: Annotated[Path, typer.Argument(help="A results file (FILE.h5), one case of a sweep "
                                            "(FILE.h5:/cases/3) or a whole sweep file.", show_default=False)],
    poincare: PoincareOpt = None,
    period: PeriodOpt = None,
    angle: AngleOpt = None,
    transient: TransientOpt = 1.0,
    clock: ClockOpt = None,
    store: Annotated[bool, typer.Option("--store", help="Write the section and verdict into the file "
                                        "(group `poincare` of the run).")] = False,
    spectrum: SpectrumOpt = None,
    kind: KindOpt = "amplitude",
    window: WindowOpt = None,
    resolution: ResolutionOpt = None,
    t_from: FromOpt = None,
    t_to: ToOpt = None,
    peaks: Annotated[int, typer.Option("--peaks", help="Peaks of the spectrum printed.", min=0)] = 5,
    csv: Annotated[Optional[Path], typer.Option("--csv", help="Write the spectrum to this CSV file.",
                                                show_default="none")] = None,
) -> None:
    """Poincaré section of a run and a verdict on its motion: periodic (with its period count),
    quasi-periodic or chaotic, with the indicators it rests on (0-1 test K, nearest-neighbour
    Lyapunov growth λ per period, correlation dimension D2, recurrence residual).

    With --spectrum SIGNAL, its spectrum instead (--kind amplitude, psd or order), after --from,
    with the window and resolution stated and the highest peaks (docs/studies.md).

    For a sweep file, prints the stored verdict of every case.
    """
    try:
        if spectrum is not None:
            opts = spectrum_command.spectrum_options(kind, window, resolution, t_from, t_to, clock)
            hdf5.check_results_file(str(results).partition(":")[0])
            spectrum_command.print_spectrum(results, spectrum, opts, peaks, csv)
            return
        _analyze(results, poincare, period, angle, transient, clock, store)
    except MbsError as err:
        _fail(err)
    except (KeyError, ValueError, OSError) as err:
        _console(stderr=True).print(f"error: {err}", markup=False)
        raise typer.Exit(ExitCode.BAD_MODEL)


def _analyze(results, poincare, period, angle, transient, clock, store) -> None:
    file, _, group = str(results).partition(":")
    hdf5.check_results_file(file)
    opts = _section_options(poincare, period, angle, transient, clock, False)

    with hdf5.open_results(file) as f:
        is_sweep = f.attrs.get("kind") == "sweep"
    if is_sweep and not group:
        rows = sweep_scan.read_case_table(file)
        params = list(rows[0]["values"]) if rows else []
        _print_table(rows, params)
        return
    con = _console()
    stored = _stored_case(file, group) if is_sweep and group else None
    if stored is not None:  # a case of a scan that kept no signal: its stored section and verdict
        sec, verdict = stored
        con.print(f"{results} keeps no signals (`mbs sweep replay {file} {group.strip('/').split('/')[-1]} "
                  "-o case.h5` runs it again with all of them); its stored section:", markup=False)
        _print_verdict(con, results, sec, verdict)
        return
    res = read_results(results)
    signals = opts.pop("signals", None)  # None: the slider, chosen as plots and sweeps do
    sec = analysis.poincare_section(res, signals, **opts)
    verdict = analysis.classify(sec)
    _print_verdict(con, results, sec, verdict)
    if store:
        analysis.store_section(file, group, sec, verdict)
        con.print(f"stored in {file}:{(group or '').rstrip('/')}/poincare", markup=False)


def _stored_case(file: str, group: str):
    """(section, verdict) stored for a sweep's case that has no signals; None otherwise."""
    with hdf5.open_results(file) as f:
        g = f.get(group)
        if g is None or "signals" in g or "poincare" not in g:
            return None
        sec, verdict = analysis.read_section(g)
    return (sec, verdict) if verdict is not None else None


def _print_verdict(con, results, sec, verdict) -> None:
    con.print(f"Poincaré section of {results}: {len(sec)} points of {', '.join(sec.names)} "
              f"({sec.kind}" + (f", period {sec.period:.6g} s" if sec.period else "") + f", {sec.method}, "
              f"transient {sec.transient:g})", markup=False)
    if sec.method == "interpolated":
        con.print("  interpolation error (relative to each signal's spread): "
                  + ", ".join(f"{k} {v:.1e}" for k, v in sec.interp_error.items()), markup=False)
    for line in analysis.report(sec, verdict):  # the one wording of a verdict (run --until-settled prints it too)
        con.print(line, markup=False)


SUBCOMMANDS = {"replay": "sweep-replay", "merge": "sweep-merge", "stats": "sweep-stats"}


def route(argv: list[str]) -> None:
    """``mbs sweep replay ...`` and ``mbs sweep merge ...`` are the commands `sweep_replay` and
    `sweep_merge` (``sweep`` itself takes a model file first; a model file named ``replay`` in the
    working folder is still a model)."""
    if argv[1:2] == ["sweep"] and argv[2:3] and argv[2] in SUBCOMMANDS and not Path(argv[2]).exists():
        argv[1:3] = [SUBCOMMANDS[argv[2]]]


def sweep_replay(
    scan: Annotated[Path, typer.Argument(help="The sweep's HDF5 file.", show_default=False)],
    case: Annotated[int, typer.Argument(help="The case's index (the `case` column of `mbs analyze`).",
                                        show_default=False)],
    output: Annotated[Path, typer.Option("--output", "-o", help="The case's results file (every signal).",
                                         show_default=False)],
) -> None:
    """Run one case of a sweep again, from what the sweep file records (the model with its includes,
    the --set values, the settings): the same results as `mbs run` with those settings, bit for bit."""
    try:
        hdf5.check_results_file(scan)
        check_output(output, "--output", [("the sweep file", scan)])
        res = sweep_scan.replay_case(scan, case, output)
    except MbsError as err:
        _fail(err)
    _console().print(f"case {case}: {res.attrs.get('message', 'finished')} ({len(res.time)} rows) → {output}",
                     markup=False)
    if not res.attrs.get("complete", True):
        raise typer.Exit(ExitCode.SIMULATION_FAILED)


def sweep_merge(
    inputs: Annotated[list[Path], typer.Argument(help="Sweep files of the same model and settings.",
                                                 show_default=False)],
    output: Annotated[Path, typer.Option("--output", "-o", help="The merged sweep file.", show_default=False)],
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing output.")] = False,
) -> None:
    """Merge sweep files of the same model and settings (e.g. computed on two machines) into one;
    a case found in two files is refused."""
    try:
        for p in inputs:
            hdf5.check_results_file(p)
        check_output(output, "--output", [("a file to merge", p) for p in inputs])
        n = sweep_scan.merge_sweeps(inputs, output, overwrite=overwrite)
    except MbsError as err:
        _fail(err)
    _console().print(f"{n} case(s) from {len(inputs)} files → {output}", markup=False)
