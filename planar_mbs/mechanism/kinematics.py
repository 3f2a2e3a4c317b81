"""Initial conditions: move the user's approximate pose onto the constraints.

What the model states is kept unless an ideal joint or a driver forbids it.
A clearance joint that closes a loop of the mechanism (it lies on a cycle of
the joint graph, as in a slider-crank) starts, unless told otherwise, with its
journal centred and at rest relative to the bearing (Muvengei et al. §III.A:
the run starts from the ideal-joint kinematics), so for assembly it is an
ideal revolute joint.  Its ``offset`` (journal centre minus bearing centre,
bearing frame) and ``relative_velocity``, when given, are assembled instead.
A translational clearance joint that closes a loop holds its block centred in
the guide, at the angle, angular velocity and velocity across the guide that
the bodies state (the block is free to turn and to move across: nothing
forbids them), or at its ``offset``, ``tilt``, ``relative_velocity`` and
``tilt_rate`` where given (`slide_joints`).
A clearance joint that closes no loop (a journal held by nothing else) adds no
rows: the journal keeps the position and velocity it is given.  Positions are
found by Newton–Raphson with minimum-norm corrections (the assembled pose is
the one closest to what the user wrote), velocities by the minimum-norm
correction of the user's velocities onto ``Cq q' = -Ct`` (and the clearance
rows' ``P_i' - P_j' = -A_i v_rel``).  `assembly_changes` says what moved.

Redundant or singular constraints are found by adding the joints' rows one at a
time and watching the rank of ``Cq``; the joints that add no rank are named.
A redundant joint is accepted (the solver splits its reaction, docs/signals.md);
a redundant driver is an error (it repeats or contradicts a prescribed motion).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import re

import numpy as np

from ..errors import ModelError
from ..lazy import lazy
from .portable import LARGE_ROWS, envelope_factor, matvec, min_norm_step, rotate
from .model import (CP_BREAKDOWN, CP_CLEARANCE, CP_KIND, CP_NX, CP_NY, CP_R_BEARING, CP_R_JOURNAL, JOINT_ROWS,
                    JP_PHI0, JointType, KernelModel, Model, PairKind)

# the constraint kernels' source run as plain Python (20 ms to import): only an assembly needs it
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from ..pykernel import constraints as pyconstraints
else:  # each loaded on its first use (see the comments: not on the light paths)
    pyconstraints = lazy("..pykernel.constraints", __package__)

MAX_NEWTON = 50
POSITION_TOL = 1e-12  # m (and rad): residual of C at an assembled pose
RANK_TOL = 1e-9  # singular values below this x the largest count as zero


def clearly_full_rank(Cq: np.ndarray) -> bool:
    """Whether Cq (LARGE_ROWS rows or more) has full row rank by its envelope factor, every row's
    remainder above `portable.CLEAR` of the largest row (far above RANK_TOL): the O(m n²) SVD of a
    thousand-body model took seconds, the envelope factor a fraction of one.  A nearer row is left to
    the SVD."""
    return Cq.shape[0] >= LARGE_ROWS and envelope_factor(Cq) is not None


def clearance_start(model: Model) -> np.ndarray:
    """(nclearance, 4): offset (x, y) and relative velocity (x, y) as written, NaN where not given."""
    cs = model.clearance_start
    if cs is None or len(cs) != model.nclearance:
        return np.full((model.nclearance, 4), np.nan)
    return np.asarray(cs, dtype=np.float64)


def closes_loop(model: Model) -> list[bool]:
    """For each clearance joint: does it lie on a cycle of the graph whose nodes are the
    bodies and the ground and whose edges are all joints, clearance joints and drivers?
    (Not a bridge: without it, its two bodies are still connected.)"""
    k = model.kernel
    nb = model.nbody
    edges = [tuple(b) for b in np.asarray(k.joint_body)] + [tuple(b) for b in np.asarray(k.driver_body)]
    holds = [a[0] != "none" for a in _assembly_of(model)]  # a contact holds nothing; a translational
    clear = [tuple(b) if h else (-1, -1) for b, h in zip(np.asarray(k.clearance_body), holds)]  # joint: 1 edge
    out = []
    for c, (a, b) in enumerate(clear):
        parent = list(range(nb + 1))

        def find(x):
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        for i, j in edges + clear[:c] + clear[c + 1:]:
            parent[find(int(i) % (nb + 1))] = find(int(j) % (nb + 1))  # ground (-1) -> node nb
        out.append(find(int(a) % (nb + 1)) == find(int(b) % (nb + 1)))
    return out


def _assembly_of(model: Model) -> list[tuple]:
    """How the assembly treats each clearance element (`Model.clearance_assembly`; all revolute
    when the model does not say)."""
    a = list(model.clearance_assembly or [])
    return a if len(a) == model.nclearance else [("revolute",)] * model.nclearance


def revolute_clearances(model: Model) -> list[int]:
    """The clearance elements that assemble as revolute joints (journals in bearings)."""
    return [c for c, a in enumerate(_assembly_of(model)) if a[0] == "revolute"]


NOT_GIVEN = (np.nan,) * 4  # a translational clearance joint's (offset, tilt, relative_velocity, tilt_rate)


def slide_joints(model: Model) -> list[tuple]:
    """The translational clearance joints the assembly holds as translational joints: those that close
    a loop, and those given an initial `offset`, `tilt` or velocity; each as its assembly tuple
    (`Model.clearance_assembly`) with its stated initial state (offset, tilt, relative_velocity,
    tilt_rate; NaN where not given) last."""
    loop = closes_loop(model)
    out = []
    for c, a in enumerate(_assembly_of(model)):
        if a[0] != "translational":
            continue
        start = tuple(a[8]) if len(a) > 8 else NOT_GIVEN
        if loop[c] or not np.all(np.isnan(start)):
            out.append((*a[:8], start, loop[c]))
    return out


def _guide_frame(q: np.ndarray, a: tuple):
    """(P_i, P_j, n_i) of a translational clearance joint at pose q: its guide and block points and the
    guide's left normal, in the ground frame."""
    (bi, bj), pts = a[1:3], (a[3], a[4])
    ends = []
    for b, p in zip((bi, bj), pts):
        phi = q[3 * b + 2] if b >= 0 else 0.0
        ends.append((q[3 * b:3 * b + 2] if b >= 0 else np.zeros(2)) + rotate(phi, p))
    phi_i = q[3 * bi + 2] if bi >= 0 else 0.0
    n = rotate(phi_i, (-a[5][1], a[5][0]))  # A_i (-u_y, u_x)
    return ends[0], ends[1], n


def _slide_rows(model: Model, sl: list[tuple]) -> tuple[np.ndarray, np.ndarray]:
    """(phi0, across offset) of each slide's assembly rows: the `tilt` given, else the relative angle the
    pose states; the `offset` given, else 0 (centred) where it closes a loop, else as the pose states."""
    q0 = np.asarray(model.q0, dtype=np.float64)
    phi0, across = np.zeros(len(sl)), np.zeros(len(sl))
    for s, a in enumerate(sl):
        (bi, bj), (offset, tilt, _, _), loop = a[1:3], a[8], a[9]
        stated = (q0[3 * bj + 2] if bj >= 0 else 0.0) - (q0[3 * bi + 2] if bi >= 0 else 0.0)
        phi0[s] = stated if np.isnan(tilt) else tilt
        if not np.isnan(offset):
            across[s] = offset
        elif not loop:
            pi, pj, n = _guide_frame(q0, a)
            across[s] = float(n @ (pj - pi))
    return phi0, across


def assembly_kernel(model: Model, use=None, offset=None, slides=True) -> tuple[KernelModel, list[str]]:
    """The model's kernel arrays with the clearance joints `use` (default: every revolute one) turned
    into revolute joints whose bearing point is shifted by `offset` (bearing frame; default 0), with
    `slides` the translational clearance joints of `slide_joints` turned into translational joints (the
    block at its offset across the guide and its tilt: `_slide_rows`), and the name of the element
    behind each constraint row."""
    k = model.kernel
    use = revolute_clearances(model) if use is None else list(use)
    slides = slide_joints(model) if slides else []
    ns = len(slides)
    nc = len(use)
    cpoint = np.array(np.asarray(k.clearance_point)[use], dtype=np.float64).reshape(nc, 2, 2)
    if offset is not None and nc:
        cpoint[:, 0, :] += np.asarray(offset, dtype=np.float64)[use]
    spar = np.zeros((ns, k.joint_param.shape[1]))
    spar[:, JP_PHI0], across = _slide_rows(model, slides)
    spoint = np.array([(a[3], a[4]) for a in slides], dtype=np.float64).reshape(ns, 2, 2)
    spoint[:, 0, :] += across[:, None] * np.array([(-a[5][1], a[5][0]) for a in slides]).reshape(ns, 2)
    jt = np.concatenate([k.joint_type, np.full(ns, int(JointType.TRANSLATIONAL), dtype=np.int64),
                         np.full(nc, int(JointType.REVOLUTE), dtype=np.int64)])
    jb = np.concatenate([k.joint_body, np.array([a[1:3] for a in slides], dtype=np.int64).reshape(ns, 2),
                         np.asarray(k.clearance_body)[use].reshape(nc, 2)]).astype(np.int64)
    jp = np.concatenate([k.joint_point, spoint, cpoint])
    ja = np.concatenate([k.joint_axis, np.array([a[5] for a in slides], dtype=np.float64).reshape(ns, 2),
                         np.tile([1.0, 0.0], (nc, 1))])
    jpar = np.concatenate([k.joint_param, spar, np.zeros((nc, k.joint_param.shape[1]))])
    rows = JOINT_ROWS[jt]
    jrow = np.concatenate([[0], np.cumsum(rows)[:-1]]).astype(np.int64) if len(jt) else np.zeros(0, np.int64)
    ndr = len(k.driver_type)
    drow = (int(rows.sum()) + np.arange(ndr)).astype(np.int64)
    km = k._replace(
        joint_type=np.ascontiguousarray(jt, dtype=np.int64),
        joint_body=np.ascontiguousarray(jb),
        joint_point=np.ascontiguousarray(jp, dtype=np.float64),
        joint_axis=np.ascontiguousarray(ja, dtype=np.float64),
        joint_param=np.ascontiguousarray(jpar, dtype=np.float64),
        joint_row=jrow,
        driver_row=drow,
        clearance_body=np.zeros((0, 2), np.int64),
        clearance_point=np.zeros((0, 2, 2)),
        clearance_law=np.zeros(0, np.int64),
        clearance_param=np.zeros((0, k.clearance_param.shape[1])),
    )
    owners = []
    names = list(model.joint_names) + [a[7] for a in slides] + [model.clearance_names[c] for c in use]
    for name, r in zip(names, rows):
        owners += [name] * int(r)
    owners += list(model.driver_names)
    return km, owners


def _evaluate(km: KernelModel, q, qd, t, m):
    """C, Cq, Ct at (q, q', t) from the constraint kernels' source run as plain Python
    (`planar_mbs.pykernel`): assembly, and so `mbs check`, loads no numba.  A division by
    zero gives non-finite values (as the compiled kernels' numpy error model does)."""
    n = len(q)
    C, Ct, gamma = np.zeros(m), np.zeros(m), np.zeros(m)
    Cq = np.zeros((m, n))
    with np.errstate(all="ignore"):
        try:
            pyconstraints.constraint_eval(km, q, qd, t, C, Cq, Ct, gamma)
        except ZeroDivisionError:
            C[:] = np.nan
    return C, Cq, Ct


def _dependent_rows(Cq: np.ndarray, owners: list[str], sv=None) -> list[str]:
    """Names of the elements whose rows do not raise the rank of Cq (in order).

    Full rank (the usual case) is settled by one SVD; otherwise the rows are
    orthogonalised one by one (Gram-Schmidt, twice for accuracy) against those kept,
    O(m r n) instead of one SVD per row."""
    if sv is None:
        sv = np.linalg.svd(Cq, compute_uv=False)
    scale = max(sv[0] if len(sv) else 0.0, 1.0)
    tol = RANK_TOL * scale
    if np.count_nonzero(sv > tol) == Cq.shape[0]:
        return []
    bad, basis = [], np.zeros((0, Cq.shape[1]))
    for i, row in enumerate(Cq):
        r = row.astype(np.float64).copy()
        for _ in range(2):
            r -= basis.T @ (basis @ r)
        norm = np.linalg.norm(r)
        if norm > tol:
            basis = np.vstack([basis, r / norm])
        elif owners[i] not in bad:
            bad.append(owners[i])
    return bad


def _where(model: Model) -> dict:
    """Element name → its SourceRef."""
    where = {}
    for names, refs in ((model.body_names, model.body_source), (model.joint_names, model.joint_source),
                        (model.clearance_names, model.clearance_source),
                        (model.driver_names, model.driver_source)):
        where.update(zip(names, refs))
    return where


def _model_error(model: Model, message: str, names: list[str], hint: str) -> ModelError:
    """Point at the first named element's line (at its name when it is on that line)."""
    where = _where(model)
    src = next((where[n] for n in names if n in where), None)
    if src is None:
        return ModelError(message, model.source_path, hint=hint)
    line = None
    if src.file == model.source_path and model.source_text:
        lines = model.source_text.splitlines()
        line = lines[src.line - 1] if 0 < src.line <= len(lines) else None
    if line is None:
        return ModelError(message, src.file, src.line, src.column, hint=hint)
    name = next(n for n in names if n in where)
    column, width = src.column, 1
    m = re.search(r"(?<!\w)" + re.escape(name) + r"(?!\w)", line[src.column - 1:])
    if m is not None:
        column, width = src.column + m.start(), len(name)
    return ModelError(message, src.file, src.line, column, hint=hint, source_line=line, width=width)


def _isolated_bodies(model: Model) -> list[str]:
    """Bodies that nothing acts on: no joint, clearance joint, driver or force refers to
    them and there is no gravity.  (A free body under gravity, or pushed by a force, is
    a legitimate model: it flies.)"""
    k = model.kernel
    if np.any(k.gravity != 0):
        return []
    used = set()
    for arr in (k.joint_body, k.clearance_body, k.driver_body, k.force_body):
        used.update(int(b) for b in np.asarray(arr).ravel() if b >= 0)
    beam = np.asarray(k.body_beam)
    if beam.size:  # a beam's node bodies are held together by the beam: one of them used, all are
        tied = {int(beam[b]) for b in used if beam[b] >= 0}
        used.update(b for b in range(beam.size) if beam[b] in tied)
    return [n for b, n in enumerate(model.body_names) if b not in used]


def _positions(model: Model, km: KernelModel, owners: list[str], q, qd, t: float, m: int) -> None:
    """Newton-Raphson of the position rows (q in place), then the closure and rank checks."""
    for _ in range(MAX_NEWTON):
        C, Cq, _ = _evaluate(km, q, qd, t, m)
        if not np.all(np.isfinite(C)):
            break
        if np.max(np.abs(C)) < POSITION_TOL:
            break
        q += min_norm_step(Cq, -C, RANK_TOL)
    C, Cq, Ct = _evaluate(km, q, qd, t, m)
    finite = bool(np.all(np.isfinite(Cq)))
    full = finite and clearly_full_rank(Cq)
    if finite and not full:  # singular values for the rank test
        sv = np.linalg.svd(Cq, compute_uv=False)
    if not finite or not np.all(np.isfinite(C)) or np.max(np.abs(C)) > 1e-9:
        worst = int(np.argmax(np.abs(np.nan_to_num(C, nan=np.inf))))
        gap = (f"stays open by {abs(C[worst]):.3g} (m or rad)" if np.isfinite(C[worst])
               else "cannot be closed (the Newton iteration diverged)")
        raise _model_error(
            model,
            f"the initial pose cannot be assembled: joint `{owners[worst]}` {gap} after "
            f"{MAX_NEWTON} Newton iterations",
            [owners[worst]],
            "check the joint points and the bodies' `position`/`angle`; the mechanism may not "
            "close with these lengths",
        )
    dependent = [] if full else _dependent_rows(Cq, owners, sv)
    drivers = [n for n in dependent if n in set(model.driver_names)]
    if drivers:
        raise _model_error(
            model,
            "redundant or conflicting driver: " + ", ".join(f"`{n}`" for n in drivers) + " prescribes a motion "
            "the joints and the other drivers already fix",
            drivers,
            "remove it, or drive another coordinate (or move the initial pose off a singular, toggle position)",
        )


def assemble(model: Model, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Consistent (q, q') at time t from the user's pose ``model.q0`` and velocities ``model.qd0``."""
    isolated = _isolated_bodies(model)
    if isolated:
        names = ", ".join(f"`{n}`" for n in isolated)
        raise _model_error(
            model,
            f"body {names} is connected to nothing: no joint, driver or force acts on it and there is "
            "no gravity" if len(isolated) == 1 else
            f"bodies {names} are connected to nothing: no joint, driver or force acts on them and "
            "there is no gravity",
            isolated,
            f"connect it, e.g. `joint pin = revolute(ground (0, 0), {isolated[0]})`, or remove it; a body "
            "meant to fly free needs gravity or a force",
        )
    start = clearance_start(model)
    loop = closes_loop(model)
    has_offset = ~np.isnan(start[:, 0])
    has_vel = ~np.isnan(start[:, 2])
    revolute = revolute_clearances(model)
    pos_use = [c for c in revolute if loop[c] or has_offset[c]]
    vel_use = [c for c in revolute if c in pos_use or has_vel[c]]
    km, owners = assembly_kernel(model, pos_use, np.nan_to_num(start[:, :2]))
    m = len(owners)
    q = model.q0.astype(np.float64).copy()
    qd = model.qd0.astype(np.float64).copy()
    if m == 0 and not vel_use:
        return q, qd
    if m:
        _positions(model, km, owners, q, qd, t, m)
    # velocities: ideal rows and the (unshifted) revolute rows of the clearance joints in vel_use,
    # whose P_i' - P_j' is -A_i v_rel (v_rel in the bearing's frame; 0 when not given)
    kv, owners_v = assembly_kernel(model, vel_use)
    mv = len(owners_v)
    _, Cqv, Ctv = _evaluate(kv, q, qd, t, mv)
    target = -Ctv
    r0 = mv - model.ndriver - 2 * len(vel_use)
    k = model.kernel
    for i, c in enumerate(vel_use):
        v = np.nan_to_num(start[c, 2:])
        bi = int(k.clearance_body[c, 0])
        phi = q[3 * bi + 2] if bi >= 0 else 0.0
        target[r0 + 2 * i:r0 + 2 * i + 2] = -rotate(phi, v)
    _slide_velocities(model, Cqv, target, qd)
    return q, qd + min_norm_step(Cqv, target - matvec(Cqv, qd), RANK_TOL)


def _slide_velocities(model: Model, Cqv: np.ndarray, target: np.ndarray, qd: np.ndarray) -> None:
    """The targets of the slides' velocity rows (after the ideal joints' rows): the block's `tilt_rate`
    and `relative_velocity` across the guide where given, else what the stated velocities give (so the
    assembly keeps them: the block is free to turn and to move across its guide)."""
    r = int(JOINT_ROWS[np.asarray(model.kernel.joint_type, dtype=np.int64)].sum())
    for s, a in enumerate(slide_joints(model)):
        _, _, vel, rate = a[8]
        for row, given in ((r + 2 * s, rate), (r + 2 * s + 1, vel)):  # the angle row, then the axis row
            target[row] = float((Cqv[row] * qd).sum()) if np.isnan(given) else given


def assembly_changes(model: Model, q: np.ndarray, qd: np.ndarray, rtol: float | None = None,
                     atol: float | None = None) -> list[str]:
    """What the assembly changed in the model's stated initial state, as at most two lines:
    the bodies it moved (pose corrections beyond the integrator's tolerance atol + rtol |value|,
    the model's settings by default) and the bodies whose *stated* (non-zero) velocity it
    changed.  Velocities left at their default 0 are simply what the drivers and joints impose."""
    rtol = model.settings.rtol if rtol is None else rtol
    atol = model.settings.atol if atol is None else atol
    out = []
    for what, given, got in (("pose", model.q0, q), ("velocity", model.qd0, qd)):
        d = np.abs(got - given)
        tol = atol + rtol * np.maximum(np.abs(given), np.abs(got))
        moved = []
        for b, name in enumerate(model.body_names):
            s = slice(3 * b, 3 * b + 3)
            if np.all(d[s] <= tol[s]) or (what == "velocity" and not np.any(given[s])):
                continue
            moved.append(f"`{name}` by {_change(d[s], tol[s], what)}")
        if moved:
            out.append(("assembly moved " + ", ".join(moved) + " to close the joints"
                        if what == "pose" else "assembly changed the stated velocity of " + ", ".join(moved)
                        + ": the joints and drivers forbid it"))
    return out


MOVE_FRACTION = 0.5  # a body the assembly moves by more than this x the mechanism's size: warned about
TURN_LIMIT = np.radians(45.0)  # ... or turns by more than this: another branch of a loop than the sketch


def assembly_warnings(model: Model, q: np.ndarray) -> list[str]:
    """What the assembly did that a sketch does not explain: a body moved by more than `MOVE_FRACTION`
    of the mechanism's size (`Model.size`: a position in the wrong unit, a typo) or turned by more than
    `TURN_LIMIT` (the loop closed on another branch than the one drawn: a link with its ends swapped),
    each naming the body and the move."""
    size = model.size
    out = []
    d = (np.asarray(q, dtype=np.float64) - np.asarray(model.q0, dtype=np.float64)).reshape(-1, 3)
    for b, name in enumerate(model.body_names):
        shift, turn = float(np.hypot(d[b, 0], d[b, 1])), float(abs(d[b, 2]))
        if shift > MOVE_FRACTION * size:
            out.append(f"assembly moved `{name}` by {_length(shift)}, more than {MOVE_FRACTION:g} x the "
                       f"mechanism's size ({_length(size)}): its stated `position` is far from where its joints "
                       "put it (a unit or a typo?); the run starts from the assembled pose")
        if turn > TURN_LIMIT:
            out.append(f"assembly turned `{name}` by {np.degrees(turn):.3g}°, more than "
                       f"{np.degrees(TURN_LIMIT):.3g}°: the joints closed on another configuration than the one "
                       "drawn (a link with its ends swapped, a loop flipped?); check its `angle`, `position` and "
                       "joint points")
    return out


def _length(x: float) -> str:
    return f"{x * 1e3:.3g} mm" if x < 1.0 else f"{x:.3g} m"


def _change(d: np.ndarray, tol: np.ndarray, what: str) -> str:
    """A body's change (|dx|, |dy|, |dφ|) in one unit per kind: the displacement in mm and the turn
    in degrees (a pose), or m/s and rad/s (a velocity); a part within its tolerance is left out."""
    shift, turn = float(np.hypot(d[0], d[1])), float(d[2])
    if what == "pose":
        parts = [f"{shift * 1e3:.3g} mm" if np.any(d[:2] > tol[:2]) else "",
                 f"{np.degrees(turn):.3g}°" if d[2] > tol[2] else ""]
    else:
        parts = [f"{shift:.3g} m/s" if np.any(d[:2] > tol[:2]) else "",
                 f"{turn:.3g} rad/s" if d[2] > tol[2] else ""]
    return " and ".join(p for p in parts if p)


def constraint_report(model: Model, q: np.ndarray, t: float = 0.0) -> dict:
    """Rank of the ideal joints' and drivers' constraints at pose q, degrees of freedom
    (coordinates - rank) and the joints whose rows add no rank (in declaration order: the later
    of two equal joints is the redundant one; drivers are kept last).  Clearance joints are
    force elements, not constraints: their rows are not counted.  A pose where the rank is lost
    only there (a singular position: nearby poses on the constraints have full rank) is
    reported as `singular` with the rank nearby, and no joint is called redundant.  For `mbs check`."""
    km, owners = assembly_kernel(model, use=[], slides=False)
    m = len(owners)
    if m == 0:
        return dict(rank=0, dof=model.ncoord, redundant=[], singular=False)
    rank, Cq, sv = _rank(km, q, t, m)
    if rank == m:
        return dict(rank=rank, dof=model.ncoord - rank, redundant=[], singular=False)
    near = _rank_nearby(km, q, t, m, model.size)
    if near is not None and near > rank:
        return dict(rank=rank, dof=model.ncoord - near, redundant=[], singular=True, rank_nearby=near)
    return dict(rank=rank, dof=model.ncoord - rank, redundant=_dependent_rows(Cq, owners, sv), singular=False)


def _rank(km: KernelModel, q, t, m):
    _, Cq, _ = _evaluate(km, q, np.zeros_like(q), t, m)
    if np.all(np.isfinite(Cq)) and clearly_full_rank(Cq):
        return m, Cq, None
    sv = np.linalg.svd(Cq, compute_uv=False)
    tol = RANK_TOL * max(sv[0] if len(sv) else 0.0, 1.0)
    return int(np.count_nonzero(sv > tol)), Cq, sv


def _rank_nearby(km: KernelModel, q, t, m, size: float, tries: int = 3):
    """The largest rank of the constraints at poses near q that satisfy them: q moved by 1e-3 of
    the mechanism's size in a random direction, then back onto C = 0 by minimum-norm Newton steps.
    None when no such pose is found."""
    rng = np.random.default_rng(1)
    best = None
    for _ in range(tries):
        x = np.asarray(q, dtype=float) + 1e-3 * size * rng.standard_normal(len(q))
        for _ in range(50):
            C, Cq, _ = _evaluate(km, x, np.zeros_like(x), t, m)
            if not np.all(np.isfinite(C)):
                break
            if np.abs(C).max() <= 1e-13 * size:
                r = _rank(km, x, t, m)[0]
                best = r if best is None else max(best, r)
                break
            x = x - min_norm_step(Cq, C, RANK_TOL)
    return best


def start_gaps(model: Model, q: np.ndarray) -> np.ndarray:
    """Gap of every clearance element at pose q (> 0 apart, < 0 penetrating), the penetration of
    `kernel/contact.py` with the opposite sign, computed here without numba (for `mbs check`)."""
    k = model.kernel
    out = np.zeros(model.nclearance)
    for c in range(model.nclearance):
        p = k.clearance_param[c]
        pts, rot = [], np.eye(2)
        for side in (0, 1):
            b = int(k.clearance_body[c, side])
            s = np.asarray(k.clearance_point[c, side], dtype=float)
            if b < 0:
                pts.append(s)
                continue
            cs, sn = np.cos(q[3 * b + 2]), np.sin(q[3 * b + 2])
            R = np.array([[cs, -sn], [sn, cs]])
            rot = R if side == 0 else rot
            pts.append(q[3 * b:3 * b + 2] + R @ s)
        e = pts[1] - pts[0]
        kind = int(p[CP_KIND])
        if kind == PairKind.CIRCLE_ON_LINE:
            out[c] = float(e @ (rot @ p[[CP_NX, CP_NY]])) - p[CP_R_JOURNAL]
        elif kind == PairKind.CIRCLE_ON_CIRCLE:
            out[c] = float(np.hypot(*e)) - p[CP_R_BEARING] - p[CP_R_JOURNAL]
        else:
            ratio = p[CP_BREAKDOWN] if kind == PairKind.LUBRICATED else 1.0
            out[c] = ratio * p[CP_CLEARANCE] - float(np.hypot(*e))
    return out
