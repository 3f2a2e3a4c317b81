"""Linearisation of the constrained motion about a state, and its modes.

In the minimal coordinates z of the constraint manifold about the state's pose (`run/manifold.py`),
the motion is x' = F(x) with x = (z, z') and F = (z', Z^T D q''(q(z), q'(z, z'), t)): q'' from the
compiled right-hand side (`run/state_rhs.py`), the multipliers and every force included.  The state
matrix A = dF/dx (2f x 2f) is taken by central differences:

* a minimal coordinate (a length: angles count times the mechanism's half-size) by
  h = (eps L l^2)^(1/3), l the length over which the forces change at the state (the size of the
  mechanism, or the gap or penetration of a clearance element near contact), L the magnitude of the
  positions (`state_rhs.difference_step`);
* a minimal velocity by h_v = eps^(1/3) max(|z'|_inf, size / 1 s) (`state_rhs.velocity_step`);

every perturbed state is put back on the constraints (positions by Newton, velocities by the velocity
constraint), so A is the linearisation on the manifold.  About an equilibrium (q' = 0, the drivers
held) A = [[0, I], [-M^-1 K, -M^-1 C]]; about any other state it is the instantaneous Jacobian of the
motion (drivers moving, velocities as given).

Its eigenvalues lambda give the modes: a conjugate pair -zeta w_n +- i w_n sqrt(1 - zeta^2) is an
oscillation of natural frequency w_n = |lambda| and damping ratio zeta = -Re(lambda) / |lambda|; a real
eigenvalue is a motion that decays (lambda < 0) or grows (lambda > 0, unstable) without oscillating.
A mode shape is the eigenvector's position part mapped to the body coordinates (dq = T dz), scaled
so that its largest component (angles times the half-size) is 1.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..mechanism.kinematics import assemble
from ..mechanism.model import Model
from .manifold import Chart, held_drivers, scales
from .state_rhs import StateRhs, contact_memory, difference_step, velocity_step
from .static import Equilibrium, equilibrium, write_equilibrium, write_file

NEUTRAL_TOL = 1e-5  # |lambda| below this x the largest: a motion without restoring force
ROUNDING_RATIO = 1e-9  # a damping ratio below this is the differences' rounding (printed as 0)
STEP_RULE = ("central differences; minimal coordinates (lengths; angles times the half-size) stepped by "
             "h = (eps L l^2)^(1/3), l the length scale of the forces, L of the positions; minimal velocities "
             "by h_v = eps^(1/3) max(|z'|, size / 1 s)")


@dataclass
class Mode:
    """One mode: a conjugate pair of eigenvalues (the one with Im > 0) or a real eigenvalue."""

    index: int
    eigenvalue: complex
    kind: str  # "oscillating", "decaying", "growing" or "neutral"
    shape: np.ndarray  # (3 nbody,) complex, largest component 1

    @property
    def omega(self) -> float:
        """Natural frequency |lambda| (rad/s)."""
        return float(abs(self.eigenvalue))

    @property
    def frequency(self) -> float:
        """Natural frequency (Hz)."""
        return self.omega / (2.0 * np.pi)

    @property
    def damping_ratio(self) -> float:
        """-Re(lambda) / |lambda| (nan for a neutral motion)."""
        return float(-self.eigenvalue.real / self.omega) if self.omega > 0 else float("nan")

    @property
    def damped_frequency(self) -> float:
        """|Im(lambda)| / 2 pi (Hz): the frequency of the free oscillation."""
        return float(abs(self.eigenvalue.imag) / (2.0 * np.pi))


@dataclass
class Modes:
    """The linearisation of `model` at the state (q, q', t) and its modes (the module docstring)."""

    model: Model
    q: np.ndarray
    qd: np.ndarray
    t: float
    state_matrix: np.ndarray  # (2f, 2f) A of x' = A x, x = (z, z')
    basis: np.ndarray  # (3 nbody, f) T: dq = T dz
    projection: np.ndarray  # (f, 3 nbody) P: dz = P dq
    eigenvalues: np.ndarray  # (2f,) complex, by |lambda|
    vectors: np.ndarray  # (2f, 2f) complex eigenvectors of A (columns)
    step: float  # h of the minimal coordinates (m)
    velocity_step: float  # h_v of the minimal velocities (m/s)
    held: bool  # drivers held at their values at t
    equilibrium: Equilibrium | None = None

    @property
    def dof(self) -> int:
        return self.basis.shape[1]

    def modes(self) -> list[Mode]:
        """One `Mode` per conjugate pair (Im > 0) and per real eigenvalue, by natural frequency."""
        lam = self.eigenvalues
        big = float(np.max(np.abs(lam), initial=0.0))
        out = []
        for i, v in enumerate(lam):
            tol = 1e-9 * max(abs(v), 1e-300)
            if v.imag < -tol:
                continue
            if abs(v) <= NEUTRAL_TOL * big or big == 0.0:
                kind = "neutral"
            elif v.imag > tol:
                kind = "oscillating"
            else:
                kind = "decaying" if v.real < 0 else "growing"
            out.append(Mode(len(out) + 1, complex(v), kind, self.shape(i)))
        return out

    def shape(self, i: int) -> np.ndarray:
        """Mode shape of eigenvalue i in the body coordinates, its largest scaled component 1."""
        phi = self.basis @ self.vectors[:self.dof, i]
        scaled = np.abs(phi * scales(self.model))
        if not scaled.max() > 0:
            return phi
        return phi / phi[int(np.argmax(scaled))]

    @property
    def stable(self) -> bool:
        return bool(np.all(self.eigenvalues.real <= NEUTRAL_TOL * np.max(np.abs(self.eigenvalues), initial=0.0)))


def state_matrix(model: Model, q: np.ndarray, qd: np.ndarray, t: float, rhs: StateRhs):
    """(A, chart, h, h_v) at (q, q', t): the state is put on the constraints first."""
    near = Chart(model, q, t)
    chart = Chart(model, near.position(np.zeros(near.dof)), t)
    f = chart.dof
    zd0 = chart.P @ np.asarray(qd, dtype=float)
    h = difference_step(model, chart.q0)
    hv = velocity_step(float(np.max(np.abs(zd0), initial=0.0)), model)

    def accel(z, zd):
        qq = chart.position(z)
        return chart.P @ rhs(qq, chart.velocity(qq, zd), t)[1]

    A = np.zeros((2 * f, 2 * f))
    A[:f, f:] = np.eye(f)
    z0 = np.zeros(f)
    for j in range(f):
        e = np.zeros(f)
        e[j] = h
        A[f:, j] = (accel(z0 + e, zd0) - accel(z0 - e, zd0)) / (2.0 * h)
        e[j] = hv
        A[f:, f + j] = (accel(z0, zd0 + e) - accel(z0, zd0 - e)) / (2.0 * hv)
    return A, chart, h, hv


def linearize(model: Model, state=None, t: float | None = None, contact: np.ndarray | None = None,
              impact_velocity: float | None = None, hold_drivers: bool | None = None) -> Modes:
    """The state matrix and modes of `model` about ``state``: None (the static equilibrium, found
    first), an `Equilibrium`, ``"assembled"`` (the assembled initial state, drivers moving) or a
    pair (q, q').  ``t`` is the time of the state (default: the equilibrium's, else 0); ``contact``
    the clearance elements' memory (`state_rhs.contact_memory` by default: in contact mode, impact
    velocity ``impact_velocity`` or the floor); ``hold_drivers`` defaults to True about an
    equilibrium and False about another state.  Raises `StaticError` or `SimulationError` (exit 3)."""
    eq = None
    if state is None or isinstance(state, Equilibrium):
        eq = equilibrium(model, t=0.0 if t is None else t, impact_velocity=impact_velocity) if state is None \
            else state
        q, qd, t = eq.q, np.zeros_like(eq.q), eq.t
        if contact is None:
            contact = eq.contact if impact_velocity is None else contact_memory(model, impact_velocity)
        hold = True if hold_drivers is None else hold_drivers
    else:
        t = 0.0 if t is None else float(t)
        q, qd = assemble(model, t) if isinstance(state, str) and state == "assembled" else state
        hold = False if hold_drivers is None else hold_drivers
    used = held_drivers(model, t) if hold else model
    rhs = StateRhs(used, contact_memory(model, impact_velocity) if contact is None else contact)
    A, chart, h, hv = state_matrix(used, np.asarray(q, dtype=float), np.asarray(qd, dtype=float), t, rhs)
    lam, vec = np.linalg.eig(A) if A.size else (np.zeros(0, complex), np.zeros((0, 0), complex))
    order = np.lexsort((-lam.imag, np.round(np.abs(lam), 12)))
    return Modes(model=model, q=chart.q0, qd=np.asarray(qd, dtype=float), t=float(t), state_matrix=A,
                 basis=chart.T0, projection=chart.P, eigenvalues=lam[order].astype(complex),
                 vectors=vec[:, order].astype(complex), step=h, velocity_step=hv, held=hold, equilibrium=eq)


def report(modes: Modes, limit: int | None = None) -> list[str]:
    """The modes in words: one line per mode (frequency, damping ratio, what moves most)."""
    from_static = "about the static equilibrium" if modes.equilibrium is not None else f"at t = {modes.t:.6g} s"
    held = ", drivers held" if modes.held and modes.model.ndriver else ""
    lines = [f"{modes.dof} degree(s) of freedom, linearised {from_static}{held}; "
             f"steps h = {modes.step:.3g} m, h_v = {modes.velocity_step:.3g} m/s ({STEP_RULE.split(';')[0]})"]
    shown = modes.modes()
    for m in shown[:limit]:
        lines.append(f"  mode {m.index}: {_mode_words(m)}; moves {_moving(modes.model, m.shape)}")
    if limit is not None and len(shown) > limit:
        lines.append(f"  ... {len(shown) - limit} more (--modes N shows more)")
    if not modes.stable:
        lines.append("  unstable: an eigenvalue has a positive real part")
    return lines


def damping_words(zeta: float) -> str:
    """A damping ratio as printed: below ROUNDING_RATIO it is the differences' rounding, shown as 0."""
    return f"0 (|zeta| < {ROUNDING_RATIO:g})" if abs(zeta) < ROUNDING_RATIO else f"{zeta:.4g}"


def _mode_words(m: Mode) -> str:
    re = 0.0 if abs(m.eigenvalue.real) < ROUNDING_RATIO * m.omega else m.eigenvalue.real
    lam = f"lambda = {re:.6g}{m.eigenvalue.imag:+.6g}i 1/s"
    if m.kind == "oscillating":
        return (f"f = {m.frequency:.6g} Hz (omega_n = {m.omega:.6g} rad/s), damping ratio "
                f"{damping_words(m.damping_ratio)}, damped {m.damped_frequency:.6g} Hz; {lam}")
    if m.kind == "neutral":
        return f"no restoring force (|lambda| = {m.omega:.3g} 1/s)"
    rate = "decays" if m.kind == "decaying" else "grows (unstable)"
    return f"{rate} without oscillating at {abs(m.eigenvalue.real):.6g} 1/s"


def _moving(model: Model, shape: np.ndarray) -> str:
    scaled = np.abs(shape * scales(model))
    top = [i for i in np.argsort(-scaled) if scaled[i] >= 0.3 * scaled.max()][:3]
    return ", ".join(f"{model.body_names[i // 3]}.{('x', 'y', 'angle')[i % 3]}" for i in top)


def write(modes: Modes, path: str | Path) -> Path:
    """The linearisation and its modes as HDF5 (group /modes; /static with the equilibrium when there
    is one), written beside `path` and moved into place whole."""
    def fill(f):
        _write_modes(f.create_group("modes"), modes)
        if modes.equilibrium is not None:
            write_equilibrium(f.create_group("static"), modes.equilibrium)
    return write_file(path, modes.model, fill)


def _write_modes(g, modes: Modes) -> None:
    shown = modes.modes()
    g["state_matrix"], g["basis"], g["projection"] = modes.state_matrix, modes.basis, modes.projection
    g["eigenvalues"], g["eigenvectors"] = modes.eigenvalues, modes.vectors
    g["q"], g["qd"] = modes.q, modes.qd
    g["frequency"] = np.array([m.frequency for m in shown])
    g["damping_ratio"] = np.array([m.damping_ratio for m in shown])
    g["damped_frequency"] = np.array([m.damped_frequency for m in shown])
    g["shapes"] = np.array([m.shape for m in shown]).reshape(len(shown), modes.model.ncoord)
    g.attrs.update(t=modes.t, step=modes.step, velocity_step=modes.velocity_step, step_rule=STEP_RULE,
                   drivers_held=modes.held, kinds=[m.kind for m in shown], body_names=list(modes.model.body_names),
                   coordinates="per body: x [m], y [m], angle [rad]", frequency_unit="Hz")
