"""HDF5 results: chunked writing, layout of docs/signals.md, read back."""
import h5py
import numpy as np

from planar_mbs.results.hdf5 import ResultsWriter, read_results
from planar_mbs.results.signals import Signal

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
    """A run that dies mid-way leaves the earlier file at its name untouched, and what it computed
    in a readable part file beside it, marked incomplete."""
    from planar_mbs.results.hdf5 import ResultsFileError, part_beside

    path = tmp_path / "partial.h5"
    w = ResultsWriter(path, TABLE, {})
    w.append(np.array([0.0, 0.1]), np.ones((2, 3)))
    w.file.close()  # as if the process stopped without `close(...)`:
    w.lock.release()  # its lock dies with it
    res = read_results(part_beside(path))
    assert len(res.time) == 2 and not res.complete
    import pytest

    with pytest.raises(ResultsFileError, match=r"\.partial\.h5\.part"):  # the name says where the rows are
        read_results(path)


def test_a_file_another_process_writes_is_refused_by_name(tmp_path, monkeypatch):
    """Reading a results file while another process writes it (holds its `WriteLock`): a clear error
    that says so, with HDF5's own locking on or off (it used to be reported as a damaged file, or,
    with HDF5's locking off, read halfway through a write); once the writer is gone, it reads."""
    import subprocess
    import sys

    import pytest

    from planar_mbs.results.hdf5 import ResultsFileError

    path = tmp_path / "r.h5"
    w = ResultsWriter(path, TABLE, {})
    w.append(np.array([0.0, 0.1]), np.ones((2, 3)))
    w.close()
    writer = subprocess.Popen([sys.executable, "-c", "import pathlib, sys\nfrom planar_mbs.results.hdf5 import WriteLock\n"
                               f"lock = WriteLock(pathlib.Path({str(path)!r}))\nprint('writing', flush=True)\n"
                               "sys.stdin.read()"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert writer.stdout.readline().strip() == "writing"
        for hdf5_locking in ("TRUE", "FALSE"):
            monkeypatch.setenv("HDF5_USE_FILE_LOCKING", hdf5_locking)
            with pytest.raises(ResultsFileError, match="is being written by another process") as err:
                read_results(path)
            assert "damaged" not in str(err.value) and err.value.exit_code == 2
    finally:
        writer.communicate("", timeout=30)
    assert len(read_results(path).time) == 2


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


def test_written_records_equal_each_signals_own_extract(tmp_path):
    """The writer packs each entity itself (a gather of its columns, magnitudes and sums computed into
    theirs): every stored value equals `Signal.extract` of the same rows, bit for bit, for columns in
    any order, combined signals mixed with plain ones, and rows that are a non-contiguous selection."""
    rng = np.random.default_rng(3)
    table = [Signal("a", "x", "m", (4,)), Signal("a", "y", "m", (0,)), Signal("a", "z", "m", (7,)),
             Signal("b", "fx", "N", (2,)), Signal("b", "force", "N", (2, 5), "hypot"), Signal("b", "fy", "N", (5,)),
             Signal("c", "sum", "J", (1, 3, 6), "sum"), Signal("d", "only", "s", (6,))]
    full = rng.standard_normal((5000, 10))
    rows = full[:, [0, 1, 2, 3, 4, 5, 6, 7]]  # a fancy-indexed copy, as simulate's --signals selection makes
    strided = full[::2, :8]  # and a strided view
    for block in (rows, strided):
        path = tmp_path / "rec.h5"
        w = ResultsWriter(path, table, {})
        w.append(np.arange(len(block) - 7.0), block[:-7])
        w.append(np.arange(7.0), block[-7:])
        w.close({"complete": True})
        res = read_results(path)
        for s in table:
            assert res[s.name].tobytes() == s.extract(block).tobytes(), s.name


def test_appends_across_chunk_boundaries_read_back_bit_for_bit(tmp_path):
    """Whole chunks go straight to the file, the last one of an append padded to a whole chunk, and
    the next append writes the rest of that chunk over the padding: blocks of any size, starting
    anywhere in a chunk, read back as the rows written (NaN and infinities included), the file
    readable after each append as a run that stopped there would leave it."""
    chunk = ResultsWriter.CHUNK
    rng = np.random.default_rng(7)
    sizes = [1, chunk - 1, 5, 2 * chunk + 3, chunk, chunk - 5, 7]
    rows = rng.standard_normal((sum(sizes), 3)) * 10.0 ** rng.integers(-300, 300, (sum(sizes), 1))
    rows[::97, 0], rows[5::89, 1], rows[7::83, 2], rows[3::101, 0] = np.nan, np.inf, np.inf, -np.inf
    t = np.cumsum(rng.random(len(rows)))
    path = tmp_path / "chunks.h5"
    w = ResultsWriter(path, TABLE, {})
    end = 0
    for n in sizes:
        w.append(t[end:end + n], rows[end:end + n])
        end += n
        with h5py.File(w.path, "r", locking=False) as f:  # the part file, moved into place by close
            assert f["time"].shape == (end,) and f["time"][()].tobytes() == t[:end].tobytes()
            assert f["signals/slider"]["x"].tobytes() == rows[:end, 0].tobytes()
    w.close({"complete": True})
    res = read_results(path)
    assert res.time.tobytes() == t.tobytes()
    for s in TABLE:
        assert res[s.name].tobytes() == s.extract(rows).tobytes(), s.name


def test_a_run_streamed_to_a_file_equals_the_run_in_memory(tmp_path, monkeypatch):
    """The kernel writes rows straight into the block that goes to the file, which is written in
    whole chunks (and whatever a time-forced write leaves): every signal of the file equals the run
    kept in memory bit for bit, with the default blocks and with tiny blocks written every call."""
    from pathlib import Path

    import planar_mbs as mbs
    from planar_mbs.run import simulation

    model = mbs.load_model(Path(__file__).resolve().parents[1] / "models" / "slider_crank_clearance_a.mbs")
    ref = mbs.simulate(model, t_end=0.01)
    assert len(ref.time) > 1000
    for flush_bytes, seconds in ((simulation.FLUSH_BYTES, simulation.FLUSH_SECONDS), (1, 0.0)):
        monkeypatch.setattr(simulation, "FLUSH_BYTES", flush_bytes)
        monkeypatch.setattr(simulation, "FLUSH_SECONDS", seconds)
        out = tmp_path / f"run{flush_bytes}.h5"
        mbs.simulate(model, output=out, t_end=0.01)
        res = read_results(out)
        assert res.time.tobytes() == ref.time.tobytes()
        assert sorted(res.signals) == sorted(ref.signals)
        for name in ref.signals:
            assert res[name].tobytes() == ref[name].tobytes(), name
    kept = mbs.simulate(model, output=tmp_path / "kept.h5", t_end=0.01, signals=["slider", "A.contact_force"])
    res = read_results(tmp_path / "kept.h5")
    assert sorted(res.signals) == sorted(kept.signals) and "A.contact_force" in res.signals
    for name in res.signals:
        assert res[name].tobytes() == ref[name].tobytes(), name
