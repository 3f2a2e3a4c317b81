"""The lowest versions pyproject.toml declares are true: a fresh virtual environment with exactly
those versions of the core dependencies installs the project and runs the slider-crank.  CI runs
it (slow-marked: it needs a package index and a minute of numba compilation)."""
from __future__ import annotations

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def lowest_versions() -> list[str]:
    """`name==floor` for every core dependency of pyproject.toml (each must declare a floor)."""
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    pins = []
    for dep in deps:
        match = re.fullmatch(r"([A-Za-z0-9_.\-\[\]]+)\s*>=\s*([0-9][0-9a-z.]*)\s*(,\s*<\s*[0-9][0-9a-z.]*)?", dep)
        assert match, f"{dep!r}: a dependency without a floor and a ceiling"
        pins.append(f"{match[1]}=={match[2]}")
    return pins


def test_every_core_dependency_declares_a_floor_and_a_ceiling():
    pins = lowest_versions()
    assert {p.split("==")[0] for p in pins} >= {"numpy", "numba", "scipy", "h5py", "rerun-sdk"}


# the slider of the ideal slider-crank (crank 0.05 m, rod 0.12 m) against its closed form, read with
# the environment's own numpy and h5py
CHECK = """
import sys, numpy as np, planar_mbs as mbs
res = mbs.read_results(sys.argv[1])
phi, x = np.asarray(res["crank.phi"]), np.asarray(res["slider.x"])
closed = 0.05 * np.cos(phi) + np.sqrt(0.12 ** 2 - (0.05 * np.sin(phi)) ** 2)
print(len(x), float(np.max(np.abs(x - closed))))
"""


@pytest.mark.slow
def test_lowest_declared_versions_install_and_run_the_slider_crank(tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    py = venv / "bin" / "python"
    install = subprocess.run([str(py), "-m", "pip", "install", "-q", str(ROOT), *lowest_versions()],
                             capture_output=True, text=True, timeout=1800)
    assert install.returncode == 0, install.stderr[-3000:]
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    env.pop("PYTHONPATH", None)
    mbs = str(venv / "bin" / "mbs")
    # 5000 rpm in a unit outside the toolkit's own table: pint reads it
    run = subprocess.run([mbs, "run", str(ROOT / "models" / "slider_crank.mbs"), "--t-end", "3ms",
                          "--set", "speed=1800 arcminute/ms", "-o", str(tmp_path / "a.h5")],
                         capture_output=True, text=True, timeout=1800, env=env, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "note:" not in run.stderr  # the fast path: the floor of numba is one it was checked on
    plot = subprocess.run([mbs, "plot", str(tmp_path / "a.h5"), "slider.x", "-o", str(tmp_path / "plots")],
                          capture_output=True, text=True, timeout=600, env=env, cwd=tmp_path)  # typer, matplotlib
    assert plot.returncode == 0 and any((tmp_path / "plots").iterdir()), plot.stderr[-3000:]
    check = subprocess.run([str(py), "-c", CHECK, str(tmp_path / "a.h5")], capture_output=True, text=True,
                           timeout=600, env=env, cwd=tmp_path)
    assert check.returncode == 0, check.stderr[-3000:]
    rows, error = check.stdout.split()
    assert int(rows) > 250 and float(error) < 1e-9  # 3 ms at 10 us per row: 5000 rpm it was
