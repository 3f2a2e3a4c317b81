"""Limits are errors, not bugs: a file-size limit stops a run like a full disk (exit 3, a readable
prefix), a run whose bound is known before it starts is refused at once, a state beyond every
physical bound stops the run (exit 3), and closed, full or ASCII-only standard streams never
give a traceback."""
from __future__ import annotations

import os
import resource
import subprocess
import time

import pytest

import planar_mbs as mbs_api
from advhelp import MBS, MODELS, Outcome, assert_clean, mbs, snapshot
from planar_mbs.errors import ModelError, SimulationError


def _run(args, cwd, env=None, limit=None, stdout=subprocess.PIPE, timeout=180) -> Outcome:
    """`mbs ARGS` as a process, with `limit` = (resource, value) set in it first."""
    def preexec():
        if limit:
            resource.setrlimit(limit[0], (limit[1], limit[1]))

    start = time.perf_counter()
    proc = subprocess.run([str(MBS), *map(str, args)], cwd=cwd, stdout=stdout, stderr=subprocess.PIPE,
                          env=dict(os.environ, COLUMNS="160", **(env or {})), preexec_fn=preexec, timeout=timeout)
    text = (proc.stdout.decode(errors="replace") if isinstance(proc.stdout, bytes) else "") + \
        proc.stderr.decode(errors="replace")
    return Outcome(proc.returncode, text, time.perf_counter() - start)


def test_a_file_size_limit_keeps_a_readable_prefix(sandbox):
    """`ulimit -f` (4 MB) below what 60 revolutions write: exit 3 naming the limit, and the file holds
    the rows up to it, marked incomplete (it used to be an internal error and an unreadable file)."""
    model = MODELS / "slider_crank_clearance_a.mbs"
    before = snapshot(sandbox)
    out = _run(["run", model, "-o", "big.h5", "-n", "60", "-q"], sandbox,
               limit=(resource.RLIMIT_FSIZE, 4_000_000))
    assert_clean(out, 3, "file-size limit", before=before, folder=sandbox, allowed=["big.h5"])
    kept = mbs_api.read_results(sandbox / "big.h5")
    assert not kept.complete and kept.attrs["status"] == "disk_full" and len(kept.time) > 0
    assert (sandbox / "big.h5").stat().st_size <= 4_000_000


@pytest.mark.parametrize("how", ["cli", "api"])
def test_an_rk4_step_that_cannot_reach_t_end_is_refused_at_once(sandbox, how):
    """step x max_steps < t_end is known before the run (it used to run 5 minutes to the step limit)."""
    before = snapshot(sandbox)
    if how == "cli":
        out = mbs("run", "mech.mbs", "-o", "x.h5", "--integrator", "rk4", "--step", "1e-30s", cwd=sandbox,
                  timeout=30)
        assert_clean(out, 2, "--step", "max_steps", before=before, folder=sandbox)
    else:
        with pytest.raises(ModelError, match="step = 1e-30 s.*max_steps"):
            mbs_api.simulate(mbs_api.load_model(sandbox / "mech.mbs"), step="1e-30 s", output=sandbox / "x.h5")
        assert snapshot(sandbox) == before


def test_simulation_memory_is_bounded_up_front(sandbox):
    """`Simulation` keeps every row in memory: rows that cannot fit are refused when it is made, and
    run_until past t_end is refused (it used to grow memory without limit: 0.8 -> 4.4 GB in 20 s)."""
    model = mbs_api.load_model(sandbox / "mech.mbs")
    with pytest.raises(ModelError, match="would not fit"):
        mbs_api.Simulation(model, t_end="100 s", output_step="1 ns")
    sim = mbs_api.Simulation(model)
    with pytest.raises(ModelError, match="past the end"):
        sim.run_until(1e12)
    assert sim.t == 0.0


def test_an_absurd_state_stops_the_run(sandbox):
    """A body given 1e30 m/s: the run stops at once with exit 3 naming the body (it used to crawl at
    1 us of simulated time per second with a garbage state)."""
    text = (sandbox / "parts" / "bodies.mbs").read_text()
    (sandbox / "parts" / "bodies.mbs").write_text(text.replace("position = (0.025, 0)",
                                                               "position = (0.025, 0)  velocity = (1e30 m/s, 0)"))
    out = mbs("run", "mech.mbs", "-o", "x.h5", "-q", cwd=sandbox, timeout=60)
    assert out.code in (2, 3), out.output  # assembly may already refuse it
    assert "Traceback" not in out.output and "internal error" not in out.output
    if out.code == 3:
        assert "physical bound" in out.output and mbs_api.read_results(sandbox / "x.h5").attrs["status"] \
            == "absurd_state"


def test_an_absurd_state_during_the_run_stops_it(sandbox):
    """The time loop hands back a state beyond every bound: SimulationError, status absurd_state."""
    from planar_mbs.run import driver

    model = mbs_api.load_model(sandbox / "mech.mbs")
    real = driver.absurd_state
    calls = []

    def after_first_chunk(model_, y, t):
        calls.append(t)
        if len(calls) > 1:
            y[model_.ncoord] = 1e30  # as if a step had produced it
        return real(model_, y, t)

    driver.absurd_state = after_first_chunk
    try:
        with pytest.raises(SimulationError, match="physical bound") as err:
            mbs_api.simulate(model, t_end="5 ms", output_step="1 us")
    finally:
        driver.absurd_state = real
    assert err.value.results.attrs["status"] == "absurd_state"


# ---------------------------------------------------------------- standard streams
STREAM_CASES = {
    "check, stdout closed": (["check", "mech.mbs"], dict(stdout=None), 1, "cannot write"),
    "check, stdout /dev/full": (["check", "mech.mbs"], dict(stdout="/dev/full"), 1, "No space left"),
    "run, stdout closed": (["run", "mech.mbs", "-o", "x.h5"], dict(stdout=None), 1, "cannot write"),
    "run, stdout /dev/full": (["run", "mech.mbs", "-o", "x.h5"], dict(stdout="/dev/full"), 1, "No space left"),
    "check, ascii": (["check", "mech.mbs"], dict(env={"PYTHONIOENCODING": "ascii"}), 0, "degrees of freedom"),
    "run, ascii": (["run", "mech.mbs", "-o", "x.h5"], dict(env={"PYTHONIOENCODING": "ascii"}), 0, "-> x.h5"),
    "sweep, ascii": (["sweep", "mech.mbs", "-P", "speed=3000rpm,4000rpm", "-o", "x.h5", "-j", "1", "--t-end", "1ms",
                      "--no-section"], dict(env={"PYTHONIOENCODING": "ascii"}), 0, ""),
}


@pytest.mark.parametrize("case", list(STREAM_CASES))
def test_standard_streams(sandbox, case):
    """`>&-`, `>/dev/full`, PYTHONIOENCODING=ascii: no traceback (they used to give one, or exit 1
    "internal error ... isatty"); a lost output is exit 1 with a sentence on stderr, and the run's
    file is written whole all the same; non-ASCII characters degrade to ASCII."""
    args, how, code, words = STREAM_CASES[case]
    before = snapshot(sandbox)
    if "stdout" in how and how["stdout"] is None:
        out = _closed_stdout(args, sandbox)
    elif "stdout" in how:
        with open(how["stdout"], "wb") as full:
            out = _run(args, sandbox, stdout=full)
    else:
        out = _run(args, sandbox, env=how["env"])
        out.output.encode("ascii")  # every character ASCII
    assert_clean(out, code, *([words] if words else []), before=before, folder=sandbox, allowed=["x.h5"])
    assert "internal error" not in out.output, out.output
    if "x.h5" in args:
        assert (sandbox / "x.h5").exists()


def _closed_stdout(args, cwd) -> Outcome:
    start = time.perf_counter()
    proc = subprocess.run(["sh", "-c", '"$@" >&-', "sh", str(MBS), *map(str, args)], cwd=cwd,
                          stderr=subprocess.PIPE, env=dict(os.environ, COLUMNS="160"), timeout=180)
    return Outcome(proc.returncode, proc.stderr.decode(errors="replace"), time.perf_counter() - start)
