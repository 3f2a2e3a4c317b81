"""docs/python_api.md is a notebook: its ```python blocks run in order, in one namespace,
from a folder that holds the shipped models (as a user's checkout does)."""
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "python_api.md"
BLOCK = re.compile(r"^```python[ \t]*\n(.*?)^```", re.S | re.M)


def test_the_page_has_the_promised_parts():
    text = DOC.read_text(encoding="utf-8")
    for call in ("load_model(", "compile_text(", "simulate(", "read_results(", "to_dataframe(", "h5py",
                 "Simulation(", ".step(", ".run_until(", "callback", "set_load("):
        assert call in text, call


def test_python_api_page_runs(tmp_path, capsys):
    pytest.importorskip("pandas")
    (tmp_path / "models").symlink_to(ROOT / "models")
    blocks = BLOCK.findall(DOC.read_text(encoding="utf-8"))
    assert len(blocks) >= 7
    namespace: dict = {}
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        for i, code in enumerate(blocks):
            exec(compile(code, f"{DOC.name} block {i + 1}", "exec"), namespace)
    finally:
        os.chdir(cwd)
    out = capsys.readouterr().out
    assert "did you mean `speed`" in out and "--set" not in out
    # the controller's loop: torque k (target - omega_n) held for dt gives
    # omega_{n+1} = omega_n + k dt / I (target - omega_n), so omega_n = target (1 - (1 - k dt / I)^n)
    assert namespace["omega"] == pytest.approx(10.0 * (1 - (1 - 20.0 * 0.005 / 0.5) ** 100), rel=1e-9)
    # then it coasts: omega stays
    assert namespace["res3"]["wheel.omega"][-1] == pytest.approx(namespace["omega"], rel=1e-9)
    assert namespace["res3"].complete and (tmp_path / "a.h5").exists()
