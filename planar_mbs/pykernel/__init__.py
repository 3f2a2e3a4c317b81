"""The kernels' source run as plain Python, without numba.

``planar_mbs.pykernel.constraints`` is ``planar_mbs/kernel/constraints.py`` executed a second time
as an ordinary module: this package's search path is the kernel directory, and its ``jit`` is a
stand-in whose ``kernel`` decorator returns the function unchanged.  The same source, so the same
equations.  Assembly of the initial pose (`kinematics.assemble`, hence `mbs check`) uses it: a
Newton iteration is a few hundred scalar operations, milliseconds in Python, while importing numba
and loading compiled kernels from its cache costs most of a second.  Nothing that runs per time step
belongs here.
"""
from __future__ import annotations

import sys
import types
from pathlib import Path

__path__ = [str(Path(__file__).resolve().parent.parent / "kernel")]


def _plain(fn=None, *, inline=False):
    return fn if fn is not None else _plain


jit = types.ModuleType(__name__ + ".jit", "`kernel` without numba: the function itself.")
jit.kernel = _plain
sys.modules[jit.__name__] = jit
