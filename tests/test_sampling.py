"""Sampled studies (planar_mbs.sweep.sampling, planar_mbs.results.statistics) against closed forms:
Sobol indices of a linear model, the spread of an ideal slider-crank's slider position under a
toleranced crank length, reproducible designs, intervals that hold and narrow."""
import math

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from planar_mbs.cli.app import app
from planar_mbs.cli.sweep_commands import route
from planar_mbs.results import statistics as st
from planar_mbs.sweep import sampling as sa
from planar_mbs.sweep.scan import SweepError

runner = CliRunner()
DISTS = ["a=normal(1, 2)", "b=uniform(0mm, 6mm)", "c=truncnormal(0, 1, -1, 2)"]


def _dists():
    return tuple(sa.parse_distribution(t) for t in DISTS)


def test_distributions_are_parsed_and_checked():
    a, b, c = _dists()
    assert (a.kind, a.args, a.unit) == ("normal", (1.0, 2.0), "")
    assert b.unit == "mm" and b.variance() == pytest.approx(3.0) and b.text(2.5) == "2.5mm"
    u = np.linspace(0.001, 0.999, 101)
    assert c.ppf(u).min() >= -1 and c.ppf(u).max() <= 2
    for bad, says in [("x=normal(1mm)", "takes 2"), ("x=uniform(2, 1)", "LOW < HIGH"), ("x=gauss(1, 2)", "NAME="),
                      ("x=normal(1mm, 2m)", "one unit"), ("x=normal(1, -2)", "positive")]:
        with pytest.raises(SweepError, match=says):
            sa.parse_distribution(bad)


@pytest.mark.parametrize("sampler", sa.SAMPLERS)
def test_the_same_seed_gives_the_same_cases(sampler):
    one = sa.Study(_dists(), 32, sampler, seed=5)
    assert one.cases() == sa.Study(_dists(), 32, sampler, seed=5).cases()
    assert one.cases() != sa.Study(_dists(), 32, sampler, seed=6).cases()
    if sampler != "lhs":  # Monte Carlo and Sobol' designs extend: a larger n keeps the first cases
        assert sa.Study(_dists(), 48, sampler, seed=5).cases()[:32] == one.cases()


def test_latin_hypercube_strata():
    u = sa.unit_points("lhs", 50, 3, seed=2)
    for col in u.T:  # one point in each of the 50 equal strata of every coordinate
        assert sorted(np.floor(col * 50).astype(int)) == list(range(50))


def test_sobol_indices_of_a_linear_model():
    """y = Σ a_i x_i with independent x_i: S_i = ST_i = a_i² var_i / Σ_j a_j² var_j."""
    coef = np.array([1.0, 0.5, 3.0])
    var = np.array([d.variance() for d in _dists()])
    exact = coef ** 2 * var / np.sum(coef ** 2 * var)
    m = sa.Study(_dists(), 4096, "sobol", seed=3, sobol_indices=True).matrices()
    res = st.sobol_indices(m["A"] @ coef, m["B"] @ coef, np.stack([x @ coef for x in m["AB"]]), "abc", n_boot=200)
    for e, s, t in zip(exact, res.first, res.total):
        assert s.value == pytest.approx(e, abs=0.01) and s.low <= e <= s.high
        assert t.value == pytest.approx(e, abs=0.01) and t.low <= e <= t.high
    assert "first" in "\n".join(res.lines())


def test_intervals_hold_and_narrow():
    rng = np.random.default_rng(0)
    hits = {"mean": 0, "std": 0, "p50": 0, "p90": 0}
    for _ in range(200):
        y = rng.normal(3.0, 2.0, 100)
        s = st.describe(y, percentiles=(50, 90))
        hits["mean"] += s.mean.low <= 3.0 <= s.mean.high
        hits["std"] += s.std.low <= 2.0 <= s.std.high
        hits["p50"] += s.percentiles[50.0].low <= 3.0 <= s.percentiles[50.0].high
        hits["p90"] += s.percentiles[90.0].low <= 3.0 + 2.0 * 1.2815515655446004 <= s.percentiles[90.0].high
    assert all(h >= 0.92 * 200 for h in hits.values()), hits
    y = rng.normal(0.0, 1.0, 1024)
    widths = [(m.high - m.low, s.high - s.low) for _, m, s in st.convergence(y)]
    assert all(w1[0] < w0[0] and w1[1] < w0[1] for w0, w1 in zip(widths, widths[1:]))
    assert math.isnan(st.percentile_interval(y[:20], 5.0).low)  # 20 cases bound no 5th percentile at 95 %


# an ideal slider-crank whose crank length is a param
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
simulate { t_end = 4 ms  integrator = dopri5  rtol = 1e-10  atol = 1e-12  output_step = 0.1 ms }
"""
R, L, SIGMA, OMEGA = 0.05, 0.12, 1e-4, 2 * math.pi * 50.0


def _dx_dr(theta: float) -> float:
    """∂x/∂r of the slider position x = r cos θ + √(l² − r² sin² θ) at crank angle θ."""
    s2 = math.sin(theta) ** 2
    return math.cos(theta) - R * s2 / math.sqrt(L ** 2 - R ** 2 * s2)


def _sweep(path, out, n):
    args = ["sweep", str(path), "--sample", "r=normal(50mm, 0.1mm)", "--cases", str(n), "--sampler", "mc",
            "--random-state", "11", "--keep", "slider.x", "--no-section", "-j", "1", "-q", "-o", str(out)]
    return runner.invoke(app, args)


def test_monte_carlo_spread_of_the_slider_position(tmp_path):
    path = tmp_path / "sc_r.mbs"
    path.write_text(MODEL)
    out = tmp_path / "study.h5"
    res = _sweep(path, out, 48)
    assert res.exit_code == 0 and "48 case(s) run" in res.output, res.output
    at = sa.study_report(out, "slider.x@4ms")
    expected = abs(_dx_dr(OMEGA * 0.004)) * SIGMA  # the linearised spread; the curvature adds O(σ²/r)
    assert at.statistics.n == 48 and at.statistics.unit == "m"
    assert at.statistics.std.low <= expected <= at.statistics.std.high
    assert at.statistics.mean.low <= R * math.cos(OMEGA * 0.004) + math.sqrt(
        L ** 2 - (R * math.sin(OMEGA * 0.004)) ** 2) <= at.statistics.mean.high
    top = sa.study_report(out, "slider.x:max")  # x = r + l at θ = 0: ∂x/∂r = 1
    assert top.statistics.std.low <= SIGMA <= top.statistics.std.high
    # more cases with the same seed: only the new ones run, and the interval narrows
    res = _sweep(path, out, 96)
    assert res.exit_code == 0 and "48 case(s) run, 48 already in the file" in res.output, res.output
    wider = sa.study_report(out, "slider.x@4ms").statistics
    assert wider.n == 96 and wider.std.low <= expected <= wider.std.high
    assert wider.std.high - wider.std.low < at.statistics.std.high - at.statistics.std.low
    argv = ["mbs", "sweep", "stats", str(out), "slider.x@4ms"]
    route(argv)
    res = runner.invoke(app, argv[1:])
    assert res.exit_code == 0 and "mc study, random state 11, 96 samples" in res.output and "std" in res.output, res.output


def test_study_usage_errors(tmp_path):
    path = tmp_path / "sc_r.mbs"
    path.write_text(MODEL)
    out = tmp_path / "s.h5"
    for args, says in [([], "--param NAME=VALUES"), (["--sample", "r=normal(50mm,0.1mm)"], "--cases"),
                       (["--sample", "r=normal(50mm,0.1mm)", "--cases", "8", "-P", "speed=1rpm"], "not both"),
                       (["--sample", "r=normal(50mm,0.1mm)", "--cases", "8", "--sampler", "grid"], "--sampler")]:
        res = runner.invoke(app, ["sweep", str(path), "-o", str(out), *args])
        assert res.exit_code == 2 and says in res.output, res.output
    res = runner.invoke(app, ["sweep-stats", str(out), "slider.x"])
    assert res.exit_code == 2 and "Traceback" not in res.output


def _stored(out):
    """Every case's parameters and its stored slider.x, by case."""
    with h5py.File(out, "r") as f:
        return {k: (g.attrs["case_key"], g["signals/slider"]["x"][()]) for k, g in f["cases"].items()}


def test_the_same_random_state_gives_the_same_study_on_one_core_or_two(tmp_path):
    """The design is drawn before any case runs: one worker or two store the same cases and results."""
    path = tmp_path / "sc_r.mbs"
    path.write_text(MODEL)
    stored = []
    for jobs in ("1", "2"):
        out = tmp_path / f"study{jobs}.h5"
        args = ["sweep", str(path), "--sample", "r=normal(50mm, 0.1mm)", "--cases", "6", "--sampler", "lhs",
                "--random-state", "4", "--keep", "slider.x", "--no-section", "-j", jobs, "-q", "-o", str(out)]
        res = runner.invoke(app, args)
        assert res.exit_code == 0 and "6 case(s) run" in res.output, res.output
        stored.append(_stored(out))
    one, two = stored
    assert sorted(one) == sorted(two) and len(one) == 6
    for k in one:
        assert one[k][0] == two[k][0]
        np.testing.assert_array_equal(one[k][1], two[k][1])
