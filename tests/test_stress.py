"""Numerical stress tests (slow): each case runs to its end with sane results or
stops with a clear message -- never NaN reported as success.

The cases are data (`CASES`); benchmarks/run.py runs the same list and writes
the table in docs/benchmarks.md.  Run with ``pytest -m slow tests/test_stress.py``.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.mechanism.compile import compile_text
from planar_mbs.errors import SimulationError

MODELS = Path(__file__).resolve().parents[1] / "models"
REV_5000 = 60 / 5000  # s per revolution at 5000 rpm

STIFF = """include "{models}/slider_crank_clearance_a.mbs"
override joint A = clearance_revolute(crank (0.025, 0), rod (-0.06, 0)) {{
    clearance = clearance  bearing_radius = 5 mm  length = 20 mm  material = steel
    law = law  restitution = restitution  stiffness = {K} N/m^1.5
}}
"""

TOGGLE = """include "{models}/four_bar.mbs"
# drive the rocker instead of the crank: at the rocker's extreme angle the crank and
# the coupler are collinear (a toggle) and the mechanism cannot go on
override driver crank_drive = rotation(rocker_link, speed = 60 rpm)
override simulate {{ t_end = 2 s  integrator = dopri5  rtol = 1e-8  output_step = 1 ms }}
"""


def _case(name, kind, value, **settings):
    return dict(name=name, kind=kind, value=value, settings=settings)


CASES = (
    [_case(f"clearance {c * 1e3:g} mm", "set", {"clearance": f"{c * 1e3:g} mm"}, t_end=REV_5000)
     for c in (1e-6, 1e-5, 1e-4, 1e-3)]
    + [_case(f"speed {s} rpm", "set", {"speed": f"{s} rpm"}, t_end=60 / s) for s in (100, 1000, 5000, 20000)]
    + [_case(f"stiffness {K:g} N/m^1.5", "stiffness", K, t_end=REV_5000) for K in (1e6, 1e8, 1e10, 1e12)]
    + [_case(f"restitution {e:g}", "set", {"restitution": f"{e:g}"}, t_end=REV_5000) for e in (0.3, 0.6, 0.9, 1.0)]
    + [_case("four-bar driven through a toggle", "toggle", None)]
)


def load(case):
    if case["kind"] == "set":
        return mbs.load_model(MODELS / "slider_crank_clearance_a.mbs", **case["value"])
    if case["kind"] == "stiffness":
        return compile_text(STIFF.format(models=MODELS, K=case["value"]), "stiff.mbs")
    return compile_text(TOGGLE.format(models=MODELS), "toggle.mbs")


def run_case(case) -> dict:
    """Run one case; returns a row for the table (outcome, message, checks)."""
    import time

    model = load(case)
    start = time.perf_counter()
    try:
        res = mbs.simulate(model, **case["settings"])
        outcome, message = "finished", res.attrs["message"]
    except SimulationError as err:
        res, outcome, message = err.results, "stopped", err.message
    wall = time.perf_counter() - start
    row = dict(name=case["name"], outcome=outcome, message=message, wall=wall,
               steps=int(res.attrs.get("n_steps", 0)), events=int(res.attrs.get("n_contact_events", 0)))
    finite = all(np.all(np.isfinite(v)) for v in res.signals.values())
    row["finite"] = bool(finite)
    row["t_reached"] = float(res.attrs.get("t_reached", float("nan")))
    if "A.e" in res.signals and len(res.time):
        c = model.kernel.clearance_param[0, 0]
        row["max_penetration_over_c"] = float(np.max(res["A.penetration"]) / c)
    row["max_position_error"] = float(np.max(res["system.position_error"])) if len(res.time) else float("nan")
    return row


def check_row(row):
    # never NaN reported as success; a stop says why
    if row["outcome"] == "finished":
        assert row["finite"], row
        assert row["max_position_error"] < 1e-5, row
    else:
        assert row["message"] and "status" not in row["message"], row


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_stress_case(case):
    row = run_case(case)
    check_row(row)
    if case["kind"] == "toggle":
        assert row["outcome"] == "stopped", row
        assert "singular" in row["message"] or "constraints gave way" in row["message"], row
    elif row.get("max_penetration_over_c", 0.0) > 1.0:
        # the journal sank deeper than the clearance: not physical, and a run says so by stopping (exit 3)
        assert row["outcome"] == "stopped" and "not physical" in row["message"], row
    elif case["name"] != "clearance 0.001 mm":
        assert row["outcome"] == "finished", row


def long_run(revolutions=1000, projection=True):
    """1000 crank revolutions at 5000 rpm with the clearance at A and projection:
    constraint drift and the energy balance W_driver - (E(t) - E(0)) >= 0
    (the contact only dissipates)."""
    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    res = mbs.simulate(model, t_end=revolutions * REV_5000, output_step=20e-6, projection=projection,
                       signals=["system", "crank_speed", "A"])
    t = res.time
    E = res["system.total_energy"]
    P = res["crank_speed.power"]
    W = np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1]) * np.diff(t))])
    D = W - (E - E[0])  # energy dissipated by the contact
    return dict(revolutions=revolutions, wall=res.attrs["wall_time"], steps=res.attrs["n_steps"],
                events=res.attrs["n_contact_events"],
                max_position_error=float(np.max(res["system.position_error"])),
                max_velocity_error=float(np.max(res["system.velocity_error"])),
                dissipated=float(D[-1]), min_dissipated=float(D.min()), driver_work_abs=float(np.sum(np.abs(
                    0.5 * (P[1:] + P[:-1]) * np.diff(t)))), finite=bool(np.all(np.isfinite(E))))


@pytest.mark.slow
def test_thousand_revolutions_bounded_drift_no_energy_creation():
    r = long_run()
    assert r["finite"]
    assert r["max_position_error"] <= 1e-8, r
    # no energy creation: what the driver put in minus the change of energy is the
    # contact's dissipation; quadrature of the power on the 20 us grid bounds its accuracy
    assert r["min_dissipated"] >= -1e-3 * r["driver_work_abs"], r
    assert r["dissipated"] > 0, r
