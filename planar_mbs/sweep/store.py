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

import hashlib
import hmac
import json
import os
import secrets
import shutil
import stat
from pathlib import Path

import numpy as np

from ..errors import MbsError
from ..files import replace_atomically
from ..lazy import lazy
from ..results.hdf5 import WRITE_CHUNK_CACHE
from ..results.output_lock import OutputLock

h5py = lazy("h5py")

JOURNAL = ".cases"  # the folder .<scan name>.cases beside the scan file
OLD_PARTS = ".cases-"  # the temporary case folders of earlier versions: .<scan name>.cases-XXXX
TEXT_COLUMNS = ("key", "status", "message", "verdict")
NUMBER_COLUMNS = ("period", "K", "lyapunov", "dimension", "wall_time")
ROW_ATTR = "sweep_row"  # a case file's row of the table (JSON)


def journal_folder(output: str | Path) -> Path:
    output = Path(output)
    return output.parent / f".{output.name}{JOURNAL}"


class UnsafeJournal(MbsError):
    """The journal folder, or a case file in it, is not one this sweep made."""

    exit_code = 2


class JournalLock:
    """Exclusive ownership of a scan for one sweep: the output's `OutputLock` (no run, merge or
    other sweep writes the name meanwhile), then its journal folder, private (`private_folder`),
    and the key its case files are signed with (`journal_key`)."""

    def __init__(self, output: Path):
        self.folder = journal_folder(output)
        self.output = None  # the scan file's own WriteLock, held by the sweep beside this one
        self.beside = OutputLock(output, "a sweep")  # OutputBusy, or OSError: the caller says so
        try:
            private_folder(self.folder, output)
            self.key = journal_key(self.folder)
        except BaseException:
            self.beside.release()
            raise

    def release(self, remove: bool = False) -> None:
        """Drop the lock; with ``remove``, the journal folder goes too when it holds no case."""
        if self.beside is None:
            return
        if remove and not case_files(self.folder):
            shutil.rmtree(self.folder, ignore_errors=True)
        self.beside.release()
        self.beside = None


def private_folder(folder: Path, output: Path) -> None:
    """Make ``folder`` with mode 0700, or take the one there only if it is a real folder of this
    user that nobody else can write in (its mode then narrowed to 0700); `UnsafeJournal` if not."""
    try:
        os.mkdir(folder, 0o700)
        return
    except FileExistsError:
        pass
    why = ""
    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
    except OSError:
        why = "is a symbolic link" if os.path.islink(folder) else "is not a folder"
    else:
        try:
            info = os.fstat(fd)
            if info.st_uid != os.geteuid():
                why = "belongs to another user"
            elif info.st_mode & 0o022:
                why = "can be written by other users"
            else:
                os.fchmod(fd, 0o700)
        finally:
            os.close(fd)
    if why:
        raise UnsafeJournal(f"{folder}, the journal folder of {output}, {why}: a sweep keeps its cases only in "
                            "a folder of its own; remove it (after checking what it holds) or choose another -o")


KEY = "key"  # the journal's file of the key its case files are signed with
MAC_ATTR = "sweep_mac"  # a case file's signature: HMAC-SHA256 of all else it holds (`case_mac`)


def journal_key(folder: Path) -> bytes:
    """The key of the journal ``folder`` (made, 32 random bytes in a file of mode 0600, if none)."""
    path = folder / KEY
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    except FileExistsError:
        return read_key(folder)
    try:
        os.write(fd, secrets.token_hex(32).encode())
        os.fsync(fd)
    finally:
        os.close(fd)
    return read_key(folder)


def read_key(folder: Path) -> bytes:
    """The journal's key, or b"" when it has none that can be read (no case is then taken)."""
    try:
        fd = os.open(folder / KEY, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        try:
            return os.read(fd, 64) if stat.S_ISREG(os.fstat(fd).st_mode) else b""
        finally:
            os.close(fd)
    except OSError:
        return b""


def case_mac(f, key: bytes) -> str:
    """HMAC-SHA256 under ``key`` of an open case file: every link, attribute and dataset but the MAC."""
    h = hmac.new(key, digestmod=hashlib.sha256)

    def put(data: bytes) -> None:
        h.update(len(data).to_bytes(8, "little") + data)

    def attrs(obj) -> None:
        for name in sorted(obj.attrs):
            if name != MAC_ATTR:
                put(name.encode())
                put(_bytes(obj.attrs[name]))

    attrs(f)
    names: list[str] = []
    f.visit_links(names.append)
    for name in sorted(names):
        put(name.encode())
        link = f.get(name, getlink=True)
        if not isinstance(link, h5py.HardLink):
            put(repr((type(link).__name__, getattr(link, "filename", ""), link.path)).encode())
            continue
        obj = f[name]
        attrs(obj)
        if isinstance(obj, h5py.Dataset):
            put(repr((obj.dtype.descr, obj.shape)).encode())
            for i in range(0, obj.shape[0] if obj.shape else 1, 1 << 16):
                put(_bytes(obj[i:i + (1 << 16)] if obj.shape else obj[()]))
    return h.hexdigest()


def _bytes(value) -> bytes:
    if isinstance(value, bytes):
        return value
    if isinstance(value, str):
        return value.encode()
    a = np.asarray(value)
    if a.dtype.kind != "O":
        return repr((a.dtype.descr, a.shape)).encode() + a.tobytes()
    parts = [_bytes(x) if isinstance(x, (str, bytes, np.ndarray)) else repr(x).encode() for x in a.ravel()]
    return b"".join(len(x).to_bytes(8, "little") + x for x in parts)


def sign_case(f, key: bytes) -> None:
    """Store the MAC of an open case file (written last: it covers everything else)."""
    f.attrs[MAC_ATTR] = case_mac(f, key)


def signed(path: Path, key: bytes) -> bool:
    """Whether the case file ``path`` carries a MAC under ``key`` that matches what it holds."""
    if not key:
        return False
    try:
        with h5py.File(path, "r", locking=False) as f:
            mac = f.attrs.get(MAC_ATTR, "")
            return isinstance(mac, str) and hmac.compare_digest(mac, case_mac(f, key))
    except (OSError, KeyError, ValueError, RuntimeError):
        return False


def clean_leftovers(output: Path) -> None:
    """Remove what killed sweeps left on this output: half-written case files in the journal, a
    half-written copy of the scan file, the case folders of earlier versions (the caller holds
    the lock)."""
    folder = journal_folder(output)
    for p in [*folder.glob(".case-*.tmp"), *folder.glob(f".{PLAN}.*.tmp")]:
        p.unlink(missing_ok=True)
    clean_stale_copies(output)
    for p in output.parent.glob(f".{output.name}{OLD_PARTS}*"):
        shutil.rmtree(p, ignore_errors=True)


def clean_stale_copies(output: Path) -> None:
    """Remove the half-written copies ``.<name>.tmp-<pid>`` of ``output`` that processes now
    dead left (a killed sweep or merge); those of a live process, or another user's, stay."""
    for p in output.parent.glob(f".{output.name}.tmp-*"):
        pid = p.name.rsplit("-", 1)[1]
        try:
            mine = os.lstat(p).st_uid == os.geteuid()
        except OSError:
            continue
        if mine and (not pid.isdigit() or not _alive(int(pid))):
            p.unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return pid != 0


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


def publish(tmp: Path, final: Path) -> None:
    """Flush ``tmp`` to the disk and rename it to ``final`` (the folder's entry flushed too)."""
    replace_atomically(tmp, final, durable=True)


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
