"""How tight the shipped models' tolerances must be: the first revolution's slider (or rocker)
velocity at several tolerances against a converged reference (DOP853, rtol 1e-12), and the cost.

    .venv/bin/python docs/scripts/tolerances.py      # writes docs/tolerances_data.json, prints the table
                                                     # of docs/numerics.md ("Tolerances of the shipped models")

At each model's own parameters.  Error = max over the first revolution of |v − v_ref| / max |v_ref| (both sampled at 1200 points of the revolution).
The shipped defaults were chosen as the loosest rtol whose error is below 0.1 % (docs/numerics.md says which still are).
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

CASES = {  # model, signal followed, --set values
    "slider_crank_clearance_a.mbs": ("slider.vx", {}),
    "slider_crank_clearance_b.mbs": ("slider.vx", {}),
    "slider_crank_clearance_ab.mbs": ("slider.vx", {}),
    "four_bar_clearance.mbs": ("rocker_link.omega", {}),
    "four_bar_two_clearances.mbs": ("rocker_link.omega", {}),
}
RTOLS = [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11]


def one(model_file: str, signal: str, speed: str | None, rtol: float, atol: float, integrator="dopri5"):
    from planar_mbs import load_model, simulate
    from planar_mbs.results.section import driver_period

    m = load_model(ROOT / "models" / model_file, **({"speed": speed} if speed else {}))
    T = driver_period(m)[0]
    start = time.process_time()
    r = simulate(m, t_end=T, output_step=T / 1200, rtol=rtol, atol=atol, integrator=integrator, signals=[signal])
    return r[signal], time.process_time() - start, r.attrs["n_steps"]


def main() -> dict:
    from planar_mbs import load_model

    out = {}
    for model_file, (signal, _) in CASES.items():
        try:
            speeds = [None]  # the model's own parameters
            one(model_file, signal, None, 1e-6, 1e-9)
        except Exception as err:  # noqa: BLE001  (a model without that signal: say so)
            out[model_file] = {"error": str(err)}
            continue
        for speed in speeds:
            ref, ref_cpu, _ = one(model_file, signal, speed, 1e-12, 1e-15, "dop853")
            ref2, _, _ = one(model_file, signal, speed, 1e-11, 1e-14, "dop853")
            ref_err = float(np.max(np.abs(ref2 - ref)) / np.max(np.abs(ref)))
            rows = []
            for rtol in RTOLS:
                v, cpu, steps = one(model_file, signal, speed, rtol, rtol * 1e-3)
                err = float(np.max(np.abs(v - ref)) / np.max(np.abs(ref)))
                rows.append({"rtol": rtol, "atol": rtol * 1e-3, "error": err, "cpu": cpu, "steps": steps})
                print(model_file, speed, rtol, f"{err:.2e}", f"{cpu:.2f} s", steps, flush=True)
            out[model_file] = {"signal": signal, "rows": rows, "reference_check": ref_err}
            print(model_file, "reference: DOP853 1e-11 vs 1e-12", f"{ref_err:.1e}", flush=True)
    (ROOT / "docs" / "tolerances_data.json").write_text(json.dumps(out, indent=1))
    return out


def table(data: dict) -> str:
    """The markdown table of docs/numerics.md from `data` (docs/tolerances_data.json): the error at each
    rtol (the shipped rtol's in bold), the reference check, the shipped rtol and the step counts of one
    revolution at rtol 1e-6 and at the shipped rtol (tests/test_doc_numbers.py compares the page with it)."""
    from planar_mbs import load_model

    head = ["model (signal)", *(f"rtol {r:.0e}" for r in RTOLS), "DOP853 1e-11 vs 1e-12", "shipped rtol",
            "steps of 1 rev, 1e-6 → shipped"]
    lines = ["| " + " | ".join(head) + " |", "| " + " | ".join("---" for _ in head) + " |"]
    for model_file, d in data.items():
        shipped = load_model(ROOT / "models" / model_file).settings.rtol
        rows = {r["rtol"]: r for r in d["rows"]}
        cells = [f"**{r['error']:.1e}**" if r["rtol"] == shipped else f"{r['error']:.1e}" for r in d["rows"]]
        first, last = rows[RTOLS[0]]["steps"], rows[shipped]["steps"]
        lines.append("| " + " | ".join([f"`{model_file}` ({d['signal']})", *cells, f"{d['reference_check']:.1e}",
                                        f"{shipped:.0e}", f"{first} → {last} (×{last / first:.1f})"]) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(table(main()))
