"""Where each CPU second of a scan goes: the phases of `mbs sweep`, and the serial fraction they imply.

    .venv/bin/python benchmarks/scan_phases.py                      # 16 x 40 rev and 8 x 200 rev, -j 1 and -j 2
    .venv/bin/python benchmarks/scan_phases.py --cases 200 --revolutions 2 --jobs 1   # per-case costs

Each scan runs `mbs sweep` as its own process tree (the command's own code path, `planar_mbs.cli.entry`),
counted with `benchmarks/process.py`'s subreaper (CPU seconds of every process: the command, the fork
server, its workers).  Inside the command the functions of each phase are wrapped to add up the CPU
seconds of this process spent in them, nested calls counted in the inner phase only:

* start-up: the interpreter, the imports and typer reading the command line, until the sweep begins;
* model: reading the model once (its snapshot) and expanding the cases;
* checks: compiling and checking every case before any runs (`scan.check_cases`);
* kernels: loading numba's compiled kernels (`sweep.worker.warm_up`; with -j 1 before the first case,
  otherwise in the fork server, off this process);
* cases: each case's own CPU seconds as stored with it (`case_cpu_time`: compile, time loop, section);
* journal: writing each case into its journal file (`scan.store_outcome`; in the workers with -j 2);
* gather: copying the journal into the scan file, table of cases excluded (`store.gather`);
* table: writing the table of cases into the file (`store.write_table`) and printing it;
* rest: the sweep's own bookkeeping, locks, the pool, the interpreter's end (total minus the above).

Every phase but `cases` is serial on one machine however many cores it has (the journal is written
by each worker for its own case, so with a pool it parallelises too: it is counted apart).  Prints a
table per scan and Amdahl's bound 1 / (f + (1 - f) / N) for 16, 64 and 256 cores.  Writes nothing else.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "slider_crank_clearance_a.mbs"
PHASES = ("start-up", "model", "checks", "kernels", "cases", "journal", "gather", "table", "rest")
REPORT_ENV = "SCAN_PHASES_REPORT"


def _wrap(owner, name: str, phase: str, spent: dict, stack: list) -> None:
    """Replace ``owner.name`` by a wrapper adding its CPU seconds (its nested wrapped calls excluded) to
    ``spent[phase]``."""
    inner = getattr(owner, name)

    def timed(*args, **kwargs):
        stack.append(0.0)
        t0 = time.process_time()
        try:
            return inner(*args, **kwargs)
        finally:
            dt = time.process_time() - t0
            nested = stack.pop()
            spent[phase] = spent.get(phase, 0.0) + dt - nested
            if stack:
                stack[-1] += dt

    setattr(owner, name, timed)


def child() -> None:
    """Run `mbs sweep` (argv after --child) in this process with the phases wrapped; at its exit write
    this process's CPU seconds per phase to the file named in $SCAN_PHASES_REPORT."""
    from planar_mbs.cli import entry, sweep_commands
    from planar_mbs.sweep import scan, server, store

    spent: dict[str, float] = {}
    stack: list[float] = []
    sweep_begins: list[float] = []
    run_sweep = scan.run_sweep

    def begin(*args, **kwargs):
        sweep_begins.append(time.process_time())
        return run_sweep(*args, **kwargs)

    scan.run_sweep = begin
    for owner, name, phase in [(scan.ModelSnapshot, "of", "model"), (scan, "plan", "model"),
                               (scan, "check_cases", "checks"),
                               (scan, "run_case", "cases"), (scan, "store_outcome", "journal"),
                               (store, "gather", "gather"), (store, "write_table", "table"),
                               (scan, "gather", "gather"), (scan, "write_table", "table"),  # where imported by name
                               (sweep_commands, "_print_table", "table")]:
        if hasattr(owner, name):
            _wrap(owner, name, phase, spent, stack)
    start = scan._start

    def warm_first(pending, folder, jobs, *rest):
        """-j 1: the kernels load (importing `sweep.worker` does) before the first case, not in it; with a
        pool they load in the fork server, and in this process only if that did not start."""
        t0 = time.process_time()
        if jobs == 1 or len(pending) <= 1 or not server.started():
            from planar_mbs.sweep import worker  # noqa: F401
        spent["kernels"] = time.process_time() - t0
        return start(pending, folder, jobs, *rest)

    scan._start = warm_first
    leave = entry.leave

    def report(code, printed_only=False):
        spent["start-up"] = sweep_begins[0] if sweep_begins else time.process_time()
        spent["own"] = time.process_time()
        Path(os.environ[REPORT_ENV]).write_text(json.dumps(spent))
        leave(code, printed_only)

    entry.leave = report
    sys.argv = ["mbs", *sys.argv[sys.argv.index("--child") + 1:]]
    entry.main()


def measure(cases: int, revolutions: int, jobs: int, folder: Path) -> dict:
    """CPU seconds per phase of one scan of `cases` speeds x `revolutions`, the whole tree's total and wall."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import h5py
    from process import wall_and_cpu

    out, report = folder / f"phases-j{jobs}.h5", folder / "phases.json"
    out.unlink(missing_ok=True)
    os.environ[REPORT_ENV] = str(report)
    cmd = [sys.executable, __file__, "--child", "sweep", str(MODEL), "-P", f"speed=500rpm..6000rpm:{cases}",
           "-n", str(revolutions), "--per-rev", "180", "-j", str(jobs), "-q", "-o", str(out)]
    wall, tree = wall_and_cpu(cmd)
    spent = json.loads(report.read_text())
    with h5py.File(out, "r") as f:
        in_cases = sum(float(g.attrs["case_cpu_time"]) for g in f["cases"].values())
    spent["cases"] = in_cases  # the workers' too (with -j 1 equal to this process's, to rounding)
    if jobs > 1:  # the pool's processes: their cases, their journal writes, the server's kernels
        pool = tree - spent["own"]
        spent["kernels+journal (pool)"] = pool - in_cases
    spent["rest"] = tree - sum(v for k, v in spent.items() if k in PHASES[:-1] or k.endswith("(pool)"))
    return {"wall": wall, "total": tree, "spent": spent}


def show(label: str, jobs: int, m: dict) -> float:
    """Print one scan's phases; return its serial fraction (all but the cases, and with a pool its journal)."""
    total, spent = m["total"], m["spent"]
    print(f"\n{label}, -j {jobs}: {total:.2f} CPU s in all, {m['wall']:.2f} s wall, load "
          f"{os.getloadavg()[0]:.1f}\n| phase | CPU s | share |\n| --- | ---: | ---: |")
    keys = [k for k in PHASES if k in spent] + [k for k in spent if k.endswith("(pool)")]
    for k in keys:
        print(f"| {k} | {spent[k]:.3f} | {spent[k] / total:.1%} |")
    parallel = spent["cases"] + (spent.get("kernels+journal (pool)", 0.0) if jobs > 1 else spent.get("journal", 0.0))
    f = 1.0 - parallel / total
    print(f"serial fraction f = {f:.4f}; Amdahl bound 1 / (f + (1 - f) / N): " + ", ".join(
        f"{n} cores {1 / (f + (1 - f) / n):.1f}x ({1 / (f + (1 - f) / n) / n:.0%})" for n in (16, 64, 256)))
    return f


def main() -> None:
    if "--child" in sys.argv:
        child()
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=None, help="one scan of this many speeds (default: two scans)")
    ap.add_argument("--revolutions", type=int, default=40)
    ap.add_argument("--jobs", default="1,2")
    args = ap.parse_args()
    scans = [(args.cases, args.revolutions)] if args.cases else [(16, 40), (8, 200)]
    with tempfile.TemporaryDirectory() as tmp:
        for cases, revolutions in scans:
            for jobs in map(int, args.jobs.split(",")):
                show(f"{cases} cases x {revolutions} rev", jobs, measure(cases, revolutions, jobs, Path(tmp)))


if __name__ == "__main__":
    main()
