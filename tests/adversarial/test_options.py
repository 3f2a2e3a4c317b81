"""Bad option values, every command: refused with exit 2 before anything runs (no output
file appears, nothing else changes), the message naming the option."""
from __future__ import annotations

import pytest

from advhelp import assert_clean, mbs, snapshot

TIMES = ["0", "0 s", "-1 s", "-0.5ms", "nan s", "inf s", "-inf s", "1e9 s", "1e300 s", "abc", "1 m", "5 kg"]
TOLERANCES = ["0", "-1e-8", "1", "1.5", "1e300", "nan", "inf", "-inf"]
POSITIVE_COUNTS = ["0", "-1", "-0.5", "nan", "inf", "1e99"]

RUN_CASES = (
    [("--t-end", v) for v in TIMES]
    + [("--step", v) for v in ["0", "0 us", "-1us", "nan us", "inf s", "2 kg", "1e9 s"]]
    + [("--rtol", v) for v in TOLERANCES]
    + [("--integrator", v) for v in ["rk5", "euler", "dopri", "RK45", "dop85"]]
    + [("--rerun-signals", v) for v in ["fulll", "all", "envelop", "none"]]
    + [("--magnify", v) for v in ["nan", "inf", "-1"]]
    + [("--fps", v) for v in ["0", "-30", "nan", "inf"]]
    + [("--keep", v) for v in ["slider.xx", "slidr", "", " , ", "time", "slider.x,,nope"]]
)


@pytest.mark.parametrize("option,value", RUN_CASES)
def test_run_refuses_bad_option(sandbox, option, value):
    before = snapshot(sandbox)
    out = mbs("run", "mech.mbs", "-o", "out.h5", option, value, "-q", cwd=sandbox)
    assert_clean(out, 2, option.split("-")[-1], before=before, folder=sandbox)


SWEEP_CASES = (
    [("--t-end", v) for v in TIMES[:9]]
    + [("--output-step", v) for v in ["0", "-1us", "nan us", "inf us", "3 kg"]]
    + [("--rtol", v) for v in TOLERANCES]
    + [("--revolutions", v) for v in POSITIVE_COUNTS]
    + [("--integrator", v) for v in ["rk5", "euler"]]
    + [("--jobs", v) for v in ["0", "-1", "100000"]]
    + [("--transient", v) for v in ["-1", "nan", "inf"]]
    + [("--period", v) for v in ["0", "-1ms", "nan ms", "3 kg"]]
    + [("--angle", v) for v in ["nan deg", "inf deg", "90 kg"]]
    + [("--keep", v) for v in ["slider.xx", "slidr.x", "slidr", "crank.phi,slider.vv", "time", "slider.x,,nope"]]
    + [("--param", v) for v in ["speed", "speed=", "=1rpm", "speed=1rpm..2rpm:0", "speed=1..2",
                                "speed=1rpm..2kg:3", "speed=1rpm,1rpm"]]
)


@pytest.mark.parametrize("option,value", SWEEP_CASES)
def test_sweep_refuses_bad_option(sandbox, option, value):
    before = snapshot(sandbox)
    base = ["-P", "speed=3000rpm,4000rpm"] if option != "--param" else []
    jobs = ["-j", "1"] if option != "--jobs" else []
    out = mbs("sweep", "mech.mbs", *base, "-o", "new.h5", *jobs, option, value, "-q", cwd=sandbox)
    word = "param" if option == "--param" else option.split("-")[-1]
    assert_clean(out, 2, before=before, folder=sandbox)
    assert word in out.output.lower() or "keep" in option or "swept" in out.output, out.output


VIEW_CASES = ([("--signals", v) for v in ["ful", "all", "", "none"]]
              + [("--magnify", v) for v in ["nan", "inf", "-2"]]
              + [("--fps", v) for v in ["0", "nan", "inf", "-1"]]
              + [("--signal-rate", v) for v in ["0", "nan", "inf"]]
              + [("--signal-stride", v) for v in ["0", "-3"]])


@pytest.mark.parametrize("option,value", VIEW_CASES)
def test_view_refuses_bad_option(sandbox, option, value):
    before = snapshot(sandbox)
    out = mbs("view", "run.h5", "-o", "new.rrd", option, value, cwd=sandbox)
    assert_clean(out, 2, before=before, folder=sandbox)
    assert option.split("-")[-1] in out.output.lower() or "signal-stride" in option, out.output


PLOT_CASES = ([("--format", v) for v in ["jpg", "gif", "png2", ""]] + [("--skip", v) for v in ["-1", "x"]]
              + [(o, v) for o in ("--from", "--to") for v in ["nan s", "inf s", "-1 s", "3 kg"]] + [("--to", "0 s")])


@pytest.mark.parametrize("option,value", PLOT_CASES)
def test_plot_refuses_bad_option(sandbox, option, value):
    before = snapshot(sandbox)
    out = mbs("plot", "run.h5", "-o", "figs", option, value, cwd=sandbox)
    assert_clean(out, 2, before=before, folder=sandbox)


ANALYZE_CASES = ([("--transient", v) for v in ["-1", "nan", "inf"]]
                 + [("--period", v) for v in ["0", "-1ms", "nan s", "1 kg"]]
                 + [("--angle", v) for v in ["nan deg", "inf deg", "1 kg"]]
                 + [("--poincare", v) for v in ["slider.vx", ":", "a:"]])


@pytest.mark.parametrize("option,value", ANALYZE_CASES)
def test_analyze_refuses_bad_option(sandbox, option, value):
    before = snapshot(sandbox)
    out = mbs("analyze", "run.h5", option, value, "--store", cwd=sandbox)
    assert_clean(out, 2, option.split("-")[-1], before=before, folder=sandbox)


@pytest.mark.parametrize("value", ["speed", "speed=", "=3", "speed=1 parsec", "speed=((", "nosuch=1",
                                   "speed=1e", "speed=" + "9" * 400])
@pytest.mark.parametrize("command", ["check", "run"])
def test_bad_set_values(sandbox, command, value):
    before = snapshot(sandbox)
    extra = ["-o", "new.h5", "-q"] if command == "run" else []
    out = mbs(command, "mech.mbs", "--set", value, *extra, cwd=sandbox)
    assert_clean(out, 2, before=before, folder=sandbox)


def test_t_end_and_revolutions_together(sandbox):
    before = snapshot(sandbox)
    out = mbs("sweep", "mech.mbs", "-P", "speed=3000rpm", "-o", "new.h5", "--t-end", "1ms", "-n", "2", cwd=sandbox)
    assert_clean(out, 2, "--revolutions", before=before, folder=sandbox)
