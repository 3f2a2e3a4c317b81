"""A run that writes its results to a file keeps none of its rows in memory: the returned
`Results` reads them back from the file, and gives the same numbers as a run kept in memory."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from planar_mbs import load_model, simulate
from planar_mbs.results import FileResults, peak, row_count

ROOT = Path(__file__).resolve().parents[2]


def test_file_results_are_read_back_lazily_and_equal_an_in_memory_run(tmp_path):
    model = load_model(ROOT / "models" / "slider_crank_clearance_a.mbs")
    mem = simulate(model, t_end=0.02)
    res = simulate(model, output=tmp_path / "a.h5", t_end=0.02)
    assert isinstance(res, FileResults) and not isinstance(mem, FileResults)
    assert vars(res).get("_time") is None  # nothing read yet
    assert row_count(res) == len(mem.time) == 2001
    np.testing.assert_array_equal(res.time, mem.time)
    assert sorted(res.signals) == sorted(mem.signals)
    for name in mem.signals:
        np.testing.assert_array_equal(res[name], mem[name])
    err = mem["system.position_error"]
    assert peak(res, "system.position_error") == peak(mem, "system.position_error") == np.max(err)
    assert res.attrs["warnings"] == mem.attrs["warnings"]
