"""What a local sweep's worker process is set up with before its first case
(planar_mbs/sweep/worker.py, through the pool's initializer `sweep.start_worker`): freed memory
kept for the next case."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from planar_mbs.sweep import worker as sweep_worker

ROOT = Path(__file__).resolve().parents[1]

# Four cases run one after the other in the one worker of the sweep's own pool (a fork server that
# preloads `sweep_worker`, as `mbs sweep` runs them); prints the minor page faults of each case and
# the worker's peak memory after it.
FAULTS = """
import os, resource, sys
from planar_mbs.sweep.scan import default_executor, parse_param, plan, run_case_stored

def faults(spec, folder):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    os.unlink(run_case_stored(spec, folder).part)
    after = resource.getrusage(resource.RUSAGE_SELF)
    return f"{after.ru_minflt - before}:{after.ru_maxrss}"

if __name__ == "__main__":
    specs = plan(sys.argv[1], [parse_param("speed=4000rpm..4500rpm:4")], revolutions=30, section={})
    with default_executor(1) as pool:
        print(*[pool.submit(faults, s, sys.argv[2]).result() for s in specs])
"""


def case_faults(tmp_path: Path, env: dict) -> tuple[list[int], list[int]]:
    """The page faults of each case and the worker's peak memory (kB) after each."""
    script = tmp_path / "faults.py"
    script.write_text(FAULTS)
    out = subprocess.run([sys.executable, str(script), str(ROOT / "models" / "slider_crank_clearance_a.mbs"),
                          str(tmp_path)], capture_output=True, text=True, env=env, timeout=600, check=True)
    pairs = [[int(n) for n in case.split(":")] for case in out.stdout.split()]
    return [f for f, _ in pairs], [m for _, m in pairs]


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc, Linux page-fault counts")
def test_a_worker_reuses_the_memory_of_its_previous_case(tmp_path):
    """The first case maps its memory; the next three of the same size reuse it (a few dozen faults,
    not thousands), and the worker's memory stays that of one case.  The control keeps glibc's
    initial mmap threshold (128 kB) fixed through a malloc tunable, which also makes
    `keep_freed_memory` stand back: it maps every case afresh, so this test can fail.  (Left to
    adapt, glibc's threshold may or may not settle after a few cases, depending on the process's
    allocation history: a control relying on it passed or failed with unrelated changes.)"""
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_") and k != "GLIBC_TUNABLES"}
    kept, peak = case_faults(tmp_path, env)
    if kept[0] < 1000:
        pytest.skip(f"this malloc maps too little to tell ({kept})")
    assert max(kept[1:]) < 0.05 * kept[0], kept
    assert peak[-1] < 1.05 * peak[0], peak
    control, _ = case_faults(tmp_path, {**env, "GLIBC_TUNABLES": "glibc.malloc.mmap_threshold=131072"})
    assert min(control[1:]) > 0.3 * control[0], control


def test_a_user_s_malloc_settings_are_left_alone(monkeypatch):
    monkeypatch.setenv("GLIBC_TUNABLES", "glibc.malloc.trim_threshold=1000000")
    assert sweep_worker.keep_freed_memory() is False
    monkeypatch.delenv("GLIBC_TUNABLES")
    monkeypatch.setenv("MALLOC_ARENA_MAX", "2")
    assert sweep_worker.keep_freed_memory() is False
