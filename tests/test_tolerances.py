"""--atol beside --rtol; tolerances double precision cannot deliver are refused (exit 2) with
the floor named; a step-size underflow names what limited the step."""
from pathlib import Path

import pytest
from typer.testing import CliRunner

import planar_mbs as mbs
from planar_mbs import read_results
from planar_mbs.cli.app import app
from planar_mbs.errors import ModelError, SimulationError

MODELS = Path(__file__).resolve().parents[1] / "models"
runner = CliRunner()


def test_atol_is_used(tmp_path):
    out = tmp_path / "a.h5"
    res = runner.invoke(app, ["run", str(MODELS / "slider_crank.mbs"), "-q", "-o", str(out), "--t-end", "1ms",
                              "--rtol", "1e-8", "--atol", "1e-12"])
    assert res.exit_code == 0, res.output
    settings = read_results(out).attrs["settings"]
    assert settings["rtol"] == 1e-8 and settings["atol"] == 1e-12


@pytest.mark.parametrize("args, says", [(["--rtol", "1e-20"], "2.22e-15"), (["--rtol", "0"], "--rtol"),
                                        (["--atol", "0"], "atol = 0 must be positive")])
def test_undeliverable_tolerances_are_refused(tmp_path, args, says):
    res = runner.invoke(app, ["run", str(MODELS / "slider_crank.mbs"), "-q", "-o", str(tmp_path / "a.h5"),
                              "--t-end", "1ms", *args])
    assert res.exit_code == 2, res.output
    assert says in res.output and "Traceback" not in res.output
    assert not (tmp_path / "a.h5").exists()
    res = runner.invoke(app, ["sweep", str(MODELS / "slider_crank.mbs"), "-P", "speed=800rpm,900rpm", "-o",
                              str(tmp_path / "s.h5"), "-q", "--t-end", "1ms", *args])
    assert res.exit_code == 2 and says in res.output, res.output


def test_rk4_ignores_the_tolerances():
    model = mbs.load_model(MODELS / "slider_crank.mbs")
    mbs.simulate(model, t_end=1e-5, integrator="rk4", rtol=1e-20)  # below the floor: RK4 does not use it
    with pytest.raises(ModelError, match="`rtol = 0` must be greater than 0"):  # a mistake wherever given
        mbs.simulate(model, t_end=1e-5, integrator="rk4", rtol=0.0)
    with pytest.raises(ModelError, match="below what double precision can deliver"):
        mbs.simulate(model, t_end=1e-5, rtol=1e-16)


def test_step_underflow_names_what_limited_the_step():
    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    with pytest.raises(SimulationError, match=r"the error estimate of the (position|velocity) \w+ of body `\w+` "
                                              r"limited it \(rtol = 1e-10"):
        mbs.simulate(model, t_end=5e-3, rtol=1e-10, atol=1e-13, h_min=1e-5)
