"""Hostile table files: a UTF-8 BOM (Excel's "CSV UTF-8"), a typo on the first line, a FIFO or a
device in place of the CSV, a CSV edited or removed while a sweep uses it or after."""
from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np
import pytest

import planar_mbs as api
from advhelp import assert_clean, fifo, mbs
from planar_mbs.errors import ModelError

MODEL = """\
param F0 = 1
body mass { mass = 2 kg  inertia = 0.5 kg*m^2 }
force push = expression(mass, fx = F0 * table("f.csv", x = t, x_unit = "ms", y_unit = "N"))
simulate { t_end = 4 ms  output_step = 1 ms }
"""


def _model(folder: Path, csv: bytes | str | None = None) -> Path:
    if csv is not None:
        (folder / "f.csv").write_bytes(csv if isinstance(csv, bytes) else csv.encode())
    path = folder / "m.mbs"
    path.write_text(MODEL)
    return path


def _knots(folder: Path) -> list[tuple[float, float]]:
    seg = api.load_model(folder / "m.mbs").kernel.table_seg
    return [(round(r[0], 9), round(r[1], 9)) for r in seg]


def test_a_bom_does_not_drop_the_first_row(tmp_path):
    _model(tmp_path, "0, 5\n1, 7\n2, 9\n".encode("utf-8-sig"))
    assert _knots(tmp_path) == [(0.0, 5.0), (0.001, 7.0), (0.002, 9.0)]


def test_a_bom_before_a_header(tmp_path):
    _model(tmp_path, "time, force\n0, 5\n1, 7\n".encode("utf-8-sig"))
    assert _knots(tmp_path) == [(0.0, 5.0), (0.001, 7.0)]


@pytest.mark.parametrize("first", ["0, 5O", "O, 5", "0,, x5"])
def test_a_typo_in_the_first_row_is_not_taken_for_a_header(tmp_path, first):
    _model(tmp_path, f"{first}\n1, 7\n2, 9\n")
    out = mbs("check", tmp_path / "m.mbs", cwd=tmp_path)
    assert_clean(out, 2, "f.csv:1:1", "is not a number")


@pytest.mark.parametrize("command", ["check", "run"])
def test_a_fifo_table_is_refused_without_hanging(tmp_path, command):
    _model(tmp_path)
    with fifo(tmp_path / "f.csv"):
        out = mbs(command, tmp_path / "m.mbs", *(["-q", "-o", tmp_path / "r.h5"] if command == "run" else []),
                  cwd=tmp_path, timeout=30)
    assert_clean(out, 2, "m.mbs:3:", "f.csv", "not a regular file", bound=5)


def test_a_device_table_is_refused(tmp_path):
    _model(tmp_path)
    (tmp_path / "f.csv").symlink_to("/dev/zero")
    with pytest.raises(ModelError, match="not a regular file") as info:
        api.load_model(tmp_path / "m.mbs")
    assert info.value.line == 3


# ---------------------------------------------------------------- the table is part of the sweep's model
SWEEP = ["-P", "F0=1,2", "--t-end", "4ms", "-j", "1", "-q", "--no-section", "--keep", "all"]


def test_sweep_stores_its_table_and_replays_without_it(tmp_path):
    model = _model(tmp_path, "0, 5\n1, 7\n2, 9\n")
    assert_clean(mbs("sweep", model, *SWEEP, "-o", tmp_path / "s.h5", cwd=tmp_path, timeout=120), 0)
    with h5py.File(tmp_path / "s.h5", "r") as f:
        stored = f["cases/1/signals/mass"]["vx"][()]
    (tmp_path / "f.csv").write_text("0, 500\n1, 700\n2, 900\n")  # another table in the folder
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out = mbs("sweep-replay", tmp_path / "s.h5", "1", "-o", elsewhere / "r.h5", cwd=elsewhere, timeout=120)
    assert_clean(out, 0)
    with h5py.File(elsewhere / "r.h5", "r") as f:
        assert (f["signals/mass"]["vx"][()] == stored).all()


def test_resume_after_the_table_changed_is_refused(tmp_path):
    model = _model(tmp_path, "0, 5\n1, 7\n2, 9\n")
    out = tmp_path / "s.h5"
    assert_clean(mbs("sweep", model, "-P", "F0=1", *SWEEP[2:], "-o", out, cwd=tmp_path, timeout=120), 0)
    (tmp_path / "f.csv").write_text("0, 5\n1, 8\n2, 9\n")
    res = mbs("sweep", model, *SWEEP, "-o", out, cwd=tmp_path, timeout=120)
    assert_clean(res, 2, "different model source")


def test_merge_of_sweeps_with_different_tables_is_refused(tmp_path):
    model = _model(tmp_path, "0, 5\n1, 7\n2, 9\n")
    assert mbs("sweep", model, "-P", "F0=1", *SWEEP[2:], "-o", tmp_path / "a.h5", cwd=tmp_path, timeout=120).code == 0
    (tmp_path / "f.csv").write_text("0, 5\n1, 8\n2, 9\n")
    assert mbs("sweep", model, "-P", "F0=2", *SWEEP[2:], "-o", tmp_path / "b.h5", cwd=tmp_path, timeout=120).code == 0
    res = mbs("sweep-merge", tmp_path / "a.h5", tmp_path / "b.h5", "-o", tmp_path / "all.h5", cwd=tmp_path)
    assert_clean(res, 2, "different model source")
    assert not os.path.exists(tmp_path / "all.h5")


def test_a_runs_results_hold_its_tables_so_the_model_rebuilds_without_the_file(tmp_path):
    """A table is part of the model: a run stores the bytes it read in its results, and the model is
    rebuilt from them (as `mbs view` does) after the CSV is gone, with the same table."""
    import planar_mbs as mbs
    from planar_mbs.outputs.rerun_log import model_from_results

    (tmp_path / "push.csv").write_text("t,f\n0,0\n0.5,2\n1,0\n", encoding="utf-8")
    model_file = tmp_path / "m.mbs"
    model_file.write_text("""body m { mass = 1 kg  inertia = 1 kg*m^2  position = (0, 0) }
joint slide = translational(ground (0, 0), m, axis = (1, 0))
force push = expression(m, fx = table("push.csv", x = t, x_unit = "s", y_unit = "N"))
simulate { t_end = 10 ms  output_step = 1 ms }
""", encoding="utf-8")
    model = mbs.load_model(model_file)
    mbs.simulate(model, output=tmp_path / "r.h5")
    (tmp_path / "push.csv").unlink()
    rebuilt = model_from_results(mbs.read_results(tmp_path / "r.h5"))
    assert np.array_equal(rebuilt.kernel.table_seg, model.kernel.table_seg) and len(model.kernel.table_seg)
