"""Linear algebra of the assembly that rounds the same way on every machine.

A run starts from the assembled state, and on a chaotic run (the slider-crank at 5000 rpm) a change
in the last bit of that state changes the motion after a few dozen revolutions.  numpy's ``@`` and
``lstsq`` call BLAS and LAPACK, whose kernels are picked for the processor when the library loads
(OpenBLAS: by core type) and round differently from one processor to another; numpy's element-wise
operations and its sums are the same IEEE operations in the same order everywhere, and
``math.cos``/``math.sin`` are the C library's.  So the assembly's products, rotations and
minimum-norm Newton steps are written with those alone: the step is a Householder QR with column
pivoting of the transposed Jacobian (G. H. Golub and C. F. Van Loan, *Matrix Computations*, §5.4.1
and §5.7), O(m² n) for m rows and n coordinates.
"""
from __future__ import annotations

import math

import numpy as np


def matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A x without BLAS."""
    return (np.asarray(A, dtype=np.float64) * np.asarray(x, dtype=np.float64)).sum(axis=1)


def rotate(phi: float, s) -> np.ndarray:
    """The planar rotation by phi applied to the 2-vector s, without BLAS."""
    c, sn = math.cos(phi), math.sin(phi)
    return np.array([c * s[0] - sn * s[1], sn * s[0] + c * s[1]], dtype=np.float64)


def min_norm_step(A: np.ndarray, b: np.ndarray, rank_tol: float) -> np.ndarray:
    """The smallest x with A x = b on a largest set of independent rows of A.

    Rows are taken greedily by the size of what they add (column pivoting of Aᵀ); a row whose
    remainder is below ``rank_tol`` times the largest row norm (at least 1) adds no rank and is left
    out, as a redundant joint's rows are.  With Aᵀ P = Q R the kept rows read Rᵀ (Qᵀx)[:r] = (Pᵀb)[:r],
    and the smallest x sets the rest of Qᵀx to zero."""
    A = np.asarray(A, dtype=np.float64)
    m, n = A.shape
    X = np.array(A.T, dtype=np.float64, order="C")  # column i is row perm[i] of A
    perm = np.arange(m)
    tol = rank_tol * max(math.sqrt(float((X * X).sum(axis=0).max(initial=0.0))), 1.0)
    reflectors = []
    for k in range(min(m, n)):
        tail = (X[k:, k:] * X[k:, k:]).sum(axis=0)
        j = k + int(np.argmax(tail))
        size = math.sqrt(float(tail[j - k]))
        if not size > tol:
            break
        X[:, [k, j]] = X[:, [j, k]]
        perm[[k, j]] = perm[[j, k]]
        v = X[k:, k].copy()
        v[0] -= -math.copysign(size, v[0])
        scale = 2.0 / float((v * v).sum())
        w = (v[:, None] * X[k:, k:]).sum(axis=0) * scale
        X[k:, k:] -= v[:, None] * w[None, :]
        reflectors.append((v, scale))
    r = len(reflectors)
    y = np.zeros(n)
    c = np.asarray(b, dtype=np.float64)[perm[:r]]
    for i in range(r):  # forward substitution with Rᵀ
        y[i] = (c[i] - float((X[:i, i] * y[:i]).sum())) / X[i, i]
    for k in range(r - 1, -1, -1):  # x = H_0 ... H_{r-1} y
        v, scale = reflectors[k]
        y[k:] -= v * (scale * float((v * y[k:]).sum()))
    return y
