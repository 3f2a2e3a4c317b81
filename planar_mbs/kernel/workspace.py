"""Preallocated work arrays of one run (allocated once, passed to the kernels)."""
from __future__ import annotations

import os
from typing import NamedTuple

import numpy as np

from .. import catalog
from ..mechanism.model import CP_STATE, JOINT_ROWS, N_STATS, WL_SIZE, KernelModel, frozen, observation_size, work_layout
from .beam import BEAM_ROWS
from .constraints import row_bodies
from .expressions import expression_scratch


# stage and dense-output buffer rows: the most any integrator uses (catalog.INTEGRATORS)
N_STAGES = max(s.stages for s in catalog.INTEGRATORS)
N_DENSE_ROWS = max(3, max(len(s.dense_rows) for s in catalog.INTEGRATORS))  # 3: the passage check's scratch


# ws.flags slots (int64) -- the time loop's state between steps and calls
FL_PENDING_OUTPUTS = 0  # 1: outputs of the last accepted step still to be written
FL_SWITCH_JOINT = 1  # clearance joint whose contact mode switches at the end of the last step (-1: none)
FL_DENSE_METHOD = 2  # integrator code of the stored dense output
FL_DENSE_READY = 3  # 1: the dense-output rows ws.F of the last step are prepared
FL_SCHUR_REG = 4  # 1: ws.S holds the factor of S + REG diag(S), not of S (`dynamics.schur_factor`)
FL_REG_SEEN = 5  # 1: a factor since the last projection was regularised (`dynamics.project`)
FL_PROJECTING = 6  # `projection = auto` has turned the projection on: 1 at a loss of rank, 2 at drift past the bound
FL_STEP_REG = 7  # 1: a factor of the current step was regularised (a singular position or redundant rows)
FL_PASSAGE = 8  # 1: the last accepted step had a regularised factor (its successor lands on the next output)
FL_SWITCH_EXPR = 9  # comparison of an expression that switches at the end of the last step (-1: none)
FL_JUMPS = 10  # switches at which a driver's motion jumped and the state was projected (`loop.motion_jump`)
FL_JUMP_ROW = 11  # the constraint row of the first such jump
FL_ENERGY0 = 12  # 1: ws.energy0 and the works ws.wk[WK_NOW] start from the run's first state (`work.energy_start`)
FL_RANK_LOST = 13  # 1: a regularised factor may have withheld a direction: the constraints lost rank (`dynamics.withholds`)
N_FLAGS = 14
# ws.dense slots (float64)
DN_TA = 0  # start of the last accepted step
DN_H = 1  # its size
DN_T_END = 2  # end of its kept part (an event cuts it)
DN_FINAL_SAMPLE = 3  # time of the last off-grid final sample (NaN: none)
DN_ERR_OLD = 4  # error of the last accepted step (PI controller)
DN_PROJECT_FROM = 5  # time at which `projection = auto` turned the projection on (NaN: never)
DN_SPEED = 6  # largest speed |v| + L |omega| of a body seen by the constraint check (`loop.lost_check`)
DN_JUMP_AT = 7  # time of the first switch at which a driver's motion jumped (NaN: none; `loop.motion_jump`)
DN_CUT = 8  # theta at which an event cut the last accepted step (1: not cut)
N_DENSE = 9
# ws.fs slots of a friction joint: slip coordinate, its rate, slip acceleration without friction, friction,
# its bound mu_s x load, the stuck target acceleration, J_s M^-1 J_s^T
JW_S, JW_V, JW_A0, JW_T, JW_LIMIT, JW_TARGET, JW_FREE = range(7)
N_JW = 7
# ws.wk rows (float64, one column per work channel, `model.work_layout`): the cumulative works
WK_A = 0  # at the start of the last accepted step
WK_B = 1  # at the end of its full step (the quadrature of its stages' powers)
WK_PA = 2  # the powers at its start ...
WK_PB = 3  # ... and at its end (the cubic Hermite between them, `work.work_at`)
WK_NOW = 4  # at the current state (the end of the kept part of the last step)
WK_T = 5  # at the time of the observation row being written
WK_SAVE = 6  # scratch: the powers of ws.f while `loop.passage_check` moves it
N_WK = 7


class Workspace(NamedTuple):
    C: np.ndarray  # (m,) constraint values
    J: np.ndarray  # (m, 2, 3) row-sparse Jacobian: J[r, a] = dC_r / dq of body rowbody[r, a]
    rowbody: np.ndarray  # (m, 2) int: the two bodies of each row (-1 = ground)
    first: np.ndarray  # (m,) int: first row sharing a body with row r (envelope of S)
    lastrow: np.ndarray  # (m,) int: last row i with first[i] <= r
    cs: np.ndarray  # (nbody, 2) cos, sin of every body angle at the current rhs
    Ct: np.ndarray  # (m,) dC/dt
    gam: np.ndarray  # (m,) gamma
    S: np.ndarray  # (profile,) Schur complement Cq M^-1 Cq^T, its envelope packed by rows, factored in place
    ptr: np.ndarray  # (m,) int: where row r's envelope (columns first[r]..r) starts in S
    sdiag: np.ndarray  # (m,) diagonal of S before factoring
    lam: np.ndarray  # (m,) Lagrange multipliers
    b: np.ndarray  # (m,) right side of the Schur system during `multipliers`
    Qe: np.ndarray  # (n,) applied forces
    qdd: np.ndarray  # (n,) accelerations
    K: np.ndarray  # (N_STAGES, N) stage derivatives (N = 2n + nstate: y = (q, q', z)); K[0] = f(ya), K[END_STAGE[method]] = f(yb)
    F: np.ndarray  # (N_DENSE_ROWS, N) dense-output rows of the last step (`integrators.dense_rows`); with beams
    # BEAM_ROWS more, the beams' scratch (`beam.beam_row`)
    f: np.ndarray  # (2n,) derivative at the current state (the next step's k1)
    ya: np.ndarray  # (2n,) state at the start of the last step
    yb: np.ndarray  # (2n,) state at the end of the last step
    ys: np.ndarray  # (2n,) stage argument / scratch
    yt: np.ndarray  # (2n,) dense-output scratch
    gs: np.ndarray  # (nclearance, 5) event function samples
    dense: np.ndarray  # (N_DENSE,) float, slots DN_*
    flags: np.ndarray  # (N_FLAGS,) int, slots FL_*
    sstats: np.ndarray  # (N_STATS,) scratch counters for `observe`
    res: np.ndarray  # (m,) residual of the multiplier refinement
    dl: np.ndarray  # (m,) projection corrections
    rdiag: np.ndarray  # (m,) the diagonal of S in the heaviest-mass metric (km.unit_minv), the regularisation's scale
    v: np.ndarray  # (n,) M^-1 Cq^T x scratch of the multiplier refinement
    solver: np.ndarray  # (8,) [REG, REFINE, REFINE_TOL, TAU, RESTORE, RATE, WITHHELD, UNIT_MASS] (`solver_settings`)
    xreg: np.ndarray  # (max(ninstr, 1), 3) expression registers: value, d/dt, d2/dt2 (`kernel.expressions`)
    xmode: np.ndarray  # (ninstr,) frozen 0/1 of a comparison row, or a table's piece (LIVE: computed afresh)
    xfault: np.ndarray  # (2,) [force element, t] of the first non-finite expression value (-1: none)
    pw: np.ndarray  # (nwork,) powers of the work channels at the current rhs (`model.work_layout`)
    pf: np.ndarray  # (nwork,) the powers at the state of ws.f (the next step's first stage)
    pk: np.ndarray  # (N_STAGES, nwork) the powers at each stage of the last step, as ws.K
    wk: np.ndarray  # (N_WK, nwork) cumulative works, rows WK_*
    fv: np.ndarray  # (nforce, N_FORCE_VALUES) each force element's reported values (`forces.force_element`)
    fsave: np.ndarray  # (6,) scratch of `forces.element_power`
    wF: np.ndarray  # (N_DENSE_ROWS,) scratch of `work.work_at`
    energy0: np.ndarray  # (2 + nclearance,) at the start: T + V, the loads' potential, each clearance's elastic energy
    z: np.ndarray  # (nstate,) the contact elements' own states (LuGre's sigma_0 z) at the current rhs: y[2n:]
    zd: np.ndarray  # (nstate,) their rates there (`contact.clearance_force`)
    # the friction joints' solve (`dynamics.joint_friction`, njf = len(km.joint_friction); empty without)
    fJ: np.ndarray  # (njf, 2, 3) Jacobian of each slip coordinate on the joint's two bodies
    fU: np.ndarray  # (njf, m) S^-1 Cq M^-1 J_s^T: the multipliers' response to a unit friction torque
    fD: np.ndarray  # (njf, n) M^-1 (J_s^T - Cq^T fU): the accelerations' response
    fA: np.ndarray  # (njf, njf + 1) the stuck joints' linear system
    fG: np.ndarray  # (njf, njf) slip accelerations' response J_s fD
    fi: np.ndarray  # (njf,) int: the stuck joints of the solve
    fs: np.ndarray  # (njf, N_JW) per friction joint, slots JW_*


def kernel_model(km: KernelModel) -> KernelModel:
    """The same model with every field as a contiguous, read-only float64 / int64 array
    (one numba signature for every model)."""
    fields = {}
    for name, value in km._asdict().items():
        arr = np.asarray(value)
        if np.issubdtype(arr.dtype, np.integer) or name in {
            "joint_type", "joint_body", "joint_row", "driver_type", "driver_body",
            "driver_motion", "driver_row", "clearance_body", "clearance_law",
            "force_type", "force_body", "joint_friction",
        }:
            fields[name] = np.ascontiguousarray(arr, dtype=np.int64)
        else:
            fields[name] = np.ascontiguousarray(arr, dtype=np.float64)
    return frozen(KernelModel(**fields))


def sizes(km: KernelModel) -> tuple[int, int, int, int, int]:
    """(nbody, njoint, ndriver, nclearance, m rows)."""
    nb = len(km.body_mass)
    nj = len(km.joint_type)
    nd = len(km.driver_type)
    nc = len(km.clearance_law)
    m = int(JOINT_ROWS[np.asarray(km.joint_type, dtype=np.int64)].sum()) + nd
    return nb, nj, nd, nc, m


def state_count(km: KernelModel) -> int:
    """States of the contact elements' own after (q, q') in y (`Model.nstate`)."""
    return int(np.count_nonzero(np.asarray(km.clearance_param)[:, CP_STATE] > 0))


def nobs(km: KernelModel) -> int:
    """Columns of one observation row (model.observation_size)."""
    nb, nj, nd, nc, _ = sizes(km)
    return observation_size(nb, nj, nd, nc, len(km.force_type), len(km.joint_friction))


def envelope(rowbody: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, lastrow) of the Schur complement's envelope: rows r and c couple
    when they share a body."""
    m = rowbody.shape[0]
    first = np.arange(m, dtype=np.int64)
    seen: dict[int, int] = {}
    for r in range(m):
        for b in rowbody[r]:
            if b >= 0:
                first[r] = min(first[r], seen.setdefault(int(b), r))
    lastrow = np.arange(m, dtype=np.int64)
    for i in range(m):
        lastrow[first[i]:i] = np.maximum(lastrow[first[i]:i], i)
    return first, lastrow


REG = 1e-8  # Tikhonov weight: S + REG diag(S) is factored (`dynamics` module docstring)
REFINE = 2  # refinement sweeps the regularised solve always makes
RATE = 0.03  # ... then more while each sweep shrinks the residual at least this much (`dynamics.refine`):
# directions of S that keep their rank (a light cart under a heavy pendulum: relative eigenvalue 1e-6)
# converge to rounding; only those below ~REG / RATE (a singular position) stay damped (0.01 left the
# light cart inexact, 0.1 made the singular passages of the parallelogram chain stiffer: 1.7x the steps)
TAU = 1e-3  # relative pivot (d_j / S_jj) below which S is refactored regularised
REFINE_TOL = 0.0  # stop early only on a zero residual: every sweep counts at the rounding level
# (a relative stop at 2e-16 of the largest row left small rows inexact; measured convergence orders drop)
RESTORE = 1.0  # 1: the projection keeps the kinetic energy a withheld constraint force would have kept
WITHHELD = 1e-6  # relative pivot (d_j / S_jj, of the regularised factor) at or below which a direction may be
# withheld: the solve converges by REG / (s + REG) a sweep, so only s below ~REG / RATE stays damped; only then
# has the mechanism lost rank (a singular position, redundant joints).  Pivots between WITHHELD and TAU are
# regular rows of a large or badly scaled mechanism (an 800-bar chain's are 1e-3 of their diagonal), solved
# exactly by the regularised solve and not reported.
UNIT_MASS = 1.0  # 1: a pivot below TAU is first checked against the unit-mass complement (`dynamics.scaled_by_masses`)
# (ws.solver holds [REG, REFINE, REFINE_TOL, TAU, RESTORE, RATE, WITHHELD, UNIT_MASS] so that experiments need no
# recompilation)


def solver_settings() -> np.ndarray:
    """[REG, REFINE, REFINE_TOL, TAU, RESTORE, RATE, WITHHELD, UNIT_MASS] of the multiplier solve (`dynamics.schur_factor`,
    `dynamics.multipliers`) and the velocity projection (`dynamics.project`)."""
    env = os.environ.get("PLANAR_MBS_SOLVER")  # experiments only: "reg,refine,tol,tau,restore,rate,withheld,unit_mass"
    settings = np.array([REG, float(REFINE), REFINE_TOL, TAU, RESTORE, RATE, WITHHELD, UNIT_MASS])
    if env:  # the values given replace the first ones, the rest keep their defaults
        given = [float(v) for v in env.split(",")][: settings.size]
        settings[: len(given)] = given
    return settings


def grouped(rowbody: np.ndarray, km: KernelModel) -> np.ndarray:
    """The rows' bodies as their coupling groups (`body_groups`): ground stays -1."""
    if not np.asarray(km.body_beam).size:
        return rowbody
    g = body_groups(km)
    return np.where(rowbody >= 0, g[np.maximum(rowbody, 0)], -1)


def make_workspace(km: KernelModel) -> Workspace:
    nb, nj, nd, nc, m = sizes(km)
    n = 3 * nb
    nz = state_count(km)
    N = 2 * n + nz
    rowbody = row_bodies(km)
    first, lastrow = envelope(grouped(rowbody, km))
    ptr = np.concatenate([[0], np.cumsum(np.arange(m) - first + 1)[:-1]]).astype(np.int64) if m else np.zeros(0, np.int64)
    xreg, xmode, xfault = expression_scratch(km)
    flags = np.zeros(N_FLAGS, dtype=np.int64)
    flags[FL_SWITCH_JOINT] = -1
    flags[FL_SWITCH_EXPR] = -1
    dense = np.zeros(N_DENSE)
    dense[DN_FINAL_SAMPLE] = np.nan
    dense[DN_PROJECT_FROM] = np.nan
    dense[DN_JUMP_AT] = np.nan
    dense[DN_CUT] = 1.0
    nf = len(km.force_type)
    njf = len(km.joint_friction)
    nw = work_layout(nf, nd, nc, njf, len(km.beam_info))[WL_SIZE]
    return Workspace(
        C=np.zeros(m), J=np.zeros((m, 2, 3)), rowbody=rowbody, first=first, lastrow=lastrow,
        cs=np.zeros((nb, 2)), Ct=np.zeros(m), gam=np.zeros(m),
        S=np.zeros(int(np.sum(np.arange(m) - first + 1))), ptr=ptr, sdiag=np.zeros(m), lam=np.zeros(m), b=np.zeros(m),
        Qe=np.zeros(n), qdd=np.zeros(n), K=np.zeros((N_STAGES, N)), F=np.zeros((N_DENSE_ROWS + (BEAM_ROWS if beam_coords(km) else 0), N)), f=np.zeros(N),
        ya=np.zeros(N), yb=np.zeros(N), ys=np.zeros(N), yt=np.zeros(N),
        gs=np.zeros((nc, 5)), dense=dense, flags=flags, sstats=np.zeros(N_STATS, dtype=np.int64),
        res=np.zeros(m), dl=np.zeros(m), rdiag=np.zeros(m), v=np.zeros(n), solver=solver_settings(), xreg=xreg, xmode=xmode, xfault=xfault,
        pw=np.zeros(nw), pf=np.zeros(nw), pk=np.zeros((N_STAGES, nw)), wk=np.zeros((N_WK, nw)),
        fv=np.zeros((nf, catalog.N_FORCE_VALUES)), fsave=np.zeros(6), wF=np.zeros(N_DENSE_ROWS), energy0=np.zeros(2 + nc),
        z=np.zeros(nz), zd=np.zeros(nz),
        fJ=np.zeros((njf, 2, 3)), fU=np.zeros((njf, m)), fD=np.zeros((njf, n)), fA=np.zeros((njf, njf + 1)),
        fG=np.zeros((njf, njf)), fi=np.zeros(njf, dtype=np.int64), fs=np.zeros((njf, N_JW)),
    )


def beam_coords(km: KernelModel) -> int:
    """The coordinates of the largest beam (0: none)."""
    info = np.asarray(km.beam_info).reshape(-1, 4)
    return int(4 * (info[:, 1].max() + 1)) if len(info) else 0


def body_groups(km: KernelModel) -> np.ndarray:
    """Each body's group in the Schur complement's coupling: itself, or its beam (the node bodies of one
    beam all couple through its mass)."""
    nb = len(km.body_mass)
    groups = np.arange(nb, dtype=np.int64)
    bb = np.asarray(km.body_beam, dtype=np.int64)
    if bb.size:
        groups[bb >= 0] = nb + bb[bb >= 0]
    return groups


def envelope_size(km: KernelModel) -> int:
    """Entries of the envelope of S (sum over rows of r - first[r] + 1): the memory and,
    squared per row, the work of one envelope factorisation."""
    first, _ = envelope(grouped(row_bodies(km), km))
    return int(np.sum(np.arange(len(first)) - first + 1))
