"""Applied generalized forces Qe and their potential energy.

Force elements (described in `catalog.FORCES`, whose ``param_columns`` name the columns of
``force_param (nforce, N_FORCE_PARAM)``; ``force_body (nforce, 2)``, ``force_point (nforce, 2, 2)``).
A new kind is its catalog entry plus its formula here: a branch of `force_element`, which adds its
generalized force into ``Qe`` (and of `force_potential` when it has a potential); its power
``Q_e . q'`` (`element_power`) and work follow for every kind alike.  An unknown code returns Status.BAD_INPUT:

* gravity: ``m g`` on every body's centre of mass, energy ``-m g.r``;
* CONSTANT_FORCE ``F = (p0, p1)`` (global) at point 0 of body 0: ``Q_r = F``,
  ``Q_phi = (A s) x F``; energy ``-F.P``;
* CONSTANT_TORQUE ``T = p0`` on body 0; energy ``-T phi``;
* SPRING_DAMPER between P_i (point 0 of body 0) and P_j (point 1 of body 1):
  tension ``f = k (l - l0) + c l' + f_act`` pulls the points together (f_act: p3 plus, when
  ``p4 > 0``, the expression whose result row is p4 - 1)
  (``+f u`` on i, ``-f u`` on j, ``u = (P_j - P_i)/l``); energy ``k (l - l0)^2 / 2``;
* ROTATIONAL_SPRING_DAMPER on ``a = phi_j - phi_i``: torque
  ``T = k (a - a0) + c a' + t_act``, ``-T`` on j and ``+T`` on i;
  energy ``k (a - a0)^2 / 2``;
* EXPRESSION: result rows ``p = (fx, fy, torque)`` (-1: none) of programs (`kernel.expressions`) of (t, q, q'):
  the global force (fx, fy) at point 0 of body 0 and a torque on it; no potential.  A value that is
  not finite is recorded in the run's ``ws.xfault`` (element, t), so a failing run names its expression.
"""
from __future__ import annotations

import math

from .jit import kernel

from ..mechanism.model import ForceType, Status
from .beam import beam_applied, beam_weight_potential
from .constraints import body_state, point_cs, point_state
from .expressions import run_rows

BAD_INPUT = int(Status.BAD_INPUT)

CONSTANT_FORCE = int(ForceType.CONSTANT_FORCE)
CONSTANT_TORQUE = int(ForceType.CONSTANT_TORQUE)
SPRING_DAMPER = int(ForceType.SPRING_DAMPER)
ROTATIONAL_SPRING_DAMPER = int(ForceType.ROTATIONAL_SPRING_DAMPER)
EXPRESSION = int(ForceType.EXPRESSION)


@kernel
def add_point_force(Qe, b, ax, ay, fx, fy):
    """Qe of body b += force (fx, fy) acting at the point with arm a = P - r."""
    if b < 0:
        return
    k = 3 * b
    Qe[k] += fx
    Qe[k + 1] += fy
    Qe[k + 2] += ax * fy - ay * fx


@kernel(inline=True)
def applied_forces(km, ws, t, q, qd):
    """ws.Qe = gravity + force elements at time t (overwrites it); ws.cs: bodies' cos/sin (`body_trig`).
    Also each element's power Q_e . q' into ws.pw (`model.work_layout`: the forces', then gravity's) and
    its reported values into ws.fv (`force_element`).  Returns 0 or 7 (bad code)."""
    cs = ws.cs
    Qe = ws.Qe
    nb = km.body_mass.shape[0]
    gx = km.gravity[0]
    gy = km.gravity[1]
    pg = 0.0
    for b in range(nb):
        Qe[3 * b] = km.body_mass[b] * gx
        Qe[3 * b + 1] = km.body_mass[b] * gy
        Qe[3 * b + 2] = 0.0
        pg += Qe[3 * b] * qd[3 * b] + Qe[3 * b + 1] * qd[3 * b + 1]
    if km.expr_loads[1] > km.expr_loads[0]:  # every expression load's rows, in one call
        run_rows(km.expr_code, km.expr_const, ws.xreg, ws.xmode, km.table_info, km.table_period,
                 km.table_seg, km.expr_loads[0], km.expr_loads[1], t, q, qd)
    if km.beam_info.shape[0] > 0:
        pg += beam_applied(km, ws, q, qd)
    nf = km.force_type.shape[0]
    ws.pw[nf] = pg
    for e in range(nf):
        st = element_power(km, ws, e, t, q, qd, cs, Qe)
        if st != 0:
            return st
    return 0


@kernel(inline=True)
def element_power(km, ws, e, t, q, qd, cs, Qe):
    """Qe += the generalized force Q_e of element e (`force_element`), and its power Q_e . q' into
    ws.pw[e], for every kind alike: the change it made to the generalized forces of its bodies
    times their velocities.  Returns 0 or BAD_INPUT."""
    bi = km.force_body[e, 0]
    bj = km.force_body[e, 1]
    if bj == bi:
        bj = -1
    s = ws.fsave
    for i in range(3):
        s[i] = Qe[3 * bi + i] if bi >= 0 else 0.0
        s[3 + i] = Qe[3 * bj + i] if bj >= 0 else 0.0
    for i in range(ws.fv.shape[1]):
        ws.fv[e, i] = 0.0
    st = force_element(km, ws, e, t, q, qd, cs, Qe)
    if st != 0:
        return st
    P = 0.0
    for i in range(3):
        if bi >= 0:
            P += (Qe[3 * bi + i] - s[i]) * qd[3 * bi + i]
        if bj >= 0:
            P += (Qe[3 * bj + i] - s[3 + i]) * qd[3 * bj + i]
    ws.pw[e] = P
    return 0


@kernel(inline=True)
def force_element(km, ws, e, t, q, qd, cs, Qe):
    """Qe += the generalized force of force element e at (t, q, q'): its kind's formula (module
    docstring); the values its catalog entry reports (`ForceSpec.signals`) into ws.fv[e].  Its power
    and work follow from Qe alone (`element_power`).  Returns 0 or BAD_INPUT (unknown kind)."""
    typ = km.force_type[e]
    bi = km.force_body[e, 0]
    bj = km.force_body[e, 1]
    p = km.force_param[e]
    v = ws.fv[e]
    if typ == CONSTANT_FORCE:
        Px, Py, ax, ay, vx, vy, w = point_cs(q, qd, cs, bi, km.force_point[e, 0, 0], km.force_point[e, 0, 1])
        add_point_force(Qe, bi, ax, ay, p[0], p[1])
        v[0] = p[0]
        v[1] = p[1]
    elif typ == CONSTANT_TORQUE:
        if bi >= 0:
            Qe[3 * bi + 2] += p[0]
        v[0] = p[0]
    elif typ == SPRING_DAMPER:
        Pix, Piy, aix, aiy, vix, viy, wi = point_cs(q, qd, cs, bi, km.force_point[e, 0, 0], km.force_point[e, 0, 1])
        Pjx, Pjy, ajx, ajy, vjx, vjy, wj = point_cs(q, qd, cs, bj, km.force_point[e, 1, 0], km.force_point[e, 1, 1])
        dx = Pjx - Pix
        dy = Pjy - Piy
        l = math.sqrt(dx * dx + dy * dy)
        if l > 0.0:  # else the direction is undefined: no force
            ux = dx / l
            uy = dy / l
            ld = ux * (vjx - vix) + uy * (vjy - viy)
            f = p[0] * (l - p[2]) + p[1] * ld + p[3] + _load_value(km, ws, e, int(p[4]) - 1, t)
            add_point_force(Qe, bi, aix, aiy, f * ux, f * uy)
            add_point_force(Qe, bj, ajx, ajy, -f * ux, -f * uy)
            v[0] = f
            v[2] = ld
        v[1] = l
    elif typ == ROTATIONAL_SPRING_DAMPER:
        _, _, phi_i, _, _, w_i = body_state(q, qd, bi)
        _, _, phi_j, _, _, w_j = body_state(q, qd, bj)
        T = p[0] * (phi_j - phi_i - p[2]) + p[1] * (w_j - w_i) + p[3] + _load_value(km, ws, e, int(p[4]) - 1, t)
        if bj >= 0:
            Qe[3 * bj + 2] -= T
        if bi >= 0:
            Qe[3 * bi + 2] += T
        v[0] = T
        v[1] = phi_j - phi_i
        v[2] = w_j - w_i
    elif typ == EXPRESSION:
        expression_load(km, ws, e, t, q, qd, cs, Qe)
    else:
        return BAD_INPUT
    return 0


@kernel(inline=True)
def _load_value(km, ws, e, k, t):
    """The value of result row k of force element e (0 for none; `applied_forces` has run the rows);
    a non-finite value is recorded."""
    if k < 0:
        return 0.0
    v = ws.xreg[k, 0]
    if not math.isfinite(v):
        ws.xfault[0] = e
        ws.xfault[1] = t
    return v


@kernel(inline=True)
def expression_load(km, ws, e, t, q, qd, cs, Qe):
    """Qe += the force (fx, fy) and torque of expression element e: its result rows, which
    `applied_forces` has just evaluated."""
    bi = km.force_body[e, 0]
    p = km.force_param[e]
    fx = _load_value(km, ws, e, int(p[0]), t)
    fy = _load_value(km, ws, e, int(p[1]), t)
    tq = _load_value(km, ws, e, int(p[2]), t)
    Px, Py, ax, ay, vx, vy, w = point_cs(q, qd, cs, bi, km.force_point[e, 0, 0], km.force_point[e, 0, 1])
    add_point_force(Qe, bi, ax, ay, fx, fy)
    if bi >= 0:
        Qe[3 * bi + 2] += tq
    ws.fv[e, 0] = fx
    ws.fv[e, 1] = fy
    ws.fv[e, 2] = tq


@kernel
def force_potential(km, q, qd):
    """Potential energy of gravity and the force elements (dampers and actuators
    have none; an actuator's constant tension is not counted)."""
    V = 0.0
    nb = km.body_mass.shape[0]
    for b in range(nb):
        V -= km.body_mass[b] * (km.gravity[0] * q[3 * b] + km.gravity[1] * q[3 * b + 1])
    if km.beam_info.shape[0] > 0:
        V += beam_weight_potential(km, q)
    nf = km.force_type.shape[0]
    for e in range(nf):
        typ = km.force_type[e]
        bi = km.force_body[e, 0]
        bj = km.force_body[e, 1]
        p = km.force_param[e]
        if typ == CONSTANT_FORCE:
            if bi >= 0:
                Px, Py, ax, ay, vx, vy, w = point_state(q, qd, bi, km.force_point[e, 0, 0], km.force_point[e, 0, 1])
                V -= p[0] * Px + p[1] * Py
        elif typ == CONSTANT_TORQUE:
            if bi >= 0:
                V -= p[0] * q[3 * bi + 2]
        elif typ == SPRING_DAMPER:
            Pix, Piy, aix, aiy, vix, viy, wi = point_state(q, qd, bi, km.force_point[e, 0, 0], km.force_point[e, 0, 1])
            Pjx, Pjy, ajx, ajy, vjx, vjy, wj = point_state(q, qd, bj, km.force_point[e, 1, 0], km.force_point[e, 1, 1])
            l = math.sqrt((Pjx - Pix) ** 2 + (Pjy - Piy) ** 2)
            V += 0.5 * p[0] * (l - p[2]) ** 2
        elif typ == ROTATIONAL_SPRING_DAMPER:
            _, _, phi_i, _, _, w_i = body_state(q, qd, bi)
            _, _, phi_j, _, _, w_j = body_state(q, qd, bj)
            V += 0.5 * p[0] * (phi_j - phi_i - p[2]) ** 2
    return V
