"""Statistics of one output over the cases of a sampled study, with confidence intervals, and
Sobol' sensitivity indices (docs/studies.md).

``mean``         with the Student-t interval ``m ± t s/√n``;
``std``          with the chi-square interval of a normal sample, ``s √((n−1)/χ²)``;
``percentiles``  with distribution-free intervals between two order statistics, whose ranks
                 come from the binomial distribution of the count below the percentile
                 (Hahn & Meeker, "Statistical Intervals", 1991, §5.2);
``sobol``        first-order indices by Saltelli et al. (2010, their Table 2 (b)) and total
                 indices by Jansen (1999), from Saltelli's design, with bootstrap intervals.

Every interval narrows as cases are added, about as 1/√n (`convergence` shows it).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..lazy import lazy

stats = lazy("scipy.stats")

PERCENTILES = (5.0, 50.0, 95.0)


@dataclass(frozen=True)
class Interval:
    """An estimate and its confidence interval (NaN ends: too few cases for that confidence)."""

    value: float
    low: float
    high: float

    def text(self, fmt: str = ".4g") -> str:
        if not np.isfinite(self.value):
            return "n/a (the output does not vary, or no case has it)"
        if not (np.isfinite(self.low) and np.isfinite(self.high)):
            return f"{self.value:{fmt}} [too few cases for an interval]"
        return f"{self.value:{fmt}} [{self.low:{fmt}}, {self.high:{fmt}}]"


@dataclass
class OutputStatistics:
    """Mean, standard deviation and percentiles of one output, each with its interval."""

    name: str
    unit: str
    n: int
    confidence: float
    mean: Interval
    std: Interval
    percentiles: dict[float, Interval] = field(default_factory=dict)
    missing: int = 0  # cases without a value (failed, not yet run)

    def lines(self) -> list[str]:
        u = f" {self.unit}" if self.unit not in ("", "1") else ""
        head = f"{self.name}{u and ' [' + self.unit + ']'}: {self.n} cases" + \
            (f" ({self.missing} without a value)" if self.missing else "") + \
            f", {100 * self.confidence:g} % intervals"
        out = [head, f"  mean  {self.mean.text('.6g')}", f"  std   {self.std.text()}"]
        out += [f"  p{p:g}{' ' * max(1, 4 - len(f'{p:g}'))}{iv.text('.6g')}" for p, iv in self.percentiles.items()]
        return out


def mean_interval(y: np.ndarray, confidence: float = 0.95) -> Interval:
    n = len(y)
    m = float(np.mean(y))
    if n < 2:
        return Interval(m, np.nan, np.nan)
    half = float(stats.t.ppf(0.5 + confidence / 2, n - 1) * np.std(y, ddof=1) / np.sqrt(n))
    return Interval(m, m - half, m + half)


def std_interval(y: np.ndarray, confidence: float = 0.95) -> Interval:
    n = len(y)
    if n < 2:
        return Interval(0.0, np.nan, np.nan)
    s = float(np.std(y, ddof=1))
    lo_q, hi_q = stats.chi2.ppf([0.5 + confidence / 2, 0.5 - confidence / 2], n - 1)
    return Interval(s, s * float(np.sqrt((n - 1) / lo_q)), s * float(np.sqrt((n - 1) / hi_q)))


def percentile_interval(y: np.ndarray, p: float, confidence: float = 0.95) -> Interval:
    """The ``p``-th percentile and the interval ``[y_(l), y_(u)]`` of order statistics with
    ``P(l ≤ B < u) ≥ confidence``, ``B ~ Binomial(n, p/100)``."""
    ys = np.sort(y)
    n = len(ys)
    value = float(np.percentile(ys, p))
    q = p / 100
    lo = int(stats.binom.ppf(0.5 - confidence / 2, n, q))  # P(B <= lo) >= (1 - c)/2: y_(lo) as low end
    hi = int(stats.binom.ppf(0.5 + confidence / 2, n, q)) + 1  # P(B < hi) >= (1 + c)/2
    if lo < 1 or hi > n:
        return Interval(value, np.nan, np.nan)
    return Interval(value, float(ys[lo - 1]), float(ys[hi - 1]))


def describe(y, name: str = "", unit: str = "", confidence: float = 0.95,
             percentiles=PERCENTILES) -> OutputStatistics:
    """The statistics of the finite values of ``y`` (NaN: a case without a value, counted)."""
    y = np.asarray(y, float)
    ok = y[np.isfinite(y)]
    if len(ok) == 0:
        nan = Interval(np.nan, np.nan, np.nan)
        return OutputStatistics(name, unit, 0, confidence, nan, nan, {}, len(y))
    return OutputStatistics(name, unit, len(ok), confidence, mean_interval(ok, confidence),
                            std_interval(ok, confidence),
                            {float(p): percentile_interval(ok, p, confidence) for p in percentiles}, len(y) - len(ok))


def convergence(y, confidence: float = 0.95, steps: int = 4) -> list[tuple[int, Interval, Interval]]:
    """(n, mean, std) of the first n cases for n = N/2^(steps−1), ..., N/2, N: the intervals narrowing."""
    y = np.asarray(y, float)
    y = y[np.isfinite(y)]
    ns = sorted({max(2, len(y) >> k) for k in range(steps)})
    return [(n, mean_interval(y[:n], confidence), std_interval(y[:n], confidence)) for n in ns if n <= len(y)]


# ---------------------------------------------------------------- Sobol indices
@dataclass
class SobolIndices:
    """First-order ``S`` and total ``ST`` indices per parameter, with bootstrap intervals."""

    names: list[str]
    first: list[Interval]
    total: list[Interval]
    n: int
    confidence: float

    def lines(self) -> list[str]:
        out = [f"Sobol indices ({self.n} base samples, {100 * self.confidence:g} % bootstrap intervals):"]
        w = max(len(n) for n in self.names)
        out += [f"  {name:<{w}}  first {s.text('.3f')}   total {t.text('.3f')}"
                for name, s, t in zip(self.names, self.first, self.total)]
        return out


def sobol_estimates(fa: np.ndarray, fb: np.ndarray, fab: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(S, ST) of outputs ``fa`` (n), ``fb`` (n) and ``fab`` (d × n) of Saltelli's design:
    ``S_i = mean(f_B (f_ABi − f_A)) / V`` (Saltelli 2010), ``ST_i = mean((f_A − f_ABi)²) / 2V``
    (Jansen 1999), ``V`` the variance of f_A and f_B together."""
    v = np.var(np.r_[fa, fb], ddof=1)
    if not v > 0:
        return np.full(len(fab), np.nan), np.full(len(fab), np.nan)
    first = np.mean(fb * (fab - fa), axis=1) / v
    total = 0.5 * np.mean((fa - fab) ** 2, axis=1) / v
    return first, total


def sobol_indices(fa, fb, fab, names, confidence: float = 0.95, n_boot: int = 500,
                  seed: int = 0) -> SobolIndices:
    """`sobol_estimates` with percentile-bootstrap intervals over the base samples (rows with a NaN dropped)."""
    fa, fb, fab = np.asarray(fa, float), np.asarray(fb, float), np.asarray(fab, float)
    ok = np.isfinite(fa) & np.isfinite(fb) & np.all(np.isfinite(fab), axis=0)
    fa, fb, fab = fa[ok], fb[ok], fab[:, ok]
    s, st = sobol_estimates(fa, fb, fab)
    if len(fa) < 2 or not np.all(np.isfinite(s)):  # too few cases, or an output that does not vary
        nan = [Interval(np.nan, np.nan, np.nan)] * len(fab)
        return SobolIndices(list(names), nan, list(nan), int(len(fa)), confidence)
    rng = np.random.default_rng(seed)
    boot = [sobol_estimates(fa[i], fb[i], fab[:, i]) for i in rng.integers(0, len(fa), (n_boot, len(fa)))]
    bs, bt = np.array([b[0] for b in boot]), np.array([b[1] for b in boot])
    q = [50 - 50 * confidence, 50 + 50 * confidence]
    lo_s, hi_s = np.nanpercentile(bs, q, axis=0)
    lo_t, hi_t = np.nanpercentile(bt, q, axis=0)
    return SobolIndices(list(names), [Interval(*v) for v in zip(s, lo_s, hi_s)],
                        [Interval(*v) for v in zip(st, lo_t, hi_t)], int(len(fa)), confidence)
