"""The scan file of a sweep: small by default, any case replayable, a snapshot of the model, parameter
names free of the table's columns, merges, and the journal that keeps finished cases through a kill."""
from __future__ import annotations

import json
import re
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from planar_mbs import read_results
from planar_mbs.results.hdf5 import ResultsFileError
from planar_mbs.results.analysis import classify
from planar_mbs.results.section import poincare_section
from planar_mbs.sweep.scan import (SweepError, case_summary, merge_sweeps, parse_param, read_case_table, replay_case,
                              run_sweep, sweep_sections)
from planar_mbs.sweep.store import journal_folder, journal_key, sign_case, signal_summary

ROOT = Path(__file__).resolve().parents[1]
IDEAL = ROOT / "models" / "slider_crank.mbs"
CLEARANCE = ROOT / "models" / "slider_crank_clearance_a.mbs"
OPTS = dict(revolutions=12, per_rev=36, section={}, jobs=1)


def _split_model(folder: Path, slider_mass: str = "0.14 kg") -> Path:
    """The ideal slider-crank with its slider in an included file, included in the middle of a line."""
    text = IDEAL.read_text()
    slider = re.search(r"body slider \{.*?\}\n", text, re.S).group(0)
    (folder / "parts.mbs").write_text(slider.replace("mass = 0.14 kg", f"mass = {slider_mass}"))
    main = folder / "m.mbs"
    main.write_text(text.replace(slider, 'param unused = 1  include "parts.mbs"\n'))
    return main


def _summaries(path) -> dict:
    return {r["key"]: case_summary(path, r["index"]) for r in read_case_table(path)}


# ---------------------------------------------------------------- small by default, replayable
def test_a_replayed_case_equals_the_stored_section_and_summary_to_the_bit(tmp_path):
    """A scan keeps no signal by default, only sections, verdicts and summary statistics; a case run
    again from what the file records (`replay_case`, `mbs sweep replay`) gives the same section and
    statistics, recomputed from the replayed file, to the bit, and the same rows as `mbs run`."""
    out = tmp_path / "s.h5"
    speeds = [parse_param("speed=2000rpm,5000rpm")]
    run_sweep(CLEARANCE, speeds, out, keep=(), **OPTS)
    with h5py.File(out, "r") as f:
        assert "signals" not in f["cases/1"] and len(f["cases/1/time"]) == 0  # small
        assert "summary" in f["cases/1"] and "poincare" in f["cases/1"]
    stored = {row["index"]: (sec, verdict) for row, sec, verdict in sweep_sections(out)}
    from planar_mbs.cli.app import app

    for k in (0, 1):
        replay = tmp_path / f"case{k}.h5"
        r = CliRunner().invoke(app, ["sweep-replay", str(out), str(k), "-o", str(replay)])
        assert r.exit_code == 0, r.output
        res = read_results(replay)
        assert signal_summary(res) == case_summary(out, k)  # floats compared exactly
        sec = poincare_section(res, None, transient=1.0)
        sec0, verdict0 = stored[k]
        assert sec.names == sec0.names and len(sec) == len(sec0) > 5
        for name in sec.names:
            assert sec.points[name].tobytes() == sec0.points[name].tobytes()
        assert json.dumps(classify(sec).as_dict()) == json.dumps(verdict0.as_dict())
    # the same rows as `mbs run` with the same settings
    run = tmp_path / "run.h5"
    r = CliRunner().invoke(app, ["run", str(CLEARANCE), "--set", "speed=5000rpm", "-n", "12", "--per-rev", "36",
                                 "-o", str(run)])
    assert r.exit_code == 0, r.output
    a, b = read_results(run), read_results(tmp_path / "case1.h5")
    assert a.time.tobytes() == b.time.tobytes()
    for name in a.signals:
        assert a[name].tobytes() == b[name].tobytes(), name
    with pytest.raises(SweepError, match="no case 7"):
        replay_case(out, 7, tmp_path / "x.h5")
    # `mbs analyze` of a case without signals prints its stored verdict
    r = CliRunner().invoke(app, ["analyze", f"{out}:/cases/1"])
    assert r.exit_code == 0 and "keeps no signals" in r.output, r.output
    assert stored[1][1].label() in r.output and "11 points of slider.vx, slider.ax" in r.output, r.output
    # `mbs plot` and `read_results` of such a case say what it is and how to get its signals
    r = CliRunner().invoke(app, ["plot", f"{out}:/cases/1", "-o", str(tmp_path / "plots")])
    assert r.exit_code == 2 and "kept no signals" in r.output and f"mbs sweep replay {out} 1 -o" in r.output, r.output
    with pytest.raises(ResultsFileError, match="kept no signals"):
        read_results(f"{out}:/cases/1")


def test_mbs_sweep_replay_and_merge_are_subcommands(tmp_path, monkeypatch):
    from planar_mbs.cli.sweep_commands import route

    argv = ["mbs", "sweep", "replay", "s.h5", "3", "-o", "c.h5"]
    route(argv)
    assert argv == ["mbs", "sweep-replay", "s.h5", "3", "-o", "c.h5"]
    argv = ["mbs", "sweep", "merge", "a.h5", "b.h5", "-o", "c.h5"]
    route(argv)
    assert argv[1] == "sweep-merge"
    monkeypatch.chdir(tmp_path)
    (tmp_path / "replay").write_text("a model file named replay")
    argv = ["mbs", "sweep", "replay", "-P", "speed=1rpm", "-o", "x.h5"]
    route(argv)
    assert argv[1:3] == ["sweep", "replay"]
    from planar_mbs.cli.app import app

    for name in ("replay", "merge"):  # their usage names them as typed, not by the hidden command
        r = CliRunner().invoke(app, [f"sweep-{name}", "--help"], prog_name="mbs")
        assert r.exit_code == 0 and f"Usage: mbs sweep {name} " in r.output, r.output


def test_keep_all_stores_every_signal(tmp_path):
    out = tmp_path / "s.h5"
    run_sweep(IDEAL, [parse_param("speed=600rpm")], out, keep=None, **OPTS)
    res = read_results(f"{out}:/cases/0")
    assert len(res.time) == 12 * 36 + 1 and "slider.vx" in res.signals
    # the summary is the extrema and RMS of the stored signal itself
    lo, hi, rms = case_summary(out, 0)["slider.vx"]
    x = res["slider.vx"]
    assert (lo, hi) == (x.min(), x.max()) and rms == pytest.approx(np.sqrt(np.mean(x * x)), rel=1e-15)


# ---------------------------------------------------------------- the model's snapshot
def test_editing_the_model_or_an_include_during_a_sweep_does_not_mix_cases(tmp_path):
    """Every case compiles the text read once at the start: an edit of the model file or of a file
    it includes (in the middle of a line) after the first case changes no later case."""
    speeds = [parse_param("speed=600rpm,900rpm,1200rpm")]
    ref_folder, live_folder, edited_folder = (tmp_path / n for n in ("ref", "live", "edited"))
    for folder in (ref_folder, live_folder, edited_folder):
        folder.mkdir()
    run_sweep(_split_model(ref_folder), speeds, ref_folder / "s.h5", **OPTS)
    run_sweep(_split_model(edited_folder, "0.5 kg"), speeds, edited_folder / "s.h5", **OPTS)
    model = _split_model(live_folder)

    def edit(done, total, outcome):
        if done == 1:
            (live_folder / "parts.mbs").write_text((edited_folder / "parts.mbs").read_text())
            model.write_text(model.read_text().replace("speed = 5000 rpm", "speed = 100 rpm"))

    run_sweep(model, speeds, live_folder / "s.h5", progress=edit, **OPTS)
    ref, live, edited = (_summaries(f / "s.h5") for f in (ref_folder, live_folder, edited_folder))
    assert live == ref
    assert all(edited[k]["crank_speed.torque"] != ref[k]["crank_speed.torque"] for k in ref)  # the edit matters
    with h5py.File(live_folder / "s.h5", "r") as f:
        includes = json.loads(f.attrs["model_includes"])
        assert list(includes.values()) == [(ref_folder / "parts.mbs").read_text()]


def test_an_include_in_the_middle_of_a_line_edited_between_runs_is_caught_on_resume(tmp_path):
    model = _split_model(tmp_path)
    speeds = [parse_param("speed=600rpm")]
    run_sweep(model, speeds, tmp_path / "s.h5", **OPTS)
    (tmp_path / "parts.mbs").write_text((tmp_path / "parts.mbs").read_text().replace("0.14 kg", "0.15 kg"))
    with pytest.raises(SweepError, match="different model source"):
        run_sweep(model, [parse_param("speed=600rpm,900rpm")], tmp_path / "s.h5", **OPTS)


# ---------------------------------------------------------------- parameter names
COLUMN_NAMES = ["K", "period", "status", "key", "index", "message", "verdict", "lyapunov", "dimension",
                "wall_time", "X_si", "X", "values", "params", "params_si"]


def test_parameters_named_like_the_table_s_columns(tmp_path):
    """A swept parameter may be called K (a contact stiffness), status, index, ... or X_si beside X:
    the table keeps every column and every parameter."""
    model = tmp_path / "m.mbs"
    model.write_text(IDEAL.read_text() + "".join(f"param {n} = 1\n" for n in COLUMN_NAMES))
    axes = [parse_param(f"{n}={'1,2' if n == 'K' else '3'}") for n in COLUMN_NAMES]
    run_sweep(model, axes, tmp_path / "s.h5", revolutions=3, per_rev=12, section=None, jobs=1)
    rows = read_case_table(tmp_path / "s.h5")
    assert [r["index"] for r in rows] == [0, 1]
    assert [r["status"] for r in rows] == ["finished", "finished"]
    assert [r["values"]["K"] for r in rows] == ["1", "2"]
    assert all(r["values"][n] == "3" for r in rows for n in COLUMN_NAMES if n != "K")
    assert all(np.isnan(r["K"]) for r in rows)  # no section: no 0-1 test


# ---------------------------------------------------------------- merge
def _by_key(path) -> dict:
    """Per case key: its table row (index and wall time left out) and every dataset of its group."""
    out = {}
    rows = read_case_table(path)
    with h5py.File(path, "r") as f:
        for r in rows:
            data = {}
            f[f"cases/{r['index']}"].visititems(
                lambda n, o: data.__setitem__(n, o[()].tobytes() if o.dtype.kind != "O" else list(o[()]))
                if isinstance(o, h5py.Dataset) else None)
            row = {k: v for k, v in r.items() if k not in ("index", "wall_time")}
            out[r["key"]] = (json.dumps(row, sort_keys=True), data)
    return out


def test_a_merge_of_two_halves_equals_the_whole_scan(tmp_path):
    a, b, whole, merged = (tmp_path / n for n in ("a.h5", "b.h5", "whole.h5", "all.h5"))
    run_sweep(IDEAL, [parse_param("speed=600rpm,900rpm")], a, **OPTS)
    run_sweep(IDEAL, [parse_param("speed=1200rpm,1500rpm")], b, **{**OPTS, "jobs": 2})
    run_sweep(IDEAL, [parse_param("speed=600rpm,900rpm,1200rpm,1500rpm")], whole, **OPTS)
    assert merge_sweeps([a, b], merged) == 4
    assert _by_key(merged) == _by_key(whole)
    assert [r["index"] for r in read_case_table(merged)] == [0, 1, 2, 3]
    with h5py.File(merged, "r") as f, h5py.File(whole, "r") as g:
        assert f.attrs["params"] == g.attrs["params"]
    from planar_mbs.cli.app import app

    r = CliRunner().invoke(app, ["sweep-merge", str(a), str(b), "-o", str(tmp_path / "cli.h5")])
    assert r.exit_code == 0 and "4 case(s) from 2 files" in r.output, r.output
    assert _by_key(tmp_path / "cli.h5") == _by_key(whole)
    r = CliRunner().invoke(app, ["sweep-merge", str(a), str(merged), "-o", str(tmp_path / "x.h5")])
    assert r.exit_code == 2 and "in both" in r.output and "Traceback" not in r.output
    with pytest.raises(SweepError, match="in both"):  # duplicates refused
        merge_sweeps([a, merged], tmp_path / "x.h5")
    other = tmp_path / "other.h5"
    run_sweep(IDEAL, [parse_param("speed=2000rpm")], other, **{**OPTS, "revolutions": 13})
    with pytest.raises(SweepError, match="other settings"):
        merge_sweeps([a, other], tmp_path / "y.h5")
    assert not (tmp_path / "x.h5").exists() and not (tmp_path / "y.h5").exists()


# ---------------------------------------------------------------- the journal
def test_cases_a_killed_sweep_left_in_its_journal_are_read_and_gathered(tmp_path):
    """A finished case waits in the journal until it is gathered into the scan file: the table reads
    it there, and the next sweep on that output gathers it without running it again."""
    out = tmp_path / "s.h5"
    run_sweep(IDEAL, [parse_param("speed=600rpm,900rpm")], out, **OPTS)
    folder = journal_folder(out)
    assert not folder.exists()
    # a sweep killed after its third case reached the journal: made here from a second scan's case
    other = tmp_path / "t.h5"
    run_sweep(IDEAL, [parse_param("speed=600rpm,900rpm,1200rpm")], other, **OPTS)
    folder.mkdir()
    row = [r for r in read_case_table(other) if r["index"] == 2][0]
    with h5py.File(out, "r") as f:
        config = f.attrs["config"]
    with h5py.File(other, "r") as src, h5py.File(folder / "case-2.h5", "w") as part:
        src.copy(src["cases/2"], part, "cases/2")
        part.attrs["sweep_row"] = json.dumps(row)
        part.attrs["sweep_config"] = config
        sign_case(part, journal_key(folder))  # as the killed sweep signed it
    (folder / ".case-3.123.tmp").write_bytes(b"half a case")  # a case cut off while being written
    assert [r["values"]["speed"] for r in read_case_table(out)] == ["600rpm", "900rpm", "1200rpm"]
    s = run_sweep(IDEAL, [parse_param("speed=600rpm,900rpm,1200rpm")], out, **OPTS)
    assert s.ran == [] and sorted(s.skipped) == [0, 1, 2]
    assert not folder.exists()
    assert _by_key(out) == _by_key(other)


def test_a_sweep_killed_before_its_first_gather_keeps_its_numbering(tmp_path):
    """The last case finished first (a pool) and the sweep was killed before it gathered anything:
    its journal holds that case and the plan of the numbering, so the resumed scan numbers every
    case as the uninterrupted one does (not the unfinished cases after the finished one)."""
    from planar_mbs.sweep.store import write_plan

    speeds = [parse_param("speed=600rpm,900rpm,1200rpm")]
    whole, out = tmp_path / "whole.h5", tmp_path / "s.h5"
    run_sweep(IDEAL, speeds, whole, **OPTS)
    rows = read_case_table(whole)
    folder = journal_folder(out)
    folder.mkdir()
    write_plan(folder, {r["key"]: r["index"] for r in rows})
    with h5py.File(whole, "r") as src, h5py.File(folder / "case-2.h5", "w") as part:
        src.copy(src["cases/2"], part, "cases/2")
        part.attrs["sweep_row"] = json.dumps(rows[2])
        part.attrs["sweep_config"] = src.attrs["config"]
        sign_case(part, journal_key(folder))
    s = run_sweep(IDEAL, speeds, out, **OPTS)
    assert sorted(s.ran) == [0, 1] and s.skipped == [2]
    assert _by_key(out) == _by_key(whole)
