"""The first run on a machine says at once that it compiles the solver, and a second process
compiles the kernels the time loop's typing reaches last (`planar_mbs.run.first_compile`)."""
from __future__ import annotations

import importlib
import io
import time
from pathlib import Path

import pytest

from planar_mbs.kernel.jit import native
from planar_mbs.run import first_compile as F


class _FakeIndex:
    def __init__(self, entries):
        self.entries = entries

    def _load_index(self):
        return self.entries


class _FakeDispatcher:
    """Stands for a kernel whose first call compiles for `seconds`; records what stderr held then."""

    def __init__(self, stream, seconds=0.3, cached=False):
        self.overloads = {}
        self._cache = type("C", (), {"_cache_file": _FakeIndex({"sig": "x"} if cached else {})})()
        self.stream, self.seconds, self.seen = stream, seconds, None

    def __call__(self, *args):
        self.seen = self.stream.getvalue()
        time.sleep(self.seconds)
        self.overloads["sig"] = True
        return sum(args)


@pytest.fixture
def stderr(monkeypatch):
    stream = io.StringIO()
    monkeypatch.setattr(F, "_stderr", lambda: stream)
    monkeypatch.setattr(F, "_ANNOUNCED", False)
    monkeypatch.setattr(F, "_start_helper", lambda: None)
    return stream


def test_a_cold_cache_is_announced_before_compiling_and_timed(stderr, monkeypatch):
    monkeypatch.setattr(F, "LOG_EVERY", 0.1)
    d = _FakeDispatcher(stderr, seconds=0.35)
    assert F.first_call(d, 1, 2) == 3
    assert d.seen.startswith(F.HEAD + "\n")  # said before the compilation began
    lines = stderr.getvalue().splitlines()
    assert any(line.startswith("  still compiling the solver:") for line in lines)  # elapsed time in a log
    assert lines[-1].startswith("compiled the solver in ")
    before = stderr.getvalue()
    assert F.first_call(d, 1, 2) == 3 and stderr.getvalue() == before  # compiled: nothing more said


def test_a_warm_cache_says_nothing(stderr):
    d = _FakeDispatcher(stderr, seconds=0.0, cached=True)
    assert F.first_call(d, 2, 2) == 4 and stderr.getvalue() == ""


def test_announced_before_the_model_is_read_when_no_cache_exists(stderr, monkeypatch, tmp_path):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    F.announce_if_cold()
    assert stderr.getvalue() == F.HEAD + "\n"
    d = _FakeDispatcher(stderr, seconds=0.0)
    F.first_call(d, 1, 1)
    assert stderr.getvalue().count(F.HEAD) == 1  # said once


def test_no_early_notice_when_an_index_exists(stderr, monkeypatch, tmp_path):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    (tmp_path / "kernel_0123").mkdir()
    (tmp_path / "kernel_0123" / "loop.advance-388.py311.nbi").write_bytes(b"")
    F.announce_if_cold()
    assert stderr.getvalue() == ""


def test_the_helper_compiles_the_signatures_the_time_loop_uses():
    """Each kernel the helper compiles, with the argument types `_signature` gives it, is one the
    time loop's own compilation put in numba's cache (else the helper's work would be wasted)."""
    import planar_mbs as mbs
    from planar_mbs.mechanism.compile import compile_text
    from planar_mbs.kernel import make_workspace

    text = F._TINY + "simulate { t_end = 10 ms  output_step = 1 ms }\n"
    mbs.simulate(compile_text(text))  # compiles or loads the time loop (and writes the cache)
    km = compile_text(F._TINY).kernel
    ws = make_workspace(km)
    for module, name in F.HELPER_KERNELS:
        dispatcher = native(getattr(importlib.import_module(f"planar_mbs.kernel.{module}"), name))  # as `advance` calls it
        keys = [key[0] for key in dispatcher._cache._cache_file._load_index()]
        assert F._signature(dispatcher, km, ws) in keys, name


@pytest.mark.slow
def test_a_cold_mbs_run_says_so_first_and_the_helper_does_part_of_the_work(tmp_path):
    """`mbs run` with an empty numba cache: the notice is its first line of stderr, the last one before
    the summary gives the time taken, and the kernels of `HELPER_KERNELS` are in the cache."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    model = Path(__file__).resolve().parents[1] / "models" / "slider_crank.mbs"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    mbs = Path(sys.executable).with_name("mbs")
    res = subprocess.run([str(mbs), "run", str(model), "-q", "--t-end", "2 ms",
                          "-o", str(tmp_path / "a.h5")], capture_output=True, text=True, env=env, timeout=1800)
    assert res.returncode == 0, res.stderr
    lines = res.stderr.splitlines()
    assert lines[0] == F.HEAD and lines[-1].startswith("compiled the solver in "), res.stderr
    written = {p.name.split("-native-")[0] for p in (tmp_path / "cache").rglob("*-native-*.nbi")}
    for module, name in F.HELPER_KERNELS:  # the versions `advance` calls
        assert f"{module}.{name}" in written


def test_mbs_run_announces_before_reading_the_model(stderr, monkeypatch, tmp_path):
    """With no cached time loop, `mbs run` says it will compile before it even reads the model (the
    first line within a fraction of a second, whatever the model costs to load)."""
    from planar_mbs.mechanism import compile as C
    from planar_mbs.cli.run_command import run_model

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    seen = []

    def load(*args, **kwargs):
        from planar_mbs.errors import ModelError

        seen.append(stderr.getvalue())
        raise ModelError("stop here: nothing is compiled", "m.mbs")

    monkeypatch.setattr(C, "load_model", load)
    assert run_model(Path(__file__).resolve().parents[1] / "models" / "slider_crank.mbs") == 2
    assert seen == [F.HEAD + "\n"]


def test_the_helper_compiles_this_package_even_from_a_folder_holding_another(tmp_path, monkeypatch):
    """Started from a folder that holds another `planar_mbs` (a second checkout, an old copy), the
    helper still imports this one: `python -m` alone would put the current folder first, and the
    helper would compile the other copy's kernels, or nothing, while this process compiles alone."""
    marker = tmp_path / "imported-the-other-copy"
    for sub in ("planar_mbs", "planar_mbs/run"):
        (tmp_path / sub).mkdir()
        (tmp_path / sub / "__init__.py").write_text("")
    (tmp_path / "planar_mbs/run/first_compile.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    monkeypatch.chdir(tmp_path)
    helper = F._start_helper()  # this package's kernels are cached here: the real helper finds nothing to do
    assert helper is not None and helper.wait(timeout=120) == 0
    assert not marker.exists()
