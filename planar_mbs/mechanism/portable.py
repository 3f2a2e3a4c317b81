"""Linear algebra of the assembly that rounds the same way on every machine.

A run starts from the assembled state, and on a chaotic run (the slider-crank at 5000 rpm) a change
in the last bit of that state changes the motion after a few dozen revolutions.  numpy's ``@`` and
``lstsq`` call BLAS and LAPACK, whose kernels are picked for the processor when the library loads
(OpenBLAS: by core type) and round differently from one processor to another; numpy's element-wise
operations and its sums are the same IEEE operations in the same order everywhere, and
``math.cos``/``math.sin`` are the C library's.  So the assembly's products, rotations and
minimum-norm Newton steps are written with those alone: the step is a Householder QR with column
pivoting of the transposed Jacobian (G. H. Golub and C. F. Van Loan, *Matrix Computations*, §5.4.1
and §5.7), O(m² n) for m rows and n coordinates.  From LARGE_ROWS rows on (a chain of more than a
hundred bodies) the step first tries the sparse path: each row touches one or two bodies, so A Aᵀ has
an envelope of a few rows in reverse Cuthill-McKee row order (`row_order`), and its envelope Cholesky
(George and Liu) with exactly rounded dot products (`math.fsum`) gives x = Aᵀ (A Aᵀ)⁻¹ b in
O(m · width²).  A row less than CLEAR clear of the others, or a solution whose residual is not at
rounding, leaves the decision to the QR (redundant joints, near-singular poses).
"""
from __future__ import annotations

import math

import numpy as np

from .ordering import reverse_cuthill_mckee


def matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A x without BLAS."""
    return (np.asarray(A, dtype=np.float64) * np.asarray(x, dtype=np.float64)).sum(axis=1)


def rotate(phi: float, s) -> np.ndarray:
    """The planar rotation by phi applied to the 2-vector s, without BLAS."""
    c, sn = math.cos(phi), math.sin(phi)
    return np.array([c * s[0] - sn * s[1], sn * s[0] + c * s[1]], dtype=np.float64)


LARGE_ROWS = 256  # rows from which `min_norm_step` tries `envelope_step` first (smaller models: the QR only)
STEP_RESIDUAL = 1e-12  # relative residual |A x - b| the envelope step must reach, else the QR's
CLEAR = 1e-6  # the envelope step is taken only when every row stands this clear (relative to the largest row) of
# the rows before it: A Aᵀ squares the conditioning, and its rounding hides remainders below ~sqrt(eps) = 1.5e-8,
# so nearly dependent rows (redundant joints, a singular pose) are left to the QR and its rank tolerance


def row_order(cols: list[np.ndarray]) -> list[int]:
    """Reverse Cuthill-McKee order of the rows (two rows are neighbours when they share a column):
    a small envelope of A Aᵀ whatever order the model text gave the joints in (`mechanism.ordering`)."""
    by_col: dict[int, list[int]] = {}
    for i, c in enumerate(cols):
        for k in c.tolist():
            by_col.setdefault(k, []).append(i)
    adj: list[set[int]] = [set() for _ in cols]
    for rows in by_col.values():
        for i in rows:
            adj[i].update(rows)
    return reverse_cuthill_mckee([sorted(a - {i}) for i, a in enumerate(adj)])


def envelope_factor(A: np.ndarray, clear: float = CLEAR):
    """The envelope Cholesky factor of P A (P A)ᵀ, P the rows' `row_order`: (the order, the nonzero
    columns of each row of P A, the first row of each row's envelope, each row's part of L), or None when
    a row's remainder (its pivot's square root: its distance from the span of the rows before it) is not
    above ``clear`` times the largest row norm (at least 1)."""
    A = np.asarray(A, dtype=np.float64)
    m = A.shape[0]
    perm = row_order([np.flatnonzero(A[i]) for i in range(m)])
    A = A[perm]
    cols = [np.flatnonzero(A[i]) for i in range(m)]
    first = np.arange(m)
    seen: dict[int, int] = {}
    for i, c in enumerate(cols):
        for k in c.tolist():
            first[i] = min(first[i], seen.setdefault(k, i))
    norm2 = max((math.fsum(A[i, c] * A[i, c]) for i, c in enumerate(cols)), default=0.0)
    tol2 = (clear * max(math.sqrt(norm2), 1.0)) ** 2
    L: list[np.ndarray] = []
    for i in range(m):
        fi, ci = int(first[i]), cols[i]
        Li = np.zeros(i - fi + 1)
        ai = A[i, ci]
        for j in range(fi, i + 1):
            fj = int(first[j])
            k0 = max(fi, fj)
            Lj = Li if j == i else L[j]
            s = math.fsum(ai * A[j, ci])
            if k0 < j:
                s -= math.fsum(Li[k0 - fi:j - fi] * Lj[k0 - fj:j - fj])
            if j < i:
                Li[j - fi] = s / Lj[j - fj]
            elif s > tol2:
                Li[i - fi] = math.sqrt(s)
            else:
                return None
        L.append(Li)
    return perm, cols, first, L


def envelope_step(A: np.ndarray, b: np.ndarray):
    """x = Aᵀ (A Aᵀ)⁻¹ b by `envelope_factor`: the smallest x with A x = b when every row stands CLEAR
    of the others; None when one does not, or when x's residual is not at rounding (then the QR decides)."""
    A = np.asarray(A, dtype=np.float64)
    factor = envelope_factor(A)
    if factor is None:
        return None
    perm, cols, first, L = factor
    A, b = A[perm], np.asarray(b, dtype=np.float64)[perm]
    m = A.shape[0]
    y = np.zeros(m)
    for i in range(m):  # L z = b
        fi = int(first[i])
        y[i] = (b[i] - math.fsum(L[i][:i - fi] * y[fi:i])) / L[i][i - fi]
    for i in range(m - 1, -1, -1):  # Lᵀ y = z: row i's entries subtract from the rows before it
        fi = int(first[i])
        y[i] /= L[i][i - fi]
        y[fi:i] -= L[i][:i - fi] * y[i]
    x = np.zeros(A.shape[1])
    for i in range(m):
        x[cols[i]] += A[i, cols[i]] * y[i]
    residual = max((abs(b[i] - math.fsum(A[i, cols[i]] * x[cols[i]])) for i in range(m)), default=0.0)
    if not residual <= STEP_RESIDUAL * max(float(np.abs(b).max(initial=0.0)), 1.0):
        return None
    return x


def min_norm_step(A: np.ndarray, b: np.ndarray, rank_tol: float) -> np.ndarray:
    """The smallest x with A x = b on a largest set of independent rows of A.

    Rows are taken greedily by the size of what they add (column pivoting of Aᵀ); a row whose
    remainder is below ``rank_tol`` times the largest row norm (at least 1) adds no rank and is left
    out, as a redundant joint's rows are.  With Aᵀ P = Q R the kept rows read Rᵀ (Qᵀx)[:r] = (Pᵀb)[:r],
    and the smallest x sets the rest of Qᵀx to zero.  From LARGE_ROWS rows on, `envelope_step` first."""
    A = np.asarray(A, dtype=np.float64)
    m, n = A.shape
    if m >= LARGE_ROWS:
        x = envelope_step(A, b)
        if x is not None:
            return x
    with np.errstate(over="ignore", invalid="ignore"):  # a hostile model's huge entries: no rank, no warning
        return _pivoted_step(A, b, rank_tol)


def _pivoted_step(A: np.ndarray, b: np.ndarray, rank_tol: float) -> np.ndarray:
    """`min_norm_step` by Householder reflections with column pivoting of Aᵀ."""
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
