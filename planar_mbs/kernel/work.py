"""The cumulative work of every load, driver and clearance element, and the energy at the start.

Each right-hand side leaves the power of every work channel in ws.pw (`model.work_layout`: the force
elements' Q_e . q', gravity's, the drivers' -lam_r J_r q', the clearance elements' contact forces on
both bodies); `integrators.rk_stages` keeps them beside the stages (ws.pk).  An accepted step adds
h sum_j b_j P_j, its own Runge-Kutta weights on its own stages: the works are extra states W' = P(t, y)
integrated by the same method, to its order, but outside the error control (the steps, and so the
trajectory, are those without them).  Between a step's ends (an output time, an event that cuts the
step) the work is the method's own dense output applied to it (its stage derivatives are the stage
powers), the same interpolant as the state's.  `energy_start` keeps T + V and its parts at the first state, the reference of the energy
balance (`loop._observe_system`)."""
from __future__ import annotations

from .jit import kernel

from .beam import beam_kinetic, beam_strain_energy
from .contact import clearance_energy, contact_energy
from .forces import force_potential
from .integrators import (
    DENSE_DY,
    DENSE_J,
    DENSE_NONE,
    DENSE_NZ,
    DENSE_PREV,
    DENSE_ROWS,
    DENSE_ROWS_OF,
    DENSE_RULE,
    DENSE_W,
    END_STAGE,
    EXTRA_STAGES,
    N_METHODS,
    RK_B,
    TRIAL_STAGES,
)
from .workspace import DN_CUT, DN_H, FL_DENSE_METHOD, FL_DENSE_READY, FL_ENERGY0, WK_A, WK_B, WK_NOW, WK_PA, WK_PB


@kernel(inline=True)
def work_accept(method, h, ws):
    """An accepted step of length h: the works at its start and at its end, the powers there."""
    wk = ws.wk
    pk = ws.pk
    ke = END_STAGE[method]
    B = RK_B[method]
    ns = TRIAL_STAGES[method]
    for i in range(wk.shape[1]):
        acc = 0.0
        for j in range(ns):
            acc += B[j] * pk[j, i]
        wk[WK_A, i] = wk[WK_NOW, i]
        wk[WK_B, i] = wk[WK_NOW, i] + h * acc
        wk[WK_PA, i] = pk[0, i]
        wk[WK_PB, i] = pk[ke, i]
    ws.dense[DN_CUT] = 1.0


@kernel(inline=True)
def work_at(ws, theta, row):
    """ws.wk[row] = the works at ta + theta h of the last accepted step: the method's own dense output
    (`integrators.dense_eval`) applied to the works, whose stage derivatives are the stage powers ws.pk;
    the cubic Hermite of the end values and powers for a Hermite method (or rows not prepared)."""
    method = ws.flags[FL_DENSE_METHOD]
    rule = DENSE_RULE[method] if 0 <= method < N_METHODS else DENSE_NONE
    ready = rule == DENSE_ROWS and (ws.flags[FL_DENSE_READY] == 1 or EXTRA_STAGES[method] == 0)
    h = ws.dense[DN_H]
    th = theta
    wk = ws.wk
    if not ready:
        h00 = (2.0 * th - 3.0) * th * th + 1.0
        h10 = ((th - 2.0) * th + 1.0) * th
        h01 = (3.0 - 2.0 * th) * th * th
        h11 = (th - 1.0) * th * th
        for i in range(wk.shape[1]):
            wk[row, i] = h00 * wk[WK_A, i] + h01 * wk[WK_B, i] + h * (h10 * wk[WK_PA, i] + h11 * wk[WK_PB, i])
        return
    F = ws.wF
    nr = DENSE_ROWS_OF[method]
    x1 = 1.0 - th
    for i in range(wk.shape[1]):
        for r in range(nr):  # the rows F_r of `integrators.dense_rows`, for the works
            acc = 0.0
            for n in range(DENSE_NZ[method, r]):
                acc += DENSE_W[method, r, n] * ws.pk[DENSE_J[method, r, n], i]
            prev = F[r - 1] if r > 0 else 0.0
            F[r] = DENSE_DY[method, r] * (wk[WK_B, i] - wk[WK_A, i]) + h * acc - DENSE_PREV[method, r] * prev
        acc = 0.0
        r = nr - 1
        if r % 2 == 0:
            acc = (F[r] + 0.0) * th
            r -= 1
        while r > 0:
            acc = ((F[r] + acc) * x1 + F[r - 1]) * th
            r -= 2
        wk[row, i] = wk[WK_A, i] + acc


@kernel(inline=True)
def work_end(ws):
    """The works at the end of the kept part of the last step (all of it unless an event cut it)."""
    th = ws.dense[DN_CUT]
    if th >= 1.0:
        for i in range(ws.wk.shape[1]):
            ws.wk[WK_NOW, i] = ws.wk[WK_B, i]
    else:
        work_at(ws, th, WK_NOW)


@kernel(inline=True)
def work_restore(ws):
    """The works back at the start of the last step (its end state was refused)."""
    for i in range(ws.wk.shape[1]):
        ws.wk[WK_NOW, i] = ws.wk[WK_A, i]


@kernel
def kinetic_energy(km, qd):
    """T = sum m v^2 / 2 + I omega^2 / 2."""
    T = 0.0
    for b in range(km.body_mass.shape[0]):
        T += (0.5 * km.body_mass[b] * (qd[3 * b] ** 2 + qd[3 * b + 1] ** 2)
              + 0.5 * km.body_inertia[b] * qd[3 * b + 2] ** 2)
    if km.beam_info.shape[0] > 0:
        T += beam_kinetic(km, qd)
    return T


@kernel
def energy_start(km, q, qd, contact, ws):
    """The reference of the energy balance at the first state (contact modes set): T + V, the loads'
    potential and each clearance element's elastic energy into ws.energy0; every work from 0."""
    Vf = force_potential(km, q, qd)
    Vc = contact_energy(km, q, qd, contact) if km.clearance_body.shape[0] > 0 else 0.0
    if km.beam_info.shape[0] > 0:
        Vc += beam_strain_energy(km, q)
    ws.energy0[0] = kinetic_energy(km, qd) + Vf + Vc
    ws.energy0[1] = Vf
    for k in range(km.clearance_body.shape[0]):
        ws.energy0[2 + k] = clearance_energy(km, k, q, qd, contact)
    for i in range(ws.wk.shape[1]):
        ws.wk[WK_NOW, i] = 0.0
    ws.flags[FL_ENERGY0] = 1
