"""Benettin's method (planar_mbs.results.lyapunov.benettin) against known largest Lyapunov exponents:
the Hénon map (a = 1.4, b = 0.3): 0.419 per iteration; the Lorenz system (σ = 10, ρ = 28,
β = 8/3): 0.906 per unit time (Sprott, "Chaos and Time-Series Analysis", 2003, table A.1)."""
from __future__ import annotations

import numpy as np
import pytest

from planar_mbs.results.lyapunov import benettin


def _euclid(a, b):
    return float(np.linalg.norm(b - a))


def _pull(a, b, s):
    return a + s * (b - a)


def henon(x):
    return np.array([1 - 1.4 * x[0] ** 2 + x[1], 0.3 * x[0]])


def test_henon_map():
    x = np.array([0.1, 0.1])
    for _ in range(1000):
        x = henon(x)
    e = benettin(henon, x, x + np.array([1e-9, 0.0]), _euclid, _pull, 1e-9, 50_000, discard=100)
    assert e.value == pytest.approx(0.419, rel=0.02)
    # convergence: the running mean over the last half stays within 2 % as well
    assert np.all(np.abs(e.running[len(e.running) // 2:] / 0.419 - 1) < 0.02)


def test_lorenz_flow():
    from numba import njit

    @njit
    def flow(x, tau, dt):
        for _ in range(int(round(tau / dt))):
            k1 = np.array([10.0 * (x[1] - x[0]), x[0] * (28.0 - x[2]) - x[1], x[0] * x[1] - 8.0 / 3.0 * x[2]])
            u = x + dt / 2 * k1
            k2 = np.array([10.0 * (u[1] - u[0]), u[0] * (28.0 - u[2]) - u[1], u[0] * u[1] - 8.0 / 3.0 * u[2]])
            u = x + dt / 2 * k2
            k3 = np.array([10.0 * (u[1] - u[0]), u[0] * (28.0 - u[2]) - u[1], u[0] * u[1] - 8.0 / 3.0 * u[2]])
            u = x + dt * k3
            k4 = np.array([10.0 * (u[1] - u[0]), u[0] * (28.0 - u[2]) - u[1], u[0] * u[1] - 8.0 / 3.0 * u[2]])
            x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return x

    x = flow(np.array([1.0, 1.0, 1.0]), 50.0, 0.005)
    e = benettin(lambda u: flow(u, 1.0, 0.005), x, x + np.array([1e-8, 0.0, 0.0]), _euclid, _pull, 1e-8, 1500,
                 discard=10)
    assert e.value == pytest.approx(0.906, rel=0.02)


def test_a_contraction_has_its_exponent():
    """A linear map x -> 0.5 x: exponent ln 0.5 whatever d0 (the method is exact when linear)."""
    e = benettin(lambda x: 0.5 * x, np.zeros(2), np.array([1e-3, 0.0]), _euclid, _pull, 1e-3, 50, discard=0)
    assert e.value == pytest.approx(np.log(0.5), rel=1e-12)
