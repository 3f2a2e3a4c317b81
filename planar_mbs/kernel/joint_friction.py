"""Friction in ideal joints: a friction joint's slip coordinate, its rate and Jacobian, and its load.

A revolute joint with friction slips on its relative angle s = phi_j - phi_i (the friction torque T acts
on the second body, -T on the first); a translational joint on its sliding distance s = u_i . (P_j - P_i)
(the friction force T along the axis, on the second body at its point).  Either way T enters the
equations of motion as the generalised force J_s^T T, J_s = ds/dq, whose power is T s'.

Its bound is mu times the joint's load from its own reaction lambda (the multipliers of its rows): a pin,
mu r |lambda| (r the pin radius, |lambda| the norm of the two rows' reaction); a slide,
mu max(|lambda_n|, 2 |lambda_m| / l) (a block of length l centred on the second body's point, its two
ends carrying lambda_n / 2 -+ lambda_m / l; without l, mu |lambda_n|).  `dynamics.joint_friction` solves
for T together with lambda; the modes (stick, slip and its direction, the anchor) are the run's, rows
nclearance + f of its contact memory."""
from __future__ import annotations

import math

from .jit import kernel

from ..mechanism.model import JP_BLOCK_LENGTH, JP_PIN_RADIUS, JointType
from .constraints import _axis_row, point_cs, point_state

REVOLUTE = int(JointType.REVOLUTE)


@kernel
def slip_row(km, f, q, qd, cs, J):
    """J[f] (2, 3) = ds/dq on the two bodies of friction joint f (cs: the bodies' cos/sin); returns
    (s, s', gamma) with s'' = J_s q'' - gamma."""
    jt = km.joint_friction[f]
    bi = km.joint_body[jt, 0]
    bj = km.joint_body[jt, 1]
    for a in range(2):
        for k in range(3):
            J[f, a, k] = 0.0
    if km.joint_type[jt] == REVOLUTE:
        s = 0.0
        v = 0.0
        if bj >= 0:
            J[f, 1, 2] = 1.0
            s += q[3 * bj + 2]
            v += qd[3 * bj + 2]
        if bi >= 0:
            J[f, 0, 2] = -1.0
            s -= q[3 * bi + 2]
            v -= qd[3 * bi + 2]
        return s, v, 0.0
    Pix, Piy, aix, aiy, vix, viy, wi = point_cs(q, qd, cs, bi, km.joint_point[jt, 0, 0], km.joint_point[jt, 0, 1])
    Pjx, Pjy, ajx, ajy, vjx, vjy, wj = point_cs(q, qd, cs, bj, km.joint_point[jt, 1, 0], km.joint_point[jt, 1, 1])
    s, gam = _axis_row(J, f, cs, bi, bj, Pix, Piy, aix, aiy, vix, viy, wi, Pjx, Pjy, ajx, ajy, vjx, vjy, wj,
                       km.joint_axis[jt, 0], km.joint_axis[jt, 1])
    v = 0.0
    for a in range(2):
        b = bi if a == 0 else bj
        if b >= 0:
            for k in range(3):
                v += J[f, a, k] * qd[3 * b + k]
    return s, v, gam


@kernel
def slip_state(km, f, q, qd):
    """(s, s') of friction joint f at (q, q'), from the state alone (the events' switching functions)."""
    jt = km.joint_friction[f]
    bi = km.joint_body[jt, 0]
    bj = km.joint_body[jt, 1]
    phi_i = q[3 * bi + 2] if bi >= 0 else 0.0
    wi = qd[3 * bi + 2] if bi >= 0 else 0.0
    if km.joint_type[jt] == REVOLUTE:
        phi_j = q[3 * bj + 2] if bj >= 0 else 0.0
        wj = qd[3 * bj + 2] if bj >= 0 else 0.0
        return phi_j - phi_i, wj - wi
    Pix, Piy, aix, aiy, vix, viy, wi = point_state(q, qd, bi, km.joint_point[jt, 0, 0], km.joint_point[jt, 0, 1])
    Pjx, Pjy, ajx, ajy, vjx, vjy, wj = point_state(q, qd, bj, km.joint_point[jt, 1, 0], km.joint_point[jt, 1, 1])
    c = math.cos(phi_i)
    sn = math.sin(phi_i)
    ux = c * km.joint_axis[jt, 0] - sn * km.joint_axis[jt, 1]
    uy = sn * km.joint_axis[jt, 0] + c * km.joint_axis[jt, 1]
    dx = Pjx - Pix
    dy = Pjy - Piy
    return ux * dx + uy * dy, ux * (vjx - vix) + uy * (vjy - viy) + wi * (-uy * dx + ux * dy)


@kernel
def friction_load(km, f, l0, l1):
    """The load that multiplies mu in the bound of friction joint f, from its rows' multipliers (l0, l1):
    r |lambda| for a pin (N*m), max(|lambda_n|, 2 |lambda_m| / l) for a slide (N)."""
    jt = km.joint_friction[f]
    if km.joint_type[jt] == REVOLUTE:
        return km.joint_param[jt, JP_PIN_RADIUS] * math.sqrt(l0 * l0 + l1 * l1)
    load = abs(l1)
    length = km.joint_param[jt, JP_BLOCK_LENGTH]
    if length > 0.0:
        load = max(load, 2.0 * abs(l0) / length)
    return load


@kernel
def small_solve(A, ns, fs, fi, col):
    """Solve the ns x ns system in A[:ns, :ns] with right side A[:ns, ns] in place (Gaussian elimination,
    partial pivoting); the solution in A[:ns, ns].  Returns the first pivot row at or below 1e-9 of its
    scale fs[fi[row], col] (a stuck joint whose slip the other constraints already fix), else -1."""
    for c in range(ns):
        p = c
        for r in range(c + 1, ns):
            if abs(A[r, c]) > abs(A[p, c]):
                p = r
        if not (abs(A[p, c]) > 1e-9 * fs[fi[c], col]):
            return c
        if p != c:
            for k in range(ns + 1):
                A[p, k], A[c, k] = A[c, k], A[p, k]
        for r in range(c + 1, ns):
            x = A[r, c] / A[c, c]
            for k in range(c, ns + 1):
                A[r, k] -= x * A[c, k]
    for c in range(ns - 1, -1, -1):
        x = A[c, ns]
        for k in range(c + 1, ns):
            x -= A[c, k] * A[k, ns]
        A[c, ns] = x / A[c, c]
    return -1
