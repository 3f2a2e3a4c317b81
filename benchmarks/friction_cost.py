"""Cost of friction on a clearance slider-crank (docs/benchmarks.md, "Friction"): models/
slider_crank_clearance_a.mbs, frictionless and with mu = 0.1 in each friction model, after a warm-up; prints the CPU time (the least of five runs), its ratio to the frictionless run, the accepted steps per revolution,
the friction events and the share of the time joint A is stuck.

    .venv/bin/python benchmarks/friction_cost.py [revolutions]
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import planar_mbs as mbs

ROOT = Path(__file__).resolve().parents[1]
REPEAT = 5
CASES = (("frictionless", ""), ("coulomb (default)", "friction = 0.1"),
         ("stribeck", "friction = 0.1  static_friction = 0.15  friction_model = stribeck  "
                      "stribeck_velocity = 1 mm/s"),
         ("ambrosio", "friction = 0.1  friction_model = ambrosio"))


def model(extra: str):
    text = (ROOT / "models" / "slider_crank_clearance_a.mbs").read_text(encoding="utf-8")
    text = text.replace("law = law  restitution = restitution\n", f"law = law  restitution = restitution  {extra}\n")
    return mbs.compile_text(text, path=ROOT / "models" / "slider_crank_clearance_a.mbs")


def main(revolutions: float = 5.0) -> None:
    mbs.simulate(model(CASES[1][1]), revolutions=0.2)  # compile, warm
    base = None
    for name, extra in CASES:
        m = model(extra)
        walls = []
        for _ in range(REPEAT):  # the least of a few: the machine is shared
            t0 = time.process_time()
            res = mbs.simulate(m, revolutions=revolutions)
            walls.append(time.process_time() - t0)
        wall = min(walls)
        base = base or wall
        steps = res.attrs.get("n_steps", 0)
        stuck = float(np.mean(res["A.stick"])) if "A.stick" in res else 0.0
        rhs = res.attrs.get("n_rhs", 0)
        print(f"{name:20s} cpu {wall:6.2f} s  ratio {wall / base:5.2f}  steps/rev {steps / revolutions:6.0f}  "
              f"rhs/rev {rhs / revolutions:6.0f}  "
              f"contact+friction events {res.attrs.get('n_contact_events', '?')}  stuck {stuck:5.1%}")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 5.0)
