"""The static equilibrium of a mechanism: where it rests under its loads, and what its joints carry.

At rest (q' = 0, the drivers held at their values at time t, 0 by default) the mechanism is in
equilibrium where the generalized applied forces Qe (loads, springs, gravity, contact and film forces
of the clearance elements: the compiled right-hand side, `run/state_rhs.py`) are carried by the ideal
joints and drivers alone, Qe = Cq^T lam.  In the minimal coordinates z of the constraint manifold
(`run/manifold.py`) this is g(z) = T(z)^T Qe(q(z)) = 0 with T = dq/dz: the virtual work of the loads
vanishes for every motion the joints allow.

Newton's method on g, from the assembled pose, with the stiffness K = -dg/dz by central differences
(step `state_rhs.difference_step`) on a chart re-centred at every iterate.  A journal centred in its
bearing has no stiffness until it touches, so each step solves (K + mu M) dz = g (M = T^T M T, the
reduced mass): pseudo-transient continuation (C. T. Kelley and D. E. Keyes, "Convergence analysis of
pseudo-transient continuation", SIAM J. Numer. Anal. 35 (1998)), an implicit step of the motion
M z'' = g with heavy damping.  mu starts where the first step moves the mechanism by the step bound
and shrinks tenfold per step; it is zero (Newton) while the symmetric part of K is positive definite,
and stays above its most negative eigenvalue otherwise, so the iteration slides down to a stable
equilibrium rather than up to an unstable one.  No step moves a body (or turns it, times the
mechanism's half-size) by more than the bound: an eighth of the mechanism's size, a quarter of the
smallest clearance.  Converged when the reduced force vanishes to rounding, or a Newton step is below
1e-8 of the length scale of the forces (`state_rhs.length_scale`: a resting journal's penetration).

Refused (`StaticError`, exit 3): no equilibrium within the iterations (a load along a direction
nothing resists), and an equilibrium that is not unique: K singular at it (a direction along which
the mechanism moves with no restoring force, such as a frictionless journal's rotation).
"""
from __future__ import annotations

import dataclasses
import os
import secrets
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SimulationError
from ..files import replace_atomically
from ..lazy import lazy
from ..version import __version__
from ..mechanism.kinematics import assemble, start_gaps
from ..mechanism.model import CP_CLEARANCE, CP_R_JOURNAL, JOINT_ROWS, Model
from .manifold import Chart, constraints, held_drivers, scales
from .state_rhs import StateRhs, contact_memory, difference_step, length_scale

MAX_ITERATIONS = 200
STEP_TOL = 1e-8  # a Newton step below this x the length scale of the forces: converged
FORCE_TOL = 1e-14  # a reduced force below this x the largest generalized force: converged
SINGULAR_TOL = 1e-12  # smallest / largest singular value of M^-1/2 K M^-1/2 below this: not unique
COORDS = ("x", "y", "angle")

h5py = lazy("h5py")  # only a file being written loads it


class StaticError(SimulationError):
    """No equilibrium found, or one that is not unique (exit code 3)."""


@dataclass
class Equilibrium:
    """A static equilibrium of `model` at time `t` (drivers held at their values then)."""

    model: Model
    q: np.ndarray  # (3 nbody,) the pose
    t: float
    multipliers: np.ndarray  # (m,) lam of Qe = Cq^T lam, per constraint row (model.kernel's row order)
    forces: np.ndarray  # (3 nbody,) Qe at the pose
    residual: np.ndarray  # (3 nbody,) Qe - Cq^T lam: what the joints do not carry (rounding)
    reduced_residual: float  # |g|_inf: the virtual work per unit minimal coordinate left
    constraint_residual: float  # |C|_inf (m or rad)
    stiffness: np.ndarray  # (f, f) K = -dg/dz at the pose
    basis: np.ndarray  # (3 nbody, f) T = dq/dz of the chart at the pose
    iterations: int
    gaps: np.ndarray = field(default_factory=lambda: np.zeros(0))  # per clearance element (> 0 apart)
    contact: np.ndarray | None = None  # the contact memory the forces were evaluated with

    @property
    def penetrations(self) -> np.ndarray:
        return np.maximum(-self.gaps, 0.0)

    def reactions(self) -> list[tuple[str, str, np.ndarray]]:
        """(element, body, (fx, fy, moment)) of each ideal joint and driver on each body it holds: the
        constraint force -Cq^T lam of its rows (N, N·m about the body's centre of mass)."""
        model, k = self.model, self.model.kernel
        _, Cq, _ = constraints(model, self.q, np.zeros_like(self.q), self.t)
        out = []
        elements = [(name, int(k.joint_row[j]), int(JOINT_ROWS[k.joint_type[j]]), k.joint_body[j])
                    for j, name in enumerate(model.joint_names)]
        elements += [(name, int(k.driver_row[d]), 1, k.driver_body[d]) for d, name in enumerate(model.driver_names)]
        for name, r0, nr, bodies in elements:
            f = -Cq[r0:r0 + nr].T @ self.multipliers[r0:r0 + nr]
            for b in sorted({int(b) for b in np.asarray(bodies).ravel() if b >= 0}):
                out.append((name, model.body_names[b], f[3 * b:3 * b + 3]))
        return out

    def stable(self) -> bool:
        """Every eigenvalue of M^-1 K has a positive real part (a minimum of the potential)."""
        if self.stiffness.size == 0:
            return True
        lam = np.linalg.eigvals(np.linalg.solve(reduced_mass(self.model, self.basis), self.stiffness))
        return bool(np.all(lam.real > 0.0))


def reduced_mass(model: Model, T: np.ndarray) -> np.ndarray:
    """T^T M T with the diagonal mass matrix M."""
    mass = 1.0 / np.asarray(model.kernel.minv, dtype=float)
    return T.T @ (mass[:, None] * T)


def step_bound(model: Model) -> float:
    """The largest move of one step (m): an eighth of the mechanism's size, a quarter of the smallest
    clearance (or journal radius, for an outline contact)."""
    params = np.asarray(model.kernel.clearance_param)
    bound = model.size / 8.0
    for k in range(model.nclearance):
        c = params[k, CP_CLEARANCE] if params[k, CP_CLEARANCE] > 0 else params[k, CP_R_JOURNAL]
        if c > 0:
            bound = min(bound, c / 4.0)
    return float(bound)


def force_scale(model: Model, Qe: np.ndarray) -> float:
    """The largest generalized force (N; a moment over the mechanism's half-size)."""
    return float(np.max(np.abs(Qe * np.tile([1.0, 1.0, 2.0 / model.size], model.nbody)), initial=0.0))


def describe(model: Model, dq: np.ndarray) -> str:
    """The largest components of a motion dq (angles times the half-size), as 'body `b` x, ...'."""
    scaled = np.abs(dq * scales(model))
    if not scaled.size or not scaled.max() > 0:
        return "no coordinate"
    top = [i for i in np.argsort(-scaled) if scaled[i] >= 0.3 * scaled.max()][:3]
    return ", ".join(f"body `{model.body_names[i // 3]}` {COORDS[i % 3]}" for i in top)


class _Reduced:
    """g(z) = T^T Qe on a chart centred at q, and K = -dg/dz by central differences."""

    def __init__(self, model: Model, rhs: StateRhs, q: np.ndarray, t: float):
        self.model, self.rhs, self.t = model, rhs, t
        self.chart = Chart(model, q, t)
        self.Qe = rhs.forces(self.chart.q0, t)
        self.g = self.chart.T0.T @ self.Qe
        self.h = difference_step(model, self.chart.q0)

    def at(self, z: np.ndarray) -> np.ndarray:
        q = self.chart.position(z)
        return self.chart.tangent(q).T @ self.rhs.forces(q, self.t)

    def stiffness(self) -> np.ndarray:
        f, h = self.chart.dof, self.h
        K = np.zeros((f, f))
        for j in range(f):
            e = np.zeros(f)
            e[j] = h
            K[:, j] = -(self.at(e) - self.at(-e)) / (2.0 * h)
        return K

    def small(self) -> bool:
        """The reduced force vanishes to rounding."""
        return bool(np.max(np.abs(self.g), initial=0.0) <= FORCE_TOL * force_scale(self.model, self.Qe))

    def normalised(self, K: np.ndarray):
        """(L, M^-1/2 K M^-1/2) with M = L L^T the reduced mass."""
        L = np.linalg.cholesky(reduced_mass(self.model, self.chart.T0))
        Li = np.linalg.inv(L)
        return L, Li @ K @ Li.T


class _Solver:
    """The iteration of the module docstring: damped Newton steps on a re-centred chart."""

    def __init__(self, model: Model, rhs: StateRhs, t: float):
        self.model, self.rhs, self.t = model, rhs, t
        self.bound = step_bound(model)
        self.mu_relax: float | None = None

    def run(self, q: np.ndarray, max_iterations: int) -> tuple[_Reduced, int]:
        red = _Reduced(self.model, self.rhs, q, self.t)
        for it in range(1, max_iterations + 1):
            if red.small() or red.chart.dof == 0:
                return red, it - 1
            K = red.stiffness()
            L, Kh = red.normalised(K)
            mu, stiff = self._damping(Kh, L, red)
            dz = np.linalg.lstsq(K + mu * (L @ L.T), red.g, rcond=None)[0]
            size = float(np.max(np.abs(scales(self.model) * (red.chart.T0 @ dz)), initial=0.0))
            capped = size > self.bound
            if capped:
                dz *= self.bound / size
            q_new, size = self._move(red, dz, size)
            red = _Reduced(self.model, self.rhs, q_new, self.t)
            if not capped and mu <= 1e-6 * stiff and size <= STEP_TOL * length_scale(self.model, q_new):
                return red, it
        direction = red.chart.T0 @ np.linalg.lstsq(reduced_mass(self.model, red.chart.T0), red.g, rcond=None)[0]
        raise StaticError(f"no equilibrium found in {max_iterations} iterations: the loads still push "
                          f"{describe(self.model, direction)} (reduced force {np.max(np.abs(red.g)):.3g} N); "
                          "nothing may resist them along that motion (a load along a free slide, a mechanism "
                          "that turns under a constant torque)", time=self.t)

    def _damping(self, Kh: np.ndarray, L: np.ndarray, red: _Reduced) -> tuple[float, float]:
        """(mu, the largest |eigenvalue| of the normalised stiffness): 0 while its symmetric part is
        positive definite, else above its most negative eigenvalue and the relaxation, which starts
        where the first step moves by the bound and shrinks tenfold per step."""
        ev = np.linalg.eigvalsh(0.5 * (Kh + Kh.T))
        stiff = float(np.max(np.abs(ev), initial=0.0))
        if self.mu_relax is None:
            explicit = red.chart.T0 @ np.linalg.solve(L @ L.T, red.g)
            self.mu_relax = float(np.max(np.abs(scales(self.model) * explicit))) / self.bound
        else:
            self.mu_relax /= 10.0
        if ev.size and ev.min() > 1e-10 * stiff:
            return 0.0, stiff
        return max(self.mu_relax, 1.1 * max(0.0, -float(ev.min())), 1e-8 * stiff), stiff

    def _move(self, red: _Reduced, dz: np.ndarray, size: float) -> tuple[np.ndarray, float]:
        """The chart point dz away (halved while the constraints cannot close or the forces fail there)."""
        for _ in range(40):
            try:
                q = red.chart.position(dz)
                self.rhs.forces(q, self.t)
                return q, min(size, self.bound)
            except SimulationError as err:
                last = err
                dz, size = 0.5 * dz, 0.5 * size
        raise StaticError(f"no equilibrium found: no step from the pose reached is possible ({last.message})",
                          time=self.t)


def equilibrium(model: Model, t: float = 0.0, start: np.ndarray | None = None,
                impact_velocity: float | None = None, max_iterations: int = MAX_ITERATIONS) -> Equilibrium:
    """The static equilibrium of `model` at time `t`, from the assembled pose (or ``start``).
    ``impact_velocity`` is the delta'(-) the dissipative contact laws are evaluated with (only the
    linearisation reads it: at rest their damping term is zero).  Raises `StaticError` (exit 3)
    when none is found or it is not unique."""
    q = assemble(model, t)[0] if start is None else np.array(start, dtype=np.float64)
    held = held_drivers(model, t)
    rhs = StateRhs(held, contact_memory(model, impact_velocity))
    red, iterations = _Solver(held, rhs, float(t)).run(q, max_iterations)
    K = red.stiffness()
    if red.chart.dof:
        _not_unique(held, red, K)
    q = red.chart.q0
    C, Cq, _ = constraints(model, q, np.zeros_like(q), t)
    lam = np.linalg.lstsq(Cq.T, red.Qe, rcond=None)[0] if Cq.shape[0] else np.zeros(0)
    return Equilibrium(model=model, q=q, t=float(t), multipliers=lam, forces=red.Qe,
                       residual=red.Qe - Cq.T @ lam, reduced_residual=float(np.max(np.abs(red.g), initial=0.0)),
                       constraint_residual=float(np.max(np.abs(C), initial=0.0)), stiffness=K,
                       basis=red.chart.T0, iterations=iterations, gaps=start_gaps(model, q), contact=rhs.contact)


def _not_unique(model: Model, red: _Reduced, K: np.ndarray) -> None:
    """StaticError when the normalised stiffness is singular, naming the free motion."""
    L, Kh = red.normalised(K)
    _, s, vt = np.linalg.svd(Kh)
    if s[0] > 0 and s[-1] > SINGULAR_TOL * s[0]:
        return
    free = red.chart.T0 @ np.linalg.solve(L.T, vt[-1])
    raise StaticError(f"the equilibrium is not unique: {describe(model, free)} can move with no restoring "
                      "force (the stiffness of the reduced system is singular there), so every pose along that "
                      "motion is at rest too; a spring, a driver, friction or a joint that holds it makes it "
                      "unique", time=red.t)


def at_rest(model: Model, eq: Equilibrium) -> Model:
    """`model` with the equilibrium as its initial state: at rest, every clearance element where the
    equilibrium put it (the assembly keeps the pose; the drivers give their velocities)."""
    return dataclasses.replace(model, q0=eq.q.copy(), qd0=np.zeros_like(eq.q), clearance_start=None,
                               clearance_assembly=[("none",)] * model.nclearance)


def write_equilibrium(g, eq: Equilibrium) -> None:
    """An equilibrium into the HDF5 group g (SI units; per body x, y, angle)."""
    g["q"], g["multipliers"], g["forces"], g["residual"] = eq.q, eq.multipliers, eq.forces, eq.residual
    g["stiffness"], g["basis"], g["gaps"] = eq.stiffness, eq.basis, eq.gaps
    g.attrs.update(t=eq.t, iterations=eq.iterations, reduced_residual=eq.reduced_residual,
                   constraint_residual=eq.constraint_residual, stable=eq.stable(),
                   body_names=list(eq.model.body_names), clearance_names=list(eq.model.clearance_names))


def write(eq: Equilibrium, path: str | Path) -> Path:
    """The equilibrium as HDF5 (group /static), written beside `path` and moved into place whole."""
    return write_file(path, eq.model, lambda f: write_equilibrium(f.create_group("static"), eq))


def write_file(path: str | Path, model: Model, fill) -> Path:
    """An HDF5 file filled by ``fill(file)``, with the model's text and the version as attributes,
    written beside `path` and moved over it once whole."""
    path = Path(path)
    part = path.with_name(f".{path.name}.{secrets.token_hex(4)}.part")
    try:
        with h5py.File(part, "w") as f:
            fill(f)
            f.attrs.update(model_source=model.source_text, model_path=model.source_path, version=__version__)
        replace_atomically(part, path)
    finally:
        if os.path.lexists(part):
            part.unlink()
    return path


def report(eq: Equilibrium) -> list[str]:
    """The equilibrium in words: how it was found, the pose, the clearance elements, the reactions."""
    model = eq.model
    held = ", drivers held at their values then" if model.ndriver else ""
    lines = [f"static equilibrium at t = {eq.t:.6g} s{held}: {eq.iterations} iteration(s); residuals: "
             f"reduced force {eq.reduced_residual:.3g} N, constraints {eq.constraint_residual:.3g} (m or rad), "
             f"unbalanced generalized force {np.max(np.abs(eq.residual), initial=0.0):.3g}",
             "  stable (the stiffness of the reduced system is positive definite)" if eq.stable() else
             "  unstable: a small displacement grows (the stiffness of the reduced system has a negative "
             "eigenvalue)", "pose (x [m], y [m], angle [deg]):"]
    tiny = 1e-14 * model.size  # rounding: printed as 0
    for b, name in enumerate(model.body_names):
        x, y, phi = (v if abs(v) > tiny else 0.0 for v in eq.q[3 * b:3 * b + 3])
        lines.append(f"  {name}: {x:.9g}, {y:.9g}, {np.degrees(phi):.9g}")
    for k, name in enumerate(model.clearance_names):
        gap = float(eq.gaps[k])
        lines.append(f"clearance element {name}: " + (f"penetration {-gap:.6g} m" if gap < 0 else
                                                      f"apart, gap {gap:.6g} m"))
    reactions = eq.reactions()
    if reactions:
        lines.append("reactions (the force each joint and driver applies to each body: fx [N], fy [N], "
                     "moment about its centre of mass [N*m]):")
    small = 1e-12 * max(force_scale(model, eq.forces), 1e-300)  # rounding: printed as 0
    for element, body, f in reactions:
        fx, fy, mz = (v if abs(v) > small * (1.0 if i < 2 else model.size / 2) else 0.0 for i, v in enumerate(f))
        lines.append(f"  {element} on {body}: {fx:.6g}, {fy:.6g}, {mz:.6g}")
    return lines
