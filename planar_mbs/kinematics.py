"""Initial conditions: move the user's approximate pose onto the constraints.

Muvengei et al. §III.A: the run starts from the ideal-joint kinematics with every
clearance journal centred in its bearing.  So for assembly each clearance
joint is treated as an ideal revolute joint; positions are found by
Newton–Raphson with minimum-norm corrections (the assembled pose is the one
closest to what the user wrote), velocities by the minimum-norm correction of
the user's velocities onto ``Cq q' = -Ct``.

Redundant or singular constraints are found by adding the joints' rows one at a
time and watching the rank of ``Cq``; the joints that add no rank are named.
"""
from __future__ import annotations

import re

import numpy as np

from .errors import ModelError
from .model import JOINT_ROWS, JointType, KernelModel, Model

MAX_NEWTON = 50
POSITION_TOL = 1e-12  # m (and rad): residual of C at an assembled pose
RANK_TOL = 1e-9  # singular values below this x the largest count as zero


def assembly_kernel(model: Model) -> tuple[KernelModel, list[str]]:
    """The model's kernel arrays with clearance joints turned into revolute joints,
    and the name of the element behind each constraint row."""
    k = model.kernel
    nc = model.nclearance
    jt = np.concatenate([k.joint_type, np.full(nc, int(JointType.REVOLUTE), dtype=np.int64)])
    jb = np.concatenate([k.joint_body, k.clearance_body]).astype(np.int64)
    jp = np.concatenate([k.joint_point, k.clearance_point])
    ja = np.concatenate([k.joint_axis, np.tile([1.0, 0.0], (nc, 1))])
    jpar = np.concatenate([k.joint_param, np.zeros((nc, k.joint_param.shape[1]))])
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
    names = list(model.joint_names) + list(model.clearance_names)
    for name, r in zip(names, rows):
        owners += [name] * int(r)
    owners += list(model.driver_names)
    return km, owners


def _evaluate(km: KernelModel, q, qd, t, m):
    """C, Cq, Ct at (q, q', t) from the constraint kernels' source run as plain Python
    (`planar_mbs.pykernel`): assembly, and so `mbs check`, loads no numba.  A division by
    zero gives non-finite values (as the compiled kernels' numpy error model does)."""
    from .pykernel.constraints import constraint_eval

    n = len(q)
    C, Ct, gamma = np.zeros(m), np.zeros(m), np.zeros(m)
    Cq = np.zeros((m, n))
    with np.errstate(all="ignore"):
        try:
            constraint_eval(km, q, qd, t, C, Cq, Ct, gamma)
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
    return [n for b, n in enumerate(model.body_names) if b not in used]


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
    km, owners = assembly_kernel(model)
    m = len(owners)
    q = model.q0.astype(np.float64).copy()
    qd = model.qd0.astype(np.float64).copy()
    if m == 0:
        return q, qd
    for _ in range(MAX_NEWTON):
        C, Cq, _ = _evaluate(km, q, qd, t, m)
        if not np.all(np.isfinite(C)):
            break
        if np.max(np.abs(C)) < POSITION_TOL:
            break
        dq, *_ = np.linalg.lstsq(Cq, -C, rcond=None)
        q += dq
    C, Cq, Ct = _evaluate(km, q, qd, t, m)
    finite = bool(np.all(np.isfinite(Cq)))
    if finite:  # singular values for the rank test
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
    dependent = _dependent_rows(Cq, owners, sv)
    if dependent:
        raise _model_error(
            model,
            "redundant or singular constraints at the assembled pose: " + ", ".join(f"`{n}`" for n in dependent),
            dependent,
            "these joints or drivers repeat what others already impose (or the pose is a "
            "singular, toggle position); remove one or move the initial pose",
        )
    dqd, *_ = np.linalg.lstsq(Cq, -(Cq @ qd + Ct), rcond=None)
    return q, qd + dqd
