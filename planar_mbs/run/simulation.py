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

from .. import catalog
from ..version import __version__
from ..errors import ModelError, SimulationError, did_you_mean
from ..lazy import lazy
from ..language.units import parse_quantity
from ..mechanism.kinematics import assemble, assembly_changes
from ..mechanism.model import (
    CFG_SKIP,
    CP_CLEARANCE,
    CT_MODE,
    JOINT_ROWS,
    TOUCHING,
    ST_CONTACT_EVENTS,
    ST_INFO,
    ST_OUTPUTS,
    ST_REJECTED,
    ST_RHS,
    ST_STEPS,
    N_STATS,
    ForceType,
    Integrator,
    Model,
    Settings,
    Status,
    lost_bound,
    observation_size,
)
from .first_compile import first_call
from .output_size import MAX_ROWS, estimate
from .settings_check import check_memory, check_settings, check_stop, given_settings as _given
from ..results.hdf5 import DiskFull, FileResults, Results, ResultsWriter
from ..results.section import driver_period
from ..results.signals import signal_table, skip_bits

# numba: `mbs check` and `import planar_mbs` read this module's settings without loading the kernels
kernel = lazy("..kernel", __package__)
dynamics = lazy("..kernel.dynamics", __package__)
integrators = lazy("..kernel.integrators", __package__)
workspace = lazy("..kernel.workspace", __package__)

CALL_SECONDS = 0.1  # wall time of one kernel call (a work budget in right-hand sides calibrated per call)
FIRST_BUDGET = 2000.0  # right-hand sides of the first call, before any calibration
RTOL_FLOOR = 10 * float(np.finfo(np.float64).eps)  # smallest rtol (Hairer's codes: rtol > 10 uround)
BUFFER_ROWS = 2048  # observation rows per chunk handed back by the kernel (at most)
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


def _next_budget(n_rhs: int, seconds: float, budget: float) -> float:
    """Right-hand sides for the next kernel call so that it lasts about CALL_SECONDS: the
    kernel returns to Python (signals, progress, the file) at least that often, however
    hard the run grinds between two outputs."""
    if n_rhs <= 0 or seconds <= 0.0:
        return budget
    return float(min(max(100.0, n_rhs / seconds * CALL_SECONDS), 4.0 * budget, 1e9))


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
    if isinstance(value, str):
        try:
            if name in _TIME_SETTINGS:
                return parse_quantity(value, "time", where=where)
            if name in _RATE_SETTINGS:
                return parse_quantity(value, "angular_velocity", where=where)
            value = float(value)
        except ValueError:
            raise ModelError(f"`{name}` takes a number, not `{value}`", where, hint="e.g. rtol=1e-8") from None
    if name == "max_steps":
        return int(value)
    return float(value)


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


def _state_name(model: Model, i: int) -> str:
    """Name of component i of the state y = (q, q')."""
    n = model.ncoord
    if not 0 <= i < 2 * n:
        return "?"
    b, c = divmod(i % n, 3)
    coord = ("x", "y", "angle")[c]
    return f"{'velocity' if i >= n else 'position'} {coord} of body `{model.body_names[b]}`"


def _bad_method() -> int:
    return integrators.BAD_METHOD


def _failure_message(model: Model, status: int, info: int, t: float, settings: Settings,
                     contact: np.ndarray) -> str:
    at = f"at t = {t:.9g} s"
    fault = model.kernel.expr_fault
    # a load that gave NaN in the failing step (after the last accepted time t) is the cause, also where
    # its NaN reached the constraint solve first (a jointed body: "singular")
    if 0 <= fault[0] < model.nforce and (status in (Status.NONFINITE, Status.STEP_UNDERFLOW) or
                                         (status == Status.SINGULAR and fault[1] >= t)):
        return (f"the expression of force `{model.force_names[int(fault[0])]}` gave NaN or infinity at "
                f"t = {fault[1]:.9g} s (the run stopped {at}): check it for a square root or logarithm of "
                "a negative value, or a division by zero, along the motion")
    if status == Status.STEP_UNDERFLOW:
        touching = [n for n, mode in zip(model.clearance_names, contact[:, CT_MODE]) if int(mode) == TOUCHING]
        where = f" while clearance joint{'s' if len(touching) > 1 else ''} " + ", ".join(
            f"`{n}`" for n in touching) + " in contact" if touching else ""
        limit = ""
        if catalog.INTEGRATORS[int(settings.integrator)].adaptive:
            limit = (f"; the error estimate of the {_state_name(model, info)} limited it (rtol = "
                     f"{settings.rtol:g}, atol = {settings.atol:g})")
        return (f"step size fell below h_min = {settings.h_min:g} s {at}{where}{limit}: the motion is too stiff "
                "or discontinuous here (try a looser rtol, a smaller h_min, or check the contact stiffness)")
    if status == Status.NONFINITE:
        what = f" (body `{model.body_names[info]}`)" if 0 <= info < model.nbody else ""
        return f"the state became NaN or infinite {at}{what}: the run blew up"
    if status == Status.SINGULAR:
        return f"the constraint matrix became singular {at}{_row_owner(model, info)}: a toggle or locked position"
    if status == Status.DRIFT:
        return (f"the constraints drifted beyond |C| = {dynamics.DRIFT_POSITION:g} or |C'| = {dynamics.DRIFT_VELOCITY:g} (m, rad, "
                f"per second for C') {at}{_row_owner(model, info)}: the fixed RK4 step is too long for this "
                "motion, or a singular position was crossed (use a shorter step, or dopri5/dop853)")
    if status == Status.CONSTRAINTS_LOST:
        return (f"the constraints gave way {at}{_row_owner(model, info)}: a residual beyond "
                f"{lost_bound(settings.rtol):g} of the mechanism's size ({model.size:.3g} m) or of its speed; "
                "a driver pushed past a limit position (toggle, dead centre) the mechanism cannot pass, or the "
                "tolerances are too loose for this motion (check the driver's motion, or tighten rtol)")
    if status == Status.PASSAGE:
        return (f"the fixed RK4 step cannot resolve a singular position {at} (the {_state_name(model, info)} "
                f"differs from two half steps by more than rtol = {settings.rtol:g}, atol = {settings.atol:g}): "
                "the motion would go on wrong (use a shorter step, or dopri5/dop853)")
    if status == Status.MAX_STEPS:
        return f"the step limit max_steps = {settings.max_steps} was reached {at}"
    if status == Status.CONTACT_SOLVE:
        name = model.clearance_names[info] if 0 <= info < model.nclearance else "?"
        return f"the contact law of clearance joint `{name}` found no force {at}"
    if status == Status.BAD_INPUT and info == _bad_method():
        code = int(settings.integrator)
        spec = catalog.INTEGRATORS[code] if 0 <= code < len(catalog.INTEGRATORS) else None
        why = ("has no dense output (the time loop writes its outputs and finds contact events on it)"
               if spec is not None and spec.dense == "none" else "is not one the time loop knows")
        return (f"the integrator `{spec.name if spec else code}` {why}: the run did not start "
                f"(choose {catalog.choices([s for s in catalog.INTEGRATORS if s.dense != 'none'])})")
    return f"the solver stopped with status {Status(status).name} {at}"


def _near_singular(model: Model, y: np.ndarray, t: float, y0: np.ndarray) -> str:
    """When a run stalls (step underflow, blow-up), say so if the constraint matrix has
    become nearly singular there (a toggle or locked position): its smallest relative
    singular value (mass-scaled Jacobian) fell below a tenth of the initial pose's."""
    m = kernel.constraint_rows(model.kernel)
    n = model.ncoord
    if m == 0 or not np.all(np.isfinite(y)):
        return ""

    def scaled(state, tt):
        C, Ct, g, Cq = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros((m, n))
        if kernel.constraint_eval(model.kernel, state[:n], state[n:], tt, C, Cq, Ct, g) != 0:
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
    warnings = []
    for c, name in enumerate(model.clearance_names):
        clearance = float(model.kernel.clearance_param[c, CP_CLEARANCE])
        deepest_c = deepest.get(f"{name}.penetration", -np.inf)
        if deepest_c > clearance > 0:  # (a contact between outlines has no clearance to compare with)
            warnings.append(
                f"clearance joint `{name}`: the journal sank {deepest_c * 1e6:.3g} µm into the bearing, more than "
                f"the clearance ({clearance * 1e6:.3g} µm); the contact is too soft for this clearance and "
                "the results are not physical (raise the stiffness or the clearance)")
    return warnings


def not_physical(warnings: list[str]) -> str:
    """The failure message of results with `_physics_warnings` (`simulate`, `Simulation`, `Stepper`)."""
    return "the results are not physical: " + warnings[0]


ABSURD = 1e9  # m, m/s, rad/s: beyond it no planar mechanism is being simulated (light: 3e8 m/s)


def _absurd_state(model: Model, y: np.ndarray, t: float) -> str:
    """Why the state y = (q, q') is beyond every physical bound (`ABSURD`: a position or speed of a
    billion metres, per second), or ''.  Angles are not bounded (a crank turns on and on).  A run
    in such a state only crawls (its steps shrink to the round-off of huge numbers)."""
    n = model.ncoord
    size = np.abs(y).copy()
    size[2:n:3] = 0.0  # the angles
    if np.all(size < ABSURD):
        return ""
    i = int(np.argmax(np.where(np.isfinite(size), size, np.inf)))
    what = "position" if i < n else "velocity"
    return (f"the state left every physical bound at t = {t:.9g} s: {_state_name(model, i)} = {y[i]:.3g} "
            f"(a {what} beyond {ABSURD:g} in SI units); check the initial velocities, the forces and the units")


def _projection_note(model: Model, settings: Settings, ws) -> list[str]:
    """`projection = auto` projected the state: say when and why (a singular position or redundant
    joints, a drift past the bound, a driver's motion that jumped)."""
    if settings.projection != "auto":
        return []
    return _jump_note(model, ws) + _projecting_note(ws)


def _jump_note(model: Model, ws) -> list[str]:
    jumps, t = int(ws.flags[workspace.FL_JUMPS]), float(ws.dense[workspace.DN_JUMP_AT])
    if not jumps:
        return []
    more = f" (and {jumps - 1} later time{'s' if jumps > 2 else ''})" if jumps > 1 else ""
    return [f"a driver's motion jumps in value or first derivative at t = {t:.9g} s{more}"
            f"{_row_owner(model, int(ws.flags[workspace.FL_JUMP_ROW]))}: the mechanism cannot follow it "
            "smoothly, so the positions and velocities were projected onto the new motion there, an "
            "impulsive change (projection = auto; smooth the motion with `step` or a cubic table to avoid it)"]


def _projecting_note(ws) -> list[str]:
    t = float(ws.dense[workspace.DN_PROJECT_FROM])
    if np.isnan(t):
        return []
    if ws.flags[workspace.FL_PROJECTING] == 2:
        return [f"the constraint residuals drifted past their bound at t = {t:.9g} s: the positions and "
                "velocities are projected onto the constraints from then on (projection = auto)"]
    return [f"the constraints lost rank at t = {t:.9g} s (a singular position or redundant joints): the "
            "positions and velocities are projected onto the constraints from then on (projection = auto)"]


ENERGY_PER_RTOL = 1e3  # a workless mechanism's energy may drift by this many rtol of its largest kinetic energy


def _workless(model: Model) -> bool:
    """No driver, no clearance joint, no damper, actuator or expression load (none of which has a
    potential in `kernel.forces.force_potential`): the total energy is conserved."""
    k = model.kernel
    if model.ndriver or model.nclearance:
        return False
    for typ, p in zip(k.force_type, k.force_param):
        if int(typ) == ForceType.EXPRESSION:
            return False
        if int(typ) in (ForceType.SPRING_DAMPER, ForceType.ROTATIONAL_SPRING_DAMPER) and \
                (p[1] != 0 or p[3] != 0 or p[4] != 0):  # damping, a constant or an expression actuator
            return False
    return True


def _energy_drift(table, rows: np.ndarray, track: dict[str, float]) -> None:
    """Track the total energy's first value, its largest change and the largest kinetic energy."""
    cols = {s.quantity: s.extract(rows) for s in table
            if s.entity == "system" and s.quantity in ("kinetic_energy", "potential_energy")}
    if len(cols) < 2 or not len(rows):
        return
    T, E = cols["kinetic_energy"], cols["kinetic_energy"] + cols["potential_energy"]
    if not np.all(np.isfinite(E)):
        return
    E0 = track.setdefault("energy.first", float(E[0]))
    track["energy.drift"] = max(track.get("energy.drift", 0.0), float(np.abs(E - E0).max()))
    track["energy.kinetic"] = max(track.get("energy.kinetic", 0.0), float(T.max()))


def _energy_warning(model: Model, settings: Settings, track: dict[str, float]) -> list[str]:
    """A workless mechanism whose energy drifted by more than ENERGY_PER_RTOL rtol of its largest
    kinetic energy: the motion is not to be trusted (a singular position crossed onto another
    branch, a too loose tolerance)."""
    drift, T = track.get("energy.drift", 0.0), track.get("energy.kinetic", 0.0)
    if not _workless(model) or not T > 0 or drift <= ENERGY_PER_RTOL * settings.rtol * T:
        return []
    return [f"the total energy of this mechanism, which nothing drives or damps, changed by {drift:.3g} J "
            f"({drift / T:.2g} of its largest kinetic energy, more than {ENERGY_PER_RTOL:g} rtol): the motion is "
            "not to be trusted (tighten rtol; with projection = off, a singular position may have been crossed "
            "onto another branch)"]


def _deepest(table, rows: np.ndarray, deepest: dict[str, float]) -> None:
    """Update the largest penetration of each clearance joint with a chunk of rows."""
    for s in table:
        if s.quantity == "penetration":
            x = s.extract(rows)
            x = x[np.isfinite(x)]
            if len(x):
                deepest[s.name] = max(deepest.get(s.name, -np.inf), float(x.max()))


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
    file or a file it includes.
    """
    settings = run_settings(model, **settings_changes)
    check_settings(settings, given=_given(settings_changes), source=model.source_path)
    check_tolerances(settings)
    _check_rows(model, settings, max_rows)
    run = _Run(model, settings, output, signals, overwrite)
    with _deferred_interrupts() as received:
        try:
            run.loop(received, progress)
        finally:
            run.finish(received)
    return run.outcome()


def _header(model: Model, settings: Settings) -> dict:
    """The attributes a results file starts with: the model's text, parameters and the settings."""
    return {
        "model_source": model.source_text,
        "model_path": model.source_path,
        "model_key": model.source_key,
        "model_includes": model.source_includes,  # every included file: `mbs view` rebuilds anywhere
        "parameters": model.parameters,
        "version": __version__,
        "settings": {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)},
    }


class _Run:
    """One run of `simulate`: the time loop's arrays (allocated once), the writer, the rows kept in
    memory without a file, and what the rows tell on the way (deepest penetration, energy drift).
    The steps: `__init__` (assemble, allocate, compile), `loop`, `finish` (the run's attributes,
    the file closed) and `outcome` (the `Results`, or the exception that carries them)."""

    def __init__(self, model: Model, settings: Settings, output, signals, overwrite: bool):
        self.model, self.settings, self.advance = model, settings, kernel.advance
        q, qd = assemble(model)
        self.changes = assembly_changes(model, q, qd, settings.rtol, settings.atol)
        self.y0 = np.concatenate([q, qd])
        self.km, self.cfg, self.y = model.kernel, settings.cfg(model.size), self.y0.copy()
        self.clock = np.zeros(4)  # t, h, t0, work budget of one call (right-hand sides)
        self.clock[3] = FIRST_BUDGET
        self.contact = np.zeros((model.nclearance, 3))
        self.stats = np.zeros(N_STATS, dtype=np.int64)
        self.ws = kernel.make_workspace(self.km)
        self.nobs = observation_size(model.nbody, model.njoint, model.ndriver, model.nclearance)
        # with a file, the kernel writes its rows straight into the block that goes to the file next
        self.rows_held = flush_rows(self.nobs) if output is not None else BUFFER_ROWS
        self.out_t, self.out = np.zeros(self.rows_held), np.zeros((self.rows_held, self.nobs))
        self.table, self.cols = signal_selection(model, signals, self.cfg)
        # compile (or load from the cache) outside the timed loop, on throw-away copies
        first_call(kernel.advance, self.km, self.cfg, self.y.copy(), self.clock.copy(), self.contact.copy(),
                   self.stats.copy(), self.ws, 0.0, self.out_t[:1], self.out[:1])
        self.attrs = _header(model, settings)
        self.writer = ResultsWriter(output, self.table, self.attrs, overwrite=overwrite,
                                    inputs=model.source_files) if output is not None else None
        self.times: list[np.ndarray] = []  # all rows, kept only without an output file
        self.blocks: list[np.ndarray] = []
        self.held = 0  # rows of out_t/out not yet written to the file
        self.track: dict[str, float] = {}  # deepest penetration per joint, energy drift
        self.disk_full: list[DiskFull] = []
        self.wall, self.status = 0.0, int(Status.DONE)
        self.absurd = _absurd_state(model, self.y, 0.0)  # a state beyond every physical bound: not worth a step

    def _watch(self, rows: np.ndarray) -> None:
        _deepest(self.table, rows, self.track)
        _energy_drift(self.table, rows, self.track)

    def flush(self) -> None:
        """Write the rows held to the file (a full disk is noted, and ends the loop)."""
        k, self.held = self.held, 0
        if self.writer and k and not self.disk_full:
            block = self.out[:k] if self.cols is None else self.out[:k, self.cols]
            self._watch(block)
            try:
                self.writer.append(self.out_t[:k], block)
            except DiskFull as exc:
                self.disk_full.append(exc)

    def _keep_in_memory(self, n: int) -> None:
        chunk_t = self.out_t[:n].copy()
        chunk = self.out[:n].copy() if self.cols is None else self.out[:n, self.cols]
        self._watch(chunk)
        self.times.append(chunk_t)
        self.blocks.append(chunk)

    def loop(self, received: list[int], progress) -> None:
        """Call the kernel until t_end, a failure, a signal (`received`) or a full disk.

        One call of the kernel runs to t_end unless its output buffer (BUFFER_ROWS) fills or
        its work budget (CALL_SECONDS, which bounds the time between returns: progress bar,
        Ctrl-C) is spent -- never at an intermediate t_stop, which would cut steps short.
        (Cutting calls at 1/200 of the run as well cost 0.035 us per output row.)"""
        t_end, stats, clock = self.settings.t_end, self.stats, self.clock
        last_flush = _time.perf_counter()
        room = self.rows_held  # rows to hold before the next write: ends it on a chunk boundary of the file
        while not received and not self.absurd:
            start = _time.perf_counter()
            rhs_before = int(stats[ST_RHS])
            k = self.held
            m = min(BUFFER_ROWS, room - k) if self.writer else BUFFER_ROWS
            self.status, n = self.advance(self.km, self.cfg, self.y, clock, self.contact, stats, self.ws, t_end,
                                          self.out_t[k:k + m], self.out[k:k + m])
            now = _time.perf_counter()
            self.wall += now - start
            clock[3] = _next_budget(int(stats[ST_RHS]) - rhs_before, now - start, clock[3])
            if n and self.writer:
                self.held = k + n
                if self.held >= room or now - last_flush >= FLUSH_SECONDS:
                    self.flush()
                    room = self.rows_held - self.writer.n % ResultsWriter.CHUNK
                    last_flush = _time.perf_counter()
            elif n:
                self._keep_in_memory(n)
            if progress:
                progress(float(clock[0]), t_end)
            if self.status != Status.BUFFER_FULL or self.disk_full:
                break
            self.absurd = _absurd_state(self.model, self.y, float(clock[0]))

    def _message(self) -> str:
        """Why the run ended, in words (before the checks of `finish` may overrule it)."""
        if self.disk_full:
            return f"{self.disk_full[0].message}; stopped at t = {self.t_kept:.9g} s"
        if self.interrupted:
            return f"interrupted ({signal.Signals(self.interrupted).name}) at t = {self.clock[0]:.9g} s"
        if self.complete:
            return "finished"
        t = float(self.clock[0])
        message = _failure_message(self.model, self.status, int(self.stats[ST_INFO]), t, self.settings,
                                   self.contact)
        if self.status in (Status.STEP_UNDERFLOW, Status.NONFINITE, Status.CONTACT_SOLVE):
            message += _near_singular(self.model, self.y, t, self.y0)
        return message

    def _statistics(self) -> dict:
        stats = self.stats
        status = "disk_full" if self.disk_full else "interrupted" if self.interrupted else \
            Status(self.status).name.lower()
        return {
            "complete": self.complete, "status": status, "message": self.message, "t_reached": self.t_kept,
            "wall_time": self.wall, "n_steps": int(stats[ST_STEPS]), "n_rejected": int(stats[ST_REJECTED]),
            "n_rhs": int(stats[ST_RHS]), "n_contact_events": int(stats[ST_CONTACT_EVENTS]),
            "n_outputs": int(stats[ST_OUTPUTS]),
        }

    def finish(self, received: list[int]) -> None:
        """The rows held written, how the run ended (`run_attrs`) and the file closed with it; a
        finished run that is not physical, or that stopped in an absurd state, is not complete."""
        self.flush()
        finished = self.status == Status.DONE and self.clock[0] >= self.settings.t_end and not self.disk_full
        self.interrupted = received[0] if received and not finished else 0
        self.complete = self.status == Status.DONE and not self.interrupted and not self.disk_full
        self.t_kept = self.writer.t_last if self.disk_full else float(self.clock[0])
        self.message = self._message()
        run_attrs = self._statistics()
        unphysical = _physics_warnings(self.model, self.track)
        run_attrs["warnings"] = (unphysical + _projection_note(self.model, self.settings, self.ws)
                                 + _energy_warning(self.model, self.settings, self.track))
        run_attrs["assembly_changes"] = self.changes
        if self.absurd and not self.interrupted and not self.disk_full:
            self.complete, self.message = False, self.absurd
            run_attrs.update(complete=False, status="absurd_state", message=self.message)
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
            rows = np.concatenate(self.blocks) if self.blocks else np.zeros((0, width))
            results = Results(time=np.concatenate(self.times) if self.times else np.zeros(0),
                              signals={s.name: s.extract(rows) for s in self.table}, units=units, attrs=attrs)
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

    The same compiled time loop as `simulate` (`kernel.advance`), called with ``t_stop`` at the
    end of each step: outputs stay on the model's output grid, plus one sample at the end of a
    step that falls between two grid points (so `latest` is the state at `t`).  Ctrl-C stops
    a step between two chunks (`RunInterrupted`, with the results so far); a numerical failure
    raises `SimulationError`.  ``output`` writes an HDF5 file as the run goes; `close` (or
    `run`, or leaving a ``with`` block) marks it complete or not.
    """

    def __init__(self, model: Model, output: str | Path | None = None, signals: list[str] | None = None,
                 overwrite: bool = False, **settings_changes):
        self.model = model
        self.settings = run_settings(model, **settings_changes)
        check_settings(self.settings, given=_given(settings_changes), source=model.source_path)
        check_tolerances(self.settings)
        check_memory(model, self.settings)
        self.t_end = self.settings.t_end
        q, qd = assemble(model)
        self._y0 = np.concatenate([q, qd])
        self._km = model.kernel._replace(force_param=model.kernel.force_param.copy())  # set_load: this run only
        self._cfg = self.settings.cfg(model.size)
        self._y = self._y0.copy()
        self._clock = np.zeros(3)
        self._contact = np.zeros((model.nclearance, 3))
        self._stats = np.zeros(N_STATS, dtype=np.int64)
        self._ws = kernel.make_workspace(self._km)
        nobs = observation_size(model.nbody, model.njoint, model.ndriver, model.nclearance)
        self._out_t, self._out = np.zeros(BUFFER_ROWS), np.zeros((BUFFER_ROWS, nobs))
        self._table, self._cols = signal_selection(model, signals, self._cfg)
        self._where = {s.name: s for s in self._table}
        self._times: list[np.ndarray] = []
        self._blocks: list[np.ndarray] = []
        self._wall = 0.0
        self._status = int(Status.DONE)
        self._failure = ""
        first_call(kernel.advance, self._km, self._cfg, self._y.copy(), self._clock.copy(),  # compile first
                   self._contact.copy(), self._stats.copy(), self._ws, 0.0, self._out_t[:1], self._out[:1])
        self._ws = kernel.make_workspace(self._km)
        self._attrs = {
            "model_source": model.source_text, "model_path": model.source_path, "parameters": model.parameters,
            "version": __version__,
            "settings": {f.name: getattr(self.settings, f.name) for f in dataclasses.fields(self.settings)},
        }
        self._writer = ResultsWriter(output, self._table, self._attrs, overwrite=overwrite,
                                     inputs=model.source_files) if output is not None else None
        self.output = output

    # ---------------------------------------------------------------- driving
    @property
    def t(self) -> float:
        """Simulated time reached, in seconds (between two chunks of a `run_until` the integrator
        may be up to one step ahead of the last sample handed back)."""
        return float(self._clock[0])

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
        dto = self.settings.output_step
        n_grid = int(math.floor(max(self.t_end, t_stop) / dto * (1 + 1e-12)))
        cap = max(1, min(BUFFER_ROWS, math.ceil((n_grid + 1) / PROGRESS_SLICES)))
        if t_stop < self.t:
            return self
        with _deferred_interrupts() as received:
            while not received:  # until DONE: a long step may have outputs still to hand back
                start = _time.perf_counter()
                status, n = kernel.advance(self._km, self._cfg, self._y, self._clock, self._contact, self._stats,
                                    self._ws, t_stop, self._out_t[:cap], self._out[:cap])
                self._wall += _time.perf_counter() - start
                self._status = int(status)
                if n:
                    chunk_t = self._out_t[:n].copy()
                    chunk = self._out[:n].copy() if self._cols is None else self._out[:n, self._cols]
                    self._times.append(chunk_t)
                    self._blocks.append(chunk)
                    if self._writer:
                        self._writer.append(chunk_t, chunk)
                if status not in (Status.BUFFER_FULL, Status.DONE):
                    self._failure = _failure_message(self.model, status, int(self._stats[ST_INFO]), self.t,
                                                     self.settings, self._contact)
                    raise SimulationError(self._failure, time=self.t, results=self.results())
                if callback is not None and callback(self) is True:
                    break
                if status == Status.DONE:
                    break
        if received:
            raise RunInterrupted(received[0], self.results())
        return self

    def run(self, callback: Callable[["Simulation"], object] | None = None):
        """Advance to ``t_end`` and close; returns the `Results` (as `simulate` does)."""
        self.run_until(self.t_end, callback)
        return self.close()

    def set_load(self, name: str, value) -> None:
        """Change a force element for the rest of the run (SI): the torque of a `torque`, the
        (fx, fy) of a `constant` force, the actuator of a spring-damper."""
        if name not in self.model.force_names:
            raise ModelError(f"no force element `{name}`", "set_load",
                             hint=did_you_mean(name, self.model.force_names) or
                             "forces: " + (", ".join(self.model.force_names) or "none"))
        k = self.model.force_names.index(name)
        kind = int(self._km.force_type[k])
        if kind == ForceType.CONSTANT_FORCE:
            self._km.force_param[k, :2] = np.asarray(value, dtype=float)
        elif kind == ForceType.CONSTANT_TORQUE:
            self._km.force_param[k, 0] = float(value)
        elif kind == ForceType.EXPRESSION:
            raise ModelError(f"`{name}` is an expression force: it has no value to set", "set_load",
                             hint="write the load as a `constant`, `torque` or spring-damper to set it from Python")
        elif self._km.force_param[k, 4] > 0:
            raise ModelError(f"the actuator of `{name}` is an expression: it has no value to set", "set_load",
                             hint="give the actuator a constant in the model to set it from Python")
        else:  # spring-dampers: the actuator force or torque
            self._km.force_param[k, 3] = float(value)

    # ---------------------------------------------------------------- reading
    @property
    def time(self) -> np.ndarray:
        """Output times so far."""
        return np.concatenate(self._times) if self._times else np.zeros(0)

    def _rows(self) -> np.ndarray:
        width = self._out.shape[1] if self._cols is None else len(self._cols)
        return np.concatenate(self._blocks) if self._blocks else np.zeros((0, width))

    def __getitem__(self, name: str) -> np.ndarray:
        """A signal's samples so far (as `Results`)."""
        if name not in self._where:
            hint = did_you_mean(name, self._where)
            raise KeyError(f"no signal {name!r}" + (f"; {hint}" if hint else ""))
        return self._where[name].extract(self._rows())

    def latest(self, name: str) -> float:
        """A signal's last sample (at `t` after a step)."""
        if name not in self._where:
            self[name]  # raises the KeyError with a hint
        if not self._blocks:
            raise KeyError("no samples yet: step first")
        return float(self._where[name].extract(self._blocks[-1][-1:])[0])

    @property
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Copies of the coordinates q (x, y, phi per body) and velocities q' at `t`."""
        n = self.model.ncoord
        return self._y[:n].copy(), self._y[n:].copy()

    def results(self) -> Results:
        """Everything so far as `Results` (marked complete once `t_end` is reached)."""
        rows = self._rows()
        done = self.t >= self.t_end and not self._failure
        deepest: dict[str, float] = {}
        _deepest(self._table, rows, deepest)
        warnings = _physics_warnings(self.model, deepest)  # as `simulate`: not physical is not complete
        status = "done" if done else ("failed" if self._failure else "running")
        message = self._failure or ("finished" if done else f"stopped at t = {self.t:.9g} s")
        if done and warnings:
            done, status, message = False, "not_physical", not_physical(warnings)
        attrs = {
            **self._attrs, "complete": done, "status": status, "message": message, "warnings": warnings,
            "t_reached": self.t, "wall_time": self._wall, "n_steps": int(self._stats[ST_STEPS]),
            "n_rejected": int(self._stats[ST_REJECTED]), "n_rhs": int(self._stats[ST_RHS]),
            "n_contact_events": int(self._stats[ST_CONTACT_EVENTS]), "n_outputs": int(self._stats[ST_OUTPUTS]),
        }
        return Results(time=self.time, signals={s.name: s.extract(rows) for s in self._table},
                       units={s.name: s.unit for s in self._table}, attrs=attrs)

    def close(self) -> Results:
        """Finish the output file (if any) and return the `Results` so far."""
        res = self.results()
        if self._writer is not None:
            self._writer.close({k: res.attrs[k] for k in res.attrs if k not in self._attrs})
            self._writer = None
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
    return float(value)
