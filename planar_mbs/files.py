"""Files written whole or not at all: the one way the package puts a finished file in place.

Every output (results, sweep files and their journals, figures, recordings, the parser's cache) is
written beside its name first and moved over it by `replace_atomically`: a reader, a kill or a full
disk sees the earlier file or the new one, never half of one.  ``durable`` adds the flushes that make
the move survive a power cut too (the file's data before the rename, the folder's entry after it).
"""
from __future__ import annotations

import os
from pathlib import Path


def fsync_path(path: str | Path) -> None:
    """Flush a file's (or a folder's) data to the disk."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def replace_atomically(part: str | Path, final: str | Path, durable: bool = True) -> None:
    """Move the finished `part` over `final` in one step (``os.replace``); ``durable``: flushed first,
    and the folder's entry after."""
    if durable:
        fsync_path(part)
    os.replace(part, final)
    if durable:
        fsync_path(Path(final).parent)
