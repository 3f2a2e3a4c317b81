"""Poincaré sections and a measured verdict on the motion: periodic, quasi-periodic or chaotic.

A **Poincaré section** (`poincare_section`) samples chosen signals of a run once
per period of the driver (stroboscopic section, Muvengei et al.'s choice) or each time
a clock body passes a given angle, after a transient.  When the output step
divides the period, the section times are output times and the samples are the
integrator's own values (``method = "grid"``); otherwise they are interpolated
linearly and the interpolation error is estimated from the local second
difference (``interp_error``, relative to each signal's range).

A **verdict** (`classify`) rests on three indicators computed on the sequence
of section points, each reported with it (docs/replication.md gives the
thresholds and how they were validated on the forced Duffing oscillator):

``recurrence``  the smallest ``p`` such that the points repeat after ``p``
                iterations, ``max_k |x[k+p] − x[k]|`` relative to the spread of
                the signals (``tol_periodic``); finds periodic motion and its
                period count (the number of distinct Poincaré points).
``K``           the 0-1 test for chaos of Gottwald & Melbourne (correlation
                method, SIAM J. Appl. Dyn. Syst. 8 (2009) 129): the median over
                random frequencies ``c`` of the correlation of the mean-square
                displacement of the translation variables with time; near 0 for
                regular motion (periodic or quasi-periodic), near 1 for chaos.
``lyapunov``    the mean logarithmic growth per iteration of the distance of
                nearest neighbours in the section (a Lyapunov exponent of the
                Poincaré map estimated from data, Rosenstein-style): about 0 on
                the invariant circle of quasi-periodic motion, clearly positive
                for chaos.
``dimension``   the correlation dimension of the section (Grassberger–
                Procaccia): about 1 for points on a closed curve
                (quasi-periodic), above 1 for a strange attractor.  Reported,
                and used only to tell a closed curve from a cloud when the
                other two disagree.

Rules: periodic(p) when the recurrence test passes; otherwise chaotic when
``K`` and ``lyapunov`` both say so, quasi-periodic when both say regular,
and when they disagree the correlation dimension decides (the verdict then
carries ``agree = False``).

numpy only; matplotlib only inside the figure functions.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Sequence

import numpy as np

# ---------------------------------------------------------------- thresholds
TOL_PERIODIC = 1e-3  # recurrence residual / spread below which the motion is periodic
MAX_PERIOD = 16  # longest period looked for (in driver periods)
K_CHAOS = 0.5  # 0-1 test: K above -> chaotic, below -> regular
LYAPUNOV_CHAOS = 0.1  # nearest-neighbour growth per iteration above -> chaotic
DIMENSION_CURVE = 1.3  # correlation dimension below -> points on a curve


# ---------------------------------------------------------------- the section
@dataclass
class PoincareSection:
    """Section points of a run: ``points[name]`` sampled at ``time``."""

    time: np.ndarray
    points: dict[str, np.ndarray]
    period: float | None  # driver period T (s); None for an angle section with a varying speed
    transient: float  # periods (or revolutions) dropped
    method: str  # "grid" (section times are output times) or "interpolated"
    kind: str = "stroboscopic"  # or "angle"
    angle: float | None = None  # rad, for kind == "angle"
    clock: str | None = None  # the body whose angle clocks the section
    interp_error: dict[str, float] = field(default_factory=dict)  # relative, per signal
    scale: dict[str, float] = field(default_factory=dict)  # spread of each signal after the transient

    @property
    def names(self) -> list[str]:
        return list(self.points)

    def array(self, names: Sequence[str] | None = None) -> np.ndarray:
        names = list(names or self.names)
        return np.column_stack([self.points[n] for n in names]) if len(self.time) else np.zeros((0, len(names)))

    def __len__(self) -> int:
        return len(self.time)

    def attrs(self) -> dict:
        return {
            "period": self.period if self.period is not None else float("nan"),
            "transient": self.transient, "method": self.method, "kind": self.kind,
            "angle": self.angle if self.angle is not None else float("nan"),
            "clock": self.clock or "", "signals": self.names,
            "interp_error": self.interp_error, "scale": self.scale,
        }


class AnalysisError(ValueError):
    """The section cannot be taken (no driver period, too short a run, unknown signal)."""


def driver_period(model) -> tuple[float, str] | None:
    """``(T, body name)`` of the model's first absolute rotation driver at constant speed, else None."""
    from .model import DriverType, MotionType

    k = model.kernel
    for d in range(model.ndriver):
        if (k.driver_type[d] == DriverType.ANGLE and k.driver_body[d, 0] < 0
                and k.driver_motion[d] == MotionType.CONSTANT_SPEED):
            w = float(k.driver_motion_param[d, 1])
            if w != 0.0:
                return 2 * math.pi / abs(w), model.body_names[int(k.driver_body[d, 1])]
    return None


def clock_body(results) -> str:
    """The body whose angle changes most over the run (the crank of a slider-crank)."""
    best, span = None, -1.0
    for name in results.signals:
        if name.endswith(".phi"):
            phi = results.signals[name]
            s = float(np.ptp(phi)) if len(phi) else 0.0
            if s > span:
                best, span = name[:-4], s
    if best is None:
        raise AnalysisError("the results hold no body angle to clock a Poincaré section")
    return best


def estimate_period(results, clock: str | None = None) -> tuple[float, str]:
    """The period of a clock body turning at constant speed, from its angle signal
    (a straight-line fit; refused if the speed varies by more than 0.1 %)."""
    clock = clock or clock_body(results)
    t, phi = results.time, results[f"{clock}.phi"]
    if len(t) < 3:
        raise AnalysisError("the run is too short to estimate a period")
    w, c = np.polyfit(t, phi, 1)
    if w == 0 or np.max(np.abs(phi - (w * t + c))) > 1e-3 * abs(w) * (t[-1] - t[0]):
        raise AnalysisError(f"`{clock}` does not turn at a constant speed: give the period, or use an angle section")
    return 2 * math.pi / abs(w), clock


def _sample(t: np.ndarray, x: np.ndarray, ts: np.ndarray) -> tuple[np.ndarray, float]:
    """Values of ``x`` at times ``ts``: output values where ``ts`` hits the grid, linear
    interpolation elsewhere; also the estimated largest interpolation error (absolute)."""
    idx = np.clip(np.searchsorted(t, ts), 1, len(t) - 1)
    lo, hi = t[idx - 1], t[idx]
    frac = (ts - lo) / (hi - lo)
    vals = x[idx - 1] + frac * (x[idx] - x[idx - 1])
    # |x''| h^2 / 8 bound of linear interpolation, second difference around the interval
    i0 = np.clip(idx - 1, 1, len(t) - 2)
    d2 = np.abs(x[i0 + 1] - 2 * x[i0] + x[i0 - 1])
    on_grid = (np.minimum(frac, 1 - frac) * (hi - lo)) <= 1e-9 * (hi - lo) + 1e-12 * np.abs(ts)
    err = np.where(on_grid, 0.0, d2 / 8)
    return vals, float(err.max()) if len(err) else 0.0


def section_times(t: np.ndarray, period: float, transient: float = 1.0, phase: float = 0.0) -> np.ndarray:
    """Stroboscopic section times ``t0 + phase + kT`` inside the run with ``k > transient``:
    the first ``transient`` periods are dropped, and so is the state at their end, which
    still carries the start (as in `planar_mbs.plot`: the first point is the end of period 2)."""
    if len(t) == 0:
        return np.zeros(0)
    t0, t1 = float(t[0]), float(t[-1])
    k0 = math.ceil(transient - 1e-9) + 1
    k1 = math.floor((t1 - t0 - phase) / period * (1 + 1e-12) + 1e-9)
    if k1 < k0:
        return np.zeros(0)
    ts = t0 + phase + period * np.arange(k0, k1 + 1)
    return np.minimum(ts, t1)


def snap_to_grid(t: np.ndarray, ts: np.ndarray, rel: float = 1e-6) -> tuple[np.ndarray, bool]:
    """Replace section times by the output times they coincide with (within ``rel`` of the
    output step); True if all of them do."""
    if len(ts) == 0 or len(t) < 2:
        return ts, True
    dt = float(np.min(np.diff(t)))
    idx = np.clip(np.searchsorted(t, ts), 1, len(t) - 1)
    near = np.where(np.abs(t[idx] - ts) < np.abs(t[idx - 1] - ts), idx, idx - 1)
    hit = np.abs(t[near] - ts) <= rel * dt
    out = np.where(hit, t[near], ts)
    return out, bool(hit.all())


def angle_crossings(t: np.ndarray, phi: np.ndarray, angle: float) -> np.ndarray:
    """Times at which the (unwrapped) angle ``phi`` passes ``angle + 2πk``, either direction,
    by linear interpolation between samples."""
    s = (phi - angle) / (2 * math.pi)
    lvl = np.floor(s)
    jumps = np.nonzero(np.diff(lvl) != 0)[0]
    times = []
    for i in jumps:
        target = max(lvl[i], lvl[i + 1])  # the integer crossed
        f = (target - s[i]) / (s[i + 1] - s[i])
        times.append(t[i] + f * (t[i + 1] - t[i]))
    return np.array(times)


def poincare_section(results, signals: Sequence[str] = ("slider.vx", "slider.ax"), *, period: float | None = None,
                     angle: float | None = None, clock: str | None = None, transient: float = 1.0,
                     model=None) -> PoincareSection:
    """Sample ``signals`` of a run once per driver period (default) or at the clock body's
    ``angle`` (rad, measured like its ``phi`` signal), after ``transient`` periods/revolutions.

    The period is, in order: ``period``; the constant speed of ``model``'s first rotation
    driver; a straight-line fit of the clock body's angle.
    """
    for name in signals:
        results[name]  # KeyError with a suggestion
    t = results.time
    if len(t) < 2:
        raise AnalysisError("the run holds fewer than two output times")
    if angle is None:
        if period is None and model is not None:
            found = driver_period(model)
            if found:
                period, clock = found[0], clock or found[1]
        if period is None:
            period, clock = estimate_period(results, clock)
        ts = section_times(t, period, transient)
        ts, on_grid = snap_to_grid(t, ts)
        kind = "stroboscopic"
    else:
        clock = clock or (driver_period(model)[1] if model is not None and driver_period(model) else clock_body(results))
        phi = results[f"{clock}.phi"]
        ts = angle_crossings(t, phi, angle)
        ts = ts[ts >= t[0] + 0.0]
        skip = math.ceil(transient - 1e-9)
        ts = ts[skip:]
        ts, on_grid = snap_to_grid(t, ts)
        kind = "angle"
        if period is None:
            try:
                period = estimate_period(results, clock)[0]
            except AnalysisError:
                period = None
    points, errors, scale = {}, {}, {}
    start = np.searchsorted(t, ts[0]) if len(ts) else len(t)
    for name in signals:
        x = results[name]
        vals, err = _sample(t, x, ts) if len(ts) else (np.zeros(0), 0.0)
        spread = float(np.ptp(x[start:])) if start < len(t) else 0.0
        points[name] = vals
        scale[name] = spread
        errors[name] = err / spread if spread > 0 else 0.0
    return PoincareSection(time=np.asarray(ts, float), points=points, period=period, transient=transient,
                           method="grid" if on_grid else "interpolated", kind=kind, angle=angle, clock=clock,
                           interp_error=errors, scale=scale)


# ---------------------------------------------------------------- indicators
def recurrence(points: np.ndarray, max_period: int = MAX_PERIOD) -> np.ndarray:
    """``r[p-1] = max_k |x[k+p] − x[k]|`` over the second half of the (normalised) sequence."""
    n = len(points)
    tail = points[n // 2:] if n >= 8 else points
    out = np.full(max_period, np.inf)
    for p in range(1, min(max_period, len(tail) - 1) + 1):
        out[p - 1] = float(np.max(np.linalg.norm(tail[p:] - tail[:-p], axis=1)))
    return out


def zero_one_test(phi: np.ndarray, n_c: int = 100, seed: int = 0) -> float:
    """Gottwald–Melbourne 0-1 test, correlation method (2009), median over ``n_c`` random
    ``c`` in (π/5, 4π/5); ``phi`` is a scalar observable sequence.  Returns K in [−1, 1]."""
    phi = np.asarray(phi, float)
    n = len(phi)
    if n < 20:
        return float("nan")
    if np.ptp(phi) == 0:
        return 0.0
    phi = (phi - phi.mean()) / phi.std()
    rng = np.random.default_rng(seed)
    cs = rng.uniform(math.pi / 5, 4 * math.pi / 5, n_c)
    ncut = max(n // 10, 5)
    j = np.arange(1, n + 1)
    ns = np.arange(1, ncut + 1)
    mean2 = phi.mean() ** 2
    ks = []
    for c in cs:
        p = np.cumsum(phi * np.cos(j * c))
        q = np.cumsum(phi * np.sin(j * c))
        m = np.array([np.mean((p[k:] - p[:-k]) ** 2 + (q[k:] - q[:-k]) ** 2) for k in ns])
        d = m - mean2 * (1 - np.cos(ns * c)) / (1 - np.cos(c))
        if np.std(d) == 0:
            ks.append(0.0)
            continue
        ks.append(float(np.corrcoef(ns, d)[0, 1]))
    return float(np.median(ks))


def nearest_neighbour_growth(points: np.ndarray, exclude: int = 1) -> float:
    """Mean of ``log(d(x[i+1], x[j+1]) / d(x[i], x[j]))`` with ``j`` the nearest neighbour of
    ``i`` (``|i − j| > exclude``): the largest Lyapunov exponent of the map, per iteration,
    estimated from the data.  ~0 for a rotation on a circle, > 0 for chaos."""
    n = len(points)
    if n < 10:
        return float("nan")
    x = points[:-1]
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=2)
    idx = np.arange(len(x))
    d[np.abs(idx[:, None] - idx[None, :]) <= exclude] = np.inf
    j = np.argmin(d, axis=1)
    d0 = d[idx, j]
    d1 = np.linalg.norm(points[idx + 1] - points[j + 1], axis=1)
    ok = (d0 > 0) & np.isfinite(d0) & (d1 > 0)
    if not ok.any():
        return float("nan")
    return float(np.median(np.log(d1[ok] / d0[ok])))


def correlation_dimension(points: np.ndarray) -> float:
    """Grassberger–Procaccia slope of ``log C(r)`` against ``log r`` between the 2nd and 30th
    percentiles of the pairwise distances."""
    n = len(points)
    if n < 10:
        return float("nan")
    d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)[np.triu_indices(n, 1)]
    d = d[d > 0]
    if len(d) < 10:
        return 0.0
    lo, hi = np.percentile(d, [2, 30])
    if not (hi > lo > 0):
        return 0.0
    rs = np.geomspace(lo, hi, 12)
    c = np.array([np.mean(d < r) for r in rs])
    ok = c > 0
    return float(np.polyfit(np.log(rs[ok]), np.log(c[ok]), 1)[0])


@dataclass
class Verdict:
    """The motion's class and the indicators it rests on."""

    verdict: str  # "periodic", "quasi-periodic", "chaotic" or "undetermined"
    period: int | None  # iterations of the map (driver periods) for periodic motion
    K: float  # 0-1 test
    lyapunov: float  # nearest-neighbour growth per iteration
    dimension: float  # correlation dimension of the section
    recurrence: float  # smallest recurrence residual (relative), at `period` if periodic
    n_points: int
    agree: bool = True  # all indicators agree with the verdict
    note: str = ""

    def label(self) -> str:
        if self.verdict == "periodic":
            return f"periodic ({self.period}T)" if self.period and self.period > 1 else "periodic"
        return self.verdict

    def summary(self) -> str:
        return (f"{self.label()}: K = {self.K:.2f}, λ = {self.lyapunov:.2f}/T, D2 = {self.dimension:.2f}, "
                f"recurrence = {self.recurrence:.1e}, N = {self.n_points}" + (f" ({self.note})" if self.note else ""))

    def as_dict(self) -> dict:
        return asdict(self)


def normalise(points: np.ndarray, scale: Sequence[float] | None = None) -> np.ndarray:
    """Points divided by each column's spread (``scale``, else the points' own range)."""
    points = np.asarray(points, float)
    s = np.asarray(scale if scale is not None else np.ptp(points, axis=0), float)
    s = np.where(s > 0, s, 1.0)
    return (points - points.mean(axis=0)) / s


def classify(points, scale: Sequence[float] | None = None, *, tol_periodic: float = TOL_PERIODIC,
             max_period: int = MAX_PERIOD, seed: int = 0) -> Verdict:
    """Verdict on a sequence of Poincaré points (an (N, d) array or a `PoincareSection`).

    ``scale`` gives each column's spread over the whole run (a `PoincareSection` carries it),
    so that a period-1 orbit, whose section points coincide, is measured against the size of
    the motion and not against its own zero spread."""
    if isinstance(points, PoincareSection):
        sec = points
        points, scale = sec.array(), [sec.scale[n] for n in sec.names]
    n = len(points)
    if n < 20:  # before any arithmetic: no section points must not print numpy warnings
        return Verdict("undetermined", None, float("nan"), float("nan"), float("nan"), float("nan"), n,
                       False, "fewer than 20 section points: run longer")
    x = normalise(points, scale)
    r = recurrence(x, max_period)
    best = float(np.min(r))
    periodic = [p + 1 for p in range(len(r)) if r[p] < tol_periodic]
    # the 0-1 test on each coordinate that moves at the scale of the motion (a coordinate
    # whose section values agree to 1e-6 of its spread is constant: K = 0 for it)
    ks = [zero_one_test(x[:, i], seed=seed) if np.ptp(x[:, i]) > 1e-6 else 0.0 for i in range(x.shape[1])]
    K = float(np.mean(ks)) if ks else 0.0
    if periodic:
        # the points coincide: nearest-neighbour growth and dimension measure round-off only
        p = periodic[0]
        agree = K < K_CHAOS
        return Verdict("periodic", p, K, float("nan"), 0.0, float(r[p - 1]), n, agree,
                       "" if agree else "the 0-1 test disagrees")
    # the geometric indicators on the points' own scale
    y = normalise(points)
    lyap = nearest_neighbour_growth(y)
    dim = correlation_dimension(y)
    chaos_k = K >= K_CHAOS
    chaos_l = lyap >= LYAPUNOV_CHAOS
    if chaos_k and chaos_l:
        return Verdict("chaotic", None, K, lyap, dim, best, n, True)
    if not chaos_k and not chaos_l:
        curve = not (dim > DIMENSION_CURVE)
        return Verdict("quasi-periodic", None, K, lyap, dim, best, n, curve,
                       "" if curve else "points not on a curve (dimension)")
    # K and λ disagree: the correlation dimension decides between a curve and a cloud
    verdict = "quasi-periodic" if dim <= DIMENSION_CURVE else "chaotic"
    return Verdict(verdict, None, K, lyap, dim, best, n, False,
                   f"K {'≥' if chaos_k else '<'} {K_CHAOS} but λ {'≥' if chaos_l else '<'} {LYAPUNOV_CHAOS}; "
                   f"dimension decides")


def analyze(results, signals: Sequence[str] = ("slider.vx", "slider.ax"), **section_options) -> tuple[PoincareSection, Verdict]:
    """Poincaré section of a run and the verdict on it."""
    sec = poincare_section(results, signals, **section_options)
    return sec, classify(sec)


# ---------------------------------------------------------------- storage
def write_section(group, sec: PoincareSection, verdict: Verdict | None = None, name: str = "poincare") -> None:
    """Store a section (and its verdict) in an open h5py group as ``<group>/poincare``."""
    import json

    if name in group:
        del group[name]
    g = group.create_group(name)
    g.create_dataset("time", data=sec.time)
    for sig, vals in sec.points.items():
        g.create_dataset(sig, data=vals)
    for key, value in sec.attrs().items():
        g.attrs[key] = json.dumps(value) if isinstance(value, (dict, list)) else value
    if verdict is not None:
        g.attrs["verdict"] = json.dumps(verdict.as_dict())


def read_section(group, name: str = "poincare") -> tuple[PoincareSection, Verdict | None]:
    """Inverse of `write_section`; ``group`` is an open h5py group."""
    import json

    from .results import ResultsFileError, memory_budget

    g = group[name]
    a = dict(g.attrs)
    sigs = json.loads(a["signals"])
    if not isinstance(sigs, list) or len(sigs) > 1000:
        raise ResultsFileError(f"{g.name}: the section's signal list is damaged")
    for key in ("time", *sigs):  # a crafted file may declare 2^40 points: check before reading
        ds = g[key]
        if ds.ndim != 1 or ds.dtype.kind not in "fiu" or ds.shape[0] * 8 * (1 + len(sigs)) > memory_budget():
            raise ResultsFileError(f"{g.name}/{key} is {ds.dtype} of shape {ds.shape}: not a Poincaré section "
                                   "that fits in memory")
    nan_none = lambda v: None if v is None or (isinstance(v, float) and math.isnan(v)) else float(v)  # noqa: E731
    sec = PoincareSection(
        time=g["time"][()], points={s: g[s][()] for s in sigs}, period=nan_none(a.get("period")),
        transient=float(a.get("transient", 1.0)), method=str(a.get("method", "")), kind=str(a.get("kind", "")),
        angle=nan_none(a.get("angle")), clock=str(a.get("clock", "")) or None,
        interp_error=json.loads(a.get("interp_error", "{}")), scale=json.loads(a.get("scale", "{}")))
    verdict = Verdict(**json.loads(a["verdict"])) if "verdict" in a else None
    return sec, verdict


# ---------------------------------------------------------------- figures
VERDICT_COLOURS = {"periodic": "tab:blue", "quasi-periodic": "tab:green", "chaotic": "tab:red",
                   "undetermined": "tab:gray"}


def section_figure(sec: PoincareSection, verdict: Verdict | None = None, title: str = "", ax=None):
    """Scatter of the first two section signals, titled with the verdict."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = None
    if ax is None:
        fig, ax = plt.subplots(figsize=(4.5, 4))
    x, y = sec.names[:2]
    colour = VERDICT_COLOURS.get(verdict.verdict, "k") if verdict else "k"
    ax.plot(sec.points[x], sec.points[y], ".", ms=3, color=colour)
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    head = title + ("\n" if title and verdict else "")
    if verdict:
        head += f"{verdict.label()}  K={verdict.K:.2f} λ={verdict.lyapunov:.2f} D2={verdict.dimension:.2f}"
    ax.set_title(head, fontsize=8)
    ax.ticklabel_format(style="sci", scilimits=(-3, 4))
    return fig or ax.figure


def bifurcation_figure(sweep_path, param: str, signal: str | None = None, *, scale: float = 1.0,
                       unit: str = "", title: str = "", ax=None, where: dict | None = None):
    """Poincaré samples of ``signal`` (default: the first section signal) against the swept
    parameter ``param``, from the ``poincare`` groups of a sweep file; points coloured by the
    verdict of their case.  ``where`` keeps only cases whose other parameters have these
    values (text, as in the case table).  ``scale`` multiplies the parameter (e.g. to rpm)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .sweep import parameter_number, parameter_si, read_case_table

    table = read_case_table(sweep_path)
    # plot numbers in the unit the values were given in when they share one, else in SI
    parsed = [parameter_number(r["values"].get(param, "")) for r in table]
    units = {p[1] for p in parsed if p is not None}
    same_unit = len(units) == 1 and None not in parsed
    if same_unit and not unit:
        unit = units.pop()
    fig = None
    if ax is None:
        fig, ax = plt.subplots(figsize=(8, 4))
    seen = set()
    from .results import open_results

    with open_results(sweep_path) as f:
        for row in table:
            if where and any(row["values"].get(k) != v for k, v in where.items()):
                continue
            g = f.get(f"cases/{row['index']}")
            if g is None or "poincare" not in g:
                continue
            sec, verdict = read_section(g)
            name = signal or sec.names[0]
            text = row["values"][param]
            p = (parameter_number(text)[0] if same_unit else parameter_si(text)) * scale
            v = verdict.verdict if verdict else "undetermined"
            ax.plot(np.full(len(sec), p), sec.points[name], ".", ms=2, color=VERDICT_COLOURS[v],
                    label=v if v not in seen else None)
            seen.add(v)
    ax.set_xlabel(f"{param}" + (f" [{unit}]" if unit else ""))
    ax.set_ylabel(f"{signal or 'section'} at the Poincaré section")
    if title:
        ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8, markerscale=4)
    return fig or ax.figure
