"""What the user chose is accepted, and said back: results kept although not physical when asked
(`allow_unphysical`), one rule for numbers without a unit, warnings when the assembly moves a body far
or turns it onto another branch, messages that point where a value came from, and the stated initial
state of a translational clearance joint kept."""
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import planar_mbs as mbs
from planar_mbs.cli.app import app
from planar_mbs.errors import ModelError, SimulationError
from planar_mbs.mechanism.compile import compile_text
from planar_mbs.sweep.scan import Axis, replay_case, run_sweep

runner = CliRunner()

# ----------------------------------------------------------------------------- allow_unphysical
# A 1 kg pendulum hangs on a revolute clearance joint of 0.01 mm with a soft contact, K = 1e6 N/m^1.5:
# resting, it sinks d = (m g / K)^(2/3) = 0.46 mm into its bearing, far more than the clearance.
SOFT = """
param clearance = {clearance}
gravity (0, -9.81 m/s^2)
body bob { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0 m, -0.2 m) }
joint pin = clearance_revolute(ground (0, 0), bob (0 m, 0.2 m)) {
    clearance = clearance  bearing_radius = 5 mm  law = hertz  stiffness = 1e6 N/m^1.5
}
simulate { t_end = 20 ms  output_step = 1 ms  rtol = 1e-8  atol = 1e-11 }
"""


def soft_model(tmp_path: Path, clearance: str = "0.01 mm") -> Path:
    path = tmp_path / "soft.mbs"
    path.write_text(SOFT.replace("{clearance}", clearance, 1))
    return path


def test_results_not_physical_are_kept_when_asked(tmp_path):
    model = mbs.load_model(soft_model(tmp_path))
    sink = (9.81 / 1e6) ** (2 / 3)  # the resting penetration, m
    with pytest.raises(SimulationError, match="not physical"):  # the default: not a result to use
        mbs.simulate(model)
    res = mbs.simulate(model, output=tmp_path / "kept.h5", allow_unphysical=True)
    assert res.complete and res.attrs["status"] == "done"
    assert res.attrs["allow_unphysical"] is True and "allow_unphysical" in res.attrs["message"]
    assert any("not physical" in w for w in res.attrs["warnings"])  # the warning stays
    assert np.max(res["pin.penetration"]) > 0.5 * sink
    kept = mbs.read_results(tmp_path / "kept.h5")
    assert kept.complete and kept.attrs["allow_unphysical"] is True
    stepped = mbs.Simulation(model, allow_unphysical=True).run()
    assert stepped.complete and stepped.attrs["allow_unphysical"] is True
    plain = mbs.simulate(mbs.load_model(soft_model(tmp_path, "1 mm")))  # physical: nothing recorded
    assert plain.complete and "allow_unphysical" not in plain.attrs


def test_allow_unphysical_on_the_command_line(tmp_path):
    path = soft_model(tmp_path)
    refused = runner.invoke(app, ["run", str(path), "-o", str(tmp_path / "a.h5"), "-q"])
    assert refused.exit_code == 3 and "--allow-unphysical" in refused.output
    kept = runner.invoke(app, ["run", str(path), "-o", str(tmp_path / "b.h5"), "-q", "--allow-unphysical"])
    assert kept.exit_code == 0, kept.output
    assert "not physical" in kept.output  # the warning is printed
    assert mbs.read_results(tmp_path / "b.h5").attrs["allow_unphysical"] is True


def test_allow_unphysical_in_a_sweep(tmp_path):
    path = soft_model(tmp_path)
    axes = [Axis("clearance", ("0.01mm", "0.02mm"))]
    refused = run_sweep(path, axes, tmp_path / "a.h5", jobs=1, section=None)
    assert len(refused.failed) == 2
    kept = run_sweep(path, axes, tmp_path / "b.h5", jobs=1, section=None, allow_unphysical=True)
    assert not kept.failed
    out = runner.invoke(app, ["sweep", str(path), "-P", "clearance=0.01mm,0.02mm", "-o", str(tmp_path / "c.h5"),
                              "-j", "1", "-q", "--no-section", "--allow-unphysical"])
    assert out.exit_code == 0, out.output
    replayed = replay_case(tmp_path / "c.h5", 0)  # the file remembers the choice
    assert replayed.complete and replayed.attrs["allow_unphysical"] is True
