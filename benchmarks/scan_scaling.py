"""Parallel efficiency of `mbs sweep`: wall time of the same scan with -j 1, 2, 4, 8, 16.

    .venv/bin/python benchmarks/scan_scaling.py                 # both scans, -j 1,2,4,8,16
    .venv/bin/python benchmarks/scan_scaling.py --jobs 1,2 --rounds 3
    .venv/bin/python benchmarks/scan_scaling.py --cases 32 --revolutions 200 --jobs 1,2 --rounds 3   # one scan
    .venv/bin/python benchmarks/scan_scaling.py --serial      # the serial fraction and its Amdahl bound

Two scans of models/slider_crank_clearance_a.mbs at 180 samples per revolution: 32 cases x 40
revolutions (short cases, about 0.4 s each) and 64 cases x 200 revolutions (about 2 s each).  Each
`-j` runs as its own process, interleaved round by round (a burst of load hits all alike); the
time is the median over the rounds; speed-up and efficiency (speed-up / jobs) are against -j 1 of
the same run.  Jobs above the number of cores are skipped.  Prints a table; writes nothing else.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MBS = str(Path(sys.executable).with_name("mbs"))
MODEL = ROOT / "models" / "slider_crank_clearance_a.mbs"
SCANS = {"32 x 40 rev": ("speed=500rpm..6000rpm:32", 40), "64 x 200 rev": ("speed=500rpm..6000rpm:64", 200)}


def one(param: str, revolutions: int, jobs: int, folder: Path) -> float:
    out = folder / f"scan-j{jobs}.h5"
    out.unlink(missing_ok=True)
    cmd = [MBS, "sweep", str(MODEL), "-P", param, "-n", str(revolutions), "--per-rev", "180", "-j", str(jobs),
           "-q", "-o", str(out)]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr[-2000:]}")
    return dt


def serial_fraction(folder: Path, param: str, revolutions: int, rounds: int) -> None:
    """Where the CPU seconds of a one-process scan go: its cases (the CPU time of each, stored with it)
    and the rest (start-up, checking every case, gathering the journal into the scan
    file), which no number of cores shortens.  CPU seconds of the whole process tree of -j 1 and -j 2
    are counted with `benchmarks/process.py`'s subreaper.  Prints the serial fraction and the Amdahl
    bound 1 / (f + (1 - f) / N) for 16, 64 and 256 cores."""
    import h5py

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from process import wall_and_cpu

    rows = []
    for _ in range(rounds):
        for jobs in (1, 2):
            out = folder / f"serial-j{jobs}.h5"
            out.unlink(missing_ok=True)
            cmd = [MBS, "sweep", str(MODEL), "-P", param, "-n", str(revolutions), "--per-rev", "180",
                   "-j", str(jobs), "-q", "-o", str(out)]
            wall, cpu = wall_and_cpu(cmd)
            with h5py.File(out, "r") as f:
                cases = sum(float(g.attrs["case_cpu_time"]) for g in f["cases"].values())
            rows.append((jobs, wall, cpu, cases))
    one = [r for r in rows if r[0] == 1]
    two = [r for r in rows if r[0] == 2]
    t1, c1, s1 = (statistics.median(r[i] for r in one) for i in (1, 2, 3))
    t2, c2 = (statistics.median(r[i] for r in two) for i in (1, 2))
    f = max(c1 - s1, 0.0) / c1  # CPU seconds: a loaded machine stretches wall time, not these
    print(f"{param} x {revolutions} rev, load {os.getloadavg()[0]:.1f}: -j 1 {t1:.2f} s wall, {c1:.2f} CPU s "
          f"({s1:.2f} in the cases); -j 2 {t2:.2f} s wall, {c2:.2f} CPU s (the pool's own: {c2 - c1:+.2f}); "
          f"speed-up {t1 / t2:.2f}")
    print(f"serial fraction {f:.3f}; Amdahl bound: " +
          ", ".join(f"{n} cores {1 / (f + (1 - f) / n):.1f}x ({1 / (f + (1 - f) / n) / n:.0%})" for n in (16, 64, 256)))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--jobs", default="1,2,4,8,16")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--only", choices=list(SCANS), default=None)
    ap.add_argument("--cases", type=int, default=None, help="instead: one scan of this many speeds ...")
    ap.add_argument("--revolutions", type=int, default=200, help="... of this many revolutions each")
    ap.add_argument("--serial", action="store_true", help="measure the serial fraction (on any machine)")
    args = ap.parse_args()
    if args.serial:
        with tempfile.TemporaryDirectory() as tmp:
            serial_fraction(Path(tmp), "speed=500rpm..6000rpm:16", 40, args.rounds)
            serial_fraction(Path(tmp), "speed=500rpm..6000rpm:8", 200, args.rounds)
        return
    cores = os.cpu_count() or 1
    jobs = [j for j in map(int, args.jobs.split(",")) if j <= cores]
    print(f"{cores} cores, python {sys.version.split()[0]}")
    scans = {f"{args.cases} x {args.revolutions} rev": (f"speed=500rpm..6000rpm:{args.cases}", args.revolutions)} \
        if args.cases else SCANS
    with tempfile.TemporaryDirectory() as tmp:
        for name, (param, revolutions) in scans.items():
            if args.only and name != args.only:
                continue
            times = {j: [] for j in jobs}
            load = os.getloadavg()[0]
            for _ in range(args.rounds):
                for j in jobs:
                    times[j].append(one(param, revolutions, j, Path(tmp)))
            base = statistics.median(times[jobs[0]]) * jobs[0]
            print(f"\n{name} (load average {load:.1f} before, {os.getloadavg()[0]:.1f} after)\n"
                  "| -j | wall [s] | speed-up | efficiency | speed-up in each round |\n| --- | --- | --- | --- | --- |")
            for j in jobs:
                t = statistics.median(times[j])
                rounds = ", ".join(f"{a * jobs[0] / b:.2f}" for a, b in zip(times[jobs[0]], times[j]))
                print(f"| {j} | {t:.2f} | {base / t:.2f} | {base / t / j:.0%} | {rounds} |")


if __name__ == "__main__":
    main()
