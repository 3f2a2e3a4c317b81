"""No heavy import (h5py, rerun, matplotlib, dask) in an entry point that does not use it;
`mbs --help` does not even load numpy's friends numba, pint or lark; `mbs check`, `mbs plot` and
`mbs analyze` load no numba and no compiled kernels, and compiling a model needs no pint.  Each check runs a
fresh interpreter and reads its sys.modules."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

MODEL = str(Path(__file__).resolve().parents[1] / "models" / "slider_crank_clearance_a.mbs")


def loaded(code: str) -> set[str]:
    res = subprocess.run([sys.executable, "-c", code + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    return {m.split(".")[0] for m in json.loads(res.stdout.strip().splitlines()[-1])}


CLI = "import sys; sys.argv = {argv!r}\nfrom planar_mbs.cli.app import main\ntry:\n    main()\nexcept SystemExit:\n    pass"


@pytest.mark.parametrize("name, code, absent", [
    ("import", "import planar_mbs", {"h5py", "rerun", "matplotlib", "dask", "numba", "pint", "lark", "scipy"}),
    ("help", CLI.format(argv=["mbs", "--help"]), {"h5py", "rerun", "matplotlib", "dask", "numba", "pint", "lark"}),
    ("check", CLI.format(argv=["mbs", "check", MODEL]),
     {"h5py", "rerun", "matplotlib", "dask", "numba", "pint", "scipy"}),
    ("simulate", f"import planar_mbs as m\nm.simulate(m.load_model({MODEL!r}), t_end=1e-4)",
     {"h5py", "rerun", "matplotlib", "dask"}),
])
def test_no_heavy_imports(name, code, absent):
    assert not (loaded(code) & absent), loaded(code) & absent


def test_run_without_rerun_imports_no_viewer_or_plots(tmp_path):
    code = CLI.format(argv=["mbs", "run", MODEL, "-q", "--t-end", "0.1ms", "-o", str(tmp_path / "a.h5")])
    mods = loaded(code)
    assert "h5py" in mods
    assert not (mods & {"rerun", "matplotlib", "dask"}), mods & {"rerun", "matplotlib", "dask"}


def test_plot_and_analyze_load_no_numba_or_kernels(tmp_path):
    out = tmp_path / "a.h5"
    subprocess.run([sys.executable, "-c", CLI.format(argv=["mbs", "run", MODEL, "-q", "--t-end", "0.2ms", "-o", str(out)])],
                   check=True, capture_output=True, timeout=300)
    for argv in (["mbs", "plot", str(out), "-o", str(tmp_path / "plots")], ["mbs", "analyze", str(out)]):
        res = subprocess.run([sys.executable, "-c", CLI.format(argv=argv) + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"],
                             capture_output=True, text=True, timeout=300)
        mods = set(json.loads(res.stdout.strip().splitlines()[-1]))
        assert not {m for m in mods if m.split(".")[0] in ("numba", "pint") or m.startswith("planar_mbs.kernel")}, argv
