"""`mbs run` and `mbs plot` of a model whose joint wears, end to end through the command line: the file is
the library's `WearRun(...).run()` bit for bit; a run stopped (by its total or by Ctrl-C/SIGTERM) and
resumed equals an uninterrupted one to 1e-6 of the deepest depth; bad resumes and options that do not
apply exit 2 with a hint; `mbs plot` draws the file; a model without `wear` runs as before."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import planar_mbs as mbs
from planar_mbs import read_results
from planar_mbs.cli.app import app
from planar_mbs.run.wear import WearRun, load_history

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()

# a journal spun at 100 rad/s in a bearing on the ground under its weight: it drops into contact and
# wears one groove; 4 updates of 10 ms of motion, each standing for 100 ms of wear (about 1 s per run)
JOURNAL = """
param omega = 100 rad/s
body journal {{ mass = 1 kg  inertia = 1e-4 kg*m^2 }}
joint J = clearance_revolute(ground (0, 0), journal) {{
    clearance = 0.1 mm  bearing_radius = 5 mm  length = 10 mm  law = kelvin_voigt  stiffness = 2e6 N/m
    restitution = 0.05
    {wear}
}}
driver spin = rotation(journal, speed = omega)
gravity (0, -10 m/s^2)
simulate {{ t_end = 20 ms  rtol = 1e-9  atol = 1e-12  output_step = 0.5 ms }}
"""
WEAR = "wear = archard(coefficient = {k}, hardness = 1 GPa, update = 10 ms, factor = 10, updates = 4, nodes = 90)"


def _model(folder: Path, name: str = "journal.mbs", k: str = "0.02", wear: bool = True) -> Path:
    path = folder / name
    path.write_text(JOURNAL.format(wear=WEAR.format(k=k) if wear else ""))
    return path


def _mbs(*args):
    r = runner.invoke(app, [str(a) for a in args])
    assert "Traceback" not in r.output, r.output
    return r


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    """The uninterrupted 4-update run, made by the library."""
    folder = tmp_path_factory.mktemp("library")
    model = mbs.load_model(_model(folder))
    return WearRun(model, "J").run(output=folder / "lib.h5")


def test_a_wear_model_runs_the_wear_run_of_the_library(tmp_path, whole):
    """`mbs run MODEL -o FILE`: one line per update and a summary; the file holds the library's history,
    bit for bit (depths, times, worn times, peak forces)."""
    out = tmp_path / "w.h5"
    r = _mbs("run", _model(tmp_path), "-o", out)
    assert r.exit_code == 0, r.output
    lines = [line for line in r.output.splitlines() if line.startswith("update")]
    assert len(lines) == 4 and all(w in lines[-1] for w in ("4/4", "cycles", "mm²", "µm at", "peak force"))
    assert "finished 4 updates" in r.output and "mbs plot" in r.output
    h = load_history(out)
    np.testing.assert_array_equal(np.array(h.depths), np.array(whole.depths))
    for a, b in ((h.times, whole.times), (h.worn_times, whole.worn_times), (h.peak_forces, whole.peak_forces)):
        np.testing.assert_array_equal(a, b)
    assert not (tmp_path / "w.h5.part").exists()


def test_a_run_stopped_by_its_total_and_resumed_equals_an_uninterrupted_one(tmp_path, whole):
    """--updates 2, then --resume --updates 4 on the same file: the deepest depth of the uninterrupted run
    to 1e-6 (the resumed integrator restarts its step size: not bit for bit)."""
    model, out = _model(tmp_path), tmp_path / "w.h5"
    assert _mbs("run", model, "-o", out, "--updates", "2").exit_code == 0
    assert len(load_history(out).depths) == 3
    r = _mbs("run", model, "-o", out, "--resume", "--updates", "4")
    assert r.exit_code == 0, r.output
    assert "resuming" in r.output and [ln[:10] for ln in r.output.splitlines() if ln.startswith("update")] == \
        ["update   3", "update   4"]
    h = load_history(out)
    assert len(h.depths) == 5 and h.worn_times[-1] == pytest.approx(whole.worn_times[-1], rel=1e-12)
    np.testing.assert_allclose(h.depths[-1], whole.depths[-1], rtol=0, atol=1e-6 * whole.max_depth())


def test_resume_finds_the_default_file_and_goes_on_to_a_new_total(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    model = _model(tmp_path)
    assert _mbs("run", model, "-q").exit_code == 0
    assert len(load_history(tmp_path / "results" / "journal.h5").depths) == 5
    r = _mbs("run", model, "--resume")
    assert r.exit_code == 2 and "holds 4 updates already" in r.output and "--updates 8" in r.output
    assert _mbs("run", model, "--resume", "--updates", "5").exit_code == 0
    assert len(load_history(tmp_path / "results" / "journal.h5").depths) == 6


def _plain_results(folder: Path) -> Path:
    out = folder / "plain.h5"
    assert _mbs("run", _model(folder, "plain.mbs", wear=False), "-o", out, "-q").exit_code == 0
    return out


@pytest.mark.parametrize("case, words", [
    ("missing", ["no such file", "without --resume"]),
    ("plain results", ["holds no wear history"]),
    ("other model file", ["it was made from", "other.mbs"]),
    ("other coefficient", ["the wear of `J` differs", "coefficient"]),
    ("other parameters", ["the parameters differ", "omega"]),
    ("other bodies", ["not one of this model"]),
])
def test_a_bad_resume_exits_2_with_a_hint(tmp_path, case, words):
    model, out = _model(tmp_path), tmp_path / "w.h5"
    args = []
    if case == "plain results":
        out = _plain_results(tmp_path)
    elif case != "missing":
        other = _model(tmp_path, "other.mbs") if case == "other model file" else model
        assert _mbs("run", other, "-o", out, "-q", "--updates", "1").exit_code == 0
        if case == "other coefficient":
            _model(tmp_path, k="0.03")
        if case == "other bodies":  # the same file, edited: a second body on a pin
            model.write_text(model.read_text() + "body extra { mass = 1 kg  inertia = 1e-4 kg*m^2  position = (1 m, 0) }"
                             "\njoint E = revolute(ground (1 m, 0), extra)\n")
        args = ["--set", "omega=50 rad/s"] if case == "other parameters" else []
    before = out.read_bytes() if out.exists() else None
    r = _mbs("run", model, "-o", out, "--resume", *args)
    assert r.exit_code == 2 and "--resume: error: cannot resume" in r.output and "\nhint: " in r.output, r.output
    assert all(w in r.output for w in words), r.output
    assert (out.read_bytes() if out.exists() else None) == before  # the file is left as it was


@pytest.mark.parametrize("option, hint", [
    (["--t-end", "1s"], "--updates N"), (["-n", "3"], "--updates N"), (["--until-settled"], "never settles"),
    (["--keep", "journal"], "not the signals"), (["--rerun", "x.rrd"], "mbs view"),
    (["--resume", "--from-static"], "drop --from-static"),
])
def test_options_that_do_not_apply_to_a_wear_run_exit_2_with_a_hint(tmp_path, option, hint):
    r = _mbs("run", _model(tmp_path), "-o", tmp_path / "w.h5", *option)
    assert r.exit_code == 2 and "does not apply" in r.output and hint in r.output, r.output
    assert not (tmp_path / "w.h5").exists()


def test_a_new_run_never_replaces_an_unfinished_wear_run_or_another_file_unless_told(tmp_path):
    model, out = _model(tmp_path), tmp_path / "w.h5"
    assert _mbs("run", model, "-o", out, "-q", "--updates", "1").exit_code == 0
    with __import__("h5py").File(out, "a") as f:
        f["wear/J"].attrs["updates"] = 4  # as a run of 4 stopped after its first update leaves it
    r = _mbs("run", model, "-o", out, "-q")
    assert r.exit_code == 2 and "unfinished wear run (1 of 4" in r.output and "--resume" in r.output
    assert _mbs("run", model, "-o", out, "-q", "--overwrite").exit_code == 0
    assert len(load_history(out).depths) == 5
    assert _mbs("run", model, "-o", out, "-q").exit_code == 0  # a finished one is replaced, as a run's results
    r = _mbs("run", _model(tmp_path, "plain.mbs", wear=False), "-o", out, "-q")
    assert r.exit_code == 2 and "the file of a wear run" in r.output and "--overwrite" in r.output
    notes = tmp_path / "notes.h5"
    notes.write_text("my notes")
    r = _mbs("run", model, "-o", notes, "-q")
    assert r.exit_code == 2 and "--overwrite" in r.output and notes.read_text() == "my notes"
    r = _mbs("run", model, "-o", model)
    assert r.exit_code == 2 and "the model file" in r.output


def test_plot_draws_the_wear_file_beside_it_or_in_the_output_folder(tmp_path):
    import matplotlib.image
    out = tmp_path / "w.h5"
    assert _mbs("run", _model(tmp_path), "-o", out, "-q").exit_code == 0
    r = _mbs("plot", out)
    assert r.exit_code == 0 and r.output.strip() == str(tmp_path / "w_wear.png"), r.output
    image = matplotlib.image.imread(tmp_path / "w_wear.png")
    assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 400 and image.std() > 0.01
    r = _mbs("plot", out, "-o", tmp_path / "figs", "-f", "svg", "--title", "J after 4 updates")
    assert r.exit_code == 0 and "J after 4 updates" in (tmp_path / "figs" / "w_wear.svg").read_text()
    r = _mbs("plot", out, "J.contact_force")
    assert r.exit_code == 2 and "does not apply to the file of a wear run" in r.output and "hint:" in r.output


def test_a_model_without_wear_runs_as_before(tmp_path):
    """The run's file is `simulate`'s, with no wear in it; --resume and --updates are refused."""
    from planar_mbs.run.simulation import simulate
    out = _plain_results(tmp_path)
    mine = simulate(mbs.load_model(tmp_path / "plain.mbs"), output=tmp_path / "lib.h5")
    res = read_results(out)
    assert res.attrs["complete"] and set(res.signals) == set(mine.signals)
    for name in mine.signals:
        np.testing.assert_array_equal(res.signals[name], mine.signals[name])
    for flag in (["--resume"], ["--updates", "3"]):
        r = _mbs("run", tmp_path / "plain.mbs", "-o", out, *flag)
        assert r.exit_code == 2 and "declares no `wear`" in r.output and "hint:" in r.output


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_leaves_the_last_finished_update_and_says_how_to_go_on(tmp_path, whole, sig, code):
    """The `mbs` executable, stopped by Ctrl-C or SIGTERM after its second update line: the file holds the
    updates finished (readable, no half-written file beside it), and the command it prints goes on to the
    same wear as an uninterrupted run."""
    model, out = _model(tmp_path), tmp_path / "w.h5"
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-c", "from planar_mbs.cli.entry import main; main()", "run", str(model), "-o",
           str(out), "--updates", "4000"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in proc.stdout:
        if line.startswith("update   2/"):
            break
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    h = load_history(out)
    done = len(h.depths) - 1
    assert 2 <= done < 4000 and f"holds the wear after update {done} of 4000" in err
    assert not list(tmp_path.glob("*.part"))
    go_on = err.strip().rsplit("go on with: ", 1)[1].split()
    assert go_on[:2] == ["mbs", "run"] and "--resume" in go_on
    total = max(4, done + 1)  # the run may have gone past update 4 before the signal came
    r = _mbs(*go_on[1:], "--updates", total)
    assert r.exit_code == 0, r.output
    if total == 4:
        np.testing.assert_allclose(load_history(out).depths[-1], whole.depths[-1], rtol=0,
                                   atol=1e-6 * whole.max_depth())


def _rrd(path) -> dict:
    """{entity: {"static": bool, column: [values in the order of the `update` timeline]}} of a recording."""
    os.environ["RERUN_TELEMETRY_ENABLED"] = "false"
    from rerun.chunk import RrdReader
    out: dict = {}
    for chunk in RrdReader(path).stream():
        rb = chunk.to_record_batch()
        ent = out.setdefault(chunk.entity_path.lstrip("/"), {"static": chunk.is_static})
        for name in rb.schema.names[1:]:
            ent.setdefault(name, []).extend(rb.column(name).to_pylist())
    for ent in out.values():
        if "update" in ent:
            order = np.argsort(ent["update"], kind="stable")
            for name in [n for n in ent if n != "static"]:
                ent[name] = [ent[name][i] for i in order]
    return out


def test_view_records_the_worn_profile_per_update_on_an_update_timeline(tmp_path):
    """`mbs view WEAR.h5`: per update the profile R_B + magnify x depth (mm, float32 in the file), the
    deepest node and the wear signals, on the sequence timeline `update`; --magnify sets the factor."""
    out = tmp_path / "w.h5"
    assert _mbs("run", _model(tmp_path), "-o", out, "-q").exit_code == 0
    r = _mbs("view", out, "--magnify", "200")
    assert r.exit_code == 0 and "5 updates" in r.output and "magnified 200 times" in r.output, r.output
    rec, h = _rrd(tmp_path / "w.rrd"), load_history(out)
    assert rec["wear/J/nominal"]["static"] and rec["model/source"]["static"]
    profile = rec["wear/J/profile"]
    assert profile["update"] == [0, 1, 2, 3, 4]
    for i, strips in enumerate(profile["LineStrips2D:strips"]):
        pts = np.array(strips[0])
        np.testing.assert_allclose(np.hypot(pts[:-1, 0], pts[:-1, 1]), (h.radius + 200 * h.depths[i]) * 1e3,
                                   rtol=0, atol=1e-5)
    depth = rec["signals/J/max_wear_depth"]
    assert depth["update"] == [0, 1, 2, 3, 4]
    np.testing.assert_allclose(depth["Scalars:scalars"], [[h.max_depth(i) * 1e6] for i in range(5)], rtol=1e-12)
    assert "µm at" in rec["wear/J/deepest"]["Points2D:labels"][-1][0]
    r = _mbs("view", out, "-o", tmp_path / "auto.rrd")  # by default the deepest wear draws a quarter of R_B
    pts = np.array(_rrd(tmp_path / "auto.rrd")["wear/J/profile"]["LineStrips2D:strips"][-1][0])
    assert np.hypot(pts[:, 0], pts[:, 1]).max() == pytest.approx(1.25 * h.radius * 1e3, rel=1e-6)
    r = _mbs("view", out, "--fps", "30")
    assert r.exit_code == 2 and "does not apply to the file of a wear run" in r.output and "hint:" in r.output


def test_a_failed_update_exits_3_and_leaves_no_half_file(tmp_path):
    model = _model(tmp_path)
    capped = tmp_path / "capped.mbs"
    capped.write_text(f'include "{model.name}"\noverride simulate {{ t_end = 20 ms  rtol = 1e-9  atol = 1e-12  '
                      'output_step = 0.5 ms  max_steps = 10 }\n')
    r = _mbs("run", capped, "-o", tmp_path / "w.h5")
    assert r.exit_code == 3 and "simulation failed" in r.output and "no update finished" in r.output, r.output
    assert not list(tmp_path.glob("w.h5*"))
