"""Contact-mode events of clearance joints, located on the dense output.

The event function of joint k is its penetration ``g = delta = e - c``.  In
free-flight mode the event is a crossing from - to + (onset), in contact mode
from + to - (separation); ``sgn`` turns both into "g becomes positive".

After each accepted step the *deepest point* of g inside the step is found:
g and its rate dg/dtheta = h sgn delta' are known exactly at both ends (from
the states); their cubic Hermite interpolant shows whether g has an interior
maximum, which is then located as the zero of dg/dtheta on the dense output
(the dense state holds the velocities), by the Illinois variant of regula falsi.
A grazing contact that begins and ends inside one step (an apex penetration
of a fraction of a micrometre in a long free-flight step) is found however
short it is; fixed samples (1/4, 1/2, 3/4) missed those.  When g is positive
at the deepest point (or at the step end), the crossing before it is refined
by the same method to about 1e-12 relative time; the step is cut at the
bracket end on the new side, and the earliest crossing over all joints wins
(cf. SciPy ``_ivp/ivp.py``: sign change, root on the dense output).

The friction of a stick model (`contact.sticks`) switches the same way: a stuck contact slips when its
spring-damper's force reaches mu_s F_N (g = |F_T| - mu_s F_N), a slipping one sticks when its slip
velocity crosses zero (g = -d v_T, d the slip direction); these are found from a sign change over the
step and refined by the same regula falsi (`locate_friction`), event index nc + k for element k.

The friction of an ideal joint (`kernel.joint_friction`) switches alike, event index 2 nc + f for friction
joint f: a slipping joint sticks where its slip rate crosses zero, if the friction that holds it stays
within mu_s times its load (else it slips on the other way); a stuck one slips when that friction reaches
mu_s times its load (g = |T| - mu_s load, from the constraint solve at the state: `accelerations`).

The comparisons of expressions (`kernel.expressions`) are switches of the same kind: `locate_switch`
finds the earliest one whose live value differs from its frozen value at the step's end, by
bisection on the dense output to the same relative time ROOT_RTOL.
"""
from __future__ import annotations

import math

from .jit import kernel
from ..mechanism.model import (CP_STATIC_FRICTION, CT_FRICTION, CT_IMPACT_VELOCITY, CT_MODE, CT_SLIP_DIRECTION, FREE,
                               NO_FRICTION_MODE, SLIP, STICK, TOUCHING)
from .contact import contact_mode, normal_force, pair_kinematics, set_anchor, state_index, stick_force, sticks

from ..mechanism.model import CT_ANCHOR, ST_CONTACT_EVENTS
from .contact import IMPACT_VELOCITY_FLOOR, clearance_kinematics
from .dynamics import accelerations
from .integrators import dense_eval
from .expressions import live_switch
from .joint_friction import slip_state
from .workspace import DN_H, DN_TA, JW_LIMIT, JW_T

ROOT_RTOL = 1e-12
PEAK_TOL = 1e-9  # step fraction to which the deepest point is located
MAX_ROOT_ITER = 200


@kernel
def _g(km, k, y, sgn, contact):
    """(g, dg/dt) of joint k at state y, signed so that the event is g becoming positive."""
    n = km.minv.shape[0]
    ex, ey, e, delta, nx, ny, vn, vt = clearance_kinematics(km, k, y[:n], y[n:2 * n], contact)
    return sgn * delta, sgn * vn


@kernel
def _cubic_peak(g0, d0, g1, d1):
    """(theta, value) of the interior local maximum of the cubic Hermite interpolant with
    p(0) = g0, p'(0) = d0, p(1) = g1, p'(1) = d1; theta = -1 when it has none in (0, 1)."""
    c2 = 3.0 * (g1 - g0) - 2.0 * d0 - d1
    c3 = 2.0 * (g0 - g1) + d0 + d1
    # p'(x) = d0 + 2 c2 x + 3 c3 x^2; a maximum where p' = 0 and p'' = 2 c2 + 6 c3 x < 0
    best = -1.0
    a = 3.0 * c3
    b = 2.0 * c2
    if a == 0.0:
        if b < 0.0:
            best = -d0 / b
    else:
        disc = b * b - 4.0 * a * d0
        if disc >= 0.0:
            r = math.sqrt(disc)
            for x in ((-b - r) / (2.0 * a), (-b + r) / (2.0 * a)):
                if 2.0 * c2 + 6.0 * c3 * x < 0.0:
                    best = x
    if not (best > 0.0 and best < 1.0):
        return -1.0, -math.inf
    x = best
    return x, g0 + x * (d0 + x * (c2 + x * c3))


@kernel
def _ends(km, ws, k, sgn, contact):
    """(g0, d0, g1, d1): g and dg/dtheta of joint k at the start and end of the last step."""
    h = ws.dense[DN_H]
    g0, v0 = _g(km, k, ws.ya, sgn, contact)
    g1, v1 = _g(km, k, ws.yb, sgn, contact)
    return g0, h * v0, g1, h * v1


@kernel(inline=True)
def event_possible(km, ws, contact, kend):
    """Screening for DOP853 (whose accurate dense output costs three extra stages): True
    when any joint's g is positive at the step end, or its cubic Hermite interpolant from the
    end values and rates has an interior maximum that could reach g > 0 (the cubic's rise above
    the higher end is allowed a 100 % error)."""
    nc = km.clearance_body.shape[0]
    for k in range(nc):
        sgn = 1.0 if contact_mode(contact, k) == FREE else -1.0
        g0, d0, g1, d1 = _ends(km, ws, k, sgn, contact)
        if g1 > 0.0:
            return True
        x, p = _cubic_peak(g0, d0, g1, d1)
        if x > 0.0 and 2.0 * p - max(g0, g1) > 0.0:
            return True
    return friction_possible(km, ws, contact)


@kernel
def _rate(km, ws, k, sgn, x, contact):
    """dg/dtheta of joint k on the dense output at step fraction x."""
    dense_eval(ws, x, ws.yt)
    g, v = _g(km, k, ws.yt, sgn, contact)
    return ws.dense[DN_H] * v


@kernel(inline=True)
def _peak(km, ws, k, sgn, g0, d0, g1, d1, contact):
    """Step fraction of the deepest interior point of g (the zero of dg/dtheta where it turns
    from + to -, on the dense output), or -1 when g has no interior maximum that could reach
    g > 0 (the same screening as `event_possible`)."""
    xc, p = _cubic_peak(g0, d0, g1, d1)
    if xc > 0.0 and 2.0 * p - max(g0, g1) <= 0.0:
        return -1.0  # even with a 100 % error in its rise, the cubic's peak stays below g = 0
    if d0 > 0.0 and d1 < 0.0:
        lo, flo, hi, fhi = 0.0, d0, 1.0, d1
    elif xc > 0.0:
        # both ends rise (or both fall) and the cubic has a maximum xc and a minimum xo inside:
        # bracket the maximum between an end and the midpoint of the two
        c2 = 3.0 * (g1 - g0) - 2.0 * d0 - d1
        c3 = 2.0 * (g0 - g1) + d0 + d1
        xo = -2.0 * c2 / (3.0 * c3) - xc if c3 != 0.0 else xc  # sum of the roots of p'
        if d0 > 0.0:  # maximum, then minimum
            lo, flo = 0.0, d0
            hi = min(1.0, 0.5 * (xc + max(xc, xo)))
            fhi = _rate(km, ws, k, sgn, hi, contact)
        else:  # minimum, then maximum
            lo = 0.5 * (xc + max(0.0, min(xc, xo)))
            flo = _rate(km, ws, k, sgn, lo, contact)
            hi, fhi = 1.0, d1
        if not (flo > 0.0 and fhi < 0.0):
            return -1.0
    else:
        return -1.0
    if xc > lo and xc < hi:  # the cubic's estimate as the first point
        fx = _rate(km, ws, k, sgn, xc, contact)
        if fx > 0.0:
            lo, flo = xc, fx
        elif fx < 0.0:
            hi, fhi = xc, fx
        else:
            return xc
    return _illinois_rate(km, ws, k, sgn, lo, flo, hi, fhi, contact)


@kernel(inline=True)
def _illinois_rate(km, ws, k, sgn, lo, flo, hi, fhi, contact):
    """Zero of dg/dtheta in [lo, hi] (flo > 0 > fhi), Illinois regula falsi."""
    side = 0
    for it in range(MAX_ROOT_ITER):
        if hi - lo <= PEAK_TOL:
            break
        x = (lo * fhi - hi * flo) / (fhi - flo) if it % 4 != 3 else 0.5 * (lo + hi)
        if not (x > lo and x < hi):
            x = 0.5 * (lo + hi)
        fx = _rate(km, ws, k, sgn, x, contact)
        if fx > 0.0:
            lo = x
            flo = fx
            if side == 1:
                fhi *= 0.5
            side = 1
        elif fx < 0.0:
            hi = x
            fhi = fx
            if side == -1:
                flo *= 0.5
            side = -1
        else:
            return x
    return 0.5 * (lo + hi)


@kernel(inline=True)
def _illinois_trial(it, lo, flo, hi, fhi):
    """The next point of Illinois regula falsi in [lo, hi] (flo <= 0 < fhi); every fourth, or on a
    flat bracket, the midpoint (the bisection safeguard)."""
    if it % 4 == 3 or not (fhi - flo > 0.0):
        return 0.5 * (lo + hi)
    x = (lo * fhi - hi * flo) / (fhi - flo)
    if not (x > lo and x < hi):
        return 0.5 * (lo + hi)
    return x


@kernel(inline=True)
def _illinois_narrow(x, fx, lo, flo, hi, fhi, side):
    """(lo, flo, hi, fhi, side) once g(x) = fx is known (g > 0 past the switch): x replaces the end on
    its side, and the end kept twice in a row has its value halved (Illinois)."""
    if fx > 0.0:
        if side == 1:
            flo *= 0.5
        side = 1
        return lo, flo, x, fx, side
    if side == -1:
        fhi *= 0.5
    side = -1
    return x, fx, hi, fhi, side


@kernel(inline=True)
def _crossing(km, ws, k, sgn, lo, flo, hi, fhi, tol, contact):
    """Bracket end on the new side (g > 0) of the crossing of g in [lo, hi] (flo <= 0 < fhi),
    refined by Illinois regula falsi (bisection safeguard) to tol."""
    side = 0
    for it in range(MAX_ROOT_ITER):
        if hi - lo <= tol:
            break
        x = _illinois_trial(it, lo, flo, hi, fhi)
        dense_eval(ws, x, ws.yt)
        fx, v = _g(km, k, ws.yt, sgn, contact)
        lo, flo, hi, fhi, side = _illinois_narrow(x, fx, lo, flo, hi, fhi, side)
    return hi


@kernel
def locate_event(km, ws, contact):
    """Earliest mode change inside the last step (dense segment ws.dense[DN_TA], ws.dense[DN_H]).

    Returns (k, theta): joint index (-1 if none; nc + k: element k's friction) and the step fraction
    of the bracket end on the new side of the switching surface."""
    nc = km.clearance_body.shape[0]
    ta = ws.dense[DN_TA]
    h = ws.dense[DN_H]
    best = 2.0
    kbest = -1
    tol = ROOT_RTOL * max(abs(ta), h) / h
    for k in range(nc):
        sgn = 1.0 if contact_mode(contact, k) == FREE else -1.0
        g0, d0, g1, d1 = _ends(km, ws, k, sgn, contact)
        x = _peak(km, ws, k, sgn, g0, d0, g1, d1, contact)
        lo = 0.0
        flo = min(g0, 0.0)
        hi = 2.0
        fhi = 0.0
        if x > 0.0:
            dense_eval(ws, x, ws.yt)
            gx, v = _g(km, k, ws.yt, sgn, contact)
            if gx > 0.0:
                hi = x
                fhi = gx
            elif g1 > 0.0:  # below the surface at the peak: the crossing comes after it
                lo = x
                flo = gx
        if hi > 1.0 and g1 > 0.0:
            hi = 1.0
            fhi = g1
        if hi > 1.0 or lo >= best:  # (the crossing lies in [lo, hi]: it may precede `best` even when hi does not)
            continue
        if g0 > 0.0:  # already on the new side at the step start (roundoff at a switch)
            hi = 0.0
        else:
            hi = _crossing(km, ws, k, sgn, lo, flo, hi, fhi, tol, contact)
        if hi < best:
            best = hi
            kbest = k
    return locate_friction(km, ws, contact, best, kbest)


@kernel
def friction_g(km, k, y, contact):
    """Event function of element k's friction mode at state y, positive past the switch: stuck,
    |F_T| - mu_s F_N of its spring-damper; slipping, -d v_T.  -1 when it has no friction mode or no force."""
    mode = int(contact[k, CT_FRICTION])
    if mode == NO_FRICTION_MODE or contact_mode(contact, k) == FREE:
        return -1.0
    n = km.minv.shape[0]
    ex, ey, e, delta, nx, ny, vn, vt, rix, riy, rjx, rjy = pair_kinematics(km, k, y[:n], y[n:2 * n], contact)
    if mode == SLIP:
        return -contact[k, CT_SLIP_DIRECTION] * vt
    if not (delta > 0.0):
        return -1.0
    law = km.clearance_law[k]
    p = km.clearance_param[k]
    F, st = normal_force(law, p, delta, vn, contact[k, CT_IMPACT_VELOCITY], 0.0)
    Ft = stick_force(km, k, y[:n], contact, law, delta, F, vt, ex, ey, nx, ny, rix, riy, rjx, rjy)
    return abs(Ft) - p[CP_STATIC_FRICTION] * F


@kernel
def friction_possible(km, ws, contact):
    """True when some element's friction event function is positive at the step end."""
    for k in range(km.clearance_body.shape[0]):
        if friction_g(km, k, ws.yb, contact) > 0.0:
            return True
    return False


@kernel
def locate_friction(km, ws, contact, best, kbest):
    """Earliest friction switch inside the last step before step fraction `best` (contact events'):
    (event index nc + k, or kbest when none is earlier; its step fraction on the new side)."""
    nc = km.clearance_body.shape[0]
    ta = ws.dense[DN_TA]
    h = ws.dense[DN_H]
    tol = ROOT_RTOL * max(abs(ta), h) / h
    for k in range(nc):
        if int(contact[k, CT_FRICTION]) == NO_FRICTION_MODE:
            continue
        g1 = friction_g(km, k, ws.yb, contact)
        if not (g1 > 0.0):
            continue
        g0 = friction_g(km, k, ws.ya, contact)
        if g0 > 0.0:  # already past the switch at the step start (roundoff at a switch)
            x = 0.0
        else:
            x = _friction_crossing(km, ws, contact, k, 0.0, g0, 1.0, g1, tol)
        if x < best:
            best = x
            kbest = nc + k
    return kbest, best


@kernel
def _friction_crossing(km, ws, contact, k, lo, flo, hi, fhi, tol):
    """Bracket end on the new side of the friction switch of element k in [lo, hi] (flo <= 0 < fhi)."""
    side = 0
    for it in range(MAX_ROOT_ITER):
        if hi - lo <= tol:
            break
        x = _illinois_trial(it, lo, flo, hi, fhi)
        dense_eval(ws, x, ws.yt)
        fx = friction_g(km, k, ws.yt, contact)
        lo, flo, hi, fhi, side = _illinois_narrow(x, fx, lo, flo, hi, fhi, side)
    return hi


@kernel
def start_friction(km, k, y, contact):
    """Friction mode of element k as its contact begins: stuck when the slip velocity is zero, else
    slipping its way (nothing for a model that does not stick)."""
    if not sticks(km.clearance_param[k]):
        return
    n = km.minv.shape[0]
    ex, ey, e, delta, nx, ny, vn, vt, rix, riy, rjx, rjy = pair_kinematics(km, k, y[:n], y[n:2 * n], contact)
    if vt == 0.0:
        set_anchor(km, k, y[:n], contact, ex, ey, nx, ny)
    else:
        contact[k, CT_FRICTION] = SLIP
        contact[k, CT_SLIP_DIRECTION] = 1.0 if vt > 0.0 else -1.0


@kernel
def switch_friction(km, k, y, contact, stats):
    """Switch element k's friction mode at state y (on the new side): a stuck contact slips against
    its spring-damper's force; a slipping one sticks where it is (its anchor)."""
    n = km.minv.shape[0]
    ex, ey, e, delta, nx, ny, vn, vt, rix, riy, rjx, rjy = pair_kinematics(km, k, y[:n], y[n:2 * n], contact)
    if int(contact[k, CT_FRICTION]) == STICK:
        law = km.clearance_law[k]
        F, st = normal_force(law, km.clearance_param[k], max(delta, 0.0), vn, contact[k, CT_IMPACT_VELOCITY], 0.0)
        Ft = stick_force(km, k, y[:n], contact, law, delta, F, vt, ex, ey, nx, ny, rix, riy, rjx, rjy)
        contact[k, CT_FRICTION] = SLIP
        contact[k, CT_SLIP_DIRECTION] = -1.0 if Ft > 0.0 else 1.0
    else:
        set_anchor(km, k, y[:n], contact, ex, ey, nx, ny)
    stats[ST_CONTACT_EVENTS] += 1


@kernel
def switch_mode(km, k, y, contact, stats):
    """Switch joint k's mode at state y (on the new side).  At an onset store the
    impact velocity delta'(-) = normal relative velocity (floored: see
    contact.IMPACT_VELOCITY_FLOOR), start its friction mode and count the contact event; at a
    separation reset its own state (LuGre's bristle deflection, z = 0); an event index nc + k switches
    element k's friction mode."""
    n = km.minv.shape[0]
    nc = km.clearance_body.shape[0]
    if k >= nc:
        switch_friction(km, k - nc, y, contact, stats)
    elif contact_mode(contact, k) == FREE:
        ex, ey, e, delta, nx, ny, vn, vt = clearance_kinematics(km, k, y[:n], y[n:2 * n], contact)
        contact[k, CT_MODE] = TOUCHING
        contact[k, CT_IMPACT_VELOCITY] = max(vn, IMPACT_VELOCITY_FLOOR)
        stats[ST_CONTACT_EVENTS] += 1
        start_friction(km, k, y, contact)
    else:
        contact[k, CT_MODE] = FREE
        contact[k, CT_FRICTION] = NO_FRICTION_MODE
        js = state_index(km.clearance_param[k])
        if js >= 0:  # the contact opens: LuGre's bristles relax (z = 0 until the next contact)
            y[2 * n + js] = 0.0


@kernel
def init_modes(km, y, contact):
    """At the start of a run: a joint already penetrating in free mode starts in
    contact mode (impact velocity = its current normal velocity, floored) and one touching without a
    friction mode starts it (`start_friction`)."""
    n = km.minv.shape[0]
    nc = km.clearance_body.shape[0]
    for k in range(nc):
        ex, ey, e, delta, nx, ny, vn, vt = clearance_kinematics(km, k, y[:n], y[n:2 * n], contact)
        if contact_mode(contact, k) == FREE and delta > 0.0:
            contact[k, CT_MODE] = TOUCHING
            contact[k, CT_IMPACT_VELOCITY] = vn
        if contact_mode(contact, k) == TOUCHING and contact[k, CT_IMPACT_VELOCITY] < IMPACT_VELOCITY_FLOOR:
            contact[k, CT_IMPACT_VELOCITY] = IMPACT_VELOCITY_FLOOR
        if contact_mode(contact, k) == TOUCHING and int(contact[k, CT_FRICTION]) == NO_FRICTION_MODE:
            start_friction(km, k, y, contact)


@kernel(inline=True)
def locate_switch(km, ws, best):
    """Earliest comparison of an expression that changes inside the last step before step fraction
    ``best`` (an earlier event's).  Returns (s, theta): its index (-1: none) and the step fraction
    of the bracket end on its new side."""
    ns = km.expr_switch.shape[0]
    ta = ws.dense[DN_TA]
    h = ws.dense[DN_H]
    n = km.minv.shape[0]
    tol = ROOT_RTOL * max(abs(ta), h) / h
    sbest = -1
    for s in range(ns):
        frozen = ws.xmode[km.expr_switch[s, 0]]
        if live_switch(km, ws.xreg, ws.xmode, s, ta + h, ws.yb[:n], ws.yb[n:2 * n]) == frozen:
            continue
        lo = 0.0
        hi = 1.0
        for _ in range(MAX_ROOT_ITER):  # the switch lies in (lo, hi]
            if hi - lo <= tol:
                break
            mid = 0.5 * (lo + hi)
            dense_eval(ws, mid, ws.yt)
            if live_switch(km, ws.xreg, ws.xmode, s, ta + mid * h, ws.yt[:n], ws.yt[n:2 * n]) == frozen:
                lo = mid
            else:
                hi = mid
        if hi < best:
            best = hi
            sbest = s
    return sbest, best


@kernel
def _friction_solve(km, cfg, t, y, contact, ws):
    """The constraint solve at state y, for its joint frictions (ws.fs): one inlined copy of
    `accelerations` for the events of every friction joint.  Returns its status."""
    n = km.minv.shape[0]
    for j in range(ws.z.shape[0]):  # the contact elements' own states (LuGre's bristles) at y
        ws.z[j] = y[2 * n + j]
    return accelerations(km, cfg, t, y[:n], y[n:2 * n], contact, ws, ws.sstats)


@kernel
def joint_friction_g(km, cfg, t, y, contact, ws, f):
    """Event function of friction joint f at (t, y), positive past its switch: slipping, -d s'; stuck,
    |T| - mu_s load (the solve at y); -1 without a friction mode (or a solve that fails: the time loop's own
    right-hand side reports it)."""
    row = km.clearance_body.shape[0] + f
    mode = int(contact[row, CT_FRICTION])
    n = km.minv.shape[0]
    if mode == SLIP:
        s, v = slip_state(km, f, y[:n], y[n:2 * n])
        return -contact[row, CT_SLIP_DIRECTION] * v
    if mode != STICK or _friction_solve(km, cfg, t, y, contact, ws) != 0:
        return -1.0
    return abs(ws.fs[f, JW_T]) - ws.fs[f, JW_LIMIT]


@kernel
def joint_friction_possible(km, cfg, ws, contact):
    """True when some friction joint's event function is positive at the step end."""
    t1 = ws.dense[DN_TA] + ws.dense[DN_H]
    for f in range(km.joint_friction.shape[0]):
        if joint_friction_g(km, cfg, t1, ws.yb, contact, ws, f) > 0.0:
            return True
    return False


@kernel
def locate_joint_friction(km, cfg, ws, contact, kbest, best):
    """Earliest switch of a joint's friction inside the last step before step fraction `best` (the contact
    events'): (event index 2 nc + f, or kbest when none is earlier; its step fraction on the new side)."""
    nc = km.clearance_body.shape[0]
    ta = ws.dense[DN_TA]
    h = ws.dense[DN_H]
    tol = ROOT_RTOL * max(abs(ta), h) / h
    for f in range(km.joint_friction.shape[0]):
        g1 = joint_friction_g(km, cfg, ta + h, ws.yb, contact, ws, f)
        if not (g1 > 0.0):
            continue
        lo = 0.0
        flo = joint_friction_g(km, cfg, ta, ws.ya, contact, ws, f)
        hi = 1.0
        fhi = g1
        if flo > 0.0:  # already past the switch at the step start (roundoff at a switch)
            hi = 0.0
        side = 0
        for it in range(MAX_ROOT_ITER):
            if hi - lo <= tol:
                break
            x = _illinois_trial(it, lo, flo, hi, fhi)
            dense_eval(ws, x, ws.yt)
            fx = joint_friction_g(km, cfg, ta + x * h, ws.yt, contact, ws, f)
            lo, flo, hi, fhi, side = _illinois_narrow(x, fx, lo, flo, hi, fhi, side)
        if hi < best:
            best = hi
            kbest = 2 * nc + f
    return kbest, best


@kernel
def try_stick(km, cfg, t, y, contact, ws, f, d):
    """Friction joint f sticks at state y (its anchor there) when the friction that holds it stays within
    mu_s times its load; else it slips in direction d (0: against that friction)."""
    row = km.clearance_body.shape[0] + f
    n = km.minv.shape[0]
    s, v = slip_state(km, f, y[:n], y[n:2 * n])
    contact[row, CT_FRICTION] = STICK
    contact[row, CT_ANCHOR] = s
    st = _friction_solve(km, cfg, t, y, contact, ws)
    T = ws.fs[f, JW_T]
    if st != 0 or abs(T) > ws.fs[f, JW_LIMIT]:
        contact[row, CT_FRICTION] = SLIP
        if d == 0.0:
            d = -1.0 if T > 0.0 else 1.0
        contact[row, CT_SLIP_DIRECTION] = d


@kernel
def switch_joint_friction(km, cfg, t, y, contact, ws, stats, f):
    """Switch friction joint f at state y (on the new side): stuck, it slips against the friction that held
    it; slipping, its slip rate crossed zero: it sticks, or slips on the other way (`try_stick`)."""
    row = km.clearance_body.shape[0] + f
    if int(contact[row, CT_FRICTION]) == STICK:
        _friction_solve(km, cfg, t, y, contact, ws)
        contact[row, CT_FRICTION] = SLIP
        contact[row, CT_SLIP_DIRECTION] = -1.0 if ws.fs[f, JW_T] > 0.0 else 1.0
    else:
        try_stick(km, cfg, t, y, contact, ws, f, -contact[row, CT_SLIP_DIRECTION])
    stats[ST_CONTACT_EVENTS] += 1


@kernel
def init_joint_friction(km, cfg, t, y, contact, ws):
    """At the start of a run, each friction joint without a mode: at rest, it sticks if it can
    (`try_stick`); moving, it slips its way."""
    nc = km.clearance_body.shape[0]
    n = km.minv.shape[0]
    for f in range(km.joint_friction.shape[0]):
        if int(contact[nc + f, CT_FRICTION]) != NO_FRICTION_MODE:
            continue
        s, v = slip_state(km, f, y[:n], y[n:2 * n])
        if v == 0.0:
            try_stick(km, cfg, t, y, contact, ws, f, 0.0)
        else:
            contact[nc + f, CT_FRICTION] = SLIP
            contact[nc + f, CT_SLIP_DIRECTION] = 1.0 if v > 0.0 else -1.0
