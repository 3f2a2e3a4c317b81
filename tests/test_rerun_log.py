"""rerun recordings, read back with rerun's own reader (`rerun.chunk.RrdReader`)."""
import os

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

os.environ["RERUN_TELEMETRY_ENABLED"] = "false"

from planar_mbs.outputs import rerun_log as R  # noqa: E402
from planar_mbs.cli.plot_commands import record_run as cli_record_run  # noqa: E402
from planar_mbs.cli.plot_commands import view  # noqa: E402
from planar_mbs.results.hdf5 import read_results  # noqa: E402
from plot_fixtures import write_run  # noqa: E402

runner = CliRunner()
app = typer.Typer()
app.command()(view)
app.command(name="noop")(lambda: None)  # keep `view` a subcommand


def read_rrd(path):
    """``{entity: {"time": ns (int64), "static": {...}, column: [values per row]}}``."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    out = {}
    for chunk in RrdReader(path).stream():
        rb = chunk.to_record_batch()
        ent = out.setdefault(chunk.entity_path.lstrip("/"), {"static": {}, "rows": []})
        if chunk.is_static:
            for name in rb.schema.names[1:]:
                ent["static"][name] = rb.column(name).to_pylist()
            continue
        cols = {name: rb.column(name) for name in rb.schema.names[1:]}
        ent["rows"].append(cols)
    for ent in out.values():
        rows = ent.pop("rows")
        if not rows:
            continue
        ent["time"] = np.concatenate([r["sim_time"].cast(pa.int64()).to_numpy() for r in rows])
        for name in rows[0]:
            if name in ("sim_time", "log_time", "log_tick"):
                continue
            ent[name] = [v for r in rows for v in r[name].to_pylist()]
        order = np.argsort(ent["time"], kind="stable")
        ent["time"] = ent["time"][order]
        for name in list(ent):
            if name not in ("time", "static"):
                ent[name] = [ent[name][i] for i in order]
    return out


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("rerun")
    h5 = d / "run.h5"
    model = write_run(h5, rpm=2500.0, revolutions=5.0, n=2000)
    results = read_results(h5)
    path = d / "run.rrd"
    info = R.record_run(results, model, path, magnify=10.0, recording_id="test")
    return results, model, info, read_rrd(path)


def test_entity_paths(recorded):
    results, model, info, rrd = recorded
    expected = {
        "model/source", "mechanism/legend", "mechanism/com", "mechanism/joints",
        "mechanism/ground/pins", "mechanism/ground/guides",
        "mechanism/bodies/crank", "mechanism/bodies/rod", "mechanism/bodies/slider",
        "mechanism/clearance/A/bearing", "mechanism/clearance/A/journal",
        "forces/joints/O", "forces/joints/B", "forces/joints/S", "forces/contact/A",
        "events/contact", "poincare/slider_vx_vs_slider_ax", "poincare/axes",
    }
    expected |= {"signals/" + name.replace(".", "/") for name in results.signals}
    assert expected <= set(rrd), expected - set(rrd)
    assert {e for e in rrd if not e.startswith("__")} == expected
    assert rrd["model/source"]["static"]["TextDocument:text"] == [[results.attrs["model_source"]]]


def test_frames_are_decimated(recorded):
    results, model, info, rrd = recorded
    # 90 frames per revolution over 5 revolutions, from 2000 samples
    assert info.frames == 451 == len(R.frame_indices(results, model))
    for ent in ("mechanism/bodies/crank", "mechanism/clearance/A/journal", "forces/contact/A"):
        assert len(rrd[ent]["time"]) == info.frames
    np.testing.assert_allclose(rrd["mechanism/com"]["time"] * 1e-9, info.frame_times, atol=1e-9)
    assert len(R.frame_indices(results, model, fps=1000.0)) == 121  # 0.12 s at 1000 frames/s
    assert len(R.frame_indices(results, model, fps=1e9)) == len(results.time)  # never more than the samples


def _series(rrd, name):
    ent = rrd["signals/" + name.replace(".", "/")]
    return ent["time"], np.array([v[0] for v in ent["Scalars:scalars"]])


def _assert_exact_envelope(results, name, t_ns, values, rate):
    """Every logged scalar is the HDF5 sample at its logged time, and of every bin of
    1/rate s the first sample, the min and the max are all there (nothing else)."""
    t = results.time
    idx = np.searchsorted(t, t_ns * 1e-9 - 5e-10)  # logged times are t truncated to ns
    assert np.all(np.abs(t[idx] - t_ns * 1e-9) < 1e-9)
    np.testing.assert_array_equal(values, results[name][idx])
    v = results[name]
    binno = np.floor((t - t[0]) * rate * (1 + 1e-12)).astype(int)
    expected = set()
    for b in np.unique(binno):
        ii = np.flatnonzero(binno == b)
        expected |= {ii[0], ii[np.nanargmin(v[ii])], ii[np.nanargmax(v[ii])]}
    assert set(idx.tolist()) == expected
    assert len(idx) <= 3 * len(np.unique(binno))


def test_scalar_series_are_exact_peak_preserving_envelopes(recorded):
    results, model, info, rrd = recorded
    assert info.signals == len(results.signals) and info.signal_mode == "envelope"
    rate = R.frame_rate(results, model)
    assert info.signal_rate == rate == pytest.approx(2500 / 60 * 90)  # bins = frames: 90 per revolution
    for name in ("slider.vx", "slider.ax", "A.contact_force", "crank_speed.torque", "system.kinetic_energy"):
        t_ns, values = _series(rrd, name)
        _assert_exact_envelope(results, name, t_ns, values, rate)
        # the extremes of the whole run survive decimation
        assert values.max() == results[name].max() and values.min() == results[name].min()
    assert info.signal_samples < 0.5 * len(results.time) * len(results.signals)


def test_scalar_series_full_resolution(tmp_path, recorded):
    results, model = recorded[:2]
    info = R.record_run(results, None, tmp_path / "f.rrd", signals="full")
    rrd = read_rrd(tmp_path / "f.rrd")
    assert info.signal_samples == len(results.time) * len(results.signals)
    for name in ("slider.vx", "A.contact_force", "crank_speed.torque", "system.kinetic_energy"):
        t_ns, values = _series(rrd, name)
        np.testing.assert_array_equal(values, results[name])
        np.testing.assert_allclose(t_ns * 1e-9, results.time, atol=1e-9)
    # a settable envelope rate: 1000 bins per simulated second
    info = R.record_run(results, None, tmp_path / "r.rrd", signal_rate=1000.0)
    t_ns, values = _series(read_rrd(tmp_path / "r.rrd"), "slider.ax")
    _assert_exact_envelope(results, "slider.ax", t_ns, values, 1000.0)
    with pytest.raises(ValueError):
        R.record_run(results, None, tmp_path / "x.rrd", signals="some")


def test_envelope_indices_nan_ties_and_fine_bins():
    t = np.arange(40) * 0.1
    v = np.array([[np.nan, 1, 1, 0, 2, 2, 0, 5, 5, 5] * 4, [3.0] * 40])
    v[0, 10:20] = np.nan
    kept = R.envelope_indices(t, v, 1.0)  # bins of 10 samples
    assert kept[0].tolist() == [0, 3, 7, 10, 20, 23, 27, 30, 33, 37]  # first, first min, first max
    assert kept[1].tolist() == [0, 10, 20, 30]  # a constant: the first sample of each bin
    assert [k.tolist() for k in R.envelope_indices(t, v, 100.0)] == [list(range(40))] * 2  # fine bins: all


def test_clearance_is_magnified(recorded):
    results, model, info, rrd = recorded
    idx = R.frame_indices(results, model)
    bearing = np.array(rrd["mechanism/clearance/A/bearing"]["Ellipses2D:centers"])[:, 0]
    journal = np.array(rrd["mechanism/clearance/A/journal"]["Ellipses2D:centers"])[:, 0]
    ecc = np.stack([results["A.ex"][idx], -results["A.ey"][idx]], 1)  # y logged upwards-negated
    np.testing.assert_allclose(journal - bearing, 10.0 * ecc, atol=1e-6)
    rj = np.array(rrd["mechanism/clearance/A/journal"]["Ellipses2D:half_sizes"])[0, 0, 0]
    rb = np.array(rrd["mechanism/clearance/A/bearing"]["Ellipses2D:half_sizes"])[0, 0, 0]
    assert rb - rj == pytest.approx(10.0 * 3e-4, rel=1e-5)
    # the rod is drawn to the magnified journal centre
    rod = rrd["mechanism/bodies/rod"]["LineStrips2D:strips"]
    ends = np.array([s[0] for s in rod])  # first strip of each frame: (2 points, 2)
    d = np.minimum(np.linalg.norm(ends[:, 0] - journal, axis=1), np.linalg.norm(ends[:, 1] - journal, axis=1))
    assert d.max() < 1e-6


def test_contact_onsets_and_poincare(recorded):
    results, model, info, rrd = recorded
    from planar_mbs.results.views import contact_onsets, poincare

    onsets = contact_onsets(results, "A")
    log = rrd["events/contact"]
    assert info.contact_onsets == len(onsets) == len(log["TextLog:text"]) > 0
    assert all(text[0].startswith("A: contact onset") for text in log["TextLog:text"])
    np.testing.assert_allclose(log["time"] * 1e-9, results.time[onsets], atol=1e-9)
    ps = poincare(results, "slider.vx", "slider.ax")
    pts = rrd["poincare/slider_vx_vs_slider_ax"]
    assert info.poincare_points == len(ps.t) == len(pts["time"]) == 4


def test_signals_only_without_model(tmp_path, recorded):
    results = recorded[0]
    info = R.record_run(results, None, tmp_path / "s.rrd", signal_stride=10)
    rrd = read_rrd(tmp_path / "s.rrd")
    assert not any(e.startswith("mechanism/bodies") for e in rrd)
    vx = np.array([v[0] for v in rrd["signals/slider/vx"]["Scalars:scalars"]])
    np.testing.assert_array_equal(vx, results["slider.vx"][::10])
    # without a model the envelope still bins at the frame rate (the crank turns)
    R.record_run(results, None, tmp_path / "e.rrd")
    t_ns, values = _series(read_rrd(tmp_path / "e.rrd"), "slider.vx")
    _assert_exact_envelope(results, "slider.vx", t_ns, values, R.frame_rate(results, None))
    assert info.frames == 0 and info.poincare_points == 4


def test_cli_view_and_record_run(tmp_path, monkeypatch):
    h5 = tmp_path / "v.h5"
    model = write_run(h5, n=500)
    monkeypatch.setattr(R, "model_from_results", lambda results: model)
    res = runner.invoke(app, ["view", str(h5), "--fps", "2000"])
    assert res.exit_code == 0, res.output
    rrd = read_rrd(tmp_path / "v.rrd")
    assert "mechanism/bodies/rod" in rrd and len(rrd["mechanism/bodies/rod"]["time"]) == 241
    info = cli_record_run(read_results(h5), model, tmp_path / "r.rrd", quiet=True)
    assert (tmp_path / "r.rrd").stat().st_size > 10_000 and info.frames > 0


def test_cli_view_signals_only_and_bad_file(tmp_path):
    h5 = tmp_path / "v.h5"
    write_run(h5, n=300)
    res = runner.invoke(app, ["view", str(h5), "-o", str(tmp_path / "x.rrd"), "--signals-only"])
    assert res.exit_code == 0, res.output
    assert "signals/slider/vx" in read_rrd(tmp_path / "x.rrd")
    res = runner.invoke(app, ["view", str(tmp_path / "missing.h5")])
    assert res.exit_code == 2 and "Traceback" not in res.output


def test_model_from_results_with_compiler(tmp_path):
    pytest.importorskip("planar_mbs.mechanism.compile")
    from pathlib import Path

    models = Path(__file__).resolve().parents[1] / "models"
    path = models / "slider_crank_clearance_a.mbs"
    if not path.exists():
        pytest.skip("shipped clearance model not there yet")
    from planar_mbs import load_model
    from planar_mbs.results.hdf5 import Results

    model = load_model(path)
    res = Results(time=np.zeros(0), signals={}, attrs={
        "model_source": path.read_text(), "model_path": str(path), "parameters": model.parameters})
    again = R.model_from_results(res)
    assert again.body_names == model.body_names and again.clearance_names == model.clearance_names


def test_recording_of_the_shipped_clearance_model(tmp_path):
    """The shipped clearance model records with its bodies, clearance and contact force, and
    the slider's velocity series is the exact peak-keeping envelope of the HDF5 signal.
    (What recording costs against the time loop is measured by benchmarks/rerun_logging.py,
    not asserted here: the project keeps timings out of tests.)"""
    from pathlib import Path

    import planar_mbs as mbs

    path = Path(__file__).resolve().parents[1] / "models" / "slider_crank_clearance_a.mbs"
    model = mbs.load_model(path)
    res = mbs.simulate(model)
    R.record_run(res, model, tmp_path / "p.rrd")
    rrd = read_rrd(tmp_path / "p.rrd")
    assert {"mechanism/bodies/crank", "mechanism/bodies/rod", "mechanism/bodies/slider",
            "mechanism/clearance/A/journal", "forces/contact/A"} <= set(rrd)
    t_ns, vx = _series(rrd, "slider.vx")
    _assert_exact_envelope(res, "slider.vx", t_ns, vx, R.frame_rate(res, model))


def _real_app_has(command: str, option: str | None = None) -> bool:
    from planar_mbs.cli.app import app as real

    for cmd in real.registered_commands:
        name = cmd.name or cmd.callback.__name__
        if name == command:
            if option is None:
                return True
            import inspect

            return any(option in str(p.default) or option.lstrip("-") == n
                       for n, p in inspect.signature(cmd.callback).parameters.items())
    return False


def test_mbs_view_and_plot_are_registered(tmp_path):
    if not (_real_app_has("plot") and _real_app_has("view")):
        pytest.skip("`plot` and `view` not registered in planar_mbs/cli/app.py yet")
    from planar_mbs.cli.app import app as real

    h5 = tmp_path / "r.h5"
    write_run(h5, n=300)
    res = runner.invoke(real, ["view", str(h5), "--signals-only"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(real, ["plot", str(h5), "slider.vz"])
    assert res.exit_code == 2 and "did you mean" in res.output


def test_mbs_run_rerun(tmp_path):
    if not _real_app_has("run", "rerun"):
        pytest.skip("`mbs run --rerun` not wired in planar_mbs/cli/app.py yet")
    from pathlib import Path

    from planar_mbs.cli.app import app as real

    model = Path(__file__).resolve().parents[1] / "models" / "slider_crank_clearance_a.mbs"
    res = runner.invoke(real, ["run", str(model), "-o", str(tmp_path / "a.h5"), "--rerun", str(tmp_path / "a.rrd"),
                               "-q", "--t-end", "2 ms"])
    assert res.exit_code == 0, res.output
    rrd = read_rrd(tmp_path / "a.rrd")
    assert "mechanism/clearance/A/journal" in rrd
    res = read_results(tmp_path / "a.h5")
    t_ns, vx = _series(rrd, "slider.vx")
    _assert_exact_envelope(res, "slider.vx", t_ns, vx, R.frame_rate(res, R.model_from_results(res)))



def test_stick_and_slip_of_the_belt_oscillator_are_on_the_timeline(tmp_path):
    """The belt oscillator sticks, slips and sticks again within 1.5 s (from the spring's rest length it
    rides the belt until the spring pulls mu_s m g, 0.78 s; it slips for less than a period
    2 pi sqrt(m/k) = 0.63 s): every change of its `on_belt.stick`
    signal is an `events/friction` entry at that sample's time, and its force arrow is green exactly
    on the frames where the contact is stuck."""
    from pathlib import Path

    from planar_mbs.cli.app import app as real

    model = Path(__file__).resolve().parents[1] / "models" / "belt_oscillator.mbs"
    res = runner.invoke(real, ["run", str(model), "-o", str(tmp_path / "b.h5"), "--rerun", str(tmp_path / "b.rrd"),
                               "-q", "--t-end", "1.5 s"])
    assert res.exit_code == 0, res.output
    results, rrd = read_results(tmp_path / "b.h5"), read_rrd(tmp_path / "b.rrd")
    stuck = results["on_belt.stick"] > 0.5
    flips = np.flatnonzero(np.diff(stuck.astype(int))) + 1
    assert len(flips) >= 3
    log = rrd["events/friction"]
    np.testing.assert_allclose(log["time"] * 1e-9, results.time[flips], atol=1e-9)
    assert [t[0].split(":")[1].split()[0] for t in log["TextLog:text"]] == ["sticks" if s else "slips" for s in stuck[flips]]
    arrows = rrd["forces/contact/on_belt"]
    frames = np.searchsorted(results.time, arrows["time"] * 1e-9 - 1e-12)
    green = np.array([c[0] == R._rgba(R.STUCK)[0] for c in arrows["Arrows2D:colors"]])
    assert green.any() and not green.all()
    assert (green == stuck[frames]).all()

# ---------------------------------------------------------------- viewers that fail, outputs of other runs
def _viewer_that_fails(tmp_path, monkeypatch):
    """A stand-in `rerun` module, first on the viewer's path, that fails as rerun does without a display."""
    fake = tmp_path / "fake" / "rerun"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("")
    (fake / "__main__.py").write_text("import sys\nprint('\\x1b[33m WARN\\x1b[0m something', file=sys.stderr)\n"
                                      "print('Error: neither WAYLAND_DISPLAY nor DISPLAY is set.', file=sys.stderr)\n"
                                      "sys.exit(7)\n")
    monkeypatch.setenv("PYTHONPATH", str(tmp_path / "fake"))


def test_view_open_reports_the_viewers_failure(tmp_path, monkeypatch):
    """A viewer that cannot start makes `mbs view --open` exit 2 with the viewer's exit code and its
    own reason; the recording is written."""
    _viewer_that_fails(tmp_path, monkeypatch)
    h5 = tmp_path / "v.h5"
    write_run(h5, n=300)
    res = runner.invoke(app, ["view", str(h5), "--signals-only", "--open"])
    assert res.exit_code == 2, res.output
    assert "exit code 7" in res.output and "neither WAYLAND_DISPLAY nor DISPLAY is set" in res.output
    assert (tmp_path / "v.rrd").stat().st_size > 0


def test_run_view_without_rerun_says_it_cannot_act():
    from pathlib import Path

    from planar_mbs.cli.run_command import run_model

    model = Path(__file__).resolve().parents[1] / "models" / "slider_crank.mbs"
    assert run_model(model, view_=True) == 2  # refused before anything runs (no kernel, no file)


def test_a_recording_of_other_results_is_not_replaced(tmp_path):
    """`mbs view b.h5 -o a.rrd` where a.rrd records a.h5: refused (exit 2) unless --force; a recording
    of the same results is replaced; a missing output folder is made."""
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    write_run(a, n=300)
    write_run(b, n=300, rpm=2500.0)
    rrd = tmp_path / "deeper" / "still" / "a.rrd"
    assert runner.invoke(app, ["view", str(a), "-o", str(rrd), "--signals-only"]).exit_code == 0
    before = rrd.read_bytes()
    res = runner.invoke(app, ["view", str(b), "-o", str(rrd), "--signals-only"])
    assert res.exit_code == 2 and "--force" in res.output and rrd.read_bytes() == before
    assert runner.invoke(app, ["view", str(a), "-o", str(rrd), "--signals-only"]).exit_code == 0
    assert runner.invoke(app, ["view", str(b), "-o", str(rrd), "--signals-only", "--force"]).exit_code == 0
    assert rrd.read_bytes() != before
    notes = tmp_path / "notes.rrd"
    notes.write_text("my notes")
    assert runner.invoke(app, ["view", str(a), "-o", str(notes), "--signals-only"]).exit_code == 2
    assert notes.read_text() == "my notes"


def test_run_open_reports_the_viewers_failure(tmp_path, monkeypatch):
    """`mbs run --rerun --open`: the run and its recording are written, the viewer's failure is said and
    the exit code is 2 (it was 0, silently)."""
    from pathlib import Path

    from planar_mbs.cli.app import app as real

    _viewer_that_fails(tmp_path, monkeypatch)
    model = Path(__file__).resolve().parents[1] / "models" / "slider_crank.mbs"
    res = runner.invoke(real, ["run", str(model), "-q", "--t-end", "1 ms", "-o", str(tmp_path / "a.h5"),
                               "--rerun", str(tmp_path / "a.rrd"), "--open"])
    assert res.exit_code == 2 and "exit code 7" in res.output and "DISPLAY is set" in res.output, res.output
    assert (tmp_path / "a.rrd").stat().st_size > 0 and read_results(tmp_path / "a.h5").complete
