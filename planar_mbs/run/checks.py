"""The checks of a run, read by its one driver (`driver.Driver`) and the runs over it: why the time
loop stopped (`failure_message`), results that finished but are not physical (`physics_warnings`), a
state beyond every physical bound (`absurd_state`), and the notes a finished run carries (the
projection turned on, an energy drift: `end_warnings`)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .. import catalog
from ..errors import ModelError
from ..lazy import lazy
from ..mechanism.model import ABSURD_STATE, CP_CLEARANCE, CT_MODE, JOINT_ROWS, ST_INFO, TOUCHING, Model, \
    Settings, Status, lost_bound

# numba: `mbs check` and `import planar_mbs` read this module without loading the kernels
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from .. import kernel
    from ..kernel import dynamics
    from ..kernel import integrators
    from ..kernel import workspace
else:  # each loaded on its first use (see the comments: not on the light paths)
    kernel = lazy("..kernel", __package__)
    dynamics = lazy("..kernel.dynamics", __package__)
    integrators = lazy("..kernel.integrators", __package__)
    workspace = lazy("..kernel.workspace", __package__)


def state_name(model: Model, i: int) -> str:
    """Name of component i of the state y = (q, q')."""
    n = model.ncoord
    if 2 * n <= i < 2 * n + model.nstate:
        return f"bristle deflection {i - 2 * n} of the LuGre contacts"
    if not 0 <= i < 2 * n:
        return "?"
    b, c = divmod(i % n, 3)
    coord = ("x", "y", "angle")[c]
    return f"{'velocity' if i >= n else 'position'} {coord} of body `{model.body_names[b]}`"


def _bad_method() -> int:
    return integrators.BAD_METHOD


def failure_message(model: Model, settings: Settings, status: int, data, y0: np.ndarray | None = None) -> str:
    """Why the time loop stopped with `status` at the time of `data` (a `driver.RunData`), in words: the
    element involved, the time, and what to try; near a singular position (measured against the
    start `y0`) it says so."""
    t, info = data.t, int(data.stats[ST_INFO])
    if status == Status.ABSURD:  # the time loop stopped at the first accepted state beyond the bound
        return absurd_state(model, data.y, t) or f"the state left every physical bound at t = {t:.9g} s"
    message = _status_message(model, settings, status, info, t, data.contact, data.ws.xfault)
    if y0 is not None and status in (Status.STEP_UNDERFLOW, Status.NONFINITE, Status.CONTACT_SOLVE):
        message += near_singular(model, data.y, t, y0)
    return message


def _status_message(model: Model, settings: Settings, status: int, info: int, t: float, contact: np.ndarray,
                    fault: np.ndarray) -> str:
    at = f"at t = {t:.9g} s"
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
            limit = (f"; the error estimate of the {state_name(model, info)} limited it (rtol = "
                     f"{settings.rtol:g}, atol = {settings.atol:g})")
        return (f"step size fell below h_min = {settings.h_min:g} s {at}{where}{limit}: the motion is too stiff "
                "or discontinuous here (try a looser rtol, a smaller h_min, or check the contact stiffness)")
    if status == Status.NONFINITE:
        what = f" (body `{model.body_names[info]}`)" if 0 <= info < model.nbody else ""
        return f"the state became NaN or infinite {at}{what}: the run blew up"
    if status == Status.SINGULAR:
        return f"the constraint matrix became singular {at}{row_owner(model, info)}: a toggle or locked position"
    if status == Status.DRIFT:
        return (f"the constraints drifted beyond |C| = {dynamics.DRIFT_POSITION:g} or |C'| = {dynamics.DRIFT_VELOCITY:g} (m, rad, "
                f"per second for C') {at}{row_owner(model, info)}: the fixed RK4 step is too long for this "
                "motion, or a singular position was crossed (use a shorter step, or dopri5/dop853)")
    if status == Status.CONSTRAINTS_LOST:
        return (f"the constraints gave way {at}{row_owner(model, info)}: a residual beyond "
                f"{lost_bound(settings.rtol):g} of the mechanism's size ({model.size:.3g} m) or of its speed; "
                "a driver pushed past a limit position (toggle, dead centre) the mechanism cannot pass, or the "
                "tolerances are too loose for this motion (check the driver's motion, or tighten rtol)")
    if status == Status.PASSAGE:
        return (f"the fixed RK4 step cannot resolve a singular position {at} (the {state_name(model, info)} "
                f"differs from two half steps by more than rtol = {settings.rtol:g}, atol = {settings.atol:g}): "
                "the motion would go on wrong (use a shorter step, or dopri5/dop853)")
    if status == Status.MAX_STEPS:
        return f"the step limit max_steps = {settings.max_steps} was reached {at}"
    if status == Status.JOINT_FRICTION:
        name = model.jfriction_names[info] if 0 <= info < model.njfriction else "?"
        return (f"the friction of joint `{name}` found no torque {at}: its friction torque changes its "
                f"own reaction more than it holds (mu r too large for the mechanism; docs/contact.md, "
                f"\"Friction in ideal joints\")")
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


def near_singular(model: Model, y: np.ndarray, t: float, y0: np.ndarray) -> str:
    """When a run stalls (step underflow, blow-up), say so if the constraint matrix has
    become nearly singular there (a toggle or locked position): its smallest relative
    singular value (mass-scaled Jacobian) fell below a tenth of the initial pose's."""
    m = kernel.constraint_rows(model.kernel)
    n = model.ncoord
    if m == 0 or not np.all(np.isfinite(y)):
        return ""

    def scaled(state, tt):
        C, Ct, g, Cq = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros((m, n))
        if kernel.constraint_eval(model.kernel, state[:n], state[n:2 * n], tt, C, Cq, Ct, g) != 0:
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
            f"{ratio:.1e}, {ratio0:.1e} at the start{row_owner(model, row)}): a toggle or locked position")


def row_owner(model: Model, row: int) -> str:
    k = model.kernel
    for j, name in enumerate(model.joint_names):
        if k.joint_row[j] <= row < k.joint_row[j] + JOINT_ROWS[k.joint_type[j]]:
            return f" at joint `{name}`"
    for d, name in enumerate(model.driver_names):
        if k.driver_row[d] == row:
            return f" at driver `{name}`"
    return ""


def physics_warnings(model: Model, deepest: dict[str, float]) -> list[str]:
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
    """The failure message of results with `physics_warnings` (`simulate`, `Simulation`, `Stepper`)."""
    return "the results are not physical: " + warnings[0]


def kept_unphysical(message: str) -> str:
    """The message of a finished run whose results are not physical, kept by ``allow_unphysical``."""
    return f"{message}; the results are not physical, kept as asked (allow_unphysical)"


ABSURD = ABSURD_STATE  # m, m/s, rad/s: beyond it no planar mechanism is being simulated (light: 3e8 m/s)


def absurd_state(model: Model, y: np.ndarray, t: float) -> str:
    """Why the state y = (q, q') is beyond every physical bound (`ABSURD`: a position or speed of a
    billion metres, per second), or ''.  Angles are not bounded (a crank turns on and on).  A run
    in such a state only crawls (its steps shrink to the round-off of huge numbers), or finishes
    with infinite energies: the time loop stops at the first accepted step beyond it
    (`Status.ABSURD`), and the driver checks the state it hands back after every call."""
    n = model.ncoord
    size = np.abs(y).copy()
    size[2:n:3] = 0.0  # the angles
    if np.all(size < ABSURD):
        return ""
    i = int(np.argmax(np.where(np.isfinite(size), size, np.inf)))
    what = "position" if i < n else "velocity"
    return (f"the state left every physical bound at t = {t:.9g} s: {state_name(model, i)} = {y[i]:.3g} "
            f"(a {what} beyond {ABSURD:g} in SI units); check the initial velocities, the forces and the units, "
            "or the step (a fixed step too long for a stiff element blows the state up)")


def projection_note(model: Model, settings: Settings, ws) -> list[str]:
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
            f"{row_owner(model, int(ws.flags[workspace.FL_JUMP_ROW]))}: the mechanism cannot follow it "
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


def known_force_kinds(model: Model) -> None:
    """Every force element of `model` is a kind the catalog describes (ModelError otherwise: a model
    built by hand, or by another version, with a code the kernel would refuse mid-run)."""
    for name, code in zip(model.force_names, model.kernel.force_type):
        try:
            catalog.force_kind(int(code))
        except ValueError as exc:
            raise ModelError(f"force `{name}`: {exc}", model.source_path or "model",
                             hint="compile the model with this version of planar_mbs") from None


def _workless(model: Model) -> bool:
    """No driver, no clearance joint, no joint friction, and every force element one with a potential whose
    dissipative columns (damping, an actuator: `catalog.ForceSpec.dissipative`) are zero: the total energy is
    conserved.  An unknown force kind is an error (`catalog.force_kind`), never counted as workless."""
    k = model.kernel
    if model.ndriver or model.nclearance or model.njfriction:
        return False
    for code, p in zip(k.force_type, k.force_param):
        spec = catalog.force_kind(int(code))
        if not spec.potential or any(p[spec.column(c)] != 0 for c in spec.dissipative):
            return False
    return True


def energy_drift(table, rows: np.ndarray, track: dict[str, float]) -> None:
    """Track the energy balance's largest magnitude and the run's energy scale (`energy_scale`)."""
    want = ("kinetic_energy", "input_work", "dissipated", "energy_balance")
    cols = {s.quantity: s.extract(rows) for s in table if s.entity == "system" and s.quantity in want}
    if len(cols) < len(want) or not len(rows):
        return
    balance = cols["energy_balance"]
    if not np.all(np.isfinite(balance)):
        return
    scale = np.maximum(np.maximum(cols["kinetic_energy"], np.abs(cols["input_work"])), np.abs(cols["dissipated"]))
    track["energy.balance"] = max(track.get("energy.balance", 0.0), float(np.abs(balance).max()))
    track["energy.scale"] = max(track.get("energy.scale", 0.0), float(scale.max()))


BALANCE_PER_RTOL = 100.0  # the energy balance may be off by this many rtol of the run's energy scale


def energy_bound(settings: Settings, scale: float) -> float:
    """The largest |energy balance| (J) a run keeps without a warning: BALANCE_PER_RTOL rtol of its energy
    scale (the largest kinetic energy, input work or dissipated energy of the run)."""
    return BALANCE_PER_RTOL * settings.rtol * scale


def _energy_warning(model: Model, settings: Settings, track: dict[str, float]) -> list[str]:
    """A run whose energy balance (`system.energy_balance`: T + V - (T + V)(0) - input work + dissipated)
    is off by more than `energy_bound`: the motion is not to be trusted (too loose a tolerance for its
    impacts, a singular position crossed onto another branch)."""
    off, scale = track.get("energy.balance", 0.0), track.get("energy.scale", 0.0)
    if not scale > 0 or off <= energy_bound(settings, scale):
        return []
    what = ("the total energy of this mechanism, which nothing drives or damps, changed by" if _workless(model)
            else "the energy balance does not close: the total energy less the work of the loads and drivers, "
                 "plus the energy the contacts dissipated, changed by")
    return [f"{what} {off:.3g} J ({off / scale:.2g} of the run's energy scale, {scale:.3g} J; more than "
            f"{BALANCE_PER_RTOL:g} rtol): the motion is not to be trusted (tighten rtol; with projection = off, "
            "a singular position may have been crossed onto another branch)"]


def deepest_penetration(table, rows: np.ndarray, deepest: dict[str, float]) -> None:
    """Update the largest penetration of each clearance joint with a chunk of rows."""
    for s in table:
        if s.quantity == "penetration":
            x = s.extract(rows)
            x = x[np.isfinite(x)]
            if len(x):
                deepest[s.name] = max(deepest.get(s.name, -np.inf), float(x.max()))


def end_warnings(model: Model, settings: Settings, ws, track: dict[str, float]) -> tuple[list[str], list[str]]:
    """(not physical, every warning) of a finished or stopped run from what its rows showed (`track`)."""
    unphysical = physics_warnings(model, track)
    return unphysical, unphysical + projection_note(model, settings, ws) + _energy_warning(model, settings, track)
