"""Constraint rows of ideal joints and drivers: C, Cq, Ct and gamma (Nikravesh).

Body ``b`` owns ``q[3b:3b+3] = (x, y, phi)``; a point ``s`` (body frame) sits at
``P = r + A s``.  With the rotated arm ``a = A s`` and ``perp(a) = (-a_y, a_x)``:

* ``dP/dphi = perp(a)``, ``P' = r' + phi' perp(a)``,
* ``P'' = r'' + phi'' perp(a) - phi'^2 a``.

Ground (body -1) has no coordinates: ``P = s``, no Jacobian columns, no velocity.

``gamma`` is the right side of the acceleration equation ``Cq q'' = gamma``:
``gamma = -(Cq q')_q q' - 2 Cq_t q' - C_tt``, i.e. minus every term of ``C''``
that does not contain ``q''``.  Drivers are ``C = g(q) - f(t)``: ``Ct = -f'`` and
``gamma`` gets ``+f''``.

The translational and revolute-translational joints use ``joint_axis`` as the
sliding direction ``u`` in body i's frame; their normal is ``n = perp(u)``
rotated with body i: ``n_i = A_i perp(u)``.  The POSITION driver measures along
``u_i = A_i driver_axis``.
"""
from __future__ import annotations

import math

import numpy as np
from .jit import kernel

from ..mechanism.model import JOINT_ROWS, JP, DriverType, JointType, MotionType, Status
from .expressions import expr_dual, expression_scratch

REVOLUTE = int(JointType.REVOLUTE)
TRANSLATIONAL = int(JointType.TRANSLATIONAL)
WELD = int(JointType.WELD)
REVOLUTE_REVOLUTE = int(JointType.REVOLUTE_REVOLUTE)
REVOLUTE_TRANSLATIONAL = int(JointType.REVOLUTE_TRANSLATIONAL)
BEAM_SLOPE = int(JointType.BEAM_SLOPE)
# the joint_param columns of the joint types' settings (catalog.JointSetting.column)
PHI0 = JP["phi0"]
LENGTH = JP["length"]

BAD_INPUT = int(Status.BAD_INPUT)

ANGLE = int(DriverType.ANGLE)
POSITION = int(DriverType.POSITION)

CONSTANT_SPEED = int(MotionType.CONSTANT_SPEED)
RAMP = int(MotionType.RAMP)
HARMONIC = int(MotionType.HARMONIC)
POLYNOMIAL = int(MotionType.POLYNOMIAL)
EXPRESSION = int(MotionType.EXPRESSION)

# rows per joint type (catalog.JOINTS), frozen by numba as a constant array
_JOINT_ROWS = np.ascontiguousarray(JOINT_ROWS)


@kernel
def body_state(q, qd, b):
    """(x, y, phi, vx, vy, omega) of body b; zeros for ground (b = -1)."""
    if b < 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    k = 3 * b
    return q[k], q[k + 1], q[k + 2], qd[k], qd[k + 1], qd[k + 2]


@kernel
def point_state(q, qd, b, sx, sy):
    """Global point of body b: (Px, Py, ax, ay, vx, vy, w) with arm a = A s,
    velocity P' and the body's angular velocity w (ground: a = s, P = s)."""
    if b < 0:
        return sx, sy, sx, sy, 0.0, 0.0, 0.0
    k = 3 * b
    c = math.cos(q[k + 2])
    s = math.sin(q[k + 2])
    ax = c * sx - s * sy
    ay = s * sx + c * sy
    w = qd[k + 2]
    return q[k] + ax, q[k + 1] + ay, ax, ay, qd[k] - w * ay, qd[k + 1] + w * ax, w


@kernel
def body_trig(q, cs):
    """cs[b] = (cos phi_b, sin phi_b) of every body: computed once per right-hand side."""
    for b in range(cs.shape[0]):
        cs[b, 0] = math.cos(q[3 * b + 2])
        cs[b, 1] = math.sin(q[3 * b + 2])


@kernel
def point_cs(q, qd, cs, b, sx, sy):
    """`point_state` with the body's cos/sin taken from cs (see `body_trig`)."""
    if b < 0:
        return sx, sy, sx, sy, 0.0, 0.0, 0.0
    k = 3 * b
    c = cs[b, 0]
    s = cs[b, 1]
    ax = c * sx - s * sy
    ay = s * sx + c * sy
    w = qd[k + 2]
    return q[k] + ax, q[k + 1] + ay, ax, ay, qd[k] - w * ay, qd[k + 1] + w * ax, w


@kernel
def add_point_jac(J, row, slot, b, ax, ay, wx, wy, sign):
    """J[row, slot] += sign * w . dP/dq_b for the point with arm a (nothing for ground)."""
    if b < 0:
        return
    J[row, slot, 0] += sign * wx
    J[row, slot, 1] += sign * wy
    J[row, slot, 2] += sign * (-wx * ay + wy * ax)


@kernel
def motion(mtype, p, t):
    """Prescribed motion f(t), f'(t), f''(t) of a driver (MotionType code)."""
    if mtype == CONSTANT_SPEED:
        return p[0] + p[1] * t, p[1], 0.0
    if mtype == RAMP:
        if p[2] <= 0.0 or t >= p[2]:
            if p[2] <= 0.0:
                return p[0] + p[1] * t, p[1], 0.0
            return p[0] + p[1] * (t - 0.5 * p[2]), p[1], 0.0
        if t <= 0.0:
            return p[0], 0.0, 0.0
        return p[0] + p[1] * t * t / (2.0 * p[2]), p[1] * t / p[2], p[1] / p[2]
    if mtype == HARMONIC:
        w = 2.0 * math.pi * p[2]
        s = math.sin(w * t + p[3])
        c = math.cos(w * t + p[3])
        return p[0] + p[1] * s, p[1] * w * c, -p[1] * w * w * s
    # POLYNOMIAL (Horner), 8 coefficients
    f = 0.0
    fd = 0.0
    fdd = 0.0
    for k in range(7, -1, -1):
        fdd = fdd * t + 2.0 * fd
        fd = fd * t + f
        f = f * t + p[k]
    return f, fd, fdd


@kernel(inline=True)
def driver_motion(km, reg, modes, d, t):
    """f(t), f'(t), f''(t) of driver d: its motion law, or its expression program by dual numbers.
    Inlined: a call that is not passes every array of the KernelModel (kernel/jit.py)."""
    mtype = km.driver_motion[d]
    if mtype == EXPRESSION:
        return expr_dual(km, reg, modes, int(km.driver_motion_param[d, 0]), t)
    return motion(mtype, km.driver_motion_param[d], t)


@kernel(inline=True)
def constraint_rows_eval(km, q, qd, t, cs, C, J, Ct, gamma, reg, modes):
    """Fill C (m), the row-sparse Jacobian J (m, 2, 3), Ct (m) and gamma (m) of every
    joint and driver row; cs holds the bodies' cos/sin (`body_trig`).

    Row r involves at most two bodies, ``rowbody[r] = (i, j)`` of its joint or
    driver (`row_bodies`); ``J[r, 0]`` is dC_r/dq_i and ``J[r, 1]`` dC_r/dq_j
    (zero for ground).  ``gamma`` is the right side of ``Cq q'' = gamma`` (no
    Baumgarte terms).  Returns 0 (Status.DONE) or Status.BAD_INPUT for an
    unknown type code.  Its parts are inlined: it is on the hot path (kernel/jit.py)."""
    m = C.shape[0]
    for r in range(m):
        C[r] = 0.0
        Ct[r] = 0.0
        gamma[r] = 0.0
        for a in range(2):
            for k in range(3):
                J[r, a, k] = 0.0
    nj = km.joint_type.shape[0]
    for jt in range(nj):
        if joint_rows_eval(km, jt, q, qd, cs, C, J, gamma) != 0:
            return BAD_INPUT
    nd = km.driver_type.shape[0]
    for d in range(nd):
        if driver_rows_eval(km, d, q, qd, t, cs, C, J, Ct, gamma, reg, modes) != 0:
            return BAD_INPUT
    return 0


@kernel(inline=True)
def joint_rows_eval(km, jt, q, qd, cs, C, J, gamma):
    """C, J and gamma of the rows of ideal joint jt, from row ``joint_row[jt]`` on (its settings:
    ``joint_axis[jt]`` and ``joint_param[jt, JP[column]]``, catalog.JointSetting).  Returns 0, or
    Status.BAD_INPUT for a type code without rows here."""
    typ = km.joint_type[jt]
    bi = km.joint_body[jt, 0]
    bj = km.joint_body[jt, 1]
    r = km.joint_row[jt]
    Pix, Piy, aix, aiy, vix, viy, wi = point_cs(q, qd, cs, bi, km.joint_point[jt, 0, 0], km.joint_point[jt, 0, 1])
    Pjx, Pjy, ajx, ajy, vjx, vjy, wj = point_cs(q, qd, cs, bj, km.joint_point[jt, 1, 0], km.joint_point[jt, 1, 1])
    # quadratic parts of P_i'', P_j''
    gix = -wi * wi * aix
    giy = -wi * wi * aiy
    gjx = -wj * wj * ajx
    gjy = -wj * wj * ajy
    if typ == REVOLUTE or typ == WELD:
        C[r] = Pix - Pjx
        C[r + 1] = Piy - Pjy
        add_point_jac(J, r, 0, bi, aix, aiy, 1.0, 0.0, 1.0)
        add_point_jac(J, r, 1, bj, ajx, ajy, 1.0, 0.0, -1.0)
        add_point_jac(J, r + 1, 0, bi, aix, aiy, 0.0, 1.0, 1.0)
        add_point_jac(J, r + 1, 1, bj, ajx, ajy, 0.0, 1.0, -1.0)
        gamma[r] = -(gix - gjx)
        gamma[r + 1] = -(giy - gjy)
        if typ == WELD:
            _angle_row(km, jt, q, qd, bi, bj, C, J, r + 2)
    elif typ == TRANSLATIONAL or typ == REVOLUTE_TRANSLATIONAL:
        rn = r
        if typ == TRANSLATIONAL:
            _angle_row(km, jt, q, qd, bi, bj, C, J, r)
            rn = r + 1
        C[rn], gamma[rn] = _axis_row(J, rn, cs, bi, bj, Pix, Piy, aix, aiy, vix, viy, wi,
                                     Pjx, Pjy, ajx, ajy, vjx, vjy, wj,
                                     -km.joint_axis[jt, 1], km.joint_axis[jt, 0])
    elif typ == REVOLUTE_REVOLUTE:
        dx = Pjx - Pix
        dy = Pjy - Piy
        ddx = vjx - vix
        ddy = vjy - viy
        L = km.joint_param[jt, LENGTH]
        C[r] = 0.5 * (dx * dx + dy * dy - L * L)
        add_point_jac(J, r, 1, bj, ajx, ajy, dx, dy, 1.0)
        add_point_jac(J, r, 0, bi, aix, aiy, dx, dy, -1.0)
        gamma[r] = -(ddx * ddx + ddy * ddy + dx * (gjx - gix) + dy * (gjy - giy))
    elif typ == BEAM_SLOPE:
        C[r], gamma[r] = _slope_row(J, r, q, qd, cs, bi, bj, -km.joint_axis[jt, 1], km.joint_axis[jt, 0])
    else:  # a type code without rows here
        return BAD_INPUT
    return 0


@kernel
def _slope_row(J, row, q, qd, cs, bi, bj, nlx, nly):
    """Row ``C = n_i . s_j`` with ``n_i = A_i nl``: s_j = (x_j, y_j) is the slope (dx/ds, dy/ds) of a beam's
    node, held as the position of its slope body.  Fills J[row], returns (C, gamma):
    ``C'' = n.s'' + 2 phi_i' perp(n).s' + phi_i'' perp(n).s - phi_i'^2 n.s``."""
    c = 1.0
    s = 0.0
    wi = 0.0
    if bi >= 0:
        c = cs[bi, 0]
        s = cs[bi, 1]
        wi = qd[3 * bi + 2]
    nx = c * nlx - s * nly
    ny = s * nlx + c * nly
    sx, sy, _, vx, vy, _ = body_state(q, qd, bj)
    if bj >= 0:
        J[row, 1, 0] += nx
        J[row, 1, 1] += ny
    if bi >= 0:
        J[row, 0, 2] += -ny * sx + nx * sy
    quad = 2.0 * wi * (-ny * vx + nx * vy) - wi * wi * (nx * sx + ny * sy)
    return nx * sx + ny * sy, -quad


@kernel(inline=True)
def driver_rows_eval(km, d, q, qd, t, cs, C, J, Ct, gamma, reg, modes):
    """C, J, Ct and gamma of the row of driver d at time t.  Returns 0 or Status.BAD_INPUT."""
    r = km.driver_row[d]
    bi = km.driver_body[d, 0]
    bj = km.driver_body[d, 1]
    f, fd, fdd = driver_motion(km, reg, modes, d, t)
    typ = km.driver_type[d]
    if typ == ANGLE:
        _, _, phi_i, _, _, _ = body_state(q, qd, bi)
        _, _, phi_j, _, _, _ = body_state(q, qd, bj)
        C[r] = phi_j - phi_i - f
        if bj >= 0:
            J[r, 1, 2] += 1.0
        if bi >= 0:
            J[r, 0, 2] -= 1.0
        gamma[r] = fdd
    elif typ == POSITION:
        Pix, Piy, aix, aiy, vix, viy, wi = point_cs(q, qd, cs, bi, km.driver_point[d, 0, 0], km.driver_point[d, 0, 1])
        Pjx, Pjy, ajx, ajy, vjx, vjy, wj = point_cs(q, qd, cs, bj, km.driver_point[d, 1, 0], km.driver_point[d, 1, 1])
        g, gg = _axis_row(J, r, cs, bi, bj, Pix, Piy, aix, aiy, vix, viy, wi,
                          Pjx, Pjy, ajx, ajy, vjx, vjy, wj,
                          km.driver_axis[d, 0], km.driver_axis[d, 1])
        C[r] = g - f
        gamma[r] = gg + fdd
    else:
        return BAD_INPUT
    Ct[r] = -fd
    return 0


@kernel
def _angle_row(km, jt, q, qd, bi, bj, C, J, row):
    """The relative-angle row of a weld or a translational joint: phi_j - phi_i - phi0 = 0 (its gamma
    is 0: the row is linear in the coordinates)."""
    _, _, phi_i, _, _, _ = body_state(q, qd, bi)
    _, _, phi_j, _, _, _ = body_state(q, qd, bj)
    C[row] = phi_j - phi_i - km.joint_param[jt, PHI0]
    if bj >= 0:
        J[row, 1, 2] += 1.0
    if bi >= 0:
        J[row, 0, 2] -= 1.0


@kernel
def _axis_row(J, row, cs, bi, bj, Pix, Piy, aix, aiy, vix, viy, wi,
              Pjx, Pjy, ajx, ajy, vjx, vjy, wj, nlx, nly):
    """Row ``C = n_i . (P_j - P_i)`` with ``n_i = A_i nl`` (nl in body i's frame).

    Fills J[row] and returns (C, gamma).  With d = P_j - P_i:
    ``C'' = n.d'' + 2 phi_i' perp(n).d' + phi_i'' perp(n).d - phi_i'^2 n.d``."""
    c = 1.0
    s = 0.0
    if bi >= 0:
        c = cs[bi, 0]
        s = cs[bi, 1]
    nx = c * nlx - s * nly
    ny = s * nlx + c * nly
    dx = Pjx - Pix
    dy = Pjy - Piy
    ddx = vjx - vix
    ddy = vjy - viy
    add_point_jac(J, row, 1, bj, ajx, ajy, nx, ny, 1.0)
    add_point_jac(J, row, 0, bi, aix, aiy, nx, ny, -1.0)
    pnd = -ny * dx + nx * dy  # perp(n) . d
    if bi >= 0:
        J[row, 0, 2] += pnd
    # quadratic part of d''
    qx = -wj * wj * ajx + wi * wi * aix
    qy = -wj * wj * ajy + wi * wi * aiy
    quad = nx * qx + ny * qy + 2.0 * wi * (-ny * ddx + nx * ddy) - wi * wi * (nx * dx + ny * dy)
    return nx * dx + ny * dy, -quad


def row_bodies(km) -> np.ndarray:
    """(m, 2) int64: the two bodies (i, j) of each constraint row (-1 = ground)."""
    m = constraint_rows(km)
    rb = np.full((m, 2), -1, dtype=np.int64)
    jt = np.asarray(km.joint_type, dtype=np.int64)
    for j in range(len(jt)):
        r0 = int(km.joint_row[j])
        rb[r0:r0 + int(_JOINT_ROWS[jt[j]])] = km.joint_body[j]
    for d in range(len(km.driver_type)):
        rb[int(km.driver_row[d])] = km.driver_body[d]
    return rb


def dense_jacobian(J: np.ndarray, rowbody: np.ndarray, n: int) -> np.ndarray:
    """The (m, n) Jacobian Cq from the row-sparse J (m, 2, 3)."""
    Cq = np.zeros((J.shape[0], n))
    for r in range(J.shape[0]):
        for a in range(2):
            b = rowbody[r, a]
            if b >= 0:
                Cq[r, 3 * b:3 * b + 3] += J[r, a]
    return Cq


def constraint_eval(km, q, qd, t, C, Cq, Ct, gamma) -> int:
    """Python helper (assembly, tests): fill C (m), the dense Cq (m, n), Ct (m) and
    gamma (m) through the kernel `constraint_rows_eval`.  Returns 0 or 7 (bad type code)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    qd = np.ascontiguousarray(qd, dtype=np.float64)
    nb = len(q) // 3
    cs = np.empty((nb, 2))
    for b in range(nb):  # the C library's cos and sin, as the compiled kernels call (numpy's own
        cs[b, 0] = math.cos(q[3 * b + 2])  # vectorised ones round by processor)
        cs[b, 1] = math.sin(q[3 * b + 2])
    m = C.shape[0]
    J = np.zeros((m, 2, 3))
    reg, modes, _ = expression_scratch(km)  # this call's own: the model stays read-only
    st = constraint_rows_eval(km, q, qd, float(t), cs, C, J, Ct, gamma, reg, modes)
    if st == 0:
        Cq[...] = dense_jacobian(J, row_bodies(km), len(q))
    return int(st)


def constraint_rows(km) -> int:
    """Number of constraint rows m (Python helper)."""
    return int(_JOINT_ROWS[np.asarray(km.joint_type, dtype=np.int64)].sum()) + int(len(km.driver_type))
