"""Poincaré sections and the periodic / quasi-periodic / chaotic classifier.

The classifier is validated on systems whose answer is published: the forced
Duffing oscillator x'' + 0.3 x' - x + x^3 = γ cos(1.2 t) is period-1 at γ = 0.20,
period-2 at γ = 0.28 and chaotic (the classical strange attractor) at γ = 0.50
(Guckenheimer & Holmes, Nonlinear Oscillations..., 1983, §2.2; the same values
appear in the Duffing-equation article of Wikipedia), and two incommensurate
frequencies sampled stroboscopically are quasi-periodic.
"""
from __future__ import annotations

import math

import h5py
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from planar_mbs.results.analysis import (
    classify,
    correlation_dimension,
    nearest_neighbour_growth,
    poincare_section,
    read_section,
    section_times,
    write_section,
    zero_one_test,
)
from planar_mbs.results.hdf5 import Results

OMEGA = 1.2
T = 2 * math.pi / OMEGA


def duffing(gamma: float, periods: int = 250, transient: int = 100, per: int = 8):
    """Stroboscopic samples (x, v) after `transient` periods, and the spread of the whole orbit."""
    def f(t, y):
        return [y[1], -0.3 * y[1] + y[0] - y[0] ** 3 + gamma * math.cos(OMEGA * t)]

    t_eval = np.arange((periods + transient) * per + 1) * T / per
    sol = solve_ivp(f, (0, t_eval[-1]), [1.0, 0.0], t_eval=t_eval, rtol=1e-9, atol=1e-11, method="DOP853")
    y = sol.y.T[transient * per:]
    return y[::per], np.ptp(y, axis=0)


@pytest.fixture(scope="module")
def duffing_cases():
    return {g: duffing(g) for g in (0.20, 0.28, 0.50)}


def test_duffing_period_one(duffing_cases):
    points, spread = duffing_cases[0.20]
    v = classify(points, spread)
    assert v.verdict == "periodic" and v.period == 1, v.summary()
    assert v.recurrence < 1e-6
    assert v.K < 0.5


def test_duffing_period_two(duffing_cases):
    points, spread = duffing_cases[0.28]
    v = classify(points, spread)
    assert v.verdict == "periodic" and v.period == 2, v.summary()
    assert v.K < 0.5


def test_duffing_chaotic(duffing_cases):
    points, spread = duffing_cases[0.50]
    v = classify(points, spread)
    assert v.verdict == "chaotic" and v.agree, v.summary()
    assert v.K > 0.8  # the 0-1 test
    assert v.lyapunov > 0.2  # nearest neighbours separate


@pytest.mark.parametrize("ratio", [math.sqrt(2), (1 + math.sqrt(5)) / 2, math.pi])
def test_quasi_periodic_two_frequencies(ratio):
    k = np.arange(150) * 2 * math.pi  # sampled once per period of the first frequency
    points = np.column_stack([np.cos(k) + np.cos(ratio * k), -np.sin(k) - ratio * np.sin(ratio * k)])
    v = classify(points, [4.0, 2 + 2 * ratio])
    assert v.verdict == "quasi-periodic" and v.agree, v.summary()
    assert v.K < 0.5
    assert abs(v.lyapunov) < 0.05
    assert 0.8 < v.dimension < 1.3  # points on a closed curve


def test_noise_is_not_regular():
    rng = np.random.default_rng(3)
    v = classify(rng.normal(size=(150, 2)))
    assert v.verdict == "chaotic"


def test_too_few_points_is_undetermined():
    v = classify(np.zeros((5, 2)))
    assert v.verdict == "undetermined"


def test_indicators_on_simple_sequences():
    n = np.arange(400)
    assert abs(zero_one_test(np.cos(0.7 * n))) < 0.3
    rng = np.random.default_rng(0)
    assert zero_one_test(rng.normal(size=400)) > 0.9
    circle = np.column_stack([np.cos(n * 2.4), np.sin(n * 2.4)])
    assert abs(nearest_neighbour_growth(circle)) < 0.02
    assert 0.9 < correlation_dimension(circle) < 1.1
    assert correlation_dimension(rng.uniform(size=(400, 2))) > 1.6


# ---------------------------------------------------------------- sampling a run
def fake_run(period: float, per: int, revolutions: int, step: float | None = None) -> Results:
    """A crank at constant speed and a 'slider' whose vx/ax are smooth functions of time."""
    dt = step if step is not None else period / per
    t = np.arange(int(round(revolutions * period / dt)) + 1) * dt
    w = 2 * math.pi / period
    sig = {"crank.phi": w * t, "slider.vx": np.sin(w * t) + 0.5 * np.cos(2 * w * t + 0.3),
           "slider.ax": w * np.cos(w * t), "slider.phi": 0 * t}
    return Results(time=t, signals=sig, units={k: "" for k in sig}, attrs={})


def test_stroboscopic_section_on_output_grid():
    res = fake_run(0.012, 360, 30)
    sec = poincare_section(res, ("slider.vx", "slider.ax"), period=0.012, transient=1)
    assert sec.method == "grid"
    assert len(sec) == 29  # t = 2T, ..., 30T
    assert np.allclose(sec.points["slider.vx"], 0.5 * math.cos(0.3), atol=1e-9)
    v = classify(sec)
    assert v.verdict == "undetermined" or v.verdict == "periodic"


def test_section_period_from_the_clock_body():
    res = fake_run(0.05, 100, 40)
    sec = poincare_section(res, ("slider.vx", "slider.ax"))
    assert sec.period == pytest.approx(0.05, rel=1e-9)
    assert sec.clock == "crank"
    assert classify(sec).verdict == "periodic"


def test_interpolated_section_reports_its_error():
    period = 0.012
    res = fake_run(period, 0, 30, step=period / 97.3)
    sec = poincare_section(res, ("slider.vx", "slider.ax"), period=period)
    assert sec.method == "interpolated"
    err = np.max(np.abs(sec.points["slider.vx"] - 0.5 * math.cos(0.3)))
    assert err <= 2 * sec.interp_error["slider.vx"] * sec.scale["slider.vx"] + 1e-12
    assert 0 < sec.interp_error["slider.vx"] < 1e-2


def test_angle_section():
    res = fake_run(0.012, 360, 20)
    sec = poincare_section(res, ("slider.vx",), angle=math.pi / 2, transient=1)
    assert sec.kind == "angle"
    # crossings at t = (k + 1/4) T, the first dropped
    assert np.allclose(np.diff(sec.time), 0.012)
    assert sec.time[0] == pytest.approx(1.25 * 0.012)
    assert np.allclose(sec.points["slider.vx"], 1 + 0.5 * math.cos(math.pi + 0.3), atol=1e-9)


def test_a_section_is_not_stored_in_a_file_another_process_writes(tmp_path):
    """`store_section` takes the results file's write lock, as every writer does: while another
    process holds it (a run still writing the file), a clean error and the file untouched; once it is
    free, the section is stored and reads back."""
    import subprocess
    import sys

    from planar_mbs.results.analysis import store_section
    from planar_mbs.errors import MbsError

    path = tmp_path / "r.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("time", data=np.arange(3.0))
    sec = poincare_section(fake_run(0.012, 36, 40), ("slider.vx", "slider.ax"), period=0.012)
    holder = subprocess.Popen([sys.executable, "-c", "import sys\nfrom planar_mbs.results.hdf5 import WriteLock\n"
                               f"lock = WriteLock(__import__('pathlib').Path({str(path)!r}))\n"
                               "print('locked', flush=True)\nsys.stdin.read()"],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        before = path.read_bytes()
        with pytest.raises(MbsError, match="being written by another process") as err:
            store_section(path, "", sec, classify(sec))
        assert err.value.exit_code == 2
        assert path.read_bytes() == before
    finally:
        holder.communicate("", timeout=30)
    store_section(path, "", sec, classify(sec))
    with h5py.File(path, "r") as f:
        back, verdict = read_section(f)
    assert np.array_equal(back.time, sec.time) and verdict is not None


def test_section_times_skip_the_transient():
    t = np.linspace(0, 10, 1001)
    assert np.allclose(section_times(t, 2.0, transient=2), [6, 8, 10])


def test_section_round_trip(tmp_path, duffing_cases):
    res = fake_run(0.012, 36, 40)
    sec = poincare_section(res, ("slider.vx", "slider.ax"), period=0.012)
    verdict = classify(sec)
    with h5py.File(tmp_path / "s.h5", "w") as f:
        write_section(f, sec, verdict)
    with h5py.File(tmp_path / "s.h5", "r") as f:
        back, v2 = read_section(f)
    assert np.array_equal(back.time, sec.time)
    assert back.names == sec.names
    assert (v2.verdict, v2.period, v2.K, v2.n_points) == (verdict.verdict, verdict.period, verdict.K, verdict.n_points)


def test_a_verdict_with_numpy_scalars_is_stored_as_json():
    """A periodic verdict's `agree` flag came from a numpy comparison (numpy.bool_), which json cannot
    write: the last case of a 64-case scan died storing its row ("Object of type bool is not JSON
    serializable").  `as_dict` gives plain values, and a case's row is written whatever the verdict holds."""
    import json

    from planar_mbs.results.analysis import Verdict
    from planar_mbs.sweep.scan import CaseOutcome, _plain, _row

    v = Verdict("periodic", 2, np.float64(0.01), float("nan"), 0.0, np.float64(1e-9), 40, np.bool_(False))
    d = json.loads(json.dumps(v.as_dict()))
    assert d["agree"] is False and d["K"] == 0.01 and d["period"] == 2
    periodic = np.tile([[0.0, 1.0], [1.0, 0.0]], (20, 1))
    assert type(classify(periodic).agree) is bool
    outcome = CaseOutcome(index=3, key="k", values={"speed": "1rpm"}, status="finished", message="",
                          results=None, verdict=v, wall_time=np.float64(0.5))
    row = json.loads(json.dumps(_row(outcome), default=_plain))
    assert row["index"] == 3 and row["wall_time"] == 0.5 and row["K"] == 0.01
