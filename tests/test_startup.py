"""Start-up paths: `mbs check` without typer, sweep workers forked from a preloaded server."""
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
