"""Peak memory of `mbs run` against the simulated time (section "memory" of benchmarks/run.py).

Each run is its own process (`mbs run ... -q --force`), and its peak resident set size is the
kernel's count for that child alone (`os.wait4`), so the runs do not see each other's memory.
A run streams its rows to the HDF5 file, so the peak must not grow with t_end: the target is a
100-simulated-second run within 1.2x the peak of a 1-second run.

    .venv/bin/python benchmarks/memory.py            # 1, 10 and 100 simulated seconds
    .venv/bin/python benchmarks/memory.py 1 10        # some of them
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "slider_crank_clearance_a.mbs"
MBS = str(Path(sys.executable).with_name("mbs"))
TARGET = 1.2  # peak(100 s) / peak(1 s)


def peak_rss(t_end: float, folder: Path) -> dict:
    """One `mbs run` of the clearance slider-crank (default output step, 10 µs) to t_end seconds."""
    out = folder / f"run_{t_end:g}s.h5"
    t0 = time.perf_counter()
    proc = subprocess.Popen([MBS, "run", str(MODEL), "-o", str(out), "--t-end", f"{t_end}s", "-q", "--force"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    stdout = proc.stdout.read().decode()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(proc.stderr.read().decode()[-2000:])
    size = out.stat().st_size
    out.unlink()
    rows = next((int(w.replace(",", "")) for w in stdout.split("outputs")[-1].split()[:1]), 0)
    return dict(t_end=t_end, peak_mb=usage.ru_maxrss / 1024, wall=wall, rows=rows, file_mb=size / 1e6)


def section_memory(t_ends=(1.0, 10.0, 100.0)) -> dict:
    with tempfile.TemporaryDirectory(prefix="mbs-memory-") as tmp:
        subprocess.run([MBS, "run", str(MODEL), "-o", str(Path(tmp) / "warm.h5"), "--t-end", "0.001s", "-q"],
                       capture_output=True)  # the numba cache filled before the first measurement
        rows = [peak_rss(t, Path(tmp)) for t in t_ends]
    base = rows[0]["peak_mb"]
    for r in rows:
        r["ratio"] = r["peak_mb"] / base
    return dict(rows=rows, target=TARGET)


def table(sec: dict) -> list[str]:
    out = ["| simulated time [s] | output rows | file [MB] | wall [s] | peak RSS [MB] | ÷ 1-s run |",
           "| ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in sec["rows"]:
        out.append(f"| {r['t_end']:g} | {r['rows']:,} | {r['file_mb']:.0f} | {r['wall']:.0f} | {r['peak_mb']:.0f} | "
                   f"{r['ratio']:.2f} |")
    return out


if __name__ == "__main__":
    sec = section_memory(tuple(float(a) for a in sys.argv[1:]) or (1.0, 10.0, 100.0))
    print("\n".join(table(sec)))
