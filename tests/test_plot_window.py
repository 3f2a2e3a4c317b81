"""`mbs plot` for long runs: a time window (--from/--to), a warning when the output step is too
coarse to draw a journal orbit, and titles of square figures that fit their figure."""
from __future__ import annotations

import math

import numpy as np
import pytest
from plot_fixtures import write_run
from typer.testing import CliRunner

from planar_mbs.outputs.plot import orbit_figure, orbit_resolution_warning, poincare_figure, series_figure
from planar_mbs.results.views import time_window
from planar_mbs.results.hdf5 import Results, read_results

RPM = 2500.0
T = 60.0 / RPM  # one crank revolution
runner = CliRunner()


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("window") / "run.h5"
    write_run(path, rpm=RPM, revolutions=10.0, n=4000)
    return path


def test_time_window_keeps_the_samples_inside(run_file):
    res = read_results(run_file)
    cut = time_window(res, 2.5 * T, 4.0 * T)
    inside = (res.time >= 2.5 * T) & (res.time <= 4.0 * T)
    np.testing.assert_array_equal(cut.time, res.time[inside])
    np.testing.assert_array_equal(cut["slider.vx"], res["slider.vx"][inside])
    assert set(cut.signals) == set(res.signals) and cut.units == res.units
    fig = series_figure(cut, [["slider.vx"]])
    x = fig.axes[0].lines[0].get_xdata()
    assert x.min() >= 2.5 * T and x.max() <= 4.0 * T
    with pytest.raises(Exception, match="no samples"):
        time_window(res, 20 * T, 30 * T)


def test_poincare_map_in_a_window_counts_revolutions_from_the_start(run_file):
    res = read_results(run_file)
    fig = poincare_figure(res, "slider.vx", "slider.ax", skip=1, window=(2.5 * T, 6.2 * T))
    # sections at k T after the first revolution: k = 3, 4, 5, 6 lie in the window
    assert fig.axes[0].get_title().startswith("Poincaré map: 4 points")
    x = fig.axes[0].lines[0].get_xdata()
    np.testing.assert_allclose(x, np.interp([3 * T, 4 * T, 5 * T, 6 * T], res.time, res["slider.vx"]), rtol=1e-9)


def test_cli_plot_window(run_file, tmp_path):
    r = runner.invoke(__import__("planar_mbs.cli.app", fromlist=["app"]).app,
                      ["plot", str(run_file), "slider.vx", "--from", f"{2 * T * 1e3:.6f}ms", "--to", f"{3 * T:.6f}s",
                       "-o", str(tmp_path)])
    assert r.exit_code == 0 and (tmp_path / "run_slider.vx.png").exists(), r.output
    r = runner.invoke(__import__("planar_mbs.cli.app", fromlist=["app"]).app,
                      ["plot", str(run_file), "slider.vx", "--from", "3s", "--to", "1s", "-o", str(tmp_path)])
    assert r.exit_code == 2 and "--from must be before --to" in r.output


def wall_orbit(step_deg: float, n: int = 200, c: float = 3e-4) -> Results:
    """A journal sliding along the bearing wall, turning `step_deg` between samples."""
    th = np.radians(step_deg) * np.arange(n)
    e = np.full(n, c * 1.001)
    sig = {"A.ex": e * np.cos(th), "A.ey": e * np.sin(th), "A.e": e, "A.penetration": e - c}
    return Results(time=np.arange(n) * 1e-4, signals=sig, units={k: "m" for k in sig},
                   attrs={"parameters": {}, "complete": True})


def test_coarse_orbit_warns_and_fine_one_does_not():
    coarse = orbit_resolution_warning(wall_orbit(40.0), "A")
    assert coarse and "turns up to 40°" in coarse and "--output-step" in coarse
    # the suggested step turns the journal by at most 15 degrees: 1e-4 s * 15/40
    import re

    suggested = float(re.search(r"--output-step ([0-9.e-]+)s", coarse).group(1))
    assert 3.5e-5 <= suggested <= 3.75e-5 * (1 + 1e-9)
    assert orbit_resolution_warning(wall_orbit(5.0), "A") is None


def test_cli_prints_the_orbit_warning(tmp_path):
    from planar_mbs.cli.app import app
    from planar_mbs.results.hdf5 import write_results

    path = tmp_path / "coarse.h5"
    write_results(path, wall_orbit(40.0))
    r = runner.invoke(app, ["plot", str(path), "--orbit", "A", "-o", str(tmp_path / "p")])
    assert r.exit_code == 0 and "warning: the orbit of `A`" in r.output, r.output


@pytest.mark.parametrize("figure", ["poincare", "orbit"])
def test_square_figure_titles_fit(run_file, figure):
    res = read_results(run_file)
    res.attrs["parameters"] = {"speed": "2500 rpm", "clearance": "0.3 mm", "law": "lankarani_nikravesh",
                               "restitution": "0.9", "youngs_modulus": "207 GPa", "friction": "0"}
    res.attrs["model_path"] = "models/slider_crank_clearance_a.mbs"
    fig = poincare_figure(res, "slider.vx", "slider.ax") if figure == "poincare" else orbit_figure(res, "A")
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    width = fig.bbox.width
    for text in [fig._suptitle, fig.axes[0].title]:
        box = text.get_window_extent(renderer)
        assert text.get_text() and box.x0 >= 0 and box.x1 <= width, (text.get_text(), box, width)
