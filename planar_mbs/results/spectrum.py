"""Spectra of a signal after its transient: FFT amplitude, Welch PSD, order spectrum.

Three kinds, all through `scipy.signal` (docs/studies.md):

``amplitude``  one-sided amplitude spectrum, `scipy.signal.periodogram` with
               ``scaling="spectrum"``: a sine ``A sin(2π f t)`` on a bin reads ``A`` at ``f``
               (the window's coherent gain corrected); unit: the signal's.
``psd``        power spectral density by Welch's method (`scipy.signal.welch`,
               ``scaling="density"``): unit²/Hz, its integral over frequency the
               signal's variance (Parseval).  Welch, IEEE Trans. Audio Electroacoust. 15 (1967) 70.
``order``      the amplitude spectrum of the signal resampled at equal steps of the
               clock body's angle (computed order tracking): a component that repeats
               ``k`` times per revolution reads its amplitude at order ``k``.  Whole
               revolutions only, so that integer orders fall on bins.

Each `Spectrum` states its window, resolution, segment length and the part of the run
used, and names its unit as docs/signals.md writes units (``m/s^2``, ``m^2/s^4/Hz``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from ..lazy import lazy
from .section import clock_body

signal = lazy("scipy.signal")
interpolate = lazy("scipy.interpolate")

KINDS = ("amplitude", "psd", "order")
DEFAULT_WINDOW = {"amplitude": "hann", "psd": "hann", "order": "boxcar"}
WELCH_SEGMENTS = 8  # default Welch: about this many segments of 50 % overlap
UNIFORM_TOL = 1e-6  # relative spread of the time steps below which the samples are uniform


class SpectrumError(ModelError, ValueError):
    """The spectrum cannot be computed (too few samples, no clock angle, a bad option): exit code 2."""


@dataclass
class Spectrum:
    """One spectrum of one signal and how it was computed."""

    signal: str
    kind: str  # one of KINDS
    x: np.ndarray  # frequencies (Hz) or orders (per revolution)
    y: np.ndarray  # amplitude (signal unit) or PSD (unit^2/Hz)
    x_unit: str  # "Hz" or "order"
    y_unit: str
    window: str
    resolution: float  # bin width, in x_unit
    t_from: float  # s: the first sample used
    t_to: float  # s: the last sample used
    n_samples: int  # samples (or angle steps) transformed
    meta: dict = field(default_factory=dict)  # fs, segment length, overlap, revolutions, clock, ...

    def peaks(self, count: int = 5, floor: float = 1e-3) -> list[tuple[float, float]]:
        """The ``count`` highest local maxima above ``floor`` × the highest, highest first."""
        y = np.asarray(self.y, float)
        if len(y) < 3 or not np.any(y > 0):
            return []
        idx, _ = signal.find_peaks(np.r_[0.0, y, 0.0], height=floor * float(y.max()))
        idx = idx - 1
        best = idx[np.argsort(y[idx])[::-1][:count]]
        return [(float(self.x[i]), float(self.y[i])) for i in best]

    def describe(self) -> str:
        """One line: the method, window, resolution and span, as `mbs analyze --spectrum` prints it."""
        what = {"amplitude": "amplitude spectrum (periodogram)", "psd": "power spectral density (Welch)",
                "order": "order spectrum (resampled on the angle of " + str(self.meta.get("clock")) + ")"}[self.kind]
        res = f"{self.resolution:.4g} {self.x_unit}" + ("s" if self.x_unit == "order" else "")
        extra = ""
        if self.kind == "psd":
            extra = f", segments of {self.meta['nperseg']} samples, {self.meta['noverlap']} overlapping"
        if self.kind == "order":
            extra = f", {self.meta['revolutions']} whole revolutions, {self.meta['per_rev']} samples per revolution"
        return (f"{what} of {self.signal} [{self.y_unit}]: {self.window} window, resolution {res}{extra}; "
                f"t = {self.t_from:.6g} s to {self.t_to:.6g} s ({self.n_samples} samples)")

    def as_dict(self) -> dict:
        """Plain values, ready for JSON (the arrays as lists)."""
        out = {k: getattr(self, k) for k in ("signal", "kind", "x_unit", "y_unit", "window", "resolution",
                                             "t_from", "t_to", "n_samples", "meta")}
        return {**out, "x": np.asarray(self.x).tolist(), "y": np.asarray(self.y).tolist()}


# ---------------------------------------------------------------- the samples
def _after(results, name: str, t_from: float | None, t_to: float | None):
    """(t, x) of signal ``name`` with ``t_from <= t <= t_to``."""
    t = np.asarray(results.time, float)
    x = np.asarray(results[name], float)
    mask = np.ones(len(t), bool)
    if t_from is not None:
        mask &= t >= t_from
    if t_to is not None:
        mask &= t <= t_to
    if mask.sum() < 8:
        raise SpectrumError(f"{mask.sum()} samples of {name} between {t_from or t[0]:g} s and {t_to or t[-1]:g} s: "
                            "a spectrum needs at least 8 (choose an earlier --from or run longer)")
    return t[mask], x[mask]


def uniform(t: np.ndarray, x: np.ndarray) -> tuple[float, np.ndarray, bool]:
    """(dt, x on equal steps, resampled?): linear interpolation onto the median step where the
    steps differ by more than `UNIFORM_TOL` (a run that ended between two output steps)."""
    dt = np.diff(t)
    step = float(np.median(dt))
    if not step > 0:
        raise SpectrumError("the samples' times do not increase: no spectrum")
    if np.ptp(dt) <= UNIFORM_TOL * step:
        return step, x, False
    grid = t[0] + step * np.arange(int(math.floor((t[-1] - t[0]) / step * (1 + 1e-12))) + 1)
    return step, np.interp(grid, t, x), True


def _unit_squared(unit: str) -> str:
    if unit in ("", "1"):
        return "1"
    return f"({unit})^2" if "/" in unit or "*" in unit else f"{unit}^2"


# ---------------------------------------------------------------- the three kinds
def amplitude_spectrum(results, name: str, *, t_from: float | None = None, t_to: float | None = None,
                       window: str = DEFAULT_WINDOW["amplitude"]) -> Spectrum:
    """One-sided amplitude spectrum (peak amplitude per bin); mean removed."""
    t, x = _after(results, name, t_from, t_to)
    dt, x, resampled = uniform(t, x)
    f, p = signal.periodogram(x, fs=1.0 / dt, window=window, detrend="constant", scaling="spectrum")
    amp = np.sqrt(2.0 * p)
    amp[0] = math.sqrt(p[0])  # DC is not doubled (and ~0 after the mean is removed)
    if len(x) % 2 == 0:
        amp[-1] = math.sqrt(p[-1])  # nor Nyquist
    unit = results.units.get(name, "")
    return Spectrum(name, "amplitude", f, amp, "Hz", unit, window, 1.0 / (dt * len(x)), float(t[0]), float(t[-1]),
                    len(x), {"fs": 1.0 / dt, "detrend": "constant", "resampled": resampled})


def psd(results, name: str, *, t_from: float | None = None, t_to: float | None = None,
        window: str = DEFAULT_WINDOW["psd"], resolution: float | None = None) -> Spectrum:
    """Welch PSD with 50 % overlapping segments: of ``fs / resolution`` samples when a resolution
    (Hz) is given, else about `WELCH_SEGMENTS` segments; mean removed per segment."""
    t, x = _after(results, name, t_from, t_to)
    dt, x, resampled = uniform(t, x)
    n = len(x)
    if resolution is not None:
        nperseg = int(math.ceil(1.0 / (dt * resolution)))
        if nperseg > n:
            raise SpectrumError(f"a resolution of {resolution:g} Hz needs {nperseg} samples per segment, more than "
                                f"the {n} of the signal ({n * dt:.4g} s): ask for at least {1 / (n * dt):.4g} Hz")
    else:
        nperseg = max(8, min(n, int(2 * n / (WELCH_SEGMENTS + 1))))
    noverlap = nperseg // 2
    f, p = signal.welch(x, fs=1.0 / dt, window=window, nperseg=nperseg, noverlap=noverlap, detrend="constant",
                        scaling="density")
    unit = results.units.get(name, "")
    segments = 1 + (n - nperseg) // (nperseg - noverlap)
    return Spectrum(name, "psd", f, p, "Hz", _unit_squared(unit) + "/Hz", window, 1.0 / (dt * nperseg), float(t[0]),
                    float(t[-1]), n, {"fs": 1.0 / dt, "nperseg": nperseg, "noverlap": noverlap,
                                      "segments": segments, "detrend": "constant", "resampled": resampled})


def order_spectrum(results, name: str, *, t_from: float | None = None, t_to: float | None = None,
                   clock: str | None = None, per_rev: int | None = None,
                   window: str = DEFAULT_WINDOW["order"]) -> Spectrum:
    """Amplitude against order (cycles per revolution of ``clock``, default the driven body):
    the signal interpolated at ``per_rev`` equal steps of the angle per revolution over the whole
    revolutions after ``t_from``.  Brandt, "Noise and Vibration Analysis" (2011), §12.3."""
    clock = clock or clock_body(results)
    if clock is None or f"{clock}.phi" not in results:
        raise SpectrumError("no turning body to take the order spectrum against: name one (--clock BODY)")
    t, x = _after(results, name, t_from, t_to)
    _, phi = _after(results, f"{clock}.phi", t_from, t_to)
    sense = 1.0 if phi[-1] >= phi[0] else -1.0
    turn = sense * (phi - phi[0])
    if np.any(np.diff(turn) < 0):
        raise SpectrumError(f"{clock} does not turn one way over the samples used: no order spectrum")
    revs = int(math.floor(turn[-1] / (2 * math.pi) + 1e-9))
    if revs < 1:
        raise SpectrumError(f"{clock} turns {turn[-1] / (2 * math.pi):.3g} revolutions after t = {t[0]:g} s: "
                            "an order spectrum needs at least one whole revolution")
    per_rev = per_rev or _per_rev(len(t), turn[-1])
    angles = 2 * math.pi * np.arange(revs * per_rev) / per_rev
    xs = _at_angles(turn, x, angles)
    o, p = signal.periodogram(xs, fs=per_rev, window=window, detrend="constant", scaling="spectrum")
    amp = np.sqrt(2.0 * p)
    amp[0] = math.sqrt(p[0])
    if len(xs) % 2 == 0:
        amp[-1] = math.sqrt(p[-1])
    t_end = float(np.interp(revs * 2 * math.pi, turn, t))
    return Spectrum(name, "order", o, amp, "order", results.units.get(name, ""), window, 1.0 / revs, float(t[0]),
                    t_end, len(xs), {"clock": clock, "revolutions": revs, "per_rev": per_rev,
                                     "detrend": "constant"})


def _per_rev(n: int, turn: float) -> int:
    """Angle steps per revolution: the samples per revolution (rounded up), at least 16; at a
    constant speed sampled ``--per-rev`` times a revolution, the samples themselves."""
    per = (n - 1) / max(turn / (2 * math.pi), 1e-300)
    return max(16, int(math.ceil(per - 1e-6)))


def _at_angles(turn: np.ndarray, x: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """``x`` at ``angles`` by a cubic spline in the angle (linear where the angle stands still)."""
    if len(turn) < 4 or np.any(np.diff(turn) <= 0):
        return np.interp(angles, turn, x)
    return interpolate.make_interp_spline(turn, x, k=3)(angles)


def spectrum(results, name: str, kind: str = "amplitude", **options) -> Spectrum:
    """The spectrum of ``kind`` (`KINDS`) of signal ``name`` of `results`."""
    if name not in results:
        try:
            results[name]
        except KeyError as err:  # the closest names
            raise SpectrumError(str(err.args[0]), hint="`mbs plot FILE --list` lists the signals") from None
    funcs = {"amplitude": amplitude_spectrum, "psd": psd, "order": order_spectrum}
    if kind not in funcs:
        raise SpectrumError(f"unknown spectrum `{kind}`: choose one of {', '.join(KINDS)}")
    if options.get("window") is None:
        options.pop("window", None)
    try:
        return funcs[kind](results, name, **options)
    except ValueError as err:  # scipy: an unknown window name
        if isinstance(err, SpectrumError):
            raise
        raise SpectrumError(f"{kind} spectrum of {name}: {err}") from None


def report(spec: Spectrum, count: int = 5) -> list[str]:
    """The lines `mbs analyze --spectrum` prints: the description, then the highest peaks."""
    lines = [spec.describe()]
    unit = f" {spec.y_unit}" if spec.y_unit not in ("", "1") else ""
    for x, y in spec.peaks(count):
        where = f"order {x:.4g}" if spec.kind == "order" else f"{x:.6g} Hz"
        lines.append(f"  peak at {where}: {y:.4g}{unit}")
    if len(lines) == 1:
        lines.append("  no peak: the signal is constant after the transient")
    return lines
