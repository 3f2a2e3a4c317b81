"""The compiled time loop and the observation row.

`advance` integrates from ``clock[0]`` towards ``t_stop``, writing observation
rows at ``t0 + k * output_step`` (k = stats[ST_OUTPUTS], ...; times by
multiplication, no drift) from the dense output of each accepted step, plus a
last sample at ``t_stop`` when it is off the grid.  It returns (status,
n_written); BUFFER_FULL means "write the buffer out and call again": the run
continues exactly (pending outputs of a step and a pending mode switch are
kept in the workspace).  Callers should pass the same ``t_stop`` (the end of
the run) on every call; an intermediate ``t_stop`` off the output grid adds an
off-grid sample.

A trial step of the adaptive methods whose stages leave the branch of an implicit
contact law (Status.CONTACT_SOLVE from the rhs) or reach a pose with dependent
constraints (Status.SINGULAR: a loose-tolerance trial step can fling a stage
there) is rejected like a non-finite one; the run returns that status only when
the step falls below h_min (fixed-step RK4 returns it at once).

Workspace flags: [0] outputs of the last step pending, [1] joint whose mode
switches at the end of the last step (-1 none), [2] integrator of the stored
dense output, [3] its rows (ws.F) prepared for the last step.  ws.dense:
[0] step start ta, [1] step size h, [2] end of the kept part of the step (an
event cuts it), [3] time of the last off-grid final sample, [4] error of the
last accepted step (PI controller).
"""
from __future__ import annotations

import math

from .jit import kernel
from ..mechanism.model import ABSURD_STATE, CP_BRISTLE_STIFFNESS, CT_FRICTION, CT_IMPACT_VELOCITY, STICK, TOUCHING
from .contact import contact_mode
from .workspace import (
    DN_ERR_OLD,
    DN_FINAL_SAMPLE,
    DN_H,
    DN_JUMP_AT,
    DN_PROJECT_FROM,
    DN_SPEED,
    DN_CUT,
    DN_TA,
    DN_T_END,
    FL_DENSE_METHOD,
    FL_DENSE_READY,
    FL_ENERGY0,
    FL_JUMP_ROW,
    FL_JUMPS,
    FL_PASSAGE,
    FL_PENDING_OUTPUTS,
    FL_PROJECTING,
    FL_RANK_LOST,
    FL_STEP_REG,
    FL_SWITCH_EXPR,
    FL_SWITCH_JOINT,
    JW_T,
    WK_NOW,
    WK_SAVE,
    WK_T,
)

from ..mechanism.model import (
    CFG_ATOL,
    CFG_HMAX,
    CFG_HMIN,
    CFG_LOST,
    CFG_MAX_STEPS,
    CFG_METHOD,
    CFG_OUTPUT_STEP,
    CFG_PROJECT,
    CFG_RTOL,
    CFG_SIZE,
    CFG_SKIP,
    CFG_STEP,
    CS_E,
    CS_EX,
    CS_EY,
    CS_FN,
    CS_FRICTION,
    CS_FX,
    CS_FY,
    CS_IMPACT_VELOCITY,
    CS_IN_CONTACT,
    CS_PENETRATION,
    CS_FILM_PRESSURE,
    CS_POINT_X,
    CS_POINT_Y,
    CS_SLIP,
    CS_STICK,
    CS_FRICTION_POWER,
    CS_BRISTLE,
    CS_DISSIPATED,
    CS_WORK,
    FS_POWER,
    FS_VALUE,
    FS_WORK,
    N_FORCE_SIGNALS,
    OB_DRIVER_WORK,
    OB_FORCE,
    OBS_SKIP_LOADS,
    SYS_BALANCE,
    SYS_DISSIPATED,
    SYS_GRAVITY_POWER,
    SYS_GRAVITY_WORK,
    SYS_INPUT_WORK,
    JS_FX,
    JS_FY,
    JS_MOMENT,
    N_CLEARANCE_SIGNALS,
    N_JOINT_SIGNALS,
    OBS_SKIP_CLEARANCE,
    OBS_SKIP_DYNAMICS,
    OBS_SKIP_ENERGY,
    OBS_SKIP_ERRORS,
    OB_CLEARANCE,
    OB_EFFORT,
    OB_JOINT,
    OB_POWER,
    OB_Q,
    OB_QD,
    OB_QDD,
    OB_JFRICTION,
    OB_SIZE,
    OB_SYSTEM,
    JF_FRICTION,
    JF_POWER,
    JF_RATE,
    JF_STICK,
    JF_WORK,
    N_JFRICTION_SIGNALS,
    SYS_KINETIC,
    SYS_POSITION_ERROR,
    SYS_POTENTIAL,
    SYS_VELOCITY_ERROR,
    observation_layout,
    ST_OUTPUTS,
    ST_REJECTED,
    ST_RHS,
    ST_STEPS,
    ST_INFO,
    Integrator,
    Status,
)
from .constraints import _JOINT_ROWS, ANGLE, body_trig, constraint_rows_eval, driver_motion, point_cs
from .contact import (
    add_clearance_forces,
    clearance_energy,
    clearance_force,
    clearance_kinematics,
    contact_energy,
    contact_time_scale,
    film_peak,
    law_supported,
    state_index,
)
from .dynamics import DRIFT_POSITION, DRIFT_VELOCITY, accelerations, drift_check, jac_dot, project, rhs
from .events import (event_possible, init_joint_friction, init_modes, joint_friction_possible, locate_event,
                     locate_joint_friction, locate_switch, switch_joint_friction, switch_mode)
from .joint_friction import slip_state
from .expressions import flip_switch, init_switches
from .beam import beam_strain_energy
from .forces import applied_forces, force_potential
from .work import energy_start, kinetic_energy, work_accept, work_at, work_end, work_restore
from .integrators import (
    ADAPTIVE,
    BAD_METHOD,
    END_STAGE,
    ERROR_EXPONENT,
    EXTRA_STAGES,
    FAC_MAX,
    FAC_MIN,
    METHOD_ORDER,
    RICHARDSON,
    SAFETY,
    dense_eval,
    dense_pending,
    dense_prepare,
    end_stage,
    fixed_step,
    initial_step,
    method_ok,
    rk_trial,
    scaled_error,
)

DONE = int(Status.DONE)
BUFFER_FULL = int(Status.BUFFER_FULL)
STEP_UNDERFLOW = int(Status.STEP_UNDERFLOW)
NONFINITE = int(Status.NONFINITE)
MAX_STEPS = int(Status.MAX_STEPS)
BAD_INPUT = int(Status.BAD_INPUT)
CONTACT_SOLVE = int(Status.CONTACT_SOLVE)
SINGULAR = int(Status.SINGULAR)
CONSTRAINTS_LOST = int(Status.CONSTRAINTS_LOST)
PASSAGE = int(Status.PASSAGE)
ABSURD = int(Status.ABSURD)
layout = kernel(observation_layout)  # the observation row's block offsets, compiled

GRID_TOL = 1e-9  # an output time within GRID_TOL * output_step of a step end belongs to it
STRETCH = 1e-9  # a step within STRETCH * h of t_stop is stretched to land on it
# Step-size control: h_new = h SAFETY err^-(1/(q+1) - 0.75 PI_BETA) err_prev^PI_BETA (the
# stabilised controller of Hairer's DOPRI5 code, PI_BETA = 0 is the plain I controller; used for
# DOP853 too, whose own code in Hairer's has beta = 0 and factors in [1/3, 6]).  On the clearance slider-crank
# (5 rev, 5000 rpm) it cuts the rejected steps by a quarter to a third (DOPRI5 rtol 1e-6: 570 -> 389,
# 1e-8: 683 -> 512; DOP853: 749 -> 471, 1208 -> 866) at the same or fewer rhs; the rejections come from the contact force's limited
# smoothness (F ~ delta^1.5 and the clip F >= 0), not from the restart after an event: a fresh
# Hairer initial step after each onset was tried and never shortened the step.
PI_BETA = 0.04
# First trial step after a contact onset, as a fraction of the contact's own time scale
# (contact.contact_time_scale: d_max / v, an impact lasts ~3 of them).  Without it the step
# after the onset reuses the long free-flight step: only one stage sees the force, the clip
# F >= 0 hides it from the error estimate, and a gentle impact of a damped law lost its rebound.
ONSET_STEP = 0.1


@kernel
def _jac_body(ws, r, b, i):
    """dC_r / dq[3 b + i] from the row-sparse Jacobian."""
    s = 0.0
    for a in range(2):
        if ws.rowbody[r, a] == b:
            s += ws.J[r, a, i]
    return s


@kernel
def observe(km, cfg, t, y, contact, ws, row):
    """Fill one observation row (model.observation_size layout) at (t, y).
    Returns a Status code (0 = fine).  The bodies' cos/sin are those `accelerations` (or
    `body_trig`) just left in ws.cs: no second sine or cosine per joint.

    cfg[CFG_SKIP] (OBS_SKIP_* bits) names the groups no stored signal needs: their columns are
    NaN and their work is skipped -- above all the `accelerations` call (its Schur solve) that
    the q'' block, the joint reactions and the driver efforts take; the constraint errors alone
    need only the constraint rows."""
    n = km.minv.shape[0]
    q = y[:n]
    qd = y[n:2 * n]
    for j in range(ws.z.shape[0]):  # the contact elements' own states (LuGre's bristles)
        ws.z[j] = y[2 * n + j]
    skip = int(cfg[CFG_SKIP])
    dynamics = (skip & OBS_SKIP_DYNAMICS) == 0
    errors = (skip & OBS_SKIP_ERRORS) == 0
    m = ws.C.shape[0]
    if dynamics:
        st = accelerations(km, cfg, t, q, qd, contact, ws, ws.sstats)
        if st != 0:
            return st
    else:
        body_trig(q, ws.cs)
        if errors and m > 0:
            st = constraint_rows_eval(km, q, qd, t, ws.cs, ws.C, ws.J, ws.Ct, ws.gam, ws.xreg, ws.xmode)
            if st != 0:
                return st
    nj = km.joint_type.shape[0]
    nd = km.driver_type.shape[0]
    nc = km.clearance_body.shape[0]
    nf = km.force_type.shape[0]
    loads = (skip & OBS_SKIP_LOADS) == 0
    if loads and not dynamics:  # the powers and values of the loads, which `accelerations` leaves in ws
        st = applied_forces(km, ws, t, q, qd)
        if st == 0 and nc > 0:
            st = add_clearance_forces(km, q, qd, ws.cs, contact, ws.z, ws.zd, ws.Qe, ws.sstats, ws.pw, nf + 1 + nd)
        if st != 0:
            return st
    lay = layout(n // 3, nj, nd, nc, nf, km.joint_friction.shape[0])  # model.observation_layout, compiled
    for i in range(n):
        row[lay[OB_Q] + i] = q[i]
        row[lay[OB_QD] + i] = qd[i]
    if dynamics:
        _observe_dynamics(km, t, q, qd, ws, row, lay[OB_QDD], lay[OB_JOINT], lay[OB_EFFORT], lay[OB_POWER])
    else:
        for i in range(lay[OB_QDD], lay[OB_CLEARANCE]):
            row[i] = math.nan
    if (skip & OBS_SKIP_CLEARANCE) == 0:
        _observe_clearances(km, q, qd, contact, ws, row, lay[OB_CLEARANCE])
    else:
        for i in range(lay[OB_CLEARANCE], lay[OB_FORCE]):
            row[i] = math.nan
    _observe_system(km, q, qd, contact, ws, row, lay[OB_SYSTEM], (skip & OBS_SKIP_ENERGY) == 0, errors, loads)
    _observe_loads(km, ws, row, lay[OB_FORCE], lay[OB_DRIVER_WORK], loads)
    if km.joint_friction.shape[0] > 0:
        _observe_joint_friction(km, q, qd, contact, ws, row, lay[OB_JFRICTION], dynamics)
    return 0


@kernel
def _observe_joint_friction(km, q, qd, contact, ws, row, col0, dynamics):
    """The friction joints' block: friction (from the solve `accelerations` just made), slip rate, power,
    stick flag, work."""
    nc = km.clearance_body.shape[0]
    nfj = km.joint_friction.shape[0]
    w0 = km.force_type.shape[0] + 1 + km.driver_type.shape[0] + nc
    for f in range(nfj):
        col = col0 + N_JFRICTION_SIGNALS * f
        s, v = slip_state(km, f, q, qd)
        T = ws.fs[f, JW_T] if dynamics else math.nan
        row[col + JF_FRICTION] = T
        row[col + JF_RATE] = v
        row[col + JF_POWER] = T * v
        row[col + JF_STICK] = 1.0 if int(contact[nc + f, CT_FRICTION]) == STICK else 0.0
        row[col + JF_WORK] = ws.wk[WK_T, w0 + f]


@kernel(inline=True)
def _observe_loads(km, ws, row, cforce, cdwork, loads):
    """The force elements' values, powers and works, and the drivers' works (ws.wk[WK_T]: at this row)."""
    nf = km.force_type.shape[0]
    nd = km.driver_type.shape[0]
    w = ws.wk[WK_T]
    for e in range(nf):
        col = cforce + N_FORCE_SIGNALS * e
        for i in range(FS_POWER - FS_VALUE):
            row[col + FS_VALUE + i] = ws.fv[e, i] if loads else math.nan
        row[col + FS_POWER] = ws.pw[e] if loads else math.nan
        row[col + FS_WORK] = w[e]
    for d in range(nd):
        row[cdwork + d] = w[nf + 1 + d]


@kernel(inline=True)
def _observe_clearances(km, q, qd, contact, ws, row, col0):
    """The clearance joints' block of an observation row (eccentricity, penetration, forces, contact point)."""
    for k in range(km.clearance_body.shape[0]):
        ex, ey, e, delta, nx, ny, vn, vt = clearance_kinematics(km, k, q, qd, contact)
        F, Ft, nx, ny, vt, st, rix, riy, rjx, rjy = clearance_force(km, k, q, qd, ws.cs, contact, ws.z, ws.zd)
        col = col0 + N_CLEARANCE_SIGNALS * k
        row[col + CS_EX] = ex
        row[col + CS_EY] = ey
        row[col + CS_E] = e
        row[col + CS_PENETRATION] = delta
        row[col + CS_FN] = F
        row[col + CS_FX] = -F * nx - Ft * ny  # normal + friction force on the journal
        row[col + CS_FY] = -F * ny + Ft * nx
        row[col + CS_IN_CONTACT] = 1.0 if contact_mode(contact, k) == TOUCHING else 0.0
        row[col + CS_IMPACT_VELOCITY] = contact[k, CT_IMPACT_VELOCITY]
        row[col + CS_FRICTION] = Ft
        row[col + CS_SLIP] = vt
        row[col + CS_STICK] = 1.0 if contact[k, CT_FRICTION] == STICK else 0.0
        row[col + CS_FRICTION_POWER] = Ft * vt
        js = state_index(km.clearance_param[k])
        row[col + CS_BRISTLE] = ws.z[js] / km.clearance_param[k, CP_BRISTLE_STIFFNESS] if js >= 0 else 0.0
        bj = km.clearance_body[k, 1]
        row[col + CS_POINT_X] = (q[3 * bj] if bj >= 0 else 0.0) + rjx
        row[col + CS_POINT_Y] = (q[3 * bj + 1] if bj >= 0 else 0.0) + rjy
        row[col + CS_FILM_PRESSURE] = film_peak(km, k, q, qd, e, vn)
        W = ws.wk[WK_T, km.force_type.shape[0] + 1 + km.driver_type.shape[0] + k]
        row[col + CS_WORK] = W
        row[col + CS_DISSIPATED] = ws.energy0[2 + k] - clearance_energy(km, k, q, qd, contact) - W


@kernel(inline=True)
def _observe_system(km, q, qd, contact, ws, row, col, energy, errors, loads):
    """The system block of an observation row: energies, gravity's power and work, the energy balance
    and constraint errors (NaN where skipped)."""
    T = math.nan
    V = math.nan
    Win = math.nan
    Wd = math.nan
    nf = km.force_type.shape[0]
    nd = km.driver_type.shape[0]
    w = ws.wk[WK_T]
    if energy:
        T = kinetic_energy(km, qd)
        Vf = force_potential(km, q, qd)
        V = Vf
        if km.clearance_body.shape[0] > 0:
            V += contact_energy(km, q, qd, contact)
        if km.beam_info.shape[0] > 0:
            V += beam_strain_energy(km, q)
        # the loads' and drivers' work less what their potentials (gravity's too) stored since the start
        Win = Vf - ws.energy0[1]
        for i in range(nf + 1 + nd):
            Win += w[i]
        Wd = 0.0
        nc = km.clearance_body.shape[0]
        for k in range(nc):
            Wd -= w[nf + 1 + nd + k] + clearance_energy(km, k, q, qd, contact) - ws.energy0[2 + k]
        for f in range(km.joint_friction.shape[0]):  # the joints' friction work (<= 0) is dissipated
            Wd -= w[nf + 1 + nd + nc + f]
        for bm in range(km.beam_info.shape[0]):  # and the beams' material damping's (the last channels)
            Wd -= w[w.shape[0] - km.beam_info.shape[0] + bm]
    row[col + SYS_GRAVITY_POWER] = ws.pw[nf] if loads else math.nan
    row[col + SYS_GRAVITY_WORK] = w[nf]
    row[col + SYS_INPUT_WORK] = Win
    row[col + SYS_DISSIPATED] = Wd
    row[col + SYS_BALANCE] = T + V - ws.energy0[0] - Win + Wd
    perr = math.nan
    verr = math.nan
    if errors:
        perr = 0.0
        verr = 0.0
        for r in range(ws.C.shape[0]):
            perr = max(perr, abs(ws.C[r]))
            verr = max(verr, abs(ws.Ct[r] + jac_dot(ws, r, qd)))
    row[col + SYS_KINETIC] = T
    row[col + SYS_POTENTIAL] = V
    row[col + SYS_POSITION_ERROR] = perr
    row[col + SYS_VELOCITY_ERROR] = verr


@kernel(inline=True)
def _observe_dynamics(km, t, q, qd, ws, row, cqdd, cjoint, ceffort, cpower):
    """The q'' block, the joint reactions and the driver efforts and powers of an observation row
    from the multipliers `accelerations` just left in ws (columns from `observation_layout`)."""
    n = q.shape[0]
    for i in range(n):
        row[cqdd + i] = ws.qdd[i]
    lam = ws.lam
    nj = km.joint_type.shape[0]
    nd = km.driver_type.shape[0]
    for jt in range(nj):
        r0 = km.joint_row[jt]
        nr = _JOINT_ROWS[km.joint_type[jt]]
        bi = km.joint_body[jt, 0]
        bj = km.joint_body[jt, 1]
        Pjx, Pjy, ajx, ajy, vjx, vjy, wj = point_cs(q, qd, ws.cs, bj, km.joint_point[jt, 1, 0], km.joint_point[jt, 1, 1])
        b = bj
        sign = 1.0
        if bj < 0:
            b = bi
            sign = -1.0
        fx = 0.0
        fy = 0.0
        mc = 0.0
        if b >= 0:
            for r in range(r0, r0 + nr):
                fx -= _jac_body(ws, r, b, 0) * lam[r]
                fy -= _jac_body(ws, r, b, 1) * lam[r]
                mc -= _jac_body(ws, r, b, 2) * lam[r]
            # moment about the joint point of the second body
            mc += (q[3 * b] - Pjx) * fy - (q[3 * b + 1] - Pjy) * fx
        col = cjoint + N_JOINT_SIGNALS * jt
        row[col + JS_FX] = sign * fx
        row[col + JS_FY] = sign * fy
        row[col + JS_MOMENT] = sign * mc
    for d in range(nd):
        r = km.driver_row[d]
        bi = km.driver_body[d, 0]
        bj = km.driver_body[d, 1]
        f, fd, fdd = driver_motion(km, ws.xreg, ws.xmode, d, t)
        eff = 0.0
        if bj >= 0:
            if km.driver_type[d] == ANGLE:
                eff = -_jac_body(ws, r, bj, 2) * lam[r]
            else:
                c = 1.0
                s = 0.0
                if bi >= 0:
                    c = ws.cs[bi, 0]
                    s = ws.cs[bi, 1]
                ux = c * km.driver_axis[d, 0] - s * km.driver_axis[d, 1]
                uy = s * km.driver_axis[d, 0] + c * km.driver_axis[d, 1]
                eff = -(_jac_body(ws, r, bj, 0) * ux + _jac_body(ws, r, bj, 1) * uy) * lam[r]
        row[ceffort + d] = eff
        row[cpower + d] = eff * fd


# `observe` inlined at its one call site in the time loop (`_emit`, which writes every row of a run): a
# call that is not inlined passes every array of the model and workspace tuples, about 0.2 us per row
# (kernel/jit.py).  One call site, so one more copy of it to compile: the public `observe` is compiled
# only when Python calls it (tests).
observe_inlined = kernel(observe.py_func, inline=True)


@kernel
def _emit(km, cfg, t0, contact, stats, ws, out_t, out, nw, t1, y1):
    """Write the grid outputs inside the kept part of the last step (t1 = NaN); or, with a time t1, only
    the row at (t1, y1) into out[nw] (the first row of a run, a last sample off the grid; the caller
    keeps the output count).  Returns (status, n_written, pending).  (A time rather than a flag, and
    never a constant count: numba compiles a function once more for each literal argument.)"""
    dto = cfg[CFG_OUTPUT_STEP]
    ta = ws.dense[DN_TA]
    h = ws.dense[DN_H]
    tend = ws.dense[DN_T_END]
    cap = out_t.shape[0]
    single = not math.isnan(t1)
    while True:
        k = stats[ST_OUTPUTS]
        tk = t1
        if single:
            for i in range(y1.shape[0]):
                ws.yt[i] = y1[i]
            for i in range(ws.wk.shape[1]):
                ws.wk[WK_T, i] = ws.wk[WK_NOW, i]
        else:
            tk = t0 + k * dto
            if tk > tend + GRID_TOL * dto:
                return 0, nw, False
            if nw >= cap:
                return 0, nw, True
            th = (min(tk, tend) - ta) / h
            if dense_pending(ws):
                st = dense_prepare(km, cfg, contact, ws, stats)
                if st != 0:
                    return st, nw, False
            dense_eval(ws, th, ws.yt)
            work_at(ws, th, WK_T)
        st = observe_inlined(km, cfg, tk, ws.yt, contact, ws, out[nw])
        if st != 0:
            stats[ST_INFO] = ws.sstats[ST_INFO]
            return st, nw, False
        out_t[nw] = tk
        nw += 1
        if single:
            return 0, nw, False
        stats[ST_OUTPUTS] = k + 1


@kernel
def _finish_step(km, cfg, t, y, contact, stats, ws):
    """Mode switch found by the event logic, then optional projection.
    Returns (status, restart, hcap): hcap caps the next trial step after a contact onset
    (ONSET_STEP of the contact's time scale), inf otherwise."""
    restart = False
    hcap = math.inf
    if ws.flags[FL_SWITCH_EXPR] >= 0:
        auto = cfg[CFG_PROJECT] == 2.0 and ws.flags[FL_PROJECTING] == 0
        held = auto and _within_bound(km, cfg, t, y, ws, stats)
        flip_switch(km, ws.xreg, ws.xmode, ws.flags[FL_SWITCH_EXPR], t, y)
        ws.flags[FL_SWITCH_EXPR] = -1
        restart = True
        if held and not _within_bound(km, cfg, t, y, ws, stats):
            st = motion_jump(km, t, y, ws, stats)
            if st != 0:
                return st, True, hcap
    k = ws.flags[FL_SWITCH_JOINT]
    nc = km.clearance_body.shape[0]
    if k >= 0:
        if k >= 2 * nc:
            switch_joint_friction(km, cfg, t, y, contact, ws, stats, k - 2 * nc)
        else:
            switch_mode(km, k, y, contact, stats)
        ws.flags[FL_SWITCH_JOINT] = -1
        restart = True
        if k < nc and contact_mode(contact, k) == TOUCHING:  # (k >= nc: a friction switch)
            n = km.minv.shape[0]
            hcap = ONSET_STEP * contact_time_scale(km, k, y[:n], y[n:2 * n], contact[k, CT_IMPACT_VELOCITY], contact)
    if cfg[CFG_PROJECT] == 2.0 and ws.flags[FL_PROJECTING] == 0 and ws.flags[FL_RANK_LOST] == 1:
        ws.flags[FL_PROJECTING] = 1  # `projection = auto`: a singular position or redundant joints
        ws.dense[DN_PROJECT_FROM] = t
    if cfg[CFG_PROJECT] == 1.0 or (cfg[CFG_PROJECT] == 2.0 and ws.flags[FL_PROJECTING] != 0):
        st = project(km, t, y, ws, stats)
        if st != 0:
            return st, True, hcap
        restart = True
    return 0, restart, hcap


@kernel(inline=True)
def _within_bound(km, cfg, t, y, ws, stats):
    """The state at t meets the constraint check's bounds (`lost_check`), the expressions' branches
    as they are now; stats[ST_INFO] names the first row beyond them."""
    n = km.minv.shape[0]
    body_trig(y[:n], ws.cs)
    if constraint_rows_eval(km, y[:n], y[n:2 * n], t, ws.cs, ws.C, ws.J, ws.Ct, ws.gam, ws.xreg, ws.xmode) != 0:
        return True  # left to the step's own checks
    return lost_check(cfg, ws, y[n:2 * n], stats) == 0


@kernel(inline=True)
def motion_jump(km, t, y, ws, stats):
    """`projection = auto`, at a located switch of an expression that put a state within the constraint
    check's bounds beyond them: a driver's motion jumped there (in value or first derivative: a kink
    asks for an infinite acceleration, which the integrator cannot see).  The state is projected onto
    the new motion at once, the mass-weighted (perfectly plastic) impulsive change; counted and timed
    for the run's warning.  A switch of a load changes no constraint and never comes here; nor does
    a state already beyond the bounds (drift of a too long fixed step: the drift check stops it)."""
    if ws.flags[FL_JUMPS] == 0:
        ws.dense[DN_JUMP_AT] = t
        ws.flags[FL_JUMP_ROW] = stats[ST_INFO]
    ws.flags[FL_JUMPS] += 1
    return project(km, t, y, ws, stats)


@kernel
def lost_check(cfg, ws, qd, stats):
    """The adaptive methods' constraint check at the state of the last right-hand side (ws.C, ws.J,
    ws.Ct): CONSTRAINTS_LOST (stats[ST_INFO] = row) when a row's residual, as a distance (|C_r| over
    its Jacobian's norm, angles weighted by the size L), exceeds cfg[CFG_LOST] times L, or its velocity
    residual that times the largest speed seen (|v| + L |omega| of a body, ws.dense[DN_SPEED]).  The
    methods keep the residuals near rtol; far beyond, the constraints gave way (a driver pushing past a
    limit position): bounds scaled to the mechanism, so a 5 mm link has its own."""
    L = cfg[CFG_SIZE]
    rel = cfg[CFG_LOST]
    floor = 1e3 * cfg[CFG_ATOL]
    vs = ws.dense[DN_SPEED]
    for b in range(qd.shape[0] // 3):
        vs = max(vs, math.hypot(qd[3 * b], qd[3 * b + 1]) + L * abs(qd[3 * b + 2]))
    ws.dense[DN_SPEED] = vs
    for r in range(ws.C.shape[0]):
        g = 0.0
        for a in range(2):
            if ws.rowbody[r, a] >= 0:
                g += ws.J[r, a, 0] ** 2 + ws.J[r, a, 1] ** 2 + (ws.J[r, a, 2] / L) ** 2
        g = math.sqrt(g)
        if not (g > 0.0):
            continue
        if (not (abs(ws.C[r]) / g <= rel * L + floor)
                or not (abs(ws.Ct[r] + jac_dot(ws, r, qd)) / g <= rel * vs + floor)):
            stats[ST_INFO] = r
            return CONSTRAINTS_LOST
    return 0


@kernel(inline=True)
def passage_check(method, km, cfg, t, y, h, contact, ws, stats):
    """After a fixed step (RK4) in which a factor was regularised (a singular position; ws.yb, ws.K hold
    the step): the same step in two halves.  The positions' difference over 2^p - 1 (Richardson, p the
    method's order: 15 for RK4) is the error of the step; beyond rtol / atol the step cannot resolve the
    passage and the run stops (PASSAGE)
    instead of going on wrong, as the adaptive methods' error estimate would shorten the step.
    Leaves the full step in ws.yb, ws.K as before (ws.F rows as scratch).  Returns a Status code."""
    N = y.shape[0]
    F = ws.F
    for i in range(N):
        F[0, i] = ws.f[i]
        F[1, i] = ws.yb[i]
    for i in range(ws.pf.shape[0]):
        ws.wk[WK_SAVE, i] = ws.pf[i]
    st = fixed_step(method, km, cfg, t, y, 0.5 * h, contact, ws, stats)
    if st == 0:
        for i in range(N):
            F[2, i] = ws.yb[i]
            ws.f[i] = ws.K[END_STAGE[method], i]
        for i in range(ws.pf.shape[0]):
            ws.pf[i] = ws.pk[END_STAGE[method], i]
        st = fixed_step(method, km, cfg, t + 0.5 * h, F[2], 0.5 * h, contact, ws, stats)
    err = 0.0
    if st == 0:
        rtol = cfg[CFG_RTOL]
        atol = cfg[CFG_ATOL]
        for i in range(km.minv.shape[0]):  # positions: a velocity's noise at the passage itself is not an error of the motion
            e = abs(ws.yb[i] - F[1, i]) / RICHARDSON[method] / (atol + rtol * max(abs(y[i]), abs(ws.yb[i])))
            if e > err:
                err = e
                stats[ST_INFO] = i
    for i in range(N):
        ws.f[i] = F[0, i]
    for i in range(ws.pf.shape[0]):
        ws.pf[i] = ws.wk[WK_SAVE, i]
    st2 = fixed_step(method, km, cfg, t, y, h, contact, ws, stats)
    if st != 0:
        return st
    if st2 != 0:
        return st2
    return PASSAGE if err > 1.0 else 0


@kernel
def _worst_component(method, cfg, y, h, ws):
    """Index of the state component with the largest scaled error estimate in the last
    trial step (what limited the step)."""
    worst = -1.0
    iw = 0
    for i in range(y.shape[0]):
        r = scaled_error(method, cfg, y, h, ws, i)
        if r > worst:
            worst = r
            iw = i
    return iw


@kernel
def _all_finite(a):
    """Whether every entry of `a` is finite (the time loop's guard against NaN and infinity)."""
    for i in range(a.shape[0]):
        if not math.isfinite(a[i]):
            return False
    return True


@kernel
def _beyond_bound(y, n):
    """The first finite component of (q, q') in y (n coordinates) beyond every physical bound
    (ABSURD_STATE; angles are not bounded), or -1.  Once per accepted step: 2n comparisons beside
    several right-hand sides."""
    for i in range(2 * n):
        if abs(y[i]) >= ABSURD_STATE and math.isfinite(y[i]) and (i >= n or i % 3 != 2):
            return i
    return -1


# The steps of `advance`, each inlined at its one call site (`@kernel(inline=True)`): a call that is
# not inlined passes every array of the model and workspace tuples (kernel/jit.py), and the loop's
# machine code stays what it was when `advance` was one function (same results, same speed).


@kernel(inline=True)
def _refused(km, cfg, y, stats, ws, out_t, out):
    """BAD_INPUT for arrays that do not fit the model, an unknown method or an unsupported law; else 0."""
    N = y.shape[0]
    nc = km.clearance_body.shape[0]
    cap = out_t.shape[0]
    method = int(cfg[CFG_METHOD])
    n = km.minv.shape[0]
    nobs = layout(n // 3, km.joint_type.shape[0], km.driver_type.shape[0], nc, km.force_type.shape[0],
                  km.joint_friction.shape[0])[OB_SIZE]
    if (cap == 0 or not (cfg[CFG_OUTPUT_STEP] > 0.0) or out.shape[0] < cap or out.shape[1] != nobs
            or N != 2 * n + ws.z.shape[0]):
        return BAD_INPUT
    if not method_ok(method) or (not ADAPTIVE[method] and not (cfg[CFG_STEP] > 0.0)):
        stats[ST_INFO] = BAD_METHOD  # unknown, without dense output, or fixed-step without a step
        return BAD_INPUT
    for k in range(nc):
        if not law_supported(km.clearance_law[k]):
            stats[ST_INFO] = k
            return BAD_INPUT
    return 0


@kernel(inline=True)
def _resume(km, cfg, t0, t, y, clock, contact, stats, ws, out_t, out, nw):
    """Finish the previous call's last step (pending outputs, mode switch) and write a run's first row."""
    if ws.flags[FL_PENDING_OUTPUTS] == 1:
        st, nw, pending = _emit(km, cfg, t0, contact, stats, ws, out_t, out, nw, math.nan, y)
        if st != 0:
            return st, nw
        if pending:
            return BUFFER_FULL, nw
        ws.flags[FL_PENDING_OUTPUTS] = 0
        st, restart, hcap = _finish_step(km, cfg, t, y, contact, stats, ws)
        if st != 0:
            return st, nw
        clock[1] = min(clock[1], hcap)
    n = km.minv.shape[0]
    if stats[ST_OUTPUTS] == 0:
        init_modes(km, y, contact)
        init_switches(km, ws.xreg, ws.xmode, ws.xfault, t, y)
        if km.joint_friction.shape[0] > 0:
            init_joint_friction(km, cfg, t, y, contact, ws)
    if ws.flags[FL_ENERGY0] == 0:  # the first state of the run (or one a study set): the energy balance's reference
        energy_start(km, y[:n], y[n:2 * n], contact, ws)
    if stats[ST_OUTPUTS] == 0:
        st, nw, pending = _emit(km, cfg, t0, contact, stats, ws, out_t, out, nw, t, y)
        if st != 0:
            return st, 0
        stats[ST_OUTPUTS] = 1
    return 0, nw


@kernel(inline=True)
def _start(km, cfg, t, y, contact, stats, ws):
    """f(t, y) into ws.f, the first stage of the first step; NONFINITE for a non-finite y or f."""
    if not _all_finite(y):
        return NONFINITE
    st = rhs(km, cfg, t, y, contact, ws, stats, ws.f)
    if st != 0:
        return st
    _keep_powers(ws)
    if not _all_finite(ws.f):
        return NONFINITE
    return 0


@kernel(inline=True)
def _keep_powers(ws):
    """ws.pf = the powers of the rhs just evaluated into ws.f (the next step's first stage)."""
    for i in range(ws.pw.shape[0]):
        ws.pf[i] = ws.pw[i]


@kernel(inline=True)
def _first_step(method, km, cfg, t, y, clock, contact, stats, ws, hmax):
    """The first trial step: the fixed step, else the last call's, the setting's or Hairer's hinit."""
    if not ADAPTIVE[method]:
        return cfg[CFG_STEP]
    h = clock[1]
    if not (h > 0.0):
        order = float(METHOD_ORDER[method])
        h = cfg[CFG_STEP] if cfg[CFG_STEP] > 0.0 else initial_step(km, cfg, t, y, contact, ws, stats, hmax, order)
    return min(h, hmax)


@kernel(inline=True)
def _pause(cfg, stats, nw, cap, budget, steps_start, rhs_start):
    """Why the loop stops before its next step (BUFFER_FULL: buffer full or work budget used; MAX_STEPS), or 0."""
    maxsteps = cfg[CFG_MAX_STEPS]
    if nw >= cap:
        return BUFFER_FULL
    if maxsteps > 0 and stats[ST_STEPS] >= maxsteps:
        return MAX_STEPS
    if budget > 0.0 and stats[ST_STEPS] > steps_start and stats[ST_RHS] - rhs_start >= budget:
        return BUFFER_FULL
    return 0


@kernel(inline=True)
def _fixed(method, km, cfg, t, y, h, t_stop, contact, stats, ws):
    """One fixed step (RK4) with its drift and passage checks (no error control).  Returns (status, hh, last)."""
    hh = h
    last = False
    if t + hh >= t_stop - STRETCH * hh:
        hh = t_stop - t
        last = True
    ws.flags[FL_STEP_REG] = 0
    st = fixed_step(method, km, cfg, t, y, hh, contact, ws, stats)
    if st == 0:
        n = km.minv.shape[0]
        st = drift_check(ws, ws.yb[n:2 * n], stats, DRIFT_POSITION, DRIFT_VELOCITY)
    if st == 0 and ws.flags[FL_STEP_REG] == 1:
        st = passage_check(method, km, cfg, t, y, hh, contact, ws, stats)
    return st, hh, last


@kernel(inline=True)
def _trial_length(cfg, t, t0, h, t_stop, stats, ws):
    """A trial step from t: h, cut to land on t_stop or on the next output after a passage.  Returns (hh, last, cut)."""
    dto = cfg[CFG_OUTPUT_STEP]
    hh = h
    last = False
    cut = False
    if t + hh >= t_stop - STRETCH * hh:
        hh = t_stop - t
        last = True
    elif ws.flags[FL_PASSAGE] == 1:
        # the last step passed near a singular position, where the dense output is not
        # controlled: a grid output inside this step gets a step of its own
        tk = t0 + stats[ST_OUTPUTS] * dto
        if t + GRID_TOL * dto < tk < t + hh:
            hh = tk - t
            cut = True
    return hh, last, cut


@kernel(inline=True)
def _next_h(expo, err, hh, h, hmax, rejected, last, cut, ws):
    """The step after an accepted trial: PI controller (Hairer's DOPRI5, beta = PI_BETA; previous error in ws.dense)."""
    errold = ws.dense[DN_ERR_OLD] if ws.dense[DN_ERR_OLD] > 0.0 else 1e-4
    fac = FAC_MAX if err == 0.0 else SAFETY * err ** -(expo - 0.75 * PI_BETA) * errold ** PI_BETA
    ws.dense[DN_ERR_OLD] = max(err, 1e-4)
    fac = min(FAC_MAX, max(FAC_MIN, fac))
    if rejected:
        fac = min(fac, 1.0)
    hnew = hh * fac
    if (last or cut) and hnew < h and fac >= 1.0:
        hnew = h  # a step shortened to land on t_stop or an output says nothing against h
    return min(hnew, hmax)


@kernel(inline=True)
def _adaptive(method, km, cfg, t, t0, y, h, hmax, t_stop, clock, contact, stats, ws):
    """Trial steps of an adaptive method, shorter after each rejection, until one is accepted.
    Returns (status, next h, accepted step hh, last)."""
    expo = ERROR_EXPONENT[method]  # 1/(q+1), q = order of the error estimate (catalog)
    rejected = False
    nonfinite = False
    solve_failed = False
    stage_status = 0
    hh = h
    while True:
        if h < cfg[CFG_HMIN]:
            clock[1] = h
            if solve_failed:
                return stage_status, h, hh, False
            if nonfinite:
                return NONFINITE, h, hh, False
            stats[ST_INFO] = _worst_component(method, cfg, y, hh, ws)
            return STEP_UNDERFLOW, h, hh, False
        hh, last, cut = _trial_length(cfg, t, t0, h, t_stop, stats, ws)
        ws.flags[FL_STEP_REG] = 0
        st, err = rk_trial(method, km, cfg, t, y, hh, contact, ws, stats)
        if st == 0 and err <= 1.0:
            st = end_stage(method, km, cfg, t, hh, contact, ws, stats)
        if st == CONTACT_SOLVE or st == SINGULAR:
            # a trial stage went past the end of an implicit law's branch (no force exists there), or
            # a too long trial step reached a pose where the constraints are dependent: the trial fails
            # like a non-finite one, and the run stops with this status only if the step cannot shrink
            solve_failed = True
            stage_status = st
            err = math.inf
        elif st != 0:
            return st, h, hh, last
        else:
            solve_failed = False
        if err <= 1.0:
            return 0, _next_h(expo, err, hh, h, hmax, rejected, last, cut, ws), hh, last
        stats[ST_REJECTED] += 1
        rejected = True
        nonfinite = not (err < math.inf)
        fac = FAC_MIN if nonfinite else max(FAC_MIN, SAFETY * err ** -expo)
        h = hh * min(fac, 1.0)


@kernel(inline=True)
def _held(cfg, t, hh, y, stats, ws):
    """CONSTRAINTS_LOST after an accepted step whose constraints gave way (`lost_check`), else 0."""
    ws.flags[FL_PASSAGE] = ws.flags[FL_STEP_REG]
    n = ws.qdd.shape[0]
    if lost_check(cfg, ws, ws.yb[n:2 * n], stats) != 0:
        if cfg[CFG_PROJECT] == 2.0 and ws.flags[FL_PROJECTING] == 0:
            # `projection = auto`: the residuals drifted past the bound without a loss of
            # rank (long runs, hard impacts); projected from the next step on
            ws.flags[FL_PROJECTING] = 2
            ws.dense[DN_PROJECT_FROM] = t + hh
        else:
            return CONSTRAINTS_LOST  # the constraints gave way: a driver past a limit position
    return 0


@kernel(inline=True)
def _accept(method, t, hh, last, t_stop, y, stats, ws):
    """Keep an accepted step from (t, y) of length hh for its dense output; returns its end time."""
    ws.flags[FL_DENSE_METHOD] = method
    ws.flags[FL_DENSE_READY] = 0  # the dense output of this step is not prepared yet
    stats[ST_STEPS] += 1
    tnew = t_stop if last else t + hh
    for i in range(y.shape[0]):
        ws.ya[i] = y[i]
    ws.dense[DN_TA] = t
    ws.dense[DN_H] = hh
    ws.dense[DN_T_END] = tnew
    work_accept(method, hh, ws)
    return tnew


@kernel(inline=True)
def _contact_event(method, km, cfg, t, hh, tnew, y, contact, stats, ws):
    """The first contact onset or separation in the step: y and the kept step end there.
    Returns (status, joint or -1, theta, end time)."""
    kev = -1
    th = 1.0
    nfj = km.joint_friction.shape[0]
    if km.clearance_body.shape[0] > 0 or nfj > 0:
        if EXTRA_STAGES[method] > 0:  # screen first: its dense output costs stages
            if event_possible(km, ws, contact, END_STAGE[method]) or (
                    nfj > 0 and joint_friction_possible(km, cfg, ws, contact)):
                st = dense_prepare(km, cfg, contact, ws, stats)
                if st != 0:
                    return st, kev, th, tnew
                kev, th = locate_event(km, ws, contact)
                if nfj > 0:
                    kev, th = locate_joint_friction(km, cfg, ws, contact, kev, th)
        else:
            kev, th = locate_event(km, ws, contact)
            if nfj > 0:
                kev, th = locate_joint_friction(km, cfg, ws, contact, kev, th)
        if kev >= 0 and th < 1.0:
            tnew = t + th * hh
            dense_eval(ws, th, y)
            ws.dense[DN_T_END] = tnew
            ws.dense[DN_CUT] = th
        elif kev >= 0:
            for i in range(y.shape[0]):
                y[i] = ws.yb[i]
    return 0, kev, th, tnew


@kernel(inline=True)
def _switch_event(km, cfg, t, hh, tnew, kev, th, y, contact, stats, ws):
    """The first switch of a comparison before the contact event: the step ends there instead; the
    new state into y and the switches to make into ws.flags.  Returns (status, end time)."""
    N = y.shape[0]
    sev = -1
    if km.expr_switch.shape[0] > 0:
        st = dense_prepare(km, cfg, contact, ws, stats) if dense_pending(ws) else 0
        if st != 0:
            return st, tnew
        sev, ths = locate_switch(km, ws, th if kev >= 0 else 1.0 + 1e-9)
        if sev >= 0:  # a comparison switches first: the step ends there, a later contact event waits
            kev = -1
            if ths < 1.0:
                tnew = t + ths * hh
                dense_eval(ws, ths, y)
                ws.dense[DN_CUT] = ths
            else:
                for i in range(N):
                    y[i] = ws.yb[i]
                ws.dense[DN_CUT] = 1.0
            ws.dense[DN_T_END] = tnew
    ws.flags[FL_SWITCH_EXPR] = sev
    if kev < 0 and sev < 0:
        for i in range(N):
            y[i] = ws.yb[i]
    ws.flags[FL_SWITCH_JOINT] = kev
    return 0, tnew


@kernel(inline=True)
def _end_step(method, km, cfg, t0, t, h, y, clock, contact, stats, ws, out_t, out, nw):
    """Write the step's outputs, switch modes, project, and f at the new state into ws.f.
    Returns (status, n_written, next h)."""
    N = y.shape[0]
    clock[0] = t
    clock[1] = h
    i = _beyond_bound(y, km.minv.shape[0])
    if i >= 0:  # stop before the step's outputs are written: y stays the state beyond the bound
        stats[ST_INFO] = i
        return ABSURD, nw, h
    st, nw, pending = _emit(km, cfg, t0, contact, stats, ws, out_t, out, nw, math.nan, y)
    if st != 0:
        return st, nw, h
    if pending:
        ws.flags[FL_PENDING_OUTPUTS] = 1
        return BUFFER_FULL, nw, h
    st, restart, hcap = _finish_step(km, cfg, t, y, contact, stats, ws)
    if st != 0:
        return st, nw, h
    if ADAPTIVE[method]:
        h = min(h, hcap)
        clock[1] = h
    if not _all_finite(y):
        clock[0] = ws.dense[DN_TA]
        for i in range(N):
            y[i] = ws.ya[i]
        work_restore(ws)
        return NONFINITE, nw, h
    if restart:
        st = rhs(km, cfg, t, y, contact, ws, stats, ws.f)
        if st != 0:
            return st, nw, h
        _keep_powers(ws)
    else:
        kf = END_STAGE[method]
        for i in range(N):
            ws.f[i] = ws.K[kf, i]
        for i in range(ws.pw.shape[0]):
            ws.pf[i] = ws.pk[kf, i]
    if not _all_finite(ws.f):
        return NONFINITE, nw, h
    return 0, nw, h


@kernel(inline=True)
def _final_sample(km, cfg, t0, t, t_stop, h, y, clock, contact, stats, ws, out_t, out, nw):
    """A last sample at t_stop when it is off the output grid.  Returns (status, n_written)."""
    dto = cfg[CFG_OUTPUT_STEP]
    tlast = t0 + (stats[ST_OUTPUTS] - 1) * dto
    if abs(tlast - t_stop) > GRID_TOL * dto and ws.dense[DN_FINAL_SAMPLE] != t_stop and t == t_stop:
        if nw >= out_t.shape[0]:
            clock[1] = h
            return BUFFER_FULL, nw
        st, nw, pending = _emit(km, cfg, t0, contact, stats, ws, out_t, out, nw, t, y)
        if st != 0:
            return st, nw
        ws.dense[DN_FINAL_SAMPLE] = t_stop
    clock[1] = h
    return DONE, nw


@kernel
def advance(km, cfg, y, clock, contact, stats, ws, t_stop, out_t, out):
    """Integrate y = (q, q', z) (z: the contact elements' own states, LuGre's bristles) from clock[0] towards t_stop; see the module docstring.

    clock = [t, h (current step, 0 = automatic), t0 (start of the run), work budget]:
    with clock[3] > 0 (optional) the call returns BUFFER_FULL after the step in which
    it has used that many right-hand sides, so that the caller regains control (signals,
    progress) after a bounded time; the run continues exactly.
    Returns (status, n_written).  On an error clock[0] is the time of failure
    and y the last good state (on ABSURD the accepted state beyond the bound, stats[ST_INFO] its
    component); on STEP_UNDERFLOW limited by the error estimate,
    stats[ST_INFO] is the state component whose error limited the step."""
    cap = out_t.shape[0]
    nw = cap - cap  # 0, but not a constant: `_emit(..., nw, ...)` with a literal 0 is compiled once more
    st = _refused(km, cfg, y, stats, ws, out_t, out)
    if st != 0:
        return st, 0
    method = int(cfg[CFG_METHOD])
    t0 = clock[2]
    t = clock[0]
    st, nw = _resume(km, cfg, t0, t, y, clock, contact, stats, ws, out_t, out, nw)
    if st != 0:
        return st, nw
    st = _start(km, cfg, t, y, contact, stats, ws)
    if st != 0:
        return st, nw
    hmax = cfg[CFG_HMAX] if cfg[CFG_HMAX] > 0.0 else math.inf
    budget = clock[3] if clock.shape[0] > 3 else 0.0
    rhs_start = stats[ST_RHS]
    steps_start = stats[ST_STEPS]
    h = _first_step(method, km, cfg, t, y, clock, contact, stats, ws, hmax)
    while t < t_stop:
        st = _pause(cfg, stats, nw, cap, budget, steps_start, rhs_start)
        if st != 0:
            clock[1] = h
            return st, nw
        if not ADAPTIVE[method]:
            st, hh, last = _fixed(method, km, cfg, t, y, h, t_stop, contact, stats, ws)
        else:
            st, h, hh, last = _adaptive(method, km, cfg, t, t0, y, h, hmax, t_stop, clock, contact, stats, ws)
            if st == 0:
                st = _held(cfg, t, hh, y, stats, ws)
        if st != 0:
            clock[0] = t
            return st, nw
        tnew = _accept(method, t, hh, last, t_stop, y, stats, ws)
        st, kev, th, tnew = _contact_event(method, km, cfg, t, hh, tnew, y, contact, stats, ws)
        if st == 0:
            st, tnew = _switch_event(km, cfg, t, hh, tnew, kev, th, y, contact, stats, ws)
        if st != 0:
            clock[0] = t
            return st, nw
        work_end(ws)
        t = tnew
        st, nw, h = _end_step(method, km, cfg, t0, t, h, y, clock, contact, stats, ws, out_t, out, nw)
        if st != 0:
            return st, nw
    return _final_sample(km, cfg, t0, t, t_stop, h, y, clock, contact, stats, ws, out_t, out, nw)
