"""Revolute clearance joints: kinematics (Muvengei et al. eqs. 3-12), normal force laws, friction.

Joint k joins the bearing body i (``clearance_body[k, 0]``) and the journal
body j (``clearance_body[k, 1]``); ``clearance_point[k]`` holds the bearing and
journal centres in their body frames.  Either body may be ground (-1).

* eccentricity ``e = P_j - P_i`` (eq. 3), ``e = |e|`` (4), penetration
  ``delta = e - c`` (5), normal ``n = e / e`` (8), tangent ``t = perp(n)``;
* contact points ``r_Ci = P_i + R_B n``, ``r_Cj = P_j + R_J n`` (6, 7);
* normal relative velocity ``delta' = (r_Cj' - r_Ci') . n = (P_j' - P_i') . n``
  (eq. 11: the ``n'`` terms are orthogonal to n);
* slip velocity: tangential relative velocity of the two *material* contact
  points, ``v_T = (P_j' - P_i') . t + w_j R_J - w_i R_B`` (what a friction law
  needs; eq. 12 with the geometric ``n'`` terms differs).

Forces (eqs. 13-16): ``+F n - F_T t`` on the bearing body at r_Ci,
``-F n + F_T t`` on the journal body at r_Cj, moments about each centre of
mass; ground takes nothing.  F_T is the friction force on the journal along t, by the element's
friction model (catalog.FRICTION_MODELS): Ambrosio's ``-mu c_d(|v_T|) F sign(v_T)`` (c_d: 0 below
v0, linear between v0 and v1, 1 above v1), Coulomb or Stribeck with stick (`friction_force`), or
LuGre's bristles, ``F_T = -F (w + sigma_1 dz/dt) - sigma_2 v_T`` with w = sigma_0 z a state of the run
(y[2n + j], j = `state_index`) whose rate `bristle_rate` gives.

Contact *mode* (``contact[k, CT_MODE]``: 0 free flight, 1 contact) is switched by the
event logic of the time loop; in free mode the joint applies no force even if
delta > 0, in contact mode it applies ``law(delta, delta')`` when delta > 0.
``contact[k, CT_IMPACT_VELOCITY]`` is the impact velocity ``delta'(-)`` of the current contact;
``contact[k, CT_LAST_FORCE]`` is unused (it held a warm start of the implicit laws, which made
the last bits of the force, and so the trajectory, depend on which states had
been evaluated before: on the output step, the chunking and resuming).

Laws (``ContactLaw`` codes; docs/contact.md has the equations and references):

* HERTZ ``F = K d^n``;
* KELVIN_VOIGT ``F = K d + c d'`` (n = 1), clipped at F >= 0, c in ``CP_DAMPING`` (given, or
  2 zeta sqrt(K m) from a restitution: `mechanism/restitution.py`);
* the dissipative laws ``F = K d^n (1 + chi d'/d'(-))``, clipped at F >= 0 (a
  contact pushes, never pulls) with chi(ce) of Lankarani-Nikravesh
  ``3 (1 - ce^2)/4``, Hunt-Crossley ``3 (1 - ce)/2``, Flores ``8 (1 - ce)/(5 ce)``
  and Gonthier ``(1 - ce^2)/ce``;
* the cylindrical laws, implicit in F: ``delta = A F (ln(B / F) + 1)`` with
  ``h = (sigma_1 + sigma_2)/pi`` (sigma = (1 - nu^2)/E as in Muvengei et al. eq. 18),
  ``A = h / L`` and ``B = L^3 c / (h R_B R_J)`` (Dubowsky-Freudenstein, the
  sigma_1 + sigma_2 form) or ``B = 4 L c / h`` (ESDU-78035).  With x = F / B and
  s = delta / (A B): ``x (1 - ln x) = s``; this is monotone for 0 < x <= 1 and
  ends at ``delta_max = A B`` (where d delta/dF = A ln(B/F) = 0).  Solved by a
  safeguarded Newton iteration in u = ln x (bracket, bisection fallback), always
  from the same start, so F is a function of delta alone, bit for bit.  Past the branch's end (delta > A B) there is no
  force: `normal_force` returns Status.CONTACT_SOLVE; the adaptive integrator
  treats it as a failed trial step (the branch end acts as a wall it steps up
  to) and the run stops with CONTACT_SOLVE (stats[ST_INFO] = joint) only when
  the step cannot shrink further or the method is fixed-step RK4.
"""
from __future__ import annotations

import math

import numpy as np

from .. import catalog
from .jit import kernel

from ..mechanism.model import (
    CP_CLEARANCE,
    CP_DAMPING,
    CP_EXPONENT,
    CP_FRICTION,
    CP_FRICTION_V0,
    CP_FRICTION_V1,
    CP_FRICTION_MODEL,
    CP_STATIC_FRICTION,
    CP_STICK_DAMPING,
    CP_STICK_STIFFNESS,
    CP_STRIBECK_EXPONENT,
    CP_STRIBECK_VELOCITY,
    CP_VISCOUS_FRICTION,
    CP_BRISTLE_DAMPING,
    CP_BRISTLE_STIFFNESS,
    CP_STATE,
    CP_BREAKDOWN,
    CP_KIND,
    CP_LENGTH,
    CP_NX,
    CP_NY,
    CP_VISCOSITY,
    CP_R_BEARING,
    CP_R_JOURNAL,
    CP_RESTITUTION,
    CP_SIGMA_SUM,
    CP_STIFFNESS,
    ST_INFO,
    CT_IMPACT_VELOCITY,
    CT_LAST_FORCE,
    CT_MODE,
    CT_ANCHOR,
    CT_FRICTION,
    CT_SLIP_DIRECTION,
    NO_FRICTION_MODE,
    SLIP,
    STICK,
    FrictionModel,
    FREE,
    TOUCHING,
    ContactLaw,
    PairKind,
    Status,
)
from .beam import beam_node_mobility
from .constraints import point_cs, point_state
from .forces import add_point_force
from .wear import worn, worn_kinematics

HERTZ = int(ContactLaw.HERTZ)
LANKARANI_NIKRAVESH = int(ContactLaw.LANKARANI_NIKRAVESH)
DUBOWSKY_FREUDENSTEIN = int(ContactLaw.DUBOWSKY_FREUDENSTEIN)
ESDU_78035 = int(ContactLaw.ESDU_78035)
HUNT_CROSSLEY = int(ContactLaw.HUNT_CROSSLEY)
FLORES = int(ContactLaw.FLORES)
GONTHIER = int(ContactLaw.GONTHIER)
KELVIN_VOIGT = int(ContactLaw.KELVIN_VOIGT)
N_LAWS = len(catalog.LAWS)
AMBROSIO = int(FrictionModel.AMBROSIO)
STRIBECK = int(FrictionModel.STRIBECK)
# per friction model code: 1 = it sticks (catalog.FrictionSpec.stick)
STICKS = np.array([1 if m.stick else 0 for m in catalog.FRICTION_MODELS], dtype=np.int64)
CIRCLE_IN_CIRCLE = int(PairKind.CIRCLE_IN_CIRCLE)
LUBRICATED = int(PairKind.LUBRICATED)
CIRCLE_ON_LINE = int(PairKind.CIRCLE_ON_LINE)
CIRCLE_ON_CIRCLE = int(PairKind.CIRCLE_ON_CIRCLE)
# per law code: 1 = implicit cylindrical law (catalog group "cylindrical")
CYLINDRICAL = np.array([1 if s.cylindrical else 0 for s in catalog.LAWS], dtype=np.int64)
CONTACT_SOLVE = int(Status.CONTACT_SOLVE)
BAD_INPUT = int(Status.BAD_INPUT)

# Floor of the stored impact velocity delta'(-) [m/s].  A grazing onset has
# delta'(-) ~ 0, which would make the hysteresis factor chi / delta'(-)
# unbounded; below this floor the contact is a gentle, quasi-static one and the
# floor only bounds its (then large) damping.
IMPACT_VELOCITY_FLOOR = 1e-5

# safeguarded Newton of the cylindrical laws
CYL_MAX_ITER = 100
CYL_UTOL = 4e-16


@kernel
def contact_mode(contact, k):
    """Contact mode of clearance joint k as its integer code (FREE or TOUCHING)."""
    return int(contact[k, CT_MODE])


@kernel
def law_supported(law):
    return 0 <= law < N_LAWS


@kernel
def is_cylindrical(law):
    return 0 <= law < N_LAWS and CYLINDRICAL[law] == 1


@kernel
def damping_factor(law, ce):
    """chi of the dissipative laws F = K d^n (1 + chi d'/d'(-)); 0 for the elastic ones."""
    if law == LANKARANI_NIKRAVESH:  # Muvengei et al. eq. 21 (Lankarani & Nikravesh 1990)
        return 0.75 * (1.0 - ce * ce)
    if law == HUNT_CROSSLEY:  # Hunt & Crossley 1975 (lambda = 3 alpha K / 2, ce = 1 - alpha v)
        return 1.5 * (1.0 - ce)
    if law == FLORES:  # Flores, Machado, Silva & Martins 2011
        return 1.6 * (1.0 - ce) / ce
    if law == GONTHIER:  # Gonthier, McPhee, Lange & Piedboeuf 2004
        return (1.0 - ce * ce) / ce
    return 0.0


@kernel
def cylinder_scales(law, p):
    """(A, B) of delta = A F (ln(B/F) + 1); A B = delta_max, B = F at the branch end."""
    h = p[CP_SIGMA_SUM] / math.pi
    L = p[CP_LENGTH]
    A = h / L
    if law == DUBOWSKY_FREUDENSTEIN:
        B = L * L * L * p[CP_CLEARANCE] / (h * p[CP_R_BEARING] * p[CP_R_JOURNAL])
    else:
        B = 4.0 * L * p[CP_CLEARANCE] / h
    return A, B


@kernel
def cylinder_solve(s, x0):
    """x in (0, 1] with x (1 - ln x) = s for 0 < s <= 1; x0 = warm start (ignored
    unless 0 < x0 < 1).  Returns (x, status): CONTACT_SOLVE when s > 1 (past the
    end of the monotone branch) or s is not a number.

    Newton on g(u) = u + ln(1 - u) - ln s, u = ln x <= 0: g is increasing and
    concave, the root lies in [2 ln s - 1, ln s]; a Newton step leaving the
    current bracket is replaced by bisection."""
    if not (s > 0.0):
        return 0.0, (0 if s == 0.0 else CONTACT_SOLVE)
    if s >= 1.0:
        if s == 1.0:
            return 1.0, 0
        return 1.0, CONTACT_SOLVE
    ls = math.log(s)
    lo = 2.0 * ls - 1.0
    hi = ls
    if x0 > 0.0 and x0 < 1.0 and math.log(x0) > lo and math.log(x0) < hi:
        u = math.log(x0)
    else:
        u = ls - math.log1p(-ls)
    for it in range(CYL_MAX_ITER):
        g = u + math.log1p(-u) - ls
        if g == 0.0:
            break
        if g > 0.0:
            hi = u
        else:
            lo = u
        dg = -u / (1.0 - u)
        un = u - g / dg if dg > 0.0 else 0.5 * (lo + hi)
        if not (un > lo and un < hi):
            un = 0.5 * (lo + hi)
        du = un - u
        u = un
        if abs(du) <= CYL_UTOL * max(1.0, abs(u)) or hi - lo <= CYL_UTOL * max(1.0, abs(u)):
            break
    return math.exp(u), 0


@kernel
def normal_force(law, p, delta, vn, v_impact, f_last):
    """Normal force F >= 0 of a law at penetration delta > 0, normal velocity vn
    (> 0 approaching) and impact velocity v_impact; returns (F, status).  f_last is
    ignored (the implicit laws start their iteration from the same point every time,
    so that F depends on delta alone)."""
    if is_cylindrical(law):
        A, B = cylinder_scales(law, p)
        x, st = cylinder_solve(delta / (A * B), 0.0)
        return B * x, st
    K = p[CP_STIFFNESS]
    dn = K * delta ** p[CP_EXPONENT]
    if law == HERTZ:  # Muvengei et al. eq. 17
        return dn, 0
    if law == KELVIN_VOIGT:  # linear spring-dashpot (n = 1), clipped: no pull
        return max(dn + p[CP_DAMPING] * vn, 0.0), 0
    if law < 0 or law >= N_LAWS:
        return 0.0, BAD_INPUT
    chi = damping_factor(law, p[CP_RESTITUTION])
    F = dn * (1.0 + chi * vn / v_impact)
    if F < 0.0:
        F = 0.0
    return F, 0


@kernel
def elastic_energy(law, p, delta, f_last):
    """Energy stored in the contact spring at penetration delta > 0: K delta^(n+1)/(n+1),
    or for the cylindrical laws int F d delta = A F^2 (1 + 2 ln(B/F)) / 4 at F(delta)."""
    if is_cylindrical(law):
        A, B = cylinder_scales(law, p)
        x, st = cylinder_solve(delta / (A * B), 0.0)
        F = B * x
        if F <= 0.0:
            return 0.0
        return 0.25 * A * F * F * (1.0 + 2.0 * math.log(B / F))
    ne = p[CP_EXPONENT]
    return p[CP_STIFFNESS] * delta ** (ne + 1.0) / (ne + 1.0)


@kernel
def normal_stiffness(law, p, delta, F):
    """dF/dd of the law's elastic part at penetration delta > 0 (force F there): n K d^(n-1), or for
    the cylindrical laws 1 / (A ln(B/F))."""
    if is_cylindrical(law):
        A, B = cylinder_scales(law, p)
        if not (F > 0.0) or F >= B:
            return 0.0
        return 1.0 / (A * math.log(B / F))
    ne = p[CP_EXPONENT]
    return ne * p[CP_STIFFNESS] * delta ** (ne - 1.0)


@kernel
def sticks(p):
    """True when element p's friction model holds a stuck contact (and it has friction)."""
    return STICKS[int(p[CP_FRICTION_MODEL])] == 1 and p[CP_STATIC_FRICTION] > 0.0


@kernel
def state_index(p):
    """Index j of element p's own state (LuGre's sigma_0 z = y[2n + j]), or -1."""
    return int(p[CP_STATE]) - 1


@kernel
def stribeck_curve(p, vt):
    """g(v) = mu_k + (mu_s - mu_k) exp(-(|v|/v_s)^d), the Stribeck curve per unit normal force."""
    mk = p[CP_FRICTION]
    return mk + (p[CP_STATIC_FRICTION] - mk) * math.exp(-(abs(vt) / p[CP_STRIBECK_VELOCITY]) ** p[CP_STRIBECK_EXPONENT])


@kernel
def bristle_slip_rate(p, w, vt):
    """dz/dt = v - sigma_0 |v| z / g(v) of LuGre's bristle deflection z (Canudas de Wit, Olsson, Astrom
    & Lischinsky, "A new model for control of systems with friction", 1995), sigma_0 per unit normal
    force, from w = sigma_0 z: its steady state z = g(v) sign(v) / sigma_0 at a constant slip speed."""
    return vt - abs(vt) * w / stribeck_curve(p, vt)


@kernel
def bristle_rate(p, w, vt):
    """dw/dt of the state the integrator carries, w = sigma_0 z: the bristles' force per unit normal
    force, of the size of mu (z itself, micrometres, would sit below the error control's atol)."""
    return p[CP_BRISTLE_STIFFNESS] * bristle_slip_rate(p, w, vt)


@kernel
def lugre_friction(p, F, vt, w):
    """F_T = -F_N (sigma_0 z + sigma_1 dz/dt) - sigma_2 v, w = sigma_0 z: LuGre with its bristle stiffness
    and damping scaled by the normal force (the steady state is F_N g(v) sign(v) + sigma_2 v against the
    slip)."""
    return -F * (w + p[CP_BRISTLE_DAMPING] * bristle_slip_rate(p, w, vt)) - p[CP_VISCOUS_FRICTION] * vt


@kernel
def slip_friction(p, F, vt, d):
    """Friction force along t of a slipping contact of a stick model, slip direction d = +-1:
    -mu_k F d (coulomb), or the Stribeck curve with its viscous term."""
    if int(p[CP_FRICTION_MODEL]) == STRIBECK:
        return -d * stribeck_curve(p, vt) * F - p[CP_VISCOUS_FRICTION] * vt
    return -d * p[CP_FRICTION] * F


@kernel
def _angle(q, b):
    return q[3 * b + 2] if b >= 0 else 0.0


@kernel
def slip_coordinates(km, k, q, ex, ey, nx, ny):
    """(a, b, c) of element k whose change s = (a - a0) + (b - b0) (circle on line) or (a - a0) +
    c wrap(b - b0) (b an angle) is the slip at the contact since (a0, b0): its rate is the slip velocity
    v_T to first order in the penetration, and rolling without slip leaves it unchanged.  With gamma
    the angle of n: circle in circle s = R_j (phi_j - gamma) - R_i (phi_i - gamma); circles from outside
    R_j (phi_j - gamma) + R_i (phi_i - gamma); circle on line R_j (phi_j - phi_i) + xi, xi = (P_j - P_i) . t
    the contact's place along the line."""
    p = km.clearance_param[k]
    kind = int(p[CP_KIND])
    pi_ = _angle(q, km.clearance_body[k, 0])
    pj = _angle(q, km.clearance_body[k, 1])
    rj = p[CP_R_JOURNAL]
    ri = p[CP_R_BEARING]
    if kind == CIRCLE_ON_LINE:
        return rj * (pj - pi_), -ex * ny + ey * nx, 0.0
    if kind == CIRCLE_ON_CIRCLE:
        return rj * pj + ri * pi_, math.atan2(ny, nx), -(rj + ri)
    return rj * pj - ri * pi_, math.atan2(ny, nx), ri - rj


@kernel
def set_anchor(km, k, q, contact, ex, ey, nx, ny):
    """Element k sticks from now: its slip coordinates now are its anchor."""
    a, b, c = slip_coordinates(km, k, q, ex, ey, nx, ny)
    contact[k, CT_ANCHOR] = a
    contact[k, CT_ANCHOR + 1] = b
    contact[k, CT_FRICTION] = STICK


@kernel
def stuck_slip(km, k, q, contact, ex, ey, nx, ny):
    """Slip s of stuck element k since it stuck (`slip_coordinates`)."""
    a, b, c = slip_coordinates(km, k, q, ex, ey, nx, ny)
    db = b - contact[k, CT_ANCHOR + 1]
    if c == 0.0:
        return a - contact[k, CT_ANCHOR] + db
    db = math.atan2(math.sin(db), math.cos(db))
    return a - contact[k, CT_ANCHOR] + c * db


@kernel
def stick_force(km, k, q, contact, law, delta, F, vt, ex, ey, nx, ny, rix, riy, rjx, rjy):
    """Friction force along t of stuck element k, uncapped: -(k_t s + c_t v_T), s its slip since it
    stuck (`stuck_slip`), k_t = stick_stiffness x dF/dd of the normal law, c_t = 2 zeta sqrt(k_t m_t)
    with m_t the two bodies' effective mass along t at the contact points."""
    p = km.clearance_param[k]
    bi = km.clearance_body[k, 0]
    bj = km.clearance_body[k, 1]
    s = stuck_slip(km, k, q, contact, ex, ey, nx, ny)
    kt = p[CP_STICK_STIFFNESS] * normal_stiffness(law, p, delta, F)
    w = _inverse_mass_along(km, bi, rix, riy, -ny, nx) + _inverse_mass_along(km, bj, rjx, rjy, -ny, nx)
    ct = 2.0 * p[CP_STICK_DAMPING] * math.sqrt(kt / w) if w > 0.0 else 0.0
    return -(kt * s + ct * vt)


@kernel
def friction_force(km, k, q, contact, law, delta, F, vt, ex, ey, nx, ny, rix, riy, rjx, rjy, zk):
    """Friction force F_T on the second body along t of element k in contact (normal force F): the
    model's (catalog.FRICTION_MODELS); a stuck contact's spring-damper capped at mu_s F; LuGre's from
    its state zk = sigma_0 z (z its bristle deflection)."""
    p = km.clearance_param[k]
    if state_index(p) >= 0:
        return lugre_friction(p, F, vt, zk)
    if not sticks(p):
        return -friction_coefficient(p, vt) * F
    mode = int(contact[k, CT_FRICTION])
    if mode == SLIP:
        return slip_friction(p, F, vt, contact[k, CT_SLIP_DIRECTION])
    if mode != STICK:
        return 0.0
    Ft = stick_force(km, k, q, contact, law, delta, F, vt, ex, ey, nx, ny, rix, riy, rjx, rjy)
    cap = p[CP_STATIC_FRICTION] * F
    return max(-cap, min(cap, Ft))


@kernel
def friction_coefficient(p, vt):
    """mu c_d(|v_T|) sign(v_T): Ambrosio's dynamic correction coefficient c_d = 0 for
    |v_T| <= v0, (|v_T| - v0)/(v1 - v0) between, 1 for |v_T| >= v1."""
    mu = p[CP_FRICTION]
    if mu <= 0.0:
        return 0.0
    a = abs(vt)
    v0 = p[CP_FRICTION_V0]
    v1 = p[CP_FRICTION_V1]
    if a <= v0:
        return 0.0
    if a >= v1:
        cd = 1.0
    else:
        cd = (a - v0) / (v1 - v0)
    return mu * cd if vt > 0.0 else -mu * cd


@kernel
def _pair_kin(km, k, contact, Pix, Piy, aix, aiy, vix, viy, wi, ci, si, Pjx, Pjy, ajx, ajy, vjx, vjy, wj):
    """(ex, ey, e, delta, nx, ny, vn, vt, rix, riy, rjx, rjy) of contact pair k: relative position
    ex, ey = P_j - P_i, its measure e, penetration delta, normal n (the force on the second body is
    -F n), normal and slip velocities, and the arms r from the bodies' centres of mass to the
    contact points.  ci, si: cos/sin of the first body's angle (read by the line and a worn bearing).
    A circle-in-circle joint whose run holds a worn profile (`wear.worn`) takes `wear.worn_kinematics`.

    Circle in circle and lubricated (Muvengei et al. eqs. 3-12): n = e/|e| ((1, 0) at e = 0).
    Circle on line: m = the line's outward normal, d = (P_j - P_i).m, delta = R_j - d, n = -m, contact
    points P_j + R_j n and P_j + d n (the foot on the line).  Circles from outside: delta = R_i + R_j - |e|,
    n = -e/|e|.  For the last two, vn and vt are the normal and tangential components of the relative
    velocity of the material points at the contact points (vn = d delta/dt exactly)."""
    p = km.clearance_param[k]
    kind = int(p[CP_KIND])
    ex = Pjx - Pix
    ey = Pjy - Piy
    rj = p[CP_R_JOURNAL]
    if kind == CIRCLE_ON_LINE:
        mx = ci * p[CP_NX] - si * p[CP_NY]
        my = si * p[CP_NX] + ci * p[CP_NY]
        e = ex * mx + ey * my
        nx = -mx
        ny = -my
        delta = rj - e
        cix = ex + e * nx  # the foot of P_j on the line, from P_i
        ciy = ey + e * ny
    elif kind == CIRCLE_ON_CIRCLE:
        e = math.sqrt(ex * ex + ey * ey)
        if e > 0.0:
            nx = -ex / e
            ny = -ey / e
        else:
            nx = 1.0
            ny = 0.0
        delta = p[CP_R_BEARING] + rj - e
        cix = -p[CP_R_BEARING] * nx
        ciy = -p[CP_R_BEARING] * ny
    elif kind == CIRCLE_IN_CIRCLE and worn(contact, k):  # a worn bearing (kernel.wear)
        return worn_kinematics(contact, k, p[CP_R_BEARING], rj, ex, ey, ci, si, vjx - vix, vjy - viy, wi, wj,
                               aix, aiy, ajx, ajy)
    else:
        e = math.sqrt(ex * ex + ey * ey)
        if e > 0.0:
            nx = ex / e
            ny = ey / e
        else:
            nx = 1.0
            ny = 0.0
        dvx = vjx - vix
        dvy = vjy - viy
        vn = dvx * nx + dvy * ny
        vt = -dvx * ny + dvy * nx + wj * rj - wi * p[CP_R_BEARING]
        rb = p[CP_R_BEARING]
        if kind == LUBRICATED:
            delta = e - p[CP_BREAKDOWN] * p[CP_CLEARANCE]
        else:
            delta = e - p[CP_CLEARANCE]
        return ex, ey, e, delta, nx, ny, vn, vt, aix + rb * nx, aiy + rb * ny, ajx + rj * nx, ajy + rj * ny
    cjx = rj * nx
    cjy = rj * ny
    # material velocities at the contact points: v + w k x r
    dvx = (vjx - wj * cjy) - (vix - wi * ciy)
    dvy = (vjy + wj * cjx) - (viy + wi * cix)
    vn = dvx * nx + dvy * ny
    vt = -dvx * ny + dvy * nx
    return ex, ey, e, delta, nx, ny, vn, vt, aix + cix, aiy + ciy, ajx + cjx, ajy + cjy


@kernel
def _trig(q, b):
    if b < 0:
        return 1.0, 0.0
    return math.cos(q[3 * b + 2]), math.sin(q[3 * b + 2])


@kernel
def pair_kinematics(km, k, q, qd, contact):
    """`_pair_kin` of pair k at (q, q')."""
    bi = km.clearance_body[k, 0]
    bj = km.clearance_body[k, 1]
    Pix, Piy, aix, aiy, vix, viy, wi = point_state(q, qd, bi, km.clearance_point[k, 0, 0], km.clearance_point[k, 0, 1])
    Pjx, Pjy, ajx, ajy, vjx, vjy, wj = point_state(q, qd, bj, km.clearance_point[k, 1, 0], km.clearance_point[k, 1, 1])
    ci = 1.0
    si = 0.0
    if int(km.clearance_param[k, CP_KIND]) == CIRCLE_ON_LINE or worn(contact, k):
        ci, si = _trig(q, bi)
    return _pair_kin(km, k, contact, Pix, Piy, aix, aiy, vix, viy, wi, ci, si, Pjx, Pjy, ajx, ajy, vjx, vjy, wj)


@kernel
def clearance_kinematics(km, k, q, qd, contact):
    """(ex, ey, e, delta, nx, ny, vn, vt) of clearance element k (delta: the event function).

    At e = 0 (centred journal) the normal is undefined: n = (1, 0) is used."""
    ex, ey, e, delta, nx, ny, vn, vt, rix, riy, rjx, rjy = pair_kinematics(km, k, q, qd, contact)
    return ex, ey, e, delta, nx, ny, vn, vt


@kernel
def film_force(p, e, vn, vtc, ws):
    """(Fr, Ft) of the short-bearing film on the journal along n and t = perp(n) (Flores, Ambrosio,
    Claro & Lankarani 2006, after Pinkus & Sternlicht: pi-film, wedge and squeeze terms):

        Fr = -(mu R L^3 / 2c^2) [2 eps^2 |w| / (1 - eps^2)^2 + pi eps' (1 + 2 eps^2) / (1 - eps^2)^(5/2)]
        Ft = s (mu R L^3 / 2c^2) [pi eps |w| / (2 (1 - eps^2)^(3/2)) + 4 eps eps' / (1 - eps^2)^2]

    with w = w_i + w_j - 2 gamma' (gamma' the turning rate of the line of centres), s = sign(w) (the
    positive-pressure half of the film mirrors with w).  eps = e/c is held at the breakdown ratio beyond
    it.  vn = c eps', vtc = (P_j' - P_i').t = e gamma', ws = w_i + w_j.

    The squeeze term of Ft takes s = eps w / sqrt((eps w)^2 + (2 eps')^2) instead of sign(w): the same
    while the wedge term fixes the pi-film (|eps w| >> |2 eps'|, Flores et al.'s assumption), zero in a
    pure squeeze (whose film is symmetric about the line of centres, so it has no cross force).  With the
    sign a journal whirling at half speed (w = 0, where a journal released from the centre goes) met a
    force that jumped at every crossing and the explicit integrator chattered at 1e-8 s steps."""
    c = p[CP_CLEARANCE]
    eb = p[CP_BREAKDOWN]
    eps = e / c
    if eps > eb:
        eps = eb
    epsd = vn / c
    ew = eps * ws - 2.0 * vtc / c  # eps w, finite at eps = 0
    u = 1.0 - eps * eps
    scale = p[CP_VISCOSITY] * p[CP_R_JOURNAL] * p[CP_LENGTH] ** 3 / (2.0 * c * c)
    Fr = -scale * (2.0 * eps * abs(ew) / (u * u) + math.pi * epsd * (1.0 + 2.0 * eps * eps) / (u * u * math.sqrt(u)))
    r = math.sqrt(ew * ew + 4.0 * epsd * epsd)
    s = ew / r if r > 0.0 else 0.0
    Ft = scale * (0.5 * math.pi * ew / (u * math.sqrt(u)) + s * 4.0 * eps * epsd / (u * u))
    return Fr, Ft


@kernel
def film_pressure_peak(p, e, vn, vtc, ws):
    """Largest film pressure p(psi, z = 0) = -3 mu L^2 A / (2 h^3) over the pi-film of `film_force`,
    A = (w/2) c eps sin(psi) - c eps' cos(psi), h = c (1 - eps cos psi) (psi from the line of centres),
    sampled at 1/2 degree."""
    c = p[CP_CLEARANCE]
    eps = min(e / c, p[CP_BREAKDOWN])
    ew = eps * ws - 2.0 * vtc / c
    epsd = vn / c
    sgn = 1.0 if ew >= 0.0 else -1.0
    best = 0.0
    L = p[CP_LENGTH]
    for i in range(361):
        psi = -sgn * math.pi * i / 360.0
        h = c * (1.0 - eps * math.cos(psi))
        A = 0.5 * ew * c * math.sin(psi) - c * epsd * math.cos(psi)
        pr = -1.5 * p[CP_VISCOSITY] * L * L * A / (h * h * h)
        if pr > best:
            best = pr
    return best


@kernel
def film_peak(km, k, q, qd, e, vn):
    """Peak film pressure of element k (0 unless it is a lubricated joint)."""
    p = km.clearance_param[k]
    if int(p[CP_KIND]) != LUBRICATED:
        return 0.0
    bi = km.clearance_body[k, 0]
    bj = km.clearance_body[k, 1]
    Pix, Piy, aix, aiy, vix, viy, wi = point_state(q, qd, bi, km.clearance_point[k, 0, 0], km.clearance_point[k, 0, 1])
    Pjx, Pjy, ajx, ajy, vjx, vjy, wj = point_state(q, qd, bj, km.clearance_point[k, 1, 0], km.clearance_point[k, 1, 1])
    ex = Pjx - Pix
    ey = Pjy - Piy
    nx, ny = 1.0, 0.0
    if e > 0.0:
        nx = ex / e
        ny = ey / e
    vtc = -(vjx - vix) * ny + (vjy - viy) * nx
    return film_pressure_peak(p, e, vn, vtc, wi + wj)


@kernel
def clearance_force(km, k, q, qd, cs, contact, z, zd):
    """(F, Ft, nx, ny, vt, status, rix, riy, rjx, rjy) of element k in its current mode:
    normal force magnitude F (the force on the second body is -F n + Ft t), friction force Ft on
    the second body along t = (-ny, nx) (with the film's tangential force for a lubricated joint),
    slip velocity vt, and the arms from the centres of mass to the contact points; cs = the
    bodies' cos/sin (`body_trig`).  z: the elements' own states (LuGre's sigma_0 z), whose rates go
    into zd (0 out of contact: the bristles hold until the contact opens, where they are reset)."""
    js = state_index(km.clearance_param[k])
    if js >= 0:
        zd[js] = 0.0
    bi = km.clearance_body[k, 0]
    bj = km.clearance_body[k, 1]
    Pix, Piy, aix, aiy, vix, viy, wi = point_cs(q, qd, cs, bi, km.clearance_point[k, 0, 0], km.clearance_point[k, 0, 1])
    Pjx, Pjy, ajx, ajy, vjx, vjy, wj = point_cs(q, qd, cs, bj, km.clearance_point[k, 1, 0], km.clearance_point[k, 1, 1])
    p = km.clearance_param[k]
    kind = int(p[CP_KIND])
    ci = 1.0
    si = 0.0
    if (kind == CIRCLE_ON_LINE or worn(contact, k)) and bi >= 0:
        ci = cs[bi, 0]
        si = cs[bi, 1]
    ex, ey, e, delta, nx, ny, vn, vt, rix, riy, rjx, rjy = _pair_kin(
        km, k, contact, Pix, Piy, aix, aiy, vix, viy, wi, ci, si, Pjx, Pjy, ajx, ajy, vjx, vjy, wj)
    F0 = 0.0
    Ft0 = 0.0
    if kind == LUBRICATED:
        vtc = -(vjx - vix) * ny + (vjy - viy) * nx
        Fr, Ftf = film_force(p, e, vn, vtc, wi + wj)
        F0 = -Fr
        Ft0 = Ftf
    if contact_mode(contact, k) == FREE or delta <= 0.0:
        return F0, Ft0, nx, ny, vt, 0, rix, riy, rjx, rjy
    law = km.clearance_law[k]
    F, st = normal_force(law, p, delta, vn, contact[k, CT_IMPACT_VELOCITY], contact[k, CT_LAST_FORCE])
    if st != 0:
        return F, 0.0, nx, ny, vt, st, rix, riy, rjx, rjy
    zk = 0.0
    if js >= 0:
        zk = z[js]
        zd[js] = bristle_rate(p, zk, vt)
    Ft = friction_force(km, k, q, contact, law, delta, F, vt, ex, ey, nx, ny, rix, riy, rjx, rjy, zk) \
        if p[CP_FRICTION] > 0.0 or sticks(p) else 0.0
    return F + F0, Ft + Ft0, nx, ny, vt, 0, rix, riy, rjx, rjy


@kernel
def add_clearance_forces(km, q, qd, cs, contact, z, zd, Qe, stats, pw, p0):
    """Qe += contact forces (normal and friction) of every clearance element in contact mode, and
    the film force of every lubricated joint (an element in free flight costs one comparison); the
    power of element k's forces on its two bodies into pw[p0 + k]; the rates of the elements' own
    states z into zd (`clearance_force`).
    Returns 0, or a status (BAD_INPUT, CONTACT_SOLVE) with stats[ST_INFO] = element index."""
    nc = km.clearance_body.shape[0]
    for j in range(zd.shape[0]):
        zd[j] = 0.0
    for k in range(nc):
        pw[p0 + k] = 0.0
        if contact_mode(contact, k) == FREE and int(km.clearance_param[k, CP_KIND]) != LUBRICATED:
            continue
        F, Ft, nx, ny, vt, st, rix, riy, rjx, rjy = clearance_force(km, k, q, qd, cs, contact, z, zd)
        if st != 0:
            stats[ST_INFO] = k
            return st
        if F == 0.0 and Ft == 0.0:
            continue
        bi = km.clearance_body[k, 0]
        bj = km.clearance_body[k, 1]
        # force on the second body: -F n + Ft t, t = (-ny, nx); the first takes the opposite
        fx = -F * nx - Ft * ny
        fy = -F * ny + Ft * nx
        # arms from the centres of mass to the contact points (Muvengei et al. eqs. 15, 16)
        add_point_force(Qe, bi, rix, riy, -fx, -fy)
        add_point_force(Qe, bj, rjx, rjy, fx, fy)
        pw[p0 + k] = _point_power(qd, bj, rjx, rjy, fx, fy) - _point_power(qd, bi, rix, riy, fx, fy)
    return 0


@kernel
def _point_power(qd, b, ax, ay, fx, fy):
    """Power of the force (fx, fy) at arm (ax, ay) from body b's centre of mass: its generalized force
    (fx, fy, a x f) times the body's velocities (0 on ground)."""
    if b < 0:
        return 0.0
    k = 3 * b
    return fx * qd[k] + fy * qd[k + 1] + (ax * fy - ay * fx) * qd[k + 2]


@kernel
def clearance_energy(km, k, q, qd, contact):
    """Elastic energy of clearance element k (0 unless in contact mode)."""
    if contact_mode(contact, k) == FREE:
        return 0.0
    ex, ey, e, delta, nx, ny, vn, vt = clearance_kinematics(km, k, q, qd, contact)
    if delta > 0.0:
        return elastic_energy(km.clearance_law[k], km.clearance_param[k], delta, contact[k, CT_LAST_FORCE])
    return 0.0


@kernel
def contact_energy(km, q, qd, contact):
    """Elastic energy of the clearance joints in contact mode."""
    V = 0.0
    nc = km.clearance_body.shape[0]
    for k in range(nc):
        if contact_mode(contact, k) == FREE:
            continue
        ex, ey, e, delta, nx, ny, vn, vt = clearance_kinematics(km, k, q, qd, contact)
        if delta > 0.0:
            V += elastic_energy(km.clearance_law[k], km.clearance_param[k], delta, contact[k, CT_LAST_FORCE])
    return V


@kernel
def _inverse_mass_along(km, b, ax, ay, nx, ny):
    """1/m + (a x n)^2 / I of body b for a force along n at arm a (0 for ground); at a beam's node
    the beam's mobility there (`beam_node_mobility`: its node bodies have no mass of their own, and
    a contact on one passes through the node, a = R_J n)."""
    if b < 0:
        return 0.0
    if km.body_beam.shape[0] > 0 and km.body_beam[b] >= 0:
        return beam_node_mobility(km, b, nx, ny)
    r = ax * ny - ay * nx
    return 1.0 / km.body_mass[b] + r * r / km.body_inertia[b]


@kernel
def peak_penetration(law, p, m, v):
    """Largest penetration of an elastic impact of effective mass m at speed v > 0:
    the spring energy equals m v^2 / 2 (K d^(n+1)/(n+1), or for the cylindrical laws
    A F^2 (1 + 2 ln(B/F))/4, solved for F by bisection in ln F; capped at the branch end)."""
    E = 0.5 * m * v * v
    if is_cylindrical(law):
        A, B = cylinder_scales(law, p)
        if E >= 0.25 * A * B * B:
            return A * B
        lo = -700.0
        hi = 0.0
        for it in range(80):  # u = ln(F / B): energy A B^2 x^2 (1 - 2 u)/4 increases with u
            u = 0.5 * (lo + hi)
            x = math.exp(u)
            if 0.25 * A * B * B * x * x * (1.0 - 2.0 * u) < E:
                lo = u
            else:
                hi = u
        F = B * math.exp(hi)
        return A * F * (math.log(B / F) + 1.0)
    ne = p[CP_EXPONENT]
    return ((ne + 1.0) * E / p[CP_STIFFNESS]) ** (1.0 / (ne + 1.0))


@kernel
def contact_time_scale(km, k, q, qd, v_impact, contact):
    """Time scale of the contact of joint k that has just begun: d_max / v_impact, with d_max
    the peak penetration of an elastic impact of the two bodies' effective mass along the
    normal (constraints ignored: they only add mass, so this is never longer than the real
    one).  An impact of a law with exponent n lasts about 2.9 of these for n = 1.5
    (Hertz: duration 2.94 d_max / v).  Returns inf when both bodies are ground."""
    bi = km.clearance_body[k, 0]
    bj = km.clearance_body[k, 1]
    p = km.clearance_param[k]
    ex, ey, e, delta, nx, ny, vn, vt, rix, riy, rjx, rjy = pair_kinematics(km, k, q, qd, contact)
    w = _inverse_mass_along(km, bi, rix, riy, nx, ny)
    w += _inverse_mass_along(km, bj, rjx, rjy, nx, ny)
    if not (w > 0.0) or not (v_impact > 0.0):
        return math.inf
    return peak_penetration(km.clearance_law[k], p, 1.0 / w, v_impact) / v_impact
