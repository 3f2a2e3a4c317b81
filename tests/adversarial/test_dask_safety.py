"""`mbs sweep --scheduler` against real `dask scheduler` / `dask worker` processes on loopback:
a relative model path with an include (the workers run elsewhere), every worker killed, the scheduler
killed.  Each ends with a clear message and no traceback, keeps the finished cases, and resumes."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest

pytest.importorskip("distributed")
pytestmark = pytest.mark.slow  # real scheduler and worker processes

ROOT = Path(__file__).resolve().parents[2]
MBS = str(Path(sys.executable).parent / "mbs")
LONG = ["-P", "speed=600rpm..1400rpm:4", "-n", "300", "--per-rev", "360", "-q", "--no-section", "--keep", "all"]


class Cluster:
    """A scheduler and a worker process group on 127.0.0.1, each killable on its own."""

    def __init__(self, tmp: Path):
        self.tmp = tmp
        self.procs: list[subprocess.Popen] = []
        sched_file = tmp / "scheduler.json"
        self.scheduler = self._start([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                      "--port", "0", "--dashboard-address", ":0", "--scheduler-file", str(sched_file)])
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        self.address = json.loads(sched_file.read_text())["address"]
        self.worker = None

    def _start(self, cmd):
        p = subprocess.Popen(cmd, cwd="/", stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             start_new_session=True)  # cwd "/": workers do not share the user's folder
        self.procs.append(p)
        return p

    def start_worker(self, n=1):
        from distributed import Client

        self.worker = self._start([sys.executable, "-m", "distributed.cli.dask_worker", self.address, "--nworkers",
                                   str(n), "--nthreads", "1", "--host", "127.0.0.1", "--dashboard-address", ":0"])
        with Client(self.address, timeout="30s") as client:
            client.wait_for_workers(n, timeout=60)

    @staticmethod
    def kill(p):
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        p.wait(timeout=30)

    def close(self):
        for p in reversed(self.procs):
            if p.poll() is None:
                self.kill(p)


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path)
    try:
        yield c
    finally:
        c.close()


def _stored(out: Path) -> int:
    try:
        with h5py.File(out, "r", locking=False) as f:
            return len(f["cases"]) if "cases" in f else 0
    except (OSError, KeyError):
        return 0


def _wait_stored(out: Path, proc, n=1, deadline=240) -> bool:
    end = time.time() + deadline
    while time.time() < end and proc.poll() is None:
        if _stored(out) >= n:
            return True
        time.sleep(0.3)
    return False


def _user_folder(tmp_path: Path) -> Path:
    """The user's folder: a model that includes another file, named relative to it."""
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(ROOT / "models" / "slider_crank.mbs", work / "base.mbs")
    (work / "m.mbs").write_text('include "base.mbs"\noverride param speed = 900 rpm\n')
    return work


def test_relative_model_path_with_an_include_runs_on_remote_workers(tmp_path, cluster):
    cluster.start_worker(2)
    work = _user_folder(tmp_path)
    r = subprocess.run([MBS, "sweep", "m.mbs", "-P", "speed=600rpm,900rpm", "-n", "3", "--per-rev", "36", "-q",
                        "--keep", "all", "-o", "s.h5", "--scheduler", cluster.address], cwd=work, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "2 case(s) run" in r.stdout and "Traceback" not in r.stdout + r.stderr
    with h5py.File(work / "s.h5", "r") as f:
        assert sorted(f["cases"]) == ["0", "1"]
        assert all(f[f"cases/{k}"].attrs["complete"] for k in f["cases"])
    # the same cases run locally give the same numbers (the model text sent is the model)
    local = subprocess.run([MBS, "sweep", "m.mbs", "-P", "speed=600rpm,900rpm", "-n", "3", "--per-rev", "36", "-q",
                            "--keep", "all", "-o", "local.h5", "-j", "1"], cwd=work, capture_output=True, text=True, timeout=300)
    assert local.returncode == 0, local.stderr
    with h5py.File(work / "s.h5", "r") as a, h5py.File(work / "local.h5", "r") as b:
        for k in ("0", "1"):
            assert (a[f"cases/{k}/signals/slider"]["vx"] == b[f"cases/{k}/signals/slider"]["vx"]).all()


def test_every_worker_dead_stops_the_sweep_with_a_message(tmp_path, cluster):
    cluster.start_worker(1)
    out = tmp_path / "s.h5"
    model = ROOT / "models" / "slider_crank.mbs"
    proc = subprocess.Popen([MBS, "sweep", str(model), *LONG, "-o", str(out), "--scheduler", cluster.address,
                             "--worker-timeout", "5"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_stored(out, proc), "no case stored before the workers were killed"
        cluster.kill(cluster.worker)
        stdout, stderr = proc.communicate(timeout=120)  # without the watch: waits forever
    finally:
        if proc.poll() is None:
            proc.kill()
    text = stdout + stderr
    assert proc.returncode == 3, text
    # the watch ("no dask worker for 5 s"), or dask itself failing the lost task first
    assert "Traceback" not in text and "dask" in text and "run the same command again to resume" in text
    kept = _stored(out)
    assert 1 <= kept < 4
    cluster.start_worker(1)  # workers back: the rerun computes only the missing cases
    r = subprocess.run([MBS, "sweep", str(model), *LONG, "-o", str(out), "--scheduler", cluster.address],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"{4 - kept} case(s) run, {kept} already in the file" in r.stdout


def test_a_cluster_without_workers_times_out_instead_of_waiting_forever(tmp_path, cluster):
    out = tmp_path / "s.h5"
    start = time.monotonic()
    r = subprocess.run([MBS, "sweep", str(ROOT / "models" / "slider_crank.mbs"), *LONG, "-o", str(out),
                        "--scheduler", cluster.address, "--worker-timeout", "3"], capture_output=True, text=True,
                       timeout=120)
    text = r.stdout + r.stderr
    assert r.returncode == 3, text
    assert "no dask worker for 3 s" in text and "Traceback" not in text
    assert time.monotonic() - start < 60  # a bound for the hang, not a speed claim
    with h5py.File(out, "r") as f:  # the file is a sweep file with its (empty) table: a rerun resumes it
        assert f.attrs["kind"] == "sweep" and "cases" not in f


def test_dead_scheduler_is_a_clear_error_and_the_sweep_resumes_locally(tmp_path, cluster):
    cluster.start_worker(1)
    out = tmp_path / "s.h5"
    model = ROOT / "models" / "slider_crank.mbs"
    proc = subprocess.Popen([MBS, "sweep", str(model), *LONG, "-o", str(out), "--scheduler", cluster.address,
                             "--worker-timeout", "5"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_stored(out, proc), "no case stored before the scheduler was killed"
        cluster.kill(cluster.scheduler)
        stdout, stderr = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
    text = stdout + stderr
    assert proc.returncode == 3, text
    assert "Traceback" not in text and "scheduler" in text and "resume" in text
    kept = _stored(out)
    assert 1 <= kept < 4
    r = subprocess.run([MBS, "sweep", str(model), *LONG, "-o", str(out), "-j", "1"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"{4 - kept} case(s) run, {kept} already in the file" in r.stdout
