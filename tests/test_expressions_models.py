"""The shipped models with expression loads and tables, against balances derived here."""
from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs

MODELS = Path(__file__).resolve().parent.parent / "models"


def _integral(t, f):
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t)))


def test_crank_shaper_quick_return_and_work_of_the_cut():
    """Crank radius r = 0.1 m, pivots d = 0.2 m apart: the slow stroke takes 180 + 2 asin(r/d) = 240 deg
    of crank turn.  The mechanism is driven at constant speed without gravity, so over a revolution the
    driver's work equals the work of the cutting force: 800 N times the ram's stroke."""
    res = mbs.simulate(mbs.load_model(MODELS / "crank_shaper.mbs", speed="60 rpm"), t_end="1 s",
                       output_step="0.1 ms")
    t, vx, x = res.time, res["ram.vx"], res["ram.x"]
    cutting = np.mean(vx[:-1] < 0)
    assert cutting == pytest.approx(240 / 360, abs=2e-3)
    stroke = x.max() - x.min()
    work = _integral(t, res["drive.power"])
    assert work == pytest.approx(800 * stroke, rel=1e-4)
    assert res.attrs["n_rejected"] <= 5


def test_engine_work_balance():
    """Gas force (the table, evaluated here from the file) times the piston's speed, plus the brake's
    -c omega^2, integrated over the run, equals the change of kinetic energy."""
    from planar_mbs.mechanism.tables import evaluate, knots, read_csv

    model = mbs.load_model(MODELS / "single_cylinder_engine.mbs", interpolation="linear")
    res = mbs.simulate(model, t_end="0.1 s", output_step="20 us")
    xs, ys = read_csv((MODELS / "engine_gas_force.csv").read_text(), "engine_gas_force.csv")
    rows = knots(np.radians(xs), ys * 1e3, "linear", 4 * np.pi)
    gas = -np.array([evaluate(rows, 4 * np.pi, p) for p in res["crank.phi"]])
    power = gas * res["piston.vx"] - 0.02 * res["crank.omega"] ** 2
    ke = res["system.kinetic_energy"]
    scale = _integral(res.time, np.abs(power))
    assert _integral(res.time, power) == pytest.approx(ke[-1] - ke[0], abs=1e-4 * scale)
    assert res.attrs["n_rejected"] <= res.attrs["n_steps"] // 20  # the knots are events


def test_motor_drives_the_clearance_slider_crank_near_its_synchronous_speed():
    res = mbs.simulate(mbs.load_model(MODELS / "slider_crank_motor.mbs"), t_end="30 ms")
    rpm = res["crank.omega"] * 60 / (2 * np.pi)
    assert 4600 < rpm.mean() < 5400  # on the stable side of the breakdown torque
    np.testing.assert_allclose(res["flywheel.omega"], res["crank.omega"], rtol=1e-6)
    assert res.attrs["n_contact_events"] > 0
