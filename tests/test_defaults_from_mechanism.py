"""Defaults chosen from what the mechanism has: a slider's velocity along its joint's axis, the output
link where there is no slider, no journal orbit for a contact that is no journal, sweep figures that
draw the stored sections or say why they cannot; short figure titles, labels in words, figure options.

The mechanisms are written here (a vertical slider-crank, a roller on an eccentric disc, a flail)."""
from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from planar_mbs import compile_text, read_results, simulate
from planar_mbs.cli.app import app
from planar_mbs.outputs import plot as P
from planar_mbs.results import views as V
from planar_mbs.results.analysis import read_section
from planar_mbs.results.hdf5 import Results
from planar_mbs.results import section as S

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]

# a slider-crank turned upright: the crank and the rod along y at the start, the slider on a vertical guide
VERTICAL = """
param speed = 1200 rpm
body crank  { mass = 0.30 kg  inertia = 1e-5 kg*m^2    position = (0, 0.025)  angle = 90 deg }
body rod    { mass = 0.21 kg  inertia = 2.5e-4 kg*m^2  position = (0, 0.110)  angle = 90 deg }
body slider { mass = 0.14 kg  inertia = 1e-4 kg*m^2    position = (0, 0.170) }
joint O = revolute(ground (0, 0), crank (-0.025, 0))
joint A = revolute(crank (0.025, 0), rod (-0.06, 0))
joint B = revolute(rod (0.06, 0), slider (0, 0))
joint S = translational(ground, slider, axis = (0, 1))
driver spin = rotation(crank, speed = speed)
simulate { t_end = 4 rev / speed  rtol = 1e-9  atol = 1e-12  output_step = 0.25 ms }
"""

# a roller (a circle on the follower) on an eccentric disc cam: two circles touching from outside
ROLLER = """
param speed = 300 rpm
param e = 5 mm
param Rc = 30 mm
param r = 8 mm
param K = 1e10 N/m^1.5
param P = 20 N
param k = 500 N/m
param d0 = (P / K)^(2/3)
body cam      { mass = 1 kg  inertia = 1e-3 kg*m^2  position = (0, e) }
body follower { mass = 0.2 kg  inertia = 1e-3 kg*m^2  position = (0, e + Rc + r - d0) }
joint pivot = revolute(ground (0, 0), cam (0, -e))
joint guide = translational(ground, follower, axis = (0, 1))
driver spin = rotation(cam, speed = speed)
force spring = spring_damper(ground (0, 0.3), follower) { stiffness = k  length = 0.3 m - e - Rc - r + d0 + P / k }
joint roll = contact(cam (0, 0), follower (0, 0)) {
    shape = circle_on_circle  first_radius = Rc  radius = r  stiffness = K  law = hertz
}
simulate { t_end = 3 rev / speed  rtol = 1e-9  atol = 1e-12  output_step = 0.5 ms }
"""

# a driven crank with an arm swinging from its tip: no slider, and no other link pivoted on ground
FLAIL = """
param speed = 600 rpm
body crank { mass = 1 kg  inertia = 1e-3 kg*m^2  position = (0.05, 0) }
body arm   { mass = 0.2 kg  inertia = 1e-3 kg*m^2  position = (0.15, 0) }
joint O = revolute(ground (0, 0), crank (-0.05, 0))
joint A = revolute(crank (0.05, 0), arm (-0.05, 0))
driver spin = rotation(crank, speed = speed)
simulate { t_end = 0.3 s  output_step = 1 ms }
"""


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def vertical(tmp_path_factory):
    folder = tmp_path_factory.mktemp("vertical")
    model = compile_text(VERTICAL, str(folder / "vertical.mbs"))
    out = folder / "vertical.h5"
    simulate(model, output=out)
    return model, out


def test_a_vertical_slider_is_sectioned_along_its_axis(vertical):
    """The slider moves along y only: its vx is round-off, and the default section, figures and map
    take vy and ay, from the model, from what the file recorded, and from the motion alone."""
    model, out = vertical
    res = read_results(out)
    assert np.ptp(res["slider.vx"]) < 1e-9 * np.ptp(res["slider.vy"])
    assert S.default_signals(res, model) == ("slider.vy", "slider.ay")
    assert S.default_signals(res) == ("slider.vy", "slider.ay")  # the file's recorded mechanism
    del res.attrs["mechanism"]
    assert S.default_signals(res) == ("slider.vy", "slider.ay")  # a file without it: the motion decides
    assert dict(P.default_panels(read_results(out))) == {
        "slider_velocity": ["slider.vy"], "slider_acceleration": ["slider.ay"], "driver_torque": ["spin.torque"]}
    # the section points are vy at every whole crank revolution t = k T after the first
    sec = S.poincare_section(read_results(out))
    T = 60.0 / 1200.0
    np.testing.assert_allclose(sec.time, T * np.arange(2, 5), rtol=1e-9)
    np.testing.assert_allclose(sec.points["slider.vy"], np.interp(sec.time, res.time, res["slider.vy"]),
                               atol=1e-9 * np.ptp(res["slider.vy"]))


def test_the_default_map_of_a_vertical_slider_is_drawn_in_words(vertical, tmp_path):
    _, out = vertical
    names = {p.name for p in P.plot_file(out, outdir=tmp_path)}
    assert "vertical_poincare_slider.vy_slider.ay.png" in names
    fig = P.poincare_figure(read_results(out), "slider.vy", "slider.ay")
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("slider velocity y [m/s]", "slider acceleration y [m/s²]")


def test_two_outside_circles_get_no_journal_orbit(tmp_path):
    """A roller on a disc cam: a contact of two circles from outside is no journal in a bearing, so the
    default figures draw no orbit with a "clearance c = ..." circle (its e − penetration, R₁ + R₂ −
    2 δ, is nearly constant while they roll, so the data alone would pass it for a clearance)."""
    model = compile_text(ROLLER, str(tmp_path / "roller.mbs"))
    out = tmp_path / "roller.h5"
    simulate(model, output=out)
    names = {p.name for p in P.plot_file(out, outdir=tmp_path / "figs")}
    assert not any("orbit" in n for n in names), names
    assert "roller_poincare_follower.vy_follower.ay.png" in names  # the follower rides along y
    res = read_results(out)
    assert res.attrs["mechanism"]["contacts"] == {"roll": "circle_on_circle"}
    assert not V.is_journal(None, "roll", res) and not V.is_journal(model, "roll")
    r = runner.invoke(app, ["plot", str(out), "--orbit", "roll", "-o", str(tmp_path / "figs")])  # asked for
    assert r.exit_code == 2 and "not a journal" in r.output and "roll.penetration" in r.output, r.output


@pytest.fixture(scope="module")
def four_bar(tmp_path_factory):
    out = tmp_path_factory.mktemp("four_bar") / "fb.h5"
    r = runner.invoke(app, ["run", str(ROOT / "models" / "four_bar_clearance.mbs"), "-o", str(out), "-q",
                            "--t-end", "0.25s"])
    assert r.exit_code == 0, r.output
    return out


def test_analyze_sections_the_output_link_of_a_four_bar(four_bar):
    """No body called slider: `mbs analyze` takes the rocker's angle and speed at each crank revolution
    (exit 0) instead of asking for two signals; the points are the rocker's at t = k T."""
    r = runner.invoke(app, ["analyze", str(four_bar)])
    assert r.exit_code == 0, r.output
    assert "rocker_link.phi, rocker_link.omega" in r.output
    res = read_results(four_bar)
    assert S.slider_body(res) is None and S.output_body(res) == "rocker_link"
    sec = S.poincare_section(res)
    T = 60.0 / 1000.0
    np.testing.assert_allclose(sec.time, T * np.arange(2, 2 + len(sec)), rtol=1e-9)
    for name in ("rocker_link.phi", "rocker_link.omega"):
        np.testing.assert_allclose(sec.points[name], np.interp(sec.time, res.time, res[name]),
                                   atol=1e-9 * np.ptp(res[name]))
    del res.attrs["mechanism"]  # without the recorded mechanism: the link that rotates about a fixed point
    assert S.output_body(res) == "rocker_link"


def test_default_figures_of_a_four_bar_show_its_output_link(four_bar, tmp_path):
    names = {p.name for p in P.plot_file(four_bar, outdir=tmp_path)}
    assert {"fb_rocker_link_angle.png", "fb_rocker_link_angular_velocity.png",
            "fb_poincare_rocker_link.phi_rocker_link.omega.png", "fb_orbit_B.png"} <= names


# ---------------------------------------------------------------- sweeps
@pytest.fixture(scope="module")
def vertical_model(tmp_path_factory):
    return _write(tmp_path_factory.mktemp("vmodel"), "vertical.mbs", VERTICAL)


def _sweep(model: Path, out: Path, *extra: str):
    r = runner.invoke(app, ["sweep", str(model), "-P", "speed=900rpm,1200rpm", "-n", "6", "-j", "1", "-q",
                            "-o", str(out), *extra])
    assert r.exit_code == 0, r.output
    return r


def test_a_sweep_without_a_section_says_why_and_how(tmp_path):
    """The flail has no slider and no output link: the verdict columns stay blank, and the sweep says
    why and names `-p X:Y` with signals of the mechanism."""
    r = _sweep(_write(tmp_path, "flail.mbs", FLAIL), tmp_path / "flail.h5")
    assert "no verdict for case 0, 1" in r.output and "no slider" in r.output, r.output
    hint = [line for line in r.output.splitlines() if line.startswith("hint: ")]
    assert hint and "-p arm.omega:arm.alpha" in hint[0], r.output


def test_a_sweep_keeping_no_clock_draws_its_stored_sections(vertical_model, tmp_path):
    """`--keep slider,rod` keeps no angle of the crank that clocks the section: `mbs plot` draws the
    stored sections instead of maps of 0 points, and a map asked of the kept signals is refused with a
    hint that names what to keep."""
    out = tmp_path / "s.h5"
    _sweep(vertical_model, out, "--keep", "slider,rod")
    r = runner.invoke(app, ["plot", str(out), "-o", str(tmp_path / "figs")])
    assert r.exit_code == 0, r.output
    assert "0 points" not in r.output and "s_bifurcation_slider.vy.png" in r.output, r.output
    said = " ".join(r.output.split())  # the note as printed, wrapped to the terminal
    assert "no angle of `crank`" in said and "--keep rod,slider,crank" in said, r.output
    for clock in ([], ["--clock", "crank"]):  # the clock named or not: the same reason, a hint with text
        r = runner.invoke(app, ["plot", str(out), "-p", "slider.vy:slider.ay", *clock, "-o", str(tmp_path / "figs")])
        assert r.exit_code == 2 and "no angle of `crank`" in r.output, r.output
        hint = r.output.split("hint: ", 1)[1].strip()
        assert hint and "--keep rod,slider,crank" in hint, r.output


def test_hints_are_never_empty():
    """A clock body that is neither in the results nor near any name there still gets a hint."""
    t = np.linspace(0, 1, 11)
    res = Results(time=t, signals={"a.vx": t, "a.ax": t}, units={}, attrs={})
    with pytest.raises(V.PlotError) as err:
        V.poincare(res, "a.vx", "a.ax", body="cam")
    hint = str(err.value).split("hint:", 1)[1].strip()
    assert hint, str(err.value)


def test_a_sweep_without_keep_plots_its_sections_as_a_bifurcation_diagram(vertical_model, tmp_path):
    """No --keep: `mbs plot SWEEP.h5` draws each stored section signal against the speed, with its unit,
    the points being the stored ones."""
    out = tmp_path / "s.h5"
    _sweep(vertical_model, out)
    r = runner.invoke(app, ["plot", str(out), "-o", str(tmp_path / "figs")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "figs" / "s_bifurcation_slider.vy.png").exists(), r.output
    figures = dict(P.stored_bifurcation_figures(out))
    ax = figures["slider.vy"].axes[0]
    assert ax.get_ylabel() == "slider velocity y at the Poincaré section [m/s]" and ax.get_xlabel() == "speed [rpm]"
    drawn = sorted(float(y) for ln in ax.get_lines() for y in ln.get_ydata())
    with h5py.File(out, "r") as f:
        stored = sorted(float(y) for k in f["cases"] for y in read_section(f["cases"][k])[0].points["slider.vy"])
    np.testing.assert_array_equal(drawn, stored)


# ---------------------------------------------------------------- figure titles and options
def test_a_title_is_one_line_however_many_parameters(vertical):
    _, out = vertical
    res = read_results(out)
    res.attrs["parameters"] = {f"parameter_{i}": f"{i} mm" for i in range(12)}
    title = P._title(res, 8.0)
    assert "\n" not in title and len(title) <= 80 and title.endswith("…"), title
    assert title.startswith("vertical.mbs · parameter_0 = 0 mm")


def test_plot_options_set_title_labels_and_size(vertical, tmp_path):
    _, out = vertical
    r = runner.invoke(app, ["plot", str(out), "slider.vy", "--title", "upright slider", "--xlabel", "t",
                            "--ylabel", "v", "--size", "6x3", "-o", str(tmp_path)])
    assert r.exit_code == 0, r.output
    (png,) = tmp_path.glob("*.png")
    assert Image.open(png).size == (round(6 * 110), round(3 * 110))
    fig = P.series_figure(read_results(out), [["slider.vy"]])
    P.restyle(fig, P.check_style({"title": "upright slider", "xlabel": "t", "ylabel": "v"}))
    assert fig._suptitle.get_text() == "upright slider"
    assert (fig.axes[0].get_xlabel(), fig.axes[0].get_ylabel()) == ("t", "v")
    r = runner.invoke(app, ["plot", str(out), "slider.vy", "--size", "big", "-o", str(tmp_path)])
    assert r.exit_code == 2 and "--size 8x4" in r.output, r.output

