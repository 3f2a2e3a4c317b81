"""Child processes that end with the process that started them (the compile helper, the sweep's
fork server and workers)."""
from __future__ import annotations

import ctypes
import os
import signal
from pathlib import Path

PACKAGE_ENV = ("PYTHONSAFEPATH", "PYTHONPATH")  # the variables `package_env` sets


def die_with_parent() -> bool:
    """Have the kernel send SIGKILL to this process when its parent process ends (prctl
    PR_SET_PDEATHSIG); False where that does not exist (not Linux)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL, 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return False
    return True


def package_env() -> dict[str, str]:
    """Environment variables with which a child Python imports this very package: the folder holding
    it first on PYTHONPATH, and not the current folder (PYTHONSAFEPATH), which ``python -m`` and
    ``python -c`` (multiprocessing's fork server, whose own path is applied only after its preload in
    CPython 3.11-3.13) put first: from a folder holding another ``planar_mbs`` (a source checkout
    beside an installed release) the child ran that copy (35 s of compiling it, measured)."""
    here = str(Path(__file__).resolve().parents[2])
    return {"PYTHONSAFEPATH": "1",
            "PYTHONPATH": os.pathsep.join(filter(None, [here, os.environ.get("PYTHONPATH")]))}
