"""The Python API: the same unit strings as the CLI, models from strings, errors worded for
Python, a step-by-step `Simulation` for notebooks and controllers, and pandas.  References are
closed forms derived here."""
import math
from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.errors import ModelError

MODELS = Path(__file__).resolve().parents[1] / "models"
R, L = 0.05, 0.12  # crank and rod of models/slider_crank.mbs
OMEGA = 5000 * 2 * math.pi / 60

# a wheel on a pin, driven by a torque a controller may change: omega = T t / I piecewise
WHEEL = """
body wheel { mass = 1 kg  inertia = 0.5 kg*m^2  position = (0, 0) }
joint pin = revolute(ground (0, 0), wheel (0, 0))
force motor = torque(wheel, torque = 0 N*m)
simulate { t_end = 1 s  output_step = 10 ms  rtol = 1e-10 }
"""
INERTIA = 0.5


def slider_x(phi):
    """x = r cos θ + √(l² − r² sin² θ) of the ideal slider-crank."""
    return R * np.cos(phi) + np.sqrt(L**2 - (R * np.sin(phi)) ** 2)


def test_exported_names():
    for name in ("load_model", "compile_text", "simulate", "Simulation", "read_results"):
        assert name in mbs.__all__ and callable(getattr(mbs, name))


def test_settings_take_the_cli_unit_strings():
    m = mbs.load_model(MODELS / "slider_crank.mbs")
    res = mbs.simulate(m, t_end="3 ms", output_step="0.5 ms", integrator="DOP853", rtol="1e-9")
    np.testing.assert_allclose(res.time, np.arange(7) * 0.5e-3, atol=1e-15)
    assert res.attrs["settings"]["integrator"] == mbs.run.simulation.Integrator.DOP853
    assert res.attrs["settings"]["rtol"] == 1e-9


def test_revolutions_and_samples_per_revolution():
    m = mbs.load_model(MODELS / "slider_crank.mbs")
    res = mbs.simulate(m, revolutions=1.5, per_rev=8)
    period = 2 * math.pi / OMEGA
    np.testing.assert_allclose(res.time, np.arange(13) * period / 8, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("settings, words", [
    (dict(tend="1 s"), ["unknown setting `tend`", "t_end"]),
    (dict(t_end="3 m"), ["a time was expected", "simulate(t_end=...)"]),
    (dict(integrator="dopri"), ["unknown integrator `dopri`", "dopri5"]),
    (dict(rtol="tight"), ["`rtol` takes a number"]),
    (dict(revolutions=2, t_end=1.0), ["not both"]),
])
def test_bad_settings_are_model_errors_not_type_errors(settings, words):
    m = mbs.load_model(MODELS / "slider_crank.mbs")
    with pytest.raises(ModelError) as err:
        mbs.simulate(m, **settings)
    for w in words:
        assert w in str(err.value)


@pytest.mark.parametrize("overrides, words", [
    (dict(spedd="1 rpm"), ["load_model(spedd=...)", "no param `spedd`", "did you mean `speed`"]),
    (dict(speed="3 m"), ["load_model(speed=...)", "was expected, got a length"]),
    (dict(speed="3 xx"), ["load_model(speed=...)", "unknown unit"]),
])
def test_override_errors_are_worded_for_python(overrides, words):
    with pytest.raises(ModelError) as err:
        mbs.load_model(MODELS / "slider_crank_clearance_a.mbs", **overrides)
    text = str(err.value)
    assert "--set" not in text
    for w in words:
        assert w in text


def test_compile_text_from_a_string_with_overrides():
    text = (MODELS / "slider_crank.mbs").read_text()
    m = mbs.compile_text(text, speed="2500 rpm")
    assert m.parameters["speed"] == "2500 rpm"
    with pytest.raises(ModelError) as err:
        mbs.compile_text(text + "\nbody oops { mass = 3 m }\n")
    assert str(err.value).startswith("<string>:")


def test_step_by_step_controller_against_closed_form():
    """A controller switches the torque on at 0.25 s and doubles it at 0.5 s:
    omega = T (t - 0.25) / I, then + 2T (t - 0.5) / I."""
    sim = mbs.Simulation(mbs.compile_text(WHEEL))
    sim.step("0.25 s")
    assert sim.t == pytest.approx(0.25) and sim.latest("wheel.omega") == pytest.approx(0.0, abs=1e-12)
    sim.set_load("motor", 2.0)
    sim.run_until(0.5)
    assert sim.latest("wheel.omega") == pytest.approx(2.0 * 0.25 / INERTIA, rel=1e-9)
    assert sim.latest("wheel.phi") == pytest.approx(0.5 * 2.0 / INERTIA * 0.25**2, rel=1e-9)
    sim.set_load("motor", 4.0)
    res = sim.run()
    t = res.time
    expected = np.where(t < 0.25, 0.0, 2.0 * (np.minimum(t, 0.5) - 0.25) / INERTIA) \
        + np.where(t > 0.5, 4.0 * (t - 0.5) / INERTIA, 0.0)
    np.testing.assert_allclose(res["wheel.omega"], expected, rtol=1e-9, atol=1e-9)
    assert res.complete and t[-1] == pytest.approx(1.0)
    assert len(t) == 101  # the output grid only: every step ended on it
    with pytest.raises(ModelError, match="did you mean `motor`"):
        sim.set_load("mtor", 1.0)


def test_steps_between_grid_points_follow_the_closed_form():
    """Steps of 1.234 ms across a 0.1 ms grid of the ideal slider-crank: every sample, on the grid
    or at the end of a step, lies on x(theta)."""
    sim = mbs.Simulation(mbs.load_model(MODELS / "slider_crank.mbs"), output_step="0.1 ms", rtol=1e-10)
    while sim.t < sim.t_end:
        sim.step(min(1.234e-3, sim.t_end - sim.t))
    res = sim.close()
    assert np.all(np.diff(res.time) > 0) and res.time[-1] == pytest.approx(sim.t_end)
    off_grid = np.abs(res.time / 1e-4 - np.round(res.time / 1e-4)) > 1e-6
    assert off_grid.sum() >= 3  # the step ends
    np.testing.assert_allclose(res["slider.x"], slider_x(res["crank.phi"]), atol=1e-9)


def test_callback_sees_the_run_and_can_stop_it(tmp_path):
    seen = []

    def callback(sim):
        seen.append(sim.t)
        return sim.t >= 0.3

    # h_max: the integrator's clock runs at most one output step ahead of the samples handed back
    with mbs.Simulation(mbs.compile_text(WHEEL), output=tmp_path / "w.h5", h_max="10 ms") as sim:
        sim.run_until("1 s", callback=callback)
        assert 0.3 <= sim.t < 0.4 and seen[-1] == sim.t and len(seen) >= 2
    back = mbs.read_results(tmp_path / "w.h5")
    assert not back.attrs["complete"] and len(back.time) == len(sim.time)


def test_to_dataframe():
    pd = pytest.importorskip("pandas")
    res = mbs.simulate(mbs.compile_text(WHEEL), t_end="50 ms")
    df = res.to_dataframe()
    assert isinstance(df, pd.DataFrame) and df.index.name == "time"
    assert list(df.columns) == list(res.signals)
    np.testing.assert_array_equal(df["wheel.phi"].to_numpy(), res["wheel.phi"])
    assert df.attrs["units"]["wheel.omega"] == "rad/s"
    assert list(res.to_dataframe(["wheel.x"]).columns) == ["wheel.x"]
