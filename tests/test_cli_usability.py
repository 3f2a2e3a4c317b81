"""What a new user hits on the command line: --version, grammar of `check`, defaults in every
--help, `run --revolutions/--output-step/--per-rev`, default outputs in results/, `sweep --keep ""`,
a rerun of a sweep with failed cases, an interruptible sweep."""
from __future__ import annotations

import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import typer
from typer.testing import CliRunner

import planar_mbs
from planar_mbs import read_results
from planar_mbs.cli.app import app
from planar_mbs.sweep.scan import read_case_table

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
IDEAL = MODELS / "slider_crank.mbs"
runner = CliRunner()
PERIOD = 60 / 5000  # s per crank revolution of slider_crank.mbs

PENDULUM = """
body bob { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0.5, 0) }
joint pin = revolute(ground (0, 0), bob (-0.5, 0))
gravity (0, -9.81 m/s^2)
simulate { t_end = 10 ms  output_step = 1 ms }
"""


def test_the_version_is_the_one_pyproject_declares():
    import tomllib
    from pathlib import Path

    declared = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())["project"]["version"]
    assert planar_mbs.__version__ == declared


def test_version():
    r = runner.invoke(app, ["--version"])
    assert r.exit_code == 0 and r.output.strip() == f"mbs (planar_mbs) {planar_mbs.__version__}"


def test_check_counts_in_good_english(tmp_path):
    model = tmp_path / "pendulum.mbs"
    model.write_text(PENDULUM)
    r = runner.invoke(app, ["check", str(model)])
    assert r.exit_code == 0, r.output
    assert "2 constraints, 1 degree of freedom" in r.output and "1 degrees" not in r.output


def _options():
    group = typer.main.get_command(app)
    for name, command in group.commands.items():
        for p in command.params:
            if (isinstance(p, typer.core.TyperOption) and not p.is_flag and not p.required and p.name != "help"
                    and not p.hidden):  # a hidden option is an old name of another
                yield name, p


# options whose absence means "not asked for" (nothing to show as a default)
NO_DEFAULT = {"--set", "--rerun", "--orbit", "--against", "--angle", "--revolutions", "--per-rev",
              "--scheduler", "plot --poincare"}


def test_every_option_with_a_value_shows_its_default():
    options = list(_options())
    missing = [f"{cmd} {p.opts[0]}" for cmd, p in options
               if p.show_default is False or (p.default is None and not isinstance(p.show_default, str))]
    assert len(options) > 20
    assert [m for m in missing if m.split()[1] not in NO_DEFAULT and m not in NO_DEFAULT] == []


@pytest.mark.parametrize("command", ["run", "sweep", "plot", "view", "analyze"])
def test_help_text_keeps_its_defaults_and_has_no_stray_placeholders(command):
    r = runner.invoke(app, [command, "--help"], env={"COLUMNS": "250"})
    assert r.exit_code == 0
    assert not re.search(r"\w \.(\s|$)", r.output), r.output  # what rich markup left of "[default: ...]"
    shown = {"run": ["results/<model name>.h5", "the model's simulate block, else dopri5"],
             "sweep": ["(the number of cores)", "[default: (none)]", "(the slider's vx:ax)"],
             "plot": ["<results>_plots/"], "view": ["<results>.rrd"], "analyze": ["[default: 1.0]"]}[command]
    for text in shown:
        assert text in r.output, text


def test_run_revolutions_per_rev_and_output_step(tmp_path):
    out = tmp_path / "a.h5"
    r = runner.invoke(app, ["run", str(IDEAL), "-o", str(out), "-q", "-n", "2", "--per-rev", "10"])
    assert r.exit_code == 0, r.output
    res = read_results(out)
    assert len(res.time) == 21 and math.isclose(res.time[-1], 2 * PERIOD, rel_tol=1e-12)
    r = runner.invoke(app, ["run", str(IDEAL), "-o", str(out), "-q", "--t-end", "5ms", "--output-step", "1ms"])
    assert r.exit_code == 0, r.output
    assert len(read_results(out).time) == 6
    r = runner.invoke(app, ["run", str(IDEAL), "-o", str(out), "-q", "-n", "2", "--t-end", "5ms"])
    assert r.exit_code == 2 and "not both" in r.output


def test_default_output_goes_to_results_and_keeps_other_set_values(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = runner.invoke(app, ["run", str(IDEAL), "-q", "--t-end", "2ms"])
    assert r.exit_code == 0, r.output
    first = tmp_path / "results" / "slider_crank.h5"
    assert first.exists() and "*" in (tmp_path / "results" / ".gitignore").read_text().split()
    r = runner.invoke(app, ["run", str(IDEAL), "-q", "--t-end", "2ms", "--set", "speed=2500 rpm"])
    assert r.exit_code == 0, r.output
    second = tmp_path / "results" / "slider_crank_speed=2500rpm.h5"
    assert second.exists() and str(second.relative_to(tmp_path)) in r.output
    assert read_results(first).attrs["parameters"]["speed"] == "5000 rpm"
    assert read_results(second).attrs["parameters"]["speed"] == "2500 rpm"


def test_sweep_keep_empty_stores_no_signals(tmp_path):
    out = tmp_path / "s.h5"
    r = runner.invoke(app, ["sweep", str(IDEAL), "-P", "speed=1000rpm,2000rpm", "-n", "3", "--per-rev", "36",
                            "-j", "1", "-q", "--keep", "", "-o", str(out)])
    assert r.exit_code == 0, r.output
    with h5py.File(out, "r") as f:
        for k in f["cases"]:
            assert len(f["cases"][k].get("signals", {})) == 0
            assert "poincare" in f["cases"][k]  # the section is still there


def test_rerun_of_a_sweep_with_failed_cases_still_fails(tmp_path):
    model = tmp_path / "few_steps.mbs"
    model.write_text(IDEAL.read_text().replace("output_step = 10 us", "output_step = 10 us  max_steps = 20"))
    out = tmp_path / "s.h5"
    cmd = ["sweep", str(model), "-P", "speed=1000rpm,2000rpm", "-n", "2", "-j", "1", "-q", "-o", str(out)]
    first = runner.invoke(app, cmd)
    assert first.exit_code == 3 and "2 failed" in first.output, first.output
    again = runner.invoke(app, cmd)
    assert again.exit_code == 3, again.output
    assert "0 case(s) run, 2 already in the file, 2 failed (2 from an earlier run" in again.output
    assert [r["status"] for r in read_case_table(out)] == ["failed", "failed"]


@pytest.mark.slow
def test_sweep_started_with_sigint_ignored_can_still_be_interrupted(tmp_path):
    """A script without job control starts commands with SIGINT ignored; `mbs sweep` must still
    stop on SIGINT (exit 130), as `mbs run` does.  Two jobs: the parent only waits for its
    workers (with one job the case runs in the parent, whose time loop handles SIGINT itself)."""
    out = tmp_path / "s.h5"
    cmd = [sys.executable, "-c", "from planar_mbs.cli.app import main; main()", "sweep", str(IDEAL),
           "-P", "speed=600rpm..1400rpm:6", "-n", "500", "--per-rev", "360", "-o", str(out), "-j", "2", "-q"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    from planar_mbs.sweep.store import journal_folder

    deadline = time.time() + 120
    while time.time() < deadline:  # wait for the first finished case (in the sweep's journal)
        time.sleep(0.5)
        if any(journal_folder(out).glob("case-*.h5")):
            break
    assert proc.poll() is None, "the sweep ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=60) == 130, proc.stderr.read()


def test_analyze_without_section_points_prints_no_numpy_warning(tmp_path):
    import warnings

    out = tmp_path / "short.h5"
    assert runner.invoke(app, ["run", str(IDEAL), "-o", str(out), "-q", "--t-end", "5ms"]).exit_code == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a RuntimeWarning would now fail the command
        r = runner.invoke(app, ["analyze", str(out)])
    assert r.exit_code == 0 and "0 points" in r.output and "run longer" in r.output, r.output


def test_sweep_keep_takes_an_entity_name_as_its_help_says(tmp_path):
    """`--keep slider` stores every signal of the slider and nothing else (the help: "an entity
    name (slider) keeps all its signals"); the case's stored names are read back with h5py."""
    out = tmp_path / "k.h5"
    res = runner.invoke(app, ["sweep", str(MODELS / "slider_crank_clearance_a.mbs"), "-P", "speed=4000rpm,5000rpm",
                              "-n", "2", "--per-rev", "36", "-j", "1", "-q", "--keep", "slider", "-o", str(out)])
    assert res.exit_code == 0, res.output
    with h5py.File(out, "r") as f:
        for case in f["cases"].values():
            entities = set(case["signals"].keys())
            assert entities == {"slider"}, entities
            assert {"x", "vx", "ax"} <= set(case["signals"]["slider"].dtype.names)


@pytest.mark.parametrize("fast", [True, False])
def test_run_keep_stores_only_the_named_signals_with_the_values_of_a_full_run(tmp_path, fast):
    """`mbs run --keep slider.vx,crank` (the typer-free path and typer's) stores those signals only,
    each equal to the same signal of a run that keeps everything; the summary still prints."""
    full, kept = tmp_path / "full.h5", tmp_path / "kept.h5"
    args = ["run", str(IDEAL), "-q", "--t-end", "2ms"]
    assert runner.invoke(app, args + ["-o", str(full)]).exit_code == 0
    if fast:
        from planar_mbs.cli.run_command import run_model
        from planar_mbs.cli.run_options import plain_run

        kwargs = plain_run(args + ["--keep", "slider.vx,crank", "-o", str(kept)])
        assert kwargs is not None and run_model(**kwargs) == 0
    else:
        r = runner.invoke(app, args + ["--keep", "slider.vx, crank", "-o", str(kept)])
        assert r.exit_code == 0, r.output
        assert "largest constraint error not kept (--keep)" in " ".join(r.output.split())
    a, b = read_results(full), read_results(kept)
    crank = {name for name in a.signals if name.startswith("crank.")}
    assert set(b.signals) == {"slider.vx"} | crank and len(crank) >= 6
    np.testing.assert_array_equal(b.time, a.time)
    for name in b.signals:
        np.testing.assert_array_equal(b[name], a[name])


@pytest.mark.parametrize("other", [["--rerun", "r.rrd"], ["--until-settled"]])
def test_run_keep_with_an_option_that_needs_every_signal_is_refused(tmp_path, other):
    r = runner.invoke(app, ["run", str(IDEAL), "-q", "--keep", "slider", "-o", str(tmp_path / "k.h5"), *other])
    assert r.exit_code == 2 and "--keep" in r.output, r.output
    assert not (tmp_path / "k.h5").exists()


# ---------------------------------------------------------------- help that reads well, one error style
@pytest.mark.parametrize("argv", [[], ["run"], ["plot"], ["view"], ["sweep"], ["analyze"], ["check"]])
def test_help_names_values_in_words(argv):
    """-h works everywhere; values are named in words (TIME, NAME=VALUE, MODEL), a flag shows no
    value, and choices are listed as choices; no Python type names."""
    r = runner.invoke(app, [*argv, "-h"], env={"COLUMNS": "200"})
    assert r.exit_code == 0, r.output
    for typer_text in ("<bool>", "<list[str]>", "<str>", "<path>", "<float", "<int", "{model}", "{results}"):
        assert typer_text not in r.output, (argv, typer_text)
    if argv == ["run"]:
        assert "rk4|dopri5|dop853" in r.output and "NAME=VALUE" in r.output and "TIME" in r.output
        assert "Usage: mbs run [OPTIONS] MODEL" in r.output


@pytest.mark.parametrize("argv", [["run"], ["plot"], ["view"], ["sweep"], ["analyze"], ["check"]])
def test_a_commands_help_wraps_its_paragraphs_at_the_terminals_width(argv):
    """A docstring's line breaks are not kept in --help (at 1000 columns each paragraph of the description
    is one line; at 80 the terminal's width wraps it, not the docstring's): `mbs sweep --help` once showed
    half-lines wherever its docstring broke a line."""
    wide = runner.invoke(app, [*argv, "--help"], env={"COLUMNS": "1000"}).output
    description = wide.split("Usage:", 1)[1].split("╭", 1)[0].strip("\n").split("\n")[2:]
    paragraphs = [line.strip() for line in description if line.strip()]
    assert paragraphs, wide
    blank_separated = "\n".join(line.strip() for line in description).split("\n\n")
    assert all("\n" not in para.strip() for para in blank_separated), wide  # one line per paragraph
    if argv == ["sweep"]:
        assert "the verdict on its motion (periodic, quasi-periodic or chaotic) under" in wide


def test_mbs_help_lists_every_exit_code_and_completion():
    r = runner.invoke(app, ["--help"], env={"COLUMNS": "300"})
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    table = re.findall(r"^\| (\d+(?:, \d+)*) \|", readme, re.M)
    codes = [c for row in table for c in row.split(", ")]
    assert sorted(codes) == ["0", "1", "130", "143", "2", "3"]
    for code in codes:
        assert re.search(rf"(^|[ /·]){code}[ /]", r.output.split("Exit codes:")[1]), code
    assert "--install-completion" in r.output


@pytest.mark.parametrize("argv,where", [(["run", "m.mbs", "--per-rev", "0"], "--per-rev"),
                                        (["run", "m.mbs", "--bogus"], "mbs run"),
                                        (["plot"], "RESULTS")])
def test_usage_errors_read_like_every_other_error(argv, where):
    """click's usage errors in the project's style (`WHERE: error: ...`, a hint), not a box."""
    r = runner.invoke(app, argv)
    assert r.exit_code == 2
    assert r.output.startswith(f"{where}: error: ") and "\nhint: " in r.output and "╭" not in r.output, r.output


def test_rk45_means_dopri5():
    r = runner.invoke(app, ["run", str(IDEAL), "--integrator", "rk45"])
    assert r.exit_code == 2 and "did you mean `dopri5`?" in r.output


def test_one_name_per_idea_old_names_still_work(monkeypatch):
    """`run --open` as `view --open`, `plot --transient` as `analyze --transient`; the old names
    (`--view`, `--skip`) still work and are not shown."""
    from planar_mbs.cli import run_command

    seen = []
    monkeypatch.setattr(run_command, "run_model", lambda model, **kw: seen.append(kw["view_"]) or 0)
    for flag in ("--open", "--view"):
        assert runner.invoke(app, ["run", "m.mbs", "--rerun", "x.rrd", flag]).exit_code == 0
    assert seen == [True, True]
    for command, shown, hidden in (("run", "--open", "--view"), ("plot", "--transient", "--skip")):
        text = runner.invoke(app, [command, "--help"], env={"COLUMNS": "200"}).output
        assert shown in text and hidden not in text


def test_a_default_name_does_not_replace_a_run_with_other_settings(tmp_path, monkeypatch):
    """results/<model>.h5 of a 2 ms run is kept when a 3 ms run follows: that one goes beside it, its
    name carrying the option given; the same run again replaces its own file."""
    monkeypatch.chdir(tmp_path)
    first = tmp_path / "results" / "slider_crank.h5"
    assert runner.invoke(app, ["run", str(IDEAL), "-q", "--t-end", "2ms"]).exit_code == 0
    r = runner.invoke(app, ["run", str(IDEAL), "-q", "--t-end", "3ms"])
    assert r.exit_code == 0, r.output
    second = tmp_path / "results" / "slider_crank_t-end=3ms.h5"
    assert "holds a run with other settings" in r.output and str(second.relative_to(tmp_path)) in r.output
    assert read_results(first).time[-1] == pytest.approx(2e-3) and read_results(second).time[-1] == pytest.approx(3e-3)
    r = runner.invoke(app, ["run", str(IDEAL), "-q", "--t-end", "2ms"])
    assert r.exit_code == 0 and "other settings" not in r.output and sorted(first.parent.glob("*.h5")) == [first, second]
