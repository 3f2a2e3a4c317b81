"""What a rerun recording costs against the compiled time loop (issue 5's budget: 20 %).

    .venv/bin/python benchmarks/rerun_logging.py

Runs the shipped clearance model for 5 and 50 crank revolutions and prints, for
each, the time loop, the best of three recordings (envelope and full signals)
and their ratio, measured in one process.  rerun's one-time import is excluded.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import planar_mbs as mbs
from planar_mbs.outputs import rerun_log

MODEL = Path(__file__).resolve().parents[1] / "models" / "slider_crank_clearance_a.mbs"


def main() -> None:
    model = mbs.load_model(MODEL)
    rerun_log._rerun()  # import once, outside the timing
    print(f"{'revolutions':>11} {'signals':>9} {'time loop':>10} {'recording':>10} {'ratio':>6}")
    with tempfile.TemporaryDirectory() as tmp:
        for revs in (5, 50):
            res = mbs.simulate(model, t_end=revs * 60 / 5000)
            loop = res.attrs["wall_time"]
            for signals in ("envelope", "full"):
                best = min(rerun_log.record_run(res, model, Path(tmp) / "r.rrd", signals=signals).seconds
                           for _ in range(3))
                print(f"{revs:>11} {signals:>9} {loop * 1e3:>8.1f}ms {best * 1e3:>8.1f}ms {best / loop:>6.0%}")


if __name__ == "__main__":
    main()
