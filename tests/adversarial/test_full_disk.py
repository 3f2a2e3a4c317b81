"""A disk that fills up during `mbs run` or `mbs sweep`: a clean stop (exit 3, a message naming the
full disk, no traceback), and a results file that HDF5 still reads, holding exactly the rows computed
before the stop (checked against the same run kept in memory), and a sweep that resumes once there
is room again.

The disk is a real size-limited tmpfs mounted for the test (we run as root in CI); where mounting is
not permitted, the same checks run with the disk-space reservation made to fail instead (ENOSPC
injected at the write, as the disk would)."""
from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from planar_mbs.sweep.scan import read_case_table

ROOT = Path(__file__).resolve().parents[2]
MODEL = ROOT / "models" / "slider_crank_clearance_a.mbs"
MBS = [str(Path(sys.executable).parent / "mbs")]


@contextlib.contextmanager
def small_disk(where: Path, size: str):
    """A tmpfs of `size` mounted at `where`; yields False (nothing mounted) where that is not allowed."""
    where.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        yield False
        return
    try:
        yield True
    finally:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)


def _mbs(*args, cwd=None, env=None, timeout=600):
    return subprocess.run([*MBS, *map(str, args)], capture_output=True, text=True, cwd=cwd, env=env,
                          timeout=timeout)


def _inject_env(tmp_path: Path, budget: int) -> dict:
    """Environment for the fallback without mount: a sitecustomize that makes `reserve_space` fail with
    ENOSPC once the bytes reserved so far would pass `budget`, as a disk of that size would."""
    site = tmp_path / "site"
    site.mkdir(exist_ok=True)
    (site / "sitecustomize.py").write_text(
        "import planar_mbs.results.hdf5 as R\n"
        "_orig, _used = R.reserve_space, [0]\n"
        "def _disk(fd, nbytes, path=''):\n"
        f"    if _used[0] + nbytes > {budget}:\n"
        "        raise R.DiskFull(f'the disk holding {path} is full: injected ENOSPC')\n"
        "    _used[0] += nbytes\n"
        "    return _orig(fd, nbytes, path)\n"
        "R.reserve_space = _disk\n")
    return {**os.environ, "PYTHONPATH": f"{site}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}


def test_run_stops_cleanly_and_keeps_a_readable_prefix(tmp_path):
    from planar_mbs import load_model, simulate

    disk = tmp_path / "disk"
    with small_disk(disk, "4m") as mounted:
        env = None if mounted else _inject_env(tmp_path, 4 << 20)
        out = disk / "a.h5"
        r = _mbs("run", MODEL, "-o", out, "--t-end", "0.2s", "-q", "--force", env=env)
        assert r.returncode == 3, r.stdout + r.stderr
        text = r.stdout + r.stderr
        assert "Traceback" not in text
        assert "is full" in text and "kept in" in text
        with h5py.File(out, "r") as f:  # HDF5 reads it: every dataset has the same number of rows
            t = f["time"][()]
            assert f.attrs["complete"] == False  # noqa: E712  (numpy bool)
            vx = f["signals/slider"]["vx"]
            force = f["signals/A"]["contact_force"]
            lengths = {f[f"signals/{e}"].shape[0] for e in f["signals"]}
            assert lengths == {len(t)}
    assert 0 < len(t) < 20001  # some rows, not all of them
    ref = simulate(load_model(MODEL), t_end=0.2)  # the same run, in memory
    np.testing.assert_array_equal(t, ref.time[:len(t)])
    np.testing.assert_array_equal(vx, ref["slider.vx"][:len(t)])
    np.testing.assert_array_equal(force, ref["A.contact_force"][:len(t)])


def test_full_disk_before_the_first_row_is_a_clean_error(tmp_path):
    disk = tmp_path / "disk"
    with small_disk(disk, "64k") as mounted:
        env = None if mounted else _inject_env(tmp_path, 64 << 10)
        r = _mbs("run", MODEL, "-o", disk / "a.h5", "--t-end", "0.01s", "-q", "--force", env=env)
        assert r.returncode in (2, 3), r.stdout + r.stderr
        assert "Traceback" not in r.stdout + r.stderr


SWEEP = ["-P", "speed=2500rpm,5000rpm,1200rpm,800rpm", "--revolutions", "2", "--per-rev", "180", "-j", "1",
         "--no-section", "-q", "--keep", "all"]


def test_sweep_stops_cleanly_keeps_finished_cases_and_resumes(tmp_path):
    disk = tmp_path / "disk"
    with small_disk(disk, "1200k") as mounted:
        env = None if mounted else _inject_env(tmp_path, 1200 << 10)
        out = disk / "s.h5"
        r = _mbs("sweep", MODEL, *SWEEP, "-o", out, "--force", env=env)
        text = r.stdout + r.stderr
        assert r.returncode == 3, text
        assert "Traceback" not in text and "full" in text
        with h5py.File(out, "r") as f:
            done = sorted(f["cases"]) if "cases" in f else []
            status = [s.decode() if isinstance(s, bytes) else s for s in f["cases_table/status"][()]]
            for k in done:
                g = f[f"cases/{k}"]
                assert g["time"].shape == g["signals/slider"].shape and g["time"].shape[0] > 0
        assert 0 < len(done) < 4 and status.count("finished") == len(done)
        if mounted:  # room again: the same file on a bigger disk resumes the missing cases only
            big = tmp_path / "big.h5"
            big.write_bytes(out.read_bytes())
        else:
            big = out
    r = _mbs("sweep", MODEL, *SWEEP, "-o", big)
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"{4 - len(done)} case(s) run, {len(done)} already in the file" in r.stdout
    with h5py.File(big, "r") as f:
        assert len(f["cases"]) == 4


@pytest.mark.parametrize("size", ["400k", "600k"])  # full at the first case / after some cases
def test_parallel_sweep_on_a_full_disk_stops_cleanly_and_resumes(tmp_path, size):
    """With a pool, the workers write their cases into files of their own on the same disk: the disk
    that fills under a worker's file stops the sweep as it does under the sweep file (exit 3, the
    disk named, whole cases only: in the sweep file or in its journal beside it, no half-written
    file), and the sweep resumes with room."""
    disk = tmp_path / "disk"
    args = ["-P", "speed=2500rpm,5000rpm,1200rpm,800rpm", "--revolutions", "2", "--per-rev", "180", "-j", "2",
            "--no-section", "-q", "--keep", "all"]
    with small_disk(disk, size) as mounted:
        if not mounted:
            pytest.skip("needs a size-limited tmpfs (mount): the workers' files are not reserved")
        out = disk / "s.h5"
        r = _mbs("sweep", MODEL, *args, "-o", out, "--force")
        text = r.stdout + r.stderr
        assert r.returncode == 3, text
        assert "Traceback" not in text and "is full" in text and "resume" in text, text
        from planar_mbs.sweep.store import case_files, journal_folder

        done = [r for r in read_case_table(out) if r["status"] == "finished"]
        with h5py.File(out, "r") as f:
            for k in (f["cases"] if "cases" in f else []):
                g = f[f"cases/{k}"]
                assert g["time"].shape == g["signals/slider"].shape and g["time"].shape[0] > 0
        for _, part in case_files(journal_folder(out)):
            with h5py.File(part, "r") as f:  # whole
                assert len(f["cases"]) == 1
        assert len(done) < 4
        assert set(p.name for p in disk.iterdir()) <= {"s.h5", ".s.h5.cases"}
        assert not list(journal_folder(out).glob(".case-*"))  # no half-written case
        big = tmp_path / "big.h5"
        big.write_bytes(out.read_bytes())
        if journal_folder(out).exists():
            shutil.copytree(journal_folder(out), journal_folder(big))
    r = _mbs("sweep", MODEL, *args, "-o", big)
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"{4 - len(done)} case(s) run, {len(done)} already in the file" in r.stdout


def _runs(*runs: tuple[Path, str]) -> None:
    """`mbs run` of the model into each results file for its simulated time."""
    for results, t_end in runs:
        results.parent.mkdir(exist_ok=True)
        r = _mbs("run", MODEL, "-o", results, "--t-end", t_end, "-q")
        assert r.returncode == 0, r.stderr


def _fill(disk: Path) -> Path:
    """Take every byte left on the disk mounted at `disk` with a file of its own; returns that file."""
    filler = disk / "filler"
    with open(filler, "wb", buffering=0) as f:
        with contextlib.suppress(OSError):
            while True:
                f.write(b"\0" * 4096)
    return filler


def test_a_figure_is_never_left_half_written(tmp_path):
    """`mbs plot` over the figures of an earlier call, with larger figures of a longer run, on a disk
    that is now full: a clean error, and every earlier figure still whole, byte for byte (written in
    place, they were truncated and then half rewritten), with no temporary file left beside them."""
    short, long = tmp_path / "short" / "a.h5", tmp_path / "long" / "a.h5"  # the same stem: the same figure names
    _runs((short, "0.01s"), (long, "0.1s"))
    disk = tmp_path / "disk"
    with small_disk(disk, "2m") as mounted:
        if not mounted:
            pytest.skip("no tmpfs can be mounted here, and a figure's write cannot be made to fail otherwise")
        first = _mbs("plot", short, "-o", disk)
        assert first.returncode == 0, first.stderr
        figures = {p.name: p.read_bytes() for p in disk.iterdir()}
        assert figures and all(data.startswith(b"\x89PNG") for data in figures.values())
        filler = _fill(disk)
        again = _mbs("plot", long, "-o", disk)
        assert again.returncode == 2, again.stdout + again.stderr
        assert "No space left on device" in again.stderr and "Traceback" not in again.stdout + again.stderr
        assert {p.name: p.read_bytes() for p in disk.iterdir() if p != filler} == figures


def test_a_rerun_recording_is_never_left_half_written(tmp_path):
    """`mbs view` over an earlier recording on a disk with too little room for the new one: exit 2
    with a message naming the recording and the full disk, the earlier recording byte for byte (rerun
    wrote in place, only logged its failed write, and the command reported the recording as written),
    and no temporary file left."""
    short, long = tmp_path / "short.h5", tmp_path / "long.h5"
    _runs((short, "0.002s"), (long, "0.2s"))
    disk = tmp_path / "disk"
    with small_disk(disk, "1m") as mounted:
        if not mounted:
            pytest.skip("no tmpfs can be mounted here, and rerun's write cannot be made to fail otherwise")
        first = _mbs("view", short, "-o", disk / "v.rrd")
        assert first.returncode == 0, first.stderr
        before = (disk / "v.rrd").read_bytes()
        again = _mbs("view", long, "-o", disk / "v.rrd", "--force")  # about 4 MB; a recording of other results
        assert again.returncode == 2, again.stdout + again.stderr
        assert f"cannot write the rerun recording {disk / 'v.rrd'}" in again.stderr, again.stderr
        assert "Traceback" not in again.stdout + again.stderr and "rerun recording →" not in again.stdout
        assert [p.name for p in disk.iterdir()] == ["v.rrd"]
        assert (disk / "v.rrd").read_bytes() == before


def test_analyze_store_on_a_full_disk_leaves_the_results_file_as_it_was(tmp_path):
    """`mbs analyze --store` with no room left for the section: exit 3 and a message naming the full
    disk, the results file byte for byte as before (HDF5 failing its writes halfway used to print
    tracebacks, an "internal error", and crash the process with a segmentation fault); once there
    is room, the same command stores the section, which reads back."""
    from planar_mbs.results.analysis import read_section

    disk = tmp_path / "disk"
    with small_disk(disk, "6m") as mounted:
        if not mounted:
            pytest.skip("no tmpfs can be mounted here")
        out = disk / "a.h5"
        _runs((out, "0.05s"))
        before = out.read_bytes()
        filler = _fill(disk)
        full = _mbs("analyze", out, "--store")
        assert full.returncode == 3, full.stdout + full.stderr
        assert "is full" in full.stderr and "Traceback" not in full.stdout + full.stderr
        assert out.read_bytes() == before
        filler.unlink()
        room = _mbs("analyze", out, "--store")
        assert room.returncode == 0, room.stdout + room.stderr
        with h5py.File(out, "r") as f:
            sec, verdict = read_section(f)
            assert len(sec.time) > 0 and verdict is not None
