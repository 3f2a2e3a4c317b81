"""Cost against the order of the model text and against N (issue: any planar mechanism).

    .venv/bin/python benchmarks/order_scaling.py            # prints a Markdown table, writes JSON
    PYTHONPATH=/path/to/older/checkout .venv/bin/python benchmarks/order_scaling.py --json old.json

* cost per accepted DOPRI5 step of the parallelogram chain (0.2 s from the top: no
  singular position yet) with its joints written along the chain, reversed,
  grouped by kind and shuffled, N = 10, 20, 40, 80;
* cost per right-hand side from 41 to 321 bodies: an open pendulum chain
  (41 and 321 bars) and the closed-loop parallelogram chain (N = 20 and 160).
Models come from tests/chains.py; every number is the best of 3 (rhs) or 5 (steps) repeats.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import chains  # noqa: E402
import planar_mbs as mbs  # noqa: E402
from planar_mbs.mechanism.compile import compile_text  # noqa: E402


def per_step(text: str) -> float:
    """Time-loop seconds per accepted step (best of 3), microseconds."""
    model = compile_text(text, "bench.mbs")
    mbs.simulate(model, t_end=0.01)  # compile / warm up
    best = math.inf
    for _ in range(5):
        res = mbs.simulate(model)
        best = min(best, res.attrs["wall_time"] / max(1, res.attrs["n_steps"]))
    return best * 1e6


def per_rhs(text: str) -> float:
    """Microseconds per right-hand side (kernel `rhs` in a compiled loop, best of 3)."""
    from numba import njit

    from planar_mbs.kernel import make_workspace
    from planar_mbs.kernel.dynamics import rhs
    from planar_mbs.mechanism.kinematics import assemble
    from planar_mbs.mechanism.model import N_STATS

    global _loop
    if "_loop" not in globals():
        @njit(cache=False)
        def _loop(km, cfg, y, contact, ws, stats, ydot, n):
            for i in range(n):
                rhs(km, cfg, 1e-3, y, contact, ws, stats, ydot)
    model = compile_text(text, "bench.mbs")
    q, qd = assemble(model)
    km = model.kernel
    y = np.concatenate([q, qd])
    ws = make_workspace(km)
    cfg = model.settings.cfg()
    contact = np.zeros((0, 3))
    stats = np.zeros(N_STATS, np.int64)
    ydot = np.zeros_like(y)
    _loop(km, cfg, y, contact, ws, stats, ydot, 2)
    n = max(20, int(200_000 / len(q)))
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        _loop(km, cfg, y, contact, ws, stats, ydot, n)
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e6


def measure() -> dict:
    orders = {}
    for N in (10, 20, 40, 80):
        row = {}
        for order in chains.ORDERS:
            row[order] = per_step(chains.parallelogram_chain(N, order=order, t_end=0.2, rtol=1e-8,
                                                             atol=1e-10, output_step=0.05))
        row["slowest/fastest"] = max(row.values()) / min(row.values())
        orders[N] = row
        print(f"N={N}: " + "  ".join(f"{k} {v:.3g}" for k, v in row.items()), flush=True)
    scaling = {}
    for label, small, large in (
            ("open chain (pendulum)", chains.pendulum_chain(41), chains.pendulum_chain(321)),
            ("closed loops (parallelogram)", chains.parallelogram_chain(20), chains.parallelogram_chain(160)),
            ("closed loops, driven, shuffled text", chains.parallelogram_chain(20, held=True, order="shuffled"),
             chains.parallelogram_chain(160, held=True, order="shuffled"))):
        a, b = per_rhs(small), per_rhs(large)
        scaling[label] = dict(rhs_41=a, rhs_321=b, ratio=b / a, ratio_over_linear=(b / a) / (321 / 41))
        print(f"{label}: 41 bodies {a:.3g} us, 321 bodies {b:.3g} us, ratio {b / a:.3g} "
              f"({(b / a) / (321 / 41):.2f} x linear)", flush=True)
    return dict(orders=orders, scaling=scaling)


def markdown(data: dict, before: dict | None = None) -> str:
    out = ["| N (bodies) | chain | reversed | grouped | shuffled | slowest/fastest |",
           "| --- | --- | --- | --- | --- | --- |"]
    for N, row in data["orders"].items():
        cells = [f"{row[o]:.3g}" for o in chains.ORDERS]
        ratio = f"{row['slowest/fastest']:.2f}"
        if before and str(N) in before["orders"]:
            b = before["orders"][str(N)]
            cells = [f"{row[o]:.3g} ({b[o]:.3g})" for o in chains.ORDERS]
            ratio += f" ({b['slowest/fastest']:.2f})"
        out.append(f"| {N} ({2 * int(N) + 1}) | " + " | ".join(cells) + f" | {ratio} |")
    out += ["", "| chain | rhs, 41 bodies [µs] | rhs, 321 bodies [µs] | ratio | ratio / linear (7.83) |",
            "| --- | --- | --- | --- | --- |"]
    for label, r in data["scaling"].items():
        extra = ""
        if before and label in before["scaling"]:
            b = before["scaling"][label]
            extra = f" (before: {b['rhs_41']:.3g} → {b['rhs_321']:.3g} µs, {b['ratio_over_linear']:.2f} × linear)"
        out.append(f"| {label} | {r['rhs_41']:.3g} | {r['rhs_321']:.3g} | {r['ratio']:.3g} | "
                   f"{r['ratio_over_linear']:.2f}{extra} |")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", default=str(ROOT / "docs" / "order_scaling_data.json"))
    ap.add_argument("--before", default="", help="JSON of an older checkout, shown in brackets")
    args = ap.parse_args()
    data = measure()
    Path(args.json).write_text(json.dumps(data, indent=1))
    before = json.loads(Path(args.before).read_text()) if args.before else None
    print(markdown(json.loads(json.dumps(data)), before))


if __name__ == "__main__":
    main()
