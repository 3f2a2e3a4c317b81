"""The planar ANCF cable element: a thin beam in absolute nodal coordinates.

J. Gerstmayr and A. A. Shabana, "Analysis of thin beams and cables using the absolute nodal
co-ordinate formulation", Nonlinear Dynamics 45 (2006).  Each node carries its position and its
slope, ``(x, y, dx/ds, dy/ds)``; an element of length L between two nodes interpolates the centre
line with the cubic Hermite functions of xi = s / L,

    r(xi) = S1 r_1 + L S2 r_1' + S3 r_2 + L S4 r_2',
    S1 = 1 - 3 xi^2 + 2 xi^3,  S2 = xi - 2 xi^2 + xi^3,  S3 = 3 xi^2 - 2 xi^3,  S4 = xi^3 - xi^2.

Why this element: its mass matrix ``rho A L int S^T S dxi`` is constant (the inertia of every motion,
however large its rotations, is linear in the accelerations: no centrifugal or Coriolis terms), it
has no rotational coordinates (no finite-rotation parametrisation, no singularity), and a rigid
motion of its nodes (slopes of unit length, rotated together) is an exact rigid motion of the
element: zero strain, zero elastic force.  The strains are the exact nonlinear ones,

    axial   eps   = (r'.r' - 1) / 2                       U_a = EA/2 int eps^2 ds
    bending kappa = (x' y'' - y' x'') / |r'|^3            U_b = EI/2 int kappa^2 ds

(' = d/ds), integrated by Gauss-Legendre quadrature (GAUSS_POINTS points per element); the cross
section stays rigid and normal to the centre line (Euler-Bernoulli: no shear, a thin beam).  The
optional material damping is stiffness proportional (Kelvin-Voigt on both strains, time constant
eta): the force ``-eta int (EA eps_dot d eps/de + EI kappa_dot d kappa/de) ds``, which a rigid
motion never feels.

The functions are plain loops over arrays: numba compiles them for the time loop, and
`planar_mbs.pykernel` runs the same source as Python (the compiler's mass matrix, the tests).
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel

NODE_COORDS = 4  # (x, y, dx/ds, dy/ds) per node
ELEMENT_COORDS = 8
GAUSS_POINTS = 5
# Gauss-Legendre points and weights on [0, 1] (5 points: exact for polynomials of degree 9)
_G = (0.5384693101056831, 0.9061798459386640)
GAUSS_XI = np.array([0.5 - 0.5 * _G[1], 0.5 - 0.5 * _G[0], 0.5, 0.5 + 0.5 * _G[0], 0.5 + 0.5 * _G[1]])
GAUSS_W = 0.5 * np.array([0.2369268850561891, 0.4786286704993665, 0.5688888888888889,
                          0.4786286704993665, 0.2369268850561891])


@kernel
def shape(xi, L, out):
    """Hermite shape functions (S1, L S2, S3, L S4) at xi into out[0, :], their d/ds into
    out[1, :], their d^2/ds^2 into out[2, :]."""
    x2 = xi * xi
    x3 = x2 * xi
    out[0, 0] = 1.0 - 3.0 * x2 + 2.0 * x3
    out[0, 1] = L * (xi - 2.0 * x2 + x3)
    out[0, 2] = 3.0 * x2 - 2.0 * x3
    out[0, 3] = L * (x3 - x2)
    out[1, 0] = (-6.0 * xi + 6.0 * x2) / L
    out[1, 1] = 1.0 - 4.0 * xi + 3.0 * x2
    out[1, 2] = (6.0 * xi - 6.0 * x2) / L
    out[1, 3] = 3.0 * x2 - 2.0 * xi
    out[2, 0] = (-6.0 + 12.0 * xi) / (L * L)
    out[2, 1] = (-4.0 + 6.0 * xi) / L
    out[2, 2] = (6.0 - 12.0 * xi) / (L * L)
    out[2, 3] = (6.0 * xi - 2.0) / L


@kernel
def element_mass(L, rho_a, sh, out):
    """The constant consistent mass matrix (8 x 8) rho A L int_0^1 S^T S dxi into out (Gauss: exact);
    `sh` (3, 4) is scratch."""
    for i in range(ELEMENT_COORDS):
        for j in range(ELEMENT_COORDS):
            out[i, j] = 0.0
    for g in range(GAUSS_POINTS):
        shape(GAUSS_XI[g], L, sh)
        w = rho_a * L * GAUSS_W[g]
        for a in range(4):
            for b in range(4):
                m = w * sh[0, a] * sh[0, b]
                out[2 * a, 2 * b] += m
                out[2 * a + 1, 2 * b + 1] += m


@kernel
def _interp(e, sh, d, k):
    """Component k (0: x, 1: y) of derivative d (0, 1, 2) of r at the point of `sh`."""
    return sh[d, 0] * e[k] + sh[d, 1] * e[2 + k] + sh[d, 2] * e[4 + k] + sh[d, 3] * e[6 + k]


@kernel
def element_strains(e, xi, L, sh):
    """(eps, kappa) at xi of the element with coordinates e (8,); `sh` (3, 4) is scratch."""
    shape(xi, L, sh)
    x1 = _interp(e, sh, 1, 0)
    y1 = _interp(e, sh, 1, 1)
    x2 = _interp(e, sh, 2, 0)
    y2 = _interp(e, sh, 2, 1)
    g = x1 * x1 + y1 * y1
    return 0.5 * (g - 1.0), (x1 * y2 - y1 * x2) / (g * math.sqrt(g))


@kernel
def element_energy(e, L, ea, ei, sh):
    """Strain energy EA/2 int eps^2 + EI/2 int kappa^2 of one element."""
    u = 0.0
    for g in range(GAUSS_POINTS):
        eps, kap = element_strains(e, GAUSS_XI[g], L, sh)
        u += 0.5 * L * GAUSS_W[g] * (ea * eps * eps + ei * kap * kap)
    return u


@kernel
def element_forces(e, ed, L, ea, ei, eta, sh, de, dk, out):
    """out (8,) -= the gradient of the strain energy and the material damping force at (e, e').
    `sh` (3, 4), `de`, `dk` (8,) are scratch (d eps/de, d kappa/de).  Returns the damping force's
    power, -eta int (EA eps_dot^2 + EI kappa_dot^2) ds (<= 0)."""
    pd = 0.0
    for g in range(GAUSS_POINTS):
        shape(GAUSS_XI[g], L, sh)
        x1 = _interp(e, sh, 1, 0)
        y1 = _interp(e, sh, 1, 1)
        x2 = _interp(e, sh, 2, 0)
        y2 = _interp(e, sh, 2, 1)
        gg = x1 * x1 + y1 * y1
        c = x1 * y2 - y1 * x2
        g32 = gg * math.sqrt(gg)
        eps = 0.5 * (gg - 1.0)
        kap = c / g32
        for a in range(4):
            s1 = sh[1, a]
            s2 = sh[2, a]
            de[2 * a] = s1 * x1
            de[2 * a + 1] = s1 * y1
            # d kappa = dc / g^1.5 - 1.5 c g^-2.5 dg, dg = 2 d eps
            dk[2 * a] = (s1 * y2 - s2 * y1) / g32 - 3.0 * kap / gg * de[2 * a]
            dk[2 * a + 1] = (s2 * x1 - s1 * x2) / g32 - 3.0 * kap / gg * de[2 * a + 1]
        fa = ea * eps
        fb = ei * kap
        if eta > 0.0:
            epsd = 0.0
            kapd = 0.0
            for i in range(ELEMENT_COORDS):
                epsd += de[i] * ed[i]
                kapd += dk[i] * ed[i]
            fa += eta * ea * epsd
            fb += eta * ei * kapd
            pd -= L * GAUSS_W[g] * eta * (ea * epsd * epsd + ei * kapd * kapd)
        w = L * GAUSS_W[g]
        for i in range(ELEMENT_COORDS):
            out[i] -= w * (fa * de[i] + fb * dk[i])
    return pd


@kernel
def beam_forces(q, qd, first, nel, L, ea, ei, eta, sh, de, dk, fe, Q):
    """Q[first:] -= elastic and damping forces of a beam of `nel` elements of length L whose
    coordinates start at q[first] (node k at first + 4 k); fe (8,) scratch.  Returns the damping's power."""
    pd = 0.0
    for k in range(nel):
        o = first + NODE_COORDS * k
        for i in range(ELEMENT_COORDS):
            fe[i] = 0.0
        pd += element_forces(q[o:o + ELEMENT_COORDS], qd[o:o + ELEMENT_COORDS], L, ea, ei, eta, sh, de, dk, fe)
        for i in range(ELEMENT_COORDS):
            Q[o + i] += fe[i]
    return pd


@kernel
def beam_energy(q, first, nel, L, ea, ei, sh):
    """Strain energy of a whole beam (`beam_forces`' layout)."""
    u = 0.0
    for k in range(nel):
        o = first + NODE_COORDS * k
        u += element_energy(q[o:o + ELEMENT_COORDS], L, ea, ei, sh)
    return u


# ---- beams in the time loop.  A beam's node k is two bodies of the rigid layout without mass of their
# own: its position body (x, y, unused) and its slope body (dx/ds, dy/ds, unused), at first + 2 k and
# first + 2 k + 1 (km.beam_info[bm] = first body, elements, offset in beam_mass / beam_minv, offset in
# beam_weight; km.beam_param[bm] = element length, EA, EI, eta, rho A).  Their rows of km.minv are zero:
# the beam's own constant mass acts through its inverse, formed once by the compiler.

BAND = 4  # entries per row of a beam's banded Cholesky factor (`km.beam_band`): L[i, i - k], k = 0 .. 3
BEAM_ROWS = 11  # rows the workspace's ws.F gets beyond its dense-output rows when the model has beams
# (scratch of the beams' kernels, `beam_row`; no array of its own, so a model without beams passes no more)
ROW_FORCE, ROW_E, ROW_ED, ROW_Q, ROW_SHAPE, ROW_DE, ROW_DK, ROW_FE, ROW_SOLVE = 0, 1, 2, 3, 4, 7, 8, 9, 10


@kernel(inline=True)
def beam_row(ws, j):
    """Row j of the beams' scratch: the last BEAM_ROWS rows of ws.F (each 2n long)."""
    return ws.F[ws.F.shape[0] - BEAM_ROWS + j]


@kernel(inline=True)
def beam_shape_rows(ws):
    """The (3, 2n) scratch of the shape functions: rows ROW_SHAPE .. ROW_SHAPE + 2 of the beams' scratch."""
    r = ws.F.shape[0] - BEAM_ROWS + ROW_SHAPE
    return ws.F[r:r + 3]


@kernel
def beam_qindex(first, i):
    """Index in q of a beam's coordinate i (node i // 4, (x, y, dx/ds, dy/ds)[i % 4])."""
    return 3 * (first + 2 * (i // NODE_COORDS) + (i % NODE_COORDS) // 2) + i % 2


@kernel
def beam_local(first, b, c):
    """A beam's own index of component c (0, 1) of its node body b."""
    return 2 * (b - first) + c


@kernel
def beam_minv_mul(km, ws, f, sign, out):
    """out += sign M^-1 f on the coordinates of every beam (f, out over the whole q), in O(elements):
    a beam's mass is its scalar mass Mbar (position and slope per node, half-bandwidth 3) times the
    2x2 identity, so M^-1 f is two banded triangular solves with Mbar's Cholesky factor (`km.beam_band`)
    per direction.  Scratch: the beams' row ROW_SOLVE."""
    y = beam_row(ws, ROW_SOLVE)
    for bm in range(km.beam_info.shape[0]):
        first = km.beam_info[bm, 0]
        ns = 2 * (km.beam_info[bm, 1] + 1)
        bo = 2 * km.beam_info[bm, 3]  # beam_weight has 4 entries per node, the band BAND per scalar (2 per node)
        for c in range(2):
            for i in range(ns):  # L y = f
                s = f[beam_qindex(first, 2 * i + c)]
                for k in range(1, min(i, BAND - 1) + 1):
                    s -= km.beam_band[bo + BAND * i + k] * y[i - k]
                y[i] = s / km.beam_band[bo + BAND * i]
            for i in range(ns - 1, -1, -1):  # L^T x = y
                s = y[i]
                for k in range(1, min(ns - 1 - i, BAND - 1) + 1):
                    s -= km.beam_band[bo + BAND * (i + k) + k] * y[i + k]
                y[i] = s / km.beam_band[bo + BAND * i]
                out[beam_qindex(first, 2 * i + c)] += sign * y[i]


@kernel
def beam_node_mobility(km, b, nx, ny):
    """n^T (M^-1)_b n: the inverse of the mass that a point force along n at node body b moves
    (the node's 2x2 block of the beam's inverse mass; the node body has no mass of its own)."""
    bm = km.body_beam[b]
    first = km.beam_info[bm, 0]
    nb = NODE_COORDS * (km.beam_info[bm, 1] + 1)
    mo = km.beam_info[bm, 2]
    i = beam_local(first, b, 0)
    mxx = km.beam_minv[mo + i * nb + i]
    mxy = km.beam_minv[mo + i * nb + i + 1]
    myy = km.beam_minv[mo + (i + 1) * nb + i + 1]
    return nx * nx * mxx + 2.0 * nx * ny * mxy + ny * ny * myy

@kernel
def beam_schur_entry(body_beam, beam_info, beam_minv, J, rb, r, c):
    """The beams' part of S[r, c] = Cq_r M^-1 Cq_c^T: pairs of node bodies of one beam in rows r, c."""
    s = 0.0
    for a1 in range(2):
        b1 = rb[r, a1]
        if b1 < 0 or body_beam[b1] < 0:
            continue
        bm = body_beam[b1]
        first = beam_info[bm, 0]
        nb = NODE_COORDS * (beam_info[bm, 1] + 1)
        mo = beam_info[bm, 2]
        for a2 in range(2):
            b2 = rb[c, a2]
            if b2 < 0 or body_beam[b2] != bm:
                continue
            for i in range(2):
                li = beam_local(first, b1, i)
                for j in range(2):
                    s += J[r, a1, i] * beam_minv[mo + li * nb + beam_local(first, b2, j)] * J[c, a2, j]
    return s


@kernel
def beam_schur_assemble(minv, J, rb, first, ptr, S, sdiag, reg, body_beam, beam_info, beam_minv):
    """`dynamics.schur_assemble` for a model with beams: the rigid bodies' diagonal terms and each beam's
    block of M^-1 (`beam_schur_entry`).  (A model without beams keeps the one without this term.)"""
    for r in range(J.shape[0]):
        s = 0.0
        br = ptr[r] - first[r]
        for c in range(first[r], r + 1):
            s = 0.0
            for a1 in range(2):
                b = rb[r, a1]
                if b < 0:
                    continue
                for a2 in range(2):
                    if rb[c, a2] == b:
                        k = 3 * b
                        s += (J[r, a1, 0] * minv[k] * J[c, a2, 0] + J[r, a1, 1] * minv[k + 1] * J[c, a2, 1]
                              + J[r, a1, 2] * minv[k + 2] * J[c, a2, 2])
            s += beam_schur_entry(body_beam, beam_info, beam_minv, J, rb, r, c)
            S[br + c] = s
        sdiag[r] = s
        S[br + r] = s * (1.0 + reg)


@kernel
def beam_constraint_force(ws, x, out):
    """out = -Cq^T x over the whole q (zeroed first)."""
    for k in range(out.shape[0]):
        out[k] = 0.0
    for r in range(x.shape[0]):
        for a in range(2):
            b = ws.rowbody[r, a]
            if b >= 0:
                for i in range(3):
                    out[3 * b + i] -= ws.J[r, a, i] * x[r]


@kernel
def beam_applied(km, ws, q, qd):
    """ws.Qe += every beam's weight and elastic and damping forces; returns the weight's power.  The
    damping's power of beam bm goes to its work channel, ws.pw[-nbeam + bm] (the last ones:
    `model.work_layout`)."""
    pg = 0.0
    e = beam_row(ws, ROW_E)
    ed = beam_row(ws, ROW_ED)
    f = beam_row(ws, ROW_Q)
    for bm in range(km.beam_info.shape[0]):
        first = km.beam_info[bm, 0]
        nel = km.beam_info[bm, 1]
        nb = NODE_COORDS * (nel + 1)
        wo = km.beam_info[bm, 3]
        for i in range(nb):
            k = beam_qindex(first, i)
            e[i] = q[k]
            ed[i] = qd[k]
            f[i] = km.beam_weight[wo + i]
            pg += f[i] * qd[k]
        p = km.beam_param[bm]
        ws.pw[ws.pw.shape[0] - km.beam_info.shape[0] + bm] = beam_forces(
            e, ed, 0, nel, p[0], p[1], p[2], p[3], beam_shape_rows(ws), beam_row(ws, ROW_DE), beam_row(ws, ROW_DK),
            beam_row(ws, ROW_FE), f)
        for i in range(nb):
            ws.Qe[beam_qindex(first, i)] += f[i]
    return pg


@kernel
def _slope_curv(q, first, o, xi, L):
    """(x', y', x'', y'') at xi of the element whose first coordinate is the beam's o, read from q."""
    x2 = xi * xi
    d1 = ((-6.0 * xi + 6.0 * x2) / L, 1.0 - 4.0 * xi + 3.0 * x2, (6.0 * xi - 6.0 * x2) / L, 3.0 * x2 - 2.0 * xi)
    d2 = ((-6.0 + 12.0 * xi) / (L * L), (-4.0 + 6.0 * xi) / L, (6.0 - 12.0 * xi) / (L * L), (6.0 * xi - 2.0) / L)
    x1 = 0.0
    y1 = 0.0
    xx = 0.0
    yy = 0.0
    for a in range(4):
        ex = q[beam_qindex(first, o + 2 * a)]
        ey = q[beam_qindex(first, o + 2 * a + 1)]
        x1 += d1[a] * ex
        y1 += d1[a] * ey
        xx += d2[a] * ex
        yy += d2[a] * ey
    return x1, y1, xx, yy


@kernel
def beam_strains_q(km, bm, q, k, xi):
    """(eps, kappa) at xi of element k of beam bm, read from q."""
    x1, y1, xx, yy = _slope_curv(q, km.beam_info[bm, 0], NODE_COORDS * k, xi, km.beam_param[bm, 0])
    g = x1 * x1 + y1 * y1
    return 0.5 * (g - 1.0), (x1 * yy - y1 * xx) / (g * math.sqrt(g))


@kernel
def beam_weight_potential(km, q):
    """The potential -Q_g . q of every beam's constant weight (its work is gravity's)."""
    V = 0.0
    for bm in range(km.beam_info.shape[0]):
        first = km.beam_info[bm, 0]
        wo = km.beam_info[bm, 3]
        for i in range(NODE_COORDS * (km.beam_info[bm, 1] + 1)):
            V -= km.beam_weight[wo + i] * q[beam_qindex(first, i)]
    return V


@kernel
def beam_strain_energy(km, q):
    """Every beam's strain energy, read from q (an internal energy: no load's work)."""
    V = 0.0
    for bm in range(km.beam_info.shape[0]):
        p = km.beam_param[bm]
        for k in range(km.beam_info[bm, 1]):
            for g in range(GAUSS_POINTS):
                eps, kap = beam_strains_q(km, bm, q, k, GAUSS_XI[g])
                V += 0.5 * p[0] * GAUSS_W[g] * (p[1] * eps * eps + p[2] * kap * kap)
    return V


@kernel
def beam_kinetic(km, qd):
    """Every beam's kinetic energy q'^T M q' / 2 (its constant mass, 7 coordinates either side of the
    diagonal: two neighbouring nodes)."""
    T = 0.0
    for bm in range(km.beam_info.shape[0]):
        first = km.beam_info[bm, 0]
        nb = NODE_COORDS * (km.beam_info[bm, 1] + 1)
        mo = km.beam_info[bm, 2]
        for i in range(nb):
            vi = qd[beam_qindex(first, i)]
            for j in range(max(0, i - 2 * NODE_COORDS + 1), min(nb, i + 2 * NODE_COORDS)):
                T += 0.5 * vi * km.beam_mass[mo + i * nb + j] * qd[beam_qindex(first, j)]
    return T
