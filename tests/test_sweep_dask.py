"""`mbs sweep --scheduler`: cases sent to a real dask.distributed scheduler and real
worker processes on loopback give the local run's results to the last bit."""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from planar_mbs.cli.app import app

pytest.importorskip("distributed")
pytestmark = pytest.mark.slow  # starts a scheduler and worker processes (~20 s)

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "slider_crank_clearance_a.mbs"
ARGS = ["-P", "speed=2500rpm,5000rpm", "-P", "law=hertz,flores", "--revolutions", "3", "--per-rev", "90", "-q",
        "--keep", "all"]


@pytest.fixture
def cluster(tmp_path):
    """`dask scheduler` and `dask worker` as subprocesses on 127.0.0.1; yields the address."""
    sched_file = tmp_path / "scheduler.json"
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [subprocess.Popen(dask + ["--host", "127.0.0.1", "--port", "0", "--dashboard-address", ":0",
                                      "--scheduler-file", str(sched_file)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nworkers", "2", "--nthreads", "1",
             "--host", "127.0.0.1", "--dashboard-address", ":0"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


def _cases(path):
    out = {}
    with h5py.File(path, "r") as f:
        for k, g in f["cases"].items():
            key = g.attrs["case_key"]
            out[key] = {f"{e}.{q}": g[f"signals/{e}"][q] for e, q in (("slider", "vx"), ("A", "contact_force"))}
            out[key]["time"] = g["time"][()]
    return out


def test_cluster_sweep_equals_local_sweep_bit_for_bit(tmp_path, cluster):
    runner = CliRunner()
    local = tmp_path / "local.h5"
    remote = tmp_path / "remote.h5"
    res = runner.invoke(app, ["sweep", str(MODEL), *ARGS, "-o", str(local), "--jobs", "1"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["sweep", str(MODEL), *ARGS, "-o", str(remote), "--scheduler", cluster])
    assert res.exit_code == 0, res.output
    assert "4 case(s) run" in res.output
    a, b = _cases(local), _cases(remote)
    assert sorted(a) == sorted(b) and len(a) == 4
    for key in a:
        for name in a[key]:
            np.testing.assert_array_equal(a[key][name], b[key][name])
    # resuming against the cluster runs nothing again
    res = runner.invoke(app, ["sweep", str(MODEL), *ARGS, "-o", str(remote), "--scheduler", cluster])
    assert res.exit_code == 0 and "0 case(s) run, 4 already in the file" in res.output


def test_unreachable_scheduler_is_a_clear_error(tmp_path):
    res = CliRunner().invoke(app, ["sweep", str(MODEL), *ARGS, "-o", str(tmp_path / "x.h5"),
                                   "--scheduler", "tcp://127.0.0.1:1"])
    assert res.exit_code == 2
    assert "cannot reach the dask scheduler" in res.output and "Traceback" not in res.output


STUDY = ["--sample", "clearance=uniform(0.1mm, 0.3mm)", "--sample", "speed=normal(3000rpm, 200rpm)",
         "--cases", "4", "--sampler", "sobol", "--random-state", "3", "--revolutions", "2", "--per-rev", "90",
         "-q", "--keep", "all"]


def test_a_sampled_study_on_the_cluster_draws_and_runs_the_local_cases(tmp_path, cluster):
    """The same random state gives the same cases, and the same results to the last bit, on one
    local process and on the cluster's workers (the design is drawn before any case runs)."""
    runner = CliRunner()
    local, remote = tmp_path / "local.h5", tmp_path / "remote.h5"
    res = runner.invoke(app, ["sweep", str(MODEL), *STUDY, "-o", str(local), "--jobs", "1"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["sweep", str(MODEL), *STUDY, "-o", str(remote), "--scheduler", cluster])
    assert res.exit_code == 0 and "4 case(s) run" in res.output, res.output
    a, b = _cases(local), _cases(remote)
    assert sorted(a) == sorted(b) and len(a) == 4
    for key in a:
        for name in a[key]:
            np.testing.assert_array_equal(a[key][name], b[key][name])
