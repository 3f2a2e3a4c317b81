"""The `mbs` command line end to end, through typer's CliRunner."""
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from planar_mbs import read_results
from planar_mbs.cli.app import app

MODELS = Path(__file__).resolve().parents[1] / "models"
runner = CliRunner()


def test_help_teaches():
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0
    assert "run" in res.output and "check" in res.output and "Exit codes" in res.output


def test_check_accepts_every_shipped_model():
    for path in sorted(MODELS.glob("*.mbs")):
        res = runner.invoke(app, ["check", str(path)])
        assert res.exit_code == 0, (path, res.output)
        assert "of freedom" in res.output


def test_check_reports_clearance_joint():
    res = runner.invoke(app, ["check", str(MODELS / "slider_crank_clearance_a.mbs")])
    assert "clearance joints" in res.output and "lankarani_nikravesh" in res.output


def test_run_with_overrides_writes_results(tmp_path):
    out = tmp_path / "a.h5"
    res = runner.invoke(app, [
        "run", str(MODELS / "slider_crank_clearance_a.mbs"), "-o", str(out), "-q",
        "--set", "speed=2500rpm", "--set", "clearance=0.2 mm", "--set", "law=hertz", "--t-end", "24ms",
    ])
    assert res.exit_code == 0, res.output
    for word in ("steps", "rejected", "rhs evaluations", "contact events", "wall time", "constraint error"):
        assert word in res.output
    r = read_results(out)
    assert r.time[-1] == np.float64(0.024) or abs(r.time[-1] - 0.024) < 1e-12
    assert r.attrs["parameters"]["speed"].startswith("2500")
    assert r.attrs["parameters"]["law"] == "hertz"
    assert r.attrs["n_steps"] > 0 and r.attrs["wall_time"] > 0


def test_rk4_fixed_step(tmp_path):
    out = tmp_path / "rk4.h5"
    res = runner.invoke(app, ["run", str(MODELS / "slider_crank.mbs"), "-o", str(out), "-q",
                              "--integrator", "rk4", "--step", "10us", "--t-end", "2ms"])
    assert res.exit_code == 0, res.output
    assert read_results(out).attrs["n_steps"] == 200


def test_bad_model_exit_2_with_position(tmp_path):
    bad = tmp_path / "bad.mbs"
    bad.write_text("body crank { mass = 3 m  inertia = 1 kg*m^2 }\n")
    res = runner.invoke(app, ["check", str(bad)])
    assert res.exit_code == 2
    assert f"{bad}:1:" in res.output and "mass" in res.output and "^" in res.output
    assert "Traceback" not in res.output


def test_unknown_override_suggests(tmp_path):
    res = runner.invoke(app, ["run", str(MODELS / "slider_crank.mbs"), "-o", str(tmp_path / "x.h5"),
                              "--set", "sped=100rpm"])
    assert res.exit_code == 2 and "speed" in res.output


def test_bad_set_syntax_exit_2():
    res = runner.invoke(app, ["check", str(MODELS / "slider_crank.mbs"), "--set", "speed"])
    assert res.exit_code == 2 and "NAME=VALUE" in res.output


def test_failed_simulation_exit_3_keeps_results(tmp_path):
    model = tmp_path / "tiny.mbs"
    text = (MODELS / "slider_crank.mbs").read_text()
    model.write_text(text + "\noverride simulate { t_end = 10 ms  max_steps = 10 }\n")
    out = tmp_path / "tiny.h5"
    res = runner.invoke(app, ["run", str(model), "-o", str(out), "-q"])
    assert res.exit_code == 3, res.output
    assert "max_steps" in res.output
    assert not read_results(out).complete


def _wait_for_samples(path, proc, timeout=120.0):
    """Wait until the running `mbs run` has flushed at least one chunk to `path` (to the part file
    beside it, which the run moves over `path` when it ends)."""
    import time

    import h5py

    from planar_mbs.results.hdf5 import part_beside

    start = time.monotonic()
    while time.monotonic() - start < timeout:
        assert proc.poll() is None, proc.stderr.read()
        try:
            with h5py.File(part_beside(path), "r", locking=False) as f:
                if f["time"].shape[0] > 0:
                    return
        except (OSError, KeyError):
            pass
        time.sleep(0.1)
    raise AssertionError("no samples written")


def test_sigterm_and_sigint_keep_a_valid_file(tmp_path):
    """Kill a real `mbs run` subprocess mid-run: the file stays valid, marked incomplete."""
    import signal
    import subprocess
    import sys

    for sig, code in ((signal.SIGTERM, 143), (signal.SIGINT, 130)):
        out = tmp_path / f"killed_{sig.name}.h5"
        proc = subprocess.Popen(
            [sys.executable, "-c", "from planar_mbs.cli.app import main; main()", "run",
             str(MODELS / "slider_crank_clearance_a.mbs"), "-o", str(out), "-q", "--t-end", "100 s"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        _wait_for_samples(out, proc)
        proc.send_signal(sig)
        proc.wait(timeout=60)
        assert proc.returncode == code, proc.stderr.read()
        kept = read_results(out)
        assert not kept.complete and kept.attrs["status"] == "interrupted"
        assert 0 < kept.time[-1] < 100 and len(kept.time) == len(kept["slider.x"])


@pytest.mark.slow
def test_sigterm_while_a_recording_is_written_leaves_no_file(tmp_path):
    """SIGTERM to `mbs view` halfway through writing a 20-MB recording: exit 143, and neither the
    recording nor the hidden file it was being written to is left (the process used to end where it
    stood, with the file half-written)."""
    import signal
    import subprocess
    import sys
    import time

    results = tmp_path / "a.h5"
    mbs = str(Path(sys.executable).with_name("mbs"))
    subprocess.run([mbs, "run", str(MODELS / "slider_crank_clearance_a.mbs"), "-o", str(results), "--t-end", "1s",
                    "-q"], check=True, capture_output=True)
    proc = subprocess.Popen([mbs, "view", str(results), "-o", str(tmp_path / "v.rrd")], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and not list(tmp_path.glob(".v.rrd.*.part")):  # rerun has started writing
        time.sleep(0.02)
    assert list(tmp_path.glob(".v.rrd.*.part")), "the recording never started"
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.h5"]


DROPPED_SIGTERM = """
import signal, time, weakref
from planar_mbs.cli.entry import stop_cleanly_on_sigterm
stop_cleanly_on_sigterm()
class Thing:
    pass
thing = Thing()
ref = weakref.ref(thing, lambda r: signal.raise_signal(signal.SIGTERM))
try:
    del thing  # SIGTERM arrives while Python runs a weakref callback: an exception there is dropped
    for _ in range(100):
        time.sleep(0.01)  # the command goes on working
    print("ran to the end")
finally:
    print("finally ran")
"""


def test_a_sigterm_that_lands_in_a_weakref_callback_still_ends_the_command():
    """SIGTERM's SystemExit raised inside a weakref callback is dropped by Python (printed as
    "Exception ignored ... SystemExit: 143", the command ran on to exit 0); the signal is sent again
    and ends the command with 143, its `finally` blocks run, nothing on stderr."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", DROPPED_SIGTERM], capture_output=True, text=True, timeout=60)
    assert out.returncode == 143, out.stdout + out.stderr
    assert out.stdout.split() == ["finally", "ran"] and out.stderr == ""


SWALLOWED_SIGTERM = """
import signal, sys
from planar_mbs.cli.common import internal_error
from planar_mbs.cli.entry import stop_cleanly_on_sigterm
stop_cleanly_on_sigterm()
try:
    try:
        signal.raise_signal(signal.SIGTERM)
    except SystemExit:  # what numpy's comparison of structured arrays does with its callee's exception
        raise TypeError("Cannot compare structured arrays unless they have a common dtype.")
    finally:
        print("finally ran")
except Exception as exc:
    sys.exit(internal_error(exc))
"""


def test_a_sigterm_that_c_code_turns_into_another_error_still_exits_143():
    """SIGTERM's SystemExit raised in Python code that numpy calls while it compares structured
    arrays came back as a TypeError, reported as a bug (exit 1, "internal error"); the handler notes
    the signal first, so the command ends with 143 and nothing on stderr."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", SWALLOWED_SIGTERM], capture_output=True, text=True, timeout=60)
    assert out.returncode == 143, out.stdout + out.stderr
    assert out.stdout.split() == ["finally", "ran"] and out.stderr == ""


def test_second_writer_of_a_results_file_is_refused(tmp_path):
    """Two processes writing one results file: the second gets a clear error (exit 2) and the
    first one's file is not touched."""
    import subprocess
    import sys

    import signal

    out = tmp_path / "shared.h5"
    first = subprocess.Popen(
        [sys.executable, "-c", "from planar_mbs.cli.app import main; main()", "run",
         str(MODELS / "slider_crank_clearance_a.mbs"), "-o", str(out), "-q", "--t-end", "100 s"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    _wait_for_samples(out, first)
    res = runner.invoke(app, ["run", str(MODELS / "slider_crank.mbs"), "-o", str(out), "-q", "--t-end", "1ms"])
    assert first.poll() is None  # the first run was still writing
    assert res.exit_code == 2, res.output
    assert "being written by a run (python, pid" in res.output and "Traceback" not in res.output
    first.send_signal(signal.SIGINT)
    assert first.wait(timeout=60) == 130, first.stderr.read()
    kept = read_results(out)  # the first run's own samples, from its model
    assert kept.attrs["status"] == "interrupted" and "A.contact_force" in kept and kept.time[-1] > 0.001
