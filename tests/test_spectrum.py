"""Spectra (planar_mbs.results.spectrum) against closed forms: a sum of sines, Parseval, and the
Fourier series of the ideal slider-crank's slider position in the crank angle."""
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import planar_mbs as mbs
from planar_mbs.cli.app import app
from planar_mbs.results import spectrum as sp
from planar_mbs.results.hdf5 import Results

MODELS = Path(__file__).resolve().parents[1] / "models"
runner = CliRunner()


def _results(t, x, unit="m"):
    return Results(time=np.asarray(t), signals={"s.x": np.asarray(x)}, units={"s.x": unit})


SINES = [(0.3, 50.0, 0.0), (0.1, 120.0, 0.3), (0.02, 333.0, 1.0)]  # amplitude, frequency (Hz), phase


def _sines(t, offset=2.0):
    return offset + sum(a * np.sin(2 * np.pi * f * t + p) for a, f, p in SINES)


def test_amplitude_spectrum_recovers_a_sum_of_sines():
    fs, n = 2000.0, 8000  # 4 s: the frequencies fall on bins (0.25 Hz)
    t = np.arange(n) / fs
    spec = sp.amplitude_spectrum(_results(t, _sines(t)), "s.x")
    assert spec.resolution == pytest.approx(0.25) and spec.window == "hann" and spec.y_unit == "m"
    found = sorted(spec.peaks(3))
    for (f, a), (a0, f0, _) in zip(found, sorted(SINES, key=lambda s: s[1])):
        assert f == pytest.approx(f0, abs=1e-9)
        assert a == pytest.approx(a0, rel=1e-9)
    assert spec.y[0] == pytest.approx(0.0, abs=1e-12)  # the mean is removed


def test_flattop_reads_amplitudes_between_bins():
    fs, n = 2000.0, 7777  # the frequencies fall between bins: the flat-top window's scalloping is < 0.1 %
    t = np.arange(n) / fs
    spec = sp.amplitude_spectrum(_results(t, _sines(t)), "s.x", window="flattop")
    for (f, a), (a0, f0, _) in zip(sorted(spec.peaks(3)), sorted(SINES, key=lambda s: s[1])):
        assert abs(f - f0) <= spec.resolution
        assert a == pytest.approx(a0, rel=2e-3)


def test_psd_integrates_to_the_variance():
    rng = np.random.default_rng(1)
    fs, n = 1000.0, 1 << 15
    t = np.arange(n) / fs
    x = 0.5 * rng.standard_normal(n) + _sines(t)
    res = _results(t, x)
    one = sp.psd(res, "s.x", window="boxcar", resolution=fs / n)  # one rectangular segment: exact Parseval
    assert one.meta["segments"] == 1
    assert np.sum(one.y) * one.resolution == pytest.approx(np.var(x), rel=1e-12)
    welch = sp.psd(res, "s.x")  # Hann, 50 % overlap: the average of the segments' variances
    assert welch.meta["segments"] >= 7 and welch.y_unit == "m^2/Hz"
    assert np.sum(welch.y) * welch.resolution == pytest.approx(np.var(x), rel=0.02)
    assert sp.psd(res, "s.x", resolution=2.0).resolution <= 2.0


def test_uneven_samples_are_resampled():
    t = np.r_[np.arange(1000) / 1000.0, 0.9995]  # a run that ended between two output steps
    t.sort()
    x = np.sin(2 * np.pi * 25 * t)
    spec = sp.amplitude_spectrum(_results(t, x), "s.x")
    assert spec.meta["resampled"] and spec.peaks(1)[0][0] == pytest.approx(25.0, abs=spec.resolution)


def test_errors_are_worded():
    t = np.arange(100) / 100.0
    res = _results(t, np.sin(t))
    with pytest.raises(sp.SpectrumError, match="at least 8"):
        sp.spectrum(res, "s.x", t_from=0.95)
    with pytest.raises(sp.SpectrumError, match="needs 1000 samples per segment"):
        sp.spectrum(res, "s.x", "psd", resolution=0.1)
    with pytest.raises(sp.SpectrumError, match="no signal 's.y'"):
        sp.spectrum(res, "s.y")
    with pytest.raises(sp.SpectrumError, match="no turning body"):
        sp.spectrum(res, "s.x", "order")


R, L = 0.05, 0.12  # models/slider_crank.mbs: crank O-A, rod A-B


def _slider_series(order: int) -> float:
    """Amplitude of ``cos(order θ)`` in x(θ) = r cos θ + √(l² − r² sin² θ), the slider's position at
    crank angle θ: r for order 1 (the root is even in θ ↦ θ + π: only even orders), and for even
    orders the coefficient (1/π) ∫ x cos(kθ) dθ, by the trapezoidal rule on 4096 points (exact to
    rounding for a smooth periodic integrand)."""
    th = 2 * np.pi * np.arange(4096) / 4096
    x = R * np.cos(th) + np.sqrt(L ** 2 - (R * np.sin(th)) ** 2)
    return abs(2 * np.mean(x * np.cos(order * th)))


@pytest.fixture(scope="module")
def slider_crank(tmp_path_factory):
    model = mbs.load_model(MODELS / "slider_crank.mbs", speed="3000 rpm")
    path = tmp_path_factory.mktemp("spectrum") / "sc.h5"
    return mbs.simulate(model, revolutions=6, per_rev=360, output=path), path


def test_order_spectrum_of_the_slider_crank_peaks_at_integer_orders(slider_crank):
    res, _ = slider_crank
    assert _slider_series(1) == pytest.approx(R, rel=1e-12)
    assert _slider_series(2) == pytest.approx(L * ((R / L) ** 2 / 4 + (R / L) ** 4 / 16), rel=5e-3)  # series in r/l
    spec = sp.order_spectrum(res, "slider.x", t_from=0.02)  # after the first revolution
    assert spec.meta["clock"] == "crank" and spec.meta["revolutions"] == 5 and spec.resolution == pytest.approx(0.2)
    peaks = spec.peaks(4, floor=1e-9)
    assert [round(o, 9) for o, _ in peaks] == [1, 2, 4, 6]
    for order, amplitude in peaks:
        assert amplitude == pytest.approx(_slider_series(int(order)), rel=1e-4, abs=1e-8)
    between = spec.y[np.abs(spec.x - np.round(spec.x)) > 0.1]  # off the integer orders: nothing
    assert between.max() < 1e-6 * R
    # in time: the crank's frequency (50 Hz) and its multiples
    freq = sp.amplitude_spectrum(res, "slider.x", t_from=0.02)
    assert sorted(round(f / 50.0, 2) for f, _ in freq.peaks(3)) == [1, 2, 4]


def test_analyze_and_plot_spectrum(slider_crank, tmp_path):
    _, path = slider_crank
    out = runner.invoke(app, ["analyze", str(path), "--spectrum", "slider.x", "--kind", "order", "--from", "20ms",
                              "--csv", str(tmp_path / "s.csv")])
    assert out.exit_code == 0, out.output
    assert "boxcar window, resolution 0.2 orders" in out.output and "peak at order 1: 0.05 m" in out.output
    table = np.loadtxt(tmp_path / "s.csv", delimiter=",")
    assert table.shape[1] == 2 and (tmp_path / "s.csv").read_text().startswith("# order spectrum")
    out = runner.invoke(app, ["analyze", str(path), "--spectrum", "slider.ax", "--kind", "psd", "--resolution",
                              "10Hz"])
    assert out.exit_code == 0 and "m^2/s^4/Hz" not in out.output and "(m/s^2)^2/Hz" in out.output, out.output
    out = runner.invoke(app, ["analyze", str(path), "--spectrum", "slider.x", "--resolution", "10Hz"])
    assert out.exit_code == 2 and "takes --kind psd" in out.output
    out = runner.invoke(app, ["plot", str(path), "--spectrum", "slider.ax", "--kind", "order", "--from", "20ms",
                              "-o", str(tmp_path / "figs")])
    assert out.exit_code == 0, out.output
    assert (tmp_path / "figs" / "sc_order_slider.ax.png").stat().st_size > 1000
