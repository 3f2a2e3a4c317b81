"""Sampled studies: parameters drawn from distributions instead of a grid, run as a sweep.

::

    from planar_mbs.sweep.sampling import parse_distribution, run_study
    run_study("models/slider_crank_clearance_a.mbs",
              [parse_distribution("clearance=uniform(0.1mm, 0.3mm)")], "study.h5", n=64, sampler="lhs", seed=1)

A sampler gives points in the unit cube, seeded and reproducible (`unit_points`: Monte Carlo,
Latin hypercube, scrambled Sobol' sequence, `scipy.stats.qmc`); each distribution maps its
coordinate to a value by its inverse CDF (`Distribution.ppf`).  With ``sobol_indices=True`` the
cases are Saltelli's design (`saltelli`: matrices A, B and, for each parameter, A with that
column from B; Saltelli et al., Comput. Phys. Commun. 181 (2010) 259), from which
`planar_mbs.results.statistics.sobol_indices` estimates first-order and total indices.

The cases run through `planar_mbs.sweep.scan.run_sweep` (parallel, resumable, on a cluster);
the design is stored as the sweep file's ``study`` attribute, so `study_outputs` finds each
case of it again.  A larger ``n`` with the same seed extends Monte Carlo and Sobol' designs
(their first ``n`` points do not change): the finished cases are kept and only the new ones run.
"""
from __future__ import annotations

import json
import math
import re
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from ..language.units import parse_quantity
from ..lazy import lazy
from ..results import hdf5
from ..results import statistics as st
from . import empirical, scan
from .scan import Axis, SweepError, _fmt, case_key, parameter_number
from .store import read_summary

stats = lazy("scipy.stats")
qmc = lazy("scipy.stats.qmc")

SAMPLERS = ("mc", "lhs", "sobol")
KINDS = {"normal": 2, "uniform": 2, "truncnormal": 4}  # arguments of each distribution
TABLE = "table"  # measured values (`empirical`): table(FILE.csv) or table(FILE.csv, UNIT)
_CALL = re.compile(r"\s*([A-Za-z_]\w*)\s*\((.*)\)\s*", re.S)


@dataclass(frozen=True)
class Distribution:
    """One toleranced parameter: ``kind`` with ``args`` in ``unit`` (text as `--set` takes it).

    normal(mean, std), uniform(low, high), truncnormal(mean, std, low, high); table: ``args``
    the measured values, sorted, read from the file ``source`` (`empirical`)."""

    name: str
    kind: str
    args: tuple[float, ...]
    unit: str = ""
    source: str = ""

    def ppf(self, u: np.ndarray) -> np.ndarray:
        """The values at cumulative probabilities ``u`` (inverse transform sampling)."""
        a = self.args
        if self.kind == TABLE:
            return empirical.ppf(a, u)
        if self.kind == "uniform":
            return a[0] + (a[1] - a[0]) * np.asarray(u)
        if self.kind == "normal":
            return stats.norm.ppf(u, loc=a[0], scale=a[1])
        lo, hi = (a[2] - a[0]) / a[1], (a[3] - a[0]) / a[1]
        return stats.truncnorm.ppf(u, lo, hi, loc=a[0], scale=a[1])

    def variance(self) -> float:
        """The distribution's variance (in ``unit``²)."""
        a = self.args
        if self.kind == TABLE:
            return empirical.variance(a)
        if self.kind == "uniform":
            return (a[1] - a[0]) ** 2 / 12
        if self.kind == "normal":
            return a[1] ** 2
        return float(stats.truncnorm.var((a[2] - a[0]) / a[1], (a[3] - a[0]) / a[1], loc=a[0], scale=a[1]))

    def text(self, x: float) -> str:
        return _fmt(float(x)) + self.unit

    def describe(self) -> str:
        if self.kind == TABLE:
            return (f"{self.name} = table({self.source}: {len(self.args)} measured values, "
                    f"{self.text(self.args[0])} to {self.text(self.args[-1])})")
        return f"{self.name} = {self.kind}({', '.join(_fmt(v) + self.unit for v in self.args)})"


def parse_distribution(text: str, stored: "Study | None" = None) -> Distribution:
    """``NAME=normal(50mm, 0.1mm)``, ``NAME=uniform(0.1mm, 0.3mm)``,
    ``NAME=truncnormal(MEAN, STD, LOW, HIGH)``; every argument in one unit (or none);
    ``NAME=table(FILE.csv)`` or ``table(FILE.csv, UNIT)``: measured values, read now (`empirical`), or
    taken from ``stored`` (the study being resumed) when the file is gone."""
    name, sep, rest = text.partition("=")
    m = _CALL.fullmatch(rest) if sep else None
    if not name.strip() or m is None or m.group(1).lower() not in (*KINDS, TABLE):
        raise SweepError(f"`--sample {text}` is not NAME=DISTRIBUTION(...): write e.g. `--sample "
                         "crank=normal(50mm,0.1mm)`, `uniform(LOW,HIGH)`, `truncnormal(MEAN,STD,LOW,HIGH)` "
                         "or `table(FILE.csv, UNIT)`")
    kind = m.group(1).lower()
    if kind == TABLE:
        return _table(text, name.strip(), m.group(2), stored)
    parts = [parameter_number(p.strip()) for p in m.group(2).split(",")]
    if len(parts) != KINDS[kind] or any(p is None for p in parts):
        raise SweepError(f"--sample {text}: {kind} takes {KINDS[kind]} numbers with units")
    units = {p[1].replace(" ", "") for p in parts} - {""}
    if len(units) > 1:
        raise SweepError(f"--sample {text}: give every argument in one unit (got {', '.join(sorted(units))})")
    args = tuple(float(p[0]) for p in parts)
    _check_args(text, kind, args)
    return Distribution(name.strip(), kind, args, units.pop() if units else "")


def _table(text: str, name: str, inside: str, stored: "Study | None") -> Distribution:
    """``table(FILE, UNIT)``: the file's values, sorted, in UNIT (none: plain numbers); a file
    no longer there is the ``stored`` study's table of that name and file, if it has one."""
    parts = [p.strip().strip("'\"") for p in inside.split(",")]
    if not 1 <= len(parts) <= 2 or not parts[0]:
        raise SweepError(f"--sample {text}: write table(FILE.csv) or table(FILE.csv, UNIT), e.g. "
                         "`--sample clearance=table(measured.csv, mm)`")
    unit = parts[1].replace(" ", "") if len(parts) == 2 else ""
    if unit and parameter_number(f"1{unit}") != (1.0, unit):
        raise SweepError(f"--sample {text}: `{parts[1]}` is not a unit (e.g. mm, rpm, GPa)")
    if stored is not None and not Path(parts[0]).exists():  # resuming: the study file holds the values
        for d in stored.distributions:
            if (d.name, d.kind, d.source, d.unit) == (name, TABLE, parts[0], unit):
                return d
    values = empirical.read_values(parts[0])
    return Distribution(name, TABLE, tuple(float(v) for v in values), unit, parts[0])


def _check_args(text: str, kind: str, a: tuple[float, ...]) -> None:
    if not all(math.isfinite(v) for v in a):
        raise SweepError(f"--sample {text}: the numbers must be finite")
    if kind == "uniform" and not a[1] > a[0]:
        raise SweepError(f"--sample {text}: uniform(LOW, HIGH) needs LOW < HIGH")
    if kind != "uniform" and not a[1] > 0:
        raise SweepError(f"--sample {text}: the standard deviation must be positive")
    if kind == "truncnormal" and not a[3] > a[2]:
        raise SweepError(f"--sample {text}: truncnormal(MEAN, STD, LOW, HIGH) needs LOW < HIGH")


# ---------------------------------------------------------------- the design
def unit_points(sampler: str, n: int, d: int, seed: int) -> np.ndarray:
    """``n`` points of the unit cube of dimension ``d``: ``mc`` (numpy's PCG64), ``lhs`` (Latin
    hypercube, McKay et al. 1979), ``sobol`` (scrambled Sobol' sequence, Owen scrambling)."""
    if sampler not in SAMPLERS:
        raise SweepError(f"unknown sampler `{sampler}`: choose one of {', '.join(SAMPLERS)}")
    rng = np.random.default_rng(seed)
    if sampler == "mc":
        return rng.random((n, d))
    engine = qmc.LatinHypercube if sampler == "lhs" else qmc.Sobol
    try:
        gen = engine(d, rng=rng)
    except TypeError:  # scipy before 1.15 names it seed
        gen = engine(d, seed=rng)
    if sampler == "sobol":
        m = int(math.ceil(math.log2(max(n, 1))))
        return gen.random_base2(m)[:n]  # the balanced 2^m points, the first n (a prefix of the sequence)
    return gen.random(n)


def values_of(dists: Sequence[Distribution], u: np.ndarray) -> np.ndarray:
    """(n, d) values of unit points ``u``; a coordinate of exactly 0 (Sobol's first point) is moved
    half an ulp inside, where the normal's inverse CDF is finite."""
    u = np.clip(u, 1e-12, 1 - 1e-12)
    return np.column_stack([d.ppf(u[:, i]) for i, d in enumerate(dists)])


def saltelli(dists: Sequence[Distribution], n: int, sampler: str, seed: int) -> dict[str, np.ndarray]:
    """Saltelli's design: A, B (each n × d) from one 2d-dimensional draw, and ``AB[i]`` = A with
    column i from B."""
    d = len(dists)
    x = values_of(list(dists) * 2, unit_points(sampler, n, 2 * d, seed))
    a, b = x[:, :d], x[:, d:]
    ab = np.stack([np.where(np.arange(d) == i, b, a) for i in range(d)])
    return {"A": a, "B": b, "AB": ab}


@dataclass(frozen=True)
class Study:
    """A sampled study's design: enough to draw its cases again (stored with the sweep)."""

    distributions: tuple[Distribution, ...]
    n: int
    sampler: str = "lhs"
    seed: int = 0
    sobol_indices: bool = False

    def matrices(self) -> dict[str, np.ndarray]:
        """{"X": values} of a plain study; Saltelli's A, B, AB with `sobol_indices`."""
        if self.sobol_indices:
            return saltelli(self.distributions, self.n, self.sampler, self.seed)
        return {"X": values_of(self.distributions, unit_points(self.sampler, self.n, len(self.distributions),
                                                               self.seed))}

    def case_values(self, row: np.ndarray) -> dict[str, str]:
        return {d.name: d.text(v) for d, v in zip(self.distributions, row)}

    def cases(self) -> list[dict[str, str]]:
        """Every case's values (as text with units), each once, in design order."""
        out: dict[str, dict[str, str]] = {}
        for m in self.matrices().values():
            for row in m.reshape(-1, m.shape[-1]):
                values = self.case_values(row)
                out.setdefault(case_key(values), values)
        return list(out.values())

    def as_dict(self) -> dict:
        return {**asdict(self), "distributions": [asdict(d) for d in self.distributions]}

    @classmethod
    def from_dict(cls, d: dict) -> "Study":
        dists = tuple(Distribution(x["name"], x["kind"], tuple(x["args"]), x["unit"], x.get("source", ""))
                      for x in d["distributions"])
        return cls(dists, int(d["n"]), d["sampler"], int(d["seed"]), bool(d["sobol_indices"]))

    def same_design(self, other: "Study") -> bool:
        """The same cases for the same n (n itself may grow)."""
        return (self.distributions, self.sampler, self.seed, self.sobol_indices) == \
            (other.distributions, other.sampler, other.seed, other.sobol_indices)


def axes_of(study: Study, cases: Sequence[dict[str, str]]) -> list[Axis]:
    """One `Axis` per parameter holding the values its cases take (the sweep file's ``params``)."""
    return [Axis(d.name, tuple(dict.fromkeys(c[d.name] for c in cases))) for d in study.distributions]


# ---------------------------------------------------------------- running and reading
def stored_study(path: str | Path) -> Study | None:
    """The design stored in a sweep file (None: a grid sweep, or no file)."""
    if not Path(path).exists():
        return None
    with hdf5.open_results(path) as f:
        text = f.attrs.get("study")
    return Study.from_dict(json.loads(text)) if text else None


def run_study(model_path, distributions: Sequence[Distribution], output, *, n: int, sampler: str = "lhs",
              seed: int = 0, sobol_indices: bool = False, overwrite: bool = False, **sweep_options):
    """Run the cases of a sampled study (`Study.cases`) with `scan.run_sweep` (its options:
    ``sets``, ``settings``, ``revolutions``, ``keep``, ``jobs``, ...); returns its `SweepSummary`."""
    if n < 2 or n > scan.MAX_CASES:
        raise SweepError(f"a sampled study needs between 2 and {scan.MAX_CASES:,} samples (got {n})")
    names = [d.name for d in distributions]
    if not names or len(set(names)) != len(names):
        raise SweepError("give each sampled parameter once (--sample NAME=...)")
    study = Study(tuple(distributions), int(n), sampler, int(seed), bool(sobol_indices))
    old = None if overwrite else stored_study(output)
    if old is None and not overwrite and Path(output).exists():
        raise SweepError(f"{output} exists and is not a sampled study (a grid sweep, or a run); choose another -o "
                         "or pass --overwrite")
    if old is not None and not old.same_design(study):
        raise SweepError(f"{output} holds another sampled study (other distributions, sampler, seed or design); "
                         "choose another -o or pass --overwrite")
    cases = study.cases()
    if old is not None and old.n > study.n:
        study = old  # fewer samples asked for than done: the file's design stays the larger one
    return scan.run_sweep(model_path, axes_of(study, cases), output, cases=cases, study=study.as_dict(),
                          overwrite=overwrite, **sweep_options)


# ---------------------------------------------------------------- outputs of the cases
SUMMARIES = ("min", "max", "rms")  # what a sweep stores of every signal of every case (`store.signal_summary`)


def parse_output(text: str) -> tuple[str, str, float | None]:
    """``slider.x:max`` (a stored summary: min, max or rms over the run) → (signal, "max", None);
    ``slider.x@15ms`` (a kept signal at a time, linearly interpolated) → (signal, "at", 0.015)."""
    name, at, when = text.partition("@")
    if at:
        return name.strip(), "at", parse_quantity(when.strip(), "time", f"the output {text}")
    name, colon, what = text.rpartition(":")
    if not colon or what.strip() not in SUMMARIES:
        raise SweepError(f"`{text}` is not an output of a study: write SIGNAL:min, SIGNAL:max, SIGNAL:rms "
                         "(stored for every case) or SIGNAL@TIME for a kept signal (`mbs sweep --keep`), "
                         "e.g. `slider.x@15ms`")
    return name.strip(), what.strip(), None


def output_values(path, output: str) -> tuple[dict[str, float], str]:
    """({case key: value} of every finished case, unit) of ``output`` (`parse_output`)."""
    name, what, when = parse_output(output)
    values, unit = {}, ""
    rows = [r for r in scan.read_case_table(path) if r["status"] == scan.FINISHED]
    with hdf5.open_results(path) as f:
        for r in rows:
            g = f.get(f"cases/{r['index']}")
            if g is None or what == "at":
                continue
            summary = read_summary(g)
            if name not in summary:
                raise SweepError(f"case {r['index']} of {path} has no signal {name}")
            values[r["key"]] = summary[name][SUMMARIES.index(what)]
            unit = unit or _summary_unit(g, name)
    for r in rows if what == "at" else ():
        res = hdf5.read_results(f"{path}:/cases/{r['index']}")
        if name not in res:
            raise SweepError(f"case {r['index']} of {path} keeps no signal {name}: run the study with "
                             f"`--keep {name}`, or use a stored summary ({name}:max)")
        t = np.asarray(res.time)
        if not t[0] <= when <= t[-1]:
            raise SweepError(f"{output}: case {r['index']} covers t = {t[0]:g} s to {t[-1]:g} s only")
        values[r["key"]] = float(np.interp(when, t, res[name]))
        unit = res.units.get(name, "")
    return values, unit


def _summary_unit(g, name: str) -> str:
    s = g["summary"]
    names = [n.decode() if isinstance(n, bytes) else str(n) for n in s["name"][()]]
    u = s["unit"][()][names.index(name)]
    return u.decode() if isinstance(u, bytes) else str(u)


@dataclass
class StudyReport:
    """The statistics of one output of a study, its convergence, and its Sobol indices (when designed for)."""

    study: Study
    output: str
    statistics: st.OutputStatistics
    convergence: list
    sobol: st.SobolIndices | None
    values: np.ndarray | None = None  # the output of every sample, in design order (NaN: no value)
    unit: str = ""

    def lines(self) -> list[str]:
        d = self.study
        out = [f"{d.sampler} study, random state {d.seed}, {d.n} samples"
               + (" (Saltelli's design for Sobol indices)" if d.sobol_indices else "") + ": "
               + "; ".join(x.describe() for x in d.distributions)]
        out += self.statistics.lines()
        out.append("  convergence: " + ", ".join(f"n = {n}: mean ± {(m.high - m.low) / 2:.3g}, std {s.value:.3g}"
                                                 for n, m, s in self.convergence))
        if self.sobol is not None:
            out += self.sobol.lines()
        return out


def study_report(path, output: str, confidence: float = 0.95) -> StudyReport:
    """Statistics of ``output`` over the cases of the study stored in ``path`` (over matrix A and B
    of a Saltelli design), in design order, and its Sobol indices."""
    study = stored_study(path)
    if study is None:
        raise SweepError(f"{path} is not a sampled study (it was run with --param, not --sample)")
    values, unit = output_values(path, output)
    mats = study.matrices()
    at = lambda m: np.array([values.get(case_key(study.case_values(r)), np.nan) for r in m])  # noqa: E731
    if study.sobol_indices:
        fa, fb = at(mats["A"]), at(mats["B"])
        fab = np.stack([at(m) for m in mats["AB"]])
        y = np.r_[fa, fb]
        names = [d.name for d in study.distributions]
        sobol = st.sobol_indices(fa, fb, fab, names, confidence, seed=study.seed)
    else:
        y, sobol = at(mats["X"]), None
    return StudyReport(study, output, st.describe(y, output, unit, confidence), st.convergence(y, confidence), sobol,
                       y, unit)


def sample_keys(study: Study) -> list[str]:
    """The case key of every sample the statistics are over, in design order (X; A then B of Saltelli's)."""
    mats = study.matrices()
    rows = np.r_[mats["A"], mats["B"]] if study.sobol_indices else mats["X"]
    return [case_key(study.case_values(r)) for r in rows]


def kept_band(path, signal: str, percentiles=st.PERCENTILES):
    """(t, bands, unit, n): the ``percentiles`` of a kept signal over the study's samples at each time
    (``bands[k]`` the k-th percentile, `np.percentile`'s linear rule), on the first case's time grid over
    the span every case covers (each case interpolated linearly onto it; cases of one grid are not)."""
    study = stored_study(path)
    if study is None:
        raise SweepError(f"{path} is not a sampled study (it was run with --param, not --sample)")
    index = {r["key"]: r["index"] for r in scan.read_case_table(path) if r["status"] == scan.FINISHED}
    series, unit = [], ""
    for key in [k for k in sample_keys(study) if k in index]:  # a repeated sample counts twice, as in the statistics
        res = hdf5.read_results(f"{path}:/cases/{index[key]}")
        if signal not in res:
            raise SweepError(f"case {index[key]} of {path} keeps no signal {signal}: run the study with "
                             f"`--keep {signal}`")
        series.append((np.asarray(res.time, float), np.asarray(res[signal], float)))
        unit = unit or res.units.get(signal, "")
    if len(series) < 2:
        raise SweepError(f"{path}: fewer than two finished cases keep {signal}; nothing to draw a band of")
    lo, hi = max(t[0] for t, _ in series), min(t[-1] for t, _ in series)
    t = series[0][0][(series[0][0] >= lo) & (series[0][0] <= hi)]
    ys = np.array([y if len(tc) == len(series[0][0]) and np.array_equal(tc, series[0][0]) and len(t) == len(tc)
                   else np.interp(t, tc, y) for tc, y in series])
    return t, np.percentile(ys, list(percentiles), axis=0), unit, len(series)
