"""Sampled studies from measured values (`--sample NAME=table(FILE.csv)`, planar_mbs.sweep.empirical)
and the figures of a study (`mbs sweep stats ... --plot`, planar_mbs.outputs.study_plot), each
against what numpy computes from the stored cases."""
import math

import numpy as np
import pytest
from matplotlib import image as mpl_image
from matplotlib.container import BarContainer
from typer.testing import CliRunner

from planar_mbs.cli.app import app
from planar_mbs.outputs import study_plot
from planar_mbs.results import hdf5
from planar_mbs.sweep import empirical
from planar_mbs.sweep import sampling as sa
from planar_mbs.sweep.scan import read_case_table

runner = CliRunner()
PNG = b"\x89PNG\r\n\x1a\n"

# measured crank lengths [mm]: a header, a comment, a tie (50.02 three times), unsorted
MEASURED = "crank length\n# from the inspection report\n50.02\n49.91\n50.10\n50.02\n49.97\n50.02\n50.21\n49.85\n"


def _is_png(path) -> bool:
    """A PNG file that decodes to an image of at least 100 × 100 pixels."""
    return path.read_bytes()[:8] == PNG and min(mpl_image.imread(path).shape[:2]) >= 100


def _table(tmp_path, text=MEASURED, name="r.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_table_distribution_samples_the_empirical_quantiles(tmp_path):
    d = sa.parse_distribution(f"r=table({_table(tmp_path)}, mm)")
    x = np.sort([50.02, 49.91, 50.10, 50.02, 49.97, 50.02, 50.21, 49.85])
    assert (d.kind, d.unit) == ("table", "mm") and d.args == tuple(x) and "8 measured values" in d.describe()
    n = len(x)
    # the inverse CDF passes through every order statistic: u = k/(n-1) gives the (k+1)-th smallest
    assert np.array_equal(d.ppf(np.arange(n) / (n - 1)), x)
    # a Latin hypercube of N samples: the p-th sample quantile is within 2/N in probability of p, so within
    # 2/N times the inverse CDF's largest slope, (n - 1) times the largest gap, of the table's p-th quantile
    big = 4000
    sample = sa.values_of([d], sa.unit_points("lhs", big, 1, seed=4))[:, 0]
    tol = 2.0 / big * (n - 1) * np.max(np.diff(x))
    q = np.linspace(0.0, 1.0, 41)
    assert np.max(np.abs(np.quantile(sample, q) - np.quantile(x, q))) <= tol
    assert x[0] <= sample.min() and sample.max() <= x[-1]
    # a value measured 3 times is drawn on a flat piece of (3 - 1)/(n - 1) of the probability
    assert np.mean(sample == 50.02) == pytest.approx(2 / (n - 1), abs=2.0 / big)
    # the stated variance is that of the distribution sampled (a fine midpoint rule over u)
    u = (np.arange(200_000) + 0.5) / 200_000
    assert d.variance() == pytest.approx(np.var(d.ppf(u)), rel=1e-6)


@pytest.mark.parametrize("text, line, says", [
    ("x\n1.0\n2.0, 3.0\n", 3, "one number a line"),
    ("1.0\nabc\n", 2, "is not a number"),
    ("1.0\n2.0\nnan\n", 3, "not a finite number"),
    ("# only\n1.5\n", 1, "at least two values"),
])
def test_a_bad_table_is_refused_at_its_line(tmp_path, text, line, says):
    path = _table(tmp_path, text, "bad.csv")
    model = tmp_path / "m.mbs"
    model.write_text(MODEL)
    res = runner.invoke(app, ["sweep", str(model), "--sample", f"r=table({path}, mm)", "--cases", "4",
                              "-q", "-o", str(tmp_path / "s.h5")], env={"COLUMNS": "200"})
    assert res.exit_code == 2 and f"bad.csv:{line}:" in res.output and says in res.output, res.output
    assert "hint" in res.output and "Traceback" not in res.output
    res = runner.invoke(app, ["sweep", str(model), "--sample", "r=table(none.csv)", "--cases", "4", "-q",
                              "-o", str(tmp_path / "s.h5")])
    assert res.exit_code == 2 and "cannot read the table" in res.output, res.output


# an ideal slider-crank whose crank length and speed are params (a run of 4 ms costs milliseconds)
MODEL = """
param r = 50 mm
param speed = 3000 rpm
body crank  { mass = 0.30 kg  inertia = 1e-5 kg*m^2    position = (r / 2, 0 m)  angle = 0 deg }
body rod    { mass = 0.21 kg  inertia = 2.5e-4 kg*m^2  position = (r + 60 mm, 0 m) }
body slider { mass = 0.14 kg  inertia = 1e-4 kg*m^2    position = (r + 120 mm, 0 m) }
joint O = revolute(ground (0, 0), crank (-r / 2, 0 m))
joint A = revolute(crank (r / 2, 0 m), rod (-60 mm, 0 m))
joint B = revolute(rod (60 mm, 0 m), slider (0, 0))
joint S = translational(ground, slider, axis = (1, 0))
driver crank_speed = rotation(crank, speed = speed)
simulate { t_end = 4 ms  integrator = dopri5  rtol = 1e-9  atol = 1e-12  output_step = 0.1 ms }
"""


def _study(tmp_path, *extra, write_table=True, result=False):
    model = tmp_path / "sc.mbs"
    model.write_text(MODEL)
    out = tmp_path / f"study{len(extra)}.h5"
    table = _table(tmp_path) if write_table else tmp_path / "r.csv"
    args = ["sweep", str(model), "--sample", f"r=table({table}, mm)", "--sample",
            "speed=uniform(2900rpm, 3100rpm)", "--keep", "slider.x", "--no-section", "-j", "1", "-q", "-o", str(out)]
    res = runner.invoke(app, [*args, *extra])
    assert res.exit_code == 0, res.output
    return res if result else out


def _kept(out):
    """Every finished case's kept slider.x, read from the file as a run's results."""
    rows = [r for r in read_case_table(out) if r["status"] == "finished"]
    return [hdf5.read_results(f"{out}:/cases/{r['index']}") for r in rows]


def test_histogram_and_band_are_numpys_over_the_stored_cases(tmp_path):
    out = _study(tmp_path, "--cases", "24", "--sampler", "lhs")
    cases = _kept(out)
    assert len(cases) == 24
    values = np.array([np.interp(0.003, c.time, c["slider.x"]) for c in cases])
    fig = study_plot.figure(out, ["slider.x@3ms"], ["slider.x"])
    hist, band = fig.axes
    counts, edges = np.histogram(values, bins="auto")
    bars = hist.patches
    assert [p.get_height() for p in bars] == list(counts)
    assert np.allclose([p.get_x() for p in bars] + [bars[-1].get_x() + bars[-1].get_width()], edges, rtol=0,
                       atol=1e-12 * np.ptp(edges))
    # the band: np.percentile over the cases' kept signals at each output time (one grid: no interpolation)
    t = np.asarray(cases[0].time)
    ys = np.array([c["slider.x"] for c in cases])
    median = band.lines[0]
    assert np.array_equal(median.get_xdata(), t)
    assert np.allclose(median.get_ydata(), np.percentile(ys, 50, axis=0), rtol=0, atol=1e-15)
    poly = band.collections[0].get_paths()[0].vertices
    for p in (5, 95):
        curve = np.percentile(ys, p, axis=0)
        assert all(np.min(np.abs(poly[:, 1][np.isclose(poly[:, 0], ti, rtol=0, atol=1e-15)] - yi)) < 1e-15
                   for ti, yi in zip(t, curve))
    # the command line writes it as a PNG
    png = tmp_path / "study.png"
    res = runner.invoke(app, ["sweep-stats", str(out), "slider.x@3ms", "--plot", str(png), "--band", "slider.x"])
    assert res.exit_code == 0 and "figure →" in res.output, res.output
    assert _is_png(png)
    for args, says in [(["--band", "slider.x"], "give --plot"), (["slider.x@3ms", "--plot", "f.jpg"], "png"),
                       (["--plot", str(png), "--band", "slider.vx"], "--keep slider.vx"), ([], "name the outputs")]:
        res = runner.invoke(app, ["sweep-stats", str(out), *args])
        assert res.exit_code == 2 and says in res.output and "Traceback" not in res.output, (args, res.output)


def test_sobol_bars_are_the_indices_sweep_stats_prints(tmp_path):
    out = _study(tmp_path, "--cases", "8", "--sampler", "sobol", "--sobol-indices")
    png = tmp_path / "sobol.png"
    res = runner.invoke(app, ["sweep-stats", str(out), "slider.x@3ms", "--plot", str(png)],
                        env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    assert _is_png(png)
    printed = {}
    for line in res.output.splitlines():
        words = line.split()
        if len(words) > 4 and words[1] == "first" and "total" in words:
            printed[words[0]] = (float(words[2]), float(words[words.index("total") + 1]))
    assert set(printed) == {"r", "speed"}
    fig = study_plot.figure(out, ["slider.x@3ms"])
    _, bars = fig.axes
    first, total = [c for c in bars.containers if isinstance(c, BarContainer)]
    labels = [t.get_text() for t in bars.get_xticklabels()]
    for k, name in enumerate(labels):
        s, st = printed[name]
        assert math.isclose(first.patches[k].get_height(), s, abs_tol=5e-4)
        assert math.isclose(total.patches[k].get_height(), st, abs_tol=5e-4)
    sobol = sa.study_report(out, "slider.x@3ms").sobol
    assert [p.get_height() for p in first.patches] == [iv.value for iv in sobol.first]
    assert [p.get_height() for p in total.patches] == [iv.value for iv in sobol.total]


def test_a_table_study_resumes_without_its_file(tmp_path):
    """The measured values are stored with the design: the same command, the file gone, runs nothing new."""
    out = _study(tmp_path, "--cases", "4", "--sampler", "mc")
    before = sa.stored_study(out)
    (tmp_path / "r.csv").unlink()
    res = _study(tmp_path, "--cases", "6", "--sampler", "mc", write_table=False, result=True)
    assert "2 case(s) run, 4 already in the file" in res.output, res.output
    fresh = runner.invoke(app, ["sweep", str(tmp_path / "sc.mbs"), "--sample", f"r=table({tmp_path / 'r.csv'})",
                                "--cases", "4", "-q", "-o", str(tmp_path / "fresh.h5")])
    assert fresh.exit_code == 2 and "cannot read the table" in fresh.output, fresh.output
    after = sa.stored_study(out)
    assert after.n == 6 and after.distributions == before.distributions
    assert after.distributions[0].args == tuple(np.sort([50.02, 49.91, 50.10, 50.02, 49.97, 50.02, 50.21, 49.85]))


def test_a_sweeps_spectrum_grid_draws_each_cases_spectrum(tmp_path, monkeypatch):
    """`mbs plot SWEEP.h5 --spectrum SIGNAL`: one panel per case, each the spectrum of that case's kept
    signal (`results.spectrum`, tested on its own in tests/test_spectrum.py)."""
    from planar_mbs.outputs import plot
    from planar_mbs.results import spectrum

    model = tmp_path / "sc.mbs"
    model.write_text(MODEL)
    out = tmp_path / "speeds.h5"
    res = runner.invoke(app, ["sweep", str(model), "-P", "speed=2000rpm,3000rpm", "--t-end", "60ms", "--keep",
                              "slider.ax,crank", "--no-section", "-j", "1", "-q", "-o", str(out)])
    assert res.exit_code == 0, res.output
    cases = plot.sweep_cases(out)
    fig, kind = plot.sweep_spectrum_figure(cases, "slider.ax", {"kind": "order"})
    assert kind == "order" and len([a for a in fig.axes if a.get_visible()]) == 2
    for ax, (_, case) in zip(fig.axes, cases):
        spec = spectrum.spectrum(case, "slider.ax", "order")
        assert np.array_equal(ax.lines[0].get_ydata(), spec.y)
        # an ideal slider-crank's acceleration: its largest component is order 1, r ω²
        assert spec.peaks(1)[0][0] == pytest.approx(1.0)
    png = tmp_path / "figs"
    res = runner.invoke(app, ["plot", str(out), "--spectrum", "slider.ax", "--kind", "order", "-o", str(png)])
    assert res.exit_code == 0, res.output
    assert _is_png(png / "speeds_order_grid_slider.ax.png")
