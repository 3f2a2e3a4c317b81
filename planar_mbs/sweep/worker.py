"""Loaded once by a sweep before its workers exist (`warm_up` in the sweep's process, or the
preload of the fork server that `mbs sweep` starts at its first line, `sweep_server`; see
`sweep.default_executor`).  Importing this module loads the kernels.

Everything a case needs is loaded here, before any worker exists: numba, the kernels and their
compiled code (read from numba's cache by one short run of a small model), the analysis.  Each
worker is then a fork of this process and starts running cases at once, instead of paying that
start-up (most of a second to seconds) itself.  BLAS is kept to one thread per process: the
dense solves of one case are small, and two workers on two cores must not each start a pool.
Each worker keeps the memory it frees for its next case (`keep_freed_memory`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import ctypes
import os

from ..lazy import lazy
from .server import die_with_the_sweep

# Loaded by `warm_up`, after BLAS is limited to one thread (numpy reads it when imported) and the
# server is tied to the sweep (`die_with_the_sweep`): hence declared lazily.
h5py = lazy("h5py")  # a local pool's workers write their cases: `sweep.run_case_stored`
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from ..results import analysis
    from ..run import simulation
    from ..mechanism import compile as compiler
else:  # each loaded on its first use (see the comments: not on the light paths)
    analysis = lazy("..results.analysis", __package__)  # every case is classified
    simulation = lazy("..run.simulation", __package__)  # numba and the kernels
    compiler = lazy("..mechanism.compile", __package__)

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def keep_freed_memory() -> bool:
    """Called first in every worker of a local pool (`sweep.start_worker`), never in a process that
    does anything else: glibc's malloc then serves every allocation from the heap (M_MMAP_MAX = 0)
    and keeps what is freed there (M_TRIM_THRESHOLD = -1, no trimming), for the next case.

    A worker runs case after case of about the same size.  With glibc's defaults each case's large
    arrays were mapped afresh and unmapped at its end, so the kernel zeroed their pages again for
    every case: measured on the clearance slider-crank, 9,000-10,000 page faults and 15 ms in each
    0.15-s case of 30 revolutions, 31,000-38,000 faults in each 0.6-s case of 120 (whose time loop
    then took 0.56-0.67 s instead of 0.64-0.74 s); about 20 per case after the first now.  The
    worker's memory stays at its largest case, which the next case would map again anyway.  False
    (and nothing set) without glibc, or when the user tunes malloc through the environment."""
    if "malloc" in os.environ.get("GLIBC_TUNABLES", "") or any(v.startswith("MALLOC_") for v in os.environ):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    M_TRIM_THRESHOLD, M_MMAP_MAX = -1, -4  # malloc.h
    return bool(mallopt(M_MMAP_MAX, 0)) and bool(mallopt(M_TRIM_THRESHOLD, -1))


die_with_the_sweep()  # in `mbs sweep`'s fork server: end with the sweep, even while loading

WARM_MODEL = """
body crank { mass = 0.3 kg  inertia = 1e-5 kg*m^2  position = (0.025, 0) }
joint O = revolute(ground (0, 0), crank (-0.025, 0))
driver d = rotation(crank, speed = 100 rpm)
"""


_WARM: list[bool] = []  # this process has run `warm_up`


def warm_up() -> None:
    """Load the compiled kernels into this process (1 ms of a driven crank: every model runs the same
    compiled entry points, one signature for all) and the modules a case imports; once per process.
    Also usable for long-lived dask workers: ``client.run(warm_up)``."""
    if _WARM:
        return
    h5py.File, analysis.classify  # noqa: B018  (loaded now, before any worker exists)
    simulation.simulate(compiler.compile_text(WARM_MODEL, "<warm-up>"), t_end=1e-3)
    _WARM.append(True)


try:
    warm_up()
except Exception:  # noqa: BLE001  a fork server must not die of it: each case then meets it and reports it
    pass
