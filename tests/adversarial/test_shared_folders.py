"""Shared folders and concurrent writers: a sweep's journal planted by someone else (a link, a
folder of another user, a folder anyone may write in), a forged case file, a planted part file,
a run or a merge into a file a sweep is writing, the copies killed merges left behind."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest

from advhelp import MBS, assert_clean, mbs, snapshot

ROOT = Path(__file__).resolve().parents[2]
IDEAL = ROOT / "models" / "slider_crank.mbs"
SWEEP = ["-P", "speed=600rpm,900rpm", "-n", "2", "--per-rev", "36", "-j", "1", "-q", "--no-section"]
OTHER_USER = 65534  # nobody


def _sweep(out: Path, *extra):
    return mbs("sweep", IDEAL, *SWEEP, *extra, "-o", out, cwd=out.parent, timeout=120)


# ---------------------------------------------------------------- a planted journal folder
def test_planted_journal_link_is_refused_and_nothing_written_through_it(tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (tmp_path / ".s.h5.cases").symlink_to(elsewhere)
    before = snapshot(tmp_path)
    out = _sweep(tmp_path / "s.h5")
    assert_clean(out, 2, ".s.h5.cases", "is a symbolic link", "remove it", before=before, folder=tmp_path)


def test_journal_folder_anyone_may_write_in_is_refused(tmp_path):
    folder = tmp_path / ".s.h5.cases"
    folder.mkdir()
    folder.chmod(0o777)
    before = snapshot(tmp_path)
    assert_clean(_sweep(tmp_path / "s.h5"), 2, "can be written by other users", before=before, folder=tmp_path)


@pytest.mark.skipif(os.geteuid() != 0, reason="planting another user's folder needs root")
def test_journal_folder_of_another_user_is_refused(tmp_path):
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o1777)
    folder = shared / ".s.h5.cases"
    folder.mkdir(mode=0o700)
    os.chown(folder, OTHER_USER, OTHER_USER)
    before = snapshot(tmp_path)
    assert_clean(_sweep(shared / "s.h5"), 2, "belongs to another user", before=before, folder=tmp_path)


def test_new_journal_folder_is_private(tmp_path, monkeypatch):
    """The journal exists only while cases wait in it: caught here inside a case's run."""
    from planar_mbs.sweep import scan

    modes = []
    real = scan.run_case

    def spy(spec):
        modes.append(os.stat(tmp_path / ".s.h5.cases").st_mode & 0o777)
        return real(spec)

    monkeypatch.setattr(scan, "run_case", spy)
    scan.run_sweep(IDEAL, [scan.parse_param("speed=600rpm")], tmp_path / "s.h5", revolutions=2, per_rev=12, jobs=1)
    assert modes == [0o700]


# ---------------------------------------------------------------- a forged case file
def _forge(tmp_path: Path, out: Path, mac: bool) -> None:
    """Case 1 of `out`'s next sweep, copied from another scan with a verdict of its own, the right
    config and (``mac``) a signature under a key of the forger's."""
    from planar_mbs.sweep.store import journal_folder, sign_case

    other = tmp_path / "other.h5"
    assert _sweep(other).code == 0
    with h5py.File(out, "r") as f:
        config = f.attrs["config"]
    with h5py.File(other, "r") as f:
        row = {"index": 1, "key": "speed=900rpm", "status": "finished", "message": "", "values": {"speed": "900rpm"},
               "verdict": "FORGED", "period": 1.0, "K": 1, "lyapunov": 0, "dimension": 0, "wall_time": 0}
    folder = journal_folder(out)
    folder.mkdir(mode=0o700)
    (folder / "key").write_text("ab" * 32)
    with h5py.File(other, "r") as src, h5py.File(folder / "case-1.h5", "w") as part:
        src.copy(src["cases/1"], part, "cases/1")
        part.attrs["sweep_row"] = json.dumps(row)
        part.attrs["sweep_config"] = config
        if mac:
            sign_case(part, b"forger's own key")


@pytest.mark.parametrize("mac", [False, True], ids=["unsigned", "signed-with-another-key"])
def test_forged_case_file_is_refused(tmp_path, mac):
    out = tmp_path / "s.h5"
    assert mbs("sweep", IDEAL, *SWEEP[:1], "speed=600rpm", *SWEEP[2:], "-o", out, timeout=120).code == 0
    _forge(tmp_path, out, mac)
    res = _sweep(out)
    assert_clean(res, 2, "case-1.h5 was not written by a sweep of", "remove it to run case 1 again")
    with h5py.File(out, "r") as f:
        assert sorted(f["cases"]) == ["0"]
    from planar_mbs.sweep.scan import read_case_table

    assert all(r["verdict"] != "FORGED" for r in read_case_table(out))


# ---------------------------------------------------------------- a planted part file
def test_planted_part_file_link_is_named_with_its_cause(sandbox):
    victim = sandbox / "victim.txt"
    victim.write_text("keep me")
    (sandbox / ".out.h5.part").symlink_to(victim)
    before = snapshot(sandbox)
    out = mbs("run", "mech.mbs", "-o", "out.h5", "-q", cwd=sandbox)
    assert_clean(out, 2, "cannot write out.h5", "part file .out.h5.part is a symbolic link", before=before,
                 folder=sandbox)
    assert victim.read_text() == "keep me"


# ---------------------------------------------------------------- writers of a file a sweep writes
LONG = ["-P", "speed=600rpm..1400rpm:6", "-n", "800", "--per-rev", "360", "-j", "1", "-q", "--no-section",
        "--keep", "all"]


def _wait_for_case(out: Path, proc, deadline=120) -> bool:
    end = time.time() + deadline
    while time.time() < end and proc.poll() is None:
        time.sleep(0.2)
        try:
            with h5py.File(out, "r", locking=False) as f:
                if "cases" in f and len(f["cases"]):
                    return True
        except (OSError, KeyError):
            pass
    return False


@pytest.mark.slow  # waits for a long sweep to store its first case (~15 s)
def test_run_and_merge_into_a_file_a_sweep_writes_are_refused(sandbox):
    out = sandbox / "sw.h5"
    a, b = sandbox / "a.h5", sandbox / "b.h5"
    assert _sweep(a).code == 0
    assert mbs("sweep", IDEAL, "-P", "speed=1200rpm", *SWEEP[2:], "-o", b, timeout=120).code == 0
    sweep = subprocess.Popen([str(MBS), "sweep", str(IDEAL), *LONG, "-o", str(out)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_for_case(out, sweep), "the sweep stored no case"
        ran = mbs("run", "mech.mbs", "-o", out, "--overwrite", "-q", cwd=sandbox)
        assert_clean(ran, 2, "is being written by a sweep", "mbs sweep, pid")
        merged = mbs("sweep-merge", a, b, "-o", out, "--overwrite", cwd=sandbox)
        assert_clean(merged, 2, "is being written by a sweep", "mbs sweep, pid")
        _, stderr = sweep.communicate(timeout=600)
    finally:
        if sweep.poll() is None:
            sweep.kill()
    assert sweep.returncode == 0, stderr
    with h5py.File(out, "r") as f:
        assert f.attrs["kind"] == "sweep" and "time" not in f and "signals" not in f
        assert sorted(f["cases"], key=int) == [str(k) for k in range(6)]
    assert not (sandbox / ".sw.h5.lock").exists()


def test_a_killed_merge_leaves_no_copy_for_good(tmp_path):
    a, b, out = tmp_path / "a.h5", tmp_path / "b.h5", tmp_path / "all.h5"
    assert _sweep(a).code == 0
    assert mbs("sweep", IDEAL, "-P", "speed=1200rpm", *SWEEP[2:], "-o", b, timeout=120).code == 0
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (tmp_path / f".all.h5.tmp-{dead.pid}").write_bytes(b"half a merged file")
    assert_clean(mbs("sweep-merge", a, b, "-o", out), 0)
    assert not list(tmp_path.glob(".all.h5.tmp-*"))
    assert not (tmp_path / ".all.h5.lock").exists()
