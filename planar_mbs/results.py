"""Results of a run: named signals in memory and in one HDF5 file.

File layout::

    /time                         (n,)  s
    /signals/<entity>/<quantity>  (n,)  attribute `unit`
    attributes of /: model_source, model_path, parameters (JSON), version,
        complete (bool), status, message, wall_time, n_steps, n_rejected,
        n_rhs, n_contact_events, n_outputs, settings (JSON)

`ResultsWriter` appends chunks while the run goes and flushes after each, so a
crash or Ctrl-C keeps what was computed.  h5py is imported only here.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .signals import Signal


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
            from .errors import did_you_mean

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
    import h5py

    if not isinstance(target, (h5py.File, h5py.Group)):
        with h5py.File(target, "a") as f:
            return write_results(f, results, group, compression)
    name = group.strip("/")
    if name and name in target:
        del target[name]
    g = target.require_group(name) if name else target
    opts = dict(compression=compression) if compression else {}
    n = len(results.time)
    chunks = dict(chunks=(min(max(n, 1), ResultsWriter.CHUNK),)) if opts else {}
    ds = g.create_dataset("time", data=np.asarray(results.time, "f8"), **opts, **chunks)
    ds.attrs["unit"] = "s"
    for sig, values in results.signals.items():
        entity, qty = sig.rsplit(".", 1)
        ds = g.create_dataset(f"signals/{entity}/{qty}", data=np.asarray(values, "f8"), **opts, **chunks)
        ds.attrs["unit"] = results.units.get(sig, "")
    set_attrs(g, results.attrs)


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
        import fcntl
        import os

        self.fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            raise ResultsBusy(f"{path} is being written by another process") from None

    def release(self) -> None:
        import os

        if self.fd >= 0:
            os.close(self.fd)  # closing the descriptor drops the flock
            self.fd = -1


def open_for_writing(path: Path, mode: str):
    """(h5py.File, WriteLock) for a writer; raises `ResultsBusy` or OSError."""
    import h5py

    lock = WriteLock(path)
    try:
        return h5py.File(path, mode, locking=False), lock
    except BaseException:
        lock.release()
        raise


class ResultsWriter:
    """Appends observation chunks to an HDF5 file as the run goes."""

    CHUNK = 4096

    def __init__(self, path: str | Path, table: list[Signal], attrs: dict, group: str = "/", mode: str = "w"):
        """``group`` places the run inside a file (``"/cases/3"`` of a sweep); ``mode`` is the
        h5py mode (``"w"`` truncates the file, ``"a"`` adds the group to an existing file; an
        existing group of that name is replaced)."""
        import h5py

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.table = table
        try:
            self.file, self.lock = open_for_writing(self.path, mode)
        except (OSError, ResultsBusy) as exc:
            from .errors import MbsError

            err = MbsError(f"cannot write {self.path}: {exc}")
            err.exit_code = 2
            raise err from None
        if group.strip("/") and group.strip("/") in self.file:
            del self.file[group.strip("/")]
        self.group = self.file.require_group(group) if group.strip("/") else self.file
        self.n = 0
        opts = dict(shape=(0,), maxshape=(None,), dtype="f8", chunks=(self.CHUNK,))
        self.time = self.group.create_dataset("time", **opts)
        self.time.attrs["unit"] = "s"
        self.datasets = []
        for sig in table:
            ds = self.group.create_dataset(f"signals/{sig.entity}/{sig.quantity}", **opts)
            ds.attrs["unit"] = sig.unit
            self.datasets.append(ds)
        self.set_attrs(dict(attrs, complete=False, status="running"))
        self.file.flush()

    def set_attrs(self, attrs: dict) -> None:
        set_attrs(self.group, attrs)

    def append(self, t: np.ndarray, rows: np.ndarray) -> None:
        n = len(t)
        if n == 0:
            return
        end = self.n + n
        self.time.resize((end,))
        self.time[self.n:end] = t
        for sig, ds in zip(self.table, self.datasets):
            ds.resize((end,))
            ds[self.n:end] = sig.extract(rows)
        self.n = end
        self.file.flush()

    def close(self, attrs: dict | None = None) -> None:
        if attrs:
            self.set_attrs(attrs)
        self.file.close()
        self.lock.release()


def read_results(path: str | Path) -> Results:
    """Load a run written by `ResultsWriter` (or one case of a sweep file: `file.h5:/cases/3`)."""
    import h5py

    path = str(path)
    group = "/"
    if ":/" in path:
        path, group = path.split(":", 1)
    with h5py.File(path, "r") as f:
        g = f[group]
        time = g["time"][()]
        signals, units = {}, {}
        for entity, grp in g["signals"].items():
            for qty, ds in grp.items():
                signals[f"{entity}.{qty}"] = ds[()]
                units[f"{entity}.{qty}"] = ds.attrs.get("unit", "")
        attrs = {}
        for key, value in g.attrs.items():
            if isinstance(value, bytes):
                value = value.decode()
            if isinstance(value, np.generic):
                value = value.item()
            if key in ("parameters", "settings", "warnings") and isinstance(value, str) and value:
                value = json.loads(value)
            attrs[key] = value
    return Results(time=time, signals=signals, units=units, attrs=attrs)
