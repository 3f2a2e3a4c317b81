"""A run that writes its results to a file keeps none of its rows in memory: the returned
`Results` reads them back from the file, and gives the same numbers as a run kept in memory."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from planar_mbs import load_model, simulate
from planar_mbs.results.hdf5 import FileResults, ResultsFileError, peak, row_count

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


def _crafted_time_only(path: Path) -> None:
    import h5py

    with h5py.File(path, "w") as f:
        f.create_dataset("time", data=np.zeros(3))  # no signals group


def _truncated_declaration(path: Path) -> None:
    import h5py

    with h5py.File(path, "w") as f:
        f.create_dataset("time", shape=(10**12,), dtype="f8", chunks=(4096,), maxshape=(None,))
        f.create_group("signals")


@pytest.mark.parametrize("replace", [
    lambda p: p.write_bytes(b"not hdf5 at all"),
    lambda p: p.write_bytes(b""),
    _crafted_time_only,
    _truncated_declaration,
    lambda p: os.mkfifo(p),
], ids=["text", "empty", "no signals", "declared 10^12 rows", "fifo"])
def test_a_results_file_replaced_after_the_run_is_refused_not_read(tmp_path, replace):
    """`FileResults` reads the file again at every access: whatever took its place goes through
    the same checks as any results file a command reads (a ResultsFileError, no hang)."""
    model = load_model(ROOT / "models" / "slider_crank.mbs")
    out = tmp_path / "a.h5"
    res = simulate(model, output=out, t_end=0.01)
    out.unlink()
    replace(out)
    for read in (lambda: res.time, lambda: res["slider.x"], lambda: row_count(res),
                 lambda: peak(res, "slider.x")):
        with pytest.raises(ResultsFileError):
            read()


def test_asking_whether_a_signal_exists_reads_nothing(tmp_path):
    """`name in res.signals` (the summary of `mbs run` asks it) must not read the signal: a
    10^7-row run would read 80 MB for a yes.  Shown with the file gone: the answer needs none of it."""
    res = simulate(load_model(ROOT / "models" / "slider_crank.mbs"), output=tmp_path / "a.h5", t_end=0.01)
    (tmp_path / "a.h5").unlink()
    assert "system.position_error" in res.signals and "no.such" not in res.signals
    assert len(res.signals) > 0 and "slider.x" in list(res.signals)
