"""What a flexible connecting rod costs (docs/beams.md, "Cost"): models/slider_crank_flexible_rod.mbs with
1 to 32 ANCF elements against models/slider_crank.mbs at the same speed (3000 rpm) and with the same
settings (DOPRI5, rtol 1e-8, atol 1e-10: the models' own).

Two tables, time-loop wall seconds (`wall_time`), the least of REPEAT runs after a warm-up:

* cost per accepted step and per right-hand side over the first SHORT seconds, by element count, with
  the straight line a + b elements fitted to the cost per right-hand side and each count's distance from
  it (linear in the elements: the beam's forces are a loop over its elements, its mass solve two banded
  triangular solves per direction);
* the whole two revolutions of the models with 8 elements against the rigid rod: steps, right-hand
  sides, time loop, and their ratios.

    .venv/bin/python benchmarks/beam_cost.py            # prints the tables, writes docs/beam_cost.json
    .venv/bin/python benchmarks/beam_cost.py --page     # prints the page's tables from that JSON
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import planar_mbs as mbs  # noqa: E402

OUT = ROOT / "docs" / "beam_cost.json"
ELEMENTS = (1, 2, 4, 8, 16, 32)
SHORT = 2e-3  # s: a tenth of a revolution at 3000 rpm, enough steps for a per-step cost
REPEAT = 3
RATIO_ELEMENTS = 8


def flexible(elements: int):
    text = (ROOT / "models" / "slider_crank_flexible_rod.mbs").read_text(encoding="utf-8")
    if "elements = 4" not in text:
        raise SystemExit("models/slider_crank_flexible_rod.mbs no longer says `elements = 4`")
    return mbs.compile_text(text.replace("elements = 4", f"elements = {elements}"),
                            path=ROOT / "models" / "slider_crank_flexible_rod.mbs")


def rigid():
    """models/slider_crank.mbs at the flexible model's speed."""
    return mbs.load_model(ROOT / "models" / "slider_crank.mbs", speed="3000 rpm")


def timed(model, **settings) -> dict:
    """The least time-loop wall time of REPEAT runs, with the run's steps and right-hand sides."""
    best = None
    for _ in range(REPEAT):
        a = mbs.simulate(model, signals=["crank.phi"], **settings).attrs
        if a.get("status") != "done":
            raise SystemExit(f"a run failed: {a.get('message')}")
        if best is None or a["wall_time"] < best["wall"]:
            best = {"wall": a["wall_time"], "steps": int(a["n_steps"]), "rhs": int(a["n_rhs"])}
    return best


def per_step_table() -> list[dict]:
    rows = []
    for e in ELEMENTS:
        r = timed(flexible(e), t_end=SHORT)
        rows.append({"elements": e, "coordinates": 4 * (e + 1), **r,
                     "us_per_step": 1e6 * r["wall"] / r["steps"], "us_per_rhs": 1e6 * r["wall"] / r["rhs"]})
    x = np.array([r["elements"] for r in rows], float)
    y = np.array([r["us_per_rhs"] for r in rows])
    b, a = np.polyfit(x, y, 1)
    for r in rows:
        r["fit_deviation"] = r["us_per_rhs"] / (a + b * r["elements"]) - 1.0
    return rows, {"intercept_us": a, "per_element_us": b}


def ratio_table() -> dict:
    flex, rig = timed(flexible(RATIO_ELEMENTS)), timed(rigid())
    return {"elements": RATIO_ELEMENTS, "flexible": flex, "rigid": rig,
            "steps_ratio": flex["steps"] / rig["steps"], "rhs_ratio": flex["rhs"] / rig["rhs"],
            "wall_ratio": flex["wall"] / rig["wall"]}


def machine() -> str:
    """The machine in one line, from `run.machine` (the benchmarks' own description of it)."""
    from run import machine as described

    m = described()
    return f"{m['cpu']}, {m['cores']} cores; Python {m['python']}, numpy {m['numpy']}, numba {m['numba']}"


def markdown(data: dict) -> str:
    """The tables docs/beams.md "Cost" shows, from this script's JSON (tests/test_flexible_slider_crank.py
    checks that the page holds them)."""
    lines = ["| elements | coordinates | steps | per step [µs] | per right-hand side [µs] | off the line |",
             "| ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in data["per_step"]:
        lines.append(f"| {r['elements']} | {r['coordinates']} | {r['steps']:,} | {r['us_per_step']:.1f} | "
                     f"{r['us_per_rhs']:.2f} | {r['fit_deviation']:+.1%} |")
    fit, ratio = data["fit"], data["ratio"]
    f, g = ratio["flexible"], ratio["rigid"]
    lines += ["", f"Fitted line: {fit['intercept_us']:.2f} µs + {fit['per_element_us']:.3f} µs per element "
                  "per right-hand side.", "",
              f"| two revolutions | steps | right-hand sides | time loop [s] |", "| --- | ---: | ---: | ---: |",
              f"| rigid rod (`slider_crank.mbs` at 3000 rpm) | {g['steps']:,} | {g['rhs']:,} | {g['wall']:.4f} |",
              f"| beam of {ratio['elements']} elements | {f['steps']:,} | {f['rhs']:,} | {f['wall']:.2f} |",
              f"| ratio | {ratio['steps_ratio']:,.0f}× | {ratio['rhs_ratio']:,.0f}× | {ratio['wall_ratio']:,.0f}× |"]
    return "\n".join(lines)


def main() -> None:
    timed(flexible(2), t_end=1e-4)  # compile or load the kernels
    rows, fit = per_step_table()
    print(f"{'elements':>8} {'coords':>6} {'steps':>7} {'us/step':>8} {'us/rhs':>7} {'vs line':>8}")
    for r in rows:
        print(f"{r['elements']:8d} {r['coordinates']:6d} {r['steps']:7d} {r['us_per_step']:8.2f} "
              f"{r['us_per_rhs']:7.3f} {r['fit_deviation']:+8.1%}")
    print(f"line: {fit['intercept_us']:.3f} us + {fit['per_element_us']:.3f} us per element")
    ratio = ratio_table()
    f, g = ratio["flexible"], ratio["rigid"]
    print(f"two revolutions, {RATIO_ELEMENTS} elements against the rigid rod: steps {f['steps']} / {g['steps']} "
          f"= {ratio['steps_ratio']:.0f}x, rhs {ratio['rhs_ratio']:.0f}x, time loop {f['wall']:.3f} s / "
          f"{g['wall']:.4f} s = {ratio['wall_ratio']:.0f}x")
    OUT.write_text(json.dumps({"machine": machine(), "short_span_s": SHORT, "per_step": rows, "fit": fit,
                               "ratio": ratio}, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {OUT.relative_to(ROOT)}\n")
    print(markdown(json.loads(OUT.read_text(encoding="utf-8"))))


if __name__ == "__main__":
    if sys.argv[1:] == ["--page"]:
        print(markdown(json.loads(OUT.read_text(encoding="utf-8"))))
    else:
        main()
