"""The worn bearing of the clearance slider-crank: joint A (crank - connecting rod) wearing by Archard's law.

    .venv/bin/python docs/scripts/wear_slider_crank.py

models/slider_crank_clearance_a.mbs (at 5000 and 1200 rpm, c = 0.3 mm, R_B = 5 mm, L = 20 mm, steel, Lankarani-Nikravesh,
c_e = 0.9) with `wear = archard(...)` on A: 4 revolutions to leave the start-up, then WEAR's updates, each
2 revolutions of motion standing for FACTOR; the same worn time with the factor halved (the halving check).
Writes docs/images/wear_slider_crank_<speed>rpm.png and docs/wear_slider_crank.json (the numbers docs/wear.md
quotes).
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

K, H, FACTOR, UPDATES, NODES = 1e-5, 2e9, 1000, 20, 360  # Archard's k, hardness (Pa), cycles per cycle, updates
SPEEDS = (5000, 1200)  # rpm
WARM_UP = 4  # revolutions before the wear starts
TEXT = """include "slider_crank_clearance_a.mbs"
override joint A = clearance_revolute(crank (0.025 m, 0), rod (-0.06 m, 0)) {{
    clearance = clearance  bearing_radius = 5 mm  length = 20 mm  material = steel  law = law
    restitution = restitution
    wear = archard(coefficient = {k}, hardness = {h} Pa, update = 2 rev / speed, factor = {f}, updates = {u},
                   nodes = {n})
}}
"""


def model(rpm, factor=FACTOR, updates=UPDATES, k=K):
    from planar_mbs import compile_text
    return compile_text(TEXT.format(k=k, h=H, f=factor, u=updates, n=NODES),
                        str(ROOT / "models" / "wear_slider_crank.mbs"), speed=f"{rpm} rpm")


def wear_run(rpm, factor=FACTOR, updates=UPDATES, k=K):
    from planar_mbs.run.stepper import Stepper
    from planar_mbs.run.wear import WearRun
    m = model(rpm, factor, updates, k)
    period = 60.0 / rpm
    st = Stepper(m)
    st.run_to(WARM_UP * period)
    run = WearRun(m, "A", stepper=st)
    run.run()
    impacts = int(st.stats[3])  # contact events of the whole run (ST_CONTACT_EVENTS)
    return run, period, impacts


def concentration(depth: np.ndarray, share: float) -> float:
    """The fraction of the circumference whose deepest nodes hold `share` of the worn volume."""
    d = np.sort(depth)[::-1]
    return float(np.searchsorted(np.cumsum(d) / d.sum(), share) + 1) / len(d)


def peaks(depth: np.ndarray, theta: np.ndarray, rel=0.25) -> list[float]:
    """Angles (deg) of the local maxima of the profile above `rel` of its deepest."""
    n = len(depth)
    out = [i for i in range(n) if depth[i] >= depth[i - 1] and depth[i] > depth[(i + 1) % n]
           and depth[i] > rel * depth.max()]
    return [round(math.degrees(theta[i]), 1) for i in out]


def study(rpm: int) -> dict:
    from planar_mbs.outputs.wear_plot import wear_figure
    run, period, impacts = wear_run(rpm)
    h = run.history
    half, _, _ = wear_run(rpm, FACTOR / 2, 2 * UPDATES)
    hh = half.history
    control = wear_run(rpm, k=0.0)[0].history  # the same motion on the unworn bearing
    d = h.depths[-1]
    facts = {
        "k": K, "hardness_pa": H, "k_d_per_pa": K / H, "factor": FACTOR, "updates": UPDATES, "nodes": NODES,
        "cycles_worn": round(h.worn_times[-1] / period), "cycles_simulated": 2 * UPDATES,
        "max_depth_um": round(h.max_depth() * 1e6, 2), "max_angle_deg": round(math.degrees(h.max_angle()), 1),
        "mean_depth_um": round(float(d.mean()) * 1e6, 2),
        "volume_per_width_mm2": round(h.volume() * 1e6, 5),
        "clearance_max_mm": round(0.3 + h.max_depth() * 1e3, 4),
        "share_50_circumference": round(concentration(d, 0.5), 3),
        "share_90_circumference": round(concentration(d, 0.9), 3),
        "peaks_deg": peaks(d, h.theta),
        "halving_depth_change": round(abs(h.max_depth() - hh.max_depth()) / hh.max_depth(), 4),
        "halving_volume_change": round(abs(h.volume() - hh.volume()) / hh.volume(), 4),
        "contact_events": impacts,
        "volume_first_update_mm2": round(h.volume(1) * 1e6, 5),
        "volume_last_update_mm2": round((h.volume(-1) - h.volume(-2)) * 1e6, 5),
        "peak_force_first_update_n": round(h.peak_forces[1], 1), "peak_force_last_update_n": round(h.peak_forces[-1], 1),
        "in_contact_first_update": round(h.in_contact[1], 3), "in_contact_last_update": round(h.in_contact[-1], 3),
        "unworn_peak_force_first_n": round(control.peak_forces[1], 1),
        "unworn_peak_force_last_n": round(control.peak_forces[-1], 1),
        "unworn_in_contact_last": round(control.in_contact[-1], 3),
    }
    fig = wear_figure(h, period=period, curves=5,
                      title=f"slider-crank joint A, {rpm} rpm: Archard k = {K:g}, H = {H / 1e9:g} GPa")
    fig.savefig(ROOT / "docs" / "images" / f"wear_slider_crank_{rpm}rpm.png", dpi=110)
    return facts


def main() -> None:
    facts = {f"{rpm} rpm": study(rpm) for rpm in SPEEDS}
    (ROOT / "docs" / "wear_slider_crank.json").write_text(json.dumps(facts, indent=1) + "\n")
    print(json.dumps(facts, indent=1))


if __name__ == "__main__":
    main()
