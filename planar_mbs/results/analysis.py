"""A measured verdict on the motion: periodic, quasi-periodic, chaotic or undecided, after its transient.

The section points come from `planar_mbs.results.section` (the one Poincaré section of
the project, shared with plots, rerun and sweeps).  A **verdict** (`classify`)
first finds where the motion settles (`planar_mbs.results.section.settling`) and
classifies only what comes after:

* **settled at revolution N** (on an orbit): the earliest point from which every
  point repeats after p ≤ 16 revolutions within ``TOL_PERIODIC`` (1e-3) of the
  signals' range over the run, and the points of each of the p phases stay within
  ``SETTLED_SPREAD`` (1e-2) of it, over a window of at least 20 and 3p points;
* **stationary from revolution N** (not an orbit): the start of the part whose
  windows of max(20, n/10) points all have the mean and spread of the last half
  within ``STATIONARY_TOL`` (0.15) of that range: steady statistics, which chaos
  has too, and which a chaotic transient keeps until it ends;
* **not settled**: neither; the last half is classified and the verdict is
  "undecided" (it says what that half looks like).

`report` names the window and the thresholds in its settling line.  The verdict
rests on these indicators of the settled points, each reported with it
(docs/replication.md gives the thresholds and how they were validated on the
forced Duffing oscillator):

``recurrence``  the smallest ``p`` such that the points repeat after ``p``
                iterations, ``max_k |x[k+p] − x[k]|`` relative to the spread of
                the signals (``tol_periodic``); finds periodic motion and its
                period count (the number of distinct Poincaré points).
``K``           the 0-1 test for chaos of Gottwald & Melbourne (correlation
                method, SIAM J. Appl. Dyn. Syst. 8 (2009) 129): the median over
                random frequencies ``c`` of the correlation of the mean-square
                displacement of the translation variables with time; near 0 for
                regular motion (periodic or quasi-periodic), near 1 for chaos.
``lyapunov``    the median logarithmic growth per iteration of the distance of
                nearest neighbours in the section (a Lyapunov exponent of the
                Poincaré map estimated from data, Rosenstein-style; the median,
                not the mean, so that a few far "neighbours" do not dominate):
                about 0 on the invariant circle of quasi-periodic motion, clearly
                positive for chaos.  `planar_mbs.run.lyapunov` computes the exponent
                from two nearby trajectories (Benettin's method) as a check.
``dimension``   the correlation dimension of the section (Grassberger–
                Procaccia): about 1 for points on a closed curve
                (quasi-periodic), above 1 for a strange attractor.

Rules: periodic(p) when the points settled on an orbit (the 0-1 test, unreliable
on short periodic sequences, is reported beside it); otherwise chaotic when
``K`` and ``lyapunov`` both say so, quasi-periodic when both say regular and the
points lie on a curve (``dimension`` ≤ 1.3).  **Undecided** (``agree = False``,
``leaning`` the class the evidence leans to, ``doubt`` why) when the run has not
settled, when ``K`` and ``lyapunov`` disagree, when both say regular but the
points fill an area, and when they say chaos but the points nearly repeat
(recurrence below ``NEAR_PERIODIC``, 1e-2: an orbit blurred by integration error
or chaos too small to tell).  A chaotic verdict over fewer revolutions than
``LONGEST_TRANSIENT`` carries the caveat that it may be transient: a clearance
slider-crank of docs/replication.md was chaotic for 980 revolutions before it
settled on an orbit.  A headline (`Verdict.headline`) opens with a class only
where the indicators agree on it.

numpy only; matplotlib is imported on first use by the figure functions.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

# ---------------------------------------------------------------- thresholds
K_CHAOS = 0.5  # 0-1 test: K above -> chaotic, below -> regular
LYAPUNOV_CHAOS = 0.1  # nearest-neighbour growth per iteration above -> chaotic
DIMENSION_CURVE = 1.3  # correlation dimension below -> points on a curve
MIN_POINTS = 20  # fewest section points classified
NEAR_PERIODIC = 1e-2  # recurrence residual below which points that are no orbit nearly repeat
LONGEST_TRANSIENT = 981  # revolution at which the longest chaotic transient of docs/replication.md ended


# the section itself lives in planar_mbs.results.section (one rule for plots, rerun, analysis, sweeps)
from ..lazy import lazy
from .hdf5 import DiskFull, ResultsFileError, memory_budget, open_for_writing, release_reserve, reserve_space
from .section import (
    MAX_PERIOD,
    MIN_SETTLED,
    SETTLED_SPREAD,
    STATIONARY_TOL,
    TOL_PERIODIC,
    AnalysisError,
    PoincareSection,
    clock_body,
    crossings,
    default_signals,
    driver_period,
    normalise,
    poincare_section,
    section_times,
    settling,
    snap_to_grid,
    stationary_window,
)

matplotlib = lazy("matplotlib")  # figures only
plt = lazy("matplotlib.pyplot")  # after `matplotlib.use("Agg")`


# ---------------------------------------------------------------- indicators
def recurrence(points: np.ndarray, max_period: int = MAX_PERIOD) -> np.ndarray:
    """``r[p-1] = max_k |x[k+p] − x[k]|`` over the (normalised, settled) sequence."""
    tail = points
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
    return float(np.median(np.log(d1[ok] / d0[ok])))  # the median: robust to the rare far neighbour


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

    verdict: str  # "periodic", "quasi-periodic", "chaotic", "undecided" or "undetermined"
    period: int | None  # iterations of the map (driver periods) for periodic motion
    K: float  # 0-1 test
    lyapunov: float  # nearest-neighbour growth per iteration
    dimension: float  # correlation dimension of the section
    recurrence: float  # smallest recurrence residual (relative), at `period` if periodic
    n_points: int
    agree: bool = True  # all indicators agree with the verdict
    note: str = ""
    settled_at: int | None = None  # index of the first section point of the settled part (None: not settled)
    settled_revolution: int | None = None  # the revolution it was taken at
    n_total: int | None = None  # section points of the whole run
    settled_by: str = ""  # "orbit" (a periodic orbit) or "statistics" (stationary); "" not settled
    revolutions: int | None = None  # revolution of the run's last section point
    leaning: str = ""  # "undecided": the class the indicators lean to
    doubt: str = ""  # "undecided": which indicators disagree, in short words

    def on_orbit(self) -> bool:
        """Settled on a periodic orbit (not only stationary statistics)."""
        return self.settled_revolution is not None and (
            self.settled_by == "orbit" or (not self.settled_by and self.verdict == "periodic"))

    def settling_text(self) -> str:
        if self.settled_revolution is not None:
            return f"{'settled at' if self.on_orbit() else 'stationary from'} revolution {self.settled_revolution}"
        if self.n_total:
            return "not settled"
        return ""

    def label(self) -> str:
        if self.verdict == "periodic":
            return f"periodic ({self.period}T)" if self.period and self.period > 1 else "periodic"
        return self.verdict

    def maybe_transient(self) -> bool:
        """Chaos seen over fewer revolutions than a chaotic transient measured in docs/replication.md
        lasted (`LONGEST_TRANSIENT`): it may still end on an orbit."""
        return self.verdict == "chaotic" and self.revolutions is not None and self.revolutions < LONGEST_TRANSIENT

    def doubts(self) -> list[str]:
        """What the verdict cannot vouch for, in short words: too few points, not settled, the
        indicators disagreeing (then the verdict is "undecided" and the last doubt says what it
        looks like), chaos that may be transient.  Every command shows them with the verdict
        (`headline`, `report`)."""
        out = []
        if self.verdict == "undetermined":
            return [f"too few points: {self.n_points} of at least {MIN_POINTS}"]
        if self.settled_revolution is None and self.n_total:
            out.append("not settled")
        if self.n_points < MIN_POINTS:  # the settled part (or last half) alone
            out.append(f"few points: {self.n_points} classified")
        if self.verdict == "undecided" and self.doubt:  # (not settled: that is the doubt)
            out.append(self.doubt)
        if self.verdict == "undecided" and self.leaning:
            out.append(f"looks {self.leaning}")
        if self.maybe_transient():
            out.append(f"may be transient: a chaotic transient of {LONGEST_TRANSIENT - 1} revolutions was "
                       f"measured, this run has {self.revolutions}")
        return out

    def headline(self) -> str:
        """The label with its doubts: ``undecided (not settled; looks chaotic)``; the sweep table's
        verdict.  It opens with a class only where the indicators agree on it."""
        doubts = self.doubts()
        return self.label() + (f" ({'; '.join(doubts)})" if doubts else "")

    def summary(self) -> str:
        settle = self.settling_text()
        return (f"{self.headline()}" + (f", {settle}" if settle else "")
                + f": K = {self.K:.2f}, λ = {self.lyapunov:.2f}/T, D2 = {self.dimension:.2f}, "
                f"recurrence = {self.recurrence:.1e}, N = {self.n_points}" + (f" ({self.note})" if self.note else ""))

    def as_dict(self) -> dict:
        """Plain Python values (numpy scalars as their items), ready for JSON."""
        return {k: (v.item() if isinstance(v, np.generic) else v) for k, v in asdict(self).items()}


def classify(points, scale: Sequence[float] | None = None, *, tol_periodic: float = TOL_PERIODIC,
             max_period: int = MAX_PERIOD, seed: int = 0) -> Verdict:
    """Verdict on a sequence of Poincaré points (an (N, d) array or a `PoincareSection`),
    on the part after the motion has settled (`planar_mbs.results.section.settling`).

    ``scale`` gives each column's spread over the whole run (a `PoincareSection` carries it),
    so that a period-1 orbit, whose section points coincide, is measured against the size of
    the motion and not against its own zero spread.  A run that has not settled is classified
    on its last half and is "undecided" (``settled_at = None``, ``leaning`` what the last half
    looks like).  An array's point k is taken as revolution k + 1."""
    revolution = None
    if isinstance(points, PoincareSection):
        sec = points
        points, scale, revolution = sec.array(), [sec.scale[n] for n in sec.names], sec.revolution
    points = np.asarray(points, float)
    if points.ndim == 1:
        points = points[:, None]
    n_all = len(points)
    last = int(revolution[-1]) if revolution is not None and n_all else n_all
    if n_all < MIN_POINTS:
        return Verdict("undetermined", None, float("nan"), float("nan"), float("nan"), float("nan"), n_all,
                       False, f"fewer than {MIN_POINTS} section points: run longer", None, None, n_all,
                       revolutions=last)
    start, period = settling(points, scale, tol_periodic=tol_periodic, max_period=max_period)
    settled = start is not None
    first = start if settled else n_all // 2
    rev = (int(revolution[first]) if revolution is not None else first + 1) if settled else None
    v = _classify_part(points[first:], scale, period, tol_periodic, max_period, seed)
    v.settled_at, v.settled_revolution, v.n_total = (first if settled else None), rev, n_all
    v.settled_by, v.revolutions = ("orbit" if period else "statistics") if settled else "", last
    if not settled:  # the class of a sequence that has not settled cannot be told
        v.note = "; ".join(filter(None, [f"not settled after {last} revolutions: last half classified", v.note]))
        if v.verdict != "undecided":
            v.verdict, v.leaning, v.period, v.agree = "undecided", v.label(), None, False
    return v


def _classify_part(points, scale, period, tol_periodic, max_period, seed) -> Verdict:
    """The verdict on the settled part (or last half); ``period``: the orbit `settling` found."""
    x = normalise(points, scale)
    n = len(x)
    r = recurrence(x, max_period)
    best = float(np.min(r))
    # the 0-1 test on each coordinate that moves at the scale of the motion (a coordinate
    # whose section values agree within the periodicity tolerance is constant: K = 0 for it;
    # the test would only see integration noise)
    ks = [zero_one_test(x[:, i], seed=seed) if np.ptp(x[:, i]) > tol_periodic else 0.0 for i in range(x.shape[1])]
    K = float(np.mean(ks)) if ks else 0.0
    if period:
        # the points coincide: nearest-neighbour growth and dimension measure round-off only; the
        # recurrence decides (the 0-1 test can exceed 0.5 on a short periodic sequence)
        agree = bool(K < K_CHAOS or np.isnan(K))
        return Verdict("periodic", period, K, float("nan"), 0.0, float(r[period - 1]), n, agree,
                       "" if agree else f"the 0-1 test disagrees (K = {K:.2f}); the recurrence decides")
    # the geometric indicators on the points' own scale
    y = normalise(points)
    lyap = nearest_neighbour_growth(y)
    dim = correlation_dimension(y)
    chaos_k, chaos_l = K >= K_CHAOS, lyap >= LYAPUNOV_CHAOS
    near = next((p + 1 for p in range(len(r)) if r[p] < NEAR_PERIODIC), None)  # the smallest such period
    if near and (chaos_k or chaos_l):  # nearly repeating points: a blurred orbit, or chaos too small to tell
        return _undecided("periodic" + (f" ({near}T)" if near > 1 else ""), K, lyap, dim, float(r[near - 1]), n,
                          f"points repeat after {near} revolution{'s' if near > 1 else ''} within "
                          f"{r[near - 1]:.1e} of their range, not {tol_periodic:g}",
                          "tighten rtol: integration error may blur a periodic orbit")
    if chaos_k and chaos_l:
        return Verdict("chaotic", None, K, lyap, dim, best, n, True)
    if not chaos_k and not chaos_l:
        if not dim > DIMENSION_CURVE:
            return Verdict("quasi-periodic", None, K, lyap, dim, best, n, True)
        return _undecided("quasi-periodic", K, lyap, dim, best, n, f"K and λ regular, points not on a curve "
                          f"(D2 = {dim:.2f} > {DIMENSION_CURVE:g})", "")
    lean = "quasi-periodic" if dim <= DIMENSION_CURVE else "chaotic"
    return _undecided(lean, K, lyap, dim, best, n,
                      f"K = {K:.2f} {'≥' if chaos_k else '<'} {K_CHAOS:g} but λ = {lyap:.2f} "
                      f"{'≥' if chaos_l else '<'} {LYAPUNOV_CHAOS:g}", f"D2 = {dim:.2f} leans {lean}")


def _undecided(lean, K, lyap, dim, best, n, doubt, note) -> Verdict:
    return Verdict("undecided", None, K, lyap, dim, best, n, False, note, leaning=lean, doubt=doubt)


def analyze(results, signals: Sequence[str] | None = None, **section_options) -> tuple[PoincareSection, Verdict]:
    """Poincaré section of a run and the verdict on it."""
    sec = poincare_section(results, signals, **section_options)
    return sec, classify(sec)


def report(sec: PoincareSection, verdict: Verdict) -> list[str]:
    """The verdict as `mbs analyze`, `mbs run --until-settled` and the sweep table give it: where the
    motion settled, with the window and thresholds that say so (or that it did not, or that there
    are too few points), then the headline (`Verdict.headline`, with its doubts) and the indicators
    it rests on, then, for chaos seen over fewer revolutions than a measured transient, why it may
    end."""
    last = int(sec.revolution[-1]) if len(sec) else 0
    where = _where(verdict, last)
    if verdict.verdict == "undetermined":
        return [where, verdict.headline()]
    note = verdict.note if verdict.note and verdict.settled_revolution is not None else ""
    lines = [where, f"{verdict.headline()}  K = {verdict.K:.3f}   λ = {verdict.lyapunov:.3f} per period   "
                    f"D2 = {verdict.dimension:.2f}   recurrence = {verdict.recurrence:.2e}"
                    + (f"   ({note})" if note else "")]
    if verdict.maybe_transient():
        lines.append(f"chaos can be transient: on the clearance slider-crank of docs/replication.md it lasted "
                     f"up to {LONGEST_TRANSIENT - 1} revolutions before the motion settled on a periodic orbit; "
                     f"this run has {last}: run longer to tell (e.g. `mbs run --until-settled "
                     f"--max-revolutions 2000`)")
    return lines


def _where(verdict: Verdict, last: int) -> str:
    """The settling line of `report`: the revolution, the window of points and the thresholds."""
    rel = "of the signals' range over the run"
    w = stationary_window(verdict.n_total or verdict.n_points)
    if verdict.verdict == "undetermined":
        return (f"too few section points to classify: {verdict.n_points}, at least {MIN_POINTS} are needed "
                "(run longer, e.g. `--revolutions 60`)")
    if verdict.settled_revolution is None:
        return (f"not settled after {last} revolutions: no periodic orbit (points repeating within "
                f"{TOL_PERIODIC:g} {rel} for at least {MIN_SETTLED} points) and no stationary statistics "
                f"(windows of {w} points keeping mean and spread within {STATIONARY_TOL:g}); the last half "
                "classified (run longer, e.g. `mbs run --until-settled`)")
    if verdict.on_orbit():
        p = verdict.period or 1
        every = "every revolution" if p == 1 else f"every {p} revolutions"
        return (f"settled at revolution {verdict.settled_revolution} (of {last}): its last {verdict.n_points} "
                f"section points repeat {every} within {TOL_PERIODIC:g} {rel} and stay within "
                f"{SETTLED_SPREAD:g} of it; classified on them")
    return (f"stationary from revolution {verdict.settled_revolution} (of {last}), not settled on an orbit: "
            f"every window of {w} section points after it keeps the mean and spread of the last half within "
            f"{STATIONARY_TOL:g} {rel}; classified on the {verdict.n_points} points after it")


# ---------------------------------------------------------------- storage
def write_section(group, sec: PoincareSection, verdict: Verdict | None = None, name: str = "poincare") -> None:
    """Store a section (and its verdict) in an open h5py group as ``<group>/poincare``."""
    if name in group:
        del group[name]
    g = group.create_group(name)
    g.create_dataset("time", data=sec.time)
    g.create_dataset("revolution", data=np.asarray(sec.revolution, np.int64))
    for sig, vals in sec.points.items():
        g.create_dataset(sig, data=vals)
    for key, value in sec.attrs().items():
        g.attrs[key] = json.dumps(value) if isinstance(value, (dict, list)) else value
    if verdict is not None:
        g.attrs["verdict"] = json.dumps(verdict.as_dict())


def store_section(path, group: str, sec: PoincareSection, verdict: Verdict | None = None) -> None:
    """Store a section (`write_section`) in the results file `path`, under `group` ("" or "/" for a
    run, ``/cases/3`` for a case of a sweep), as a writer of results does: the file's write lock first
    (another process writing it is a clean `MbsError`, never two writers), then the disk space the
    section needs reserved (a full disk is `DiskFull` before a byte is written: HDF5 failing a write
    halfway could damage the file and crashed the process), released again after."""
    arrays = [sec.time, np.asarray(sec.revolution), *sec.points.values()]
    nbytes = sum(np.asarray(a).nbytes for a in arrays) + 4096 * len(arrays) + (1 << 16)  # + headers, attributes
    f, lock = open_for_writing(Path(path), "r+")
    end = None
    try:
        try:
            end = reserve_space(lock.fd, nbytes, path)
        except DiskFull:
            raise DiskFull(f"the disk holding {path} is full: the Poincaré section ({nbytes / 1e3:.3g} kB) does "
                           "not fit (No space left on device); nothing was written: free some space and "
                           "store it again") from None
        write_section(f[group or "/"], sec, verdict)
    finally:
        f.close()
        if end is not None:
            release_reserve(lock.fd, end)
        lock.release()


def read_section(group, name: str = "poincare") -> tuple[PoincareSection, Verdict | None]:
    """Inverse of `write_section`; ``group`` is an open h5py group."""
    g = group[name]
    a = dict(g.attrs)
    sigs = json.loads(a["signals"])
    if isinstance(sigs, list):
        sigs = [s for s in sigs if s != "revolution"]
    if not isinstance(sigs, list) or len(sigs) > 1000:
        raise ResultsFileError(f"{g.name}: the section's signal list is damaged")
    for key in ("time", *sigs, *(["revolution"] if "revolution" in g else [])):  # a crafted file may declare
        # 2^40 points: check before reading
        ds = g[key]
        if ds.ndim != 1 or ds.dtype.kind not in "fiu" or ds.shape[0] * 8 * (1 + len(sigs)) > memory_budget():
            raise ResultsFileError(f"{g.name}/{key} is {ds.dtype} of shape {ds.shape}: not a Poincaré section "
                                   "that fits in memory")
    nan_none = lambda v: None if v is None or (isinstance(v, float) and math.isnan(v)) else float(v)  # noqa: E731
    sec = PoincareSection(
        time=g["time"][()], points={s: g[s][()] for s in sigs}, period=nan_none(a.get("period")),
        transient=float(a.get("transient", 1.0)), method=str(a.get("method", "")), kind=str(a.get("kind", "")),
        angle=nan_none(a.get("angle")), clock=str(a.get("clock", "")) or None,
        interp_error=json.loads(a.get("interp_error", "{}")), scale=json.loads(a.get("scale", "{}")),
        revolution=g["revolution"][()] if "revolution" in g else None)
    known = Verdict.__dataclass_fields__
    verdict = Verdict(**{k: v for k, v in json.loads(a["verdict"]).items() if k in known}) if "verdict" in a else None
    return sec, verdict


# ---------------------------------------------------------------- figures
VERDICT_COLOURS = {"periodic": "tab:blue", "quasi-periodic": "tab:green", "chaotic": "tab:red",
                   "undecided": "tab:orange", "undetermined": "tab:gray"}


def section_figure(sec: PoincareSection, verdict: Verdict | None = None, title: str = "", ax=None):
    """Scatter of the first two section signals, titled with the verdict."""
    matplotlib.use("Agg")

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
