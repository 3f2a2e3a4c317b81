"""The figures of docs/plots.md, the README, docs/tutorial.md and docs/beams.md are what the commands those
pages show (or the scripts they name) draw today: each is drawn again (docs/scripts/page_figures.py) and
compared with the page's image, so a figure that drifts from the program (a Poincaré point more, a title
changed) fails here."""
from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "scripts"))

import page_figures as F  # noqa: E402


def test_every_command_of_the_script_is_on_its_page():
    """The script runs the pages' own commands, and the pages show the images it draws."""
    for page, (commands, keep) in F.PAGES.items():
        text = (ROOT / page.split("#")[0]).read_text(encoding="utf-8")
        for command in commands:
            assert " ".join(command.split()) in " ".join(text.split()), (page, command)
        for name in keep.values():
            assert f"images/{name}" in text, (page, name)
    for page, (script, names) in F.SCRIPTS.items():
        text = (ROOT / page).read_text(encoding="utf-8")
        assert f"docs/scripts/{script}.py" in text, (page, script)
        for name in names:
            assert f"images/{name}" in text, (page, name)
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for name in re.findall(r"\(docs/images/([^)]+\.png)\)", readme):
        assert any(name in keep.values() for _, keep in F.PAGES.values()), name


@pytest.fixture(scope="module")
def drawn(tmp_path_factory):
    return F.draw(tmp_path_factory.mktemp("figures"))


def test_every_figure_of_the_pages_is_what_the_program_draws(drawn):
    from matplotlib.testing.compare import compare_images

    assert len(drawn) == (sum(len(keep) for _, keep in F.PAGES.values())
                          + sum(len(names) for _, names in F.SCRIPTS.values()))
    for path in drawn:
        # a small RMS allowance for anti-aliasing between font renderers; one Poincaré point more or
        # less, or a changed title, is far above it
        diff = compare_images(str(F.IMAGES / path.name), str(path), tol=0.3)
        assert diff is None, f"docs/images/{path.name} is stale: run docs/scripts/page_figures.py\n{diff}"


def test_a_sweep_without_the_kept_signals_draws_its_stored_sections(tmp_path, monkeypatch):
    """docs/plots.md: without the cases' signals (no --keep) or without the clock body's angle among them,
    `mbs plot sweep.h5` draws the sections the sweep stored as a bifurcation diagram (exit 0); a Poincaré
    map asked of kept signals that lack the clock's angle says what to keep (exit 2), never naming a body
    `None` or giving an empty hint."""
    from typer.testing import CliRunner

    from planar_mbs.cli.app import app

    text = (ROOT / "docs" / "plots.md").read_text(encoding="utf-8")
    assert "`--keep slider,crank`" in text and "sections the sweep stored" in text
    monkeypatch.chdir(tmp_path)
    model = str(ROOT / "models" / "slider_crank_clearance_a.mbs")
    run = CliRunner()
    for keep, out in (([], "bare.h5"), (["--keep", "slider.vx,slider.ax"], "some.h5")):
        r = run.invoke(app, ["sweep", model, "-P", "speed=2500rpm,5000rpm", "-n", "3", "-q", "-o", out, *keep])
        assert r.exit_code == 0, r.output
        r = run.invoke(app, ["plot", out])
        assert r.exit_code == 0 and f"{out[:-3]}_bifurcation_slider.vx.png" in r.output, r.output
    r = run.invoke(app, ["plot", "some.h5", "-p", "slider.vx:slider.ax"])
    assert r.exit_code == 2 and "None" not in r.output and "--keep slider,crank" in r.output, r.output
    assert r.output.split("hint:", 1)[1].strip(), r.output
