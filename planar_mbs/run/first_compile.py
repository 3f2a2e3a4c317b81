"""The one-time compilation of the time loop, said out loud.

numba compiles the kernels the first time a model runs on a machine (about 55 s of CPU, about
35 s on 2 idle cores, longer on a busy machine) and keeps the machine code in its cache; later runs
load it in a fraction of a second.  Without a word, that first half-minute looks like a hang.
`first_call` makes the first call of `kernel.advance` in a process and, when numba's cache holds
nothing for it, says at once on stderr that the solver is being compiled, once, then how long it has
taken: a line rewritten every second on a terminal, a line every `LOG_EVERY` seconds in a plain log,
and a last line with the total.  Meanwhile a helper process compiles the kernels the time loop's
typing reaches last (`HELPER_KERNELS`, the `kernel.jit.native` versions that `advance` calls), so
that this process loads them from the cache: measured on the README's first command 32-38 s of wall
time and 51-60 s of CPU in the two processes (2 idle cores: docs/benchmarks.md, "Start-up").
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import glob
import importlib
import inspect
import os
import subprocess
import sys
import tempfile
import threading
import time

from ..lazy import lazy
from .children import die_with_parent, package_env

# the helper's imports: numba and the compiler load only in the helper process, never before the
# "compiling" line (`announce_if_cold` runs before the model is read)
np = lazy("numpy")
numba = lazy("numba")
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from .. import kernel
    from ..kernel import jit
    from ..mechanism import compile as compiler
else:  # each loaded on its first use (see the comments: not on the light paths)
    kernel = lazy("..kernel", __package__)
    jit = lazy("..kernel.jit", __package__)
    compiler = lazy("..mechanism.compile", __package__)

LOG_EVERY = 15.0  # seconds between two "still compiling" lines in a plain log
HEAD = ("compiling the solver (numba, once: later runs load it from the cache in under a second; "
        "about a minute)")
_ANNOUNCED = False  # HEAD printed in this process


def announce_if_cold() -> None:
    """Print `HEAD` at once when no cached time loop exists anywhere numba keeps one (its index file,
    looked for without importing numba), before the model is even read: `mbs run` calls it first.
    A cache that exists but is stale is found by `first_call`, which then prints it."""
    global _ANNOUNCED
    if _ANNOUNCED or _index_files():
        return
    _ANNOUNCED = True
    try:
        _stderr().write(HEAD + "\n")
        _stderr().flush()
    except (OSError, ValueError):
        pass


def _index_files() -> list:
    """numba's index files of `kernel.loop.advance`: in the package (``__pycache__``), under
    ``NUMBA_CACHE_DIR`` or the user's cache folder (``<folder>_<hash>/`` subfolders), and in the other
    folders `kernel/jit.py` may choose (docs/install.md)."""
    chosen = os.environ.get("NUMBA_CACHE_DIR")  # numba then looks nowhere else
    if chosen:
        roots = [os.path.join(glob.escape(chosen), "kernel_*"),
                 os.path.join(glob.escape(chosen), "planar_mbs-*", "kernel_*")]  # jit.py's public cache
    else:
        user = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "numba")
        roots = [os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "kernel", "__pycache__"),
                 os.path.join(glob.escape(user), "kernel_*"),
                 os.path.join(glob.escape(user), "planar_mbs-*", "kernel_*")]  # jit.py's public cache
        try:  # a read-only install's private cache (jit.py), public or not
            private = os.path.join(glob.escape(tempfile.gettempdir()), f"planar_mbs-numba-{os.getuid()}")
            roots += [os.path.join(private, "kernel_*"), os.path.join(private, "planar_mbs-*", "kernel_*")]
        except (OSError, AttributeError):  # no temporary folder; no user ids (Windows)
            pass
    return [f for root in roots for f in glob.glob(os.path.join(root, "loop.advance-*.nbi"))]


def cache_is_cold(dispatcher) -> bool:
    """True when `dispatcher` (a `jit.kernel`) has no compiled version in this process and numba's
    cache holds none written from the current kernel sources (the index is keyed by their hash)."""
    if dispatcher.overloads:
        return False
    try:
        return not dispatcher._cache._cache_file._load_index()
    except Exception:  # noqa: BLE001  (an unreadable index: numba recompiles; say so)
        return True


def _stderr():
    return sys.stderr


class _Notice:
    """Prints the start line at once and the elapsed time from a thread until `stop`."""

    def __init__(self, stream):
        self.stream = stream
        self.tty = bool(getattr(stream, "isatty", lambda: False)())
        self.start = time.perf_counter()
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._tick, daemon=True)

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # a closed or broken stderr: the run goes on
            pass

    def begin(self) -> None:
        global _ANNOUNCED
        if not _ANNOUNCED:
            _ANNOUNCED = True
            self._write(HEAD + "\n")
        self.thread.start()

    def _tick(self) -> None:
        every = 1.0 if self.tty else LOG_EVERY
        while not self.done.wait(every):
            elapsed = time.perf_counter() - self.start
            if self.tty:
                self._write(f"\rcompiling the solver (numba, once) ... {elapsed:.0f} s")
            else:
                self._write(f"  still compiling the solver: {elapsed:.0f} s\n")

    def end(self, ok: bool) -> None:
        self.done.set()
        self.thread.join()
        elapsed = time.perf_counter() - self.start
        what = "compiled the solver" if ok else "compiling the solver stopped"
        self._write(("\r\x1b[K" if self.tty else "") + f"{what} in {elapsed:.0f} s\n")


def first_call(dispatcher, *args):
    """``dispatcher(*args)``, announced on stderr when it compiles (see the module docstring)."""
    if not cache_is_cold(dispatcher):
        return dispatcher(*args)
    notice = _Notice(_stderr())
    notice.begin()
    helper = _start_helper()
    ok = False
    try:
        result = dispatcher(*args)
        ok = True
    finally:
        if helper is not None:
            helper.kill()  # what it has not finished, this process compiled itself
            helper.wait()
        notice.end(ok)
    return result


# ---------------------------------------------------------------- a second process compiles what comes last
# The kernels that numba's typing of `advance` reaches last (order measured with numba's compile events
# on a cold cache): a helper process compiles them, the first one first, while this process compiles the
# time loop from its start; when the typing reaches one of them it loads it from the cache instead
# (`event_possible` and `initial_step` left the list when they were inlined at their one call site).
HELPER_KERNELS = (("loop", "_finish_step"), ("events", "locate_event"), ("integrators", "rk_stages"),
                  ("integrators", "fixed_step"))
# any model gives the kernels the same argument types (arrays of fixed dtype and rank)
_TINY = ("body crank { mass = 1 kg  inertia = 1 kg*m^2  position = (0.5, 0)  angle = 0 deg }\n"
         "joint O = revolute(ground (0, 0), crank (-0.5, 0))\n"
         "driver turn = rotation(crank, speed = 60 rpm)\n")


def _signature(dispatcher, km, ws) -> tuple:
    """numba argument types of `dispatcher` as `advance` calls it, from its parameter names."""
    typeof, types = numba.typeof, numba.types
    by_name = {"km": typeof(km), "ws": typeof(ws), "contact": typeof(np.zeros((1, 3))),
               "stats": typeof(np.zeros(1, np.int64)), "kend": types.int64, "method": types.int64,
               "first": types.int64, "last": types.int64}
    vector = typeof(np.zeros(1))
    return tuple(by_name.get(p, vector if p in ("cfg", "y", "ydot", "y0") else types.float64)
                 for p in inspect.signature(dispatcher.py_func).parameters)


def helper_main() -> None:
    """The helper process: compile `HELPER_KERNELS` into numba's cache; killed when its parent ends."""
    die_with_parent()
    km = compiler.compile_text(_TINY).kernel
    ws = kernel.make_workspace(km)
    for module, name in HELPER_KERNELS:
        # the version `advance` calls (`kernel.jit.native`), not the one Python calls
        dispatcher = jit.native(getattr(importlib.import_module(f"planar_mbs.kernel.{module}"), name))
        if cache_is_cold(dispatcher):
            dispatcher.compile(_signature(dispatcher, km, ws))


def _start_helper():
    """The helper process (None on one core or where it cannot start)."""
    if (os.cpu_count() or 1) < 2:
        return None
    try:  # this very package, not another copy in the current folder or installed elsewhere
        return subprocess.Popen([sys.executable, "-m", "planar_mbs.run.first_compile"], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                env=dict(os.environ, **package_env()))
    except OSError:
        return None


if __name__ == "__main__":
    helper_main()
