"""The time loop: output grid, chunked calls (BUFFER_FULL), statuses."""
from __future__ import annotations

import numpy as np
import pytest

import kernel_models as K
from planar_mbs import catalog
from planar_mbs.kernel import advance, make_workspace, nobs
from planar_mbs.mechanism.model import N_CONTACT_STATE, N_STATS, ContactLaw, Integrator, Status


@pytest.mark.parametrize("cap", [1, 7, 1000])
def test_chunked_calls_continue_exactly(cap):
    """Small buffers (pending outputs inside a step, mode switches deferred across
    calls) give bit-identical results to one big call."""
    km, q0, qd0 = K.free_journal(law=ContactLaw.LANKARANI_NIKRAVESH, K=1e10, v0=(0.5, 0.2))
    c = K.cfg(rtol=1e-9, atol=1e-13, output_step=1e-5)
    ref = K.run(km, q0, qd0, c, 2.5e-3, cap=100_000)
    got = K.run(km, q0, qd0, c, 2.5e-3, cap=cap)
    assert ref[0] == got[0] == Status.DONE
    np.testing.assert_array_equal(ref[1], got[1])
    np.testing.assert_array_equal(ref[2], got[2])
    np.testing.assert_array_equal(ref[3], got[3])
    keep = [0, 1, 3, 4]  # ST_RHS differs: each call recomputes f at its start state
    np.testing.assert_array_equal(ref[4][keep], got[4][keep])
    assert ref[4][3] >= 2  # several impacts


def test_output_grid_and_off_grid_final_sample():
    km, q0, qd0 = K.pendulum()
    dto = 0.03
    st, t, rows, y, stats, _ = K.run(km, q0, qd0, K.cfg(output_step=dto), 1.0)
    assert st == Status.DONE
    k = np.arange(len(t) - 1)
    np.testing.assert_array_equal(t[:-1], 0.0 + k * dto)  # by multiplication
    assert t[-1] == 1.0 and stats[4] == len(t) - 1  # the final sample is not a grid output
    np.testing.assert_array_equal(rows[-1, :6], y)
    # on-grid t_stop: no extra sample
    st, t, rows, y, stats, _ = K.run(km, q0, qd0, K.cfg(output_step=0.1), 1.0)
    assert len(t) == 11 and t[-1] == pytest.approx(1.0) and stats[4] == 11


def test_dense_outputs_match_direct_runs():
    """An output inside a step equals a run stopped at that time (to the tolerance)."""
    km, q0, qd0 = K.double_pendulum()
    c = K.cfg(rtol=1e-11, atol=1e-12, output_step=0.07)
    st, t, rows, *_ = K.run(km, q0, qd0, c, 1.0)
    st2, t2, rows2, y2, *_ = K.run(km, q0, qd0, K.cfg(rtol=1e-11, atol=1e-12, output_step=1.0), t[5])
    np.testing.assert_allclose(rows[5, :12], y2, atol=1e-8)


def _one_call(km, q0, qd0, c, t_stop):
    ws = make_workspace(km)
    y = np.concatenate([q0, qd0])
    clock = np.zeros(3)
    stats = np.zeros(N_STATS, np.int64)
    out_t, out = np.zeros(100), np.zeros((100, nobs(km)))
    st, nw = advance(km, c, y, clock, np.zeros((len(km.clearance_law), N_CONTACT_STATE)), stats, ws, t_stop, out_t, out)
    return st, nw, y, clock, stats


def test_statuses():
    km, q0, qd0 = K.pendulum()
    st, nw, y, clock, stats = _one_call(km, q0, qd0, K.cfg(max_steps=5, output_step=10.0), 1.0)
    assert st == Status.MAX_STEPS and stats[0] == 5 and 0 < clock[0] < 1.0
    st, *_ = _one_call(km, q0, qd0, K.cfg(rtol=1e-15, atol=1e-300, h_min=1e-3), 1.0)
    assert st == Status.STEP_UNDERFLOW
    bad = q0.copy()
    bad[0] = np.nan
    st, *_ = _one_call(km, bad, qd0, K.cfg(), 1.0)
    assert st == Status.NONFINITE
    st, nw, *_ = _one_call(km, q0, qd0, K.cfg(integrator=Integrator.RK4, step=0.0), 1.0)
    assert st == Status.BAD_INPUT and nw == 0
    c = K.cfg()
    c[0] = 7  # unknown integrator
    assert _one_call(km, q0, qd0, c, 1.0)[0] == Status.BAD_INPUT


def test_numba_cache_signature_is_shared():
    """All fixtures use one compiled signature of `advance` (contiguous float64/int64)."""
    assert len(advance.signatures) == 1


@pytest.mark.parametrize("law", list(ContactLaw))
def test_output_step_does_not_change_the_trajectory(law):
    """Output step 10 µs vs 1 ms and chunked calls give bit-identical states at the common
    times, for every law: evaluating outputs (or not) leaves no trace in the contact state.
    Over one crank revolution at 5000 rpm with many impacts, so any difference would grow."""
    km, q0, qd0 = K.slider_crank_clearance(law=law)
    t_end = 0.012
    for integ in (Integrator(s.code) for s in catalog.INTEGRATORS if s.adaptive):  # every adaptive one
        fine = K.run(km, q0, qd0, K.cfg(integrator=integ, rtol=1e-7, atol=1e-10, output_step=1e-5), t_end)
        coarse = K.run(km, q0, qd0, K.cfg(integrator=integ, rtol=1e-7, atol=1e-10, output_step=1e-3), t_end,
                       cap=3)
        assert fine[0] == coarse[0] == Status.DONE
        assert coarse[4][3] >= 3  # impacts happened
        tf, tc = fine[1][::100], coarse[1]
        same = tf == tc  # k * 1e-5 and (k / 100) * 1e-3 may differ in the last bit
        assert len(tf) == len(tc) == 13 and same.sum() >= 10
        np.testing.assert_array_equal(fine[2][::100][same], coarse[2][same])
        np.testing.assert_array_equal(fine[3], coarse[3])

