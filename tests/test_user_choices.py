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
from planar_mbs.mechanism.kinematics import assemble, assembly_changes, assembly_warnings
from planar_mbs.mechanism.model import CP_R_BEARING
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


# ----------------------------------------------------------------------------- translational clearance start
# A slider-crank whose slider sits in a translational clearance guide (0.1 mm wider than the block); the crank is
# not driven but turns at a stated 100 rad/s, the slider is stated tilted and turning.  At the collinear pose
# (crank angle 0) the crank pin A moves at (0, r w) and the slider centre B, pinned to the rod, at (0, vy): the
# rod turns at (vy - r w) / l and its centre moves at (0, (r w + vy) / 2) -- a state that closes every joint.
R_CRANK, L_ROD, W_CRANK = 0.05, 0.12, 100.0


def slider_in_guide(slider: str, guide: str = "", vy: float = 0.0) -> str:
    w_rod = (vy - R_CRANK * W_CRANK) / L_ROD
    return f"""
body crank  {{ mass = 0.3 kg  inertia = 1e-5 kg*m^2  position = (25 mm, 0)  omega = {W_CRANK} rad/s
              velocity = (0, {R_CRANK * W_CRANK / 2} m/s) }}
body rod    {{ mass = 0.21 kg  inertia = 2.5e-4 kg*m^2  position = (110 mm, 0)  omega = {w_rod!r} rad/s
              velocity = (0, {(R_CRANK * W_CRANK + vy) / 2!r} m/s) }}
body slider {{ mass = 0.14 kg  inertia = 1e-4 kg*m^2  position = (170 mm, 0)  {slider} }}
joint O = revolute(ground (0, 0), crank (-25 mm, 0))
joint A = revolute(crank (25 mm, 0), rod (-60 mm, 0))
joint B = revolute(rod (60 mm, 0), slider (0, 0))
joint S = clearance_translational(ground (0, 0), slider (0, 0), axis = (1, 0)) {{
    clearance = 0.1 mm  length = 30 mm  width = 15 mm  stiffness = 1e9 N/m^1.5  law = hertz  {guide}
}}
simulate {{ t_end = 1 ms }}
"""


def test_translational_clearance_keeps_the_stated_tilt_and_velocities():
    """The block is free to turn and to move across its guide: its stated angle (0.1 deg) and angular
    velocity (5 rad/s) and a velocity across the guide that the rod's motion agrees with are kept, and so
    is the crank's stated speed; the assembly says it changed nothing."""
    vy = 0.01
    model = compile_text(slider_in_guide(f"angle = 0.1 deg  omega = 5 rad/s  velocity = (0, {vy} m/s)", vy=vy))
    q, qd = assemble(model)
    assert q[8] == pytest.approx(math.radians(0.1), abs=1e-12)  # the slider's angle
    assert qd[8] == pytest.approx(5.0, abs=1e-9) and qd[7] == pytest.approx(vy, abs=1e-12)
    assert qd[2] == pytest.approx(W_CRANK, abs=1e-9)  # the crank's stated speed
    assert assembly_changes(model, q, qd) == []


def test_translational_clearance_initial_state_fields():
    """`offset`, `tilt`, `relative_velocity` and `tilt_rate` place the block in its guide: y = offset (the
    guide's left normal is +y), angle = tilt, vy = relative_velocity, omega = tilt_rate."""
    model = compile_text(slider_in_guide("", "offset = 0.01 mm  tilt = 0.1 deg  relative_velocity = 0.01 m/s  "
                                             "tilt_rate = 5 rad/s", vy=0.01))
    q, qd = assemble(model)
    assert q[7] == pytest.approx(1e-5, abs=1e-12) and q[8] == pytest.approx(math.radians(0.1), abs=1e-12)
    assert qd[7] == pytest.approx(0.01, abs=1e-12) and qd[8] == pytest.approx(5.0, abs=1e-9)
    # the offset tilts the rod by 1e-5 m / l: the stated rod velocities are off by that order, and the
    # minimum-norm correction moves the crank's speed by far less
    assert qd[2] == pytest.approx(W_CRANK, rel=1e-6)
    with pytest.raises(ModelError, match="corner beyond its guide"):  # 0.5 deg: a corner 0.13 mm across
        compile_text(slider_in_guide("", "tilt = 0.5 deg"))


# ----------------------------------------------------------------------------- messages that point where
CRANK = """
param speed = 5000 rpm
param clearance = 0.3 mm
body crank { mass = 0.3 kg  inertia = 1e-5 kg*m^2  position = (25 mm, 0) }
joint O = clearance_revolute(ground (0, 0), crank (-25 mm, 0)) {
    clearance = clearance  bearing_radius = 5 mm  stiffness = 1e10 N/m^1.5  law = hertz
}
driver d = rotation(crank, speed = speed)
simulate { t_end = 2 rev / speed }
"""


def test_a_set_without_unit_is_reported_at_the_set():
    """`--set speed=900`: reported at the `--set` (not at `t_end`, where `rev / 900` is no time) and naming
    the unit the model's `speed` has."""
    with pytest.raises(ModelError) as info:
        compile_text(CRANK, "crank.mbs", {"speed": "900"})
    e = info.value
    assert e.file == "--set" and e.source_line == "speed=900" and e.column == len("speed=") + 1
    assert "`--set speed=900`" in e.message and "--set speed=900rpm" in e.hint
    with pytest.raises(ModelError) as py:  # the same, worded for Python
        mbs.compile_text(CRANK, "crank.mbs", speed="900")
    assert "--set" not in str(py.value) and 'speed="900rpm"' in str(py.value)
    assert compile_text(CRANK, "crank.mbs", {"speed": "900 rpm"}).parameters["speed"] == "900 rpm"


def test_a_value_of_the_wrong_sign_is_shown_with_its_origin():
    """A negative clearance from a `--set`: the message gives the value and the `--set` it came from, the
    caret is under the field, the example is the value with the right sign, in its unit."""
    with pytest.raises(ModelError) as info:
        compile_text(CRANK, "crank.mbs", {"clearance": "-0.1 mm"})
    e = info.value
    assert "must be positive, got -0.1 mm (from `--set clearance=-0.1 mm`)" in e.message
    assert (e.line, e.column, e.width) == (6, 5, len("clearance")) and "`clearance = 0.1 mm`" in e.hint


@pytest.mark.parametrize("load, example", [
    ("torque = 2 + 1 N*m", "`2 N*m`"),
    ("fx = 3 + crank.vx * 1 kg/s", "`3 N`"),
    ("torque = 2 + crank.omega * 1 N*m*s", "`2 N*m`"),
])
def test_the_unit_hint_shows_a_real_unit(load, example):
    with pytest.raises(ModelError) as info:
        compile_text(CRANK + f"force f = expression(crank, {load})\n")
    assert example in info.value.hint and "..." not in info.value.hint


# ----------------------------------------------------------------------------- one rule for numbers without unit
PIN = """
body b {{ mass = 1 kg  inertia = 1e-3 kg*m^2  position = {position} }}
joint j = clearance_revolute(ground (0, 0), b (0, 0)) {{
    clearance = 0.1 mm  bearing_radius = {radius}  stiffness = 1e9 N/m^1.5  law = hertz
}}
force push = expression(b, fx = {fx})
"""


def test_a_number_without_unit_is_taken_in_si_and_warned_about():
    """`bearing_radius = 4` is 4 m, as an expression's plain `2` is 2 N: both said, with the unit taken and
    the unit to write; zero and numbers with units say nothing."""
    m = compile_text(PIN.format(position="(0, 0)", radius="4", fx="2"), "pin.mbs")
    assert m.kernel.clearance_param[0, CP_R_BEARING] == 4.0  # taken in SI
    radius, force = m.warnings
    assert radius.startswith("pin.mbs:4:") and "warning: `bearing_radius = 4` has no unit: taken as 4 m" in radius
    assert "`4 mm`" in radius and "^" in radius
    assert "`2` (force `push` (expression)'s `fx`) has no unit: taken as 2 N" in force
    vector = compile_text(PIN.format(position="(57, 53)", radius="4 mm", fx="2 N"), "pin.mbs").warnings
    assert len(vector) == 1 and "`position = (57, 53)` has no unit: taken as (57 m, 53 m)" in vector[0]
    assert compile_text(PIN.format(position="(0, 0.1 m)", radius="4 mm", fx="0")).warnings == []


def test_the_command_line_prints_the_unit_warnings(tmp_path):
    path = tmp_path / "pin.mbs"
    path.write_text(PIN.format(position="(0, 0)", radius="4", fx="2 N"))
    res = runner.invoke(app, ["check", str(path)])
    assert res.exit_code == 0 and "warning: `bearing_radius = 4` has no unit: taken as 4 m" in res.output


# ----------------------------------------------------------------------------- what the assembly moved
# A crank-rocker sketched at crank angle 60 deg: crank 20 mm, coupler 80 mm, rocker 60 mm, frame 70 mm (the
# coupler's and rocker's poses solved to 3 digits, so the assembly corrects them by micrometres).
FOUR_BAR = """
body crank   { mass = 0.05 kg  inertia = 2e-6 kg*m^2   position = (5 mm, 8.66 mm)  angle = 60 deg }
body coupler { mass = 0.2 kg   inertia = 1e-4 kg*m^2   position = {coupler}  angle = 31.79 deg }
body rocker  { mass = 0.15 kg  inertia = 4.5e-5 kg*m^2  position = (74 mm, 29.73 mm)  angle = 82.34 deg }
joint O2 = revolute(ground (0, 0), crank (-10 mm, 0))
joint A  = revolute(crank (10 mm, 0), coupler (-40 mm, 0))
joint B  = revolute(coupler (40 mm, 0), rocker ({b} mm, 0))
joint O4 = revolute(ground (70 mm, 0), rocker ({o4} mm, 0))
driver d = rotation(crank, speed = 300 rpm)
simulate { t_end = 10 ms  output_step = 1 ms }
"""


def four_bar(coupler="(44 mm, 38.39 mm)", b="30", o4="-30"):
    return compile_text(FOUR_BAR.replace("{coupler}", coupler).replace("{b}", b).replace("{o4}", o4))


def test_the_assembly_warns_when_it_moves_a_body_far_or_turns_it_onto_another_branch():
    """The sketch as drawn: no warning.  The coupler at (57, 53) (metres: millimetres were meant) is moved
    by 77.8 m, far beyond half the mechanism's size (80 mm: twice the coupler's half length); the rocker
    with its ends swapped closes the loop only with a body turned far from its drawn angle."""
    fine = four_bar()
    assert assembly_warnings(fine, assemble(fine)[0]) == []
    far = four_bar(coupler="(57, 53)")
    q, _ = assemble(far)
    moved = float(np.hypot(q[3] - 57, q[4] - 53))
    (warning,) = assembly_warnings(far, q)
    assert "`coupler`" in warning and f"{moved:.3g} m" in warning and "80 mm" in warning
    swapped = four_bar(b="-30", o4="30")
    q, _ = assemble(swapped)
    turned = np.degrees(np.abs(q[2::3] - swapped.q0[2::3]))
    warnings = assembly_warnings(swapped, q)
    assert turned.max() > 45 and any("turned" in w and f"{turned.max():.3g}°" in w for w in warnings)
    res = mbs.simulate(far)  # and the run says it too
    assert any("`coupler`" in w for w in res.attrs["warnings"])
