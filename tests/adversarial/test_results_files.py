"""Foreign, damaged or crafted files given where a results file is read -- `plot`, `plot --list`,
`view`, `view --signals-only`, `analyze`, and a sweep resuming into its `-o` file: each is
refused with exit 2 and a message (no traceback, no hang, no huge allocation), and no file
changes.  Checked with os.stat before anything opens them; HDF5 layouts are checked (names,
shapes, dtypes, declared against stored sizes, links, format version) before data is read."""
from __future__ import annotations

import json
import os
import shutil

import h5py
import numpy as np
import pytest

from advhelp import assert_clean, fifo, mbs, snapshot

COMMANDS = {
    "plot": lambda f: ["plot", f, "-o", "figs"],
    "plot-list": lambda f: ["plot", f, "--list"],
    "view": lambda f: ["view", f, "-o", "out.rrd"],
    "view-signals-only": lambda f: ["view", f, "-o", "out.rrd", "--signals-only"],
    "analyze": lambda f: ["analyze", f],
    "analyze-store": lambda f: ["analyze", f, "--store"],
    "sweep-resume": lambda f: ["sweep", "mech.mbs", "-P", "speed=3000rpm,4000rpm", "-o", f, "-q", "-j", "1",
                               "--t-end", "1ms", "--no-section"],
}


# ---------------------------------------------------------------- the files
def _copy_run(box, name):
    shutil.copy(box / "run.h5", box / name)
    return h5py.File(box / name, "r+")


def _crafted(box, name, edit):
    with _copy_run(box, name) as f:
        edit(f)
    return name


def _replace(path: str, make):
    def edit(f):
        del f[path]
        make(f, path)
    return edit


def _truncate(box, name, fraction):
    data = (box / "run.h5").read_bytes()
    (box / name).write_bytes(data[:int(len(data) * fraction)])
    return name


def _entities(f):
    return [f"signals/{e}" for e in f["signals"]]


def _each_entity(make):
    """Replace every entity's dataset by make(old dataset) (a dict of create_dataset arguments)."""
    def edit(f):
        for k in _entities(f):
            old = f[k]
            args = make(old)
            del f[k]
            f.create_dataset(k, **args)
    return edit


def _records(n, names=("x", "y"), dtype="<f8"):
    return np.zeros(n, dtype=[(q, dtype) for q in names])


def _legacy(f):
    """The earlier layout: a group per entity, a dataset per signal."""
    for k in _entities(f):
        data = f[k][()]
        del f[k]
        for q in data.dtype.names:
            f.create_dataset(f"{k}/{q}", data=np.ascontiguousarray(data[q]))


def _with_attr(key, value):
    def edit(f):
        f.attrs[key] = value
    return edit


KINDS = {
    "missing": lambda box: "nope.h5",
    "folder": lambda box: (os.mkdir(box / "d.h5"), "d.h5")[1],
    "dev-zero": lambda box: "/dev/zero",
    "dev-null": lambda box: "/dev/null",
    "empty": lambda box: ((box / "e.h5").write_bytes(b""), "e.h5")[1],
    "text": lambda box: ((box / "t.h5").write_text("time,x\n0,1\n"), "t.h5")[1],
    "model-as-results": lambda box: "mech.mbs",
    "rrd-recording": lambda box: ((box / "r.rrd").write_bytes(b"RRF2\0\0\0\0" + bytes(100)), "r.rrd")[1],
    "hdf5-signature-only": lambda box: ((box / "s.h5").write_bytes(b"\x89HDF\r\n\x1a\n"), "s.h5")[1],
    "signature-then-garbage": lambda box: ((box / "g.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + os.urandom(4000)),
                                           "g.h5")[1],
    "truncated-10%": lambda box: _truncate(box, "t10.h5", 0.1),
    "truncated-50%": lambda box: _truncate(box, "t50.h5", 0.5),
    "truncated-90%": lambda box: _truncate(box, "t90.h5", 0.9),
    "empty-hdf5": lambda box: (h5py.File(box / "n.h5", "w").close(), "n.h5")[1],
    "no-time": lambda box: _crafted(box, "c.h5", lambda f: f.__delitem__("time")),
    "no-signals": lambda box: _crafted(box, "c.h5", lambda f: f.__delitem__("signals")),
    "time-2d": lambda box: _crafted(box, "c.h5", _replace("time", lambda f, p: f.create_dataset(p, data=np.zeros((11, 2))))),
    "time-strings": lambda box: _crafted(box, "c.h5", _replace("time", lambda f, p: f.create_dataset(p, data=np.array([b"a"] * 11)))),
    "time-complex": lambda box: _crafted(box, "c.h5", _replace("time", lambda f, p: f.create_dataset(p, data=np.zeros(11, complex)))),
    "time-is-group": lambda box: _crafted(box, "c.h5", _replace("time", lambda f, p: f.create_group(p))),
    "time-scalar": lambda box: _crafted(box, "c.h5", _replace("time", lambda f, p: f.create_dataset(p, data=1.0))),
    "entity-length-differs": lambda box: _crafted(box, "c.h5", _replace("signals/slider", lambda f, p: f.create_dataset(p, data=_records(7)))),
    "entity-plain-floats": lambda box: _crafted(box, "c.h5", _replace("signals/slider", lambda f, p: f.create_dataset(p, data=np.zeros(11)))),
    "entity-2d-floats": lambda box: _crafted(box, "c.h5", _replace("signals/slider", lambda f, p: f.create_dataset(p, data=np.zeros((11, 3))))),
    "entity-integer-fields": lambda box: _crafted(box, "c.h5", _replace("signals/slider", lambda f, p: f.create_dataset(p, data=_records(11, dtype="<i8")))),
    "entity-string-field": lambda box: _crafted(box, "c.h5", _replace("signals/slider", lambda f, p: f.create_dataset(p, data=np.zeros(11, dtype=[("x", "<f8"), ("s", "S8")])))),
    "entity-array-field": lambda box: _crafted(box, "c.h5", _replace("signals/slider", lambda f, p: f.create_dataset(p, data=np.zeros(11, dtype=[("x", "<f8", (1000,))])))),
    "entity-field-with-dots": lambda box: _crafted(box, "c.h5", _replace("signals/slider", lambda f, p: f.create_dataset(p, data=_records(11, ("x.y.z", "vx"))))),
    "signals-is-dataset": lambda box: _crafted(box, "c.h5", _replace("signals", lambda f, p: f.create_dataset(p, data=np.zeros(11)))),
    "legacy-signal-is-group": lambda box: _crafted(box, "c.h5", lambda f: (_legacy(f), f.__delitem__("signals/slider/x"), f.create_group("signals/slider/x"))),
    "legacy-signal-length-differs": lambda box: _crafted(box, "c.h5", lambda f: (_legacy(f), f.__delitem__("signals/slider/x"), f.create_dataset("signals/slider/x", data=np.zeros(7)))),
    "legacy-name-with-dots": lambda box: _crafted(box, "c.h5", lambda f: (_legacy(f), f.move("signals/slider/x", "signals/slider/x.y.z"))),
    "entity-name-control-chars": lambda box: _crafted(box, "c.h5", lambda f: f.move("signals/slider", "signals/sl\x1b[31mider")),
    "huge-declared-chunked": lambda box: _crafted(box, "c.h5", _replace("time", lambda f, p: f.create_dataset(
        p, shape=(2**40,), maxshape=(None,), chunks=(4096,), dtype="f8"))),
    "huge-declared-contiguous": lambda box: _crafted(box, "c.h5", _replace("time", lambda f, p: f.create_dataset(
        p, shape=(2**37,), dtype="f8"))),
    "all-signals-huge": lambda box: _crafted(box, "c.h5", lambda f: (
        _replace("time", lambda f, p: f.create_dataset(p, shape=(10**9,), chunks=(4096,), dtype="f8"))(f),
        _each_entity(lambda old: dict(shape=(10**9,), chunks=(4096,), dtype=old.dtype))(f))),
    "soft-link": lambda box: _crafted(box, "c.h5", lambda f: (f.move("time", "t0"), f.__setitem__("time", h5py.SoftLink("/t0")))),
    "external-link-to-fifo": lambda box: _crafted(box, "c.h5", lambda f: (
        os.mkfifo(box / "ext.fifo"), f.__delitem__("time"), f.__setitem__("time", h5py.ExternalLink(str(box / "ext.fifo"), "/x")))),
    "external-storage": lambda box: _crafted(box, "c.h5", _replace("time", lambda f, p: f.create_dataset(
        p, shape=(11,), dtype="f8", external=[(str(box / "raw.bin"), 0, 88)]))),
    "newer-format": lambda box: _crafted(box, "c.h5", _with_attr("format_version", 99)),
    "format-is-text": lambda box: _crafted(box, "c.h5", _with_attr("format_version", "one")),
    "10k-entities": lambda box: _crafted(box, "c.h5", lambda f: [f.create_group(f"signals/e{i}") for i in range(100)]
                                         and [f.create_dataset(f"signals/e{i}/q{j}", data=np.zeros(3))
                                              for i in range(100) for j in range(2)]),
}

# files that are readable results, but odd: accepted or refused, never a traceback
ODD_BUT_VALID = {
    "garbage-json-attrs": lambda box: _crafted(box, "c.h5", lambda f: [f.attrs.__setitem__(k, "{not json")
                                                                      for k in ("parameters", "settings", "warnings",
                                                                                "model_includes")]),
    "model-source-garbage": lambda box: _crafted(box, "c.h5", _with_attr("model_source", "body {{{ nonsense")),
    "model-source-binary": lambda box: _crafted(box, "c.h5", _with_attr("model_source", np.void(b"\0\1\2"))),
    "zero-samples": lambda box: _crafted(box, "c.h5", lambda f: (
        _replace("time", lambda f, p: f.create_dataset(p, shape=(0,), dtype="f8"))(f),
        _each_entity(lambda old: dict(shape=(0,), dtype=old.dtype))(f))),
    "nan-everywhere": lambda box: _crafted(box, "c.h5", _each_entity(
        lambda old: dict(data=np.array([(np.nan,) * len(old.dtype.names)] * old.shape[0], dtype=old.dtype)))),
    "legacy-layout": lambda box: _crafted(box, "c.h5", _legacy),
    "time-backwards": lambda box: _crafted(box, "c.h5", lambda f: f["time"].__setitem__(slice(None), f["time"][()][::-1])),
    "integer-time": lambda box: _crafted(box, "c.h5", _replace("time", lambda f, p: f.create_dataset(p, data=np.arange(11)))),
    "units-attr-numbers": lambda box: _crafted(box, "c.h5", lambda f: f["signals/slider"].attrs.__setitem__("units", np.arange(3))),
    "units-attr-missing": lambda box: _crafted(box, "c.h5", lambda f: f["signals/slider"].attrs.__delitem__("units")),
}

# variants that read the file through the same checks as another command: in the slow run only
SLOW_VARIANTS = {"plot-list", "view-signals-only", "analyze-store"}


def commands(names, slow=SLOW_VARIANTS):
    return [pytest.param(c, marks=pytest.mark.slow) if c in slow else c for c in sorted(names)]


@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("command", commands(COMMANDS))
def test_bad_results_file(sandbox, command, kind):
    name = KINDS[kind](sandbox)
    before = snapshot(sandbox)
    out = mbs(*COMMANDS[command](name), cwd=sandbox, timeout=10)
    if command == "sweep-resume" and kind == "missing":  # a new sweep file: that is not an input
        assert_clean(out, 0, before=before, folder=sandbox, allowed=[name])
        return
    assert_clean(out, 2, before=before, folder=sandbox, bound=2.0)
    assert len(out.output) < 3000, out.output


@pytest.mark.parametrize("kind", sorted(ODD_BUT_VALID))
@pytest.mark.parametrize("command", commands(["plot", "plot-list", "view", "view-signals-only", "analyze"],
                                             slow={"plot", "view-signals-only"}))
def test_odd_but_readable_results(sandbox, command, kind):
    name = ODD_BUT_VALID[kind](sandbox)
    before = snapshot(sandbox)
    out = mbs(*COMMANDS[command](name), cwd=sandbox, timeout=30)
    assert "Traceback" not in out.output and out.exception is None, out.output
    assert out.code in (0, 2), out.output
    allowed = ["figs", "out.rrd"] if out.code == 0 else []
    assert_clean(out, out.code, before=before, folder=sandbox, allowed=allowed)


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("via", ["direct", "symlink"])
def test_fifo_as_results_file(sandbox, command, via):
    with fifo(sandbox / "pipe.h5"):
        name = "pipe.h5"
        if via == "symlink":
            os.symlink("pipe.h5", sandbox / "link.h5")
            name = "link.h5"
        before = snapshot(sandbox)
        out = mbs(*COMMANDS[command](name), cwd=sandbox, timeout=10)
        assert_clean(out, 2, "not a regular file", before=before, folder=sandbox, bound=2.0)


@pytest.mark.parametrize("case", ["/cases/7", "/cases/x", "/nope", "/cases_table", "/"])
@pytest.mark.parametrize("command", ["plot", "view", "analyze"])
def test_bad_case_of_a_sweep(sandbox, command, case):
    before = snapshot(sandbox)
    out = mbs(*COMMANDS[command](f"sweep.h5:{case}"), cwd=sandbox)
    if case == "/" and command == "analyze":  # a whole sweep: its table is printed
        assert_clean(out, 0, before=before, folder=sandbox)
        return
    assert_clean(out, 2, before=before, folder=sandbox, allowed=["figs"] if case == "/" else [])


def _sweep_edit(edit):
    def make(box):
        with h5py.File(box / "sweep.h5", "r+") as f:
            edit(f)
        return "sweep.h5"
    return make


SWEEP_KINDS = {
    "table-rows-huge": _sweep_edit(lambda f: (f["cases_table"].__delitem__("index"),
                                              f["cases_table"].create_dataset("index", shape=(10**12,), chunks=(4096,), dtype="i8"))),
    "table-columns-unequal": _sweep_edit(lambda f: (f["cases_table"].__delitem__("index"),
                                                    f["cases_table"].create_dataset("index", data=np.arange(5)))),
    "config-not-json": _sweep_edit(lambda f: f.attrs.__setitem__("config", "{")),
    "no-config": _sweep_edit(lambda f: f.attrs.__delitem__("config")),
    "params-not-json": _sweep_edit(lambda f: f["cases_table"].attrs.__setitem__("params", "[")),
    "case-group-crafted": _sweep_edit(lambda f: (f["cases/0"].__delitem__("time"),
                                                 f["cases/0"].create_dataset("time", shape=(2**40,), chunks=(4096,), dtype="f8"))),
}


@pytest.mark.parametrize("kind", sorted(SWEEP_KINDS))
@pytest.mark.parametrize("command", commands(["plot", "plot-list", "analyze", "sweep-resume"], slow={"plot"}))
def test_crafted_sweep_file(sandbox, command, kind):
    name = SWEEP_KINDS[kind](sandbox)
    before = snapshot(sandbox)
    out = mbs(*COMMANDS[command](name), cwd=sandbox, timeout=10)
    assert "Traceback" not in out.output and out.exception is None, out.output
    # what a command reads is checked; a damaged part it never needs may go unnoticed
    needed = {"sweep-resume": {"config-not-json", "no-config", "table-rows-huge", "table-columns-unequal",
                               "params-not-json"},
              "analyze": {"table-rows-huge", "table-columns-unequal", "params-not-json"},
              "plot": {"case-group-crafted"}, "plot-list": {"case-group-crafted"}}[command]
    assert out.code == 2 if kind in needed else out.code in (0, 2), out.output
    allowed = {"plot": ["figs"], "sweep-resume": ["sweep.h5"]}.get(command, []) if out.code == 0 else []
    assert_clean(out, out.code, before=before, folder=sandbox, allowed=allowed,
                 bound=None if command == "plot" else 2.0)  # drawing takes its time; reading is bounded


def test_huge_declared_shape_is_refused_without_allocating(sandbox):
    """One crafted file asked for a 7 TiB allocation: refused from its metadata."""
    KINDS["huge-declared-chunked"](sandbox)
    from planar_mbs.results.hdf5 import ResultsFileError, read_results

    with pytest.raises(ResultsFileError, match="declares|GiB"):
        read_results(sandbox / "c.h5")


def test_layout_budget_counts_every_signal(sandbox):
    from planar_mbs.results.hdf5 import ResultsFileError, check_run_layout

    with h5py.File(sandbox / "run.h5", "r") as f:
        need = check_run_layout(f, "run.h5")
        n = len(f["time"])
        count = 1 + sum(len(f["signals"][e].dtype.names) for e in f["signals"])  # time + every field
        assert need == 8 * n * count  # every dataset, 8 bytes a sample
        with pytest.raises(ResultsFileError, match="GiB"):
            check_run_layout(f, "run.h5", budget=need - 1)


def test_results_written_now_carry_the_format_version(sandbox):
    with h5py.File(sandbox / "run.h5", "r") as f:
        assert int(f.attrs["format_version"]) == 1
        assert json.loads(f.attrs["model_includes"])


@pytest.mark.parametrize("damage", ["huge", "two-d", "strings", "signals-not-a-list"])
def test_crafted_poincare_section_is_refused(sandbox, damage):
    """`sweep_sections` (Python API) reads every case's section: a crafted one is refused from its
    metadata, before any allocation."""
    from planar_mbs.results.hdf5 import ResultsFileError
    from planar_mbs.sweep.scan import sweep_sections

    with h5py.File(sandbox / "sweep.h5", "r+") as f:
        g = f.create_group("cases/0/poincare")
        g.attrs["signals"] = json.dumps(["slider.vx"]) if damage != "signals-not-a-list" else json.dumps("x")
        g.create_dataset("time", data=np.zeros(3))
        if damage == "huge":
            g.create_dataset("slider.vx", shape=(2**40,), chunks=(4096,), dtype="f8")
        elif damage == "two-d":
            g.create_dataset("slider.vx", data=np.zeros((3, 3)))
        elif damage == "strings":
            g.create_dataset("slider.vx", data=np.array([b"a", b"b", b"c"]))
    with pytest.raises(ResultsFileError):
        sweep_sections(sandbox / "sweep.h5")
