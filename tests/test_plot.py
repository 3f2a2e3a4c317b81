"""`mbs plot`: what the figures show (axes, labels, the plotted arrays), Poincaré sampling, sweeps, CLI errors."""
import math

import numpy as np
import pytest
import typer
from PIL import Image
from typer.testing import CliRunner

from planar_mbs.outputs import plot as P
from planar_mbs.results import views as V
from planar_mbs.cli.plot_commands import plot, view
from planar_mbs.results.hdf5 import read_results
from plot_fixtures import CLEARANCE, slider_crank_model, write_run, write_sweep

runner = CliRunner()
app = typer.Typer()
app.command()(plot)
app.command()(view)

RPM = 2500.0


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("plot") / "run.h5"
    write_run(path, rpm=RPM, revolutions=5.0, n=2000)
    return path


@pytest.fixture(scope="module")
def results(run_file):
    return read_results(run_file)


def assert_image(path, min_size=(300, 250)):
    """A readable PNG of sensible size (what it shows is tested on the figures' data below)."""
    img = Image.open(path)
    img.verify()
    img = Image.open(path).convert("L")
    assert img.size[0] >= min_size[0] and img.size[1] >= min_size[1]
    assert np.asarray(img, dtype=float).std() > 5.0, f"{path} looks blank"


# ---------------------------------------------------------------- figures by their data
def _lines(ax):
    return [ln for ln in ax.get_lines() if ln.get_visible()]


def test_series_figure_plots_the_signals_with_their_labels(results):
    fig = P.series_figure(results, [["slider.vx"], ["A.fx", "A.fy"]])
    ax0, ax1 = fig.axes
    assert ax0.get_ylabel() == "slider velocity x\n(slider.vx) [m/s]" and ax1.get_xlabel() == "time [s]"
    (line,) = _lines(ax0)
    np.testing.assert_array_equal(line.get_xdata(), results.time)
    np.testing.assert_array_equal(line.get_ydata(), results["slider.vx"])
    assert [ln.get_label() for ln in _lines(ax1)] == ["A.fx", "A.fy"]
    for ln in _lines(ax1):
        np.testing.assert_array_equal(ln.get_ydata(), results[ln.get_label()])
    assert ax1.get_ylabel() == "[N]"
    assert [t.get_text() for t in ax1.get_legend().get_texts()] == ["A.fx", "A.fy"]


def test_series_against_the_crank_angle_overlays_revolutions(results):
    fig = P.series_figure(results, [["slider.x"]], against="crank.phi")
    (ax,) = fig.axes
    assert ax.get_xlabel() == "crank angle [deg, mod 360]"
    (line,) = _lines(ax)
    x, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
    keep = ~np.isnan(x)
    np.testing.assert_allclose(x[keep], np.mod(np.degrees(results["crank.phi"]), 360.0), atol=1e-9)
    np.testing.assert_array_equal(y[keep], results["slider.x"])
    assert np.isnan(y[~keep]).all() and (~keep).sum() == 5  # a break at each of the five wraps


def test_orbit_figure_draws_the_journal_path_inside_the_clearance_circle(results):
    fig = P.orbit_figure(results, "A")
    (ax,) = fig.axes
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("A eccentricity x [mm]", "A eccentricity y [mm]")
    path, start, circle = _lines(ax)
    np.testing.assert_allclose(path.get_xdata(), results["A.ex"] * 1e3)
    np.testing.assert_allclose(path.get_ydata(), results["A.ey"] * 1e3)
    np.testing.assert_allclose(np.hypot(circle.get_xdata(), circle.get_ydata()), CLEARANCE * 1e3, rtol=1e-12)
    assert start.get_xdata()[0] == pytest.approx(results["A.ex"][0] * 1e3)


def test_sweep_figures_show_each_case_and_the_section_of_each_speed(tmp_path):
    rpms = (800.0, 1200.0, 2500.0)
    path = tmp_path / "sweep.h5"
    write_sweep(path, rpms=rpms)
    cases = P.sweep_cases(path)
    grid = P.sweep_grid_figure(cases, "slider.vx")
    visible = [ax for ax in grid.axes if ax.get_visible()]
    assert len(visible) == 3
    for ax, (_, res), rpm in zip(visible, cases, rpms):
        assert f"{rpm:g}" in ax.get_title() and ax.get_ylabel() == "slider velocity x [m/s]"
        np.testing.assert_array_equal(_lines(ax)[0].get_ydata(), res["slider.vx"])
    fig = P.bifurcation_figure(cases, "slider.vx")
    (ax,) = fig.axes
    assert ax.get_xlabel() == "speed [rpm]" and ax.get_ylabel() == "slider velocity x [m/s]"
    for line, (_, res), rpm in zip(_lines(ax), cases, rpms):
        xs, ys = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
        assert len(ys) >= 3 and np.all(xs == rpm)
        # every point is the slider velocity at a whole number of crank revolutions (constant speed)
        T = 60.0 / rpm
        k = np.round(res.time[-1] / T)
        ref = np.interp(np.arange(1, k + 1) * T, res.time, res["slider.vx"])
        assert all(np.min(np.abs(ref - y)) <= 1e-9 * np.max(np.abs(ref)) for y in ys)


def test_default_figures(run_file, tmp_path):
    written = P.plot_file(run_file, outdir=tmp_path)
    names = {p.name for p in written}
    assert names == {
        "run_slider_velocity.png", "run_slider_acceleration.png", "run_contact_force.png",
        "run_driver_torque.png", "run_poincare_slider.vx_slider.ax.png", "run_orbit_A.png",
    }
    for p in written:
        assert_image(p)


def test_default_panels_pick_slider_clearance_and_driver(results):
    panels = dict(P.default_panels(results))
    assert panels == {
        "slider_velocity": ["slider.vx"], "slider_acceleration": ["slider.ax"],
        "contact_force": ["A.contact_force"], "driver_torque": ["crank_speed.torque"],
    }
    assert V.slider_body(results) == "slider"
    assert V.slider_body(results, slider_crank_model()) == "slider"
    assert V.turning_body(results) == "crank"
    assert V.turning_body(results, slider_crank_model()) == "crank"


def test_named_signals_against_crank_angle(run_file, tmp_path):
    written = P.plot_file(run_file, ["slider.vx", "A.fx,A.fy"], against="crank.phi", outdir=tmp_path, fmt="svg")
    assert [p.name for p in written] == ["run_slider.vx_A.fx+A.fy_vs_crank.phi.svg".replace("+", "_")]
    text = written[0].read_text()
    assert "<svg" in text and "deg" in text


def test_angle_axis_in_degrees_wraps(results):
    x, xlabel = P.axis_values(results, "crank.phi")
    assert "deg" in xlabel
    finite = x[np.isfinite(x)]
    assert finite.min() >= 0 and finite.max() < 360
    assert np.isnan(x).sum() == 5  # five revolutions, the last sample lands on 1800 deg = 0
    y = P._with_breaks(x, results["slider.vx"], len(results.time))
    assert len(y) == len(x) and np.array_equal(np.isnan(y), np.isnan(x))


def test_revolution_times_of_constant_speed():
    omega = 2 * math.pi * 50.0
    t = np.linspace(0, 0.1, 1001)  # five revolutions
    T = 2 * math.pi / omega
    np.testing.assert_allclose(V.revolution_times(t, omega * t + 0.3, skip=1), [2 * T, 3 * T, 4 * T, 5 * T],
                               atol=1e-12)
    np.testing.assert_allclose(V.revolution_times(t, -omega * t, skip=0), T * np.arange(1, 6), atol=1e-12)
    assert len(V.revolution_times(t, omega * t, skip=5)) == 0


def test_poincare_samples_once_per_revolution(results):
    ps = V.poincare(results, "slider.vx", "slider.ax", skip=1)
    T = 60.0 / RPM
    np.testing.assert_allclose(ps.t, T * np.arange(2, 6), rtol=1e-9)
    np.testing.assert_allclose(ps.x, np.interp(ps.t, results.time, results["slider.vx"]))
    assert ps.body == "crank"
    assert len(V.poincare(results, "slider.vx", "slider.ax", skip=3).t) == 2


def test_clearance_radius_and_onsets(results):
    assert V.clearance_radius(results, "A") == pytest.approx(CLEARANCE)
    onsets = V.contact_onsets(results, "A")
    assert len(onsets) > 0
    assert np.all(results["A.in_contact"][onsets] == 1) and np.all(results["A.in_contact"][onsets - 1] == 0)


def test_envelope_keeps_peaks():
    x = np.linspace(0, 1, 1_000_000)
    y = np.sin(50 * x)
    y[123_457] = 40.0
    xs, ys = P.envelope(x, y, 10_000)
    assert len(xs) <= 10_001 and ys.max() == 40.0 and ys.min() == y.min()
    assert np.all(np.diff(xs) > 0)


def test_sweep_grid_and_bifurcation(tmp_path):
    path = tmp_path / "sweep.h5"
    write_sweep(path)
    assert P.is_sweep(path)
    written = P.plot_file(path, outdir=tmp_path / "out")
    names = {p.name for p in written}
    assert {"sweep_grid_slider.vx.png", "sweep_grid_slider.ax.png", "sweep_grid_A.contact_force.png",
            "sweep_grid_crank_speed.torque.png", "sweep_poincare_grid_slider.vx_slider.ax.png",
            "sweep_bifurcation_slider.vx.png"} == names
    for p in written:
        assert_image(p)
    assert P.parameter_value("2500 rpm") == (2500.0, "rpm")
    assert P.parameter_value("hertz") is None


def test_cli_plot_writes_and_lists(run_file, tmp_path):
    res = runner.invoke(app, ["plot", str(run_file), "slider.ax", "-o", str(tmp_path), "--against", "crank.phi"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "run_slider.ax_vs_crank.phi.png").exists()
    res = runner.invoke(app, ["plot", str(run_file), "--list"])
    assert res.exit_code == 0 and "A.contact_force" in res.output


def test_cli_sweep_case(tmp_path):
    path = tmp_path / "sweep.h5"
    write_sweep(path, rpms=(800.0, 1200.0))
    res = runner.invoke(app, ["plot", f"{path}:/cases/1", "--orbit", "A", "-o", str(tmp_path / "c")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "c" / "sweep_case1_orbit_A.png").exists()


@pytest.mark.parametrize("args, needle", [
    (["slider.vz"], "did you mean"),
    (["slider"], "`slider.vx`"),
    (["--against", "crank.ph"], "crank.phi"),
    (["--poincare", "slider.vx"], "X:Y"),
    (["--poincare", "slider.vx:slider.aa"], "slider.ax"),
    (["--orbit", "B"], "not a clearance joint"),
    (["-f", "jpg"], "png, svg, pdf"),
])
def test_cli_bad_usage_exit_2_without_traceback(run_file, tmp_path, args, needle):
    res = runner.invoke(app, ["plot", str(run_file), *args, "-o", str(tmp_path)])
    assert res.exit_code == 2, res.output
    assert needle in res.output
    assert "Traceback" not in res.output and res.exception is None or isinstance(res.exception, SystemExit)


def test_cli_missing_file(tmp_path):
    res = runner.invoke(app, ["plot", str(tmp_path / "nope.h5")])
    assert res.exit_code == 2 and "no such results file" in res.output


def test_plot_module_imports_no_matplotlib():
    import subprocess
    import sys

    code = "import sys, planar_mbs.outputs.plot, planar_mbs.outputs.rerun_log, planar_mbs.cli.plot_commands; " \
           "print('matplotlib' in sys.modules, 'rerun' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


def test_stick_phases_are_shaded_where_the_block_moves_with_the_belt():
    """The belt oscillator's block is held by static friction and carried at the belt's 50 mm/s, then
    slips back on its spring: a time panel of its contact shades exactly the phases in which the block
    moves with the belt (to the stuck contact's compliance), and no sample at which it slips."""
    from pathlib import Path

    import planar_mbs as mbs

    model = mbs.load_model(Path(__file__).resolve().parents[1] / "models" / "belt_oscillator.mbs")
    r = mbs.simulate(model, t_end=2.5)
    fig = P.series_figure(r, [["on_belt.friction_force"]])
    (shade,) = [c for c in fig.axes[0].collections if c.get_label() == "on_belt stuck"]
    spans = [(p.vertices[:, 0].min(), p.vertices[:, 0].max()) for p in shade.get_paths()]
    t, v = np.asarray(r.time), np.asarray(r["block.vx"])
    inside = np.zeros(len(t), bool)
    for a, b in spans:
        inside |= (t > a) & (t < b)
    slipping = np.abs(v - 0.05) > 1e-3
    assert len(spans) >= 2 and inside.sum() > 0.3 * len(t)
    assert np.abs(v[inside] - 0.05).max() < 1e-4
    assert not (slipping & inside).any()
    assert slipping[~inside].mean() > 0.9  # outside the shade it slips (but at the turning samples)
