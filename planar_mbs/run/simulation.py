"""Run a compiled model: assemble, call the compiled time loop chunk by chunk, keep the results.

(The module is `simulation`, not `simulate`, so that it never shadows the
public function `planar_mbs.simulate`.)

The time loop lives in numba (`kernel.advance`), called by the one `driver.Driver`; this module
reads the settings, hands the driver a place for its rows (the HDF5 writer, or memory) and the
progress callback, and turns how the run ended into its results' attributes.  A failed run raises `SimulationError` and keeps everything computed
up to the failure (in memory and in the file, marked incomplete).  With an output
file the rows are only in the file (memory stays bounded however long the run):
the returned `Results` reads them back on access; a full disk stops the run
between two chunks with everything before them readable.
"""
from __future__ import annotations

import dataclasses
import math
import signal
import threading
import time as _time
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .. import catalog
from ..version import __version__
from ..errors import ModelError, SimulationError, did_you_mean
from ..language.units import parse_quantity
from ..mechanism.kinematics import assemble, assembly_changes, assembly_warnings
from ..mechanism.start_stiffness import check_step_count
from ..mechanism.model import (
    CFG_SKIP,
    ST_CONTACT_EVENTS,
    ST_OUTPUTS,
    ST_REJECTED,
    ST_RHS,
    ST_STEPS,
    Integrator,
    Model,
    Settings,
    Status,
)
from .checks import end_warnings, kept_unphysical, not_physical
from .driver import BUFFER_ROWS, Driver, MemorySink, Sink
from .loads import Loads
from .output_size import MAX_ROWS, estimate
from .settings_check import check_arguments, check_memory, check_settings, check_stop, given_settings as _given, \
    seconds_value
from ..results.hdf5 import DiskFull, FileResults, Results, ResultsWriter
from ..results.section import driver_period, mechanism_facts
from ..results.signals import signal_table, skip_bits

RTOL_FLOOR = 10 * float(np.finfo(np.float64).eps)  # smallest rtol (Hairer's codes: rtol > 10 uround)
PROGRESS_SLICES = 200  # `Simulation.run_until` returns to its callback at least this often per run (in outputs)
FLUSH_BYTES = 8 << 20  # rows kept in memory before they are appended to the HDF5 file (whole chunks, at least one) ...
FLUSH_SECONDS = 1.0  # ... or after this much wall time since the last write, whichever comes first


def flush_rows(width: int) -> int:
    """Rows of `width` float64 columns held before a write to the file: whole HDF5 chunks of
    `ResultsWriter.CHUNK` rows filling about FLUSH_BYTES (at least one chunk), so every write but
    the last (and one after a write forced by FLUSH_SECONDS) covers whole chunks."""
    chunk = ResultsWriter.CHUNK
    return chunk * max(1, FLUSH_BYTES // (8 * max(width, 1) * chunk))


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) or SIGTERM stopped the run between two chunks; the results
    so far are kept (``.results``, and the file closed and marked incomplete)."""

    def __init__(self, signum: int, results=None):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.results = results


@contextmanager
def interrupts_handled(handler):
    """SIGINT and SIGTERM call ``handler(signum, frame)`` inside the block, the previous handlers back
    after it.  Only the main thread may install handlers: elsewhere the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


@contextmanager
def _deferred_interrupts():
    """While the time loop runs, SIGINT and SIGTERM only raise a flag that the loop
    checks between chunks, so a signal can never land halfway through writing a
    chunk to the results file."""
    received: list[int] = []
    with interrupts_handled(lambda signum, frame: received.append(signum)):
        yield received


def check_tolerances(settings: Settings) -> None:
    """Refuse (ModelError, exit 2) tolerances an adaptive method cannot deliver in double
    precision.  As in Hairer's DOPRI5/DOP853 codes: rtol > 10 eps (below it the error
    estimate is rounding noise and the step shrinks until it underflows, or forever) and
    atol > 0."""
    if not catalog.INTEGRATORS[int(settings.integrator)].adaptive:
        return
    if not (settings.rtol > RTOL_FLOOR):
        raise ModelError(f"rtol = {settings.rtol:g} is below what double precision can deliver: the floor is "
                         f"rtol > {RTOL_FLOOR:.3g} (10 x machine epsilon)", "rtol",
                         hint="use rtol >= 1e-14; DOP853 at 1e-12 is already at the limit of round-off")
    if not (settings.atol > 0.0):
        raise ModelError(f"atol = {settings.atol:g} must be positive", "atol",
                         hint="e.g. 1e-3 x rtol for coordinates of about 0.1 m")


# settings given as text take the units the CLI takes: t_end="1 s", step="1 us", alpha="5 1/s"
_TIME_SETTINGS = ("t_end", "step", "h_min", "h_max", "output_step")
_RATE_SETTINGS = ("alpha", "beta")


def _setting(model: Model, name: str, value):
    """One `simulate` setting in SI from a number or from text with units (as on the command line)."""
    fields = [f.name for f in dataclasses.fields(Settings)]
    where = f"simulate({name}=...)"
    if name not in fields:
        raise ModelError(f"unknown setting `{name}`", where,
                         hint=did_you_mean(name, fields + ["revolutions", "per_rev"]) or
                         "settings: " + ", ".join(fields + ["revolutions", "per_rev"]))
    if name == "integrator":
        return value if isinstance(value, Integrator) else integrator_of(value, where)
    if name == "projection":
        if isinstance(value, str):
            v = value.strip().lower()
            if v not in ("on", "off", "auto", "true", "false"):
                raise ModelError(f"`projection` is auto, on or off, not `{value}`", where,
                                 hint="e.g. projection=\"on\"")
            return {"true": "on", "false": "off"}.get(v, v)
        return "on" if value else "off"
    if isinstance(value, np.ndarray):  # a 1-element array is its number; any other is refused below
        value = value.item() if value.size == 1 else str(value)
    if isinstance(value, str):
        try:
            if name in _TIME_SETTINGS:
                return parse_quantity(value, "time", where=where)
            if name in _RATE_SETTINGS:
                return parse_quantity(value, "angular_velocity", where=where)
            value = float(value)
        except ValueError:
            raise ModelError(f"`{name}` takes a number, not `{value}`", where, hint="e.g. rtol=1e-8") from None
    try:
        return int(value) if name == "max_steps" else float(value)
    except (TypeError, ValueError, OverflowError):
        raise ModelError(f"`{name}` takes a number, not {value!r:.60}", where, hint="e.g. rtol=1e-8") from None


def run_settings(model: Model, revolutions=None, per_rev=None, **changes) -> Settings:
    """The model's `simulate` settings with the given fields replaced (None = keep).

    Values are SI numbers or text with units, as on the command line (``t_end="1 s"``,
    ``output_step="10 us"``, ``integrator="dop853"``).  ``revolutions`` sets t_end and
    ``per_rev`` the output step from the period of the model's constant-speed rotation driver
    (the crank)."""
    changes = {k: _setting(model, k, v) for k, v in changes.items() if v is not None}
    if revolutions is not None or per_rev is not None:
        found = driver_period(model)
        what = "revolutions" if revolutions is not None else "per_rev"
        if found is None:
            raise ModelError(f"`{what}` needs a rotation driver at constant speed (the crank)", model.source_path,
                             hint="give the end time (t_end) and the output step instead")
        if revolutions is not None and "t_end" in changes:
            raise ModelError("give the end time or a number of revolutions, not both", model.source_path,
                             hint="drop one of them")
        if per_rev is not None and "output_step" in changes:
            raise ModelError("give the output step or the samples per revolution, not both", model.source_path,
                             hint="drop one of them")
        if revolutions is not None:
            if not float(revolutions) > 0:
                raise ModelError(f"the number of revolutions must be positive, not {revolutions}",
                                 model.source_path, hint="e.g. 5 revolutions")
            changes["t_end"] = float(revolutions) * found[0]
        if per_rev is not None:
            if not int(per_rev) >= 1:
                raise ModelError(f"samples per revolution must be at least 1, not {per_rev}", model.source_path,
                                 hint="e.g. 360 per revolution")
            changes["output_step"] = found[0] / int(per_rev)
    return dataclasses.replace(model.settings, **changes)


# what scipy (solve_ivp's RK45, DOP853), MATLAB (ode45) and Hairer's codes call our integrators: a
# spelling like `rk45` is closest to `rk4` letter by letter, but means Dormand-Prince 5(4)
OTHER_INTEGRATOR_NAMES = {"rk45": "dopri5", "ode45": "dopri5", "dopri": "dopri5", "dp5": "dopri5", "dp45": "dopri5",
                          "rk853": "dop853", "dp8": "dop853", "dopri8": "dop853", "dopri853": "dop853"}


def integrator_of(name: str, where: str = "integrator") -> Integrator:
    """The integrator called `name` (catalog.INTEGRATORS); a ModelError naming the valid ones
    (and the closest) otherwise.  `where` labels the error (e.g. "--integrator")."""
    names = catalog.names(catalog.INTEGRATORS)
    if str(name).lower() not in names:
        ours = OTHER_INTEGRATOR_NAMES.get(str(name).lower())
        hint = (f"did you mean `{ours}`? (`{name}` in other tools);" if ours
                else did_you_mean(str(name).lower(), names))
        raise ModelError(f"unknown integrator `{name}`", where,
                         hint=(hint + " " if hint else "") + "choose " + catalog.choices(catalog.INTEGRATORS))
    return Integrator(catalog.integrator(name).code)


def _check_rows(model: Model, settings: Settings, max_rows: float) -> None:
    est = estimate(model, settings, columns=1)
    if est.rows > max_rows:
        raise ModelError(f"the run would write {est.describe()}, beyond the limit of {max_rows:,.0f} rows",
                         model.source_path, hint="check `output_step` and `t_end` (a unit typo?); pass a larger "
                         "max_rows (math.inf: no limit) to run it anyway")


def signal_selection(model: Model, signals, cfg: np.ndarray):
    """(table, kept observation columns or None) of a run that keeps `signals` (None: all), with
    cfg[CFG_SKIP] set so that the time loop computes only the groups of the row they read."""
    table, cols = signal_table(model), None
    if signals is not None:
        table, cols = select_signals(table, [signals] if isinstance(signals, str) else list(signals))
    cfg[CFG_SKIP] = skip_bits(model, cols)
    return table, cols


def select_signals(table, wanted):
    """The signals of `table` named in `wanted` (full names ``slider.x`` or whole
    entities ``slider``), with their columns renumbered onto the kept columns.
    Returns (table, kept column indices)."""
    names = {s.name for s in table}
    entities = {s.entity for s in table}
    for w in wanted:
        if w not in names and w not in entities:
            hint = did_you_mean(w, sorted(names | entities))
            raise ModelError(f"no signal or entity `{w}`" + (f"; {hint}" if hint else ""), "signals")
    keep = [s for s in table if s.name in wanted or s.entity in wanted]
    cols = sorted({c for s in keep for c in s.columns})
    where = {c: i for i, c in enumerate(cols)}
    keep = [dataclasses.replace(s, columns=tuple(where[c] for c in s.columns)) for s in keep]
    return keep, np.array(cols, dtype=np.int64)


def simulate(
    model: Model,
    output: str | Path | None = None,
    progress: Callable[[float, float], None] | None = None,
    signals: list[str] | None = None,
    max_rows: float = MAX_ROWS,
    overwrite: bool = False,
    allow_unphysical: bool = False,
    **settings_changes,
) -> Results:
    """Integrate `model` from its assembled initial state to ``t_end``.

    ``settings_changes`` override fields of the model's `simulate` block
    (``t_end``, ``integrator``, ``rtol``, ``step``, ...).  ``output`` is an HDF5
    path written in chunks during the run; ``progress(t, t_end)`` is called
    after each chunk.  ``signals`` (names like ``slider.x`` or whole entities)
    keeps only those signals in memory and in the file (default: all), and the time loop
    computes only the groups of the observation row they read (`signals.skip_bits`).
    A run asking for more than ``max_rows`` output rows (``math.inf``: no limit) is refused
    with `ModelError` before it starts (a typo in ``output_step`` would fill memory or disk).
    Raises `SimulationError` (with ``.results``) on failure.  ``output`` replaces an existing file
    only if it holds the results of a run (``overwrite=True``: any file), and never the model
    file or a file it includes.  A run whose results are not physical (a journal sunk deeper than
    its clearance: `checks.physics_warnings`) raises `SimulationError`, status ``not_physical``;
    ``allow_unphysical=True`` keeps it as a finished run instead (the ideal-limit study of
    docs/contact.md), with the warning and the attribute ``allow_unphysical`` in its results.
    """
    check_arguments(model, signals, "simulate")
    settings = run_settings(model, **settings_changes)
    check_settings(settings, given=_given(settings_changes), source=model.source_path)
    check_tolerances(settings)
    _check_rows(model, settings, max_rows)
    if output is None:
        check_memory(model, settings, "simulate without an output file")
    run = _Run(model, settings, output, signals, overwrite, allow_unphysical)
    with _deferred_interrupts() as received:
        try:
            run.loop(received, progress)
        finally:
            run.finish(received)
    return run.outcome()


def _header(model: Model, settings: Settings, allow_unphysical: bool = False) -> dict:
    """The attributes a results file starts with: the model's text, parameters and the settings
    (and ``allow_unphysical`` where the run keeps results that are not physical)."""
    extra = {"allow_unphysical": True} if allow_unphysical else {}
    if model.warnings:  # what the compiler took but warned about (a number without a unit)
        extra["model_warnings"] = list(model.warnings)
    return {**extra,
        "model_source": model.source_text,
        "model_path": model.source_path,
        "model_key": model.source_key,
        "model_includes": model.source_includes,  # every included file: `mbs view` rebuilds anywhere
        "model_tables": {p: d.decode("utf-8", "surrogateescape") for p, d in model.source_tables.items()},
        "parameters": model.parameters,
        "version": __version__,
        "settings": {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)},
        "mechanism": mechanism_facts(model),  # what plots and sections choose by, without the model
    }


class FileSink(Sink):
    """Rows written to the results file as the run goes: the kernel writes straight into the block that
    goes to the file next, which is written whole HDF5 chunks at a time (FLUSH_BYTES) or after
    FLUSH_SECONDS, whichever comes first; memory stays bounded however long the run."""

    def __init__(self, writer: ResultsWriter, nobs: int, cols, watch):
        self.writer, self.cols, self.watch = writer, cols, watch
        self.rows_held = flush_rows(nobs)
        self.out_t, self.out = np.zeros(self.rows_held), np.zeros((self.rows_held, nobs))
        self.held = 0  # rows of out_t/out not yet written
        self.room_left = self.rows_held  # rows to hold before the next write: ends it on a chunk boundary
        self.last_flush = _time.perf_counter()
        self.disk_full: list[DiskFull] = []

    def room(self):
        k = self.held
        m = min(BUFFER_ROWS, self.room_left - k)
        return self.out_t[k:k + m], self.out[k:k + m]

    def take(self, n: int) -> bool:
        self.held += n
        if self.held >= self.room_left or _time.perf_counter() - self.last_flush >= FLUSH_SECONDS:
            self.flush()
            self.room_left = self.rows_held - self.writer.n % ResultsWriter.CHUNK
            self.last_flush = _time.perf_counter()
        return bool(self.disk_full)

    def flush(self) -> None:
        """Write the rows held to the file (a full disk is noted, and ends the run)."""
        k, self.held = self.held, 0
        if k and not self.disk_full:
            block = self.out[:k] if self.cols is None else self.out[:k, self.cols]
            self.watch(block)
            try:
                self.writer.append(self.out_t[:k], block)
            except DiskFull as exc:
                self.disk_full.append(exc)


def _statistics(driver: Driver) -> dict:
    """The counters of a run, as its results' attributes."""
    stats = driver.data.stats
    return {"wall_time": driver.wall, "n_steps": int(stats[ST_STEPS]), "n_rejected": int(stats[ST_REJECTED]),
            "n_rhs": int(stats[ST_RHS]), "n_contact_events": int(stats[ST_CONTACT_EVENTS]),
            "n_outputs": int(stats[ST_OUTPUTS])}


class _Run:
    """One run of `simulate` over the `Driver`: the sink (the file, or memory without one), and the
    end of the run.  The steps: `__init__` (assemble, allocate, compile), `loop`, `finish` (the run's
    attributes, the file closed) and `outcome` (the `Results`, or the exception that carries them)."""

    def __init__(self, model: Model, settings: Settings, output, signals, overwrite: bool,
                 allow_unphysical: bool = False):
        self.model, self.settings, self.allow_unphysical = model, settings, bool(allow_unphysical)
        q, qd = assemble(model)
        check_step_count(model, settings, q, qd)  # a contact too stiff at the start to ever reach t_end
        self.changes = assembly_changes(model, q, qd, settings.rtol, settings.atol)
        self.assembly_warnings = assembly_warnings(model, q)  # a body moved or turned far: said with the run's
        cfg = settings.cfg(model.size)
        self.table, self.cols = signal_selection(model, signals, cfg)
        self.driver = Driver(model, settings, np.concatenate([q, qd]), cfg)
        self.driver.table = self.table
        self.nobs = self.driver.nobs
        self.attrs = _header(model, settings, self.allow_unphysical)
        self.writer = ResultsWriter(output, self.table, self.attrs, overwrite=overwrite,
                                    inputs=model.source_files) if output is not None else None
        self.sink = (FileSink(self.writer, self.nobs, self.cols, self.driver.watch) if self.writer
                     else MemorySink(self.nobs, self.cols, watch=self.driver.watch))

    @property
    def disk_full(self) -> list:
        return getattr(self.sink, "disk_full", [])

    def loop(self, received: list[int], progress) -> None:
        """Call the kernel until t_end, a failure, a signal (`received`) or a full disk.  One call runs
        to t_end unless its buffer fills or its work budget (CALL_SECONDS) is spent -- never to an
        intermediate t_stop, which would cut steps short."""
        t_end, clock = self.settings.t_end, self.driver.data.clock
        tick = (lambda: progress(float(clock[0]), t_end)) if progress else None
        self.driver.run(t_end, self.sink, received, tick)

    def _message(self) -> str:
        """Why the run ended, in words (before the checks of `finish` may overrule it)."""
        t = self.driver.t
        if self.disk_full:
            return f"{self.disk_full[0].message}; stopped at t = {self.t_kept:.9g} s"
        if self.interrupted:
            return f"interrupted ({signal.Signals(self.interrupted).name}) at t = {t:.9g} s"
        if self.complete:
            return "finished"
        return self.driver.failure()

    def finish(self, received: list[int]) -> None:
        """The rows held written, how the run ended (`run_attrs`) and the file closed with it; a
        finished run that is not physical, or that stopped in an absurd state, is not complete."""
        d = self.driver
        if self.writer:
            self.sink.flush()
        done = d.status == Status.DONE
        finished = done and d.t >= self.settings.t_end and not self.disk_full
        self.interrupted = received[0] if received and not finished else 0
        self.complete = done and not self.interrupted and not self.disk_full
        self.t_kept = self.writer.t_last if self.disk_full else d.t
        self.message = self._message()
        status = "disk_full" if self.disk_full else "interrupted" if self.interrupted else Status(d.status).name.lower()
        unphysical, warnings = end_warnings(self.model, self.settings, d.data.ws, d.track)
        warnings = self.assembly_warnings + warnings
        run_attrs = {"complete": self.complete, "status": status, "message": self.message, "t_reached": self.t_kept,
                     **_statistics(d), "warnings": warnings, "assembly_changes": self.changes}
        if d.absurd and not self.interrupted and not self.disk_full:
            self.complete, self.message = False, d.absurd
            run_attrs.update(complete=False, status="absurd_state", message=self.message)
        elif self.complete and unphysical and self.allow_unphysical:  # kept, as the user chose
            self.message = run_attrs["message"] = kept_unphysical(self.message)
        elif self.complete and unphysical:  # finished, but not physical: not a result to use
            self.complete = False
            self.message = not_physical(unphysical)
            run_attrs.update(complete=False, status="not_physical", message=self.message)
        self.run_attrs = run_attrs
        if self.writer:
            self.writer.close(run_attrs)

    def outcome(self) -> Results:
        """The run's `Results` (read back from the file, or from the rows kept); raises
        `RunInterrupted` or `SimulationError` carrying them when the run did not finish."""
        units = {s.name: s.unit for s in self.table}
        attrs = {**self.attrs, **self.run_attrs}
        if self.writer:
            results = FileResults(self.writer.path, "/", units, attrs)
        else:
            width = self.nobs if self.cols is None else len(self.cols)
            times, rows = self.sink.rows(width)
            results = Results(time=times, signals={s.name: s.extract(rows) for s in self.table}, units=units,
                              attrs=attrs)
        if self.interrupted:
            raise RunInterrupted(self.interrupted, results)
        if not self.complete:
            raise SimulationError(self.message, time=self.t_kept, results=results)
        return results


class Simulation:
    """A run driven step by step, for notebooks and controllers::

        sim = Simulation(model, t_end="0.1 s")      # settings as in `simulate`, with units
        sim.step("1 ms")                            # advance by a time span ...
        sim.run_until("20 ms", callback=show)       # ... or up to a time; show(sim) after each chunk
        sim.latest("slider.vx"), sim["slider.vx"], sim.time, sim.state
        sim.set_load("motor", 0.3)                  # a controller: change a force element, SI
        res = sim.run()                             # on to t_end; `Results`, as `simulate` returns

    The same `Driver` as `simulate`, called with ``t_stop`` at the end of each step: outputs stay on
    the model's output grid, plus one sample at the end of a step that falls between two grid points
    (so `latest` is the state at `t`).  Ctrl-C stops a step between two chunks (`RunInterrupted`, with
    the results so far); a numerical failure raises `SimulationError`.  ``output`` writes an HDF5 file
    as the run goes; `close` (or `run`, or leaving a ``with`` block) marks it complete or not.  Two
    Simulations of one model are independent: each has its own data (`driver.RunData`).
    ``allow_unphysical`` keeps results that are not physical, as in `simulate`.
    """

    def __init__(self, model: Model, output: str | Path | None = None, signals: list[str] | None = None,
                 overwrite: bool = False, allow_unphysical: bool = False, **settings_changes):
        check_arguments(model, signals, "Simulation")
        self.allow_unphysical = bool(allow_unphysical)  # as `simulate`'s
        self.settings = run_settings(model, **settings_changes)
        check_settings(self.settings, given=_given(settings_changes), source=model.source_path)
        check_tolerances(self.settings)
        check_memory(model, self.settings)
        self.model = model
        self.t_end = self.settings.t_end
        q, qd = assemble(model)
        check_step_count(model, self.settings, q, qd)
        self._assembly_warnings = assembly_warnings(model, q)  # as `simulate`'s
        self._loads = Loads(model)  # set_load: this run's own copy of the force elements' values
        cfg = self.settings.cfg(model.size)
        self._table, self._cols = signal_selection(model, signals, cfg)
        self._driver = Driver(self._loads.model, self.settings, np.concatenate([q, qd]), cfg)
        self._driver.table = self._table
        self._where = {s.name: s for s in self._table}
        self._failure = ""
        self._attrs = _header(model, self.settings, self.allow_unphysical)
        self._writer = ResultsWriter(output, self._table, self._attrs, overwrite=overwrite,
                                     inputs=model.source_files) if output is not None else None
        self._sink = MemorySink(self._driver.nobs, self._cols, also=self._writer, watch=self._driver.watch)
        self.output = output

    # ---------------------------------------------------------------- driving
    @property
    def t(self) -> float:
        """Simulated time reached, in seconds (between two chunks of a `run_until` the integrator
        may be up to one step ahead of the last sample handed back)."""
        return self._driver.t

    def step(self, dt) -> "Simulation":
        """Advance by `dt` (seconds, or text with units such as ``"1 ms"``)."""
        return self.run_until(self.t + _seconds(dt, "dt"))

    def run_until(self, t, callback: Callable[["Simulation"], object] | None = None) -> "Simulation":
        """Advance to time `t` (seconds or text with units).  ``callback(sim)`` runs after every
        chunk the time loop hands back (about 200 per run: a live plot, a progress line);
        if it returns True the run stops there, before `t`."""
        t_stop = _seconds(t, "t")
        check_stop(t_stop, self.t_end)
        if self._failure:
            raise SimulationError(self._failure, time=self.t, results=self.results())
        n_grid = int(math.floor(max(self.t_end, t_stop) / self.settings.output_step * (1 + 1e-12)))
        self._sink.cap = max(1, min(BUFFER_ROWS, math.ceil((n_grid + 1) / PROGRESS_SLICES)))
        if t_stop < self.t:
            return self
        tick = (lambda: callback(self)) if callback is not None else None
        with _deferred_interrupts() as received:
            status = self._driver.run(t_stop, self._sink, received, tick)
        if received:
            raise RunInterrupted(received[0], self.results())
        if self._driver.absurd or status not in (Status.BUFFER_FULL, Status.DONE):
            self._failure = self._driver.absurd or self._driver.failure()
            raise SimulationError(self._failure, time=self.t, results=self.results())
        return self

    def run(self, callback: Callable[["Simulation"], object] | None = None):
        """Advance to ``t_end`` and close; returns the `Results` (as `simulate` does)."""
        self.run_until(self.t_end, callback)
        return self.close()

    def set_load(self, name: str, value) -> None:
        """Change a force element for the rest of the run (SI): the value its catalog entry names as
        settable (the torque of a `torque`, the (fx, fy) of a `constant` force, a spring-damper's actuator)."""
        self._loads.set(name, value)

    # ---------------------------------------------------------------- reading
    @property
    def time(self) -> np.ndarray:
        """Output times so far."""
        return self._rows()[0]

    def _rows(self) -> tuple[np.ndarray, np.ndarray]:
        return self._sink.rows(self._driver.nobs if self._cols is None else len(self._cols))

    def __getitem__(self, name: str) -> np.ndarray:
        """A signal's samples so far (as `Results`)."""
        if name not in self._where:
            hint = did_you_mean(name, self._where)
            raise KeyError(f"no signal {name!r}" + (f"; {hint}" if hint else ""))
        return self._where[name].extract(self._rows()[1])

    def latest(self, name: str) -> float:
        """A signal's last sample (at `t` after a step)."""
        if name not in self._where:
            self[name]  # raises the KeyError with a hint
        if not self._sink.blocks:
            raise KeyError("no samples yet: step first")
        return float(self._where[name].extract(self._sink.blocks[-1][-1:])[0])

    @property
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Copies of the coordinates q (x, y, phi per body) and velocities q' at `t`."""
        n, y = self.model.ncoord, self._driver.data.y
        return y[:n].copy(), y[n:2 * n].copy()

    def results(self) -> Results:
        """Everything so far as `Results` (marked complete once `t_end` is reached)."""
        times, rows = self._rows()
        done = self.t >= self.t_end and not self._failure
        unphysical, warnings = end_warnings(self.model, self.settings, self._driver.data.ws, self._driver.track)
        warnings = self._assembly_warnings + warnings
        status = "done" if done else ("failed" if self._failure else "running")
        message = self._failure or ("finished" if done else f"stopped at t = {self.t:.9g} s")
        if done and unphysical and self.allow_unphysical:  # as `simulate`: kept, as the user chose
            message = kept_unphysical(message)
        elif done and unphysical:  # as `simulate`: not physical is not complete
            done, status, message = False, "not_physical", not_physical(unphysical)
        attrs = {**self._attrs, "complete": done, "status": status, "message": message, "warnings": warnings,
                 "t_reached": self.t, **_statistics(self._driver)}
        return Results(time=times, signals={s.name: s.extract(rows) for s in self._table},
                       units={s.name: s.unit for s in self._table}, attrs=attrs)

    def close(self) -> Results:
        """Finish the output file (if any) and return the `Results` so far."""
        res = self.results()
        if self._writer is not None:
            self._writer.close({k: res.attrs[k] for k in res.attrs if k not in self._attrs})
            self._writer = None
            self._sink.also = None
        return res

    def __enter__(self) -> "Simulation":
        return self

    def __exit__(self, *exc) -> bool:
        self.close()
        return False


def _seconds(value, name: str) -> float:
    """A time in seconds from a number or from text with units (``"1 ms"``)."""
    if isinstance(value, str):
        return parse_quantity(value, "time", where=f"{name}=")
    return seconds_value(value, name)
