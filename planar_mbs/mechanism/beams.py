"""A beam's constant matrices, formed once when the model is compiled (the kernel's ANCF cable
element, `kernel/beam.py`, run as plain Python).

A beam of n elements of length L_e has n + 1 nodes of 4 coordinates (x, y, dx/ds, dy/ds), node k's
at ``4 k .. 4 k + 3`` of the beam's own coordinate vector.  Its consistent mass matrix is constant
and banded (each element couples two nodes), and it is the scalar mass of the node's position and
slope times the 2x2 identity.  The time loop solves with the scalar mass's banded Cholesky factor
(`band_factor`: two triangular solves per direction, linear in the elements), and reads the dense
inverse (`inverse_mass`) only for the few entries at nodes that carry joints and contacts (the Schur
complement, a node's mobility); nothing is factored while a run goes.  The time loop holds
each node as two bodies of the rigid-body layout with no mass of their own: its position (x, y) and
its slope (dx/ds, dy/ds), the third coordinate of each unused.
"""
from __future__ import annotations

import math

import numpy as np

from ..pykernel import beam as pybeam  # the kernel's element as plain Python, without numba

NODE_COORDS = 4
BAND = pybeam.BAND


def beam_mass(nel: int, Le: float, rho_a: float) -> np.ndarray:
    """The assembled consistent mass matrix (4 (nel + 1) square)."""
    n = NODE_COORDS * (nel + 1)
    M = np.zeros((n, n))
    me = np.zeros((8, 8))
    pybeam.element_mass(Le, rho_a, np.zeros((3, 4)), me)
    for k in range(nel):
        o = NODE_COORDS * k
        M[o:o + 8, o:o + 8] += me
    return M


def inverse_mass(band: np.ndarray) -> np.ndarray:
    """M^-1 = Mbar^-1 times the 2x2 identity, Mbar^-1 by the solves of its band factor (`band_factor`)
    on every unit vector at once, symmetrised.  Element by element, without BLAS or LAPACK, so that its
    bits, and a run's, do not depend on the kernels the processor makes OpenBLAS choose
    (docs/numerics.md)."""
    n = band.shape[0]
    X = np.eye(n)
    for i in range(n):  # L Y = I, one row of all the columns at a time
        for k in range(1, min(BAND, i + 1)):
            X[i] -= band[i, k] * X[i - k]
        X[i] /= band[i, 0]
    for i in range(n - 1, -1, -1):  # L^T X = Y
        for k in range(1, min(BAND, n - i)):
            X[i] -= band[i + k, k] * X[i + k]
        X[i] /= band[i, 0]
    X = 0.5 * (X + X.T)
    Minv = np.zeros((2 * n, 2 * n))
    Minv[0::2, 0::2] = Minv[1::2, 1::2] = X
    return Minv


def band_factor(M: np.ndarray) -> np.ndarray:
    """The Cholesky factor L of the scalar mass Mbar = M[0::2, 0::2] (M = Mbar times the 2x2 identity:
    x and y never couple), row by row as L[i, i - k], k = 0 .. BAND - 1 (half-bandwidth 3: a node's
    position and slope couple with its neighbours' only), for `kernel.beam.beam_minv_mul`.  Formed in
    Python floats in a fixed order (no LAPACK), the same bits on every processor."""
    Mbar = M[0::2, 0::2]
    n = Mbar.shape[0]
    band = np.zeros((n, BAND))
    for i in range(n):
        for k in range(min(BAND - 1, i), -1, -1):  # L[i, j] for j = i - k, left to right
            j = i - k
            acc = float(Mbar[i, j])
            for p in range(1, min(BAND - k, j + 1)):  # columns j - p shared by rows i and j
                acc -= band[i, k + p] * band[j, p]
            if k == 0:
                if not acc > 0.0:
                    raise np.linalg.LinAlgError("the beam's mass matrix is not positive definite")
                band[i, 0] = math.sqrt(acc)
            else:
                band[i, k] = acc / band[j, 0]
    return band


def gravity_force(nel: int, Le: float, rho_a: float, g) -> np.ndarray:
    """The constant generalised weight rho A int S^T g ds of the whole beam."""
    n = NODE_COORDS * (nel + 1)
    Q = np.zeros(n)
    w = rho_a * Le * np.array([0.5, Le / 12.0, 0.5, -Le / 12.0])  # int_0^1 (S1, L S2, S3, L S4) dxi
    for k in range(nel):
        o = NODE_COORDS * k
        for a in range(4):
            Q[o + 2 * a] += w[a] * g[0]
            Q[o + 2 * a + 1] += w[a] * g[1]
    return Q


def straight_coordinates(nel: int, length: float, start, angle: float) -> np.ndarray:
    """The nodal coordinates of a straight, unstretched beam from `start` at `angle`."""
    c, s = np.cos(angle), np.sin(angle)
    e = np.zeros(NODE_COORDS * (nel + 1))
    for k in range(nel + 1):
        d = length * k / nel
        e[4 * k:4 * k + 4] = (start[0] + d * c, start[1] + d * s, c, s)
    return e


def elastic_forces(e, ed, nel: int, Le: float, ea: float, ei: float, eta: float = 0.0) -> np.ndarray:
    """The elastic (and damping) generalised force of the whole beam, in plain Python."""
    Q = np.zeros_like(e)
    pybeam.beam_forces(e, ed, 0, nel, Le, ea, ei, eta, np.zeros((3, 4)), np.zeros(8), np.zeros(8),
                       np.zeros(8), Q)
    return Q


def strain_energy(e, nel: int, Le: float, ea: float, ei: float) -> float:
    return pybeam.beam_energy(e, 0, nel, Le, ea, ei, np.zeros((3, 4)))


def q_index(first: int, i: int) -> int:
    """Index in q of a beam's coordinate i (as `kernel.beam.beam_qindex`: node i // 4 is the bodies
    first + 2 (i // 4) (position) and the next (slope))."""
    return 3 * (first + 2 * (i // NODE_COORDS) + (i % NODE_COORDS) // 2) + i % 2


def strains_rows(E: np.ndarray, Le: float, xi: float) -> tuple[np.ndarray, np.ndarray]:
    """(eps, kappa) at xi of one element for each row of its coordinates E (rows, 8)."""
    sh = np.zeros((3, 4))
    pybeam.shape(xi, Le, sh)
    x1, y1 = E[:, 0::2] @ sh[1], E[:, 1::2] @ sh[1]
    x2, y2 = E[:, 0::2] @ sh[2], E[:, 1::2] @ sh[2]
    g = x1 * x1 + y1 * y1
    return 0.5 * (g - 1.0), (x1 * y2 - y1 * x2) / (g * np.sqrt(g))


def energy_rows(E: np.ndarray, nel: int, Le: float, ea: float, ei: float) -> np.ndarray:
    """The strain energy of a whole beam for each row of its coordinates E (rows, 4 (nel + 1))."""
    U = np.zeros(E.shape[0])
    for k in range(nel):
        for xi, w in zip(pybeam.GAUSS_XI, pybeam.GAUSS_W):
            eps, kap = strains_rows(E[:, NODE_COORDS * k:NODE_COORDS * k + 8], Le, xi)
            U += 0.5 * Le * w * (ea * eps * eps + ei * kap * kap)
    return U


def inverse_mass_matrix(km) -> np.ndarray:
    """The whole dense M^-1 of a model's coordinates: the rigid bodies' diagonal and each beam's block."""
    Minv = np.diag(np.asarray(km.minv, dtype=float))
    for first, nel, mo, _ in np.asarray(km.beam_info, dtype=np.int64).reshape(-1, 4):
        nb = NODE_COORDS * (int(nel) + 1)
        idx = [q_index(int(first), i) for i in range(nb)]
        Minv[np.ix_(idx, idx)] = np.asarray(km.beam_minv[mo:mo + nb * nb]).reshape(nb, nb)
    return Minv


def node_mass(km, b: int) -> float:
    """The mass a point force at node body b of a beam moves: 1 / (M^-1)_xx of its node."""
    bm = int(km.body_beam[b])
    first, nel, mo, _ = (int(v) for v in km.beam_info[bm])
    nb = NODE_COORDS * (nel + 1)
    i = 2 * (b - first)
    return 1.0 / float(km.beam_minv[mo + i * nb + i])
