"""One right-hand side of the clearance slider-crank: the library's kernel against the
hand-specialised yardstick and the plain-numpy version of the same equations
(`slider_crank_equations`), after checking that all three agree to 1e-12.

    .venv/bin/python benchmarks/run.py --only rhs   # the section of docs/benchmarks.md
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
MODELS = ROOT / "models"


def section_rhs() -> dict:
    """Microseconds per rhs (library, hand, numpy) in free flight and in contact."""
    import planar_mbs as mbs
    import slider_crank_equations as E
    from numba import njit

    from planar_mbs.kernel import make_workspace
    from planar_mbs.kernel.dynamics import rhs
    from planar_mbs.mechanism.kinematics import assemble
    from planar_mbs.mechanism.model import N_STATS

    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    km, cfg = model.kernel, model.settings.cfg()
    p = E.parameters(model)

    @njit(cache=False)
    def loop_lib(km, cfg, y, contact, ws, stats, ydot, n):
        s = 0.0
        for i in range(n):
            rhs(km, cfg, 1e-3 + 1e-12 * i, y, contact, ws, stats, ydot)
            s += ydot[10]
        return s

    @njit(cache=False)
    def loop_hand(y, p, mode, vimp, S, r, ydot, n):
        s = 0.0
        for i in range(n):
            E.rhs_hand(1e-3 + 1e-12 * i, y, p, mode, vimp, S, r, ydot)
            s += ydot[10]
        return s

    q, qd = assemble(model)
    y_free = np.concatenate([q, qd])
    # a penetrating state: push the journal 20 um into the wall along +x
    y_contact = y_free.copy()
    y_contact[3] += p[E.P_C] + 20e-6
    assert E.penetration(y_contact, p) > 0
    ws = make_workspace(km)
    st = np.zeros(N_STATS, np.int64)
    S, r = np.zeros((7, 7)), np.zeros(7)
    out = {}
    for name, y, mode in (("free flight", y_free, 0.0), ("contact", y_contact, 1.0)):
        contact = np.array([[mode, 0.5, 0.0]])
        a, b = np.zeros(18), np.zeros(18)
        rhs(km, cfg, 1e-3, y, contact, ws, st, a)
        E.rhs_hand(1e-3, y, p, mode, 0.5, S, r, b)
        c = E.rhs_numpy(1e-3, y, p, mode, 0.5)
        agree = float(max(np.abs(a - b).max(), np.abs(a - c).max()) / np.abs(a).max())
        assert agree < 1e-12, agree
        n = 200_000
        loop_lib(km, cfg, y, contact, ws, st, a, 10)
        loop_hand(y, p, mode, 0.5, S, r, b, 10)
        tl = th = math.inf
        for _ in range(5):
            t0 = time.perf_counter()
            loop_lib(km, cfg, y, contact, ws, st, a, n)
            tl = min(tl, (time.perf_counter() - t0) / n)
            t0 = time.perf_counter()
            loop_hand(y, p, mode, 0.5, S, r, b, n)
            th = min(th, (time.perf_counter() - t0) / n)
        m = 2000
        t0 = time.perf_counter()
        for _ in range(m):
            E.rhs_numpy(1e-3, y, p, mode, 0.5)
        tn = (time.perf_counter() - t0) / m
        out[name] = dict(library=tl * 1e6, hand=th * 1e6, numpy=tn * 1e6, ratio=tl / th, agree=agree)
        print(f"  rhs {name}: library {tl * 1e6:.3f} us, hand {th * 1e6:.3f} us, numpy {tn * 1e6:.1f} us", flush=True)
    return out
