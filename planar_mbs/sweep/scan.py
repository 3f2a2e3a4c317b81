"""Parameter sweeps: the cartesian product of parameter values, run in parallel, kept in one HDF5 file.

::

    from planar_mbs.sweep.scan import parse_param, run_sweep
    run_sweep("models/slider_crank_clearance_a.mbs",
              [parse_param("speed=800rpm,1200rpm"), parse_param("clearance=0.1mm..0.5mm:5")],
              "sweep.h5", revolutions=60, per_rev=720)

File layout (each case is laid out as the file of one run, see results.py)::

    /                    attrs: kind = "sweep", config (JSON: model fingerprint, --set values,
                         settings, section options, ...), model_source, model_path, model_key,
                         model_includes (the snapshot: `ModelSnapshot`), version,
                         params (JSON: [[name, [values...]], ...] in command order)
    /cases/<k>/time, /cases/<k>/signals/<entity>   the --keep signals (none by default)
                         + attrs of a run, case (k), case_key, case_values (JSON)
    /cases/<k>/poincare  the Poincaré section of the case and its verdict (analysis.py)
    /cases/<k>/summary   min, max, RMS of every signal (sweep_store.py)
    /cases_table/        one row per case (sweep_store.write_table)

Identity and resumption: a case is identified by its parameter values (``case_key``,
the JSON of ``{name: value text without spaces}``).  Opening an existing sweep file
checks that the model snapshot (the file and everything it includes), the ``--set``
values and the run settings are the same, and refuses otherwise; cases already
finished (or failed: a failed simulation fails again) are never run twice.  Adding
values to an axis appends the new cases.

Whoever runs a case writes it whole into the sweep's journal (`store_outcome`); the sweep's process
gathers the journal into the scan file by an atomic rename (`sweep_store.gather`), so no kill loses
a finished case.  Any executor with the `concurrent.futures` interface can run the cases: a local
`ProcessPoolExecutor` (default) or, for a cluster, ``distributed.Client(address).get_executor()``.
"""
from __future__ import annotations

import dataclasses
import errno
import hashlib
import itertools
import json
import math
import os
import re
import select
import shutil
import signal
import stat
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Executor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..version import __version__
from ..errors import MbsError, ModelError, SimulationError, did_you_mean
from ..language.units import quantity
from ..lazy import lazy
from ..results.analysis import classify, read_section, write_section
from ..results.hdf5 import (
    WRITE_CHUNK_CACHE,
    DiskFull,
    Results,
    ResultsBusy,
    WriteLock,
    open_results,
    release_reserve,
    reserve_space,
    write_results,
)
from ..results.output_lock import OutputBusy, OutputLock
from ..results.section import AnalysisError, default_signals, driver_period, poincare_section
from ..results.signals import signal_table
from ..run.children import die_with_parent
from ..run.output_size import _size, check_output, estimate, free_bytes
from ..run.simulation import check_tolerances, run_settings, select_signals, simulate
from .server import kernels_loaded, started
from .store import (
    ROW_ATTR,
    DamagedTable,
    JournalLock,
    UnsafeJournal,
    case_file_row,
    case_files,
    clean_leftovers,
    gather,
    journal_folder,
    clean_stale_copies,
    publish,
    read_key,
    read_plan,
    read_summary,
    sign_case,
    signal_summary,
    signed,
    table_rows,
    write_plan,
    write_summary,
    write_table,
)

h5py = lazy("h5py")
mp = lazy("multiprocessing")  # a local pool only
process_pool = lazy("concurrent.futures.process")  # its ProcessPoolExecutor imports multiprocessing
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from ..mechanism import compile as compiler
    from ..language import parse as parsing
    from ..mechanism import tables as table_reader
    from . import worker
else:  # each loaded on its first use (see the comments: not on the light paths)
    compiler = lazy("..mechanism.compile", __package__)  # the parser's lark: not for `mbs plot`/`analyze` of a sweep
    parsing = lazy("..language.parse", __package__)  # lark, as above
    table_reader = lazy("..mechanism.tables", __package__)
    worker = lazy(".worker", __package__)  # importing it loads numba and the kernels (the pool's preload)

FINISHED, FAILED, PENDING = "finished", "failed", "pending"
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
        return float(quantity(number, unit).to_base_units().magnitude)
    except Exception:
        return float("nan")


@dataclass(frozen=True)
class ModelSnapshot:
    """A model and every file it includes, read once and resolved by the parser itself (an include
    anywhere on a line is found): what every case of a sweep compiles, what the sweep file stores
    and hashes, and what dask workers receive.  Editing the files while a sweep runs changes
    nothing of it; editing them between runs is caught on resume by `fingerprint`."""

    path: str  # the model file as given (messages)
    key: str  # its absolute path, the base of the includes' keys
    text: str
    includes: tuple[tuple[str, str], ...]  # (absolute path, text) of every included file
    tables: tuple[tuple[str, bytes], ...] = ()  # (path as the model names it, bytes) of every table file

    @classmethod
    def of(cls, path: str | Path) -> "ModelSnapshot":
        path = str(path)
        try:
            info = os.stat(path)
            if not stat.S_ISREG(info.st_mode):  # a folder, /dev/zero, a pipe: never opened
                raise IsADirectoryError(0, "not a regular file: give the .mbs model file")
            if info.st_size > parsing.MAX_MODEL_BYTES:
                raise ModelError(f"the model file is {info.st_size / 2**20:.0f} MB; models are limited to "
                                 f"{parsing.MAX_MODEL_BYTES // 2**20} MB", path, hint="is this really a model file?")
            with open(path, "rb") as f:
                text = parsing.decode_model(f.read(parsing.MAX_MODEL_BYTES + 1), path)
        except OSError as e:
            raise SweepError(f"cannot read the model file {path} ({getattr(e, 'strerror', None) or e})") from None
        spec = parsing.parse_model(text, path)  # the parser itself finds and reads every include
        tables = tuple(sorted(table_reader.table_files(spec).items()))
        return cls(path, spec.key, text, tuple(sorted(spec.includes.items())), tables)

    def fingerprint(self) -> str:
        """sha256 of the model's text, of every include's text with its path relative to the model,
        and of every table file's bytes with its path."""
        h = hashlib.sha256(self.text.encode() + b"\0")
        base = os.path.dirname(self.key)
        for key, text in self.includes:
            h.update(os.path.relpath(key, base).encode() + b"\0" + text.encode() + b"\0")
        for path, data in self.tables:
            h.update(b"table\0" + path.encode() + b"\0" + data + b"\0")
        return h.hexdigest()

    def compile(self, overrides: dict[str, str]):
        """The model of one case (errors worded for `--set`, as the sweep's values are given)."""
        with table_reader.provided(dict(self.tables)):
            return compiler.compile_text(self.text, self.path, overrides, includes=dict(self.includes), key=self.key)

    def attrs(self) -> dict:
        """Root attributes of a scan file (the layout of a run's file)."""
        tables = {p: d.decode("utf-8", "surrogateescape") for p, d in self.tables}  # JSON escapes any byte
        return {"model_source": self.text, "model_path": self.path, "model_key": self.key,
                "model_includes": json.dumps(dict(self.includes)), "model_tables": json.dumps(tables)}

    @classmethod
    def from_attrs(cls, attrs) -> "ModelSnapshot":
        includes = json.loads(attrs.get("model_includes", "{}") or "{}")
        tables = json.loads(attrs.get("model_tables", "{}") or "{}")
        path = _text(attrs["model_path"])
        return cls(path, _text(attrs.get("model_key", os.path.abspath(path))), _text(attrs["model_source"]),
                   tuple(sorted(includes.items())),
                   tuple(sorted((p, t.encode("utf-8", "surrogateescape")) for p, t in tables.items())))


def model_fingerprint(path: str | Path) -> str:
    """sha256 of the model file and, recursively, of every file it includes (`ModelSnapshot`)."""
    return ModelSnapshot.of(path).fingerprint()


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
    snapshot: ModelSnapshot | None = None  # the model's text, taken once (None: read model_path)
    allow_unphysical: bool = False  # keep results that are not physical (`simulate`'s option)

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
    results: Any  # planar_mbs.results.hdf5.Results (signals restricted to `keep`)
    section: Any = None  # analysis.PoincareSection
    verdict: Any = None  # analysis.Verdict
    wall_time: float = 0.0
    part: str | None = None  # the case's file in the journal (`run_case_stored`)
    store_error: str = ""  # ... or could not (a full disk): the sweep stops, the case is not recorded
    summary: dict | None = None  # (min, max, RMS) of every signal (`sweep_store.signal_summary`)
    units: dict | None = None
    part_bytes: int = 0
    cpu_time: float = 0.0  # CPU seconds of the case in its process (the benchmarks' serial fraction)
    # the scan's timeline (benchmarks/scan_scaling.py): when the case started (Unix seconds) and which
    # process ran it; the gaps between one process's cases (storing, waiting for the next) show there
    started: float = 0.0
    worker: int = 0


def case_settings(model, spec: CaseSpec) -> dict:
    """simulate() setting changes of a case: the spec's, plus t_end and output_step from
    the driver period when ``revolutions`` / ``per_rev`` are given."""
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
    """The default Poincaré plane: the slider's velocity against its acceleration along its axis, else
    the output link's angle against its angular velocity (`planar_mbs.results.section.default_signals`,
    the rule plots and `mbs analyze` use)."""
    try:
        return default_signals(None, model)
    except AnalysisError:
        return None


def run_case(spec: CaseSpec) -> CaseOutcome:
    """Compile, simulate and analyse one case, in memory (the worker side of a sweep)."""
    start, cpu, started = time.perf_counter(), time.process_time(), time.time()
    try:
        overrides = {**spec.sets, **spec.values}
        model = spec.snapshot.compile(overrides) if spec.snapshot else compiler.load_model(spec.model_path, overrides)
        res = simulate(model, output=None, allow_unphysical=spec.allow_unphysical, **case_settings(model, spec))
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
    summary = units = None
    if res is not None:
        summary, units = signal_summary(res), dict(res.units)
    if spec.keep is not None and res is not None:
        # the run keeps every signal (the section may need others than --keep); store only the kept ones
        kept = kept_signals(model, spec.keep) if spec.keep else set()
        res.signals = {k: v for k, v in res.signals.items() if k in kept}
        res.units = {k: v for k, v in res.units.items() if k in kept}
        if not res.signals:
            res.time = res.time[:0]  # no signal kept: no time axis either (replay_case rebuilds the run)
    if res is not None:
        res.attrs.update(case=spec.index, case_key=spec.key, case_values=spec.values)
    return CaseOutcome(spec.index, spec.key, dict(spec.values), status, message, res, section, verdict,
                       time.perf_counter() - start, summary=summary, units=units, cpu_time=time.process_time() - cpu,
                       started=started, worker=os.getpid())


def _failed_case(spec: CaseSpec, message: str, start: float) -> CaseOutcome:
    """The outcome of a case that stopped before its time loop started (no rows)."""
    res = Results(time=np.zeros(0), signals={}, attrs={"complete": False, "status": "failed", "message": message,
                                                       "case": spec.index, "case_key": spec.key,
                                                       "case_values": spec.values})
    wall = time.perf_counter() - start
    return CaseOutcome(spec.index, spec.key, dict(spec.values), FAILED, message, res, None, None, wall,
                       started=time.time() - wall, worker=os.getpid())


def run_case_stored(spec: CaseSpec, folder: str, compression: str | None = None, config: str = "{}",
                    key: bytes = b"") -> CaseOutcome:
    """The worker side of a local pool (and of ``-j 1``): `run_case`, then the case written whole into
    the sweep's journal (`store_outcome`); returns the outcome without its rows."""
    return store_outcome(run_case(spec), folder, compression, config, key)


def store_outcome(outcome: CaseOutcome, folder: str | Path, compression: str | None = None,
                  config: str = "{}", key: bytes = b"") -> CaseOutcome:
    """Write a case, exactly as the sweep file will hold it, into ``folder/case-<k>.h5``: laid out under
    a temporary name, flushed, then renamed (`sweep_store.publish`), so a kill at any moment leaves the
    whole case or none of it, signed with the journal's ``key`` (`sweep_store.sign_case`).  The disk
    space the case needs is reserved before HDF5 writes a byte (a full disk is a clean `DiskFull`,
    never an HDF5 write failing halfway).  Returns the outcome
    without its rows, naming the file (``part``), or with ``store_error``."""
    final = Path(folder, f"case-{outcome.index}.h5")
    part = Path(folder, f".case-{outcome.index}.{os.getpid()}.tmp")
    fd = -1
    try:
        fd = os.open(part, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
        end = reserve_space(fd, _case_bytes(outcome, 0), part)
        image = memoryview(_empty_hdf5())  # an empty HDF5 file, written into the reserved space
        while image:
            image = image[os.write(fd, image):]
        with h5py.File(part, "r+", locking=False, rdcc_nbytes=WRITE_CHUNK_CACHE) as f:  # "w" would free it
            _store_case(f, outcome, compression)
            f.attrs[ROW_ATTR] = json.dumps(_row(outcome), default=_plain)
            f.attrs["sweep_config"] = config  # the sweep's settings: a resume checks them
            sign_case(f, key or read_key(Path(folder)))
        release_reserve(fd, end)
        os.close(fd)
        fd = -1
        publish(part, final)
    except (DiskFull, OSError, RuntimeError) as exc:
        part.unlink(missing_ok=True)
        message = exc.message if isinstance(exc, DiskFull) else str(exc)
        return dataclasses.replace(outcome, results=None, section=None, store_error=message)
    finally:
        if fd >= 0:
            os.close(fd)
    return dataclasses.replace(outcome, results=None, section=None, part=str(final),
                               part_bytes=final.stat().st_size)


_EMPTY: list[bytes] = []


def _empty_hdf5() -> bytes:
    """The bytes of an empty HDF5 file (built in memory once per process)."""
    if not _EMPTY:
        with h5py.File("empty.h5", "w", driver="core", backing_store=False) as f:
            f.flush()
            _EMPTY.append(bytes(f.id.get_file_image()))
    return _EMPTY[0]


# ---------------------------------------------------------------- the sweep file
def read_case_table(path: str | Path) -> list[dict]:
    """Rows of ``/cases_table``: ``{"index", "key", "status", "values": {name: text}, "verdict", ...}``,
    and those of whole cases a killed sweep left in its journal (`sweep_store`), not yet gathered."""
    with open_results(path) as f:
        rows = {r["index"]: r for r in _table_rows(f)}
    folder = journal_folder(path)
    key = read_key(folder)
    for index, part in case_files(folder):
        row = case_file_row(part) if signed(part, key) else None
        if row is not None:
            rows[index] = row
    return [rows[k] for k in sorted(rows)]


def _text(v) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def _table_rows(f) -> list[dict]:
    try:
        return table_rows(f, MAX_CASES)
    except DamagedTable as err:
        raise SweepError(str(err)) from None


def _plain(value):
    """JSON for a numpy scalar in a case's row (a verdict's flags can be numpy booleans)."""
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} in a case's row")


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


def _config(snapshot: ModelSnapshot, sets, settings, revolutions, per_rev, keep, section,
            allow_unphysical: bool = False) -> dict:
    extra = {"allow_unphysical": True} if allow_unphysical else {}  # (absent: the files made before it)
    return {**extra, "model_fingerprint": snapshot.fingerprint(),
            "sets": {k: str(v).replace(" ", "") for k, v in sorted((sets or {}).items())},
            "settings": {k: settings[k] for k in sorted(settings or {})},
            "revolutions": revolutions, "per_rev": per_rev,
            "keep": sorted(keep) if keep is not None else None,
            "section": section}


def _canon(obj) -> str:
    return json.dumps(obj, sort_keys=True, default=str)


def plan(model_path, axes: Sequence[Axis], sets=None, settings=None, revolutions=None, per_rev=None,
         keep=None, section=None, snapshot: ModelSnapshot | None = None,
         cases: Sequence[dict[str, str]] | None = None, allow_unphysical: bool = False) -> list[CaseSpec]:
    """The cases of a sweep, numbered in product order (before any resumption); ``cases``, when
    given, lists each case's values instead of the product of the axes (a sampled study)."""
    values_list = expand(axes) if cases is None else [dict(c) for c in cases]
    return [CaseSpec(k, str(model_path), values, dict(sets or {}), dict(settings or {}), revolutions, per_rev,
                     tuple(keep) if keep is not None else None, section, snapshot, bool(allow_unphysical))
            for k, values in enumerate(values_list)]


def kept_signals(model, keep: Sequence[str]) -> set[str]:
    """The full signal names `keep` asks for: signal names as they are, entities (``slider``)
    expanded to all their signals.  A name that is neither raises ModelError (labelled
    ``--keep``) with the closest names."""
    try:
        table, _ = select_signals(signal_table(model), list(keep))
    except ModelError as err:
        raise ModelError(err.message, "--keep", hint="signal names are `entity.quantity` (mbs plot FILE --list "
                         "shows them); an entity name keeps all its signals") from None
    return {s.name for s in table}


def check_section(model, section: dict | None) -> None:
    """The Poincaré section's signals and clock body exist in `model` (ModelError otherwise)."""
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


def check_cases(specs: Sequence[CaseSpec], output: str | Path | None = None,
                force: bool = True) -> list[tuple[float, int]]:
    """Compile every case once in the parent, so a bad value, a misspelt `--keep` signal or a
    section signal the model lacks stops the sweep before it starts; unless ``force``, refuse a case
    beyond `output_size.MAX_ROWS` output rows (each case's rows are held in a worker's memory) or
    cases that together do not fit on the disk holding ``output``.  Returns each case's simulated span
    and output rows (the expected length of its run: `run_order`)."""
    largest, total, rows = None, 0.0, []
    for spec in specs:
        try:
            overrides = {**spec.sets, **spec.values}
            m = spec.snapshot.compile(overrides) if spec.snapshot else compiler.load_model(spec.model_path, overrides)
            changes = case_settings(m, spec)
            settings = run_settings(m, **changes)  # e.g. an unknown integrator name
            check_tolerances(settings)
            columns = None
            if spec.keep is not None:
                columns = len(kept_signals(m, spec.keep)) + 1 if spec.keep else 1
            check_section(m, spec.section)
            est = estimate(m, settings, columns)
            rows.append((float(settings.t_end), int(est.rows)))
            total += est.bytes
            if largest is None or est.rows > largest.rows:
                largest = est
            check_output(est, None, spec.model_path, force=force)
        except ModelError as err:
            where = ", ".join(f"{k}={v}" for k, v in spec.values.items())
            raise ModelError(f"case {spec.index} ({where}): {err.message}", err.file, err.line, err.column,
                             err.hint, err.source_line, err.width) from None
    if specs and output is not None and not force:  # all of them on the disk (uncompressed: an upper bound)
        free = free_bytes(output)
        if total > free:
            raise ModelError(f"the {len(specs)} case(s) to run would write about {_size(total)} of results "
                             f"(uncompressed; the largest case {largest.describe()}), more than the {_size(free)} "
                             f"free on the disk holding {output}", str(specs[0].model_path),
                             hint="write elsewhere (-o), make room, or store fewer signals (--keep); pass --force to "
                                  "run anyway (the sweep stops cleanly when the disk is full, and resumes)")
    return rows


def default_executor(jobs: int | None) -> Executor:
    """A local process pool of ``jobs`` long-lived workers (default: the number of cores).

    When `mbs sweep` started the fork server at its first line (`sweep_server`), the workers are
    forks of that server, which has loaded the kernels meanwhile.  Otherwise, in a process that has
    loaded the kernels (`run_sweep` does, `sweep_worker.warm_up`), on Linux each worker is a fork of
    it that runs cases at once: no second interpreter start-up before the first case.  Otherwise,
    with the forkserver (Linux, macOS), the server imports `planar_mbs.sweep.worker` once and the
    workers are forks of it; elsewhere (spawn) each worker loads them on its first case."""
    jobs = jobs or os.cpu_count() or 1
    methods = mp.get_all_start_methods()
    if started():  # its preload is `sweep_worker`
        ctx = mp.get_context("forkserver")
    elif sys.platform.startswith("linux") and kernels_loaded():  # forks of this process have it all loaded
        ctx = mp.get_context("fork")
    elif "forkserver" in methods:
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(["planar_mbs.sweep.worker"])
    else:
        ctx = mp.get_context("spawn")
    return process_pool.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=start_worker,
                                            initargs=(os.getpid(),))


def start_worker(parent: int) -> None:
    """Pool initializer: the worker keeps its freed memory for the next case
    (`sweep_worker.keep_freed_memory`) and ends with the sweep's process ``parent``."""
    worker.keep_freed_memory()
    end_with_parent(parent)


def end_with_parent(parent: int) -> None:
    """This worker ends when the sweep's process ends, even when that one is killed
    (SIGKILL leaves it no chance to stop its pool).  Two guards: the kernel sends SIGKILL when the
    worker's own parent (the pool's fork server) dies (prctl PR_SET_PDEATHSIG), and a daemon thread
    waits on the sweep process itself (a pidfd, else polling) and ends the worker when it is gone."""
    die_with_parent()

    def watch():
        try:
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
    """The futures as they finish; between them, every second, ``watch()`` may stop the wait.  Only
    the unfinished ones are held here: the list given would keep every finished case's outcome (its
    summary, its verdict; on a cluster its whole results) alive to the end of the scan (measured on a
    scan of 240 short cases: 22 of the 122 kB a case that the sweep's process grew by)."""
    left = set(futures)
    del futures
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

    def __init__(self, fn, *args):
        self.fn, self.args = fn, args

    def result(self):
        if PENDING_INTERRUPTS:  # an interrupt that Python dropped (raised inside a weakref callback)
            raise KeyboardInterrupt
        return self.fn(*self.args)


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
    cases: Sequence[dict[str, str]] | None = None,
    study: dict | None = None,
    allow_unphysical: bool = False,
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
    ``cases`` lists the cases' values instead of the product of ``axes`` (which then name the
    parameters and their values), and ``study`` is stored as the root attribute ``study`` (JSON):
    a sampled study (`planar_mbs.sweep.sampling`).  ``allow_unphysical`` keeps each case whose
    results are not physical as finished (as `simulate`'s), recorded in the file's ``config``.
    """
    start = time.perf_counter()
    output = Path(output)
    model_path = str(model_path)
    if not Path(model_path).exists():
        raise SweepError(f"no model file {model_path}")
    if not Path(model_path).is_file():  # a folder, /dev/zero, a pipe: never read
        raise SweepError(f"{model_path} is not a regular file: give the .mbs model file")
    snapshot = ModelSnapshot.of(model_path)  # read once: every case compiles this text
    keep = tuple(keep) if keep is not None else None
    section = dict(section) if section is not None else None
    if section and section.get("signals"):
        section["signals"] = list(section["signals"])
    settings = dict(settings or {})
    specs = plan(model_path, axes, sets, settings, revolutions, per_rev, keep, section, snapshot, cases,
                 allow_unphysical)
    config = _config(snapshot, sets, settings, revolutions, per_rev, keep, section, allow_unphysical)
    params = [a.name for a in axes]
    _check_param_names(params)

    lock = _lock(output)
    try:
        clean_leftovers(output)
        state = _open_sweep(output, overwrite, retry_failed, config, params, axes, specs, force,
                            jobs or os.cpu_count() or 1)
    except BaseException:
        if lock.output is not None:
            lock.output.release()
        lock.release(remove=True)
        raise
    header = {"kind": "sweep", "config": json.dumps(config, default=str), "params": json.dumps(state.merged),
              "version": _version(), **snapshot.attrs(), **({"study": json.dumps(study)} if study else {})}
    return _run_cases(state, lock, output, header, params, jobs, executor, compression, progress, start,
                      worker_timeout)


def _lock(output: Path):
    """The sweep's `sweep_store.JournalLock` on ``output``, with the scan file's own write lock when the
    file exists (``lock.output``): no other sweep, and no other writer of the file, while this one runs."""
    output.parent.mkdir(parents=True, exist_ok=True)
    try:
        lock = JournalLock(output)
    except OutputBusy as busy:
        raise SweepError(f"{output} is being written by {busy}; wait for it to end (or choose another -o)") from None
    except OSError as exc:
        raise SweepError(f"cannot write {output}: {exc.strerror or exc}") from None
    try:
        # none there: none made (a kill before the first gather must not leave an empty file)
        lock.output = WriteLock(output) if output.exists() else None
    except (ResultsBusy, OSError):
        lock.release(remove=True)
        raise SweepError(f"{output} is being written by another sweep or run; wait for it to end (or choose "
                         "another -o)") from None
    return lock


def _version() -> str:
    return __version__


def _check_param_names(params: list[str]) -> None:
    """A swept name is a model parameter (an identifier): never a path in the file."""
    for p in params:
        if not p or "/" in p or p in (".", ".."):
            raise SweepError(f"`{p}` cannot be a parameter name")


@dataclass
class _Plan:
    rows: dict  # key -> row of every case known (the file's, the journal's)
    merged: list  # [[name, [values...]], ...]: the file's axes extended by this call's
    numbered: list  # this call's cases, with their indices in the file
    pending: list  # ... those to run, in `run_order`
    skipped: list  # indices already done
    fresh: bool  # the scan file is started afresh (none yet, or --overwrite)


def _open_sweep(output, overwrite, retry_failed, config, params, axes, specs, force, workers) -> _Plan:
    """Read what the scan file and its journal hold (under the lock), number and check the cases to run."""
    rows: dict[str, dict] = {}
    folder = journal_folder(output)
    fresh = overwrite or not output.exists()
    merged = [[a.name, list(a.values)] for a in axes]
    if overwrite:
        for _, part in case_files(folder):
            part.unlink(missing_ok=True)
    if not fresh:
        old, old_params, existing = _read_scan(output)
        _same_sweep(output, old, config, [n for n, _ in old_params], params)
        rows = {r["key"]: r for r in existing}
        merged = [[n, list(dict.fromkeys(list(vals) + list(a.values)))] for (n, vals), a in zip(old_params, axes)]
    key = read_key(folder)
    for index, part in case_files(folder):  # whole cases a killed sweep left: done, unless of another sweep
        row = case_file_row(part)
        if row is None:
            part.unlink(missing_ok=True)
            continue
        if not signed(part, key):
            raise UnsafeJournal(f"{part} was not written by a sweep of {output} (its signature does not match "
                                f"what it holds): remove it to run case {index} again, or pass --overwrite")
        their = _case_file_config(part)
        _same_sweep(output, their, config, list(row["values"]), params)
        rows[row["key"]] = row

    plan = {} if overwrite else read_plan(folder)  # a killed sweep's numbering, before its first gather
    plan.update({key: r["index"] for key, r in rows.items()})
    next_index = max(plan.values(), default=-1) + 1
    numbered = []
    for spec in specs:  # keep the file's indices, append the new ones
        if spec.key not in plan:
            plan[spec.key] = next_index
            next_index += 1
        numbered.append(dataclasses.replace(spec, index=plan[spec.key]))
        if spec.key not in rows:  # in the table from the first gather on: its index is kept by a resume
            rows[spec.key] = _pending_row(numbered[-1])
    write_plan(folder, plan)
    done_status = {FINISHED} | (set() if retry_failed else {FAILED})
    pending = [s for s in numbered if rows.get(s.key, {}).get("status") not in done_status]
    skipped = [s.index for s in numbered if s not in pending]
    expected = check_cases(pending, output, force)
    return _Plan(rows, merged, numbered, run_order(pending, expected, workers), skipped, fresh)


def run_order(specs: Sequence[CaseSpec], expected: Sequence[tuple[float, int]], workers: int = 1) -> list[CaseSpec]:
    """The order the cases start in.  ``expected`` is each case's (simulated span, output rows).

    The cases with most output rows first, equal ones in an order fixed by a hash of their key, spread
    over every parameter instead of the order of the axes (all of the lowest speed first): the cases
    finished so far are then a fair sample of those left, for the progress line's time left, and the
    same cases run in the same order again.  The last ``2 * workers`` to start are the cheapest by
    (span, rows), dearest first, so no core is left with a long case while the others finish: a scan
    over speeds at a fixed number of revolutions has equal rows, but a slow case simulates a longer
    span and costs more (2x from 6000 to 500 rpm on the clearance slider-crank).  A pool simulated
    with each case's measured CPU seconds (64 speeds of 200 revolutions on 16 cores) ends 11 % after
    a perfect balance in this order, 18 % in the spread order alone (docs/benchmarks.md)."""
    def spread(i: int) -> bytes:
        return hashlib.blake2b(specs[i].key.encode(), digest_size=8).digest()

    tail = set(sorted(range(len(specs)), key=lambda i: (expected[i], spread(i)))[:2 * max(workers, 1)])
    bulk = sorted((i for i in range(len(specs)) if i not in tail), key=lambda i: (-expected[i][1], spread(i)))
    last = sorted(tail, key=lambda i: (expected[i], spread(i)), reverse=True)
    return [specs[i] for i in bulk + last]


def _pending_row(spec: CaseSpec) -> dict:
    """The table's row of a case not yet run."""
    return {"index": spec.index, "key": spec.key, "status": PENDING, "message": "", "values": dict(spec.values),
            "verdict": "", "period": np.nan, "K": np.nan, "lyapunov": np.nan, "dimension": np.nan,
            "wall_time": np.nan}


def _read_scan(output: Path):
    """(config, params, rows) of an existing scan file; a row whose case group is gone is "missing"."""
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
    return old, old_params, existing


def _case_file_config(part: Path) -> dict:
    with h5py.File(part, "r", locking=False) as f:
        return json.loads(f.attrs.get("sweep_config", "{}"))


def _same_sweep(output, old: dict, config: dict, old_params: list[str], params: list[str]) -> None:
    """Refuse to resume cases computed from another model, other settings or other axes."""
    if old.get("model_fingerprint") != config["model_fingerprint"]:
        raise SweepError(f"{output} was computed from a different model source "
                         "(the model file or a file it includes changed): its cases cannot be resumed; "
                         "choose another -o or pass --overwrite")
    diff = [k for k in config if _canon(config[k]) != _canon(old.get(k))]
    if diff:
        raise SweepError(f"{output} was computed with other settings ({', '.join(diff)} differ: "
                         f"{ {k: old.get(k) for k in diff} } in the file); choose another -o or pass --overwrite")
    if sorted(old_params) != sorted(params):
        raise SweepError(f"{output} sweeps {', '.join(old_params)}, not {', '.join(params)}; "
                         "choose another -o or pass --overwrite")


GATHER_MIN = 1 << 20  # bytes of journal before the first gather during a sweep


def _run_cases(state: _Plan, lock, output, header, params, jobs, executor, compression, progress, start,
               worker_timeout) -> SweepSummary:
    """Run the pending cases; each is written whole into the journal by whoever ran it, and gathered
    into the scan file (`sweep_store.gather`) when the journal has grown as large as the scan file
    and at the end, even an interrupted one.  The lock is released at the end."""
    rows, pending = state.rows, state.pending
    folder = journal_folder(output)
    ran, failed = [], []
    total, done = len(state.numbered), len(state.skipped)
    pool = None
    fresh, dirty = state.fresh, state.fresh or any(True for _ in folder.glob("case-*.h5"))
    scan_bytes = 0 if fresh else output.stat().st_size
    journal = 0
    stopping = False
    config_text = header["config"]
    try:
        if dirty:  # the file exists from the start; a killed sweep's whole cases are gathered first
            scan_bytes = _gather(output, lock, header, rows, params, fresh)
            fresh = dirty = False
        if progress:
            progress(done, total, None)
        pool, results_iter = _start(pending, str(folder), jobs, executor, compression, (config_text, lock.key),
                                    worker_timeout)
        for fut in results_iter:
            outcome = _outcome(fut, executor, len(state.skipped) + len(ran), output)
            if outcome.part is None and not outcome.store_error:  # from a cluster: written here
                outcome = store_outcome(outcome, folder, compression, config_text, lock.key)
            if outcome.store_error:  # the case could not be written (a full disk)
                raise SweepStopped(f"case {outcome.index} could not be written ({outcome.store_error}); the "
                                   f"{len(state.skipped) + len(ran)} case(s) stored so far are kept in {output}: "
                                   "make room and run the same command again to resume")
            rows[outcome.key] = _row(outcome)
            dirty = True
            journal += outcome.part_bytes
            if journal >= max(scan_bytes, GATHER_MIN):
                scan_bytes = _gather(output, lock, header, rows, params, fresh)
                fresh, dirty, journal = False, False, 0
            ran.append(outcome.index)
            if outcome.status != FINISHED:
                failed.append(outcome.index)
            done += 1
            if progress:
                progress(done, total, outcome)
        if header["params"] != _file_params(output):
            dirty = True
    except BaseException:
        stopping = True  # a failed gather below must not hide why the sweep stopped
        if pool is not None and executor is None:
            pool.shutdown(wait=False, cancel_futures=True)
            pool = None
        raise
    finally:
        if pool is not None and executor is None:
            pool.shutdown(wait=True)
        try:
            if dirty:
                _gather(output, lock, header, rows, params, fresh)
        except SweepStopped:
            if not stopping:
                raise
        finally:
            if lock.output is not None:
                lock.output.release()
            lock.release(remove=True)
    order = {s.key: i for i, s in enumerate(state.numbered)}
    out_rows = sorted(rows.values(), key=lambda r: order.get(r["key"], 1 << 30))
    return SweepSummary(output, total, ran, state.skipped, failed, time.perf_counter() - start, out_rows)


def _start(pending, folder: str, jobs, executor, compression, signing, worker_timeout):
    """(pool, the cases' futures as they finish): in this process (``-j 1``), a local pool whose workers
    write their cases into the journal themselves (``signing``: the config text and key they are
    stored with), or a dask executor whose results come back here."""
    if executor is None and (jobs == 1 or len(pending) <= 1):
        return None, [_InlineFuture(run_case_stored, s, folder, compression, *signing) for s in pending]
    if executor is None:
        if not started():  # the kernels loaded here once; the pool's workers are forks of this process
            worker.warm_up()
        pool = default_executor(min(jobs or os.cpu_count() or 1, max(len(pending), 1)))
        futures = [pool.submit(run_case_stored, s, folder, compression, *signing) for s in pending]
    else:  # workers elsewhere (dask) share no disk with us: their results come back in memory
        pool = executor
        futures = [pool.submit(run_case, s) for s in pending]
    return pool, _completed(futures, _cluster_watch(executor, worker_timeout))


def _file_params(output: Path) -> str | None:
    try:
        with open_results(output, locking=False) as f:
            return f.attrs.get("params")
    except (OSError, MbsError):
        return None


def _gather(output, lock, header, rows, params, fresh) -> int:
    """`sweep_store.gather` of the cases of ``rows``; a full disk or a write error stops the sweep
    with the finished cases kept (in the old scan file and the journal)."""
    try:
        size = gather(output, header, rows, params, parameter_si, fresh=fresh)
        old, lock.output = lock.output, WriteLock(output)  # the new scan file, locked as the old one was
        if old is not None:
            old.release()
        return size
    except ResultsBusy:
        raise SweepStopped(f"{output} was opened for writing by another process; the finished cases are kept: "
                           "run the same command again to resume") from None
    except (OSError, RuntimeError) as exc:
        why = f"the disk holding {output} is full" if getattr(exc, "errno", None) == errno.ENOSPC else \
            f"cannot write {output} ({exc})"
        raise SweepStopped(f"{why}; the finished cases are kept beside it: make room and run the same command "
                           "again to resume") from None


def _outcome(fut, executor, kept: int, output) -> CaseOutcome:
    """A finished case's outcome; a worker or a cluster lost stops the sweep (`SweepStopped`)."""
    try:
        return fut.result()
    except MbsError:
        raise
    except Exception as exc:  # a worker killed, a cluster lost: not one case's fault
        what = "the dask cluster failed" if executor is not None else "a worker process of the sweep died"
        raise SweepStopped(f"{what} ({type(exc).__name__}: {exc}); the {kept} case(s) stored so far are "
                           f"kept in {output}: run the same command again to resume") from None


def _case_bytes(outcome: CaseOutcome, n_rows: int) -> int:
    """Disk that storing a case can take: its data uncompressed (what gzip writes is at most that,
    plus headers), its section and summary, HDF5 metadata per dataset."""
    res = outcome.results
    sec = outcome.section
    arrays = [] if res is None else [res.time, *res.signals.values()]
    arrays += [sec.time, *sec.points.values()] if sec is not None else []
    data = sum(np.asarray(a).nbytes for a in arrays) + 64 * len(outcome.summary or {})
    return int(data * 1.05 + len(arrays) * 8192 + n_rows * 2048 + (1 << 18))


def _store_case(f, outcome: CaseOutcome, compression: str | None) -> None:
    """Write a case under /cases/<k> of an open (case) file: the run's kept signals and attributes,
    its status, its Poincaré section and verdict, its summary statistics."""
    group = f"cases/{outcome.index}"
    write_results(f, outcome.results, group, compression=compression)
    g = f[group]
    g.attrs["sweep_status"] = outcome.status
    g.attrs["sweep_message"] = outcome.message
    g.attrs["case_wall_time"] = outcome.wall_time
    g.attrs["case_cpu_time"] = outcome.cpu_time
    g.attrs["case_started"] = outcome.started
    g.attrs["case_worker"] = outcome.worker
    if outcome.section is not None:
        write_section(g, outcome.section, outcome.verdict)
    if outcome.summary is not None:
        write_summary(g, outcome.summary, outcome.units or {})


def sweep_sections(path: str | Path) -> list[tuple[dict, Any, Any]]:
    """``(table row, PoincareSection, Verdict)`` of every case of a sweep file that has a section."""
    out = []
    with open_results(path) as f:
        for row in _table_rows(f):
            g = f.get(f"cases/{row['index']}")
            if g is not None and "poincare" in g:
                sec, verdict = read_section(g)
                out.append((row, sec, verdict))
    return out


# ---------------------------------------------------------------- replay and merge
def replay_case(path: str | Path, index: int, output: str | Path | None = None, **run_options):
    """Run case ``index`` of the scan file ``path`` again, from what the file records (the model's
    text with its includes, the fixed ``--set`` values, the settings, the case's values): the same
    run as `mbs run` with those settings, bit for bit, with every signal (into ``output`` if given).
    Returns its `Results`."""
    with open_results(path) as f:
        if f.attrs.get("kind") != "sweep":
            raise SweepError(f"{path} is not a sweep file")
        config = json.loads(f.attrs["config"])
        snapshot = ModelSnapshot.from_attrs(f.attrs)
        rows = {r["index"]: r for r in _table_rows(f)}
    rows.update({r["index"]: r for r in read_case_table(path)})
    if index not in rows:
        raise SweepError(f"{path} has no case {index} (cases {min(rows, default=0)}..{max(rows, default=-1)})")
    spec = _replay_spec(rows[index], config, snapshot)
    model = snapshot.compile({**spec.sets, **spec.values})
    run_options.setdefault("allow_unphysical", spec.allow_unphysical)
    return simulate(model, output=output, **case_settings(model, spec), **run_options)


def _replay_spec(row: dict, config: dict, snapshot: ModelSnapshot) -> CaseSpec:
    return CaseSpec(row["index"], snapshot.path, dict(row["values"]), dict(config.get("sets") or {}),
                    dict(config.get("settings") or {}), config.get("revolutions"), config.get("per_rev"),
                    None, config.get("section"), snapshot, bool(config.get("allow_unphysical", False)))


def case_summary(path: str | Path, index: int) -> dict[str, tuple[float, float, float]]:
    """The stored (min, max, RMS) of every signal of case ``index`` (`sweep_store.signal_summary`)."""
    with open_results(path) as f:
        return read_summary(f[f"cases/{index}"])


def merge_sweeps(inputs: Sequence[str | Path], output: str | Path, overwrite: bool = False) -> int:
    """Merge scan files of the same model and settings (e.g. computed on two machines) into one:
    the first file's cases keep their indices, the others' are appended in their order; a case
    present in two files is refused, as are files of another model, other settings or other
    parameters.  Written beside ``output`` and renamed into place.  Returns the number of cases."""
    output = Path(output)
    inputs = [Path(p) for p in inputs]
    if len(inputs) < 2:
        raise SweepError("give at least two sweep files to merge")
    if any(output.exists() and p.exists() and os.path.samefile(p, output) for p in inputs):
        raise SweepError(f"{output} is one of the files to merge: choose another -o")
    if output.exists() and not overwrite:
        raise SweepError(f"{output} exists; choose another -o or pass --overwrite")
    heads = []
    for p in inputs:
        if case_files(journal_folder(p)):
            raise SweepError(f"{p} has finished cases not yet gathered (a sweep was stopped): run its sweep "
                             "command again first")
        old, old_params, rows = _read_scan(p)
        heads.append((p, old, old_params, rows))
    first, config, params0, _ = heads[0]
    names = [n for n, _ in params0]
    seen: dict[str, Path] = {}
    for p, old, old_params, rows in heads:
        _same_sweep(p, old, config, [n for n, _ in old_params], names)
        for r in rows:
            if r["status"] == "missing":  # a case not run yet (pending), or its group gone
                raise SweepError(f"{p}: case {r['index']} has not been run: run its sweep command again first")
            if r["key"] in seen:
                raise SweepError(f"case {r['key']} is in both {seen[r['key']]} and {p}: a merge takes each "
                                 "case once")
            seen[r["key"]] = p
    lock = _merge_lock(output)
    tmp = output.with_name(f".{output.name}.tmp-{os.getpid()}")
    try:
        clean_stale_copies(output)
        shutil.copyfile(first, tmp)
        with h5py.File(tmp, "r+", locking=False) as f:
            all_rows = list(heads[0][3])
            merged = [[n, list(v)] for n, v in params0]
            nxt = max((r["index"] for r in all_rows), default=-1) + 1
            for p, _, old_params, rows in heads[1:]:
                values = dict(old_params)
                for m in merged:
                    m[1] = list(dict.fromkeys(m[1] + list(values[m[0]])))
                with h5py.File(p, "r", locking=False) as src:
                    for r in sorted(rows, key=lambda r: r["index"]):
                        f.copy(src[f"cases/{r['index']}"], f"cases/{nxt}")
                        f[f"cases/{nxt}"].attrs["case"] = nxt
                        all_rows.append(dict(r, index=nxt))
                        nxt += 1
            f.attrs["params"] = json.dumps(merged)
            write_table(f, all_rows, names, parameter_si)
        publish(tmp, output)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        lock.release()
    return len(all_rows)


def _merge_lock(output: Path) -> OutputLock:
    """The merge's `OutputLock` on ``output``: refused while a sweep, a run or a merge writes it."""
    try:
        return OutputLock(output, "a merge")
    except OutputBusy as busy:
        raise SweepError(f"{output} is being written by {busy}; wait for it to end (or choose another -o)") from None
    except OSError as exc:
        raise SweepError(f"cannot write {output}: {exc.strerror or exc}") from None
