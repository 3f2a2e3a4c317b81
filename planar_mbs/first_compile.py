"""The one-time compilation of the time loop, said out loud.

numba compiles the kernels the first time a model runs on a machine (about a minute of CPU,
longer on a busy one) and keeps the machine code in its cache; later runs load it in a fraction
of a second.  Without a word, that first minute looks like a hang.  `first_call` makes the
first call of `kernel.advance` in a process and, when numba's cache holds nothing for it, says
at once on stderr that the solver is being compiled, once, then how long it has taken: a line
rewritten every second on a terminal, a line every `LOG_EVERY` seconds in a plain log, and a
last line with the total.
"""
from __future__ import annotations

import sys
import threading
import time

LOG_EVERY = 15.0  # seconds between two "still compiling" lines in a plain log


def cache_is_cold(dispatcher) -> bool:
    """True when `dispatcher` (a `jit.kernel`) has no compiled version in this process and numba's
    cache holds none written from the current kernel sources (the index is keyed by their hash)."""
    if dispatcher.overloads:
        return False
    try:
        return not dispatcher._cache._cache_file._load_index()
    except Exception:  # noqa: BLE001  (an unreadable index: numba recompiles; say so)
        return True


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
        head = ("compiling the solver (numba, once: later runs load it from the cache in under a second; "
                "about a minute of CPU)")
        self._write(f"{head} ..." if self.tty else f"{head}\n")
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
    notice = _Notice(sys.stderr)
    notice.begin()
    ok = False
    try:
        result = dispatcher(*args)
        ok = True
    finally:
        notice.end(ok)
    return result
