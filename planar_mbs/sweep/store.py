"""The scan file of a sweep, kept whole through any kill: a journal of case files beside it,
gathered into the scan file by an atomic rename.

A finished case is written whole into a file of its own, ``.<scan>.cases/case-<k>.h5``, by the
process that ran it (a pool's worker, or the sweep's process for ``-j 1`` and for cases that come
back from a dask cluster): laid out under a temporary name, flushed to the disk, then renamed, so
the journal only ever holds whole cases.  The scan file itself is never changed in place:
`gather` copies it (bytes, not groups) beside itself, adds the journal's cases and the table of
cases, flushes the copy and renames it over the scan file, and only then deletes the journal's
case files.  A kill at any moment leaves the earlier scan file or the new one, and every finished
case either in it or in the journal; the next sweep on that output gathers the journal first.
The sweep gathers at its end and whenever the journal has grown as large as the scan file (so the
copying stays within twice the final size).

The table of cases (``/cases_table``) has fixed columns (index, key, status, message, verdict,
period, K, lyapunov, dimension, wall_time) and the swept parameters in groups of their own
(``params/<name>`` the value text, ``params_si/<name>`` its SI value): no parameter name can clash
with a column.
"""
from __future__ import annotations

import fcntl
import json
import os
import shutil
from pathlib import Path

import numpy as np

from ..errors import MbsError
from ..lazy import lazy
from ..results.hdf5 import WRITE_CHUNK_CACHE, ResultsBusy

h5py = lazy("h5py")

JOURNAL = ".cases"  # the folder .<scan name>.cases beside the scan file
OLD_PARTS = ".cases-"  # the temporary case folders of earlier versions: .<scan name>.cases-XXXX
TEXT_COLUMNS = ("key", "status", "message", "verdict")
NUMBER_COLUMNS = ("period", "K", "lyapunov", "dimension", "wall_time")
ROW_ATTR = "sweep_row"  # a case file's row of the table (JSON)


def journal_folder(output: str | Path) -> Path:
    output = Path(output)
    return output.parent / f".{output.name}{JOURNAL}"


class JournalLock:
    """Exclusive ownership of a scan for one sweep: a ``flock`` on ``.lock`` inside the journal
    folder (the scan file itself is replaced by renames, so a lock on it would not exclude anyone).
    The lock dies with the process; a lock file removed by the sweep that held it is taken again."""

    def __init__(self, output: Path):
        self.folder = journal_folder(output)
        self.output = None  # the scan file's own WriteLock, held by the sweep beside this one
        for _ in range(10):
            self.folder.mkdir(exist_ok=True)
            path = self.folder / ".lock"
            self.fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
            try:
                fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(self.fd)
                raise ResultsBusy(f"{output} is being written by another sweep") from None
            try:
                if os.stat(path).st_ino == os.fstat(self.fd).st_ino:  # not removed meanwhile
                    return
            except FileNotFoundError:
                pass
            os.close(self.fd)
        raise ResultsBusy(f"{output}: the lock of its journal keeps disappearing")

    def release(self, remove: bool = False) -> None:
        """Drop the lock; with ``remove``, the journal folder goes too when it holds no case."""
        if self.fd < 0:
            return
        if remove and not case_files(self.folder):
            shutil.rmtree(self.folder, ignore_errors=True)
        os.close(self.fd)
        self.fd = -1


def clean_leftovers(output: Path) -> None:
    """Remove what killed sweeps left on this output: half-written case files in the journal, a
    half-written copy of the scan file, the case folders of earlier versions (the caller holds
    the lock)."""
    folder = journal_folder(output)
    for p in [*folder.glob(".case-*.tmp"), *folder.glob(f".{PLAN}.*.tmp")]:
        p.unlink(missing_ok=True)
    for p in output.parent.glob(f".{output.name}.tmp-*"):
        p.unlink(missing_ok=True)
    for p in output.parent.glob(f".{output.name}{OLD_PARTS}*"):
        shutil.rmtree(p, ignore_errors=True)


def case_files(folder: Path) -> list[tuple[int, Path]]:
    """(index, path) of every whole case file in the journal, by index."""
    out = []
    for p in folder.glob("case-*.h5"):
        stem = p.name[len("case-"):-len(".h5")]
        if stem.isdigit():
            out.append((int(stem), p))
    return sorted(out)


def case_file_row(path: Path) -> dict | None:
    """The table row a case file carries, or None for a file that cannot be read."""
    try:
        with h5py.File(path, "r", locking=False) as f:
            return json.loads(f.attrs[ROW_ATTR])
    except (OSError, KeyError, ValueError):
        return None


def fsync_path(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def publish(tmp: Path, final: Path) -> None:
    """Flush ``tmp`` to the disk and rename it to ``final`` (the folder's entry flushed too)."""
    fsync_path(tmp)
    os.replace(tmp, final)
    fsync_path(final.parent)


def gather(output: Path, header: dict, rows: dict[str, dict], params: list[str], parameter_si,
           fresh: bool = False) -> int:
    """Write a new scan file: the old one (copied byte for byte; none if ``fresh``), plus the cases of
    the journal that ``rows`` lists, plus the table of ``rows`` and the root attributes ``header``;
    renamed into place, then those case files deleted.  Returns the new scan file's size.  A failure
    (a full disk, an interrupt) removes the copy and leaves the old scan file and the journal as
    they were."""
    folder = journal_folder(output)
    listed = {r["index"] for r in rows.values()}
    cases = [(i, p) for i, p in case_files(folder) if i in listed]
    tmp = output.with_name(f".{output.name}.tmp-{os.getpid()}")
    try:
        fresh = fresh or not output.exists() or output.stat().st_size == 0
        if not fresh:
            shutil.copyfile(output, tmp)
        with h5py.File(tmp, "w" if fresh else "r+", locking=False, rdcc_nbytes=WRITE_CHUNK_CACHE) as f:
            f.attrs.update(header)
            for index, path in cases:  # /cases appears with the first case
                if f"cases/{index}" in f:
                    del f[f"cases/{index}"]
                with h5py.File(path, "r", locking=False) as part:
                    f.copy(part[f"cases/{index}"], f"cases/{index}")
            write_table(f, list(rows.values()), params, parameter_si)
        publish(tmp, output)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    for _, path in cases:
        path.unlink(missing_ok=True)
    return output.stat().st_size


PLAN = "plan.json"  # the journal's record of every case's index, written before any case runs


def write_plan(folder: Path, plan: dict[str, int]) -> None:
    """Record ``{case key: index}`` in the journal (atomically), so that a sweep killed before its
    first gather numbers its cases the same way when it resumes, whichever of them had finished."""
    tmp = folder / f".{PLAN}.{os.getpid()}.tmp"
    tmp.write_text(json.dumps(plan))
    publish(tmp, folder / PLAN)


def read_plan(folder: Path) -> dict[str, int]:
    try:
        plan = json.loads((folder / PLAN).read_text())
    except (OSError, ValueError):
        return {}
    return {str(k): int(v) for k, v in plan.items()} if isinstance(plan, dict) else {}


# ---------------------------------------------------------------- the table of cases
def _text(v) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def write_table(f, rows: list[dict], params: list[str], parameter_si) -> None:
    """``/cases_table``: one row per case, by index (replaced if there); ``parameter_si`` gives the
    SI value of a parameter's text."""
    if "cases_table" in f:
        del f["cases_table"]
    t = f.create_group("cases_table")
    t.attrs["params"] = json.dumps(params)
    str_dt = h5py.string_dtype()
    rows = sorted(rows, key=lambda r: r["index"])
    t.create_dataset("index", data=np.array([r["index"] for r in rows], dtype=np.int64))
    for col in TEXT_COLUMNS:
        t.create_dataset(col, data=np.array([r.get(col, "") for r in rows], dtype=object), dtype=str_dt)
    texts, si = t.create_group("params"), t.create_group("params_si")
    for p in params:
        values = [r["values"].get(p, "") for r in rows]
        texts.create_dataset(p, data=np.array(values, dtype=object), dtype=str_dt)
        si.create_dataset(p, data=np.array([parameter_si(x) for x in values], dtype=float))
    for col in NUMBER_COLUMNS:
        vals = [r.get(col) for r in rows]
        t.create_dataset(col, data=np.array([np.nan if v is None else v for v in vals], dtype=float))


class DamagedTable(MbsError):
    """The table of cases of a scan file is not one this module wrote."""

    exit_code = 2


def table_rows(f, max_rows: int) -> list[dict]:
    """The rows of ``/cases_table`` (an older file's parameter columns beside the others are read too)."""
    if "cases_table" not in f:
        return []
    t = f["cases_table"]
    params = json.loads(t.attrs.get("params", "[]"))
    where = t["params"] if "params" in t and isinstance(t["params"], type(t)) else t
    columns = [t[c] for c in t if c not in ("params", "params_si")]
    columns += [where[p] for p in params]
    n = len(t["index"])
    if n > max_rows or any(len(c) != n for c in columns):  # a crafted table: never loop over 10^12 rows
        raise DamagedTable(f"{f.filename}: the table of cases is damaged ({n:,} rows, columns of unequal length)")
    data = {c: t[c][()] for c in t if c not in ("params", "params_si")}
    vals = {p: where[p][()] for p in params}
    rows = []
    for i in range(n):
        row = {"index": int(data["index"][i]), "values": {p: _text(vals[p][i]) for p in params}}
        for col in TEXT_COLUMNS:
            row[col] = _text(data[col][i]) if col in data else ""
        for col in NUMBER_COLUMNS:
            row[col] = float(data[col][i]) if col in data else float("nan")
        rows.append(row)
    return rows


# ---------------------------------------------------------------- summary statistics of a case
def signal_summary(results) -> dict[str, tuple[float, float, float]]:
    """(min, max, RMS) of every signal of a run, over all its samples (NaN for no samples)."""
    out = {}
    for name, values in results.signals.items():
        x = np.asarray(values, dtype=float)
        if x.size:
            out[name] = (float(np.min(x)), float(np.max(x)), float(np.sqrt(np.mean(x * x))))
        else:
            out[name] = (np.nan, np.nan, np.nan)
    return out


def write_summary(group, summary: dict[str, tuple[float, float, float]], units: dict[str, str]) -> None:
    """``<group>/summary``: datasets name, unit, min, max, rms, one entry per signal."""
    if "summary" in group:
        del group["summary"]
    g = group.create_group("summary")
    names = list(summary)
    str_dt = h5py.string_dtype()
    g.create_dataset("name", data=np.array(names, dtype=object), dtype=str_dt)
    g.create_dataset("unit", data=np.array([units.get(n, "") for n in names], dtype=object), dtype=str_dt)
    for i, col in enumerate(("min", "max", "rms")):
        g.create_dataset(col, data=np.array([summary[n][i] for n in names], dtype=float))


def read_summary(group) -> dict[str, tuple[float, float, float]]:
    """Inverse of `write_summary` (``group`` is a case's group); {} when the case has none."""
    if "summary" not in group:
        return {}
    g = group["summary"]
    names = [_text(n) for n in g["name"][()]]
    cols = [g[c][()] for c in ("min", "max", "rms")]
    return {n: (float(cols[0][i]), float(cols[1][i]), float(cols[2][i])) for i, n in enumerate(names)}
