"""One writer per output name: a ``flock`` on a fixed file beside the output, ``.<name>.lock``.

Every writer of a results or sweep file takes it (a run, a merge, a sweep, a stored section):
the output itself is replaced by renames, so a lock on it would not exclude the writer of the
file that replaces it.  The lock file holds its holder's name for the message of the writer it
refuses, and goes when the holder releases it (a killed holder's file is taken by the next one).
"""
from __future__ import annotations

import fcntl
import os
import stat
import sys
from pathlib import Path


class OutputBusy(Exception):
    """Another writer holds the output; ``str()`` names it."""


def lock_path(output: Path) -> Path:
    output = Path(output)
    return output.with_name(f".{output.name}.lock")


def holder_name(kind: str) -> str:
    """``a sweep (mbs sweep, pid 123)``: what a refused writer is told."""
    prog = Path(sys.argv[0]).name if sys.argv and sys.argv[0] not in ("", "-c") else "python"
    if prog == "mbs" and len(sys.argv) > 1:
        prog = f"mbs {sys.argv[1]}"
    return f"{kind} ({prog[:60]}, pid {os.getpid()})"


def _holder(path: Path) -> str:
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        try:
            text = os.read(fd, 200).decode("utf-8", "replace")
        finally:
            os.close(fd)
    except OSError:
        text = ""
    text = "".join(c for c in text if c.isprintable()).strip()
    return text or "another process"


class OutputLock:
    """Exclusive ownership of the name ``output`` for one writer (`OutputBusy` if held); an
    `OSError` for a lock file that cannot be used (a link, a FIFO, another user's file)."""

    def __init__(self, output: Path, kind: str = "a run"):
        self.path = lock_path(output)
        self.fd = -1
        for _ in range(10):
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o600)
            info = os.fstat(fd)
            if not stat.S_ISREG(info.st_mode) or info.st_uid != os.geteuid():
                os.close(fd)
                raise OSError(0, f"its lock file {self.path} is not a regular file of this user")
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                raise OutputBusy(_holder(self.path)) from None
            if self._still_there(fd):
                self.fd = fd
                try:
                    os.ftruncate(fd, 0)
                    os.write(fd, holder_name(kind).encode())
                except OSError:
                    pass  # a full disk: the lock holds without its holder's name
                return
            os.close(fd)  # removed by its last holder meanwhile: take the new one
        raise OSError(0, f"its lock file {self.path} keeps disappearing")

    def _still_there(self, fd: int) -> bool:
        try:
            return os.lstat(self.path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            return False

    def release(self) -> None:
        """Remove the lock file (while still holding it), then drop the lock."""
        if self.fd < 0:
            return
        if self._still_there(self.fd):
            try:
                os.unlink(self.path)
            except OSError:
                pass
        os.close(self.fd)
        self.fd = -1
