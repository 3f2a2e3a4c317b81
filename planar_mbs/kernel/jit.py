"""The one decorator of every kernel: ``@kernel``.

* ``cache=True``: compiled code is stored next to the sources and reused by
  later processes.  When the package directory is not writable (a read-only or
  system install) numba falls back to the user's cache directory
  (``~/.cache/numba`` or ``$XDG_CACHE_HOME/numba``); ``NUMBA_CACHE_DIR`` chooses
  one explicitly.  Numba checks only each kernel's own source file: after
  editing a module other kernels depend on, delete ``kernel/__pycache__``.
  First compilation of all kernels: about 30 s (docs/benchmarks.md).
* ``error_model="numpy"``: a division by zero gives inf/NaN, which the time
  loop reports as a non-finite state, instead of raising inside compiled code.
* ``_nrt=False``: no numba runtime reference counting.  The kernels never
  allocate (workspaces are made once in Python), and with the runtime on,
  every call between kernels increfs and decrefs each array of the ~25-array
  `KernelModel` and the workspace with atomic operations: measured 5.4 µs per
  right-hand side of Muvengei et al.'s slider-crank with it, 0.9 µs without.
"""
from numba import njit

kernel = njit(cache=True, error_model="numpy", _nrt=False)
