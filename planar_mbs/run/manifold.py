"""Minimal coordinates of a constrained mechanism about a pose: a chart of its constraint manifold.

The ideal joints and drivers of a model are m rows C(q, t) = 0 over the N = 3 nbody body coordinates.
About a pose q0 on them, the chart is the graph of the manifold over its tangent plane:

    q(z) = q0 + D^-1 (Z z + Y w(z)),   C(q(z), t) = 0,

where the columns of Z (N x f) and Y (N x r) are the right singular vectors of the scaled Jacobian
Cq D^-1 with zero and non-zero singular value (r its rank, f = N - r the degrees of freedom), and w(z)
is found by Newton's method (``w -= (Cq D^-1 Y)^+ C``, pseudo-inverse: a redundant joint adds rows, not
rank).  D scales each angle by the mechanism's half-size (`Model.size` / 2), so that every minimal
coordinate is a length and the basis is orthonormal in a metric of lengths.  The chart is exact: z =
Z^T D (q - q0) on the manifold, so z' = Z^T D q' and z'' = Z^T D q''.  Velocities of a chart point
follow from the velocity constraint Cq q' + Ct = 0: q' = D^-1 (Z z' + Y w'), w' = -(Cq D^-1 Y)^+ (Ct +
Cq D^-1 Z z').  `tangent` is dq/dz at a chart point (Ct left out): the virtual displacements, whose
transpose maps generalized forces to the chart.

The constraint rows are those of `kernel/constraints.py`, run without numba (`planar_mbs.pykernel`), as
the assembly of the initial pose runs them.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import dataclasses

import numpy as np

from ..errors import SimulationError
from ..lazy import lazy
from ..mechanism.kinematics import RANK_TOL
from ..mechanism.model import Model, MotionType, frozen

# the constraint kernels' source as plain Python (as the assembly runs it)
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from ..pykernel import constraints as pyconstraints
else:  # each loaded on its first use (see the comments: not on the light paths)
    pyconstraints = lazy("..pykernel.constraints", __package__)

EPS = float(np.finfo(np.float64).eps)
NEWTON_STEPS = 30  # at most, for w(z); each step squares the residual until rounding stops it


def held_drivers(model: Model, t: float = 0.0) -> Model:
    """`model` with every driver held at its value at time t (a constant: no speed, no acceleration), as
    the equilibrium and the modes about it take them.  The kernel arrays keep their types, so the
    compiled kernels serve the copy as they are."""
    k = model.kernel
    if model.ndriver == 0:
        return model
    reg, modes, _ = pyconstraints.expression_scratch(k)
    param = np.zeros_like(np.asarray(k.driver_motion_param))
    for d in range(model.ndriver):
        param[d, 0] = pyconstraints.driver_motion(k, reg, modes, d, float(t))[0]
    motion = np.full(model.ndriver, int(MotionType.CONSTANT_SPEED), dtype=np.asarray(k.driver_motion).dtype)
    held = frozen(k._replace(driver_motion=motion, driver_motion_param=param))
    return dataclasses.replace(model, kernel=held)


def scales(model: Model) -> np.ndarray:
    """D: 1 for x and y, the mechanism's half-size (m) for each angle."""
    d = np.ones(model.ncoord)
    d[2::3] = model.size / 2.0
    return d


def constraints(model: Model, q: np.ndarray, qd: np.ndarray, t: float):
    """C, Cq, Ct of the ideal joints and drivers at (q, q', t)."""
    m, n = model.nconstraint, model.ncoord
    C, Ct, gamma, Cq = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros((m, n))
    if m:
        with np.errstate(all="ignore"):
            pyconstraints.constraint_eval(model.kernel, np.asarray(q, dtype=float), np.asarray(qd, dtype=float),
                                          t, C, Cq, Ct, gamma)
    return C, Cq, Ct


class Chart:
    """Minimal coordinates z about the pose ``q0`` of ``model`` at time ``t`` (the module docstring)."""

    def __init__(self, model: Model, q0: np.ndarray, t: float = 0.0):
        self.model, self.t = model, float(t)
        self.q0 = np.array(q0, dtype=np.float64)
        self.d = scales(model)
        C, Cq, _ = constraints(model, self.q0, np.zeros_like(self.q0), self.t)
        n = model.ncoord
        if Cq.shape[0] == 0:
            self.Z, self.Y = np.eye(n), np.zeros((n, 0))
        else:
            if not np.all(np.isfinite(Cq)):
                raise SimulationError("the constraint Jacobian is not finite at this pose", time=self.t)
            _, s, vt = np.linalg.svd(Cq / self.d, full_matrices=True)
            rank = int(np.count_nonzero(s > RANK_TOL * max(s[0] if len(s) else 0.0, 1.0)))
            self.Z, self.Y = vt[rank:].T.copy(), vt[:rank].T.copy()
        self.residual0 = float(np.max(np.abs(C))) if len(C) else 0.0
        self.T0 = self.Z / self.d[:, None]  # dq = T0 dz at q0
        self.P = self.Z.T * self.d  # dz = P dq

    @property
    def dof(self) -> int:
        return self.Z.shape[1]

    def coords(self, q: np.ndarray) -> np.ndarray:
        """z of a pose on the manifold near q0."""
        return self.P @ (np.asarray(q, dtype=float) - self.q0)

    def position(self, z: np.ndarray) -> np.ndarray:
        """q(z): the pose on the constraints whose tangent-plane coordinates are z (Newton on w)."""
        z = np.asarray(z, dtype=float)
        base = self.q0 + (self.Z @ z) / self.d
        if self.Y.shape[1] == 0:
            return base
        w = np.zeros(self.Y.shape[1])
        q, best, best_err = base, base, np.inf
        zero = np.zeros_like(base)
        for _ in range(NEWTON_STEPS):
            C, Cq, _ = constraints(self.model, q, zero, self.t)
            err = float(np.max(np.abs(C))) if np.all(np.isfinite(C)) else np.inf
            if not err < best_err:  # rounding reached (or a divergence): keep the best pose
                break
            best, best_err = q, err
            if err == 0.0:
                break
            w -= np.linalg.lstsq((Cq / self.d) @ self.Y, C, rcond=None)[0]
            q = base + (self.Y @ w) / self.d
        if not best_err <= max(1e-9 * self.model.size, 1e3 * self.residual0):
            raise SimulationError(f"the constraints cannot be closed {np.max(np.abs(z)):.3g} m (minimal "
                                  f"coordinates) away from this pose: residual {best_err:.3g}", time=self.t)
        return best

    def _solve(self, q: np.ndarray, qd: np.ndarray):
        """(Cq D^-1 at q, Ct at (q, q'), the pseudo-inverse of Cq D^-1 Y)."""
        _, Cq, Ct = constraints(self.model, q, qd, self.t)
        A = Cq / self.d
        return A, Ct, np.linalg.pinv(A @ self.Y, rcond=RANK_TOL)

    def tangent(self, q: np.ndarray) -> np.ndarray:
        """dq/dz at the chart point q (N x f): the virtual displacements there."""
        if self.Y.shape[1] == 0:
            return self.T0.copy()
        A, _, pinv = self._solve(q, np.zeros_like(q))
        return (self.Z - self.Y @ (pinv @ (A @ self.Z))) / self.d[:, None]

    def velocity(self, q: np.ndarray, zd: np.ndarray) -> np.ndarray:
        """q' at the chart point q for chart velocities z' (the drivers' own motion, Ct, included)."""
        zd = np.asarray(zd, dtype=float)
        if self.Y.shape[1] == 0:
            return (self.Z @ zd) / self.d
        A, Ct, pinv = self._solve(q, (self.Z @ zd) / self.d)
        wd = -pinv @ (Ct + A @ (self.Z @ zd))
        return (self.Z @ zd + self.Y @ wd) / self.d
