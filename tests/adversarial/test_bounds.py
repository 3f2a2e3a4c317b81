"""Runs that leave every physical bound, or could never end: a huge force over a short run stops at
the bound (exit 3 with the cause, the time and the body; it used to exit 0 "done" with vx = 2e299
m/s and infinite kinetic energy in the file), and a contact that starts deep inside with a
dissipative law, or a lubricated journal of absurd size, is named by `mbs check` and refused before
the run (it used to creep at 1e-12 s steps: 6 ms of 0.5 s in 170 s, or an estimated 31 hours)."""
from __future__ import annotations

import shutil
import warnings

import numpy as np
import pytest

import planar_mbs as api
from advhelp import MODELS, assert_clean, mbs, snapshot
from planar_mbs.errors import ModelError, SimulationError
from planar_mbs.results.hdf5 import _RowPacker
from planar_mbs.results.signals import signal_table

PUSHED = """\
body disc {{ mass = 1 kg  inertia = 1e-3 kg*m^2  position = (0, 0) }}
force push = constant(disc, force = ({force}, 0))
simulate {{ t_end = 0.2 s  output_step = {dt} }}
"""


def test_a_huge_force_over_a_short_run_stops_at_the_bound(sandbox):
    """1e300 N on 1 kg for 0.2 s (one call of the time loop): exit 3 naming the bound and the body, the
    file incomplete, and no row of it beyond the bound or with an infinite energy."""
    (sandbox / "push.mbs").write_text(PUSHED.format(force="1e300 N", dt="10 ms"))
    before = snapshot(sandbox)
    out = mbs("run", "push.mbs", "-o", "x.h5", cwd=sandbox, timeout=120)
    assert_clean(out, 3, "physical bound", "velocity x of body `disc`", "t =", before=before, folder=sandbox,
                 allowed=["x.h5"])
    r = api.read_results(sandbox / "x.h5")
    assert not r.complete and r.attrs["status"] == "absurd_state"
    assert np.all(np.isfinite(r["system.kinetic_energy"])) and np.all(np.abs(r["disc.vx"]) < 1e9)


def test_the_bound_stops_the_run_in_the_step_that_crosses_it(sandbox):
    """1e12 N on 1 kg: vx = 1e12 t m/s (a constant acceleration, which every Runge-Kutta method
    integrates exactly) reaches 1e9 m/s at t = 1 ms.  The run stops at the end of the step that
    crosses it: the state there is beyond the bound at its own time, every row written before is within it."""
    model = api.compile_text(PUSHED.format(force="1e12 N", dt="0.1 ms"))
    with pytest.raises(SimulationError, match="physical bound") as err:
        api.simulate(model)
    t_stop = err.value.time
    assert t_stop >= 1e-3 and t_stop < 0.2
    stated = float(err.value.message.split("velocity x of body `disc` = ")[1].split()[0])
    assert stated == pytest.approx(1e12 * t_stop, rel=5e-3)  # the message writes 3 digits
    rows = err.value.results
    assert rows.attrs["status"] == "absurd_state" and rows.time[-1] < 1e-3 + 1e-12
    assert np.all(rows["disc.vx"] < 1e9) and np.allclose(rows["disc.vx"], 1e12 * rows.time, rtol=1e-9)


def test_simulation_stops_at_the_bound_between_two_grid_points():
    """`Simulation.run_until` a time inside the first chunk: SimulationError, and again on the next call."""
    sim = api.Simulation(api.compile_text(PUSHED.format(force="1e12 N", dt="10 ms")))
    with pytest.raises(SimulationError, match="physical bound"):
        sim.run_until("5 ms")
    with pytest.raises(SimulationError, match="physical bound"):
        sim.run_until("6 ms")


DEEP = """\
param r = 50 mm
param depth = 10 mm
material steel {{ E = 207 GPa  nu = 0.3  density = 7800 kg/m^3 }}
body disc {{ mass = 1 kg  inertia = 1.25e-3 kg*m^2  position = (0, r - depth) }}
gravity (0, -9.81 m/s^2)
joint floor = contact(ground (0, 0), disc) {{
    shape = circle_on_line  normal = (0, 1)  radius = r  {law}
}}
simulate {{ t_end = 0.5 s  rtol = 1e-9  atol = 1e-12  output_step = 1 ms }}
"""
STEEL_LN = "material = steel  law = lankarani_nikravesh  restitution = 0.8"


def test_check_names_a_contact_that_starts_deep_inside(tmp_path):
    (tmp_path / "deep.mbs").write_text(DEEP.format(law=STEEL_LN))
    out = mbs("check", tmp_path / "deep.mbs", cwd=tmp_path)
    assert_clean(out, 0, "warning: contact `floor` starts 10 mm inside (0.2 of its radius", "`mbs run` refuses this")


@pytest.mark.parametrize("how", ["run", "sweep", "api", "simulation"])
def test_a_deep_dissipative_start_is_refused_before_the_run(tmp_path, how):
    """The disc 10 mm inside a steel floor, its impact velocity zero: the law's damping K d^n chi / 1e-5 m/s
    acts in 1e-12 s, so 0.5 s need some 1e11 steps.  Refused at once, at the joint's line, nothing written."""
    path = tmp_path / "deep.mbs"
    path.write_text(DEEP.format(law=STEEL_LN))
    before = snapshot(tmp_path)
    if how in ("run", "sweep"):
        args = (["run", path, "-o", "x.h5"] if how == "run" else
                ["sweep", path, "-P", "depth=10mm", "-o", "x.h5", "-j", "1", "--no-section"])
        out = mbs(*args, cwd=tmp_path, timeout=60)
        if how == "run":
            assert_clean(out, 2, "deep.mbs:6:", "`floor` starts 10 mm inside", "max_steps", before=before,
                         folder=tmp_path, bound=30)
        else:  # the case fails with the sentence, the sweep ends
            assert "Traceback" not in out.output and out.code != 0 and out.seconds < 60, out.output
        return
    model = api.load_model(path)
    with pytest.raises(ModelError, match="starts 10 mm inside.*max_steps"):
        api.simulate(model) if how == "api" else api.Simulation(model)
    assert snapshot(tmp_path) == before


def test_a_soft_contact_at_rest_deep_inside_runs_and_stays_there(tmp_path):
    """Deep is not refused by itself: a soft Hertz contact (K = 1e4 N/m^1.5) holding 1 kg at rest sits at
    its static penetration (m g / K)^(2/3) = 9.9 mm (a fifth of the radius); it is named by `mbs check`
    and runs, and the disc stays there."""
    K, g = 1e4, 9.81
    depth = (g / K) ** (2 / 3)
    text = DEEP.format(law=f"stiffness = {K:g} N/m^1.5  law = hertz").replace("param depth = 10 mm",
                                                                            f"param depth = {depth!r} m")
    (tmp_path / "soft.mbs").write_text(text.replace("t_end = 0.5 s", "t_end = 50 ms"))
    out = mbs("check", tmp_path / "soft.mbs", cwd=tmp_path)
    assert_clean(out, 0, "contact `floor` starts 9.87 mm inside")
    assert "refuses" not in out.output
    res = api.simulate(api.load_model(tmp_path / "soft.mbs"))
    assert np.abs(res["floor.penetration"] - depth).max() < 1e-9


@pytest.mark.parametrize("radius", ["1e6 m", "1000 km"])
def test_an_absurd_lubricated_journal_is_refused_before_the_run(tmp_path, radius):
    """A journal of 1000 km radius: its squeeze film damps the rod in about 1e-11 s, some 1e9 steps
    to t_end (the run was estimated at 31 hours).  Refused at once naming the joint."""
    shutil.copy(MODELS / "slider_crank.mbs", tmp_path)
    text = (MODELS / "slider_crank_lubricated_a.mbs").read_text()
    (tmp_path / "huge.mbs").write_text(text.replace("bearing_radius = 5 mm", f"bearing_radius = {radius}"))
    before = snapshot(tmp_path)
    out = mbs("run", "huge.mbs", "-o", "x.h5", cwd=tmp_path, timeout=60)
    assert_clean(out, 2, "clearance joint `A` has its film acting from the start", "max_steps", before=before,
                 folder=tmp_path, bound=30)
    check = mbs("check", "huge.mbs", cwd=tmp_path)
    assert_clean(check, 0, "`mbs run` refuses this")


def test_a_larger_max_steps_lets_the_user_insist(tmp_path):
    """The refusal is the step limit known in advance: raising max_steps passes it (and the run is the
    user's to stop)."""
    model = api.compile_text(DEEP.format(law=STEEL_LN))
    with pytest.raises(ModelError, match="max_steps"):
        api.Simulation(model)
    sim = api.Simulation(model, max_steps=10**12)
    assert sim.t == 0.0


def test_rows_of_a_run_that_blew_up_are_written_without_a_raw_warning():
    """A row holding inf and -inf (a run that blew up between two checks): its sums (the energy balance)
    and magnitudes are NaN or inf in the file, never a numpy RuntimeWarning on the user's screen."""
    model = api.compile_text(PUSHED.format(force="1 N", dt="10 ms"))
    table = signal_table(model)
    rows = np.zeros((3, 1 + max(c for s in table for c in s.columns)))
    rows[1, :] = np.inf
    rows[2, ::2], rows[2, 1::2] = np.inf, -np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _RowPacker(table).records(rows)
