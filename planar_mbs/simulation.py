"""Run a compiled model: assemble, call the compiled time loop chunk by chunk, keep the results.

(The module is `simulation`, not `simulate`, so that it never shadows the
public function `planar_mbs.simulate`.)

The time loop lives in numba (`kernel.advance`); this module only slices the
run into chunks aligned with the output grid, hands each chunk's rows to the
HDF5 writer and the progress callback, and turns integer statuses into
messages.  A failed run raises `SimulationError` and keeps everything computed
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

from . import __version__
from .errors import SimulationError
from .kinematics import assemble
from .model import (
    ST_CONTACT_EVENTS,
    ST_INFO,
    ST_OUTPUTS,
    ST_REJECTED,
    ST_RHS,
    ST_STEPS,
    N_STATS,
    Integrator,
    Model,
    Settings,
    Status,
    observation_size,
)
from .results import DiskFull, FileResults, Results, ResultsWriter
from .signals import signal_table

BUFFER_ROWS = 2048  # observation rows per chunk handed back by the kernel (at most)
PROGRESS_SLICES = 200  # the kernel returns at least this often (in outputs) for progress and Ctrl-C
FLUSH_ROWS = 65536  # rows kept in memory before they are appended to the HDF5 file ...
FLUSH_SECONDS = 1.0  # ... or after this much wall time since the last write, whichever comes first


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) or SIGTERM stopped the run between two chunks; the results
    so far are kept (``.results``, and the file closed and marked incomplete)."""

    def __init__(self, signum: int, results=None):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.results = results


@contextmanager
def _deferred_interrupts():
    """While the time loop runs, SIGINT and SIGTERM only raise a flag that the loop
    checks between chunks, so a signal can never land halfway through writing a
    chunk to the results file.  (Only the main thread may install handlers.)"""
    received: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return
    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous[sig] = signal.signal(sig, lambda signum, frame: received.append(signum))
    try:
        yield received
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def run_settings(model: Model, **changes) -> Settings:
    """The model's `simulate` settings with the given fields replaced (None = keep)."""
    changes = {k: v for k, v in changes.items() if v is not None}
    if isinstance(changes.get("integrator"), str):
        changes["integrator"] = integrator_of(changes["integrator"])
    return dataclasses.replace(model.settings, **changes)


def integrator_of(name: str, where: str = "integrator") -> Integrator:
    """The integrator called `name` (catalog.INTEGRATORS); a ModelError naming the valid ones
    (and the closest) otherwise.  `where` labels the error (e.g. "--integrator")."""
    from . import catalog
    from .errors import ModelError, did_you_mean

    names = catalog.names(catalog.INTEGRATORS)
    if str(name).lower() not in names:
        hint = did_you_mean(str(name).lower(), names)
        raise ModelError(f"unknown integrator `{name}`", where,
                         hint=(hint + " " if hint else "") + "choose " + catalog.choices(catalog.INTEGRATORS))
    return Integrator(catalog.integrator(name).code)


def _failure_message(model: Model, status: int, info: int, t: float, settings: Settings,
                     contact: np.ndarray) -> str:
    at = f"at t = {t:.9g} s"
    if status == Status.STEP_UNDERFLOW:
        touching = [n for n, mode in zip(model.clearance_names, contact[:, 0]) if mode > 0.5]
        where = f" while clearance joint{'s' if len(touching) > 1 else ''} " + ", ".join(
            f"`{n}`" for n in touching) + " in contact" if touching else ""
        return (f"step size fell below h_min = {settings.h_min:g} s {at}{where}: the motion is too stiff "
                "or discontinuous here (try a looser rtol, a smaller h_min, or check the contact stiffness)")
    if status == Status.NONFINITE:
        what = f" (body `{model.body_names[info]}`)" if 0 <= info < model.nbody else ""
        return f"the state became NaN or infinite {at}{what}: the run blew up"
    if status == Status.SINGULAR:
        return f"the constraint matrix became singular {at}{_row_owner(model, info)}: a toggle or locked position"
    if status == Status.MAX_STEPS:
        return f"the step limit max_steps = {settings.max_steps} was reached {at}"
    if status == Status.CONTACT_SOLVE:
        name = model.clearance_names[info] if 0 <= info < model.nclearance else "?"
        return f"the contact law of clearance joint `{name}` found no force {at}"
    return f"the solver stopped with status {Status(status).name} {at}"


def _near_singular(model: Model, y: np.ndarray, t: float, y0: np.ndarray) -> str:
    """When a run stalls (step underflow, blow-up), say so if the constraint matrix has
    become nearly singular there (a toggle or locked position): its smallest relative
    singular value (mass-scaled Jacobian) fell below a tenth of the initial pose's."""
    from .kernel import constraint_eval, constraint_rows

    m = constraint_rows(model.kernel)
    n = model.ncoord
    if m == 0 or not np.all(np.isfinite(y)):
        return ""

    def scaled(state, tt):
        C, Ct, g, Cq = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros((m, n))
        if constraint_eval(model.kernel, state[:n], state[n:], tt, C, Cq, Ct, g) != 0:
            return None
        return Cq * np.sqrt(model.kernel.minv)

    A, A0 = scaled(y, t), scaled(y0, 0.0)
    if A is None or A0 is None:
        return ""
    sv = np.linalg.svd(A, compute_uv=False)
    sv0 = np.linalg.svd(A0, compute_uv=False)
    ratio, ratio0 = sv[-1] / sv[0], sv0[-1] / sv0[0]
    if not ratio < 0.1 * ratio0:
        return ""
    _, _, Vt = np.linalg.svd(A.T, full_matrices=False)
    row = int(np.argmax(np.abs(Vt[-1])))  # the row that most depends on the others
    return (f"; the constraints are becoming singular there (smallest/largest singular value "
            f"{ratio:.1e}, {ratio0:.1e} at the start{_row_owner(model, row)}): a toggle or locked position")


def _row_owner(model: Model, row: int) -> str:
    from .model import JOINT_ROWS

    k = model.kernel
    for j, name in enumerate(model.joint_names):
        if k.joint_row[j] <= row < k.joint_row[j] + JOINT_ROWS[k.joint_type[j]]:
            return f" at joint `{name}`"
    for d, name in enumerate(model.driver_names):
        if k.driver_row[d] == row:
            return f" at driver `{name}`"
    return ""


def _physics_warnings(model: Model, deepest: dict[str, float]) -> list[str]:
    """Results that finished but are not physical: a journal that sank into its bearing
    deeper than the radial clearance (too soft a contact for that clearance, e.g. a
    stiffness of 1e6 N/m^1.5 or a clearance of 1 µm with steel).  ``deepest`` holds
    the largest penetration of each clearance joint over the run (`_deepest`)."""
    from .model import CP_CLEARANCE

    warnings = []
    for c, name in enumerate(model.clearance_names):
        clearance = float(model.kernel.clearance_param[c, CP_CLEARANCE])
        deepest_c = deepest.get(f"{name}.penetration", -np.inf)
        if deepest_c > clearance:
            warnings.append(
                f"clearance joint `{name}`: the journal sank {deepest_c * 1e6:.3g} µm into the bearing, more than "
                f"the clearance ({clearance * 1e6:.3g} µm); the contact is too soft for this clearance and "
                "the results are not physical (raise the stiffness or the clearance)")
    return warnings


def _deepest(table, rows: np.ndarray, deepest: dict[str, float]) -> None:
    """Update the largest penetration of each clearance joint with a chunk of rows."""
    for s in table:
        if s.quantity == "penetration":
            x = s.extract(rows)
            x = x[np.isfinite(x)]
            if len(x):
                deepest[s.name] = max(deepest.get(s.name, -np.inf), float(x.max()))


def select_signals(table, wanted):
    """The signals of `table` named in `wanted` (full names ``slider.x`` or whole
    entities ``slider``), with their columns renumbered onto the kept columns.
    Returns (table, kept column indices)."""
    from .errors import ModelError, did_you_mean

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
    **settings_changes,
) -> Results:
    """Integrate `model` from its assembled initial state to ``t_end``.

    ``settings_changes`` override fields of the model's `simulate` block
    (``t_end``, ``integrator``, ``rtol``, ``step``, ...).  ``output`` is an HDF5
    path written in chunks during the run; ``progress(t, t_end)`` is called
    after each chunk.  ``signals`` (names like ``slider.x`` or whole entities)
    keeps only those signals in memory and in the file (default: all).
    Raises `SimulationError` (with ``.results``) on failure.
    """
    from .kernel import advance, make_workspace

    settings = run_settings(model, **settings_changes)
    q, qd = assemble(model)
    km = model.kernel
    cfg = settings.cfg()
    y = np.concatenate([q, qd])
    clock = np.zeros(3)
    contact = np.zeros((model.nclearance, 3))
    stats = np.zeros(N_STATS, dtype=np.int64)
    ws = make_workspace(km)
    nobs = observation_size(model.nbody, model.njoint, model.ndriver, model.nclearance)
    out_t = np.zeros(BUFFER_ROWS)
    out = np.zeros((BUFFER_ROWS, nobs))
    table = signal_table(model)
    cols = None
    if signals is not None:
        table, cols = select_signals(table, list(signals))

    # compile (or load from the cache) outside the timed loop, on throw-away copies
    advance(km, cfg, y.copy(), clock.copy(), contact.copy(), stats.copy(), ws, 0.0, out_t[:1], out[:1])

    attrs = {
        "model_source": model.source_text,
        "model_path": model.source_path,
        "parameters": model.parameters,
        "version": __version__,
        "settings": {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)},
    }
    writer = ResultsWriter(output, table, attrs) if output is not None else None
    times, blocks = [], []  # all rows, kept only without an output file
    pending_t, pending_rows = [], []
    deepest: dict[str, float] = {}
    disk_full: list[DiskFull] = []

    def flush():
        if writer and pending_t and not disk_full:
            try:
                writer.append(np.concatenate(pending_t), np.concatenate(pending_rows))
            except DiskFull as exc:
                disk_full.append(exc)
        pending_t.clear()
        pending_rows.clear()

    # One call of the kernel runs to t_end unless its output buffer fills: the buffer
    # is sized so that it returns about PROGRESS_SLICES times per run (progress bar,
    # Ctrl-C) -- never at an intermediate t_stop, which would cut steps short.
    t_end, dt = settings.t_end, settings.output_step
    n_grid = int(math.floor(t_end / dt * (1 + 1e-12)))
    cap = max(1, min(BUFFER_ROWS, math.ceil((n_grid + 1) / PROGRESS_SLICES)))
    wall = 0.0
    status = int(Status.DONE)
    interrupted = 0
    last_flush = _time.perf_counter()
    n_pending = 0
    with _deferred_interrupts() as received:
        try:
            while not received:
                start = _time.perf_counter()
                status, n = advance(km, cfg, y, clock, contact, stats, ws, t_end, out_t[:cap], out[:cap])
                now = _time.perf_counter()
                wall += now - start
                if n:
                    chunk_t = out_t[:n].copy()
                    chunk = out[:n].copy() if cols is None else out[:n, cols]
                    _deepest(table, chunk, deepest)
                    if writer:
                        pending_t.append(chunk_t)
                        pending_rows.append(chunk)
                        n_pending += n
                        if n_pending >= FLUSH_ROWS or now - last_flush >= FLUSH_SECONDS:
                            flush()
                            n_pending = 0
                            last_flush = _time.perf_counter()
                    else:
                        times.append(chunk_t)
                        blocks.append(chunk)
                if progress:
                    progress(float(clock[0]), t_end)
                if status != Status.BUFFER_FULL or disk_full:
                    break
        finally:
            flush()
            finished = status == Status.DONE and clock[0] >= t_end and not disk_full
            interrupted = received[0] if received and not finished else 0
            complete = status == Status.DONE and not interrupted and not disk_full
            t_kept = float(clock[0])
            if disk_full:
                t_kept = writer.t_last
                message = f"{disk_full[0].message}; stopped at t = {t_kept:.9g} s"
            elif interrupted:
                message = f"interrupted ({signal.Signals(interrupted).name}) at t = {clock[0]:.9g} s"
            elif complete:
                message = "finished"
            else:
                message = _failure_message(model, status, int(stats[ST_INFO]), float(clock[0]), settings, contact)
                if status in (Status.STEP_UNDERFLOW, Status.NONFINITE, Status.CONTACT_SOLVE):
                    message += _near_singular(model, y, float(clock[0]), np.concatenate([q, qd]))
            run_attrs = {
                "complete": complete,
                "status": "disk_full" if disk_full else "interrupted" if interrupted else Status(status).name.lower(),
                "message": message,
                "t_reached": t_kept,
                "wall_time": wall,
                "n_steps": int(stats[ST_STEPS]),
                "n_rejected": int(stats[ST_REJECTED]),
                "n_rhs": int(stats[ST_RHS]),
                "n_contact_events": int(stats[ST_CONTACT_EVENTS]),
                "n_outputs": int(stats[ST_OUTPUTS]),
            }
            run_attrs["warnings"] = _physics_warnings(model, deepest)
            if writer:
                writer.close(run_attrs)
    units = {s.name: s.unit for s in table}
    if writer:
        results = FileResults(writer.path, "/", units, {**attrs, **run_attrs})
    else:
        rows = np.concatenate(blocks) if blocks else np.zeros((0, nobs if cols is None else len(cols)))
        results = Results(time=np.concatenate(times) if times else np.zeros(0),
                          signals={s.name: s.extract(rows) for s in table}, units=units,
                          attrs={**attrs, **run_attrs})
    if interrupted:
        raise RunInterrupted(interrupted, results)
    if not complete:
        raise SimulationError(message, time=t_kept, results=results)
    return results
