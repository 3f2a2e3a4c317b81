"""The tutorial's four-bar (docs/tutorial/four_bar.mbs) against its closed-form position analysis."""
import re
import shlex
from pathlib import Path

import numpy as np

import planar_mbs as mbs

MODEL = Path(__file__).resolve().parents[1] / "docs" / "tutorial" / "four_bar.mbs"
A_, B_, C_, D_ = 0.020, 0.080, 0.060, 0.070  # crank, coupler, rocker, frame [m]


def rocker_angle(theta):
    """Rocker angle from the triangle O4-A-B (circle intersection, upper branch):
    A = a (cos θ, sin θ); B is b from A and c from O4 = (d, 0)."""
    ax, ay = A_ * np.cos(theta), A_ * np.sin(theta)
    fx, fy = ax - D_, ay  # O4 -> A
    f = np.hypot(fx, fy)
    gamma = np.arccos((f**2 + C_**2 - B_**2) / (2 * f * C_))  # angle at O4 between O4A and O4B
    return np.arctan2(fy, fx) - gamma  # turn clockwise from O4A: the upper branch


def test_rough_pose_assembles_and_rocker_follows_closed_form():
    res = mbs.simulate(mbs.load_model(MODEL))
    theta = res["crank_link.phi"]
    assert np.ptp(theta) > 4 * np.pi - 0.1  # two revolutions
    diff = res["rocker_link.phi"] - rocker_angle(theta)
    diff = np.angle(np.exp(1j * diff))  # the same angle, whatever the number of turns
    assert np.max(np.abs(diff)) < 1e-8
    assert np.max(res["system.position_error"]) < 1e-9


# ---------------------------------------------------------------- the page itself
TUTORIAL = MODEL.parents[1] / "tutorial.md"
FRAGMENT = re.compile(r"^```mbs fragment\n(.*?)^```", re.S | re.M)
CONSOLE = re.compile(r"^```console\n(.*?)^```", re.S | re.M)
# numbers that depend on the machine: shown in the text, not compared
LOOSE = [(re.compile(r"wall time \S+ s"), "wall time"), (re.compile(r"constraint error \S+"), "constraint error")]


def _loose(line: str) -> str:
    for pattern, repl in LOOSE:
        line = pattern.sub(repl, line)
    return line.rstrip()


def _user_file(text: str) -> str:
    """four_bar.mbs as a reader builds it: the blocks of §1-§4, one after the other."""
    blocks = FRAGMENT.findall(text)
    return "\n".join(blocks[:4])


def test_blocks_build_the_shipped_model(tmp_path):
    """The page's blocks and docs/tutorial/four_bar.mbs are the same mechanism: same run."""
    built = mbs.compile_text(_user_file(TUTORIAL.read_text(encoding="utf-8")), str(tmp_path / "four_bar.mbs"))
    shipped = mbs.load_model(MODEL)
    a, b = mbs.simulate(built), mbs.simulate(shipped)
    assert set(a.signals) == set(b.signals)
    for name in ("rocker_link.phi", "motor.torque", "B.force"):
        np.testing.assert_array_equal(a[name], b[name])


def test_every_command_of_the_page_prints_what_the_page_shows(tmp_path, monkeypatch):
    """§3 checks the file as it is after §3 (no driver yet), §4 after the driver; every other
    command runs on the whole file.  Its output must be the lines the page shows (all of them, unless
    the page ends the block with "...")."""
    from typer.testing import CliRunner

    from planar_mbs.cli.app import app

    text = TUTORIAL.read_text(encoding="utf-8")
    blocks = FRAGMENT.findall(text)
    monkeypatch.chdir(tmp_path)
    full = _user_file(text)
    typo = full.replace("revolute(crank_link (crank / 2, 0)", "revolute(crank_lnk (crank / 2, 0)")
    assert typo != full
    (tmp_path / "broken.mbs").write_text(typo)
    stages = ["\n".join(blocks[:3]), full]  # the first `mbs check` comes before the driver, the second after
    (tmp_path / "four_bar.mbs").write_text(full)
    runner = CliRunner()
    ran = 0
    for block in CONSOLE.findall(text):
        lines = block.splitlines()
        i = 0
        while i < len(lines):
            line = lines[i]
            assert line.startswith("$ mbs "), line
            command = shlex.split(line[2:].split("  #")[0])[1:]
            expected = []
            i += 1
            while i < len(lines) and not lines[i].startswith("$ "):
                expected.append(lines[i])
                i += 1
            if "--open" in command or "--view" in command:
                continue  # opens a window
            if command[:2] == ["check", "four_bar.mbs"]:
                (tmp_path / "four_bar.mbs").write_text(stages.pop(0))
            r = runner.invoke(app, command, env={"COLUMNS": "200"})
            ran += 1
            assert r.exit_code == (2 if "broken" in line else 0), (line, r.output)
            # the whole output, unless the page ends the block with "..." (more lines follow)
            more = bool(expected) and expected[-1].strip() == "..."
            expected = expected[:-1] if more else expected
            got = [_loose(x) for x in r.output.splitlines() if x.strip()]  # (a progress bar leaves a blank line)
            got = got[:len(expected)] if more else got
            assert got == [_loose(x) for x in expected], (line, r.output)
    assert ran >= 6
