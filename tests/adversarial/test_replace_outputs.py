"""A results file is written beside its name and moved into place: a kill at any moment leaves the
earlier file whole or the new one, never an empty or half-written one.  `-o` (and `output=` in
Python) replaces only the results of a run unless told (`--overwrite`), never the model or a
file it includes, and never writes through a symbolic link planted at the name or beside it."""
from __future__ import annotations

import os
import random
import signal
import subprocess
import time

import h5py
import numpy as np
import pytest

import planar_mbs as mbs_api
from advhelp import MBS, assert_clean, mbs, snapshot
from planar_mbs.errors import ModelError
from planar_mbs.results.hdf5 import part_beside

NOT_RESULTS = {  # a file an `-o` typo could name, and its bytes
    "notes.py": b"print('my script')\n",
    "table.csv": b"a,b\n1,2\n",
    "recording.rrd": b"RRF2\x00\x00 not really a recording",
}


@pytest.mark.parametrize("name", [*NOT_RESULTS, "sweep.h5", "foreign.h5"])
def test_run_refuses_to_replace_what_is_not_a_run(sandbox, name):
    """A script, a table, a recording, a finished sweep file, a foreign HDF5 file: exit 2, untouched."""
    if name in NOT_RESULTS:
        (sandbox / name).write_bytes(NOT_RESULTS[name])
    elif name == "foreign.h5":
        with h5py.File(sandbox / name, "w") as f:
            f["data"] = np.arange(3.0)
    before = snapshot(sandbox)
    out = mbs("run", "mech.mbs", "-o", name, "-q", cwd=sandbox)
    assert_clean(out, 2, name, "--overwrite", before=before, folder=sandbox)


def test_overwrite_replaces_it_and_a_run_replaces_a_run(sandbox):
    (sandbox / "notes.py").write_bytes(NOT_RESULTS["notes.py"])
    before = snapshot(sandbox)
    out = mbs("run", "mech.mbs", "-o", "notes.py", "-q", "--overwrite", cwd=sandbox)
    assert_clean(out, 0, before=before, folder=sandbox, allowed=["notes.py"])
    assert mbs_api.read_results(sandbox / "notes.py").complete
    out = mbs("run", "mech.mbs", "-o", "run.h5", "-q", "--t-end", "0.5ms", cwd=sandbox)  # a run over a run
    assert_clean(out, 0, before=before, folder=sandbox, allowed=["notes.py", "run.h5"])
    assert mbs_api.read_results(sandbox / "run.h5").time[-1] == pytest.approx(5e-4)


@pytest.mark.parametrize("target", ["mech.mbs", "parts/bodies.mbs"])
@pytest.mark.parametrize("overwrite", [False, True])
def test_python_api_never_writes_over_the_model(sandbox, target, overwrite):
    """simulate(output=the model or its include) used to write results over it."""
    model = mbs_api.load_model(sandbox / "mech.mbs")
    before = snapshot(sandbox)
    with pytest.raises(ModelError, match="model or a file it includes"):
        mbs_api.simulate(model, output=sandbox / target, overwrite=overwrite)
    with pytest.raises(ModelError, match="model or a file it includes"):
        mbs_api.Simulation(model, output=sandbox / target, overwrite=overwrite)
    assert not [k for k, v in snapshot(sandbox).items() if before.get(k) != v]


def test_python_api_refuses_a_file_that_is_not_a_run(sandbox):
    (sandbox / "notes.py").write_bytes(NOT_RESULTS["notes.py"])
    model = mbs_api.load_model(sandbox / "mech.mbs")
    with pytest.raises(ModelError, match="not a results file"):
        mbs_api.simulate(model, output=sandbox / "notes.py")
    assert (sandbox / "notes.py").read_bytes() == NOT_RESULTS["notes.py"]
    mbs_api.simulate(model, output=sandbox / "notes.py", overwrite=True)
    assert mbs_api.read_results(sandbox / "notes.py").complete


@pytest.mark.parametrize("planted", ["name", "part"])
def test_a_planted_symlink_is_never_followed(sandbox, planted):
    """A link at the output's name, or at the hidden file written beside it, pointing at a victim
    file: the victim is never written (the write lock used to open the name following links)."""
    victim = sandbox / "victim.txt"
    victim.write_bytes(b"precious\n")
    link = sandbox / "out.h5" if planted == "name" else part_beside(sandbox / "out.h5")
    os.symlink(victim, link)
    before = snapshot(sandbox)
    out = mbs("run", "mech.mbs", "-o", "out.h5", "-q", cwd=sandbox)
    assert_clean(out, 2, "symbolic link", before=before, folder=sandbox)
    assert victim.read_bytes() == b"precious\n"


def _kill_run_over(sandbox, delay: float) -> None:
    """Start `mbs run -o run.h5` (a long run) over the finished run.h5 and SIGKILL it after `delay` s."""
    proc = subprocess.Popen([str(MBS), "run", "mech.mbs", "-o", "run.h5", "-q", "--t-end", "10 s",
                             "--output-step", "1 us", "--force"], cwd=sandbox,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(delay)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)


def test_a_kill_during_a_run_leaves_the_earlier_results_whole(sandbox):
    """SIGKILL once the new run writes rows: the earlier run.h5 is byte for byte what it was (it used
    to be truncated at once), and the new rows so far are readable in the part file."""
    earlier = (sandbox / "run.h5").read_bytes()
    part = part_beside(sandbox / "run.h5")
    proc = subprocess.Popen([str(MBS), "run", "mech.mbs", "-o", "run.h5", "-q", "--t-end", "10 s",
                             "--output-step", "1 us", "--force"], cwd=sandbox,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            with h5py.File(part, "r", locking=False) as f:
                if f["time"].shape[0] > 0:
                    break
        except (OSError, KeyError):
            pass
        time.sleep(0.05)
    assert proc.poll() is None, proc.stderr.read()
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    assert (sandbox / "run.h5").read_bytes() == earlier
    kept = mbs_api.read_results(part)
    assert len(kept.time) > 0 and not kept.complete
    out = mbs("plot", "missing.h5", cwd=sandbox)  # (a name never written says so plainly)
    assert out.code == 2 and "Traceback" not in out.output


@pytest.mark.slow
def test_kills_at_random_moments_never_lose_the_earlier_results(sandbox):
    """A seeded kill loop over start-up and the run: 20 SIGKILLs, each leaving run.h5 as it was."""
    earlier = (sandbox / "run.h5").read_bytes()
    rng = random.Random(30)
    for _ in range(20):
        _kill_run_over(sandbox, rng.uniform(0.0, 2.5))
        assert (sandbox / "run.h5").read_bytes() == earlier
        assert mbs_api.read_results(sandbox / "run.h5").complete
