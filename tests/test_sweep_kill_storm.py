"""A kill storm: sweeps SIGKILLed at random moments (seeded), fresh and resumed, one process and a
pool of two.  After every kill each finished case is readable (the scan file, whatever its age,
and every case file of its journal), no finished case is lost from one kill to the next, and the
scan completed by resuming is the uninterrupted scan, bit for bit."""
from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest

from planar_mbs.sweep.scan import parse_param, read_case_table, run_sweep
from planar_mbs.sweep.store import case_file_row, case_files, journal_folder

ROOT = Path(__file__).resolve().parents[1]
IDEAL = ROOT / "models" / "slider_crank.mbs"
SPEEDS = "speed=600rpm..1800rpm:12"
OPTS = dict(revolutions=6, per_rev=24, section={})
KILLS = 210  # across both -j values
SCRIPT = ("import sys; from planar_mbs.sweep.scan import parse_param, run_sweep; "
          f"run_sweep({str(IDEAL)!r}, [parse_param({SPEEDS!r})], sys.argv[1], jobs=int(sys.argv[2]), "
          f"keep=('slider.vx',), **{OPTS!r})")


def _finished(out: Path) -> set[str]:
    """Keys of the finished cases the scan and its journal hold, each read back whole."""
    keys = set()
    if out.exists():
        rows = read_case_table(out)  # the table, and the journal's rows
        with h5py.File(out, "r", locking=False) as f:
            for r in rows:
                g = f.get(f"cases/{r['index']}")
                if g is not None and r["status"] == "finished":
                    assert len(g["signals/slider"]["vx"]) == 6 * 24 + 1
                    keys.add(r["key"])
    for index, part in case_files(journal_folder(out)):
        row = case_file_row(part)
        assert row is not None, f"{part} is not whole"
        with h5py.File(part, "r", locking=False) as f:
            assert len(f[f"cases/{index}/signals/slider"]["vx"]) == 6 * 24 + 1
        keys.add(row["key"])
    return keys


def _tree(path) -> dict:
    out = {}
    rows = {r["index"]: r for r in read_case_table(path)}
    with h5py.File(path, "r") as f:
        for index, r in rows.items():
            def visit(name, obj, key=r["key"]):
                if isinstance(obj, h5py.Dataset):
                    out[f"{key}/{name}"] = obj[()].tobytes() if obj.dtype.kind != "O" else list(obj[()])
                for a, v in obj.attrs.items():
                    # measured, not computed: n_rhs counts one more right-hand side each time the time
                    # loop is re-entered, which a wall-time budget decides (the results are the same);
                    # when a case started and in which process
                    if not any(m in a for m in ("wall_time", "cpu_time", "case_started", "case_worker")) \
                            and a != "n_rhs":
                        out[f"{key}/{name}@{a}"] = str(v)
            f[f"cases/{index}"].visititems(visit)
            out[f"{r['key']}/row"] = str({k: v for k, v in r.items() if k != "wall_time"})
    return out


class _Lane:
    """One chain of sweeps on one output with one ``-j``: started, killed at a random moment, resumed,
    until a run completes; then a fresh chain."""

    def __init__(self, folder: Path, jobs: int, rng: random.Random, env: dict):
        self.folder, self.jobs, self.rng, self.env = folder, jobs, rng, env
        self.chain, self.proc, self.completed_chains = 0, None, 0
        self.fresh()

    def fresh(self):
        self.chain += 1
        self.out = self.folder / f"j{self.jobs}-chain{self.chain}.h5"
        self.seen: set[str] = set()

    def start(self):
        self.proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(self.out), str(self.jobs)], env=self.env,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
        # a random moment, from the start-up to the last case; one run in six is left to finish
        self.deadline = time.monotonic() + (self.rng.uniform(0.2, 2.2) if self.rng.random() > 1 / 6 else 1e9)

    def step(self, expected: dict) -> int:
        """Kill the sweep once its moment has come, or see it end; check the output.  Returns the kills."""
        killed = 0
        if self.proc.poll() is None:
            if time.monotonic() < self.deadline:
                return 0
            os.killpg(self.proc.pid, signal.SIGKILL)  # the sweep and its workers, as an OOM killer would
            killed = 1
        code = self.proc.wait(timeout=60)
        for _ in range(3000):  # its workers too (they may hold the scan file's lock for a few ms more)
            try:
                os.killpg(self.proc.pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.01)
        assert code in (0, -signal.SIGKILL), self.proc.stderr.read().decode()[-2000:]
        now = _finished(self.out)
        assert self.seen <= now, f"{self.out.name}: finished cases lost: {sorted(self.seen - now)}"
        self.seen = now
        if code == 0:
            assert _tree(self.out) == expected, f"{self.out.name} differs from the uninterrupted scan"
            assert not journal_folder(self.out).exists()
            self.completed_chains += 1
            self.fresh()
        self.start()
        return killed


@pytest.mark.slow
def test_kill_storm(tmp_path):
    """Two chains at a time (-j 1 and -j 2 side by side, so the storm fits in a few minutes)."""
    rng = random.Random(20261126)
    reference = tmp_path / "reference.h5"
    run_sweep(IDEAL, [parse_param(SPEEDS)], reference, jobs=1, keep=("slider.vx",), **OPTS)
    expected = _tree(reference)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    lanes = [_Lane(tmp_path, jobs, rng, env) for jobs in (1, 2)]
    for lane in lanes:
        lane.start()
    kills = [0, 0]
    try:
        while sum(kills) < KILLS:
            time.sleep(0.02)
            for i, lane in enumerate(lanes):
                kills[i] += lane.step(expected)
    finally:
        for lane in lanes:
            if lane.proc.poll() is None:
                os.killpg(lane.proc.pid, signal.SIGKILL)
                lane.proc.wait()
    assert min(kills) >= KILLS // 3 and all(lane.chain >= 2 for lane in lanes), (kills, [l.chain for l in lanes])
    resumed = [lane for lane in lanes if lane.completed_chains]
    assert resumed, "no chain was resumed to its end"
