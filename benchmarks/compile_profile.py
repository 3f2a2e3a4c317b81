"""Where the kernels' first compilation goes: numba's compile events of one cold run, per kernel.

    NUMBA_CACHE_DIR=$(mktemp -d) .venv/bin/python benchmarks/compile_profile.py [integrator] [--numba-inliner]

Runs the clearance slider-crank for 2 ms in this process (the compile helper of
`planar_mbs.run.first_compile` switched off) and prints, per kernel, the wall time of its own
compilation (typing, lowering and LLVM, its callees' compilations subtracted) and the LLVM part, with
the process's CPU time.  An empty NUMBA_CACHE_DIR makes the run cold; on a busy machine compare
shares, not seconds.  ``--numba-inliner`` leaves numba's inliner as numba has it (without
`planar_mbs.kernel.inline_copy`), for the before/after of that change.
"""
from __future__ import annotations

import collections
import resource
import sys
import time
from pathlib import Path

from numba.core import event

MODEL = Path(__file__).resolve().parents[1] / "models" / "slider_crank_clearance_a.mbs"


class _Recorder(event.Listener):
    """Self time (callees' compilations subtracted) and LLVM time per compiled kernel."""

    def __init__(self):
        self.stack = []
        self.own = collections.Counter()
        self.llvm = collections.Counter()

    def on_start(self, ev):
        name = ev.data["dispatcher"].py_func.__qualname__ if ev.kind == "numba:compile" else None
        self.stack.append([name, time.perf_counter(), 0.0])

    def on_end(self, ev):
        name, t0, children = self.stack.pop()
        dt = time.perf_counter() - t0
        if name is not None:
            self.own[name] += dt - children
            if self.stack:
                self.stack[-1][2] += dt
        else:
            owner = next((s[0] for s in reversed(self.stack) if s[0] is not None), "?")
            self.llvm[owner] += dt


def main() -> None:
    rec = _Recorder()
    event.register("numba:compile", rec)
    event.register("numba:llvm_lock", rec)
    import planar_mbs as mbs
    from planar_mbs.kernel import inline_copy
    from planar_mbs.run import first_compile

    first_compile._start_helper = lambda: None
    args = [a for a in sys.argv[1:] if a != "--numba-inliner"]
    if len(args) < len(sys.argv) - 1:
        inline_copy.apply = lambda: False
    t0 = time.perf_counter()
    settings = {"integrator": args[0]} if args else {}
    mbs.simulate(mbs.load_model(MODEL), t_end="2 ms", **settings)
    ru = resource.getrusage(resource.RUSAGE_SELF)
    total = sum(rec.own.values())
    print(f"wall {time.perf_counter() - t0:.1f} s, CPU {ru.ru_utime + ru.ru_stime:.1f} s; "
          f"compilation {total:.1f} s of wall, LLVM {sum(rec.llvm.values()):.1f} s; "
          f"one scope copy per inlining: {inline_copy.is_applied()}")
    for name, own in rec.own.most_common(20):
        print(f"  {name:28s} {own:7.2f} s ({100 * own / total:4.1f} %)  LLVM {rec.llvm[name]:6.2f} s")


if __name__ == "__main__":
    main()
