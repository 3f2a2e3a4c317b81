"""Start-up paths: `mbs check` and a plain `mbs run` without typer, kernels without scipy.linalg, sweep
workers forked from a preloaded server."""
from __future__ import annotations

import inspect
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MODEL = str(ROOT / "models" / "slider_crank_clearance_a.mbs")


@pytest.mark.parametrize("argv, expected", [
    (["check", "m.mbs"], ("m.mbs", [])),
    (["check", "m.mbs", "--set", "speed=1rpm", "-s", "law=hertz", "--set=c=1mm"],
     ("m.mbs", ["speed=1rpm", "law=hertz", "c=1mm"])),
    (["check"], None),
    (["check", "m.mbs", "--help"], None),
    (["check", "m.mbs", "n.mbs"], None),
    (["check", "m.mbs", "--set"], None),
    (["check", "-sx=1", "m.mbs"], None),
    (["run", "m.mbs"], None),
    ([], None),
])
def test_only_a_plain_check_bypasses_typer(argv, expected):
    from planar_mbs.cli.entry import plain_check

    assert plain_check(argv) == expected


def _run(module: str, argv: list[str]):
    """`mbs ARGV` through `module`'s main; the last line of stderr says whether typer was loaded
    (also when the process ends through os._exit)."""
    code = ("import os, sys\n_exit = os._exit\n"
            "def mark():\n    print('TYPER' if 'typer' in sys.modules else 'NO TYPER', file=sys.stderr, flush=True)\n"
            "os._exit = lambda c: (mark(), _exit(c))\n"
            f"sys.argv = {['mbs', *argv]!r}\nfrom {module} import main\n"
            "try:\n    main()\nexcept SystemExit as e:\n    mark()\n    sys.exit(e.code)\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT)


@pytest.mark.parametrize("argv", [["check", MODEL], ["check", MODEL, "--set", "speed=2500rpm"],
                                  ["check", MODEL, "--set", "speed=3 m"], ["check", MODEL, "--set", "speed"]])
def test_fast_check_prints_and_exits_as_the_typer_command(argv):
    fast, typer_app = _run("planar_mbs.cli.entry", argv), _run("planar_mbs.cli.app", argv)
    assert fast.stderr.endswith("NO TYPER\n") and typer_app.stderr.endswith("TYPER\n")
    assert (fast.returncode, fast.stdout) == (typer_app.returncode, typer_app.stdout)
    assert fast.stderr.replace("NO TYPER\n", "") == typer_app.stderr.replace("TYPER\n", "")


def test_sweep_workers_start_with_the_kernels_loaded():
    from planar_mbs.sweep.scan import default_executor
    from planar_mbs.sweep.server import kernels_loaded

    with default_executor(1) as ex:
        assert ex.submit(kernels_loaded).result(timeout=600)


def _entry(argv: list[str]):
    """`mbs ARGV` through the executable's entry point, with an exit handler that prints TEARDOWN."""
    code = ("import atexit, sys\natexit.register(lambda: print('TEARDOWN', file=sys.stderr))\n"
            f"sys.argv = {['mbs', *argv]!r}\nfrom planar_mbs.cli.entry import main\nmain()\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT)


def test_run_through_the_executable_skips_teardown_but_keeps_code_output_and_file(tmp_path):
    """After a run the process ends without the interpreter's teardown (exit handlers do not
    run), yet its exit code, its printed summary and its results file are complete."""
    out = tmp_path / "a.h5"
    res = _entry(["run", MODEL, "--t-end", "1ms", "-o", str(out)])
    assert res.returncode == 0, res.stderr
    assert "TEARDOWN" not in res.stderr
    assert "time-loop wall time" in res.stdout
    from planar_mbs.results.hdf5 import read_results

    assert read_results(out).time[-1] == pytest.approx(1e-3)


def test_a_run_prints_its_summary_without_loading_rich(tmp_path):
    """rich (about 20 ms to load and set up) is left to progress bars and errors: a run's summary and
    warnings are plain lines, the same text."""
    argv = ["mbs", "run", MODEL, "--t-end", "1ms", "-o", str(tmp_path / "a.h5")]
    code = ("import os, sys\n_exit = os._exit\n"
            "def ending(c):\n    print('RICH' if 'rich' in sys.modules else 'NO RICH', file=sys.stderr, flush=True)\n"
            "    _exit(c)\n"
            f"os._exit = ending\nsys.argv = {argv!r}\nfrom planar_mbs.cli.entry import main\nmain()\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert res.returncode == 0, res.stderr
    assert "NO RICH" in res.stderr
    assert res.stdout.startswith("finished at t = 0.001 s") and "time-loop wall time" in res.stdout


@pytest.mark.parametrize("argv, code, text", [
    (["check", MODEL], 0, "clearance joints"),
    (["check", MODEL, "--set", "speed=3 m"], 2, "error"),
    (["--help"], 0, "Exit codes"),
    (["run", "--help"], 0, "--until-settled"),
])
def test_a_command_that_only_prints_skips_teardown_and_prints_everything(argv, code, text):
    res = _entry(argv)
    assert res.returncode == code, res.stderr
    assert "TEARDOWN" not in res.stderr
    assert text in (res.stdout if code == 0 else res.stderr)
    assert res.stdout == _run("planar_mbs.cli.app", argv).stdout


def test_a_refused_run_exits_with_its_code_through_the_executable(tmp_path):
    """Refused before the kernels load: exit 2, a message, and the usual teardown."""
    res = _entry(["run", MODEL, "--t-end", "-1ms", "-o", str(tmp_path / "a.h5")])
    assert res.returncode == 2, res.stderr
    assert "Traceback" not in res.stderr and "TEARDOWN" in res.stderr


# ---------------------------------------------------------------- `mbs run` without typer
@pytest.mark.parametrize("argv", [
    ["run", "m.mbs"],
    ["run", "m.mbs", "-q", "-o", "out.h5"],
    ["run", "-o", "out.h5", "m.mbs", "--quiet", "--set", "speed=1rpm", "-s", "law=hertz", "--set=c=1mm"],
    ["run", "m.mbs", "--t-end", "20 ms", "--output-step=1us", "--rtol", "1e-8", "--atol", "1.5e-11",
     "--integrator", "dop853", "--step", "1us", "--force"],
    ["run", "m.mbs", "-n", "3", "--per-rev", "720", "--magnify", "0", "--fps", "600", "--rerun", "r.rrd",
     "--rerun-signals", "full", "--view"],
    ["run", "m.mbs", "--until-settled", "--max-revolutions", "300", "--revolutions=.5"],
    ["run", "m.mbs", "--keep", "slider.vx,crank", "-q"], ["run", "m.mbs", "--keep=slider"],
])
def test_a_plain_run_reads_the_arguments_typer_reads(argv, monkeypatch):
    """What `plain_run` reads is exactly what the typer command hands to `run_model`."""
    from typer.testing import CliRunner

    from planar_mbs.cli import run_command, run_options
    from planar_mbs.cli.app import app

    params = inspect.signature(run_command.run_model).parameters
    seen = []
    monkeypatch.setattr(run_command, "run_model", lambda model, **kw: seen.append(dict(model=model, **kw)) or 0)
    res = CliRunner().invoke(app, argv)
    assert res.exit_code == 0, res.output
    defaults = dict(seen[0])
    fast = run_options.plain_run(argv)
    assert fast is not None
    assert {k: v for k, v in defaults.items() if v is not None and v is not False and k in fast} == fast
    for k, v in defaults.items():  # every option not given is the typer default, which run_model shares
        if k not in fast:
            assert v == params[k].default, k


@pytest.mark.parametrize("argv", [
    ["run"], ["run", "m.mbs", "n.mbs"], ["run", "m.mbs", "--help"], ["run", "--help"],
    ["run", "m.mbs", "-qo", "x.h5"], ["run", "m.mbs", "-ox.h5"], ["run", "m.mbs", "-o"],
    ["run", "m.mbs", "-o", "a.h5", "-o", "b.h5"], ["run", "m.mbs", "-q", "-q"], ["run", "m.mbs", "--quiet=1"],
    ["run", "m.mbs", "--t-end", "-1ms"], ["run", "m.mbs", "--rtol", "1e-6x"], ["run", "m.mbs", "--rtol", "inf"],
    ["run", "m.mbs", "--per-rev", "0"], ["run", "m.mbs", "--per-rev", "1.5"], ["run", "m.mbs", "--magnify", "-1"],
    ["run", "m.mbs", "--max-revolutions", "0"], ["run", "m.mbs", "--unknown", "1"], ["run", "m.mbs", "--"],
    ["run", "m.mbs", "-"], ["run", "m.mbs", "--output", ""], ["check", "m.mbs"], ["sweep", "m.mbs"], [],
])
def test_any_other_run_command_line_goes_to_typer(argv):
    from planar_mbs.cli.run_options import plain_run

    assert plain_run(argv) is None


def test_typer_and_the_plain_reader_read_one_table_of_options():
    """`mbs run`'s options are written once (`run_options.RUN_OPTIONS`): the typer command has exactly
    those options, with their flags, defaults, lowest values and visibility, and `plain_run` reads each."""
    import typer.main

    from planar_mbs.cli.app import app
    from planar_mbs.cli.run_options import RUN_OPTIONS, plain_run

    command = typer.main.get_command(app).commands["run"]
    options = {p.name: p for p in command.params if p.param_type_name == "option"}
    assert set(options) == {o.param for o in RUN_OPTIONS}
    sample = {"flag": [], "list": ["a=1"], "path": ["x.h5"], "str": ["v"], "float": ["1.5"], "int": ["3"]}
    for o in RUN_OPTIONS:
        p = options[o.param]
        assert (set(p.opts) | set(p.secondary_opts), p.default, p.hidden) == (set(o.flags), o.default, o.hidden)
        assert p.min == o.low, o.param
        for flag in o.flags:
            read = plain_run(["run", "m.mbs", flag, *sample[o.kind]])
            assert read is not None and (o.into or o.param) in read, flag


def _exe(argv: list[str], module: str = "planar_mbs.cli.entry"):
    """`mbs ARGV` through `module`'s main; the last line of stderr says whether typer was loaded
    (also when the process ends through os._exit)."""
    code = ("import os, sys\n_exit = os._exit\n"
            "def mark():\n    print('TYPER' if 'typer' in sys.modules or 'pydantic' in sys.modules else 'NO TYPER',"
            " file=sys.stderr, flush=True)\n"
            "os._exit = lambda c: (mark(), _exit(c))\n"
            f"sys.argv = {['mbs', *argv]!r}\nfrom {module} import main\n"
            "try:\n    main()\nexcept SystemExit as e:\n    mark()\n    sys.exit(e.code)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT)
    return res.returncode, re.sub(r"wall time [0-9.]+ s", "wall time T s", res.stdout), res.stderr


@pytest.mark.parametrize("argv", [
    ["run", MODEL, "--t-end", "1ms", "-o", "{tmp}/a.h5"],
    ["run", MODEL, "--t-end", "1ms", "-q", "-o", "{tmp}/a.h5", "--set", "speed=2500rpm"],
    ["run", MODEL, "--t-end", "1ms", "--rtol", "2", "-o", "{tmp}/a.h5"],
    ["run", MODEL, "-n", "1", "--t-end", "1ms", "-o", "{tmp}/a.h5"],
    ["run", MODEL, "--t-end", "1ms", "-o", "{tmp}"],
    ["run", MODEL, "--set", "speed=3 m", "-o", "{tmp}/a.h5"],
    ["run", str(ROOT / "models" / "no_such_model.mbs"), "-o", "{tmp}/a.h5"],
    ["run", MODEL, "--t-end", "1ms", "--integrator", "euler", "-o", "{tmp}/a.h5"],
])
def test_a_plain_run_prints_writes_and_exits_as_the_typer_command(argv, tmp_path):
    (tmp_path / "fast").mkdir()
    (tmp_path / "typer").mkdir()
    fast = _exe([a.format(tmp=tmp_path / "fast") for a in argv])
    slow = _exe([a.format(tmp=tmp_path / "typer") for a in argv], "planar_mbs.cli.app")
    assert fast[2].splitlines()[-1] == "NO TYPER" and slow[2].splitlines()[-1] == "TYPER", (fast[2], slow[2])
    assert fast[0] == slow[0]
    assert fast[1].replace("/fast", "/typer") == slow[1]
    assert fast[2].replace("/fast", "/typer")[:-len("NO TYPER\n")] == slow[2][:-len("TYPER\n")]
    fast_file, slow_file = tmp_path / "fast" / "a.h5", tmp_path / "typer" / "a.h5"
    assert fast_file.exists() == slow_file.exists()


WARM_RUN = f"""import sys, numpy as np, planar_mbs as m
if sys.argv[1] == "refresh":  # what numba does before loading a cached kernel
    from numba.core.registry import cpu_target
    cpu_target.target_context.refresh()
r = m.simulate(m.load_model({MODEL!r}), t_end=2e-3)
np.save(sys.argv[2], np.column_stack([r.time] + [r[s] for s in r.signals]))
print(sorted({{"numba.np.arraymath", "numba.cpython.listobj", "scipy.linalg"}} & set(sys.modules)))
"""


def test_warm_kernels_load_without_numba_s_implementations_and_run_the_same(tmp_path):
    """A cached kernel is loaded without first registering every implementation numba has (among
    them its array functions, which import scipy.linalg to look for a BLAS); a cache miss still
    compiles through numba's compiler, which registers them.  The run is the same to the bit."""
    import numpy as np

    def run(mode):
        res = subprocess.run([sys.executable, "-c", WARM_RUN, mode, str(tmp_path / f"{mode}.npy")],
                             capture_output=True, text=True, timeout=600, cwd=ROOT)
        assert res.returncode == 0, res.stderr
        return res.stdout.splitlines()[-1]

    run("plain")  # compiles the kernels if their cache is cold
    assert run("plain") == "[]"
    assert run("refresh") == "['numba.cpython.listobj', 'numba.np.arraymath', 'scipy.linalg']"
    assert np.array_equal(np.load(tmp_path / "plain.npy"), np.load(tmp_path / "refresh.npy"), equal_nan=True)


def test_the_grammar_is_read_from_the_package_folder_as_importlib_resources_reads_it():
    from importlib import resources

    from planar_mbs.language.parse import _grammar_text

    assert _grammar_text() == resources.files("planar_mbs.language.grammar").joinpath("mbs.lark").read_text(encoding="utf-8")


@pytest.mark.parametrize("flags", [["--open"], ["--view"], ["--open", "--view"], []])
def test_an_old_name_sets_its_new_one(flags):
    """`--view` (the old name of `--open`) reaches `run_model` as ``view_``, alone or with `--open`."""
    from planar_mbs.cli.run_options import merged, plain_run

    read = plain_run(["run", "m.mbs", *flags])
    assert read.get("view_", False) is bool(flags) and "view_old" not in read
    typer_kwargs = {"view_": "--open" in flags, "view_old": "--view" in flags}
    assert merged(typer_kwargs) == {"view_": bool(flags)}
