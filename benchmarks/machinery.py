"""What each piece of the start-up machinery built on numba's internals gains, measured in one run.

    .venv/bin/python benchmarks/machinery.py [--rounds 2]

Each variant runs the clearance slider-crank for 2 ms in a fresh process: "cold" with an empty kernel
cache (the first compilation, the compile helper of `run.first_compile` switched off so that one
process does all of it; its CPU time is the measure, which a busy machine disturbs less than wall
time), "warm" from the cache the cold run left (the whole process's wall time, best of 5).  Variants:
everything on; without `kernel.inline_copy` (numba's own inliner); without `kernel.loop_opt_level`
(every library at O3); numba's public cache path (`PLANAR_MBS_PUBLIC_CACHE=1`: none of the private
pieces: no fast loading, no wrapper-less twins, neither of the two above).  The rounds alternate the
variants, so a change of the machine's load spreads over all of them.  Prints one line per variant.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "slider_crank_clearance_a.mbs"
RUN = ("import sys, planar_mbs as mbs; from planar_mbs.run import first_compile as F; F._start_helper = lambda: None; "
       f"mbs.simulate(mbs.load_model({str(MODEL)!r}), t_end='2 ms')")
VARIANTS = {
    "all on": {},
    "without inline_copy": {"PLANAR_MBS_WITHOUT": "inline_copy"},
    "without loop_opt_level": {"PLANAR_MBS_WITHOUT": "loop_opt_level"},
    "public cache (no private pieces)": {"PLANAR_MBS_PUBLIC_CACHE": "1"},
}


def _child(env: dict) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one process running the model."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", RUN], env=env, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=2)
    rounds = ap.parse_args().rounds
    cold = {name: [] for name in VARIANTS}
    warm = {name: [] for name in VARIANTS}
    for _ in range(rounds):
        for name, extra in VARIANTS.items():
            with tempfile.TemporaryDirectory() as cache:
                env = {**os.environ, **extra, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": str(ROOT)}
                cold[name].append(_child(env)[1])
                warm[name].append(min(_child(env)[0] for _ in range(5)))
    base_cold, base_warm = min(cold["all on"]), min(warm["all on"])
    for name in VARIANTS:
        c, w = min(cold[name]), min(warm[name])
        print(f"{name:34s} first compilation {c:6.1f} s CPU ({c / base_cold:4.2f}x)   "
              f"warm run {w:5.2f} s ({w / base_warm:4.2f}x)   [all: {', '.join(f'{x:.1f}' for x in cold[name])}]")


if __name__ == "__main__":
    main()
