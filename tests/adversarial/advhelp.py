"""What every adversarial case shares: a sandbox folder with a small model (split over an
include), a run of it and a sweep of it, the `mbs` command run in-process or as a real
process, and the three checks every case makes -- the exit code, a message without a
traceback, and that no file the user did not name as output changed."""
from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import signal
import stat
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from typer.testing import CliRunner

from planar_mbs.cli.app import app

REPO = Path(__file__).resolve().parents[2]
MODELS = REPO / "models"
MBS = Path(sys.executable).parent / "mbs"

# a slider-crank split over an include, short enough to run in a moment
PARTS = """\
body crank  { mass = 0.30 kg  inertia = 1e-5 kg*m^2    position = (0.025, 0)
              shape = bar(length = 50 mm, width = 10 mm) }
body rod    { mass = 0.21 kg  inertia = 2.5e-4 kg*m^2  position = (0.110, 0)
              shape = bar(length = 120 mm, width = 10 mm) }
body slider { mass = 0.14 kg  inertia = 1e-4 kg*m^2    position = (0.170, 0)
              shape = box(width = 30 mm, height = 15 mm) }
"""
MODEL = """\
param speed = 5000 rpm
include "parts/bodies.mbs"
joint O = revolute(ground (0, 0), crank (-0.025, 0))
joint A = revolute(crank (0.025, 0), rod (-0.06, 0))
joint B = revolute(rod (0.06, 0), slider (0, 0))
joint S = translational(ground, slider, axis = (1, 0))
driver crank_speed = rotation(crank, speed = speed)
simulate { t_end = 1 ms  integrator = rk4  step = 10 us  output_step = 100 us }
"""


def write_model(folder: Path) -> Path:
    (folder / "parts").mkdir(parents=True, exist_ok=True)
    (folder / "parts" / "bodies.mbs").write_text(PARTS)
    path = folder / "mech.mbs"
    path.write_text(MODEL)
    return path


# ---------------------------------------------------------------- running `mbs`
@dataclass
class Outcome:
    code: int
    output: str
    seconds: float
    exception: BaseException | None = None


_runner = CliRunner()
_command = None


def _built(app_):
    """typer rebuilds the click command of `app` on every invoke (0.1 s); build it once."""
    global _command
    if _command is None:
        import typer.main

        _command = typer.main.get_command(app_)
    return _command


def mbs(*args, cwd: Path | None = None, timeout: float = 20.0) -> Outcome:
    """`mbs ARGS` in this process (typer's CliRunner), inside `cwd`, with an alarm as a hang bound."""
    import typer.testing

    args = [str(a) for a in args]
    rebuild, typer.testing._get_command = typer.testing._get_command, _built
    try:
        with _chdir(cwd), deadline(timeout):
            start = time.perf_counter()
            res = _runner.invoke(app, args)
            seconds = time.perf_counter() - start
    finally:
        typer.testing._get_command = rebuild
    exc = res.exception if not isinstance(res.exception, SystemExit) else None
    if exc is not None:  # show the traceback the user would have seen
        import traceback

        text = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
        return Outcome(res.exit_code, res.output + "\nTraceback (most recent call last):\n" + text, seconds, exc)
    return Outcome(res.exit_code, res.output, seconds)


def mbs_process(*args, cwd: Path | None = None, timeout: float = 60.0) -> Outcome:
    """`mbs ARGS` as a real process (the installed entry point)."""
    start = time.perf_counter()
    proc = subprocess.run([str(MBS), *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, COLUMNS="160"))
    return Outcome(proc.returncode, proc.stdout + proc.stderr, time.perf_counter() - start)


@contextlib.contextmanager
def _chdir(folder):
    if folder is None:
        yield
        return
    old = os.getcwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(old)


class Hang(Exception):
    pass


@contextlib.contextmanager
def deadline(seconds: float):
    """Raise `Hang` in this thread after `seconds` (a bound for cases that once hung)."""
    def alarm(signum, frame):
        raise Hang(f"still running after {seconds} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


# ---------------------------------------------------------------- files before and after
def snapshot(folder: Path) -> dict[str, tuple]:
    """Every entry under `folder`: (kind, sha256 of a regular file's bytes | link target | mode)."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = Path(root) / name
            rel = str(p.relative_to(folder))
            info = os.lstat(p)
            if stat.S_ISREG(info.st_mode):
                out[rel] = ("file", hashlib.sha256(p.read_bytes()).hexdigest())
            elif stat.S_ISLNK(info.st_mode):
                out[rel] = ("link", os.readlink(p))
            elif stat.S_ISDIR(info.st_mode):
                out[rel] = ("dir",)
            else:
                out[rel] = ("other", stat.S_IFMT(info.st_mode))
    return out


def changed(before: dict, after: dict, allowed=()) -> list[str]:
    """Entries created, removed or changed, except those in `allowed` (and anything below them)."""
    allowed = [str(a).rstrip("/") for a in allowed]

    def free(rel: str) -> bool:
        return any(rel == a or rel.startswith(a + "/") for a in allowed)

    keys = set(before) | set(after)
    return sorted(k for k in keys if before.get(k) != after.get(k) and not free(k))


def assert_clean(out: Outcome, code: int, *words: str, before: dict | None = None, folder: Path | None = None,
                 allowed=(), bound: float | None = None) -> None:
    """The checks of every case: exit `code`, no traceback, each of `words` in the message, no
    file but `allowed` changed under `folder`, and (where a hang was possible) within `bound` s."""
    assert "Traceback" not in out.output, out.output
    assert out.exception is None, out.output
    assert out.code == code, f"exit {out.code}, expected {code}:\n{out.output}"
    text = " ".join(out.output.split()).lower()
    for w in words:
        assert " ".join(w.split()).lower() in text, f"{w!r} not in:\n{out.output}"
    if before is not None:
        diff = changed(before, snapshot(folder), allowed)
        assert not diff, f"files changed that were not named as output: {diff}\n{out.output}"
    if bound is not None:
        assert out.seconds < bound, f"took {out.seconds:.2f} s (bound {bound} s)"


# ---------------------------------------------------------------- awkward files
@contextlib.contextmanager
def fifo(path: Path, release_after: float = 3.0):
    """A FIFO at `path`.  Should a regression open it, a watchdog writes junk and closes it
    after `release_after` s, so the test fails on its time bound instead of hanging."""
    os.mkfifo(path)
    stop = threading.Event()

    def watchdog():
        if stop.wait(release_after):
            return
        fd = os.open(path, os.O_RDWR | os.O_NONBLOCK)  # never blocks on Linux
        try:
            os.write(fd, b"junk")
        finally:
            os.close(fd)

    t = threading.Thread(target=watchdog, daemon=True)
    t.start()
    try:
        yield path
    finally:
        stop.set()
        t.join()


def copy_tree(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst
