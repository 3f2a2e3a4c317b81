"""A run that blows up stops with exit code 3, says what happened, when, and which joint
or body is involved, and keeps its results up to that moment (marked incomplete)."""
from pathlib import Path

import pytest
from typer.testing import CliRunner

from planar_mbs import read_results
from planar_mbs.cli.app import app

MODELS = Path(__file__).resolve().parents[1] / "models"

TOGGLE = """# non-Grashof four-bar (s + l = 90 > p + q = 80 mm): the crank cannot turn all the way round
body crank_link   { mass = 0.1 kg  inertia = 1e-5 kg*m^2  position = (0.02, 0) }
body coupler_link { mass = 0.1 kg  inertia = 1e-5 kg*m^2  position = (0.06, 0.02) }
body rocker_link  { mass = 0.1 kg  inertia = 1e-5 kg*m^2  position = (0.07, 0.02) angle = 90 deg }
joint O2 = revolute(ground (0, 0), crank_link (-0.02, 0))
joint A  = revolute(crank_link (0.02, 0), coupler_link (-0.025, 0))
joint B  = revolute(coupler_link (0.025, 0), rocker_link (0.02, 0))
joint O4 = revolute(ground (0.07, 0), rocker_link (-0.02, 0))
driver motor = rotation(crank_link, speed = 60 rpm)
simulate { t_end = 1 s  output_step = 1 ms }
"""

BLOW_UP = """# explicit RK4 with a step far beyond the spring's stability limit (omega h = 1e6 rad/s x 1 ms)
body bob { mass = 1 kg  inertia = 1e-3 kg*m^2  position = (0.1, 0) }
force spring = spring_damper(ground (0, 0), bob (0, 0)) { stiffness = 1e12 N/m  length = 0.05 m }
simulate { t_end = 1 s  integrator = rk4  step = 1 ms  output_step = 10 ms }
"""

UNDERFLOW = f"""include "{MODELS / 'slider_crank_clearance_a.mbs'}"
override simulate {{ t_end = 5 rev / speed  h_min = 1e-6 s  rtol = 1e-10  output_step = 10 us }}
"""


@pytest.mark.parametrize("text, status, words", [
    (TOGGLE, "constraints_lost", ["the constraints gave way", "limit position (toggle"]),
    # the state grows by (omega h)^4 / 24 per step: the physical bound stops it before it overflows
    (BLOW_UP, "absurd_state", ["left every physical bound", "of body `bob`", "the step"]),
    (UNDERFLOW, "step_underflow", ["step size fell below h_min", "clearance joint `A` in contact"]),
], ids=["singular", "nan", "underflow"])
def test_failure_exit_3_message_and_partial_results(tmp_path, text, status, words):
    model = tmp_path / "m.mbs"
    model.write_text(text)
    out = tmp_path / "m.h5"
    res = CliRunner().invoke(app, ["run", str(model), "-o", str(out), "-q"])
    assert res.exit_code == 3, res.output
    assert "simulation failed" in res.output and "at t = " in res.output and "Traceback" not in res.output
    for w in words:
        assert w in res.output
    kept = read_results(out)
    assert not kept.complete and kept.attrs["status"] == status
    assert len(kept.time) >= 1 and kept.time[-1] <= kept.attrs["t_reached"]
    assert all(abs(v[-1]) < 1e300 for v in kept.signals.values())  # no NaN written as a result
