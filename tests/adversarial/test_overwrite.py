"""No command writes over one of its inputs: the model, a file it includes, the results file
given to `view` or `plot`, nor one output over another -- named directly, through another
spelling of the path, a symbolic link or a hard link.  Odd output paths (a folder, a missing
parent, a FIFO) are refused before anything runs, with exit 2."""
from __future__ import annotations

import os

import pytest

from advhelp import assert_clean, fifo, mbs, mbs_process, snapshot

# how the output names the protected file
SPELLINGS = ["plain", "dot-slash", "absolute", "symlink", "hardlink", "via-symlinked-folder"]


def alias(sandbox, target: str, how: str) -> str:
    """A path that names sandbox/target in the way `how`."""
    if how == "plain":
        return target
    if how == "dot-slash":
        return "./" + target
    if how == "absolute":
        return str(sandbox / target)
    if how == "symlink":
        os.symlink(sandbox / target, sandbox / "alias")
        return "alias"
    if how == "hardlink":
        os.link(sandbox / target, sandbox / "alias")
        return "alias"
    if how == "via-symlinked-folder":
        os.symlink(sandbox, sandbox / "here")
        return "here/" + target
    raise AssertionError(how)


@pytest.mark.parametrize("how", SPELLINGS)
@pytest.mark.parametrize("target,words", [("mech.mbs", "the model file"),
                                          ("parts/bodies.mbs", "a file the model includes")])
@pytest.mark.parametrize("option", ["-o", "--rerun"])
def test_run_never_writes_over_the_model(sandbox, option, target, words, how):
    path = alias(sandbox, target, how)
    before = snapshot(sandbox)
    extra = ["-o", "new.h5"] if option == "--rerun" else []
    out = mbs("run", "mech.mbs", *extra, option, path, "-q", cwd=sandbox)
    assert_clean(out, 2, words, "destroy", before=before, folder=sandbox)


@pytest.mark.parametrize("how", SPELLINGS)
def test_run_rerun_and_output_are_not_one_file(sandbox, how):
    (sandbox / "out.h5").write_bytes(b"old results")
    path = alias(sandbox, "out.h5", how)
    before = snapshot(sandbox)
    out = mbs("run", "mech.mbs", "-o", "out.h5", "--rerun", path, "-q", cwd=sandbox)
    assert_clean(out, 2, "--rerun", "also the results file", before=before, folder=sandbox)


def test_run_rerun_equal_to_output_not_yet_existing(sandbox):
    before = snapshot(sandbox)
    out = mbs("run", "mech.mbs", "-o", "new.h5", "--rerun", "./new.h5", "-q", cwd=sandbox)
    assert_clean(out, 2, "also the results file", before=before, folder=sandbox)


@pytest.mark.parametrize("how", SPELLINGS)
def test_view_never_writes_over_its_results(sandbox, how):
    path = alias(sandbox, "run.h5", how)
    before = snapshot(sandbox)
    out = mbs("view", "run.h5", "-o", path, cwd=sandbox)
    assert_clean(out, 2, "the results file", "destroy", before=before, folder=sandbox)


def test_view_of_a_recording_is_refused(sandbox):
    """`mbs view a.rrd` once wrote the recording over itself (its default output)."""
    (sandbox / "a.rrd").write_bytes(b"RRF2" + bytes(200))
    before = snapshot(sandbox)
    out = mbs("view", "a.rrd", cwd=sandbox)
    assert_clean(out, 2, "not an HDF5 file", ".rrd", before=before, folder=sandbox)


def test_view_of_hdf5_named_rrd_is_refused(sandbox):
    os.rename(sandbox / "run.h5", sandbox / "run.rrd")
    before = snapshot(sandbox)
    out = mbs("view", "run.rrd", cwd=sandbox)
    assert_clean(out, 2, "the results file", before=before, folder=sandbox)


@pytest.mark.parametrize("how", SPELLINGS)
@pytest.mark.parametrize("target", ["mech.mbs", "parts/bodies.mbs"])
def test_sweep_never_writes_over_the_model(sandbox, target, how):
    path = alias(sandbox, target, how)
    before = snapshot(sandbox)
    out = mbs("sweep", "mech.mbs", "-P", "speed=3000rpm", "-o", path, "-q", "-j", "1", cwd=sandbox)
    assert_clean(out, 2, "destroy", before=before, folder=sandbox)


@pytest.mark.parametrize("overwrite", [[], ["--overwrite"]])
def test_sweep_output_is_the_model_even_with_overwrite(sandbox, overwrite):
    before = snapshot(sandbox)
    out = mbs("sweep", "mech.mbs", "-P", "speed=3000rpm", "-o", "mech.mbs", *overwrite, "-q", cwd=sandbox)
    assert_clean(out, 2, "the model file", before=before, folder=sandbox)


def test_plot_output_naming_the_results_file(sandbox):
    before = snapshot(sandbox)
    out = mbs("plot", "run.h5", "-o", "run.h5", cwd=sandbox)
    assert_clean(out, 2, "the results file", "destroy", before=before, folder=sandbox)


def test_plot_never_draws_over_hdf5_data(sandbox):
    """A figure whose name happens to be an HDF5 file is not written over it."""
    os.makedirs(sandbox / "figs")
    os.link(sandbox / "run.h5", sandbox / "figs" / "run_slider.x.png")
    before = snapshot(sandbox)
    out = mbs("plot", "run.h5", "slider.x", "-o", "figs", cwd=sandbox)
    assert_clean(out, 2, "holds HDF5 data", before=before, folder=sandbox)


# ---------------------------------------------------------------- odd output paths
def odd_output(sandbox, kind: str) -> str:
    if kind == "folder":
        (sandbox / "d").mkdir()
        return "d"
    if kind == "missing-parent":
        return "no/such/dir/out.x"
    if kind == "parent-is-file":
        return "mech.mbs/out.x"
    if kind == "empty":
        return ""
    if kind == "dev-null":
        return "/dev/null"
    raise AssertionError(kind)


ODD = ["folder", "missing-parent", "parent-is-file", "empty", "dev-null"]


@pytest.mark.parametrize("kind", ODD)
@pytest.mark.parametrize("command", ["run-o", "run-rerun", "view", "sweep"])
def test_odd_output_paths(sandbox, command, kind):
    path = odd_output(sandbox, kind)
    before = snapshot(sandbox)
    args = {"run-o": ["run", "mech.mbs", "-q", "-o", path],
            "run-rerun": ["run", "mech.mbs", "-q", "-o", "new.h5", "--rerun", path],
            "view": ["view", "run.h5", "-o", path],
            "sweep": ["sweep", "mech.mbs", "-P", "speed=3000rpm", "-q", "-o", path]}[command]
    out = mbs(*args, cwd=sandbox)
    if kind == "missing-parent" and command in ("run-rerun", "view"):  # recording folders are made as needed
        assert out.code == 0, out.output
        assert (sandbox / path).is_file() and not list(sandbox.rglob(".*.part"))
        return
    assert_clean(out, 2, "--", before=before, folder=sandbox)


@pytest.mark.parametrize("command", ["run", "view", "sweep"])
def test_output_is_a_fifo(sandbox, command):
    with fifo(sandbox / "pipe"):
        before = snapshot(sandbox)
        args = {"run": ["run", "mech.mbs", "-q", "-o", "pipe"], "view": ["view", "run.h5", "-o", "pipe"],
                "sweep": ["sweep", "mech.mbs", "-P", "speed=3000rpm", "-q", "-o", "pipe"]}[command]
        out = mbs(*args, cwd=sandbox)
        assert_clean(out, 2, "not a regular file", before=before, folder=sandbox, bound=2.0)


@pytest.mark.parametrize("kind", ["missing-parent", "parent-is-file"])
def test_plot_odd_output_folder(sandbox, kind):
    path = "mech.mbs/figs" if kind == "parent-is-file" else "a/b/c"
    before = snapshot(sandbox)
    out = mbs("plot", "run.h5", "slider.x", "-o", path, cwd=sandbox)
    if kind == "missing-parent":  # figure folders are created as needed
        assert_clean(out, 0, before=before, folder=sandbox, allowed=["a"])
        assert (sandbox / "a/b/c/run_slider.x.png").exists()
    else:
        assert_clean(out, 2, "not a folder", before=before, folder=sandbox)


def read_only_folder(tmp_path):
    """A folder this user cannot write: a mode 555 folder, or for root (who may write anywhere
    the mode forbids) /proc/sys, which the kernel keeps read-only."""
    if os.geteuid() == 0:
        if os.access("/proc/sys", os.W_OK):
            pytest.skip("no read-only folder for root here")
        return "/proc/sys"
    ro = tmp_path / "ro"
    ro.mkdir(mode=0o555)
    return str(ro)


@pytest.mark.parametrize("command", ["run-o", "run-rerun", "view", "sweep", "plot"])
def test_read_only_folder(sandbox, command, tmp_path):
    ro = read_only_folder(tmp_path)
    before = snapshot(sandbox)
    args = {"run-o": ["run", "mech.mbs", "-q", "-o", f"{ro}/x.h5"],
            "run-rerun": ["run", "mech.mbs", "-q", "-o", "new.h5", "--rerun", f"{ro}/x.rrd"],
            "view": ["view", "run.h5", "-o", f"{ro}/x.rrd"],
            "sweep": ["sweep", "mech.mbs", "-P", "speed=3000rpm", "-q", "-o", f"{ro}/x.h5"],
            "plot": ["plot", "run.h5", "-o", f"{ro}/figs"]}[command]
    out = mbs(*args, cwd=sandbox)
    assert_clean(out, 2, "read-only", before=before, folder=sandbox)


def test_real_process_refuses_output_over_model(sandbox):
    before = snapshot(sandbox)
    out = mbs_process("run", "mech.mbs", "-o", "parts/../mech.mbs", "-q", cwd=sandbox)
    assert_clean(out, 2, "the model file", before=before, folder=sandbox)
