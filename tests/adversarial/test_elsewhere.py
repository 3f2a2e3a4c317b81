"""`mbs view` of a run whose model uses `include`, from another folder or after the model's
files are gone: rebuilt from the text the results file keeps.  Also: no parser tables are
loaded from (or written to) the shared temporary folder, and a bug still ends without a
traceback in the real `mbs` process."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys

import h5py
import pytest

from advhelp import assert_clean, fifo, mbs, mbs_process, snapshot


@pytest.mark.parametrize("where", ["other-folder", "model-files-deleted", "model-files-changed"])
def test_view_rebuilds_the_model_anywhere(sandbox, tmp_path, where):
    import json

    with h5py.File(sandbox / "run.h5", "r+") as f:  # as if run in the sandbox (not the session's folder)
        f.attrs["model_path"] = f.attrs["model_key"] = str(sandbox / "mech.mbs")
        text = list(json.loads(f.attrs["model_includes"]).values())[0]
        f.attrs["model_includes"] = json.dumps({str(sandbox / "parts" / "bodies.mbs"): text})
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    shutil.copy(sandbox / "run.h5", elsewhere / "run.h5")
    if where == "model-files-deleted":
        shutil.rmtree(sandbox / "parts")
        os.remove(sandbox / "mech.mbs")
    if where == "model-files-changed":  # the recording shows the run, not today's files
        (sandbox / "parts" / "bodies.mbs").write_text("this is no longer a model {")
    before = snapshot(elsewhere)
    out = mbs("view", "run.h5", "-o", "run.rrd", cwd=elsewhere)
    assert_clean(out, 0, "rerun recording", before=before, folder=elsewhere, allowed=["run.rrd"])
    assert (elsewhere / "run.rrd").stat().st_size > 0


def test_results_keep_every_included_file(sandbox):
    import json

    with h5py.File(sandbox / "run.h5", "r") as f:
        includes = json.loads(f.attrs["model_includes"])
        assert f.attrs["model_key"] == str(sandbox / "mech.mbs") or f.attrs["model_key"].endswith("mech.mbs")
    assert list(includes.values()) == [(sandbox / "parts" / "bodies.mbs").read_text()]


def test_view_of_older_results_without_included_files(sandbox, tmp_path):
    """Files written before the included files were kept: rebuilt from the disk when it can be,
    else a clear message (and `--signals-only` still works)."""
    with h5py.File(sandbox / "run.h5", "r+") as f:
        del f.attrs["model_includes"]
        f.attrs["model_path"] = f.attrs["model_key"] = str(sandbox / "mech.mbs")  # the session's copy stays
    shutil.rmtree(sandbox / "parts")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    shutil.copy(sandbox / "run.h5", elsewhere / "run.h5")
    before = snapshot(elsewhere)
    out = mbs("view", "run.h5", "-o", "run.rrd", cwd=elsewhere)
    assert_clean(out, 2, "no longer compiles", "bodies.mbs", before=before, folder=elsewhere)
    out = mbs("view", "run.h5", "-o", "run.rrd", "--signals-only", cwd=elsewhere)
    assert_clean(out, 0, before=before, folder=elsewhere, allowed=["run.rrd"])


def test_view_elsewhere_as_a_real_process(sandbox, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    shutil.copy(sandbox / "run.h5", elsewhere / "a.h5")
    before = snapshot(elsewhere)
    out = mbs_process("view", "a.h5", cwd=elsewhere)
    assert_clean(out, 0, "rerun recording", before=before, folder=elsewhere, allowed=["a.rrd"])


def test_no_parser_pickle_in_the_temporary_folder(tmp_path):
    """lark's `cache=True` wrote a pickle to the shared temporary folder and loaded it later:
    anyone able to write there could run code as the user.  The parser is built in memory."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    planted = tmp / ".lark_cache_planted.tmp"
    planted.write_bytes(b"not a pickle")
    code = ("from planar_mbs.language.parse import parse_model; "
            "parse_model('param a = 1 mm', 'x.mbs'); print('ok')")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, TMPDIR=str(tmp), TEMP=str(tmp), TMP=str(tmp)))
    assert proc.returncode == 0 and "ok" in proc.stdout, proc.stderr
    assert sorted(p.name for p in tmp.iterdir()) == [planted.name]


def test_parser_is_not_built_with_a_cache():
    from planar_mbs.language.parse import parser

    assert not parser().options.cache


def test_a_bug_ends_without_traceback_in_the_real_process(sandbox):
    """The last line of defence in `main`: an unexpected exception is one line and exit 1."""
    code = ("import planar_mbs.cli.app as a, planar_mbs.cli.check_command as c, sys\n"
            "def boom(*args, **kw): raise RuntimeError('injected fault')\n"
            "c._print_model = boom\n"
            "sys.argv = ['mbs', 'check', 'mech.mbs']\n"
            "a.main()\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=sandbox, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr and "internal error: RuntimeError: injected fault" in proc.stderr


@pytest.mark.parametrize("command", [["plot", "pipe.h5"], ["view", "pipe.h5"], ["analyze", "pipe.h5"],
                                     ["check", "pipe.h5"], ["run", "pipe.h5", "-q"]])
def test_fifo_input_as_a_real_process(sandbox, command):
    with fifo(sandbox / "pipe.h5", release_after=20):
        before = snapshot(sandbox)
        out = mbs_process(*command, cwd=sandbox, timeout=60)
        assert_clean(out, 2, "not a regular file", before=before, folder=sandbox)


# ---------------------------------------------------------------- the parser's cached tables
PLANTS = ["control-own-file", "other-owner", "group-writable-file", "open-folder", "symlink", "garbage"]


@pytest.mark.parametrize("plant", PLANTS)
def test_planted_parser_tables_are_never_loaded(tmp_path, plant):
    """A pickle planted where the parser's tables are cached runs code when loaded (here: it
    creates a marker file).  Only a regular file of this user, in a folder of this user with
    mode 0700, is loaded; the control case shows the pickle does run when it is."""
    import pickle

    from planar_mbs.language.parse import tables_name

    cache = tmp_path / "cache"
    folder = cache / "planar_mbs"
    folder.mkdir(parents=True, mode=0o700)
    os.chmod(folder, 0o700)
    marker = tmp_path / "code-ran"

    class Plant:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    target = folder / tables_name()
    payload = pickle.dumps(Plant()) if plant != "garbage" else b"\x80\x05garbage"
    if plant == "symlink":
        (tmp_path / "elsewhere.pickle").write_bytes(payload)
        os.symlink(tmp_path / "elsewhere.pickle", target)
    else:
        target.write_bytes(payload)
        os.chmod(target, 0o600)
    if plant == "other-owner":
        if os.geteuid() != 0:
            pytest.skip("needs root to give the file to another user")
        os.chown(target, 65534, 65534)
    if plant == "group-writable-file":
        os.chmod(target, 0o664)
    if plant == "open-folder":
        os.chmod(folder, 0o777)
    code = "from planar_mbs.language.parse import parse_model; parse_model('param a = 1 mm', 'x.mbs'); print('ok')"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, XDG_CACHE_HOME=str(cache)))
    assert proc.returncode == 0 and "ok" in proc.stdout, proc.stderr
    assert marker.exists() == (plant == "control-own-file")


def test_parser_tables_cache_is_private(tmp_path):
    cache = tmp_path / "cache"
    code = "from planar_mbs.language.parse import parser; parser()"
    for _ in range(2):  # written, then loaded
        subprocess.run([sys.executable, "-c", code], check=True, timeout=120,
                       env=dict(os.environ, XDG_CACHE_HOME=str(cache)))
    folder = cache / "planar_mbs"
    assert oct(folder.stat().st_mode & 0o777) == oct(0o700)
    files = list(folder.iterdir())
    assert len(files) == 1 and files[0].stat().st_mode & 0o077 == 0


@pytest.mark.parametrize("damage", ["self-include", "fan-out", "not-a-model", "not-json"])
def test_crafted_stored_includes(sandbox, damage):
    """The included files kept in a results file are model text like any other: a cycle, an
    explosion of includes or nonsense is a clean refusal of the drawing, not a crash."""
    import json

    key = str(sandbox / "mech.mbs")
    part = str(sandbox / "parts" / "bodies.mbs")
    includes = {"self-include": {part: 'include "bodies.mbs"\n'},
                "fan-out": {part: 'include "bodies.mbs"\n' * 5},
                "not-a-model": {part: "body {{{ ]]]\n"}}.get(damage)
    with h5py.File(sandbox / "run.h5", "r+") as f:
        f.attrs["model_path"] = f.attrs["model_key"] = key
        f.attrs["model_includes"] = json.dumps(includes) if includes is not None else "{not json"
    if damage == "not-json":  # read as "not stored": the files on disk are used
        shutil.rmtree(sandbox / "parts")
    before = snapshot(sandbox)
    out = mbs("view", "run.h5", "-o", "x.rrd", cwd=sandbox)
    assert_clean(out, 2, "no longer compiles", before=before, folder=sandbox)
