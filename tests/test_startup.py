"""Start-up paths: `mbs check` without typer, warm kernels without numba's implementations, sweep
workers forked from a preloaded server."""
from __future__ import annotations

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
    code = (f"import sys; sys.argv = {['mbs', *argv]!r}\nfrom {module} import main\n"
            "try:\n    main()\nexcept SystemExit as e:\n    sys.exit(e.code)\n"
            "finally:\n    print('TYPER' if 'typer' in sys.modules else 'NO TYPER', file=sys.stderr)")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT)


@pytest.mark.parametrize("argv", [["check", MODEL], ["check", MODEL, "--set", "speed=2500rpm"],
                                  ["check", MODEL, "--set", "speed=3 m"], ["check", MODEL, "--set", "speed"]])
def test_fast_check_prints_and_exits_as_the_typer_command(argv):
    fast, typer_app = _run("planar_mbs.cli.entry", argv), _run("planar_mbs.cli.app", argv)
    assert fast.stderr.endswith("NO TYPER\n") and typer_app.stderr.endswith("TYPER\n")
    assert (fast.returncode, fast.stdout) == (typer_app.returncode, typer_app.stdout)
    assert fast.stderr.replace("NO TYPER\n", "") == typer_app.stderr.replace("TYPER\n", "")


def test_sweep_workers_start_with_the_kernels_loaded():
    from planar_mbs.sweep import default_executor
    from planar_mbs.sweep_worker import kernels_loaded

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
    from planar_mbs.results import read_results

    assert read_results(out).time[-1] == pytest.approx(1e-3)


def test_a_refused_run_exits_with_its_code_through_the_executable(tmp_path):
    """Refused before the kernels load: exit 2, a message, and the usual teardown."""
    res = _entry(["run", MODEL, "--t-end", "-1ms", "-o", str(tmp_path / "a.h5")])
    assert res.returncode == 2, res.stderr
    assert "Traceback" not in res.stderr and "TEARDOWN" in res.stderr


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
