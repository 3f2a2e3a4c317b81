"""`mbs sweep` on hostile ground: a model that is a pipe or a device, a file another sweep is writing,
a case whose mechanism cannot be assembled, a parent killed under its pool.  Each gets a clean answer
(exit code, a message, no traceback), loses no stored case, and hangs nowhere."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest

from planar_mbs.sweep.scan import read_case_table

ROOT = Path(__file__).resolve().parents[2]
IDEAL = ROOT / "models" / "slider_crank.mbs"
FOUR_BAR = ROOT / "models" / "four_bar.mbs"
MBS = str(Path(sys.executable).parent / "mbs")
HANG = 60  # s: far above the few seconds these take; reaching it means a hang


def _mbs(*args, timeout=HANG, **kw):
    return subprocess.run([MBS, *map(str, args)], capture_output=True, text=True, timeout=timeout, **kw)


def _clean(r, code):
    text = r.stdout + r.stderr
    assert r.returncode == code, text
    assert "Traceback" not in text
    return text


# ---------------------------------------------------------------- the model is not a regular file
@pytest.fixture
def fifo(tmp_path):
    path = tmp_path / "model.mbs"
    os.mkfifo(path)
    return path


def test_model_that_is_a_fifo_is_refused_without_reading(fifo, tmp_path):
    text = _clean(_mbs("sweep", fifo, "-P", "speed=600rpm", "-o", tmp_path / "s.h5", "-q"), 2)
    assert "not a regular file" in text
    assert not (tmp_path / "s.h5").exists()


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/null", "/dev/urandom"])
def test_model_that_is_a_device_is_refused(device, tmp_path):
    text = _clean(_mbs("sweep", device, "-P", "speed=600rpm", "-o", tmp_path / "s.h5", "-q"), 2)
    assert "not a regular file" in text


@pytest.mark.parametrize("target", ["fifo", "/dev/zero", "folder"])
def test_included_fifo_or_device_is_refused(target, tmp_path):
    if target == "fifo":
        os.mkfifo(tmp_path / "inc.mbs")
        target = "inc.mbs"
    elif target == "folder":
        (tmp_path / "dir.mbs").mkdir()
        target = "dir.mbs"
    model = tmp_path / "m.mbs"
    model.write_text(f'include "{target}"\n')
    text = _clean(_mbs("sweep", model, "-P", "speed=600rpm", "-o", tmp_path / "s.h5", "-q"), 2)
    assert "m.mbs:1:" in text


# ---------------------------------------------------------------- a case that cannot be assembled
def test_case_that_cannot_be_assembled_is_a_failed_case_and_the_sweep_goes_on(tmp_path):
    out = tmp_path / "s.h5"
    args = ["sweep", FOUR_BAR, "-P", "coupler=80mm,1mm,200mm,81mm", "-n", "2", "--per-rev", "36", "-j", "1",
            "--no-section", "-q", "-o", out, "--keep", "all"]
    text = _clean(_mbs(*args), 3)
    assert "2 failed" in text
    assert "case 1 (coupler=1mm) failed" in text and "cannot be assembled" in text
    rows = {r["values"]["coupler"]: r for r in read_case_table(out)}
    assert {k: r["status"] for k, r in rows.items()} == {"80mm": "finished", "1mm": "failed",
                                                         "200mm": "failed", "81mm": "finished"}
    # a 1 mm coupler cannot reach: the message names one of its two pins (which one is the end point of the
    # assembly's Newton iteration, and may differ in the last bits from one machine to another)
    assert re.search(r"joint `[AB]` stays open", rows["1mm"]["message"]) and "joint `O4`" in rows["200mm"]["message"]
    with h5py.File(out, "r") as f:
        assert f["cases/1"].attrs["sweep_status"] == "failed" and len(f["cases/1/time"]) == 0
        assert len(f["cases/0/time"]) > 0
    # resuming runs nothing again (a failed case would fail again), --retry-failed reruns only those
    assert "0 case(s) run, 4 already in the file" in _clean(_mbs(*args), 3)
    assert "2 case(s) run, 2 already in the file" in _clean(_mbs(*args, "--retry-failed"), 3)


def test_case_that_cannot_be_assembled_in_a_pool(tmp_path):
    out = tmp_path / "s.h5"
    text = _clean(_mbs("sweep", FOUR_BAR, "-P", "coupler=1mm,80mm", "-n", "2", "--per-rev", "36", "-j", "2",
                       "--no-section", "-q", "-o", out, timeout=180), 3)
    assert "1 failed" in text
    assert sorted(r["status"] for r in read_case_table(out)) == ["failed", "finished"]


# ---------------------------------------------------------------- two sweeps on one file
LONG = ["-P", "speed=600rpm..1400rpm:4", "-n", "400", "--per-rev", "360", "-j", "1", "-q", "--no-section",
        "--keep", "all"]


def _wait_for_case(out: Path, proc, deadline=120):
    end = time.time() + deadline
    while time.time() < end and proc.poll() is None:
        time.sleep(0.3)
        try:
            with h5py.File(out, "r", locking=False) as f:
                if "cases" in f and len(f["cases"]):
                    return True
        except (OSError, KeyError):
            pass
    return False


def test_a_second_sweep_on_a_file_being_written_is_refused_and_takes_nothing(tmp_path):
    out = tmp_path / "s.h5"
    first = subprocess.Popen([MBS, "sweep", str(IDEAL), *LONG, "-o", str(out)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_for_case(out, first), "the first sweep stored no case"
        second = _mbs("sweep", IDEAL, *LONG, "-o", out)
        text = _clean(second, 2)
        assert "being written by a sweep (mbs sweep, pid" in text
        stdout, stderr = first.communicate(timeout=600)
    finally:
        if first.poll() is None:
            first.kill()
    assert first.returncode == 0, stderr
    assert "4 case(s) run" in stdout
    rows = read_case_table(out)
    assert len(rows) == 4 and all(r["status"] == "finished" for r in rows)
    with h5py.File(out, "r") as f:
        assert sorted(f["cases"]) == ["0", "1", "2", "3"]


def test_library_sweep_refuses_a_locked_file_before_reading_it(tmp_path):
    from planar_mbs.results.hdf5 import WriteLock
    from planar_mbs.sweep.scan import SweepError, parse_param, run_sweep

    out = tmp_path / "s.h5"
    out.write_bytes(b"not yet an HDF5 file: a sweep that just took the lock")
    before = out.read_bytes()
    lock = WriteLock(out)
    try:
        with pytest.raises(SweepError, match="being written by another sweep"):
            run_sweep(IDEAL, [parse_param("speed=600rpm")], out, revolutions=2, per_rev=12, jobs=1)
    finally:
        lock.release()
    assert out.read_bytes() == before


# ---------------------------------------------------------------- the pool dies with its parent
def busy(p) -> bool:
    """A process that computes: a pool worker (the sweep's fork server and multiprocessing's
    resource tracker are its descendants too, but wait)."""
    import psutil

    try:
        return p.cpu_percent(interval=0.2) > 20
    except psutil.NoSuchProcess:
        return False


@pytest.mark.slow
def test_pool_workers_end_when_the_sweep_is_killed(tmp_path):
    import psutil

    out = tmp_path / "s.h5"
    proc = subprocess.Popen([MBS, "sweep", str(IDEAL), "-P", "speed=600rpm..1400rpm:4", "-n", "3000",
                             "--per-rev", "360", "-j", "2", "-q", "--no-section", "-o", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    parent = psutil.Process(proc.pid)
    workers = []
    end = time.time() + 120
    while time.time() < end:  # the pool's workers: busy descendants of the sweep
        busy_ones = [p for p in parent.children(recursive=True) if busy(p)]
        if len(busy_ones) >= 2:
            workers = busy_ones
            break
    assert len(workers) >= 2, "the pool never started"
    everyone = parent.children(recursive=True)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    gone, alive = psutil.wait_procs(everyone, timeout=20)
    for p in alive:
        p.kill()
    assert not alive, f"{len(alive)} process(es) outlived the killed sweep: {[p.cmdline() for p in alive]}"


# ---------------------------------------------------------------- a worker killed while it writes its case
def pool_workers(sweep) -> list:
    """The sweep's pool workers: its descendants that have no child of their own, other than
    multiprocessing's resource tracker (the fork server, when there is one, is their parent)."""
    import psutil

    out = []
    for p in sweep.children(recursive=True):
        try:
            if not p.children() and not any("resource_tracker" in a for a in p.cmdline()):
                out.append(p)
        except psutil.NoSuchProcess:
            pass
    return out


@pytest.mark.slow
def test_a_killed_pool_worker_stops_the_sweep_cleanly_and_it_resumes(tmp_path):
    """The pool's workers write their cases into files of their own beside the sweep file: one killed
    (as the kernel's OOM killer would) stops the sweep with exit 3 and a sentence, the sweep file stays
    readable with whole cases only, no case file is left behind, and the same command resumes."""
    import psutil

    out = tmp_path / "s.h5"
    cmd = [MBS, "sweep", str(IDEAL), "-P", "speed=600rpm..1400rpm:6", "-n", "300", "--per-rev", "360", "-j", "2",
           "-q", "--no-section", "--keep", "all", "-o", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_for_case(out, proc), "the sweep stored no case"
        workers = pool_workers(psutil.Process(proc.pid))
        assert workers, "no pool worker"
        os.kill(workers[0].pid, signal.SIGKILL)
        stdout, stderr = proc.communicate(timeout=HANG)
    finally:
        if proc.poll() is None:
            proc.kill()
    text = stdout + stderr
    assert proc.returncode == 3, text
    assert "Traceback" not in text and "worker process of the sweep died" in text and "resume" in text
    with h5py.File(out, "r") as f:  # HDF5 reads it; every stored case is whole
        assert "incoming" not in f or not len(f["incoming"])
        kept = sorted(f["cases"])
        for k in kept:
            g = f[f"cases/{k}"]
            assert g.attrs["sweep_status"] == "finished"
            assert g["time"].shape == g["signals/slider"].shape and g["time"].shape[0] > 0
    assert 0 < len(kept) < 6
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]  # no folder of case files left
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert f"{6 - len(kept)} case(s) run, {len(kept)} already in the file" in again.stdout
    assert all(r["status"] == "finished" for r in read_case_table(out))
