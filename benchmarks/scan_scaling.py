"""Parallel efficiency of `mbs sweep`: wall time of the same scan with -j 1, 2, 4, 8, 16.

    .venv/bin/python benchmarks/scan_scaling.py                 # both scans, -j 1,2,4,8,16
    .venv/bin/python benchmarks/scan_scaling.py --jobs 1,2 --rounds 3
    .venv/bin/python benchmarks/scan_scaling.py --cases 32 --revolutions 200 --jobs 1,2 --rounds 3   # one scan
    .venv/bin/python benchmarks/scan_scaling.py --serial      # the serial fraction and its Amdahl bound

Two scans of models/slider_crank_clearance_a.mbs at 180 samples per revolution: 32 cases x 40
revolutions (short cases, about 0.4 s each) and 64 cases x 200 revolutions (about 2 s each).  Each
`-j` runs as its own process, interleaved round by round (a burst of load hits all alike); the
time is the median over the rounds; speed-up and efficiency (speed-up / jobs) are against -j 1 of
the same run.  Jobs above the number of cores are skipped.  A small scan with a pool runs first,
untimed, so that no timed scan compiles the kernels.  Beside each wall time, the CPU seconds
the cases spent (each case's own, stored with it): where they grow with -j, the cores slow each
other down (shared caches, memory, hyperthreads), which no scheduling can win back.  Prints a
table; writes nothing else.
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


def one(param: str, revolutions: int, jobs: int, folder: Path) -> tuple[float, float, str]:
    """Wall seconds of one `mbs sweep`, the CPU seconds its cases spent, and where its wall time went
    (`timeline`)."""
    import h5py

    out = folder / f"scan-j{jobs}.h5"
    out.unlink(missing_ok=True)
    cmd = [MBS, "sweep", str(MODEL), "-P", param, "-n", str(revolutions), "--per-rev", "180", "-j", str(jobs),
           "-q", "-o", str(out)]
    before = machine_times()
    t0, begin = time.perf_counter(), time.time()
    r = subprocess.run(cmd, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    after = machine_times()
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr[-2000:]}")
    with h5py.File(out, "r") as f:
        cases = [(float(g.attrs["case_started"]), float(g.attrs["case_wall_time"]), int(g.attrs["case_worker"]),
                  float(g.attrs["case_cpu_time"])) for g in f["cases"].values()]
    spent = [b - a for a, b in zip(before, after)]
    share = " | ".join(f"{x / max(sum(spent), 1):.0%}" for x in spent) if spent else "- | - | -"
    return dt, sum(c[3] for c in cases), f"{timeline(cases, begin, begin + dt, jobs)} | {share}"


def machine_times() -> list[int]:
    """The whole machine's CPU time so far, as Linux counts it (/proc/stat): [running, idle, stolen],
    stolen being the time a virtual machine's CPUs waited for the host's; [] elsewhere."""
    try:
        fields = [int(x) for x in Path("/proc/stat").read_text().split("\n")[0].split()[1:9]]
    except (OSError, ValueError):
        return []
    user, nice, system, idle, iowait, irq, softirq, steal = fields
    return [user + nice + system + irq + softirq, idle + iowait, steal]


def timeline(cases: list[tuple[float, float, int, float]], begin: float, end: float, jobs: int) -> str:
    """Where a scan's wall time went, from each case's start, duration and process (stored with it):
    the start-up before the first case, the cores' share of the time spent in cases, the gaps between
    one process's cases (storing a case, waiting for the next), the spread of the processes' last
    ends (a core finishing alone) and the end after the last case (gathering, the table, exit)."""
    by_worker: dict[int, list[tuple[float, float]]] = {}
    for started, wall, worker, _ in cases:
        by_worker.setdefault(worker, []).append((started, started + wall))
    gaps = sum(b[0] - a[1] for runs in by_worker.values() for a, b in zip(sorted(runs), sorted(runs)[1:]))
    last_ends = [max(e for _, e in runs) for runs in by_worker.values()]
    first = min(s for s, _, _, _ in cases)
    busy = sum(w for _, w, _, _ in cases) / (jobs * (end - begin))
    return (f"{first - begin:.2f} | {busy:.0%} | {gaps:.2f} | {max(last_ends) - min(last_ends):.2f} | "
            f"{end - max(last_ends):.2f} | {len(by_worker)}")


def topology() -> str:
    """CPUs, and how many of them share a core (hyperthreads), as Linux counts them."""
    cores = os.cpu_count() or 1
    try:
        siblings = Path("/sys/devices/system/cpu/cpu0/topology/thread_siblings_list").read_text().strip()
        per_core = sum(len(range(int(a), int(b) + 1)) if "-" in part else 1
                       for part in siblings.split(",") for a, _, b in [part.partition("-")])
    except OSError:
        per_core = 1
    return f"{cores} CPUs, {per_core} per core"


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
    print(f"{topology()}, python {sys.version.split()[0]}")
    scans = {f"{args.cases} x {args.revolutions} rev": (f"speed=500rpm..6000rpm:{args.cases}", args.revolutions)} \
        if args.cases else SCANS
    with tempfile.TemporaryDirectory() as tmp:
        warm = one("speed=1000rpm,2000rpm", 2, min(2, cores), Path(tmp))  # untimed: a cold cache compiles here
        print(f"warm-up scan (untimed) {warm[0]:.1f} s")
        for name, (param, revolutions) in scans.items():
            if args.only and name != args.only:
                continue
            times = {j: [] for j in jobs}
            load = os.getloadavg()[0]
            for _ in range(args.rounds):
                for j in jobs:
                    times[j].append(one(param, revolutions, j, Path(tmp)))
            walls = {j: [w for w, _, _ in times[j]] for j in jobs}
            cpu = {j: statistics.median(c for _, c, _ in times[j]) for j in jobs}
            base = statistics.median(walls[jobs[0]]) * jobs[0]
            print(f"\n{name} (load average {load:.1f} before, {os.getloadavg()[0]:.1f} after)\n"
                  "| -j | wall [s] | speed-up | efficiency | speed-up in each round | CPU s in the cases | "
                  "… against the first -j |\n| --- | --- | --- | --- | --- | --- | --- |")
            for j in jobs:
                t = statistics.median(walls[j])
                rounds = ", ".join(f"{a * jobs[0] / b:.2f}" for a, b in zip(walls[jobs[0]], walls[j]))
                print(f"| {j} | {t:.2f} | {base / t:.2f} | {base / t / j:.0%} | {rounds} | {cpu[j]:.1f} | "
                      f"{cpu[j] / cpu[jobs[0]]:.2f} |", flush=True)
            print("\nwhere the wall time went (each round): start-up before the first case [s] | cores busy in cases "
                  "| gaps between a process's cases [s, all processes] | spread of the processes' last ends [s] | "
                  "after the last case [s] | processes | the machine's CPU time running, idle and stolen by the host"
                  "\n| -j | round | start-up | busy | gaps | spread | end | processes | running | idle | stolen |"
                  "\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
            for j in jobs:
                for k, (_, _, line) in enumerate(times[j]):
                    print(f"| {j} | {k + 1} | {line} |")

if __name__ == "__main__":
    main()
