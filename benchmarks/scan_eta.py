"""How close the progress line's time left is on a real scan, in the order cases run and in the axes' order.

    .venv/bin/python benchmarks/scan_eta.py                       # 5 speeds x 4 laws x 3 clearances x 30 rev, -j 2
    .venv/bin/python benchmarks/scan_eta.py --speeds 10 --revolutions 60

Runs the same scan of models/slider_crank_clearance_a.mbs twice through `run_sweep` with the progress
line's `ProgressTally` (speed outermost, as a user would write it): once in `scan.run_order` (equal
cases spread over the parameters) and once in the order of the axes (all the lowest speed first, as
cases ran before).  After each case it notes the time left the line would show, and for the axes'
order also the one the line showed before (rich's `TimeRemainingColumn`: the cases finished in the
last 30 s over the time between the first and last of them, `rich_estimate`); at the end it prints,
at 10, 25, 50 and 75 % of the cases, how far that was from the time the scan actually took to end,
as a fraction of the whole scan.  Writes nothing else.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "slider_crank_clearance_a.mbs"


def one(order: str, args, folder: Path) -> list[tuple[int, float, float]]:
    """(cases done, seconds since start, time left shown) after each case of one scan."""
    from planar_mbs.sweep import scan
    from planar_mbs.sweep.progress import ProgressTally

    axes = [scan.parse_param(f"speed=500rpm..6000rpm:{args.speeds}"),
            scan.parse_param("law=hertz,lankarani_nikravesh,flores,gonthier"),
            scan.parse_param("clearance=0.1mm..0.5mm:3")]
    tally = ProgressTally(args.jobs)
    marks: list[tuple[int, float, float]] = []

    def progress(done, total, outcome):
        tally.update(done, total, outcome)
        if outcome is not None:
            marks.append((done, tally.elapsed(), tally.remaining_seconds()))

    spread = scan.run_order
    if order == "axes":
        scan.run_order = lambda specs, expected: list(specs)
    try:
        scan.run_sweep(MODEL, axes, folder / f"eta-{order}.h5", revolutions=args.revolutions, per_rev=180,
                       section={}, jobs=args.jobs, progress=progress, overwrite=True)
    finally:
        scan.run_order = spread
    return marks


def rich_estimate(marks: list[tuple[int, float, float]], total: int) -> list[tuple[int, float, float]]:
    """The marks with rich's time left instead (`rich.progress.Task.speed` over its default 30-s window:
    the cases of the window but its first, over the time from its first to its last); None when undefined."""
    out = []
    for k, (done, t, _) in enumerate(marks):
        window = [m[1] for m in marks[:k + 1] if m[1] >= t - 30.0]
        span = window[-1] - window[0]
        out.append((done, t, (total - done) / ((len(window) - 1) / span) if span > 0 else None))
    return out


def errors(marks: list[tuple[int, float, float]]) -> list[str]:
    """The time left at 10, 25, 50 and 75 % of the cases minus the true one, over the whole scan."""
    end, n, cells = marks[-1][1], len(marks), []
    for q in (0.10, 0.25, 0.50, 0.75):
        done, t, left = marks[max(int(q * n) - 1, 0)]
        cells.append("none" if left is None else f"{(left - (end - t)) / end:+.0%}")
    return cells


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--speeds", type=int, default=5)
    ap.add_argument("--revolutions", type=int, default=30)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    print(f"{args.speeds * 12} cases x {args.revolutions} rev, -j {args.jobs}, load {os.getloadavg()[0]:.1f}")
    print("| order | scan [s] | error of the time left at 10 % | 25 % | 50 % | 75 % of the cases |\n"
          "| --- | ---: | ---: | ---: | ---: | ---: |")
    with tempfile.TemporaryDirectory() as tmp:
        for order in ("run_order", "axes"):
            t0 = time.perf_counter()
            marks = one(order, args, Path(tmp))
            wall = time.perf_counter() - t0
            print(f"| {order} | {wall:.1f} | " + " | ".join(errors(marks)) + " |")
            if order == "axes":
                before = rich_estimate(marks, args.speeds * 12)
                print(f"| axes, rich's 30-s window (before) | {wall:.1f} | " + " | ".join(errors(before)) + " |")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
