"""The fork server that `mbs sweep` starts at its first line (planar_mbs/sweep/server.py): when it
starts, and that a sweep run through it stores what a sweep in one process stores."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from planar_mbs.sweep.server import wanted

ROOT = Path(__file__).resolve().parents[1]
IDEAL = str(ROOT / "models" / "slider_crank.mbs")


@pytest.mark.parametrize("argv, cores, expected", [
    (["m.mbs", "-P", "speed=1rpm,2rpm", "-o", "s.h5"], 2, True),  # --jobs defaults to the cores
    (["m.mbs", "-P", "speed=1rpm,2rpm", "-o", "s.h5"], 1, False),
    (["m.mbs", "-P", "speed=1rpm,2rpm", "-o", "s.h5"], None, False),
    (["m.mbs", "-j", "2"], 1, True),
    (["m.mbs", "-j", "1"], 8, False),
    (["m.mbs", "-j1"], 8, False),
    (["m.mbs", "-j4"], 1, True),
    (["m.mbs", "--jobs=1"], 8, False),
    (["m.mbs", "--jobs", "3"], 1, True),
    (["m.mbs", "--jobs", "many"], 8, False),  # typer refuses it; no server for a usage error
    (["m.mbs", "-j", "2", "--help"], 8, False),
    (["m.mbs", "-j", "2", "--scheduler", "tcp://h:8786"], 8, False),  # dask's workers, not ours
    (["m.mbs", "-j", "2", "--scheduler=tcp://h:8786"], 8, False),
])
def test_the_server_starts_only_for_a_local_pool(argv, cores, expected):
    assert wanted(argv, cores) is expected


SWEEP = ("import os, sys\n_exit = os._exit\n"
         "def mark(how):\n    print(how, 'NUMBA' if 'numba' in sys.modules else 'NO NUMBA', file=sys.stderr, flush=True)\n"
         "os._exit = lambda c: (mark('at once'), _exit(c))\n"
         "sys.argv = {argv!r}\nfrom planar_mbs.cli.entry import main\n"
         "try:\n    main()\nexcept SystemExit as e:\n    mark('teardown')\n    sys.exit(e.code)\n")


def _sweep(out: Path, jobs: str):
    argv = ["mbs", "sweep", IDEAL, "-P", "speed=800rpm..1600rpm:3", "-n", "4", "--per-rev", "90", "-j", jobs,
            "--keep", "all",
            "-q", "-o", str(out)]
    return subprocess.run([sys.executable, "-c", SWEEP.format(argv=argv)], capture_output=True, text=True,
                          timeout=600, cwd=ROOT)


def test_a_pool_sweep_leaves_the_kernels_to_its_server_and_stores_what_one_process_stores(tmp_path):
    """With two jobs the sweep's own process never imports numba (its workers are forks of the
    server, which loaded it) and ends without the interpreter's teardown; its cases are bit for
    bit those of a one-process sweep."""
    pool, alone = _sweep(tmp_path / "pool.h5", "2"), _sweep(tmp_path / "alone.h5", "1")
    assert pool.returncode == 0 and alone.returncode == 0, pool.stderr + alone.stderr
    assert pool.stderr == "at once NO NUMBA\n", pool.stderr  # files closed: no 0.2 s teardown either
    assert alone.stderr == "at once NUMBA\n", alone.stderr  # it ran its cases itself
    with h5py.File(tmp_path / "pool.h5", "r") as a, h5py.File(tmp_path / "alone.h5", "r") as b:
        assert sorted(a["cases"]) == sorted(b["cases"]) == ["0", "1", "2"]
        for k in a["cases"]:
            ga, gb = a[f"cases/{k}"], b[f"cases/{k}"]
            assert np.array_equal(ga["time"][()], gb["time"][()])
            for name in gb["signals"]:
                assert np.array_equal(ga[f"signals/{name}"][()], gb[f"signals/{name}"][()]), (k, name)


def test_a_server_still_loading_ends_with_a_sweep_that_stopped_at_a_usage_error(tmp_path):
    """With a cold numba cache the server compiles the kernels for a minute; a sweep that ends at
    once (here an unknown option, exit 2) must not leave it running (it would also hold the sweep's
    stdout and stderr open: `$(mbs sweep ...)` would wait for it).  Every process started is tagged
    through its environment and looked up by that tag."""
    import os
    import time
    import uuid

    import psutil

    tag = uuid.uuid4().hex
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cold-cache"), MBS_TEST_TAG=tag)
    mbs = Path(sys.executable).with_name("mbs")
    with open(tmp_path / "stderr", "w") as err:  # a file, not a pipe: whoever holds it open cannot delay us
        code = subprocess.run([str(mbs), "sweep", IDEAL, "-P", "speed=800rpm,900rpm", "-j", "2", "-o",
                               str(tmp_path / "s.h5"), "--no-such-option"], env=env, stdout=subprocess.DEVNULL,
                              stderr=err, timeout=120).returncode
    assert code == 2, (tmp_path / "stderr").read_text()

    def tagged():
        out = []
        for p in psutil.process_iter():
            try:
                if p.environ().get("MBS_TEST_TAG") == tag:
                    out.append(p)
            except (psutil.NoSuchProcess, psutil.AccessDenied, psutil.ZombieProcess):
                pass
        return out

    deadline = time.time() + 10  # the kernels' compilation alone takes longer than this
    while tagged() and time.time() < deadline:
        time.sleep(0.2)
    left = tagged()
    for p in left:
        p.kill()
    assert not left, [p.cmdline() for p in left]


@pytest.mark.slow
@pytest.mark.parametrize("signame, group, code", [("SIGINT", True, 130), ("SIGTERM", True, 143), ("SIGTERM", False, 143)],
                         ids=["Ctrl-C", "SIGTERM to the group", "SIGTERM to the sweep"])
def test_an_interrupted_pool_sweep_says_one_sentence_and_leaves_nothing(tmp_path, signame, group, code):
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it), SIGTERM to the group (a
    batch system ending a job) or to the sweep alone (`kill PID`) during a pool sweep: exit 128 +
    the signal, the sentence that says how to resume and nothing else on stderr (multiprocessing's
    resource tracker would add a warning about the pool's semaphores, which it unlinks), no process
    of the sweep left, and no file beside the sweep's own (SIGTERM used to leave the folder of the
    workers' case files)."""
    import os
    import signal
    import time

    import psutil

    mbs = Path(sys.executable).with_name("mbs")
    proc = subprocess.Popen([str(mbs), "sweep", IDEAL, "-P", "speed=600rpm..1400rpm:6", "-n", "4000", "--per-rev",
                             "360", "-j", "2", "-q", "-o", str(tmp_path / "s.h5")], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    everyone = []
    deadline = time.time() + 120
    while time.time() < deadline and len(everyone) < 4:  # resource tracker, server, two workers
        time.sleep(0.2)
        everyone = psutil.Process(proc.pid).children(recursive=True)
    assert len(everyone) >= 4, "the pool never started"
    time.sleep(0.5)
    if group:
        os.killpg(proc.pid, getattr(signal, signame))
    else:
        proc.send_signal(getattr(signal, signame))
    out, err = proc.communicate(timeout=120)
    gone, alive = psutil.wait_procs(everyone, timeout=20)
    for p in alive:
        p.kill()
    assert proc.returncode == code, err
    assert err.strip().splitlines() == [f"interrupted; finished cases are kept in {tmp_path / 's.h5'}: run the same "
                                        "command again to resume"], err
    assert not alive, [p.cmdline() for p in alive]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]


def test_a_pool_sweep_leaves_no_temporary_folder_and_removes_those_of_killed_sweeps(tmp_path):
    """multiprocessing's fork server keeps its socket in a temporary folder that its finalizer would
    remove, but `mbs sweep` ends with os._exit: every pool sweep left a pymp-* folder behind.  The
    sweep now gives it a folder of its own and removes it at its end; one a killed sweep left (its
    process is gone) is removed by the next sweep, one of a sweep still running is not."""
    import os
    import shutil
    import tempfile

    temp = Path(tempfile.mkdtemp(prefix="mbs-t", dir="/tmp"))  # short: a socket's path has at most 107 bytes
    try:
        _leftovers(temp, tmp_path)
    finally:
        shutil.rmtree(temp)


def _leftovers(temp: Path, tmp_path: Path) -> None:
    import os

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = temp / f"mbs-sweep-{dead.pid}-abc"  # a killed sweep's (its pid is free now)
    stale.mkdir()
    (stale / "listener-x").write_text("")
    alive = temp / f"mbs-sweep-{os.getpid()}-def"  # a running sweep's
    alive.mkdir()
    argv = ["mbs", "sweep", IDEAL, "-P", "speed=800rpm..1600rpm:3", "-n", "2", "--per-rev", "36", "-j", "2",
            "-q", "-o", str(tmp_path / "s.h5")]
    r = subprocess.run([sys.executable, "-c", SWEEP.format(argv=argv)], capture_output=True, text=True,
                       timeout=600, cwd=ROOT, env=dict(os.environ, TMPDIR=str(temp)))
    assert r.returncode == 0, r.stderr
    assert "NO NUMBA" in r.stderr  # the pool came from the fork server
    assert sorted(p.name for p in temp.iterdir()) == [alive.name]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]  # no journal left either


def test_the_workers_run_this_package_even_from_a_folder_holding_another(tmp_path):
    """Started from a folder that holds another `planar_mbs` (a source checkout beside an installed
    release), the fork server and its workers import this one: multiprocessing starts the server as
    `python -c`, which puts the current folder first and (CPython 3.11-3.13) ignores the sweep's path
    before the preload."""
    marker = tmp_path / "imported-the-other-copy"
    (tmp_path / "planar_mbs").mkdir()
    (tmp_path / "planar_mbs" / "__init__.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    mbs = str(Path(sys.executable).with_name("mbs"))
    r = subprocess.run([mbs, "sweep", IDEAL, "-P", "speed=800rpm,1600rpm", "-n", "2", "--per-rev", "36", "-j", "2",
                        "-q", "-o", str(tmp_path / "s.h5")], capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert not marker.exists()
    with h5py.File(tmp_path / "s.h5", "r") as f:
        assert sorted(f["cases"]) == ["0", "1"] and all(f[f"cases/{k}"].attrs["sweep_status"] == "finished"
                                                        for k in ("0", "1"))
