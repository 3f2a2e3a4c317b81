"""numba's IR inliner, made to copy a callee's variable scope once instead of once per block.

Each ``@kernel(inline=True)`` call site makes numba copy the callee's IR
(``InlineWorker.inline_ir``), one ``copy.deepcopy`` per block.  Every block refers to the function's
one ``Scope``, which holds every variable of the function, so each block's copy copies the whole
scope again: the work grows with blocks x variables, and the time loop's steps, which inline
other inlined kernels, are large in both (numba issue #8989, "Spurious deep copies in inlining",
open).  Measured on the first compilation of the clearance slider-crank in one process, two pairs
run side by side: 103.3 s and 97.9 s of CPU before, 84.8 s and 81.8 s after; results bit-identical
on every shipped model and three integrators (docs/benchmarks.md, "Start-up").

`apply` makes the block copies of one inlining share one ``deepcopy`` memo, so the copied blocks
share one copied scope, as the original blocks share one.  It touches two private names of numba
(`numba.core.inline_closurecall`'s ``copy`` module and ``InlineWorker.inline_ir``), so `kernel.jit`
applies it only where its other reliance on numba's internals was checked (``CHECKED_NUMBA``); elsewhere
numba inlines as it always does, slower.
"""
from __future__ import annotations

import copy
import threading

from numba.core import inline_closurecall, ir

_LOCAL = threading.local()  # .memo: the memo of the inlining under way in this thread, or None


class _SharedMemoCopy:
    """Stands in for the ``copy`` module inside numba's inliner: a block copied without a memo while
    an inlining is under way uses that inlining's memo; everything else is the ``copy`` module's."""

    def __getattr__(self, name):
        return getattr(copy, name)

    @staticmethod
    def deepcopy(x, memo=None):
        shared = getattr(_LOCAL, "memo", None)
        if memo is None and shared is not None and isinstance(x, ir.Block):
            memo = shared
        return copy.deepcopy(x, memo)


def _with_shared_memo(inline_ir):
    """`inline_ir` with one fresh memo for the copies it makes (restored after: inlinings nest)."""
    def shared_memo_inline_ir(self, *args, **kwargs):
        outer = getattr(_LOCAL, "memo", None)
        _LOCAL.memo = {}
        try:
            return inline_ir(self, *args, **kwargs)
        finally:
            _LOCAL.memo = outer
    shared_memo_inline_ir.original = inline_ir
    return shared_memo_inline_ir


def applicable() -> bool:
    """Whether numba's inliner has the two names `apply` replaces, in the form it expects."""
    worker = getattr(inline_closurecall, "InlineWorker", None)
    return getattr(inline_closurecall, "copy", None) is copy and callable(getattr(worker, "inline_ir", None))


def apply() -> bool:
    """Make numba's inliner share one memo per inlining (once per process); False where it cannot."""
    if is_applied():
        return True
    if not applicable():
        return False
    inline_closurecall.copy = _SharedMemoCopy()
    worker = inline_closurecall.InlineWorker
    worker.inline_ir = _with_shared_memo(worker.inline_ir)
    return True


def is_applied() -> bool:
    return isinstance(inline_closurecall.copy, _SharedMemoCopy)


def undo() -> None:
    """numba's own inliner again (tests compare the two)."""
    if is_applied():
        inline_closurecall.copy = copy
        worker = inline_closurecall.InlineWorker
        worker.inline_ir = worker.inline_ir.original
