"""Runge-Kutta tableaux, dense output and measured convergence orders.

Orders are measured by regressing log(error) on log(h) (cf. diffrax
test_integrate.py::test_ode_order) on the double pendulum over 1 s against a
DOPRI5 rtol = atol = 1e-13 reference.  DOPRI5 runs with fixed steps here:
rtol = 1e30 accepts every step and h_max = first step = h keeps it fixed.
"""
from __future__ import annotations

import numpy as np
import pytest

import kernel_models as K
from planar_mbs.kernel import integrators as I
from planar_mbs.kernel import make_workspace
from planar_mbs import catalog
from planar_mbs.kernel.integrators import dense_eval
from planar_mbs.mechanism.model import CFG_METHOD, ST_INFO, Integrator, Status


def order_conditions(A, b, c):
    """Residuals of the 17 order conditions up to order 5 (Butcher trees)."""
    Ac = A @ c
    conds = {
        1: [(b.sum(), 1.0)],
        2: [(b @ c, 1 / 2)],
        3: [(b @ c**2, 1 / 3), (b @ Ac, 1 / 6)],
        4: [(b @ c**3, 1 / 4), (b @ (c * Ac), 1 / 8), (b @ (A @ c**2), 1 / 12), (b @ (A @ Ac), 1 / 24)],
        5: [(b @ c**4, 1 / 5), (b @ (c**2 * Ac), 1 / 10), (b @ (c * (A @ c**2)), 1 / 15),
            (b @ (c * (A @ Ac)), 1 / 30), (b @ Ac**2, 1 / 20), (b @ (A @ c**3), 1 / 20),
            (b @ (A @ (c * Ac)), 1 / 40), (b @ (A @ (A @ c**2)), 1 / 60), (b @ (A @ (A @ Ac)), 1 / 120)],
    }
    return {p: np.array([v - w for v, w in rows]) for p, rows in conds.items()}


SPECS = catalog.INTEGRATORS  # every integrator of the catalog, no hand list
IDS = [s.name for s in SPECS]


def tableau(spec):
    """(A, b, c) of a catalog entry as arrays over all its stages (b zero beyond the trial step)."""
    n = spec.stages
    A = np.zeros((n, n))
    for s, row in enumerate(spec.a):
        A[s, :len(row)] = row
    return A, np.pad(np.array(spec.b), (0, n - len(spec.b))), np.array(spec.c)


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_tableau_row_sums_and_order_conditions(spec):
    """Row sums, the quadrature conditions b.c^k = 1/(k+1) up to the method's order, the order
    conditions up to min(order, 5) (and one failing beyond a lower order: exactly that order), and
    the end stage is f(t + h, y1) (FSAL)."""
    A, b, c = tableau(spec)
    np.testing.assert_allclose(A.sum(axis=1), c, atol=1e-13)
    for k in range(spec.order):
        assert abs(b @ c**k - 1 / (k + 1)) < 1e-13, k
    res = order_conditions(A, b, c)
    for p in range(1, min(spec.order, 5) + 1):
        np.testing.assert_allclose(res[p], 0, atol=1e-13)
    if spec.order < 5:
        assert np.abs(res[spec.order + 1]).max() > 1e-4
    np.testing.assert_array_equal(A[spec.end_stage], b)
    assert c[spec.end_stage] == 1.0


@pytest.mark.parametrize("spec", [s for s in SPECS if s.error_rule == "rms"], ids=lambda s: s.name)
def test_embedded_method_has_the_error_order(spec):
    """b - E (the embedded weights) is a method of order error_order exactly."""
    A, b, c = tableau(spec)
    bhat = b.copy()
    bhat[:len(spec.b)] -= np.array(spec.error[0])
    res = order_conditions(A, bhat, c)
    for p in range(1, spec.error_order + 1):
        np.testing.assert_allclose(res[p], 0, atol=1e-14)
    assert np.abs(res[spec.error_order + 1]).max() > 1e-5


def test_dop853_error_weights():
    """E5 and E3 vanish on the low-order quadrature conditions (each is the difference of two
    methods); the 3rd-order estimate is exactly order 3."""
    spec = catalog.integrator("dop853")
    c12 = np.array(spec.c[:12])
    e5, e3 = (np.array(row) for row in spec.error)
    for k in range(3):
        assert abs(e5 @ c12**k) < 1e-13
        assert abs(e3 @ c12**k) < 1e-13
    assert abs(e3 @ c12**3) > 1e-6


def test_dop853_dense_output_ends_and_accuracy():
    """The 7th-order dense output reproduces both step ends and, in an adaptive run,
    matches the closed-form pendulum between steps about as well as at step ends."""
    rng = np.random.default_rng(2)
    km, q0, qd0 = K.double_pendulum()
    ws = make_workspace(km)
    N = ws.ya.shape[0]
    ws.ya[:] = rng.normal(size=N)
    ws.K[:] = rng.normal(size=ws.K.shape)
    ws.dense[:2] = (0.3, 0.01)
    h = ws.dense[1]
    spec = catalog.integrator("dop853")
    ws.yb[:] = ws.ya + h * (np.array(spec.b) @ ws.K[:12])
    ws.flags[2] = spec.code
    c = K.cfg(integrator=Integrator.DOP853)
    stats = np.zeros(8, np.int64)
    contact = np.zeros((0, 3))
    assert I.dense_prepare(km, c, contact, ws, stats) == 0
    out = np.zeros(N)
    dense_eval(ws, 0.0, out)
    np.testing.assert_allclose(out, ws.ya, atol=1e-13)
    dense_eval(ws, 1.0, out)
    np.testing.assert_allclose(out, ws.yb, atol=1e-12)
    km, q0, qd0 = K.pendulum(theta0=1.0, omega0=0.0)
    st, t, rows, y, stats, _ = K.run(km, q0, qd0, K.cfg(Integrator.DOP853, rtol=1e-10, atol=1e-10,
                                                         output_step=0.01), 1.0)
    assert st == Status.DONE and stats[0] < 60  # about 40 steps for 100 outputs: most are interpolated
    th, _ = pendulum_closed_form(t, theta0=1.0)
    assert np.max(np.abs(rows[:, 2] + np.pi / 2 - th)) < 1e-9


def _dense_ws(method, rng):
    km, q0, qd0 = K.double_pendulum()
    ws = make_workspace(km)
    N = ws.ya.shape[0]
    ws.ya[:] = rng.normal(size=N)
    ws.yb[:] = rng.normal(size=N)
    ws.K[:] = rng.normal(size=ws.K.shape)
    ws.dense[:2] = (0.3, 0.01)
    ws.flags[2] = method
    return ws


def test_dopri5_dense_output_matches_scipy_rk45_polynomial():
    """Hairer's continuous extension equals SciPy's RK45.P form (same interpolant)
    when yb = ya + h sum b_j k_j, and reproduces both ends."""
    from scipy.integrate._ivp.rk import RK45

    rng = np.random.default_rng(0)
    spec = catalog.integrator("dopri5")
    ws = _dense_ws(spec.code, rng)
    h = ws.dense[1]
    ws.yb[:] = ws.ya + h * (np.array(spec.b) @ ws.K[:7])
    out = np.zeros_like(ws.ya)
    for th in [0.0, 0.13, 0.5, 0.77, 1.0]:
        dense_eval(ws, th, out)
        ref = ws.ya + h * ws.K[:7].T @ (RK45.P @ np.array([th, th**2, th**3, th**4]))
        np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)
    dense_eval(ws, 1.0, out)
    np.testing.assert_allclose(out, ws.yb, atol=1e-13)


def test_rk4_hermite_dense_output():
    rng = np.random.default_rng(1)
    ws = _dense_ws(catalog.integrator("rk4").code, rng)
    h = ws.dense[1]
    out = np.zeros_like(ws.ya)
    dense_eval(ws, 0.0, out)
    np.testing.assert_allclose(out, ws.ya, atol=1e-14)
    dense_eval(ws, 1.0, out)
    np.testing.assert_allclose(out, ws.yb, atol=1e-14)
    eps = 1e-6  # end-point derivatives are K[0] and K[4]
    o1 = np.zeros_like(out)
    dense_eval(ws, eps, o1)
    np.testing.assert_allclose((o1 - ws.ya) / (eps * h), ws.K[0], atol=1e-3)
    dense_eval(ws, 1 - eps, o1)
    np.testing.assert_allclose((ws.yb - o1) / (eps * h), ws.K[4], atol=1e-3)


T_ORDER = 4.0
THETA0 = 0.1  # small swing: with theta0 = 1 DOPRI5's local ratios are still 5.46, 5.29, 5.17 here


def pendulum_closed_form(t, L=1.0, m=1.0, I=1e-3, g=K.G, theta0=THETA0):
    """Pendulum released from rest: sin(theta/2) = k sn(K(k) - w t | k^2), k = sin(theta0/2),
    w^2 = m g L / (I + m L^2); theta' = -2 k w cn(.)."""
    from scipy.special import ellipj, ellipk

    k = np.sin(theta0 / 2)
    w = np.sqrt(m * g * L / (I + m * L * L))
    sn, cn, dn, _ = ellipj(ellipk(k * k) - w * t, k * k)
    return 2 * np.arcsin(k * sn), -2 * k * w * cn


def _fixed(method, nsteps):
    km, q0, qd0 = K.pendulum(theta0=THETA0, omega0=0.0)
    h = T_ORDER / nsteps
    if not SPECS[method].adaptive:
        c = K.cfg(integrator=method, step=h, output_step=T_ORDER)
    else:
        c = K.cfg(integrator=method, step=h, h_max=h, rtol=1e30, atol=1e30, output_step=T_ORDER)
    st, _, _, y, stats, _ = K.run(km, q0, qd0, c, T_ORDER)
    assert st == Status.DONE
    assert stats[0] == nsteps and stats[1] == 0
    return y


def measured_order(spec) -> tuple[float, np.ndarray]:
    """(regression slope of log error on log step, errors): fixed steps of `spec`'s method on the
    pendulum, (theta, theta') at T against the closed form (fewer, longer steps for a high order,
    whose error reaches roundoff sooner).  docs/validation.md states these slopes."""
    method = Integrator(spec.code)
    steps = [28, 40, 56, 80] if spec.order >= 7 else [80, 160, 320, 640]
    th, om = pendulum_closed_form(T_ORDER)
    err = []
    for n in steps:
        y = _fixed(method, n)
        err.append(max(abs(y[2] + np.pi / 2 - th), abs(y[5] - om)))
    err = np.array(err)
    h = T_ORDER / np.array(steps)
    return float(np.polyfit(np.log(h), np.log(err), 1)[0]), err


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_convergence_order(spec):
    """Every integrator of the catalog converges at its order.  Measured: RK4 3.99, DOPRI5 5.05 (local
    ratios 5.09, 5.05, 5.03), DOP853 7.88 (local ratios rising towards 8), BS3 2.99."""
    slope, err = measured_order(spec)
    print(f"{spec.name}: errors {err}, measured order {slope:.3f}")
    assert abs(slope - float(spec.order)) < 0.3
    assert err[-1] > 1e-13  # above roundoff


@pytest.mark.parametrize("method", [Integrator(s.code) for s in SPECS if s.adaptive], ids=lambda m: m.name.lower())
def test_adaptive_method_meets_tolerance(method):
    km, q0, qd0 = K.pendulum(theta0=1.0, omega0=0.0)
    th, om = pendulum_closed_form(1.0, theta0=1.0)
    errs = []
    for rtol in [1e-6, 1e-9, 1e-12]:
        st, _, _, y, stats, _ = K.run(km, q0, qd0, K.cfg(method, rtol=rtol, atol=rtol, output_step=0.1), 1.0)
        assert st == Status.DONE
        errs.append(abs(y[2] + np.pi / 2 - th))
    assert errs[0] < 1e-5 and errs[1] < 1e-8 and errs[2] < 1e-11
    assert errs[0] > errs[1] > errs[2]


@pytest.mark.parametrize("spec", [s for s in SPECS if s.dense != "none"], ids=lambda s: s.name)
def test_every_dense_output_reproduces_both_ends(spec):
    """Each method's dense output starts at y0 and ends at its own y1 = y0 + h sum b_j k_j."""
    rng = np.random.default_rng(3)
    ws = _dense_ws(spec.code, rng)
    h = ws.dense[1]
    nb = len(spec.b)
    ws.yb[:] = ws.ya + h * (np.array(spec.b) @ ws.K[:nb])
    km, _, _ = K.double_pendulum()
    c = K.cfg(integrator=Integrator(spec.code))
    assert I.dense_prepare(km, c, np.zeros((0, 3)), ws, np.zeros(8, np.int64)) == 0
    out = np.zeros_like(ws.ya)
    dense_eval(ws, 0.0, out)
    np.testing.assert_allclose(out, ws.ya, atol=1e-12)
    dense_eval(ws, 1.0, out)
    np.testing.assert_allclose(out, ws.yb, atol=1e-12)


def test_an_unknown_method_gets_no_dense_output_and_no_run():
    """No fallback to another method's interpolant: NaN from the dense output, BAD_INPUT (with the
    reason's code in stats[ST_INFO]) from the time loop."""
    ws = _dense_ws(len(SPECS), np.random.default_rng(4))
    out = np.zeros_like(ws.ya)
    dense_eval(ws, 0.5, out)
    assert np.all(np.isnan(out))
    km, q0, qd0 = K.pendulum(theta0=0.1, omega0=0.0)
    c = K.cfg(integrator=Integrator.DOPRI5)
    c[CFG_METHOD] = len(SPECS)
    st, _, _, _, stats, _ = K.run(km, q0, qd0, c, 0.1)
    assert st == Status.BAD_INPUT and stats[ST_INFO] == I.BAD_METHOD


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_the_stage_loop_reads_every_nonzero_coefficient_of_the_tableau(spec):
    """The stage loop (`rk_stages`) sums only the non-zero A_sj, read from STAGE_W/STAGE_J: rebuilt
    into a dense matrix they give back the catalog's `a` exactly, and no entry is a zero."""
    from planar_mbs.kernel import integrators as I

    for s, row in enumerate(spec.a):
        dense = np.zeros(len(row))
        nz = I.STAGE_NZ[spec.code, s]
        dense[I.STAGE_J[spec.code, s, :nz]] = I.STAGE_W[spec.code, s, :nz]
        assert np.array_equal(dense, np.asarray(row, dtype=float)), (spec.name, s)
        assert np.all(I.STAGE_W[spec.code, s, :nz] != 0.0)
        assert np.all(np.diff(I.STAGE_J[spec.code, s, :nz]) > 0)  # in the order of j: the same sums
