"""Parameter sweeps: the cartesian product of parameter values, run in parallel, kept in one HDF5 file.

::

    from planar_mbs.sweep import parse_param, run_sweep
    run_sweep("models/slider_crank_clearance_a.mbs",
              [parse_param("speed=800rpm,1200rpm"), parse_param("clearance=0.1mm..0.5mm:5")],
              "sweep.h5", revolutions=60, per_rev=720)

File layout (each case is laid out exactly as the file of one run, see results.py)::

    /                    attrs: kind = "sweep", config (JSON: model fingerprint, --set values,
                         settings, section options, ...), model_source, model_path, version,
                         params (JSON: [[name, [values...]], ...] in command order)
    /cases/<k>/time, /cases/<k>/signals/<entity>, attrs of a run
                         + case (k), case_key, case_values (JSON)
    /cases/<k>/poincare  the Poincaré section of the case and its verdict (analysis.py)
    /cases_table/        one row per case: index, key, status, one column per parameter (the
                         value text), <param>_si (SI value, NaN for names), verdict, period,
                         K, lyapunov, dimension

Identity and resumption: a case is identified by its parameter values (``case_key``,
the JSON of ``{name: value text without spaces}``).  Opening an existing sweep file
checks that the model source (the file and everything it includes), the ``--set``
values and the run settings are the same, and refuses otherwise; cases already
finished (or failed: a failed simulation fails again) are never run twice.  Adding
values to an axis appends the new cases.

Only the parent process writes the file: a worker (`run_case`, a pure function of
a picklable `CaseSpec`) returns its results in memory, or, in a local pool, lays its
case out in a file of its own beside the sweep file (`run_case_stored`), and the parent
copies or writes each case when it arrives, first under ``/incoming/<k>`` and then
moves it to ``/cases/<k>``, so ``/cases`` only ever holds whole cases.  Any executor with the
`concurrent.futures` interface can run the cases: a local `ProcessPoolExecutor`
(default) or, for a cluster, ``distributed.Client(address).get_executor()``.
"""
from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import os
import re
import sys
import time
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .errors import MbsError, ModelError
from .results import WRITE_CHUNK_CACHE, DiskFull, ResultsBusy, WriteLock, open_results, release_reserve, reserve_space

FINISHED, FAILED = "finished", "failed"
MAX_CASES = 1_000_000  # cases of one sweep
# atomic groups and a greedy tail: linear time on any text (no retrying of shorter digit runs)
_NUMBER = r"[-+]?(?>\d+(?:\.\d*)?|\.\d+)(?>[eE][-+]?\d+)?"
_QUANTITY = re.compile(rf"\s*({_NUMBER})(.*)", re.S)  # fullmatch; the unit is group 2, stripped


class SweepError(MbsError):
    """A sweep cannot start or resume (bad --param, a file from another model, ...)."""

    exit_code = 2


class SweepStopped(SweepError):
    """The sweep stopped before its end (a full disk, a lost cluster); finished cases are kept."""

    exit_code = 3


# ---------------------------------------------------------------- axes and cases
@dataclass(frozen=True)
class Axis:
    """One swept parameter and its values (text with units, as `--set` takes them)."""

    name: str
    values: tuple[str, ...]


def _fmt(x: float) -> str:
    return f"{x:.12g}"


MAX_PARAM_TEXT = 10_000  # characters of one --param


def _short(text: str, n: int = 60) -> str:
    return text if len(text) <= n else text[:n] + "…"


def _range(text: str):
    """(from, unit, to, unit, count) of ``FROM..TO:COUNT``, or None."""
    left, dots, rest = text.partition("..")
    right, colon, count = rest.rpartition(":")
    if not dots or not colon or not count.strip().isdigit():
        return None
    a, b = _QUANTITY.fullmatch(left), _QUANTITY.fullmatch(right)
    if a is None or b is None:
        return None
    ua, ub = a.group(2).strip(), b.group(2).strip()
    if ua.startswith((".", ":")) or ":" in ub:
        return None
    return a.group(1), ua, b.group(1), ub, int(count)


def parse_values(text: str) -> tuple[str, ...]:
    """``800rpm,1200rpm`` (a list), ``0.1mm..0.5mm:5`` (a linear range with a count, ends
    included) or ``hertz,lankarani_nikravesh`` (names)."""
    text = text.strip()
    m = _range(text)
    if m:
        a, ua, b, ub, n = m
        if ua and ub and ua.replace(" ", "") != ub.replace(" ", ""):
            raise SweepError(f"range `{_short(text)}`: both ends need the same unit (got `{ua}` and `{ub}`)")
        unit = (ua or ub).replace(" ", "")
        if n < 1 or n > MAX_CASES:
            raise SweepError(f"range `{_short(text)}`: the count must be between 1 and {MAX_CASES:,}")
        if not (math.isfinite(float(a)) and math.isfinite(float(b))):
            raise SweepError(f"range `{_short(text)}`: the ends must be finite numbers")
        xs = np.linspace(float(a), float(b), n) if n > 1 else np.array([float(a)])
        return tuple(_fmt(x) + unit for x in xs)
    if ".." in text:
        raise SweepError(f"`{_short(text)}` is not a range FROM..TO:COUNT",
                         )
    values = tuple(v.strip().replace(" ", "") for v in text.split(",") if v.strip())
    if not values:
        raise SweepError(f"no values in `{_short(text)}`")
    return values


def parse_param(text: str) -> Axis:
    """``NAME=VALUES`` of `mbs sweep --param` (see `parse_values`)."""
    name, sep, values = text.partition("=")
    if not sep or not name.strip() or not values.strip():
        raise SweepError(f"`--param {text}` is not NAME=VALUES: write e.g. `--param speed=800rpm,1200rpm`, "
                         "`--param clearance=0.1mm..0.5mm:5` or `--param law=hertz,lankarani_nikravesh`")
    if len(text) > MAX_PARAM_TEXT:  # checked before any regular expression looks at it
        raise SweepError(f"`--param {text[:40]}…` is {len(text):,} characters long; at most "
                         f"{MAX_PARAM_TEXT:,} are read")
    try:
        parsed = parse_values(values)
    except SweepError as err:
        raise SweepError(f"--param {_short(name)}=…: {err}") from None
    twice = sorted({v for v in parsed if parsed.count(v) > 1})
    if twice:
        raise SweepError(f"--param {text}: the value {', '.join(twice)} is given twice")
    return Axis(name.strip(), parsed)


def expand(axes: Sequence[Axis]) -> list[dict[str, str]]:
    """The cartesian product of the axes, the first axis varying slowest."""
    names = [a.name for a in axes]
    if len(set(names)) != len(names):
        raise SweepError("a parameter is swept twice: " + ", ".join(sorted(n for n in set(names) if names.count(n) > 1)))
    if math.prod(len(a.values) for a in axes) > MAX_CASES:
        raise SweepError(f"the sweep has {math.prod(len(a.values) for a in axes):,} cases; at most {MAX_CASES:,}")
    return [dict(zip(names, combo)) for combo in itertools.product(*(a.values for a in axes))]


def case_key(values: dict[str, str]) -> str:
    """The identity of a case: its parameter values, names sorted, spaces removed."""
    return json.dumps({k: str(v).replace(" ", "") for k, v in sorted(values.items())}, separators=(",", ":"))


def parameter_number(text: str) -> tuple[float, str] | None:
    """``"800rpm"`` → ``(800.0, "rpm")``; None for a name."""
    m = _QUANTITY.fullmatch(str(text))
    if not m:
        return None
    return float(m.group(1)), m.group(2).strip()


def parameter_si(text: str) -> float:
    """The value of a parameter text in SI units (NaN for names)."""
    parsed = parameter_number(text)
    if parsed is None:
        return float("nan")
    number, unit = parsed
    if not unit:
        return number
    try:
        from .units import quantity

        return float(quantity(number, unit).to_base_units().magnitude)
    except Exception:
        return float("nan")


def _model_files(path: str | Path) -> list[tuple[Path, bytes]]:
    """The model file and, recursively, every file it includes (resolved path, bytes); only regular
    files are read (a pipe or a device is left to the compiler, which reports it)."""
    files: dict[Path, bytes] = {}

    def add(p: Path):
        p = p.resolve()
        if p in files or not p.is_file():
            return
        files[p] = text = p.read_bytes()
        for inc in re.findall(rb'^\s*include\s+"([^"]+)"', text, re.M):
            add(p.parent / inc.decode("utf-8", "replace"))

    add(Path(path))
    return list(files.items())


def model_fingerprint(path: str | Path) -> str:
    """sha256 of the model file and, recursively, of every file it includes."""
    h = hashlib.sha256()
    for p, text in _model_files(path):
        h.update(p.name.encode() + b"\0" + text + b"\0")
    return h.hexdigest()


@dataclass(frozen=True)
class ModelSources:
    """A model and the files it includes, as text, laid out relative to their common folder `root`:
    what a worker on another machine (dask) compiles instead of reading our paths."""

    root: str
    files: tuple[tuple[str, bytes], ...]  # (path relative to root, bytes); the model first

    @classmethod
    def of(cls, path: str | Path) -> "ModelSources":
        found = _model_files(path)
        root = Path(os.path.commonpath([str(p.parent) for p, _ in found]))
        return cls(str(root), tuple((str(p.relative_to(root)), text) for p, text in found))

    def load(self, overrides: dict[str, str]):
        """Compile the model from these texts (in a private temporary folder); errors name the
        original files."""
        import tempfile

        from .compile import load_model  # errors worded for `--set`, as the sweep's values are given

        with tempfile.TemporaryDirectory(prefix="mbs-case-") as tmp:
            for rel, text in self.files:
                target = Path(tmp, rel)
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(text)
            try:
                model = load_model(Path(tmp, self.files[0][0]), overrides)
            except MbsError as err:
                raise MbsError(str(err).replace(str(Path(tmp).resolve()), self.root).replace(tmp, self.root)) \
                    from None
        model.source_path = str(Path(self.root, self.files[0][0]))
        return model


# ---------------------------------------------------------------- one case (runs in a worker)
@dataclass(frozen=True)
class CaseSpec:
    """Everything a worker needs to run one case; picklable, so any executor can take it."""

    index: int
    model_path: str
    values: dict[str, str]  # the swept parameters of this case
    sets: dict[str, str] = field(default_factory=dict)  # fixed --set overrides
    settings: dict[str, Any] = field(default_factory=dict)  # simulate() setting changes (SI)
    revolutions: float | None = None  # t_end = revolutions × driver period
    per_rev: int | None = None  # output_step = driver period / per_rev
    keep: tuple[str, ...] | None = None  # signals stored (None: all)
    section: dict[str, Any] | None = field(default_factory=dict)  # poincare_section options; None: no section
    sources: "ModelSources | None" = None  # the model's text, for workers that do not share our files


    @property
    def key(self) -> str:
        return case_key(self.values)


@dataclass
class CaseOutcome:
    index: int
    key: str
    values: dict[str, str]
    status: str  # finished / failed
    message: str
    results: Any  # planar_mbs.results.Results (signals restricted to `keep`)
    section: Any = None  # analysis.PoincareSection
    verdict: Any = None  # analysis.Verdict
    wall_time: float = 0.0
    part: str | None = None  # a local pool's worker stored the case in this file (`run_case_stored`)
    store_error: str = ""  # ... or could not (a full disk): the sweep stops, the case is not recorded


def case_settings(model, spec: CaseSpec) -> dict:
    """simulate() setting changes of a case: the spec's, plus t_end and output_step from
    the driver period when ``revolutions`` / ``per_rev`` are given."""
    from .section import driver_period

    changes = dict(spec.settings)
    if spec.revolutions is not None or spec.per_rev is not None:
        found = driver_period(model)
        if found is None:
            raise ModelError("--revolutions and --per-rev need a rotation driver at constant speed",
                             spec.model_path)
        period = found[0]
        if spec.revolutions is not None:
            changes["t_end"] = spec.revolutions * period
        if spec.per_rev is not None:
            changes["output_step"] = period / spec.per_rev
    return changes


def default_section_signals(model) -> tuple[str, str] | None:
    """The default Poincaré plane, slider velocity against slider acceleration
    (`planar_mbs.section.default_signals`, the rule plots and `mbs analyze` use)."""
    from .section import AnalysisError, default_signals

    try:
        return default_signals(None, model)
    except AnalysisError:
        return None


def run_case(spec: CaseSpec) -> CaseOutcome:
    """Compile, simulate and analyse one case, in memory (the worker side of a sweep)."""
    from . import simulate
    from .analysis import classify
    from .compile import load_model  # errors worded for `--set`, as the sweep's values are given
    from .errors import SimulationError
    from .section import AnalysisError, poincare_section

    start = time.perf_counter()
    try:
        overrides = {**spec.sets, **spec.values}
        model = spec.sources.load(overrides) if spec.sources else load_model(spec.model_path, overrides)
        res = simulate(model, output=None, **case_settings(model, spec))
        status, message = FINISHED, res.attrs.get("message", "finished")
    except SimulationError as err:
        res, status, message = err.results, FAILED, err.message
    except MbsError as err:  # e.g. a case whose mechanism cannot be assembled: this case fails, the sweep goes on
        return _failed_case(spec, str(err), start)
    except Exception as err:  # never lose the other cases to one case's bug
        return _failed_case(spec, f"internal error ({type(err).__name__}: {err})", start)
    section = verdict = None
    if spec.section is not None and res is not None and len(res.time) > 1:
        opts = dict(spec.section)
        signals = opts.pop("signals", None)
        try:
            section = poincare_section(res, signals, model=model, **opts)
            verdict = classify(section)
        except AnalysisError as err:  # signal names were checked by `check_cases`: no KeyError here
            message += f"; no Poincaré section: {err}"
    if spec.keep is not None and res is not None:
        # the run keeps every signal (the section may need others than --keep); store only the kept ones
        kept = kept_signals(model, spec.keep)
        res.signals = {k: v for k, v in res.signals.items() if k in kept}
        res.units = {k: v for k, v in res.units.items() if k in kept}
    if res is not None:
        res.attrs.update(case=spec.index, case_key=spec.key, case_values=spec.values)
    return CaseOutcome(spec.index, spec.key, dict(spec.values), status, message, res, section, verdict,
                       time.perf_counter() - start)


def _failed_case(spec: CaseSpec, message: str, start: float) -> CaseOutcome:
    """The outcome of a case that stopped before its time loop started (no rows)."""
    from .results import Results

    res = Results(time=np.zeros(0), signals={}, attrs={"complete": False, "status": "failed", "message": message,
                                                       "case": spec.index, "case_key": spec.key,
                                                       "case_values": spec.values})
    return CaseOutcome(spec.index, spec.key, dict(spec.values), FAILED, message, res, None, None,
                       time.perf_counter() - start)


def run_case_stored(spec: CaseSpec, folder: str, compression: str | None = None) -> CaseOutcome:
    """The worker side of a local pool: `run_case`, then the case written, exactly as the sweep file
    will hold it, into a file of its own in ``folder`` (next to the sweep file, same disk); returns
    the outcome without its rows.  The parent then copies that group into the sweep file (HDF5 copies
    the stored datasets as they are) instead of receiving tens of MB through a pipe and laying them
    out itself: the workers do the writing, in parallel, and the parent stays nearly idle.  The disk
    space the case needs is reserved before HDF5 writes a byte (a full disk is a clean `DiskFull`,
    never an HDF5 write failing halfway), and a worker killed while writing leaves only its own file
    broken, which nobody reads."""
    import h5py

    outcome = run_case(spec)
    part = Path(folder, f"case-{spec.index}.h5")
    fd = -1
    try:
        fd = os.open(part, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
        end = reserve_space(fd, _case_bytes(outcome, 0), part)
        image = memoryview(_empty_hdf5())  # an empty HDF5 file, written into the reserved space
        while image:
            image = image[os.write(fd, image):]
        with h5py.File(part, "r+", locking=False, rdcc_nbytes=WRITE_CHUNK_CACHE) as f:  # "w" would free it
            _store_case(f, outcome, compression)
        release_reserve(fd, end)
    except (DiskFull, OSError, RuntimeError) as exc:
        part.unlink(missing_ok=True)
        message = exc.message if isinstance(exc, DiskFull) else str(exc)
        return dataclasses.replace(outcome, results=None, section=None, store_error=message)
    finally:
        if fd >= 0:
            os.close(fd)
    return dataclasses.replace(outcome, results=None, section=None, part=str(part))


_EMPTY: list[bytes] = []


def _empty_hdf5() -> bytes:
    """The bytes of an empty HDF5 file (built in memory once per process)."""
    if not _EMPTY:
        import h5py

        with h5py.File("empty.h5", "w", driver="core", backing_store=False) as f:
            f.flush()
            _EMPTY.append(bytes(f.id.get_file_image()))
    return _EMPTY[0]


PARTS = ".cases-"  # the local pool's case files: a hidden folder ``.<sweep file name>.cases-XXXX`` beside it


def _parts_folder(output: Path) -> str:
    """A fresh folder for the workers' case files; folders a killed sweep left on this output are
    removed first (the caller holds the output's write lock: no other sweep uses them)."""
    import shutil
    import tempfile

    for old in output.parent.glob(f".{output.name}{PARTS}*"):
        shutil.rmtree(old, ignore_errors=True)
    return tempfile.mkdtemp(prefix=f".{output.name}{PARTS}", dir=output.parent)


# ---------------------------------------------------------------- the sweep file
def read_case_table(path: str | Path) -> list[dict]:
    """Rows of ``/cases_table``: ``{"index", "key", "status", "values": {name: text}, "verdict", ...}``."""
    from .results import open_results

    with open_results(path) as f:
        return _table_rows(f)


def _text(v) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def _table_rows(f) -> list[dict]:
    if "cases_table" not in f:
        return []
    t = f["cases_table"]
    params = json.loads(t.attrs.get("params", "[]"))
    n = len(t["index"])
    if n > MAX_CASES or any(len(t[c]) != n for c in t):  # a crafted table: never loop over 10^12 rows
        raise SweepError(f"{f.filename}: the table of cases is damaged ({n:,} rows, columns of unequal length)")
    rows = []
    for i in range(n):
        row = {"index": int(t["index"][i]), "key": _text(t["key"][i]), "status": _text(t["status"][i]),
               "message": _text(t["message"][i]) if "message" in t else "",
               "values": {p: _text(t[p][i]) for p in params}}
        for col in ("verdict",):
            row[col] = _text(t[col][i]) if col in t else ""
        for col in ("period", "K", "lyapunov", "dimension", "wall_time"):
            row[col] = float(t[col][i]) if col in t else float("nan")
        rows.append(row)
    return rows


def _write_table(f, rows: list[dict], params: list[str]) -> None:
    import h5py

    if "cases_table" in f:
        del f["cases_table"]
    t = f.create_group("cases_table")
    t.attrs["params"] = json.dumps(params)
    str_dt = h5py.string_dtype()
    rows = sorted(rows, key=lambda r: r["index"])
    t.create_dataset("index", data=np.array([r["index"] for r in rows], dtype=np.int64))
    for col in ("key", "status", "message", "verdict"):
        t.create_dataset(col, data=np.array([r.get(col, "") for r in rows], dtype=object), dtype=str_dt)
    for p in params:
        texts = [r["values"].get(p, "") for r in rows]
        t.create_dataset(p, data=np.array(texts, dtype=object), dtype=str_dt)
        t.create_dataset(f"{p}_si", data=np.array([parameter_si(x) for x in texts], dtype=float))
    for col in ("period", "K", "lyapunov", "dimension", "wall_time"):
        vals = [r.get(col) for r in rows]
        t.create_dataset(col, data=np.array([np.nan if v is None else v for v in vals], dtype=float))


def _row(outcome: CaseOutcome) -> dict:
    v = outcome.verdict
    return {"index": outcome.index, "key": outcome.key, "status": outcome.status, "message": outcome.message,
            "values": outcome.values, "verdict": v.headline() if v else "",
            "period": (v.period if v and v.period else np.nan), "K": v.K if v else np.nan,
            "lyapunov": v.lyapunov if v else np.nan, "dimension": v.dimension if v else np.nan,
            "wall_time": outcome.wall_time}


@dataclass
class SweepSummary:
    path: Path
    total: int
    ran: list[int]  # case indices computed by this call
    skipped: list[int]  # already in the file
    failed: list[int]
    wall_time: float
    rows: list[dict]


def _config(model_path, sets, settings, revolutions, per_rev, keep, section) -> dict:
    return {"model_fingerprint": model_fingerprint(model_path),
            "sets": {k: str(v).replace(" ", "") for k, v in sorted((sets or {}).items())},
            "settings": {k: settings[k] for k in sorted(settings or {})},
            "revolutions": revolutions, "per_rev": per_rev,
            "keep": sorted(keep) if keep is not None else None,
            "section": section}


def _canon(obj) -> str:
    return json.dumps(obj, sort_keys=True, default=str)


def plan(model_path, axes: Sequence[Axis], sets=None, settings=None, revolutions=None, per_rev=None,
         keep=None, section=None) -> list[CaseSpec]:
    """The cases of a sweep, numbered in product order (before any resumption)."""
    return [CaseSpec(k, str(model_path), values, dict(sets or {}), dict(settings or {}), revolutions, per_rev,
                     tuple(keep) if keep is not None else None, section)
            for k, values in enumerate(expand(axes))]


def kept_signals(model, keep: Sequence[str]) -> set[str]:
    """The full signal names `keep` asks for: signal names as they are, entities (``slider``)
    expanded to all their signals.  A name that is neither raises ModelError (labelled
    ``--keep``) with the closest names."""
    from .signals import signal_table
    from .simulation import select_signals

    try:
        table, _ = select_signals(signal_table(model), list(keep))
    except ModelError as err:
        raise ModelError(err.message, "--keep", hint="signal names are `entity.quantity` (mbs plot FILE --list "
                         "shows them); an entity name keeps all its signals") from None
    return {s.name for s in table}


def check_section(model, section: dict | None) -> None:
    """The Poincaré section's signals and clock body exist in `model` (ModelError otherwise)."""
    from .errors import did_you_mean
    from .signals import signal_table

    if not section:
        return
    names = {s.name for s in signal_table(model)}
    for name in section.get("signals") or ():
        if name not in names:
            raise ModelError(f"no signal `{name}` for the Poincaré section", "--poincare",
                             hint=did_you_mean(name, sorted(names)) or "signal names are `entity.quantity`")
    clock = section.get("clock")
    if clock is not None and clock not in model.body_names:
        raise ModelError(f"no body `{clock}` for the section's clock", "--clock",
                         hint=did_you_mean(clock, model.body_names) or "bodies: " + ", ".join(model.body_names))


def check_cases(specs: Sequence[CaseSpec], output: str | Path | None = None, force: bool = True) -> None:
    """Compile every case once in the parent, so a bad value, a misspelt `--keep` signal or a
    section signal the model lacks stops the sweep before it starts; unless ``force``, refuse a case
    beyond `output_size.MAX_ROWS` output rows (each case's rows are held in a worker's memory) or
    cases that together do not fit on the disk holding ``output``."""
    from .compile import load_model
    from .output_size import check_output, estimate
    from .simulation import check_tolerances, run_settings

    largest, total = None, 0.0
    for spec in specs:
        try:
            m = load_model(spec.model_path, {**spec.sets, **spec.values})
            changes = case_settings(m, spec)
            settings = run_settings(m, **changes)  # e.g. an unknown integrator name
            check_tolerances(settings)
            columns = None
            if spec.keep is not None:
                columns = len(kept_signals(m, spec.keep)) + 1
            check_section(m, spec.section)
            est = estimate(m, settings, columns)
            total += est.bytes
            if largest is None or est.rows > largest.rows:
                largest = est
            check_output(est, None, spec.model_path, force=force)
        except ModelError as err:
            where = ", ".join(f"{k}={v}" for k, v in spec.values.items())
            raise ModelError(f"case {spec.index} ({where}): {err.message}", err.file, err.line, err.column,
                             err.hint, err.source_line, err.width) from None
    if specs and output is not None and not force:  # all of them on the disk (uncompressed: an upper bound)
        from .output_size import free_bytes, _size

        free = free_bytes(output)
        if total > free:
            raise ModelError(f"the {len(specs)} case(s) to run would write about {_size(total)} of results "
                             f"(uncompressed; the largest case {largest.describe()}), more than the {_size(free)} "
                             f"free on the disk holding {output}", str(specs[0].model_path),
                             hint="write elsewhere (-o), make room, or store fewer signals (--keep); pass --force to "
                                  "run anyway (the sweep stops cleanly when the disk is full, and resumes)")


def default_executor(jobs: int | None) -> Executor:
    """A local process pool of ``jobs`` long-lived workers (default: the number of cores).

    When `mbs sweep` started the fork server at its first line (`sweep_server`), the workers are
    forks of that server, which has loaded the kernels meanwhile.  Otherwise, in a process that has
    loaded the kernels (`run_sweep` does, `sweep_worker.warm_up`), on Linux each worker is a fork of
    it that runs cases at once: no second interpreter start-up before the first case.  Otherwise,
    with the forkserver (Linux, macOS), the server imports `planar_mbs.sweep_worker` once and the
    workers are forks of it; elsewhere (spawn) each worker loads them on its first case."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    from .sweep_server import kernels_loaded, started  # not sweep_worker: importing it loads the kernels

    jobs = jobs or os.cpu_count() or 1
    methods = mp.get_all_start_methods()
    if started():  # its preload is `sweep_worker`
        ctx = mp.get_context("forkserver")
    elif sys.platform.startswith("linux") and kernels_loaded():  # forks of this process have it all loaded
        ctx = mp.get_context("fork")
    elif "forkserver" in methods:
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(["planar_mbs.sweep_worker"])
    else:
        ctx = mp.get_context("spawn")
    return ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=start_worker,
                               initargs=(os.getpid(),))


def start_worker(parent: int) -> None:
    """Pool initializer: the worker keeps its freed memory for the next case
    (`sweep_worker.keep_freed_memory`) and ends with the sweep's process ``parent``."""
    from .sweep_worker import keep_freed_memory  # already loaded in a fork; with spawn, loads the kernels now

    keep_freed_memory()
    end_with_parent(parent)


def end_with_parent(parent: int) -> None:
    """This worker ends when the sweep's process ends, even when that one is killed
    (SIGKILL leaves it no chance to stop its pool).  Two guards: the kernel sends SIGKILL when the
    worker's own parent (the pool's fork server) dies (prctl PR_SET_PDEATHSIG), and a daemon thread
    waits on the sweep process itself (a pidfd, else polling) and ends the worker when it is gone."""
    import signal
    import threading

    from .sweep_server import die_with_parent

    die_with_parent()

    def watch():
        try:
            import select

            fd = os.pidfd_open(parent)
            select.select([fd], [], [])  # readable once the process has ended
        except (AttributeError, OSError):  # no pidfd here: poll
            while True:
                try:
                    os.kill(parent, 0)
                except ProcessLookupError:
                    break
                except PermissionError:
                    pass
                time.sleep(0.5)
        os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, name="end-with-parent", daemon=True).start()


PENDING_INTERRUPTS: list[int] = []  # signals a handler noted (`note_interrupt`), raised at the next wait


def note_interrupt(signum: int) -> None:
    """Called by a SIGINT handler that also raises KeyboardInterrupt at once: a KeyboardInterrupt
    raised inside a garbage-collector callback is printed and dropped by Python, so the sweep's
    wait raises it again (within a second) instead of running on to the end."""
    PENDING_INTERRUPTS.append(signum)


def _completed(futures, watch: Callable[[], None] | None):
    """The futures as they finish; between them, every second, ``watch()`` may stop the wait."""
    from concurrent.futures import FIRST_COMPLETED, wait

    left = set(futures)
    while left:
        done, left = wait(left, timeout=1.0, return_when=FIRST_COMPLETED)
        if PENDING_INTERRUPTS:
            raise KeyboardInterrupt
        yield from done
        if not done and watch is not None:
            watch()


def _cluster_watch(executor, timeout: float) -> Callable[[], None] | None:
    """For a dask executor: raises `SweepStopped` once the cluster has had no worker, or the client
    no scheduler, for ``timeout`` seconds (the sweep would otherwise wait forever)."""
    client = getattr(executor, "_client", None)
    if client is None:
        return None
    since: list[float | None] = [None]

    def watch() -> None:
        try:
            problem = None if client.status == "running" else "lost its dask scheduler"
            if problem is None and not client.scheduler_info().get("workers"):
                problem = "has no dask worker"
        except Exception as exc:  # the scheduler is gone mid-call
            problem = f"lost its dask scheduler ({type(exc).__name__})"
        if problem is None:
            since[0] = None
            return
        since[0] = since[0] or time.monotonic()
        if time.monotonic() - since[0] >= timeout:
            raise SweepStopped(f"the sweep {problem} for {timeout:g} s; the cases stored so far are kept: start "
                               "workers (`dask worker ADDRESS`) and run the same command again to resume")

    return watch


class _InlineFuture:
    """A case run in this process when its result is asked for (``-j 1``)."""

    def __init__(self, fn, arg):
        self.fn, self.arg = fn, arg

    def result(self):
        if PENDING_INTERRUPTS:  # an interrupt that Python dropped (raised inside a weakref callback)
            raise KeyboardInterrupt
        return self.fn(self.arg)


def run_sweep(
    model_path: str | Path,
    axes: Sequence[Axis],
    output: str | Path,
    *,
    sets: dict[str, str] | None = None,
    settings: dict[str, Any] | None = None,
    revolutions: float | None = None,
    per_rev: int | None = None,
    keep: Sequence[str] | None = None,
    section: dict[str, Any] | None = None,
    jobs: int | None = None,
    executor: Executor | None = None,
    overwrite: bool = False,
    retry_failed: bool = False,
    compression: str | None = None,
    progress: Callable[[int, int, CaseOutcome | None], None] | None = None,
    worker_timeout: float = 60.0,
    force: bool = False,
) -> SweepSummary:
    """Run every case of the sweep not yet in ``output`` and store it there.

    ``section`` holds `analysis.poincare_section` options (``signals``, ``period``, ``angle``,
    ``transient``, ``clock``); ``None`` disables the section, ``{}`` takes the defaults (the
    slider's vx against ax, once per driver period, after one period).  ``jobs = 1`` runs the
    cases in this process; ``executor`` overrides the local pool (e.g. a dask executor).
    ``progress(done, total, outcome)`` is called once at the start and after every case.
    ``compression`` is an h5py filter for the case datasets (e.g. ``"gzip"``); none by default:
    float64 outputs shrank by ~20 % for ~20x the write time (measured: 0.26 s instead of 0.015 s
    per 10-revolution case); in a local pool the workers compress, in parallel.
    With an ``executor`` (a cluster), the cases carry the model's text, not its path, and a cluster
    left without a worker for ``worker_timeout`` seconds, or without its scheduler, stops the sweep
    (`SweepStopped`; the cases stored so far are kept and a rerun resumes).  Unless ``force``, a
    case beyond `output_size.MAX_ROWS` rows or cases that do not fit on the disk are refused first.
    """
    start = time.perf_counter()
    output = Path(output)
    model_path = str(model_path)
    if not Path(model_path).exists():
        raise SweepError(f"no model file {model_path}")
    if not Path(model_path).is_file():  # a folder, /dev/zero, a pipe: never read
        raise SweepError(f"{model_path} is not a regular file: give the .mbs model file")
    keep = tuple(keep) if keep is not None else None
    section = dict(section) if section is not None else None
    if section and section.get("signals"):
        section["signals"] = list(section["signals"])
    settings = dict(settings or {})
    specs = plan(model_path, axes, sets, settings, revolutions, per_rev, keep, section)
    if executor is not None:  # workers elsewhere (dask) need not share our files or working folder
        sources = ModelSources.of(model_path)
        specs = [dataclasses.replace(s, sources=sources) for s in specs]
    config = _config(model_path, sets, settings, revolutions, per_rev, keep, section)
    params = [a.name for a in axes]

    # the lock first, then the table: a concurrent sweep on the same file must not be read halfway
    existed = output.exists()
    if not existed:
        output.parent.mkdir(parents=True, exist_ok=True)
    try:
        lock = WriteLock(output)
    except ResultsBusy:
        raise SweepError(f"{output} is being written by another sweep; wait for it to end (or choose another -o)") \
            from None
    except OSError as exc:
        raise SweepError(f"cannot write {output}: {exc.strerror or exc}") from None
    try:
        f, rows, merged, numbered, pending, skipped = _open_sweep(
            output, lock, existed, overwrite, retry_failed, config, params, axes, specs, model_path, force)
    except BaseException:
        lock.release()
        if not existed:
            output.unlink(missing_ok=True)
        raise
    return _run_cases(f, lock, output, rows, merged, numbered, pending, skipped, config, params, model_path,
                      jobs, executor, compression, progress, start, worker_timeout)


def _open_sweep(output, lock, existed, overwrite, retry_failed, config, params, axes, specs, model_path, force):
    """Read what the file already holds (under the lock), number and check the cases to run, and
    open the file for writing."""
    import h5py

    rows: dict[str, dict] = {}
    if existed and not overwrite:
        try:
            with open_results(output, locking=False) as f:
                if f.attrs.get("kind") != "sweep":
                    raise SweepError(f"{output} exists and is not a sweep file; choose another -o or pass --overwrite")
                old = json.loads(f.attrs["config"])
                old_params = json.loads(f.attrs.get("params", "[]"))
                existing = _table_rows(f)
                for r in existing:  # a case is only done if its group is there
                    if f"cases/{r['index']}" not in f:
                        r["status"] = "missing"
        except OSError as exc:
            raise SweepError(f"cannot read {output} as a sweep file ({exc}); choose another -o or pass --overwrite") \
                from None
        if old.get("model_fingerprint") != config["model_fingerprint"]:
            raise SweepError(f"{output} was computed from a different model source than {model_path} "
                             "(the model file or a file it includes changed): its cases cannot be resumed; "
                             "choose another -o or pass --overwrite")
        diff = [k for k in config if _canon(config[k]) != _canon(old.get(k))]
        if diff:
            raise SweepError(f"{output} was computed with other settings ({', '.join(diff)} differ: "
                             f"{ {k: old.get(k) for k in diff} } in the file); choose another -o or pass --overwrite")
        if [n for n, _ in old_params] != params:
            raise SweepError(f"{output} sweeps {', '.join(n for n, _ in old_params)}, not {', '.join(params)}; "
                             "choose another -o or pass --overwrite")
        rows = {r["key"]: r for r in existing}
        merged = [[n, list(dict.fromkeys(list(vals) + list(a.values)))] for (n, vals), a in zip(old_params, axes)]
    else:
        merged = [[a.name, list(a.values)] for a in axes]

    # number the cases: keep the file's indices, append the new ones
    next_index = max((r["index"] for r in rows.values()), default=-1) + 1
    numbered = []
    for spec in specs:
        if spec.key in rows:
            numbered.append(dataclasses.replace(spec, index=rows[spec.key]["index"]))
        else:
            numbered.append(dataclasses.replace(spec, index=next_index))
            next_index += 1
    done_status = {FINISHED} | (set() if retry_failed else {FAILED})
    pending = [s for s in numbered if rows.get(s.key, {}).get("status") not in done_status]
    skipped = [s.index for s in numbered if s not in pending]
    check_cases(pending, output, force)

    mode = "w" if overwrite or not existed else "a"
    try:
        f = h5py.File(output, mode, locking=False, rdcc_nbytes=WRITE_CHUNK_CACHE)
    except OSError as exc:
        raise SweepError(f"cannot write {output}: {exc}") from None
    return f, rows, merged, numbered, pending, skipped


def _run_cases(f, lock, output, rows, merged, numbered, pending, skipped, config, params, model_path,
               jobs, executor, compression, progress, start, worker_timeout) -> SweepSummary:
    """Run the pending cases and store each as it arrives; the file and the lock are closed at the end."""
    from . import __version__

    ran, failed = [], []
    reserved = 0
    total = len(numbered)
    done = len(skipped)
    pool = None
    parts = None  # the local pool's folder of case files
    try:
        source = Path(model_path).read_text(encoding="utf-8")
        reserved = _reserve(lock, output, 4 * len(source) + len(rows) * 2048 + (1 << 18), len(skipped))
        f.attrs.update(kind="sweep", config=json.dumps(config, default=str), params=json.dumps(merged),
                       model_path=model_path, model_source=source,
                       version=__version__)
        for s in pending:  # a case cut off while being written is redone
            for grp in (f"cases/{s.index}", f"incoming/{s.index}"):
                if grp in f:
                    del f[grp]
        _write_table(f, list(rows.values()), params)
        f.flush()
        if progress:
            progress(done, total, None)
        if executor is None and (jobs == 1 or len(pending) <= 1):
            futures = [_InlineFuture(run_case, s) for s in pending]
            results_iter = futures
        else:
            if executor is None:
                from .sweep_server import started

                if not started():  # the kernels loaded here once; the pool's workers are forks of this process
                    from .sweep_worker import warm_up

                    warm_up()
                parts = _parts_folder(output)
                pool = default_executor(min(jobs or os.cpu_count() or 1, max(len(pending), 1)))
                futures = [pool.submit(run_case_stored, s, parts, compression) for s in pending]
            else:  # workers elsewhere (dask) share no disk with us: their results come back in memory
                pool = executor
                futures = [pool.submit(run_case, s) for s in pending]
            results_iter = _completed(futures, _cluster_watch(executor, worker_timeout))
        for fut in results_iter:
            try:
                outcome = fut.result()
            except MbsError:
                raise
            except Exception as exc:  # a worker killed, a cluster lost: not one case's fault
                kept = len(skipped) + len(ran)
                what = "the dask cluster failed" if executor is not None else "a worker process of the sweep died"
                raise SweepStopped(f"{what} ({type(exc).__name__}: {exc}); the {kept} case(s) stored so far are "
                                   f"kept in {output}: run the same command again to resume") from None
            if outcome.store_error:  # a worker could not write its case file (a full disk)
                kept = len(skipped) + len(ran)
                raise SweepStopped(f"case {outcome.index} could not be written ({outcome.store_error}); the {kept} "
                                   f"case(s) stored so far are kept in {output}: make room and run the same "
                                   "command again to resume")
            reserved = max(reserved, _reserve(lock, output, _case_bytes(outcome, len(rows) + 1),
                                              len(skipped) + len(ran)))
            rows[outcome.key] = _row(outcome)
            try:
                if outcome.part is not None:
                    _store_part(f, outcome)
                else:
                    _store_case(f, outcome, compression)
                _write_table(f, list(rows.values()), params)
                f.flush()
            except (OSError, RuntimeError) as exc:
                raise SweepStopped(f"cannot write {output} ({exc}); run the same command again to resume") from None
            if outcome.part is not None:
                Path(outcome.part).unlink(missing_ok=True)
            ran.append(outcome.index)
            if outcome.status != FINISHED:
                failed.append(outcome.index)
            done += 1
            if progress:
                progress(done, total, outcome)
    except BaseException:
        if pool is not None and executor is None:
            pool.shutdown(wait=False, cancel_futures=True)
            pool = None
        raise
    finally:
        if pool is not None and executor is None:
            pool.shutdown(wait=True)
        try:
            if "incoming" in f and not len(f["incoming"]):
                del f["incoming"]
            f.close()
        finally:
            if parts is not None:  # a worker still running (an interrupt) cannot write here any more
                import shutil

                shutil.rmtree(parts, ignore_errors=True)
            release_reserve(lock.fd, reserved)
            lock.release()
    order = {s.key: i for i, s in enumerate(numbered)}
    out_rows = sorted(rows.values(), key=lambda r: order.get(r["key"], 1 << 30))
    return SweepSummary(output, total, ran, skipped, failed, time.perf_counter() - start, out_rows)


def _reserve(lock, output: Path, nbytes: int, kept: int) -> int:
    """Reserve disk for the next write of the sweep file; a full disk stops the sweep (`SweepStopped`)
    before anything of that write reaches the file, so every case stored so far stays readable."""
    try:
        return reserve_space(lock.fd, nbytes, output)
    except DiskFull as exc:
        raise SweepStopped(f"{exc.message}; the {kept} case(s) stored so far are kept in {output}: make room "
                           "and run the same command again to resume") from None


def _case_bytes(outcome: CaseOutcome, n_rows: int) -> int:
    """Disk that storing a case and rewriting the table can take: its data uncompressed (what gzip
    writes is at most that, plus headers), its section, HDF5 metadata per dataset, the table's rows."""
    if outcome.part is not None:  # HDF5 copies the stored datasets: at most the case file's size
        return int(os.path.getsize(outcome.part) * 1.05 + n_rows * 2048 + (1 << 18))
    res = outcome.results
    sec = outcome.section
    arrays = [] if res is None else [res.time, *res.signals.values()]
    arrays += [sec.time, *sec.points.values()] if sec is not None else []
    data = sum(np.asarray(a).nbytes for a in arrays)
    return int(data * 1.05 + len(arrays) * 8192 + n_rows * 2048 + (1 << 18))


def _store_case(f, outcome: CaseOutcome, compression: str | None) -> None:
    """Write a case under /incoming/<k>, then move it to /cases/<k> (so /cases only holds whole cases)."""
    from .analysis import write_section
    from .results import write_results

    tmp = _incoming_slot(f, outcome.index)
    write_results(f, outcome.results, tmp, compression=compression)
    g = f[tmp]
    g.attrs["sweep_status"] = outcome.status
    g.attrs["sweep_message"] = outcome.message
    g.attrs["case_wall_time"] = outcome.wall_time
    if outcome.section is not None:
        write_section(g, outcome.section, outcome.verdict)
    _publish(f, outcome.index)


def _store_part(f, outcome: CaseOutcome) -> None:
    """Copy a case a worker stored in its own file (`run_case_stored`) under /incoming/<k>, then move
    it to /cases/<k>, as `_store_case` does."""
    import h5py

    tmp = _incoming_slot(f, outcome.index)
    f.require_group("incoming")
    with h5py.File(outcome.part, "r", locking=False) as part:
        f.copy(part[f"cases/{outcome.index}"], tmp)
    _publish(f, outcome.index)


def _incoming_slot(f, index: int) -> str:
    """/incoming/<k>, emptied: where a case is laid out before `_publish` moves it."""
    tmp = f"incoming/{index}"
    if tmp in f:
        del f[tmp]
    return tmp


def _publish(f, index: int) -> None:
    """Move /incoming/<k> to /cases/<k> in one step, so /cases only ever holds whole cases."""
    final = f"cases/{index}"
    if final in f:
        del f[final]
    f.require_group("cases")
    f.move(f"incoming/{index}", final)


def sweep_sections(path: str | Path) -> list[tuple[dict, Any, Any]]:
    """``(table row, PoincareSection, Verdict)`` of every case of a sweep file that has a section."""
    from .analysis import read_section

    out = []
    with open_results(path) as f:
        for row in _table_rows(f):
            g = f.get(f"cases/{row['index']}")
            if g is not None and "poincare" in g:
                sec, verdict = read_section(g)
                out.append((row, sec, verdict))
    return out
