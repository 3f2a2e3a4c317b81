"""Child processes that end with the process that started them (the compile helper, the sweep's
fork server and workers)."""
from __future__ import annotations

import ctypes
import signal


def die_with_parent() -> bool:
    """Have the kernel send SIGKILL to this process when its parent process ends (prctl
    PR_SET_PDEATHSIG); False where that does not exist (not Linux)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL, 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return False
    return True
