"""Edges that were reported as "internal error ... this is a bug": each is now a sentence with
exit 2 (the input or the environment is wrong) or 3 (a limit was reached), no traceback, and no
file that was not named as output changed."""
from __future__ import annotations

import os
import resource
import shutil
import subprocess
import time

import pytest

import planar_mbs as mbs_api
from advhelp import MBS, Outcome, assert_clean, mbs, snapshot
from planar_mbs.errors import ModelError


def _process(args, cwd, env=None, limit=None) -> Outcome:
    def preexec():
        if limit:
            resource.setrlimit(limit[0], (limit[1], limit[1]))

    start = time.perf_counter()
    proc = subprocess.run([str(MBS), *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=300,
                          env=dict(os.environ, COLUMNS="160", **(env or {})), preexec_fn=preexec)
    return Outcome(proc.returncode, proc.stdout + proc.stderr, time.perf_counter() - start)


def test_working_folder_deleted(sandbox):
    gone = sandbox / "gone"
    gone.mkdir()
    before = snapshot(sandbox)
    start = time.perf_counter()
    proc = subprocess.run(["sh", "-c", 'cd gone && rmdir ../gone && exec "$@"', "sh", str(MBS), "run",
                           str(sandbox / "mech.mbs"), "-q"], cwd=sandbox, capture_output=True, text=True, timeout=120)
    out = Outcome(proc.returncode, proc.stdout + proc.stderr, time.perf_counter() - start)
    assert_clean(out, 2, "working folder", before=before, folder=sandbox, allowed=["gone"])


def test_default_output_folder_cannot_be_made(sandbox, monkeypatch):
    """results/ cannot be created (a read-only folder; here mkdir is made to fail as it does there,
    since the tests may run as root): exit 2, as the README promises."""
    from pathlib import Path

    real = Path.mkdir

    def read_only(self, *args, **kwargs):
        if self.name == "results":
            raise PermissionError(13, "Permission denied", str(self))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", read_only)
    before = snapshot(sandbox)
    out = mbs("run", "mech.mbs", "-q", cwd=sandbox)
    assert_clean(out, 2, "cannot create the folder", "Permission denied", before=before, folder=sandbox)


def test_include_that_is_a_symlink_loop(sandbox):
    os.symlink("loop.mbs", sandbox / "loop.mbs")
    (sandbox / "inc.mbs").write_text('include "loop.mbs"\n')
    before = snapshot(sandbox)
    for command in (["check", "inc.mbs"], ["run", "inc.mbs", "-o", "x.h5"]):
        out = mbs(*command, cwd=sandbox)
        assert_clean(out, 2, "inc.mbs:1:1", "cannot follow the included file", before=before, folder=sandbox)


def test_too_few_open_files_for_a_sweep(sandbox):
    before = snapshot(sandbox)
    out = _process(["sweep", "mech.mbs", "-P", "speed=3000rpm,4000rpm", "-o", "s2.h5", "--t-end", "1ms", "-q"],
                   sandbox, limit=(resource.RLIMIT_NOFILE, 16))
    assert "Traceback" not in out.output and "internal error" not in out.output, out.output
    assert out.code in (0, 3), out.output
    if out.code == 3:
        assert "ulimit -n" in out.output
    assert not [k for k in set(before) | set(snapshot(sandbox)) if before.get(k) != snapshot(sandbox).get(k)
                and not k.startswith(("s2.h5", ".s2.h5", ".cases"))]


def test_unknown_matplotlib_backend(sandbox):
    before = snapshot(sandbox)
    out = _process(["plot", "run.h5", "-o", "figs"], sandbox, env={"MPLBACKEND": "nonsense"})
    assert_clean(out, 0, before=before, folder=sandbox, allowed=["figs"])
    assert any((sandbox / "figs").iterdir())


def test_numba_disabled(sandbox):
    before = snapshot(sandbox)
    out = _process(["run", "mech.mbs", "-o", "x.h5", "-q"], sandbox, env={"NUMBA_DISABLE_JIT": "1"})
    assert_clean(out, 2, "NUMBA_DISABLE_JIT", before=before, folder=sandbox)


@pytest.mark.parametrize("field,value", [("mass", "1e-320 kg"), ("inertia", "1e-310 kg*m^2")])
def test_subnormal_mass(sandbox, field, value):
    bodies = sandbox / "parts" / "bodies.mbs"
    text = bodies.read_text()
    old = "mass = 0.30 kg" if field == "mass" else "inertia = 1e-5 kg*m^2"
    bodies.write_text(text.replace(old, f"{field} = {value}", 1))
    before = snapshot(sandbox)
    out = mbs("run", "mech.mbs", "-o", "x.h5", "-q", cwd=sandbox)
    assert_clean(out, 2, "bodies.mbs:1:", "too small to compute with", before=before, folder=sandbox)


def test_compile_text_of_bytes_and_of_a_number():
    model = mbs_api.compile_text(b"body b { mass = 1 kg  inertia = 1 kg*m^2 }\n")  # the bytes of a file
    assert model.nbody == 1
    with pytest.raises(ModelError, match="takes the model's text"):
        mbs_api.compile_text(3)
    with pytest.raises(ModelError, match="UTF-8|utf-8|decode|encoding"):
        mbs_api.compile_text(b"body b { mass = 1 kg \xff\xfe }\n")


def test_analyze_with_a_period_far_below_the_output_step(sandbox):
    """--period 1e-12s used to try to allocate 1.46 TiB."""
    before = snapshot(sandbox)
    out = mbs("analyze", "run.h5", "--period", "1e-12s", cwd=sandbox, timeout=60)
    assert_clean(out, 2, "shorter than the output step", before=before, folder=sandbox, bound=30)


def test_dollars_in_a_model_name_are_not_mathtext(sandbox):
    name = "x$\\nope{$b.mbs"
    shutil.copy(sandbox / "mech.mbs", sandbox / name)
    out = mbs("run", name, "-o", "d.h5", "-q", cwd=sandbox)
    assert out.code == 0, out.output
    before = snapshot(sandbox)
    out = mbs("plot", "d.h5", "-o", "figs", cwd=sandbox)
    assert_clean(out, 0, before=before, folder=sandbox, allowed=["figs"])
