"""A million cycles of wear on the clearance slider-crank, timed, with the accuracy of the extrapolation.

    .venv/bin/python benchmarks/wear_million_cycles.py

Joint A of models/slider_crank_clearance_a.mbs at 1200 rpm wears with the settings of
docs/scripts/wear_slider_crank.py (k = 1e-5, H = 2 GPa, 360 nodes, 4 revolutions of start-up), each update
2 revolutions of motion standing for as many cycles as make its deepest node wear a depth step, until
10^6 cycles are worn.  The same with the step halved, twice, gives the accuracy of the extrapolation.
Each update's cost is split into the motion (the stepper's run) and the update itself (the wear summed
over the samples, the profile added and handed to the kernel): their ratio, measured in the same run.
Writes docs/wear_million_cycles.json (quoted by docs/wear.md, "A million cycles").
"""
from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "scripts"))

import wear_slider_crank as W  # noqa: E402

RPM, CYCLES = 1200, 1_000_000
DEPTH_STEPS = (8e-6, 4e-6, 2e-6)  # m worn at the deepest node per update: the step follows the wear rate
OUT = ROOT / "docs" / "wear_million_cycles.json"


def at_cycles(h, cycles: float, period: float):
    """The deepest depth and the volume at `cycles` worn: within an update the profile grows linearly in
    the worn time (its increment times the update's factor), so the interpolation is exact."""
    import numpy as np
    worn = np.array(h.worn_times) / period
    i = int(np.searchsorted(worn, cycles))
    w = (cycles - worn[i - 1]) / (worn[i] - worn[i - 1])
    depth = (1 - w) * h.depths[i - 1] + w * h.depths[i]
    volume = (1 - w) * h.volume(i - 1) + w * h.volume(i)
    return float(depth.max()), float(volume)


def timed_run(depth_step: float) -> dict:
    """Updates of `depth_step` until CYCLES are worn: the final numbers, the wall time and the motion's share."""
    from planar_mbs.run.stepper import Stepper
    from planar_mbs.run.wear import Archard, WearRun

    m = W.model(RPM)
    period = 60.0 / RPM
    st = Stepper(m)
    st.run_to(W.WARM_UP * period)
    motion = [0.0]
    run_to = st.run_to

    def timed(t):
        t0 = time.perf_counter()
        out = run_to(t)
        motion[0] += time.perf_counter() - t0
        return out

    st.run_to = timed
    a = Archard.of(m, "A")
    run = WearRun(m, "A", Archard(a.coefficient, a.interval, a.factor, 10**6, a.nodes, depth_step), stepper=st)
    t0 = time.perf_counter()
    while run.history.worn_times[-1] < CYCLES * period:
        run.step()
    wall = time.perf_counter() - t0
    depth, volume = at_cycles(run.history, CYCLES, period)
    updates = len(run.history.depths) - 1
    return dict(depth_step_um=depth_step * 1e6, updates=updates, cycles_simulated=2 * updates, wall_s=round(wall, 2),
                motion_s=round(motion[0], 2), update_s=round(wall - motion[0], 3),
                update_over_motion=round((wall - motion[0]) / motion[0], 4),
                max_depth_um=round(depth * 1e6, 2), volume_mm2=round(volume * 1e6, 5),
                clearance_max_mm=round((0.3e-3 + depth) * 1e3, 4))


def main() -> None:
    runs = [timed_run(d) for d in DEPTH_STEPS]
    a, b, c = runs
    change = lambda x, y, k: abs(x[k] - y[k]) / y[k]  # noqa: E731
    data = dict(rpm=RPM, cycles=CYCLES, runs=runs,
                halving_depth_change=round(change(a, b, "max_depth_um"), 4),
                halving_volume_change=round(change(a, b, "volume_mm2"), 4),
                second_halving_depth_change=round(change(b, c, "max_depth_um"), 4),
                second_halving_volume_change=round(change(b, c, "volume_mm2"), 4),
                machine=f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    OUT.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    print(json.dumps(data, indent=1))


if __name__ == "__main__":
    main()
