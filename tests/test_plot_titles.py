"""Figure titles and labels: wrapped between key = value pairs and inside the figure, the time
window as asked, angles in one unit on both axes, y labels in words."""
from __future__ import annotations

import numpy as np
import pytest

from planar_mbs.outputs import plot as P
from planar_mbs.results import views as V
from planar_mbs.results.hdf5 import read_results
from plot_fixtures import write_run

LONG = {"speed": "5000 rpm", "clearance": "0.3 mm", "law": "lankarani_nikravesh", "rod_l": "150 mm",
        "restitution": "0.9", "youngs_modulus": "207 GPa", "friction": "0.01", "bearing_radius": "5 mm"}


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    path = tmp_path_factory.mktemp("titles") / "run.h5"
    write_run(path, revolutions=5.0, n=2000)
    res = read_results(path)
    res.attrs["parameters"] = dict(LONG)
    return res


def test_titles_break_between_pairs_only():
    text = P.wrap_pairs(["slider_crank_clearance_a.mbs", ", ".join(f"{k} = {v}" for k, v in LONG.items())], 40)
    lines = text.splitlines()
    assert len(lines) > 2 and all(len(line) <= 40 for line in lines)
    for k, v in LONG.items():
        assert any(f"{k} = {v}" in line for line in lines), (k, text)  # each pair whole on one line


def test_the_title_stays_inside_the_figure(results):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = P.series_figure(results, [["slider.vx"]])
    FigureCanvasAgg(fig).draw()
    box, title = fig.bbox, fig._suptitle.get_window_extent()
    assert box.x0 <= title.x0 and title.x1 <= box.x1 and title.y1 <= box.y1, (box, title)


def test_a_window_is_titled_as_asked(results):
    cut = V.time_window(results, 0.01, 0.05)
    assert cut.time[0] > 0.01  # the first sample is after the asked start (the grid does not hit it)
    assert "t = 0.01 … 0.05 s" in P._title(cut)


def test_angles_against_an_angle_are_in_degrees(results):
    fig = P.series_figure(results, [["rod.phi"]], against="crank.phi")
    ax = fig.axes[0]
    assert ax.get_ylabel() == "rod angle\n(rod.phi) [deg]" and "deg" in ax.get_xlabel()
    y = np.concatenate([ln.get_ydata() for ln in ax.get_lines()])
    y = y[np.isfinite(y)]
    np.testing.assert_allclose(np.sort(y), np.sort(np.degrees(results["rod.phi"])))


def test_a_long_run_marks_its_start_up_and_scales_to_what_follows(tmp_path):
    """Twelve revolutions with a start-up impact 100 times the steady amplitude: the time plot shades
    the first revolution and its y range fits the samples after it."""
    path = tmp_path / "long.h5"
    write_run(path, revolutions=12.0, n=6000)
    res = read_results(path)
    period = res.time[-1] / 12.0
    start = P.startup_end(res, 1)
    assert start == pytest.approx(period, rel=1e-3)
    vx = res["slider.vx"].copy()
    vx[5] = 100 * np.max(np.abs(vx))  # the start-up impact
    res.signals["slider.vx"] = vx
    ax = P.series_figure(res, [["slider.vx"]], startup=start).axes[0]
    lo, hi = ax.get_ylim()
    steady = vx[res.time > start]
    assert hi < 2 * steady.max() and lo <= steady.min() and hi >= steady.max()
    assert any(abs(p.get_x() + p.get_width() - start) < 1e-12 for p in ax.patches)  # the shaded start-up
    assert P.startup_end(read_results(tmp_path / "long.h5"), 1) is not None
    short = tmp_path / "short.h5"
    write_run(short, revolutions=5.0, n=2000)
    assert P.startup_end(read_results(short), 1) is None  # a short run is drawn whole
