"""The ANCF cable element's formulas (kernel/beam.py run as plain Python): rigid motion strain-free,
the mass matrix's total mass and rigid kinetic energy, the elastic force the exact gradient of the
energy, the damping force zero for rigid motion and dissipative otherwise."""
from __future__ import annotations

import math

import numpy as np
import pytest

from planar_mbs.pykernel import beam

L = 0.3
EA, EI = 2.0e6, 15.0


def scratch():
    return np.zeros((3, 4)), np.zeros(8), np.zeros(8)


def rigid(theta, x0=0.1, y0=-0.2, length=L):
    """Nodal coordinates of a straight, unstretched element at angle theta."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([x0, y0, c, s, x0 + length * c, y0 + length * s, c, s])


def arc(radius, length=L, phi0=0.3):
    """Nodes on a circle of the given radius (curvature 1/radius), slopes tangent, arc length `length`."""
    p0, p1 = phi0, phi0 + length / radius
    pos = lambda p: (radius * math.sin(p), -radius * math.cos(p))
    return np.array([*pos(p0), math.cos(p0), math.sin(p0), *pos(p1), math.cos(p1), math.sin(p1)])


@pytest.mark.parametrize("theta", [0.0, 0.7, 2.5, -1.9])
def test_rigid_motion_has_no_strain_and_no_force(theta):
    sh, de, dk = scratch()
    e = rigid(theta)
    for xi in np.linspace(0, 1, 7):
        eps, kap = beam.element_strains(e, xi, L, sh)
        assert abs(eps) < 1e-15 and abs(kap) < 1e-13
    assert beam.element_energy(e, L, EA, EI, sh) < 1e-25
    f = np.zeros(8)
    beam.element_forces(e, np.random.default_rng(1).normal(size=8) * 0, L, EA, EI, 0.0, sh, de, dk, f)
    assert np.abs(f).max() < 1e-9


def test_rigid_velocity_is_not_damped():
    """A rigid motion (translation plus rotation about a point) strains nothing: the material damping
    gives no force, whatever its rate."""
    sh, de, dk = scratch()
    theta, w, v = 0.4, 3.0, np.array([1.5, -0.7])
    e = rigid(theta)
    ed = np.zeros(8)
    for node in range(2):
        r = e[4 * node:4 * node + 2] - e[:2]
        ed[4 * node:4 * node + 2] = v + w * np.array([-r[1], r[0]])
        ed[4 * node + 2:4 * node + 4] = w * np.array([-e[4 * node + 3], e[4 * node + 2]])
    f = np.zeros(8)
    beam.element_forces(e, ed, L, EA, EI, 0.01, sh, de, dk, f)
    assert np.abs(f).max() < 1e-8


def test_mass_matrix_total_mass_and_rigid_kinetic_energy():
    """A translation at unit speed carries the element's mass rho A L; a rotation of a rod of length L
    about its end at rate w carries (rho A L) L^2 / 3 w^2 / 2, exactly (cubic Hermite: rigid motion is
    in the interpolation)."""
    rho_a = 7.8
    sh = np.zeros((3, 4))
    M = np.zeros((8, 8))
    beam.element_mass(L, rho_a, sh, M)
    assert np.allclose(M, M.T) and np.all(np.linalg.eigvalsh(M) > 0)
    m = rho_a * L
    for u in (np.array([1.0, 0.0]), np.array([0.6, 0.8])):
        ed = np.concatenate([u, [0, 0], u, [0, 0]])
        assert ed @ M @ ed == pytest.approx(m, rel=1e-14)
    w, theta = 2.0, 0.9
    e = rigid(theta, 0.0, 0.0)
    ed = np.zeros(8)
    for node in range(2):
        ed[4 * node:4 * node + 2] = w * np.array([-e[4 * node + 1], e[4 * node]])
        ed[4 * node + 2:4 * node + 4] = w * np.array([-e[4 * node + 3], e[4 * node + 2]])
    assert 0.5 * ed @ M @ ed == pytest.approx(0.5 * m * L * L / 3 * w * w, rel=1e-13)


@pytest.mark.parametrize("radius", [0.5, 2.0, -1.0])
def test_curvature_of_a_circular_arc(radius):
    """Nodes on a circle: the Hermite cubic is close to the arc, its exact curvature close to 1/R."""
    sh, _, _ = scratch()
    e = arc(radius, length=0.05)
    for xi in (0.2, 0.5, 0.8):
        _, kap = beam.element_strains(e, xi, 0.05, sh)
        assert kap == pytest.approx(1.0 / radius, rel=1e-3)


def test_elastic_force_is_minus_the_energy_gradient():
    sh, de, dk = scratch()
    rng = np.random.default_rng(3)
    e = rigid(0.8) + 0.02 * rng.normal(size=8)
    f = np.zeros(8)
    beam.element_forces(e, np.zeros(8), L, EA, EI, 0.0, sh, de, dk, f)
    h = 1e-6
    for i in range(8):
        ep, em = e.copy(), e.copy()
        ep[i] += h
        em[i] -= h
        fd = (beam.element_energy(ep, L, EA, EI, sh) - beam.element_energy(em, L, EA, EI, sh)) / (2 * h)
        assert -f[i] == pytest.approx(fd, rel=1e-6, abs=1e-6 * np.abs(f).max())


def test_damping_force_dissipates():
    """The damping force's power -eta int (EA eps_dot^2 + EI kappa_dot^2) is negative for any rate."""
    sh, de, dk = scratch()
    rng = np.random.default_rng(5)
    e = rigid(-0.3) + 0.01 * rng.normal(size=8)
    for _ in range(5):
        ed = rng.normal(size=8)
        f0, f1 = np.zeros(8), np.zeros(8)
        beam.element_forces(e, ed, L, EA, EI, 0.0, sh, de, dk, f0)
        beam.element_forces(e, ed, L, EA, EI, 1e-3, sh, de, dk, f1)
        assert (f1 - f0) @ ed < 0.0


@pytest.mark.parametrize("elements", [1, 2, 7])
def test_banded_mass_solve_and_kinetic_energy_equal_the_dense_matrices(elements):
    """`beam_minv_mul` (two banded triangular solves per direction) against numpy's dense inverse of the
    beam's assembled mass, and `beam_kinetic` against q'^T M q' / 2, on a beam placed among rigid bodies
    (node bodies from 2 on) with random loads and velocities."""
    from types import SimpleNamespace

    from planar_mbs.mechanism import beams

    Le, rho_a, first = 0.03, 0.4, 2
    M = beams.beam_mass(elements, Le, rho_a)
    nb = M.shape[0]
    n = 3 * (first + 2 * (elements + 1)) + 3  # two rigid bodies before the beam, one after
    idx = [beam.beam_qindex(first, i) for i in range(nb)]
    km = SimpleNamespace(beam_info=np.array([[first, elements, 0, 0]]), beam_mass=M.ravel(),
                         beam_band=beams.band_factor(M).ravel())
    ws = SimpleNamespace(F=np.zeros((beam.BEAM_ROWS, 2 * n)))
    rng = np.random.default_rng(elements)
    f, out0 = rng.normal(size=n), rng.normal(size=n)
    out = out0.copy()
    beam.beam_minv_mul(km, ws, f, -2.0, out)
    expect = out0.copy()
    expect[idx] -= 2.0 * np.linalg.solve(M, f[idx])
    assert np.allclose(out, expect, rtol=1e-12, atol=1e-12 * np.abs(expect).max())
    assert np.array_equal(np.delete(out, idx), np.delete(out0, idx))  # the rigid bodies' entries untouched
    qd = rng.normal(size=n)
    assert beam.beam_kinetic(km, qd) == pytest.approx(0.5 * qd[idx] @ M @ qd[idx], rel=1e-13)
