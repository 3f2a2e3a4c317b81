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
    with h5py.File(path) as f:  # one dataset per entity, a field per quantity (docs/signals.md)
        assert set(f["signals"]) == {"slider", "A", "system"}
        np.testing.assert_allclose(f["signals/A"]["force"][:10], np.hypot(rows[:, 1], rows[:, 2]))
        assert list(f["signals/A"].attrs["units"]) == ["N"]


def test_plain_h5py_and_pandas_read_an_entity_in_one_line(tmp_path):
    import pytest

    pd = pytest.importorskip("pandas")
    table = [Signal("slider", q, "m", (i,)) for i, q in enumerate(("x", "y", "vx"))]
    path = tmp_path / "run.h5"
    w = ResultsWriter(path, table, {})
    rows = np.arange(12.0).reshape(4, 3)
    w.append(np.arange(4.0), rows)
    w.close()
    with h5py.File(path) as f:
        np.testing.assert_array_equal(f["signals/slider"]["vx"], rows[:, 2])  # as in docs/signals.md
        df = pd.DataFrame(f["signals/slider"][()])
    assert list(df.columns) == ["x", "y", "vx"]
    np.testing.assert_array_equal(df.to_numpy(), rows)


def test_the_number_of_datasets_grows_with_entities_not_signals(tmp_path):
    table = [Signal(f"b{e}", f"q{k}", "m", (9 * e + k,)) for e in range(4) for k in range(9)]
    path = tmp_path / "run.h5"
    w = ResultsWriter(path, table, {})
    w.append(np.arange(3.0), np.ones((3, 36)))
    w.close()
    with h5py.File(path) as f:
        objects = []
        f.visit(objects.append)
    assert sorted(objects) == ["signals", "signals/b0", "signals/b1", "signals/b2", "signals/b3", "time"]


def test_files_of_the_earlier_layout_are_still_read(tmp_path):
    """A dataset per signal (/signals/<entity>/<quantity>, attribute `unit`), as files written before."""
    path = tmp_path / "old.h5"
    with h5py.File(path, "w") as f:
        f["time"] = np.arange(3.0)
        f["signals/slider/x"] = np.array([1.0, 2.0, 3.0])
        f["signals/slider/x"].attrs["unit"] = "m"
    res = read_results(path)
    np.testing.assert_array_equal(res["slider.x"], [1.0, 2.0, 3.0])
    assert res.units["slider.x"] == "m"


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
