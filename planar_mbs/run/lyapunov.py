"""The largest Lyapunov exponent by Benettin's method: two nearby trajectories, renormalised.

G. Benettin, L. Galgani, A. Giorgilli and J.-M. Strelcyn, "Lyapunov characteristic
exponents for smooth dynamical systems and for Hamiltonian systems; a method for
computing all of them", Meccanica 15 (1980) 9–20.  A reference trajectory and a
companion started ``d0`` away are advanced together over a segment (one driver
period for a mechanism, one iteration for a map); the companion's distance ``d``
is measured, ``log(d / d0)`` recorded, and the companion pulled back along the same
direction to distance ``d0``.  The exponent is the mean of the logs per unit of
segment; its running mean shows the convergence, and starting from several
perturbed states gives a spread.

`benettin` is generic (any state, any ``advance``); `mechanism_exponent` applies it
to a model, segment = one driver period, from a given kernel state (a settled one).
`floquet_exponent` is a second, independent estimate for a periodic orbit: the
multipliers of its period map, differentiated by central differences.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..lazy import lazy

if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from .. import kernel
else:  # each loaded on its first use (see the comments: not on the light paths)
    kernel = lazy("..kernel", __package__)  # numba: only `tangent_perturbation` runs a kernel


@dataclass
class Exponent:
    """A largest Lyapunov exponent per segment, with its convergence."""

    value: float  # mean of log growth per segment, after `discard` segments
    logs: np.ndarray  # log(d/d0) of every segment
    discard: int  # segments left out while the perturbation aligns with the leading direction

    @property
    def running(self) -> np.ndarray:
        """Running mean of the logs after the discarded segments (convergence)."""
        x = self.logs[self.discard:]
        return np.cumsum(x) / np.arange(1, len(x) + 1)


def benettin(advance: Callable, reference, companion, distance: Callable, pull: Callable, d0: float,
             segments: int, discard: int = 10) -> Exponent:
    """Largest Lyapunov exponent, per segment.

    ``advance(state) -> state`` moves a state over one segment (it may change it in place);
    ``distance(a, b)`` is the norm of the difference; ``pull(a, b, s)`` returns ``b`` moved
    to ``a + s (b − a)``.  ``companion`` starts at distance ``d0`` from ``reference``."""
    logs = np.empty(segments)
    for k in range(segments):
        reference = advance(reference)
        companion = advance(companion)
        d = distance(reference, companion)
        if not (d > 0 and np.isfinite(d)):
            logs[k] = np.nan if not np.isfinite(d) else -np.inf
            companion = pull(reference, companion, 1.0)
            continue
        logs[k] = np.log(d / d0)
        companion = pull(reference, companion, d0 / d)
    discard = min(discard, segments // 2)
    x = logs[discard:]
    x = x[np.isfinite(x)]
    return Exponent(float(np.mean(x)) if len(x) else float("nan"), logs, discard)


# ---------------------------------------------------------------- mechanisms
NO_FREEDOM = ("the joints and drivers allow no motion: a mechanism without degrees of freedom has no "
              "Lyapunov exponent or Floquet multiplier")
LENGTH = 1e-3  # m: positions are measured in mm in the distance, angles in rad, rates over one radian of crank


BRISTLES = ("a model with LuGre friction (friction_model = lugre) has its bristle deflections as states beside "
            "(q, q'), which these studies do not perturb: not supported")


def _no_bristles(model) -> None:
    if model.nstate:
        raise ValueError(BRISTLES)


def state_scale(model, omega: float) -> np.ndarray:
    """Weights of (q, q') in the distance: x, y per `LENGTH`, angles as they are, velocities
    times 1/omega (a velocity is measured by the displacement it makes in one radian of crank)."""
    n = 3 * model.nbody
    w = np.ones(n)
    w[0::3] = w[1::3] = 1.0 / LENGTH
    return np.concatenate([w, w / omega])


def _jacobian(model, y: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(Cq, Ct): the constraint Jacobian and the constraints' explicit time derivative at ``y``, ``t``."""
    n = 3 * model.nbody
    m = kernel.constraint_rows(model.kernel)
    C, Ct, g, Cq = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros((m, n))
    if m:
        kernel.constraint_eval(model.kernel, y[:n], y[n:], t, C, Cq, Ct, g)
    return Cq, Ct


def _null_space(Cq: np.ndarray) -> np.ndarray:
    """Columns spanning the motions the constraint Jacobian allows."""
    if Cq.shape[0] == 0:
        return np.eye(Cq.shape[1])
    _, s, vt = np.linalg.svd(Cq)
    rank = int(np.sum(s > 1e-10 * s[0]))
    return vt[rank:].T


def tangent_perturbation(model, y: np.ndarray, t: float, rng) -> np.ndarray:
    """A random direction of (q, q') that keeps the constraints to first order: positions
    unchanged, velocities in the null space of the constraint Jacobian (a motion the joints
    allow)."""
    n = 3 * model.nbody
    null = _null_space(_jacobian(model, y, t)[0])
    dv = null @ (null.T @ rng.normal(size=n))
    return np.concatenate([np.zeros(n), dv])


def mechanism_exponent(stepper, period: float, revolutions: int, *, d0: float = 1e-6, seed: int = 0,
                       per_rev: int = 16, discard: int = 10) -> Exponent:
    """Benettin's exponent of the Poincaré map (per driver period) of the trajectory held by
    ``stepper`` (a `planar_mbs.run.stepper.Stepper` at a time on the period grid), from a
    companion perturbed in a random allowed direction (``seed``), renormalised ``per_rev``
    times per period (an impact can multiply a perturbation by 1e4 within one period: the
    companion must stay in the linear range).  The distance is measured
    with `state_scale` (d0 = 1e-6: 1 nm or 1 µrad); the contact modes and stored impact
    velocities are each trajectory's own and are not part of the distance.

    Both trajectories are projected onto the constraints after every step (``projection =
    on``): pulling the companion back by a factor s moves it to ``ref + s (comp - ref)``, so
    any constraint residual in which they differ would be multiplied by s at every
    renormalisation; unprojected, the drift off the constraints (which neither grows nor
    decays) outlasts an attracting orbit's perturbation and the estimate tends to 0."""
    model = stepper.model
    _no_bristles(model)
    w = state_scale(model, 2 * np.pi / period)
    rng = np.random.default_rng(seed)
    ref = stepper.copy(projection="on")
    comp = stepper.copy(projection="on")
    dy = tangent_perturbation(model, ref.y, ref.t, rng)
    if not np.linalg.norm(w * dy) > 0:
        raise ValueError(NO_FREEDOM)
    dy *= d0 / np.linalg.norm(w * dy)
    comp.y += dy

    seg = period / per_rev

    def advance(s):
        s.run_to((round(s.t / seg) + 1) * seg)
        return s

    def distance(a, b):
        return float(np.linalg.norm(w * (b.y - a.y)))

    def pull(a, b, s):
        b.y[:] = a.y + s * (b.y - a.y)
        b.clock[0] = a.clock[0]
        return b

    e = benettin(advance, ref, comp, distance, pull, d0, revolutions * per_rev, discard * per_rev)
    # per driver period: the logs of the segments of each revolution summed
    logs = e.logs[: revolutions * per_rev].reshape(revolutions, per_rev).sum(axis=1)
    return Exponent(e.value * per_rev, logs, discard)


@dataclass
class Floquet:
    """Multipliers of a periodic orbit's map over ``periods`` driver periods."""

    value: float  # largest log |multiplier| per driver period
    multipliers: np.ndarray  # eigenvalues of the period map, largest modulus first
    closure: float  # distance (as in `state_scale`) between the orbit's start and its end: 0 if periodic


def floquet_exponent(stepper, period: float, periods: int = 1, *, eps: float = 1e-4) -> Floquet:
    """Largest Floquet exponent of the periodic orbit through the state of ``stepper``, per driver period.

    The orbit's map over ``periods`` driver periods is differentiated by central differences: each
    coordinate of the motions the joints allow (positions and velocities in the null space of the
    constraint Jacobian, weighted by `state_scale`) is moved by ±``eps``, the velocities are put back
    on the velocity constraints, and both states run from fresh copies of the stepper (contact modes
    and stored impact velocities of the reference).  The eigenvalues μ of the map's matrix are the
    multipliers; the exponent is max log|μ| / ``periods``.  Unlike `mechanism_exponent` nothing is
    renormalised and no trajectory runs beside another, so it checks Benettin's estimate
    independently (on a periodic orbit the two must agree).

    A multiplier μ is resolved only where ``eps`` |μ| stands well above the period map's integration
    error, which is about rtol times the weighted state (1e-8 for the clearance slider-crank at rtol
    1e-10): ``eps`` = 1e-6 left its multipliers of 3e-3 in that noise (exponents from -4.8 to -6.7 as
    the orbit settled), 1e-4 and 1e-3 agree within 1 %.  Central differences keep the curvature's
    error of order ``eps``²."""
    model = stepper.model
    _no_bristles(model)
    n = 3 * model.nbody
    w = state_scale(model, 2 * np.pi / period)
    y0, t0 = stepper.y.copy(), stepper.t
    null = _null_space(_jacobian(model, y0, t0)[0])
    f = null.shape[1]
    if f == 0:
        raise ValueError(NO_FREEDOM)
    basis = np.zeros((2 * n, 2 * f))
    basis[:n, :f] = null
    basis[n:, f:] = null
    Q, _ = np.linalg.qr(w[:, None] * basis)  # orthonormal in the weighted distance

    def start(dy):
        y = y0 + dy
        Cq, Ct = _jacobian(model, y, t0)
        if Cq.shape[0]:
            y[n:] -= np.linalg.lstsq(Cq, Cq @ y[n:] + Ct, rcond=None)[0]
        return y

    def end(y):
        s = stepper.copy()
        s.y[:] = y
        s.run_to(t0 + periods * period)
        return s.y.copy()

    closure = float(np.linalg.norm(Q.T @ (w * (end(y0) - y0))))
    into, out = np.zeros((2 * f, 2 * f)), np.zeros((2 * f, 2 * f))
    for j in range(2 * f):
        plus, minus = start(eps * Q[:, j] / w), start(-eps * Q[:, j] / w)
        into[:, j] = Q.T @ (w * (plus - minus))
        out[:, j] = Q.T @ (w * (end(plus) - end(minus)))
    mu = np.linalg.eigvals(out @ np.linalg.inv(into))
    mu = mu[np.argsort(-np.abs(mu))]
    return Floquet(float(np.log(np.abs(mu[0])) / periods), mu, closure)
