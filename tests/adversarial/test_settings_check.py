"""One validation of settings for the command line and the Python API (the same refusals, the same
sentence but for how the setting is named), messages that name the real cause, and results that
are not physical ending with a non-zero exit."""
from __future__ import annotations

import re
import sys

import h5py
import numpy as np
import pytest

import planar_mbs as mbs_api
from advhelp import MODELS, assert_clean, mbs, snapshot
from planar_mbs.errors import ModelError, SimulationError

# (CLI options, simulate keywords, the sentence both say)
REFUSED = {
    "rtol=2": (["--rtol", "2"], dict(rtol=2), "must be less than 1"),
    "rtol=1": (["--rtol", "1"], dict(rtol=1), "must be less than 1"),
    "t_end=0": (["--t-end", "0s"], dict(t_end=0), "must be greater than 0"),
    "t_end=-1 ms": (["--t-end=-1ms"], dict(t_end="-1 ms"), "must be greater than 0"),
    "rk4 step=0": (["--integrator", "rk4", "--step", "0s"], dict(integrator="rk4", step=0), "must be greater than 0"),
    "output_step=0": (["--output-step", "0s"], dict(output_step="0 s"), "must be greater than 0"),
    "t_end=1e9 s": (["--t-end", "1e9s"], dict(t_end=1e9), "must be at most 1e+06"),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_the_cli_and_the_api_refuse_alike(sandbox, case):
    """They used to return complete=True with 1-11 samples (rtol=2, rtol=1, t_end=0, "-1 ms"), raise
    "status BAD_INPUT" (step=0) or report "1 columns" (output_step=0) from Python."""
    options, keywords, says = REFUSED[case]
    setting = next(iter(k for k in keywords if k != "integrator"))
    before = snapshot(sandbox)
    out = mbs("run", "dopri.mbs" if "rtol" in setting else "mech.mbs", "-o", "x.h5", "-q", *options,
              cwd=_with_dopri(sandbox))
    assert_clean(out, 2, says, "--" + setting.replace("_", "-"), before=before, folder=sandbox,
                 allowed=["dopri.mbs"])
    model = mbs_api.load_model(sandbox / ("dopri.mbs" if "rtol" in setting else "mech.mbs"))
    with pytest.raises(ModelError, match=f"`{setting} = .*{re.escape(says)}") as err:
        mbs_api.simulate(model, output=sandbox / "x.h5", **keywords)
    assert f"simulate({setting}=...)" in str(err.value)
    with pytest.raises(ModelError, match=re.escape(says)):
        mbs_api.Simulation(model, **keywords)
    assert not (sandbox / "x.h5").exists()


def _with_dopri(sandbox):
    """The sandbox model with an adaptive integrator (tolerances are checked where they are used)."""
    text = (sandbox / "mech.mbs").read_text()
    (sandbox / "dopri.mbs").write_text(text.replace("integrator = rk4  step = 10 us", "integrator = dopri5"))
    return sandbox


def test_run_until_past_t_end_and_latest_of_an_unknown_signal(sandbox):
    sim = mbs_api.Simulation(mbs_api.load_model(sandbox / "mech.mbs"))  # t_end = 1 ms
    with pytest.raises(ModelError, match="past the end of this Simulation"):
        sim.run_until("5 s")
    with pytest.raises(KeyError, match="ram.vz"):  # was "no samples yet", before any step
        sim.latest("ram.vz")
    sim.step("0.5 ms")
    assert np.isfinite(sim.latest("slider.vx"))


def test_to_dataframe_without_pandas_says_how_to_get_it(sandbox, monkeypatch):
    res = mbs_api.read_results(sandbox / "run.h5")
    monkeypatch.setitem(sys.modules, "pandas", None)  # as if it were not installed
    with pytest.raises(ImportError, match=r"planar_mbs\[pandas\]"):
        res.to_dataframe()


def test_one_signal_as_a_string_is_one_signal(sandbox):
    """signals="slider.vx" used to be iterated per character."""
    model = mbs_api.load_model(sandbox / "mech.mbs")
    res = mbs_api.simulate(model, signals="slider.vx")
    assert list(res.signals) == ["slider.vx"]
    assert list(res.to_dataframe("slider.vx").columns) == ["slider.vx"]


@pytest.mark.parametrize("setting,says", [("rtol = 1", "`rtol = 1` must be less than 1"),
                                          ("h_min = 1 ms  h_max = 1 us", "is larger than `h_max")])
def test_settings_in_the_model_file_are_checked_at_their_place(sandbox, setting, says):
    """rtol = 1 in a model used to be accepted (the run then blamed "a toggle or locked position");
    h_min > h_max was reported as "too stiff"."""
    text = (sandbox / "mech.mbs").read_text().replace("simulate {", f"simulate {{ integrator = dopri5  {setting} ")
    text = text.replace("integrator = rk4", "")
    (sandbox / "mech.mbs").write_text(text)
    before = snapshot(sandbox)
    for command in (["check", "mech.mbs"], ["run", "mech.mbs", "-o", "x.h5"]):
        out = mbs(*command, cwd=sandbox)
        assert_clean(out, 2, "mech.mbs:8:", says, before=before, folder=sandbox)


def test_analyze_of_an_empty_run(sandbox):
    """A 0-row file used to say "zero-size array to reduction operation maximum"."""
    with h5py.File(sandbox / "run.h5", "r") as f, h5py.File(sandbox / "empty.h5", "w") as g:
        for k, v in f.attrs.items():
            g.attrs[k] = v
        g.create_dataset("time", data=np.zeros(0))
        for entity in f["signals"]:
            g.create_dataset(f"signals/{entity}", data=f["signals"][entity][:0])
    before = snapshot(sandbox)
    out = mbs("analyze", "empty.h5", cwd=sandbox)
    assert_clean(out, 2, "holds 0 output times", before=before, folder=sandbox)
    assert "zero-size" not in out.output


def test_results_that_are_not_physical_end_with_exit_3(sandbox):
    """1 um of clearance with steel: the journal sinks deeper than the clearance.  It used to exit 0
    with complete = True; now exit 3, and the file says why (status not_physical, the message)."""
    before = snapshot(sandbox)
    out = mbs("run", MODELS / "slider_crank_clearance_a.mbs", "-o", "soft.h5", "-q", "--set", "clearance=1um",
              "--t-end", "10ms", cwd=sandbox, timeout=300)
    assert_clean(out, 3, "not physical", before=before, folder=sandbox, allowed=["soft.h5"])
    kept = mbs_api.read_results(sandbox / "soft.h5")
    assert not kept.complete and kept.attrs["status"] == "not_physical"
    assert "sank" in kept.attrs["message"] and kept.attrs["t_reached"] == pytest.approx(0.01)
    model = mbs_api.load_model(MODELS / "slider_crank_clearance_a.mbs", clearance="1 um")
    with pytest.raises(SimulationError, match="not physical"):
        mbs_api.simulate(model, t_end="10 ms")
    stepped = mbs_api.Simulation(model, t_end="10 ms", output=sandbox / "stepped.h5").run()  # step by step
    assert not stepped.complete and stepped.attrs["status"] == "not_physical"
    assert mbs_api.read_results(sandbox / "stepped.h5").attrs["status"] == "not_physical"
