"""The slider-crank with a translational clearance joint at the slider against the one with a revolute
clearance joint at A, at the same speed and tolerance: time-loop wall time (best of several runs in
this process), steps, right-hand sides and the cost of one of each.  The target: the translational
one within 2x the revolute one.

    .venv/bin/python benchmarks/translational_clearance.py [--revolutions 20] [--repeat 5]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def measure(name: str, revolutions: float, repeat: int, speed: str, rtol: float) -> dict:
    import planar_mbs as mbs

    model = mbs.load_model(ROOT / "models" / f"{name}.mbs", speed=speed)
    best = None
    for _ in range(repeat):
        res = mbs.simulate(model, revolutions=revolutions, per_rev=360, rtol=rtol, atol=rtol * 1e-3)
        a = res.attrs
        if best is None or a["wall_time"] < best["wall_time"]:
            best = {k: a[k] for k in ("wall_time", "n_steps", "n_rejected", "n_rhs", "n_contact_events")}
    best["us_per_rhs"] = 1e6 * best["wall_time"] / best["n_rhs"]
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--revolutions", type=float, default=20)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--speed", default="2500rpm")
    ap.add_argument("--rtol", type=float, default=1e-8)
    args = ap.parse_args(argv)
    rows = {n: measure(n, args.revolutions, args.repeat, args.speed, args.rtol)
            for n in ("slider_crank_clearance_a", "slider_crank_clearance_s")}
    for n, r in rows.items():
        print(f"{n:28s} loop {r['wall_time']:.3f} s  steps {r['n_steps']:7d}  rejected {r['n_rejected']:6d}  "
              f"rhs {r['n_rhs']:8d}  {r['us_per_rhs']:.2f} us/rhs  contact events {r['n_contact_events']}")
    a, s = rows["slider_crank_clearance_a"], rows["slider_crank_clearance_s"]
    ratio = s["wall_time"] / a["wall_time"]
    print(f"translational / revolute clearance: {ratio:.2f}x wall time, "
          f"{s['us_per_rhs'] / a['us_per_rhs']:.2f}x per rhs, {s['n_rhs'] / a['n_rhs']:.2f}x rhs "
          f"({args.revolutions:g} revolutions at {args.speed}, rtol {args.rtol:g}; target <= 2x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
