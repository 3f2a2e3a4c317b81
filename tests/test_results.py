"""HDF5 results: chunked writing, layout of docs/signals.md, read back."""
import h5py
import numpy as np

from planar_mbs.results import ResultsWriter, read_results
from planar_mbs.signals import Signal

TABLE = [
    Signal("slider", "x", "m", (0,)),
    Signal("A", "force", "N", (1, 2), "hypot"),
    Signal("system", "total_energy", "J", (1, 2), "sum"),
]


def test_chunks_append_and_read_back(tmp_path):
    path = tmp_path / "run.h5"
    w = ResultsWriter(path, TABLE, {"model_source": "body b {}", "parameters": {"speed": "5000 rpm"}})
    rows = np.arange(30.0).reshape(10, 3)
    w.append(np.linspace(0, 0.9, 10), rows)
    w.append(np.linspace(1.0, 1.4, 5), rows[:5] + 100)
    w.close({"complete": True, "n_steps": 42, "wall_time": 0.5})
    res = read_results(path)
    assert res.time.shape == (15,)
    np.testing.assert_array_equal(res["slider.x"][:10], rows[:, 0])
    np.testing.assert_allclose(res["A.force"][:10], np.hypot(rows[:, 1], rows[:, 2]))
    np.testing.assert_array_equal(res["system.total_energy"][10:], rows[:5, 1] + rows[:5, 2] + 200)
    assert res.units["slider.x"] == "m"
    assert res.attrs["parameters"] == {"speed": "5000 rpm"}
    assert res.attrs["n_steps"] == 42 and res.complete
    with h5py.File(path) as f:
        assert set(f["signals"]) == {"slider", "A", "system"}
        assert f["signals/A/force"].attrs["unit"] == "N"


def test_file_readable_while_unfinished(tmp_path):
    """A run that dies mid-way leaves a readable file marked incomplete."""
    path = tmp_path / "partial.h5"
    w = ResultsWriter(path, TABLE, {})
    w.append(np.array([0.0, 0.1]), np.ones((2, 3)))
    w.file.close()  # as if the process stopped without `close(...)`:
    w.lock.release()  # its lock dies with it
    res = read_results(path)
    assert len(res.time) == 2 and not res.complete


def test_unknown_signal_suggests(tmp_path):
    path = tmp_path / "r.h5"
    w = ResultsWriter(path, TABLE, {})
    w.close()
    res = read_results(path)
    try:
        res["slider.xx"]
    except KeyError as err:
        assert "slider.x" in str(err)
    else:
        raise AssertionError("no KeyError")
