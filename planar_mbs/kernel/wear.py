"""A worn bearing: the radius of a revolute clearance joint's bearing as a function of angle.

The bearing surface, in the bearing body's frame, is r(theta) = R_B + w(theta): the nominal radius plus
the worn depth w, a periodic cubic spline through N equally spaced nodes theta_i = 2 pi i / N (Flores,
"Modeling and simulation of wear in revolute clearance joints in multibody systems", Mech. Mach. Theory
44 (2009); Mukras et al., "Analysis of planar multibody systems with revolute joint wear", Wear 268
(2010)).  The profile is the run's own data (it changes as the joint wears), kept in the columns of the
contact memory past N_CONTACT_STATE: ``contact[k, CT_WEAR_NODES]`` = N (0: the circle, the unworn code
path), then the N node depths w_i and the N second derivatives w''_i of the spline (in theta).

Contact of the journal circle (radius R_J, centre p in the bearing frame) with the profile: the deepest
point is the profile point c(theta) = r(theta) u(theta) nearest to p, the minimum of
f(theta) = |c(theta) - p|^2 / 2, found by a scan of the nodes within WINDOW of the angle of p and a
safeguarded Newton iteration on f'(theta) = (c - p).c' from the nearest node.  Penetration
delta = R_J - |c - p|, normal n = (c - p)/|c - p| (outward, the force on the journal is -F n).  For the
circle this is delta = |p| - (R_B - R_J), n = p/|p|: the unworn formulas.
"""
from __future__ import annotations

import math

from ..mechanism.model import CT_WEAR_NODES, CT_WEAR_TABLE
from .jit import kernel

WINDOW = 1.0 / 12.0  # half-width of the node scan around the angle of p, as a fraction of a turn
NEWTON_ITER = 40
THETA_TOL = 1e-15  # radians: Newton stops below this step


@kernel
def worn(contact, k):
    """True when joint k's bearing has a worn profile (else the circle: the unworn code path)."""
    return contact.shape[1] > CT_WEAR_NODES and contact[k, CT_WEAR_NODES] > 0.0


@kernel
def profile_at(contact, k, th):
    """(w, w', w'') of joint k's worn depth at angle th (any real; periodic cubic spline)."""
    N = int(contact[k, CT_WEAR_NODES])
    h = 2.0 * math.pi / N
    u = th / h
    fi = math.floor(u)
    t = u - fi
    i = int(fi) % N
    j = (i + 1) % N
    y0 = contact[k, CT_WEAR_TABLE + i]
    y1 = contact[k, CT_WEAR_TABLE + j]
    m0 = contact[k, CT_WEAR_TABLE + N + i]
    m1 = contact[k, CT_WEAR_TABLE + N + j]
    s = 1.0 - t
    w = s * y0 + t * y1 + h * h / 6.0 * ((s * s * s - s) * m0 + (t * t * t - t) * m1)
    dw = (y1 - y0) / h + h / 6.0 * (-(3.0 * s * s - 1.0) * m0 + (3.0 * t * t - 1.0) * m1)
    return w, dw, s * m0 + t * m1


@kernel
def _df(contact, k, rb, th, px, py):
    """(f', f'') of f(theta) = |c(theta) - p|^2 / 2, c = (R_B + w) u(theta)."""
    w, dw, ddw = profile_at(contact, k, th)
    r = rb + w
    c = math.cos(th)
    s = math.sin(th)
    dx = r * c - px
    dy = r * s - py
    c1x = dw * c - r * s  # c'
    c1y = dw * s + r * c
    c2x = (ddw - r) * c - 2.0 * dw * s  # c''
    c2y = (ddw - r) * s + 2.0 * dw * c
    return dx * c1x + dy * c1y, c1x * c1x + c1y * c1y + dx * c2x + dy * c2y


@kernel
def _nearest_node(contact, k, rb, px, py):
    """Angle of the node nearest to p within WINDOW of p's angle."""
    N = int(contact[k, CT_WEAR_NODES])
    h = 2.0 * math.pi / N
    rp = math.sqrt(px * px + py * py)
    te = math.atan2(py, px) if rp > 0.0 else 0.0
    i0 = int(math.floor(te / h + 0.5))
    m = max(1, int(N * WINDOW))
    best = math.inf
    tbest = te
    for j in range(i0 - m, i0 + m + 1):
        th = j * h
        r = rb + contact[k, CT_WEAR_TABLE + j % N]
        d2 = r * r + rp * rp - 2.0 * r * rp * math.cos(th - te)
        if d2 < best:
            best = d2
            tbest = th
    return tbest, h


@kernel
def nearest_angle(contact, k, rb, px, py):
    """Angle of the profile point nearest to p (bearing frame): the nearest node, then Newton on
    f'(theta) = 0 kept inside the node's two neighbouring intervals (bisection where it leaves them
    or f'' <= 0)."""
    tb, h = _nearest_node(contact, k, rb, px, py)
    lo = tb - h
    hi = tb + h
    glo, d = _df(contact, k, rb, lo, px, py)
    ghi, d = _df(contact, k, rb, hi, px, py)
    if not (glo < 0.0 and ghi > 0.0):
        return tb
    th = tb
    for it in range(NEWTON_ITER):
        g, dg = _df(contact, k, rb, th, px, py)
        if g == 0.0:
            return th
        if g < 0.0:
            lo = th
        else:
            hi = th
        step = g / dg if dg > 0.0 else math.inf
        new = th - step
        if not (new > lo and new < hi):
            new = 0.5 * (lo + hi)
        if abs(new - th) <= THETA_TOL:
            return new
        th = new
    return th


@kernel
def worn_contact(contact, k, rb, rj, px, py):
    """(delta, nx, ny, cx, cy, theta) of the journal circle (radius rj, centre p) against joint k's
    worn bearing, all in the bearing frame: penetration, outward normal, bearing contact point
    (from the bearing centre) and its angle."""
    th = nearest_angle(contact, k, rb, px, py)
    w, dw, ddw = profile_at(contact, k, th)
    r = rb + w
    cx = r * math.cos(th)
    cy = r * math.sin(th)
    dx = cx - px
    dy = cy - py
    d = math.sqrt(dx * dx + dy * dy)
    if d > 0.0:
        nx = dx / d
        ny = dy / d
    else:
        nx = math.cos(th)
        ny = math.sin(th)
    return rj - d, nx, ny, cx, cy, th


@kernel
def worn_kinematics(contact, k, rb, rj, ex, ey, ci, si, dvx, dvy, wi, wj, aix, aiy, ajx, ajy):
    """`contact._pair_kin` of a worn circle-in-circle joint: (ex, ey, e, delta, nx, ny, vn, vt, rix, riy,
    rjx, rjy) with ci, si the bearing body's cos/sin.  vn = d delta/dt = n . (the journal centre's velocity
    seen from the bearing body); vt = the tangential relative velocity of the two material contact points,
    (P_j' - P_i').t + w_j R_J - w_i (c . n)."""
    bx = ci * ex + si * ey
    by = -si * ex + ci * ey
    delta, nbx, nby, cbx, cby, th = worn_contact(contact, k, rb, rj, bx, by)
    nx = ci * nbx - si * nby
    ny = si * nbx + ci * nby
    cx = ci * cbx - si * cby
    cy = si * cbx + ci * cby
    vn = (dvx + wi * ey) * nx + (dvy - wi * ex) * ny
    vt = -dvx * ny + dvy * nx + wj * rj - wi * (cx * nx + cy * ny)
    e = math.sqrt(ex * ex + ey * ey)
    return ex, ey, e, delta, nx, ny, vn, vt, aix + cx, aiy + cy, ajx + rj * nx, ajy + rj * ny
