"""Results of a run: named signals in memory and in one HDF5 file.

File layout (defined once: `TIME`, `SIGNALS`, `UNIT`, `UNITS`, `entity_path`, `create_run_datasets`,
shared by `ResultsWriter`, `write_results`, `read_results` and `FileResults`)::

    /time                (n,)  s
    /signals/<entity>    (n,)  one compound dataset per entity: a float64 field per quantity
                               (slider: x, y, phi, vx, ...), attribute `units` (one per field)
    attributes of /: format_version, model_source, model_path, model_key, model_includes (JSON:
        absolute path -> text of every included file), parameters (JSON), version,
        complete (bool), status, message, wall_time, n_steps, n_rejected,
        n_rhs, n_contact_events, n_outputs, settings (JSON), mechanism (JSON: the slider and its
        axis, the clock body, the output link, each contact's geometry: `section.mechanism_facts`)

`ResultsWriter` appends chunks while the run goes and flushes after each, so a
crash or Ctrl-C keeps what was computed.  Before each write it reserves the disk
space the write needs (`reserve_space`): a full disk stops the run *between* two
chunks with `DiskFull`, and the file stays readable up to the last whole chunk
(HDF5 has no journal: a write that fails halfway leaves a file it cannot read).
`FileResults` reads a written run back lazily, one signal at a time, so a run
that streams to a file never holds all its rows in memory.  h5py is imported on first use (`planar_mbs.lazy`).

One dataset per entity, not per signal: a file's cost (datasets created, resized and written at
each flush) grows with the entities, not the signals (a 40-link chain: 81 datasets instead of
1098).  Plain h5py reads one signal as ``f["signals/slider"]["vx"]`` and pandas an entity as
``pd.DataFrame(f["signals/slider"][()])``.  Files of the earlier layout (a dataset per signal,
``/signals/<entity>/<quantity>``) are still read.
"""
from __future__ import annotations

import ctypes
import errno
import fcntl
import json
import math
import os
import re
import shutil
import stat
from collections.abc import Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import MbsError, ModelError, did_you_mean
from ..files import replace_atomically
from ..lazy import lazy
from .output_lock import OutputBusy, OutputLock
from .signals import Signal

h5py = lazy("h5py")
pd = lazy("pandas")  # optional: only `Results.to_dataframe` needs it
resource = lazy("resource")  # POSIX only: `file_size_limit` does without it

FORMAT_VERSION = 1  # attribute `format_version` of a run's group; readers refuse newer ones


def entity_groups(names) -> dict[str, list[str]]:
    """Signal names grouped by entity, in order: {"slider": ["x", "y", ...], ...}."""
    groups: dict[str, list[str]] = {}
    for name in names:
        entity, qty = name.rsplit(".", 1)
        groups.setdefault(entity, []).append(qty)
    return groups


def _compound(quantities) -> np.dtype:
    return np.dtype([(q, "<f8") for q in quantities])


def _as_records(block: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """(n, k) float64 → (n,) records of k float64 fields, without a copy when contiguous."""
    return np.ascontiguousarray(block, dtype=np.float64).view(dtype).reshape(-1)


def read_signal(g, name: str, sl=slice(None)) -> np.ndarray:
    """One signal from a run's group ``g`` (an open h5py group), in either layout."""
    entity, qty = name.rsplit(".", 1)
    obj = g[entity_path(entity)]
    if hasattr(obj, "dtype"):  # one dataset per entity
        return np.ascontiguousarray(obj.fields(qty)[sl])
    return obj[qty][sl]  # earlier layout: a group of datasets


def signal_units(g) -> dict[str, str]:
    """{name: unit} of every signal of a run's group ``g``, in file order, in either layout."""
    units = {}
    for entity, obj in g[SIGNALS].items():
        if hasattr(obj, "dtype"):
            for qty, unit in zip(obj.dtype.names, obj.attrs.get(UNITS, [""] * len(obj.dtype.names))):
                units[f"{entity}.{qty}"] = unit.decode() if isinstance(unit, bytes) else str(unit)
        else:
            for qty, ds in obj.items():
                units[f"{entity}.{qty}"] = ds.attrs.get(UNIT, "")
    return units


@dataclass
class Results:
    """Time and named signals of one run, plus its attributes (statistics, model source)."""

    time: np.ndarray
    signals: dict[str, np.ndarray]
    units: dict[str, str] = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.signals[name]
        except KeyError:
            hint = did_you_mean(name, self.signals)
            raise KeyError(f"no signal {name!r}" + (f"; {hint}" if hint else "")) from None

    def __contains__(self, name: str) -> bool:
        return name in self.signals

    @property
    def complete(self) -> bool:
        return bool(self.attrs.get("complete", True))

    @property
    def stats(self) -> dict:
        keys = ("wall_time", "n_steps", "n_rejected", "n_rhs", "n_contact_events", "n_outputs")
        return {k: self.attrs[k] for k in keys if k in self.attrs}

    def to_dataframe(self, signals=None):
        """A pandas DataFrame: one column per signal (all, or those named in ``signals``), indexed
        by time in seconds; the units are in ``df.attrs["units"]``.  Needs pandas (not a
        dependency of planar_mbs: ``pip install 'planar_mbs[pandas]'``)."""
        try:
            pd.DataFrame  # the first access imports pandas
        except ImportError:
            raise ImportError("to_dataframe needs pandas, which planar_mbs does not install by itself: "
                              "pip install 'planar_mbs[pandas]' (or pip install pandas)") from None

        names = list(self.signals) if signals is None else [signals] if isinstance(signals, str) else list(signals)
        df = pd.DataFrame({name: self[name] for name in names},
                          index=pd.Index(np.asarray(self.time), name="time"))
        df.attrs["units"] = {name: self.units.get(name, "") for name in names}
        return df


class FileResults(Results):
    """A run kept in a results file: `time` and each signal are read from the file when
    asked for (and not kept), so the rows of a long run never all sit in memory."""

    def __init__(self, path: str | Path, group: str, units: dict[str, str], attrs: dict):
        self.path, self.group = Path(path), group.strip("/")
        self.units, self.attrs = dict(units), dict(attrs)
        self._time = None
        self.signals = _FileSignals(self, list(self.units))

    @contextmanager
    def _run_group(self):
        """The run's group, opened like every results file a command reads (`open_results`:
        a regular HDF5 file) and checked (`check_run_layout`) at each opening, since the file
        may have changed since the run wrote it; nothing is read whole, so no memory budget."""
        with open_results(self.path) as f:
            g = f[self.group] if self.group else f
            check_run_layout(g, str(self.path), budget=math.inf)
            yield g

    def _read(self, name: str) -> np.ndarray:
        with self._run_group() as g:
            return g[TIME][()] if name == TIME else read_signal(g, name)

    @property
    def time(self) -> np.ndarray:
        return self._read(TIME) if self._time is None else self._time

    @time.setter
    def time(self, value) -> None:
        self._time = value

    def peak(self, name: str) -> float:
        """Largest finite value of a signal, read in slices (memory bounded); NaN if none."""
        best = -np.inf
        with self._run_group() as g:
            step, n = 1 << 16, g[TIME].shape[0]  # HDF5 buffers whole compound records per slice
            for i in range(0, n, step):
                x = read_signal(g, name, slice(i, i + step))
                x = x[np.isfinite(x)]
                if len(x):
                    best = max(best, float(x.max()))
        return best if best > -np.inf else float("nan")


class _FileSignals(Mapping):
    """The signals of a `FileResults`, each read from the file on access."""

    def __init__(self, owner: FileResults, names: list[str]):
        self.owner, self.names = owner, names

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self.names:
            raise KeyError(name)
        return self.owner._read(name)

    def __contains__(self, name) -> bool:
        return name in self.names  # Mapping's default would read the whole signal to find out

    def __iter__(self):
        return iter(self.names)

    def __len__(self) -> int:
        return len(self.names)


def row_count(results: Results) -> int:
    """Number of output rows of any `Results`, without reading them."""
    if isinstance(results, FileResults):
        with results._run_group() as g:
            return int(g[TIME].shape[0])
    return len(results.time)


def peak(results: Results, name: str) -> float:
    """Largest finite value of a signal of any `Results` (NaN if it has none)."""
    if isinstance(results, FileResults):
        return results.peak(name)
    x = np.asarray(results.signals[name])
    x = x[np.isfinite(x)]
    return float(x.max()) if len(x) else float("nan")


# ---------------------------------------------------------------- disk space
class DiskFull(MbsError):
    """There is no room on the disk for the next chunk of results; nothing of it was written."""

    exit_code = 3

    def __init__(self, message: str):
        self.message = message
        super().__init__(message)


_FALLOC_FL_KEEP_SIZE, _FALLOC_FL_PUNCH_HOLE = 0x01, 0x02
_fallocate = None


def _libc_fallocate():
    """libc's fallocate(2) (it takes flags, unlike os.posix_fallocate), or None."""
    global _fallocate
    if _fallocate is None:
        try:
            fn = ctypes.CDLL(None, use_errno=True).fallocate
            fn.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int64, ctypes.c_int64]
            fn.restype = ctypes.c_int
            _fallocate = fn
        except (OSError, AttributeError):
            _fallocate = False
    return _fallocate or None


def reserve_space(fd: int, nbytes: int, path: str | Path = "") -> int:
    """Allocate ``nbytes`` of disk past the end of the file open as ``fd`` without changing its size
    (fallocate with FALLOC_FL_KEEP_SIZE), so the writes that follow cannot run out of space halfway.
    Raises `DiskFull` when the disk cannot hold them.  Where fallocate is not supported, compares
    with the free space instead.  Returns the end of the reserved range."""
    end = os.fstat(fd).st_size
    limit = file_size_limit()
    if end + int(nbytes) > limit:  # past it a write fails halfway (EFBIG): stop before, as on a full disk
        raise DiskFull(f"{path or 'the results file'} reached the file-size limit of this process "
                       f"({_mb(limit)}, `ulimit -f`): the next {_mb(nbytes)} of results do not fit; raise the "
                       "limit or keep fewer rows (--keep, --output-step)")
    fn = _libc_fallocate()
    if fn is not None and fn(fd, _FALLOC_FL_KEEP_SIZE, end, int(nbytes)) == 0:
        return end + int(nbytes)
    err = ctypes.get_errno() if fn is not None else 0
    if err not in (0, 28):  # not supported here (EOPNOTSUPP, ...): look at the free space instead
        try:
            free = shutil.disk_usage(Path(path).parent if path else ".").free
        except OSError:
            return end
        if free >= nbytes:
            return end
    need = _mb(nbytes)
    raise DiskFull(f"the disk holding {path or 'the results file'} is full: the next {need} of results do not "
                   "fit (No space left on device); free some space or write elsewhere (-o)")


def file_size_limit() -> float:
    """The largest file this process may write (RLIMIT_FSIZE, `ulimit -f`), in bytes; inf if none."""
    try:
        soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    except (ImportError, OSError, ValueError):
        return math.inf
    return math.inf if soft == resource.RLIM_INFINITY or soft < 0 else float(soft)


def release_reserve(fd: int, end: int) -> None:
    """Give back what `reserve_space` allocated past the end of the file (best effort)."""
    fn = _libc_fallocate()
    try:
        size = os.fstat(fd).st_size
    except OSError:
        return
    if fn is not None and end > size:
        fn(fd, _FALLOC_FL_PUNCH_HOLE | _FALLOC_FL_KEEP_SIZE, size, end - size)


def _mb(nbytes: float) -> str:
    return f"{nbytes / 1e6:.3g} MB" if nbytes >= 1e5 else f"{nbytes / 1e3:.3g} kB"


def results_bytes(rows_before: int, n_rows: int, n_columns: int, chunk: int = 4096) -> int:
    """Disk that appending ``n_rows`` rows after ``rows_before`` rows to ``n_columns`` chunked float64
    datasets (time included) takes: the whole new chunks it starts in each dataset, and room for
    HDF5's metadata (chunk index nodes, object headers)."""
    new_chunks = -(-(rows_before + n_rows) // chunk) - (-(-rows_before // chunk))
    return int(new_chunks * chunk * 8 * n_columns + n_columns * 2048 + (1 << 17))


# ---------------------------------------------------------------- the file layout (one definition)
TIME = "time"  # dataset of the output times
SIGNALS = "signals"  # group of the signals: SIGNALS/<entity>, one compound dataset per entity
UNIT = "unit"  # attribute of the time dataset (and of every dataset in files of the earlier layout)
UNITS = "units"  # attribute of an entity's dataset: the unit of each field
JSON_ATTRS = ("parameters", "settings", "warnings", "model_includes", "model_tables", "assembly_changes",
              "mechanism", "model_warnings")  # JSON


def entity_path(entity: str) -> str:
    """Dataset path of an entity's signals inside a run's group."""
    return f"{SIGNALS}/{entity}"


def create_run_datasets(g, names_units, data=None, **opts) -> tuple:
    """Create the time dataset and one compound dataset per entity in group ``g`` (the layout
    every writer uses); ``names_units`` is a list of (name, unit), ``data`` None (empty and
    growable) or (time, [values, ...]).  Returns (time dataset, [entity datasets in the order
    of `entity_groups`])."""
    units = dict(names_units)
    groups = entity_groups(units)
    if data is None:
        opts = dict(shape=(0,), maxshape=(None,), **opts)
        time = g.create_dataset(TIME, dtype="f8", **opts)
    else:
        time = g.create_dataset(TIME, data=np.asarray(data[0], "f8"), **opts)
        values = dict(zip(units, data[1]))
        n = len(data[0])
    time.attrs[UNIT] = "s"
    datasets = []
    for entity, qtys in groups.items():
        dtype = _compound(qtys)
        if data is None:
            ds = g.create_dataset(entity_path(entity), dtype=dtype, **opts)
        else:
            block = np.column_stack([np.asarray(values[f"{entity}.{q}"], "f8") for q in qtys]) if n else \
                np.zeros((0, len(qtys)))
            ds = g.create_dataset(entity_path(entity), data=_as_records(block, dtype), **opts)
        ds.attrs[UNITS] = [units[f"{entity}.{q}"] for q in qtys]
        datasets.append(ds)
    return time, datasets


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def set_attrs(obj, attrs: dict) -> None:
    """Write attributes the way a run stores them (dicts and lists as JSON, None as "")."""
    for key, value in attrs.items():
        if isinstance(value, (dict, list, tuple)):
            value = json.dumps(value, default=_json_default)
        elif value is None:
            value = ""
        obj.attrs[key] = value


def write_results(target, results: Results, group: str = "/", compression: str | None = None) -> None:
    """Write a finished `Results` in the layout of one run into ``group`` of ``target``
    (an open h5py File/Group, or a path opened in append mode).  An existing group of that
    name is replaced.  Used by sweeps, whose worker processes return results in memory and
    whose parent process alone writes the file."""
    if not isinstance(target, (h5py.File, h5py.Group)):
        with h5py.File(target, "a") as f:
            return write_results(f, results, group, compression)
    chunk = ResultsWriter.CHUNK
    name = group.strip("/")
    if name and name in target:
        del target[name]
    g = target.require_group(name) if name else target
    n = len(results.time)
    opts = dict(compression=compression) if compression and n else {}  # HDF5 cannot chunk 0 rows
    chunks = dict(chunks=(min(max(n, 1), chunk),)) if opts else {}
    create_run_datasets(g, [(name, results.units.get(name, "")) for name in results.signals],
                        (results.time, list(results.signals.values())), **opts, **chunks)
    set_attrs(g, dict(results.attrs, format_version=FORMAT_VERSION))


def write_beside(path, results: Results, overwrite: bool = False, inputs=()) -> None:
    """Write a finished `Results` as the file `path`: beside it first (`part_beside`, locked, not
    through a symbolic link), then moved into place, so a kill leaves the earlier file or this one."""
    path = Path(path)
    refuse_replacing(path, overwrite=overwrite, inputs=inputs)
    part = part_beside(path)
    f, lock = open_for_writing(part, "w", shown=path)
    moved = False
    try:
        try:
            write_results(f, results)
        finally:
            f.close()
        replace_atomically(part, path)
        moved = True
    finally:
        if not moved:
            part.unlink(missing_ok=True)
        lock.release()


class ResultsBusy(Exception):
    """Another process is writing this results file."""


class WriteLock:
    """Exclusive ownership of a results file for one writing process.

    HDF5 locks a file only after opening it, and opening for writing truncates
    it, so a second writer would wipe the first one's data before HDF5 noticed.
    Here the writer first takes a non-blocking ``flock`` on the file itself
    (opened without truncation), holds it while it writes, and only then lets
    h5py open the file (with HDF5's own locking off: ours covers it).  The lock
    dies with the process, so a crash leaves nothing stale behind.
    """

    def __init__(self, path: Path):
        self.fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o644)
        if not stat.S_ISREG(os.fstat(self.fd).st_mode):  # a FIFO or device planted at the name
            os.close(self.fd)
            raise OSError(0, "not a regular file")
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            raise ResultsBusy(f"{path} is being written by another process") from None

    output_lock = None  # the `OutputLock` of the name written, taken by `open_for_writing`

    def release(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)  # closing the descriptor drops the flock
            self.fd = -1
        if self.output_lock is not None:
            self.output_lock.release()
            self.output_lock = None


WRITE_CHUNK_CACHE = 1 << 17  # bytes of HDF5 chunk cache per dataset when writing (4 chunks of 4096 rows)


def part_beside(path: Path) -> Path:
    """The hidden file a whole results file is written to before it replaces `path`."""
    path = Path(path)
    return path.with_name(f".{path.name}.part")


def open_for_writing(path: Path, mode: str, shown: Path | None = None):
    """(h5py.File, WriteLock) for a writer; a file another process writes (`ResultsBusy`), a file size
    limit, or a file that cannot be opened is an `MbsError` (exit code 2) saying so (named as
    `shown`, the file the user named)."""
    shown = path if shown is None else shown
    beside = _output_lock(shown)
    try:
        lock = WriteLock(path)
        lock.output_lock, beside = beside, None
        try:
            if mode == "w":
                os.ftruncate(lock.fd, 0)  # a part file left by a killed run: ours now
            # a small chunk cache: HDF5's default (1 MiB per dataset) keeps growing with the rows
            # written (measured: all of them), which would make memory grow with t_end
            return h5py.File(path, mode, locking=False, rdcc_nbytes=WRITE_CHUNK_CACHE), lock
        except BaseException:
            lock.release()
            raise
    except ResultsBusy:
        err = MbsError(f"cannot write {shown}: {shown} is being written by another process")
        err.exit_code = 2
        raise err from None
    except OSError as exc:
        err = MbsError(f"cannot write {shown}: {_os_reason(exc, path, shown)}")
        err.exit_code = 2
        raise err from None
    finally:
        if beside is not None:
            beside.release()


def _output_lock(shown: Path) -> OutputLock:
    """The `OutputLock` of ``shown``; held by another writer, or unusable: an `MbsError` (exit 2)."""
    try:
        return OutputLock(shown)
    except OutputBusy as busy:
        message = f"cannot write {shown}: it is being written by {busy}; wait for it to end or choose another output"
    except OSError as exc:
        if exc.errno == errno.ENOSPC:
            raise DiskFull(f"the disk holding {shown} is full (No space left on device); nothing was written: "
                           "free some space and run it again") from None
        message = f"cannot write {shown}: {exc.strerror or exc}"
    err = MbsError(message)
    err.exit_code = 2
    raise err


def _os_reason(exc: OSError, path: Path | None = None, shown: Path | None = None) -> str:
    """Why ``path`` (written for ``shown``) could not be opened; a part file is named."""
    whose = "it is" if path is None or Path(path) == Path(shown) else f"its part file {path} is"
    if exc.errno == errno.ELOOP:
        return f"{whose} a symbolic link (results are never written through one): remove it"
    if exc.strerror == "not a regular file":
        return f"{whose} not a regular file: remove it"
    return f"{path}: {exc.strerror or exc}" if whose != "it is" else exc.strerror or str(exc)


def results_kind(path: Path) -> str:
    """What the file at `path` is: "run" (the results of one run), "sweep", "wear" (a wear run's profiles,
    `run.wear`), "hdf5" (another HDF5 file), "other" (any other file) -- read with h5py only after the signature matched."""
    try:
        with open(path, "rb") as f:
            if f.read(len(HDF5_SIGNATURE)) != HDF5_SIGNATURE:
                return "other"
    except OSError:
        return "other"
    try:
        with h5py.File(path, "r", locking=False) as f:
            if f.attrs.get("kind") == "sweep":
                return "sweep"
            if "wear" in f and len(f["wear"]):
                return "wear"
            return "run" if TIME in f and SIGNALS in f else "hdf5"
    except Exception:  # noqa: BLE001  (damaged: not ours to replace without being told)
        return "hdf5"


def refuse_replacing(path: Path, overwrite: bool = False, inputs=()) -> None:
    """Refuse (`MbsError`, exit code 2), before anything runs, an output that would destroy a file
    it should not: one of ``inputs`` (the model and its includes: never), a folder, FIFO or device
    (never), a symbolic link, or a file that is not the results of one run (a sweep file, a
    `.py`, a `.csv`, ...) unless ``overwrite``."""
    path = Path(path)
    for other in inputs:
        if other is not None and _same_file(path, other):
            _refuse(f"{path} is the model or a file it includes: writing results there would destroy it",
                    "choose another output file")
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return
    except OSError as exc:
        _refuse(f"cannot use {path}: {exc.strerror or exc}", "choose another output file")
    if stat.S_ISDIR(info.st_mode):
        _refuse(f"{path} is a folder", f"give a file name, e.g. {path / 'results.h5'}")
    if info.st_uid != os.geteuid() and os.geteuid() != 0 and _sticky(path.parent):
        _refuse(f"{path} belongs to another user in a shared folder (/tmp-like): it cannot be replaced",
                "choose another output file")
    if overwrite:
        if not (stat.S_ISREG(info.st_mode) or stat.S_ISLNK(info.st_mode)):
            _refuse(f"{path} is not a regular file", "give the name of a file to write")
        return
    if stat.S_ISLNK(info.st_mode):
        _refuse(f"{path} is a symbolic link: the results would replace the link (never its target)",
                "give the file itself, or pass --overwrite (overwrite=True) to replace the link")
    if not stat.S_ISREG(info.st_mode):
        _refuse(f"{path} is not a regular file", "give the name of a file to write")
    kind = results_kind(path)
    if kind != "run":
        what = {"sweep": "a sweep file", "wear": "the file of a wear run", "hdf5": "an HDF5 file that is not the results of a run",
                "other": "not a results file"}[kind]
        _refuse(f"{path} exists and is {what}; it would be replaced",
                "choose another output, or pass --overwrite (overwrite=True in Python) to replace it")


def _sticky(folder: Path) -> bool:
    try:
        return bool(os.stat(folder).st_mode & stat.S_ISVTX)
    except OSError:
        return False


def _refuse(message: str, hint: str):
    raise ModelError(message, hint=hint)


def _same_file(a, b) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


class _RowPacker:
    """Packs observation rows into each entity's records, contiguous and of its dataset's own type,
    so HDF5 writes them without a conversion: a gather of the entity's columns (`np.take`) straight
    into a buffer kept from one write to the next, the few combined signals (magnitudes, sums)
    computed into their fields.  (A strided view of the rows, which HDF5 converted field by field,
    cost about 0.1 us per row and entity; fresh arrays for each write, fresh pages from the system.)"""

    def __init__(self, table: list[Signal]):
        by_entity: dict[str, list[Signal]] = {}
        for sig in table:
            by_entity.setdefault(sig.entity, []).append(sig)
        self.entities = []
        for entity, sigs in by_entity.items():
            src = np.array([s.columns[0] for s in sigs], dtype=np.intp)
            combined = [(j, s) for j, s in enumerate(sigs) if s.op != "col"]
            self.entities.append((entity, _compound([s.quantity for s in sigs]), [s.unit for s in sigs], src, combined))
        self._buffers = [np.empty((0, len(e[3]))) for e in self.entities]

    def records(self, rows: np.ndarray) -> list[np.ndarray]:
        """[(n,) records of each entity] of an (n, columns) block of rows, in buffers that the next
        call overwrites."""
        n = len(rows)
        rows = np.asarray(rows, dtype=np.float64)
        if self._buffers and len(self._buffers[0]) < n:
            self._buffers = [np.empty((n, len(e[3]))) for e in self.entities]
        out = []
        for (_, packed, _, src, combined), buf in zip(self.entities, self._buffers):
            block = np.take(rows, src, axis=1, out=buf[:n], mode="clip")  # "clip": no buffering of `out`
            for j, sig in combined:  # into their field, without temporaries
                if sig.op == "beam":  # a beam's strain, curvature, moment or energy (`signals.beam_signals`)
                    block[:, j] = sig.extract(rows)
                    continue
                a, b = (rows[:, c] for c in sig.columns[:2])
                with np.errstate(over="ignore", invalid="ignore"):  # rows of a run that blew up: inf, NaN
                    if sig.op == "hypot":
                        np.hypot(a, b, out=block[:, j])
                    else:
                        np.add(a, b, out=block[:, j])
                        for c in sig.columns[2:]:
                            block[:, j] += rows[:, c]
            out.append(block.view(packed).reshape(-1))
        return out


class ResultsWriter:
    """Appends observation chunks to an HDF5 file as the run goes.

    A whole file (``group`` "/", ``mode`` "w") is written beside its name, in the hidden file
    `part_beside` (opened without following a symbolic link), and moved over the name by `close`
    (a rename: a symbolic link planted at the name is replaced, never followed).  So a kill at any
    moment leaves the earlier file whole, or the new one; what a killed run computed stays in the
    part file.  The part file's name is fixed, and its `WriteLock` keeps a second writer of the
    same name out.  An existing file at the name is replaced only if it is the results of one run
    (`refuse_replacing`), unless ``overwrite``."""

    CHUNK = 4096

    def __init__(self, path: str | Path, table: list[Signal], attrs: dict, group: str = "/", mode: str = "w",
                 overwrite: bool = False, inputs=()):
        """``group`` places the run inside a file (``"/cases/3"`` of a sweep); ``mode`` is the
        h5py mode (``"w"`` writes a new file, ``"a"`` adds the group to an existing file in place;
        an existing group of that name is replaced).  ``inputs``: files never written over (the
        model and its includes)."""
        self.path = Path(path)
        self.target = self.path
        self.whole = mode == "w" and not group.strip("/")
        if self.whole:
            refuse_replacing(self.path, overwrite=overwrite, inputs=inputs)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.table = table
        write_to = part_beside(self.path) if self.whole else self.path
        self.file, self.lock = open_for_writing(write_to, mode, shown=self.path)
        self.path = write_to
        self.reserved = 0
        self.broken = False
        self.t_last = 0.0  # time of the last row written
        try:
            self._reserve(len(json.dumps(attrs, default=_json_default)) + results_bytes(0, 0, len(table) + 1))
            self.packer = _RowPacker(table)
            if group.strip("/") and group.strip("/") in self.file:
                del self.file[group.strip("/")]
            self.group = self.file.require_group(group) if group.strip("/") else self.file
            self.n = 0
            self.time, self.datasets = create_run_datasets(self.group, [(sig.name, sig.unit) for sig in table],
                                                           chunks=(self.CHUNK,))
            self.set_attrs(dict(attrs, complete=False, status="running", format_version=FORMAT_VERSION))
            self.file.flush()
        except BaseException:
            self.broken = True  # nothing worth keeping: the earlier file at the name stays
            self.close()
            if self.whole and self.path != self.target:
                self.path.unlink(missing_ok=True)
            raise

    def _reserve(self, nbytes: int) -> None:
        self.reserved = max(self.reserved, reserve_space(self.lock.fd, nbytes, self.target))

    def set_attrs(self, attrs: dict) -> None:
        set_attrs(self.group, attrs)

    def append(self, t: np.ndarray, rows: np.ndarray) -> None:
        """Write the rows after the ones already in the file.  When the disk cannot hold them all,
        writes as many whole chunks of them as fit and raises `DiskFull`; a piece is written
        whole or not at all (`ResultsWriteError` if a write fails anyway)."""
        try:
            self._append(t, rows)
            return
        except ResultsWriteError:
            raise
        except DiskFull:
            pass
        for i in range(0, len(t), self.CHUNK):  # what fits, chunk by chunk; DiskFull at the first that does not
            self._append(t[i:i + self.CHUNK], rows[i:i + self.CHUNK])

    def _append(self, t: np.ndarray, rows: np.ndarray) -> None:
        n = len(t)
        if n == 0:
            return
        self._reserve(results_bytes(self.n, n, len(self.table) + 1, self.CHUNK))
        end = self.n + n
        try:
            self._write(self.time, np.ascontiguousarray(t, dtype=np.float64), end)
            for records, ds in zip(self.packer.records(rows), self.datasets):
                self._write(ds, records, end)
            self.file.flush()
        except (OSError, RuntimeError) as exc:
            self.broken = True
            raise ResultsWriteError(f"cannot write {self.path}: {exc}") from None
        self.n = end
        self.t_last = float(t[-1])

    def _write(self, ds, data: np.ndarray, end: int) -> None:
        """Rows self.n:end of dataset ``ds`` from ``data`` (contiguous, of its type).  Chunks that start
        at or after self.n go straight to the file (H5Dwrite_chunk, which the datasets' lack of
        filters allows), the last one padded to a whole chunk (HDF5 stores every chunk whole; rows
        past the dataset's end are never read, and a later append writes over them); the rest of a
        chunk already started goes through HDF5's ordinary write, which copies each chunk into
        its chunk buffer first: 1.4 GB/s against 3-4 GB/s straight (these calls: 0.18 -> 0.14 us per
        row of the slider-crank with every signal)."""
        chunk, start = self.CHUNK, self.n
        ds.resize((end,))
        a = min(end, -(-start // chunk) * chunk)  # the first chunk boundary at or after `start`
        if a > start:
            ds[start:a] = data[:a - start]
        for i in range(a, end, chunk):
            piece = data[i - start:i - start + chunk]
            if len(piece) < chunk:
                piece = np.concatenate([piece, np.zeros(chunk - len(piece), data.dtype)])
            ds.id.write_direct_chunk((i,), piece)

    def close(self, attrs: dict | None = None) -> None:
        """Store the final attributes (when there is room), close the file and move it into place
        (a whole file); a file that could not be written readably stays in its part file."""
        if self.lock.fd < 0:
            return
        try:
            if attrs and not self.broken:
                try:
                    self._reserve(len(json.dumps(attrs, default=_json_default)) + (1 << 16))
                    self.set_attrs(attrs)
                except DiskFull:
                    pass  # the file keeps status "running", complete = False: still readable
            try:
                self.file.close()
            except (OSError, RuntimeError):
                self.broken = True
        finally:
            release_reserve(self.lock.fd, self.reserved)
            if self.whole and self.path != self.target and not self.broken:
                try:
                    replace_atomically(self.path, self.target)
                    self.path = self.target
                except OSError:
                    pass  # (a sticky folder, a vanished folder) the results stay in the part file
            self.lock.release()


class ResultsWriteError(DiskFull):
    """A write to the results file failed (an I/O error, a disk that filled past the reservation)."""


# ---------------------------------------------------------------- reading files we did not write
class ResultsFileError(MbsError):
    """A file given as results is not one (missing, not a regular file, not HDF5, a foreign or
    crafted layout, more data than memory allows)."""

    exit_code = 2

    def __init__(self, message: str, hint: str = ""):
        self.message = message
        self.hint = hint
        super().__init__(f"error: {message}" + (f"\nhint: {hint}" if hint else ""))


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,199}")
MAX_SIGNALS = 100_000
_JSON_ATTRS = {"parameters": dict, "settings": dict, "warnings": list, "model_includes": dict,
               "model_tables": dict, "assembly_changes": list, "mechanism": dict, "model_warnings": list}


def memory_budget() -> int:
    """Bytes a command may read into memory at once: half of the physical memory."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2
    except (ValueError, OSError, AttributeError):
        return 4 * 2**30


def check_results_file(path: str | Path) -> Path:
    """The path of an existing regular HDF5 file, or `ResultsFileError` -- checked with
    ``os.stat`` and 8 bytes, so a FIFO, a device or a folder is never opened by HDF5."""
    path = Path(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        part = part_beside(path)
        hint = (f"a run writing it stopped without finishing (killed?): its rows so far are in {part}"
                if os.path.lexists(part) else "check the path")
        raise ResultsFileError(f"no such results file: {path}", hint=hint) from None
    except OSError as exc:
        raise ResultsFileError(f"cannot read {path}: {exc.strerror or exc}",
                               hint="give a results file written by `mbs run` or `mbs sweep`") from None
    if not stat.S_ISREG(info.st_mode):
        kind = "a folder" if stat.S_ISDIR(info.st_mode) else "not a regular file"
        raise ResultsFileError(f"{path} is {kind}", hint="give a results file written by `mbs run` or `mbs sweep`")
    try:
        with open(path, "rb") as f:
            head = f.read(len(HDF5_SIGNATURE))
    except OSError as exc:
        raise ResultsFileError(f"cannot read {path}: {exc.strerror or exc}") from None
    if head != HDF5_SIGNATURE:
        what = "empty" if info.st_size == 0 else "not an HDF5 file"
        raise ResultsFileError(f"{path} is {what}", hint="give a results file written by `mbs run` or `mbs sweep`"
                               + (" (a .rrd recording is an output of `mbs view`, not an input)"
                                  if path.suffix == ".rrd" else ""))
    return path


@contextmanager
def open_results(path: str | Path, locking: bool = True):
    """An h5py File opened read-only after `check_results_file`; reading errors of a damaged or
    foreign file (inside the ``with``) become `ResultsFileError`.  ``locking=False`` for a
    process that holds the file's `WriteLock` itself (HDF5's own lock would conflict with it)."""
    path = check_results_file(path)
    if locking:
        refuse_if_being_written(path)
    with reading(path):
        f = h5py.File(path, "r", locking=locking)
    try:
        with reading(path):
            yield f
    finally:
        f.close()


def refuse_if_being_written(path) -> None:
    """Raise `ResultsFileError` when another process holds the file's `WriteLock` (a run or a sweep
    that has not ended): HDF5 cannot read a file that another process is writing, and its own lock
    then failed in a way that `reading` reported as a damaged file.  Checked with our lock itself, so
    it holds with HDF5's locking switched off too (HDF5_USE_FILE_LOCKING=FALSE)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return  # the open that follows reports it
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        raise ResultsFileError(f"{path} is being written by another process (a run or a sweep that has not "
                               "ended)", hint="wait for it to end, or stop it (Ctrl-C keeps what it has written) "
                               "and read the file then") from None
    except OSError:  # no flock on this file system: HDF5's own lock decides
        pass
    finally:
        os.close(fd)


@contextmanager
def reading(path):
    """Turn the exceptions a damaged or foreign HDF5 file raises while read into `ResultsFileError`."""
    try:
        yield
    except MbsError:
        raise
    except MemoryError:
        raise ResultsFileError(f"{path}: not enough memory to read it") from None
    except (OSError, KeyError, ValueError, TypeError, IndexError, AttributeError, RuntimeError,
            UnicodeError) as exc:
        raise ResultsFileError(f"{path} is damaged or not in the layout of planar_mbs results "
                               f"({type(exc).__name__}: {exc})",
                               hint="give a results file written by `mbs run` or `mbs sweep`") from None


def check_run_layout(g, where: str, budget: int | None = None) -> int:
    """Check one run's group before reading it: ``time`` and ``signals/<entity>`` (a compound
    dataset of float fields, or a group of datasets in the earlier layout), 1-D, one length,
    names that are names, hard links only, stored sizes that match the declared ones, and all
    of it within `budget` bytes.  Returns the bytes the run needs in memory."""
    def bad(what: str):
        return ResultsFileError(f"{where} is not a planar_mbs results file: {what}",
                                hint="give a results file written by `mbs run` or `mbs sweep`")

    fmt = g.attrs.get("format_version", FORMAT_VERSION)
    if not isinstance(fmt, (int, np.integer)) or int(fmt) > FORMAT_VERSION:
        raise ResultsFileError(f"{where} has format version {fmt!r}; this planar_mbs reads up to "
                               f"{FORMAT_VERSION}", hint="read it with a newer planar_mbs")

    def member(parent, name: str, kinds, what: str):
        """A member reached by a hard link (soft and external links could lead to other files,
        a FIFO among them), of one of the expected kinds."""
        if not isinstance(parent.get(name, getlink=True), h5py.HardLink):
            raise bad(f"`{what}` is missing or a link")
        obj = parent[name]
        if not isinstance(obj, kinds):
            raise bad(f"`{what}` is not a {'dataset' if kinds is h5py.Dataset else 'group'}")
        return obj

    if SIGNALS not in g and "sweep_status" in g.attrs:  # a scan's case, small by default
        file, _, group = where.partition(":")
        raise ResultsFileError(
            f"{where} is a case of a scan that kept no signals (a scan stores each case's Poincaré section, "
            "verdict and summary statistics, and the signals named with --keep)",
            hint=f"`mbs sweep replay {file} {group.rstrip('/').rsplit('/', 1)[-1]} -o case.h5` runs it again with "
                 f"every signal; `mbs analyze {where}` reads its stored section")
    datasets = [(TIME, member(g, TIME, h5py.Dataset, TIME), None)]
    signals = member(g, SIGNALS, h5py.Group, SIGNALS)
    count = 0
    for entity in signals:
        if not _NAME.fullmatch(entity):
            raise bad(f"`{SIGNALS}/{entity[:80]!r}` is not an entity name")
        obj = member(signals, entity, (h5py.Group, h5py.Dataset), f"{SIGNALS}/{entity}")
        if isinstance(obj, h5py.Dataset):  # one compound dataset: a float field per quantity
            names = obj.dtype.names or ()
            if not names or any(not _NAME.fullmatch(q) or obj.dtype.fields[q][0].kind != "f"
                                or obj.dtype.fields[q][0].itemsize > 8 or obj.dtype.fields[q][0].shape
                                for q in names):
                raise bad(f"`{SIGNALS}/{entity}` is {obj.dtype}, not a record of float fields")
            datasets.append((f"{SIGNALS}/{entity}", obj, names))
            count += len(names)
        else:  # the earlier layout: a group of 1-D datasets
            for qty in obj:
                if not _NAME.fullmatch(qty):
                    raise bad(f"`{SIGNALS}/{entity}/{qty[:80]!r}` is not a signal name")
                datasets.append((f"{SIGNALS}/{entity}/{qty}",
                                 member(obj, qty, h5py.Dataset, f"{SIGNALS}/{entity}/{qty}"), None))
                count += 1
        if count > MAX_SIGNALS:
            raise bad(f"more than {MAX_SIGNALS:,} signals")
    n = None
    total = 0
    for name, ds, fields in datasets:
        if ds.ndim != 1 or (fields is None and (ds.dtype.kind not in "fiu" or ds.dtype.itemsize > 8)):
            raise bad(f"`{name}` is {ds.dtype} of shape {ds.shape}, not a 1-D array of numbers")
        if ds.is_virtual or ds.id.get_create_plist().get_external_count():
            raise bad(f"`{name}` keeps its data in other files")
        if n is None:
            n = ds.shape[0]
        elif ds.shape[0] != n:
            raise bad(f"`{name}` has {ds.shape[0]:,} samples, `time` has {n:,}")
        if not ds.id.get_create_plist().get_nfilters() and ds.id.get_storage_size() < ds.shape[0] * ds.dtype.itemsize:
            raise bad(f"`{name}` declares {ds.shape[0]:,} samples but stores only "
                      f"{ds.id.get_storage_size():,} bytes (truncated or crafted)")
        total += ds.shape[0] * 8 * (len(fields) if fields else 1)
    budget = memory_budget() if budget is None else budget
    if total > budget:
        raise ResultsFileError(f"{where} asks for {total / 2**30:.1f} GiB in memory; at most "
                               f"{budget / 2**30:.1f} GiB are allowed here",
                               hint="a file this large cannot be read on this machine")
    return total


def read_results(path: str | Path) -> Results:
    """Load a run written by `ResultsWriter` (or one case of a sweep file: `file.h5:/cases/3`),
    in either layout, after checking that it is a regular HDF5 file laid out as a run
    (`check_run_layout`): a foreign or crafted file is a `ResultsFileError`, not a traceback."""
    path = str(path)
    group = "/"
    if ":/" in path:
        path, group = path.split(":", 1)
    where = path if group == "/" else f"{path}:{group}"
    with open_results(path) as f:
        g = f.get(group)
        if not isinstance(g, h5py.Group):
            raise ResultsFileError(f"no group {group} in {path}",
                                   hint="cases of a sweep are FILE.h5:/cases/0, /cases/1, ... (see `mbs plot "
                                        "FILE.h5 --list`)")
        check_run_layout(g, where)
        time = np.asarray(g[TIME][()], dtype="f8")
        units = {k: _text_attr(v) for k, v in signal_units(g).items()}
        signals = {}
        for entity, obj in g[SIGNALS].items():
            if hasattr(obj, "dtype"):  # one compound dataset per entity: read it once, split the fields
                records = obj[()]
                signals.update({f"{entity}.{q}": np.ascontiguousarray(records[q], dtype="f8")
                                for q in records.dtype.names})
            else:
                signals.update({f"{entity}.{q}": np.asarray(ds[()], dtype="f8") for q, ds in obj.items()})
        attrs = {}
        for key, value in g.attrs.items():
            if isinstance(value, bytes):
                value = value.decode("utf-8", errors="replace")
            if isinstance(value, np.generic):
                value = value.item()
            if key in _JSON_ATTRS:
                try:
                    value = json.loads(value) if isinstance(value, str) and value else None
                except ValueError:
                    value = None
                if not isinstance(value, _JSON_ATTRS[key]):
                    value = _JSON_ATTRS[key]()
            attrs[key] = value
    return Results(time=time, signals=signals, units=units, attrs=attrs)


def _text_attr(value) -> str:
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return value if isinstance(value, str) else ""
