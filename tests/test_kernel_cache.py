"""The compiled-code cache follows every kernel source: changing a contact law in a copy of
the package (whose numba cache holds the time loop compiled with the old law) gives the new
physics, not the cached old one."""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import kernel_models as K
import planar_mbs
from planar_mbs.kernel import make_workspace, nobs
from planar_mbs.kernel.loop import observe
from planar_mbs.mechanism.model import ContactLaw

TESTS = Path(__file__).resolve().parent
# the contact force over K delta^n of a penetrating Hertz journal, read from `observe` (loop.py)
PROBE = """
import json, numpy as np, kernel_models as K
from planar_mbs.kernel import make_workspace, nobs
from planar_mbs.kernel.loop import observe
from planar_mbs.mechanism.model import CP_EXPONENT, CP_STIFFNESS, ContactLaw
km, q0, qd0 = K.free_journal(law=ContactLaw.HERTZ, offset=(1.01e-4, 0.0))
row = np.zeros(nobs(km))
contact = np.array([[1.0, 1.0, 0.0]])
st = observe(km, K.cfg(), 0.0, np.concatenate([q0, qd0]), contact, make_workspace(km), row)
p = km.clearance_param[0]
print(json.dumps([int(st), row[9 + 4] / (p[CP_STIFFNESS] * row[9 + 3] ** p[CP_EXPONENT])]))
"""


def probe(root: Path) -> float:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), str(TESTS)])}
    res = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=900, env=env,
                         cwd=root)
    assert res.returncode == 0, res.stderr
    st, ratio = json.loads(res.stdout.strip().splitlines()[-1])
    assert st == 0
    return ratio


@pytest.mark.slow
def test_changed_contact_law_is_recompiled(tmp_path):
    # warm the cache of the installed package (observe and everything it calls), then copy it
    # together with that cache
    km, q0, qd0 = K.free_journal(law=ContactLaw.HERTZ, offset=(1.01e-4, 0.0))
    observe(km, K.cfg(), 0.0, np.concatenate([q0, qd0]), np.array([[1.0, 1.0, 0.0]]), make_workspace(km),
            np.zeros(nobs(km)))
    src = Path(planar_mbs.__file__).resolve().parent
    shutil.copytree(src, tmp_path / "planar_mbs")
    assert probe(tmp_path) == pytest.approx(1.0, rel=1e-12)  # the copy runs (from its cache)
    contact = tmp_path / "planar_mbs" / "kernel" / "contact.py"
    text = contact.read_text()
    new, n = re.subn(r"(    if law == HERTZ:[^\n]*\n        return )dn, 0\n", r"\g<1>2.0 * dn, 0\n", text)
    assert n == 1
    contact.write_text(new)
    assert probe(tmp_path) == pytest.approx(2.0, rel=1e-12)  # the new law, not the cached one


# --- the way back: numba's public cache where its private classes are not what kernel/jit.py expects ---

ROOT = TESTS.parent
# `mbs` with numba's private class `UserWideCacheLocator` hidden first (as a numba that renamed it
# would): numba itself still works, its list of locators holds the class
MBS_HIDDEN = ("import sys, numba.core.caching as c; del c.UserWideCacheLocator; "
              "from planar_mbs.cli.entry import main; sys.argv[0] = 'mbs'; main()")
MBS = "import sys; from planar_mbs.cli.entry import main; sys.argv[0] = 'mbs'; main()"


def test_fast_path_problem_names_a_version_outside_the_checked_range(monkeypatch):
    import numba

    from planar_mbs.kernel import jit

    monkeypatch.delenv(jit.PUBLIC_CACHE_ENV, raising=False)
    assert jit.fast_path_problem() is None  # the numba installed by pyproject's range
    monkeypatch.setattr(numba, "__version__", "0.69.0")
    assert "numba 0.69.0 is outside" in jit.fast_path_problem()
    monkeypatch.setattr(numba, "__version__", "0.61.2")  # its locators were `_UserProvidedCacheLocator`, ...
    assert "numba 0.61.2 is outside" in jit.fast_path_problem()


@pytest.mark.parametrize("module, name", [("numba.core.caching", "UserWideCacheLocator"),
                                          ("numba.core.caching", "Cache._load_overload"),
                                          ("numba.core.codegen", "CPUCodeLibrary._finalize_final_module"),
                                          ("llvmlite.binding", "ObjectFileRef")])
def test_fast_path_problem_names_a_missing_private_attribute(monkeypatch, module, name):
    import importlib

    from planar_mbs.kernel import jit

    monkeypatch.delenv(jit.PUBLIC_CACHE_ENV, raising=False)
    owner = importlib.import_module(module)
    *path, attr = name.split(".")
    for part in path:
        owner = getattr(owner, part)
    monkeypatch.delattr(owner, attr)
    problem = jit.fast_path_problem()
    assert problem.startswith(f"no {module}.{name}") and "fast loading" in problem


def test_the_public_cache_folder_is_named_after_every_kernel_source(monkeypatch, tmp_path):
    """numba's public cache checks only each kernel's own file: its folder holds SOURCE_HASH, so a
    time loop compiled with another contact law is never found there."""
    from planar_mbs.kernel import jit

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert jit._public_cache_dir() == str(tmp_path / f"planar_mbs-{jit.source_hash()[:16]}")


def _mbs(code: str, args: list[str], env: dict, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=1800,
                          env=env, **kw)


def _slider_x(path: Path) -> np.ndarray:
    return np.asarray(planar_mbs.read_results(path)["slider.x"])


@pytest.mark.slow
def test_hidden_private_class_falls_back_to_numba_public_cache_with_the_same_results(tmp_path):
    """With a private class of numba missing, `mbs run` of the slider-crank says so in one line,
    compiles through numba's public cache (in a folder named after the sources) and gives the
    fast path's results bit for bit; a second run loads them from that cache."""
    from planar_mbs.kernel.jit import SOURCE_HASH

    args = ["run", str(ROOT / "models" / "slider_crank.mbs"), "--t-end", "3ms"]
    env = {k: v for k, v in os.environ.items() if k != "PLANAR_MBS_PUBLIC_CACHE"}
    fast = _mbs(MBS, args + ["-o", str(tmp_path / "fast.h5")], env)
    assert fast.returncode == 0, fast.stderr
    assert "note:" not in fast.stderr
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "cache")
    cached = {}
    for run in range(2):
        slow = _mbs(MBS_HIDDEN, args + ["-o", str(tmp_path / f"public{run}.h5")], env)
        assert slow.returncode == 0, slow.stderr
        notes = [line for line in slow.stderr.splitlines() if line.startswith("note:")]
        assert len(notes) == 1 and "UserWideCacheLocator" in notes[0] and "public cache" in notes[0], slow.stderr
        assert "Traceback" not in slow.stderr and "internal error" not in slow.stderr
        assert np.array_equal(_slider_x(tmp_path / f"public{run}.h5"), _slider_x(tmp_path / "fast.h5"))
        files = {p: p.stat().st_mtime_ns for p in (tmp_path / "cache").glob("planar_mbs-*/**/*") if p.is_file()}
        assert files and (run == 0 or files == cached)  # the second run compiled nothing: nothing written
        cached = files
    # (first_compile's helper process, which compiles part of the kernels, runs without the hidden class)
    assert [p.name for p in (tmp_path / "cache").glob("planar_mbs-*")] == [f"planar_mbs-{SOURCE_HASH[:16]}"]
    # the slider of an ideal slider-crank (crank 0.05 m, rod 0.12 m) at the crank's angle
    res = planar_mbs.read_results(tmp_path / "public1.h5")
    phi = np.asarray(res["crank.phi"])
    closed = 0.05 * np.cos(phi) + np.sqrt(0.12 ** 2 - (0.05 * np.sin(phi)) ** 2)
    assert np.max(np.abs(np.asarray(res["slider.x"]) - closed)) < 1e-9


def _read_only_tree(base: Path) -> Path:
    """A copy of the package and the slider-crank model with every file and folder read-only."""
    tree = base / "install"
    shutil.copytree(Path(planar_mbs.__file__).resolve().parent, tree / "planar_mbs",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "models" / "slider_crank.mbs", tree)
    for p in [tree, *tree.rglob("*")]:
        p.chmod(0o555 if p.is_dir() else 0o444)
    return tree


# TMPDIR the temporary folder even where it cannot be written (tempfile would look for another)
MBS_TMP = "import os, tempfile; tempfile.tempdir = os.environ['TMPDIR']; " + MBS
# root writes into read-only folders: for root, the folders are mounted read-only in a mount namespace
READ_ONLY = 'for d in $RO_FOLDERS; do mount --bind "$d" "$d" && mount -o remount,bind,ro "$d" "$d" || exit 99; done; ' \
            'exec "$@"'


def _read_only_run(cmd: list[str], folders: list[Path], env: dict, cwd: Path) -> subprocess.CompletedProcess:
    if os.geteuid() == 0:
        if shutil.which("unshare") is None:
            pytest.skip("root writes into read-only folders, and unshare is missing")
        cmd = ["unshare", "-m", "sh", "-c", READ_ONLY, "sh", *cmd]
        env = {**env, "RO_FOLDERS": " ".join(str(f) for f in folders)}
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=1800, env=env, cwd=cwd)
    assert res.returncode != 99, f"mounting read-only failed: {res.stderr}"
    return res


@pytest.mark.slow
def test_read_only_install_without_a_writable_cache_folder_runs(tmp_path):
    """A read-only install whose user cache folder and NUMBA_CACHE_DIR cannot be written either:
    `mbs run` keeps the compiled kernels in a folder of the temporary directory (one line says
    where; a second run loads them from there), and with no writable temporary folder either it
    compiles them uncached (one line says so); never numba's "cannot cache function"."""
    tree = _read_only_tree(tmp_path)
    locked, scratch, out = tmp_path / "locked", tmp_path / "tmp", tmp_path / "out"
    for folder in (locked, scratch, out):
        folder.mkdir()
    (locked / "numba").mkdir()
    locked.chmod(0o555)
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": str(locked / "numba"),
           "XDG_CACHE_HOME": str(locked), "HOME": str(locked)}
    env.pop("PLANAR_MBS_PUBLIC_CACHE", None)
    results, cached = [], {}
    try:
        for run, tmpdir in enumerate((scratch, scratch, locked)):
            cmd = [sys.executable, "-c", MBS_TMP, "run", "slider_crank.mbs", "--t-end", "2ms", "-o", str(out / f"{run}.h5")]
            res = _read_only_run(cmd, [tree, locked], {**env, "TMPDIR": str(tmpdir)}, tree)
            assert res.returncode == 0, res.stderr
            assert "Traceback" not in res.stderr and "internal error" not in res.stderr
            notes = [line for line in res.stderr.splitlines() if line.startswith("note:")]
            if tmpdir == scratch:
                assert len(notes) == 1 and str(scratch / "planar_mbs-numba-") in notes[0], res.stderr
            else:
                assert len(notes) == 1 and "uncached" in notes[0], res.stderr
            results.append(_slider_x(out / f"{run}.h5"))
            files = {p: p.stat().st_mtime_ns for p in scratch.rglob("*") if p.is_file()}
            assert files and (run != 1 or files == cached)  # the second run loaded the kernels: nothing written
            cached = files
    finally:
        for p in [tree, *tree.rglob("*"), locked]:
            p.chmod(0o755 if p.is_dir() else 0o644)
    assert np.array_equal(results[0], results[1]) and np.array_equal(results[0], results[2])
    assert [p.name.split("-")[:2] for p in scratch.iterdir()] == [["planar_mbs", "numba"]]
    assert not any(tree.rglob("__pycache__")) and not any(locked.rglob("*.nbi"))
