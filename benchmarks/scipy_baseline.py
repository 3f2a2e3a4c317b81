"""The scipy baseline: the clearance slider-crank with `scipy.integrate.solve_ivp`.

Written the straightforward way for the benchmark (not part of the library):
the right-hand side is `slider_crank_equations.rhs_numpy` (numpy, dense
Jacobian, `np.linalg.solve`), and the contact is handled the way solve_ivp
allows: a terminal event on the penetration ``delta`` (direction +1 in free
flight: onset; -1 in contact: separation), then a new `solve_ivp` call from the
event state with the other mode.  At an onset the impact velocity
``delta'(-)`` is computed from the event state (floored at 1e-5 m/s like the
library), so the Lankarani-Nikravesh law gets the located impact velocity, as
in planar_mbs.  Events are only detected when the sign of delta differs
between two step ends, and a segment starts *on* the switching surface
(delta = +-1e-18 after the root), so in smooth free flight solve_ivp's first
steps can jump across the whole gap and through the opposite wall unseen (it
did: the journal left the bearing).  The simple remedy solve_ivp offers is
``max_step``.  50 us was not enough: after an impact the journal bounces on the
same side with free flights of ~70 us, and a step from one separation to past
the next onset sees delta > 0 at both ends (events lost, journal escaped);
10 us (Muvengei et al.'s output step) finds every contact the library finds (77
switches in the benchmark horizon at rtol 1e-6, 75 at 1e-8; 76 for the library).
Differences that favour scipy: no interior samples (a grazing contact inside
one step is missed) and no outputs beyond the state are computed.
"""
from __future__ import annotations

import time

import numpy as np
from scipy.integrate import solve_ivp

from slider_crank_numpy import P_OMEGA, normal_velocity, penetration, rhs_numpy

IMPACT_VELOCITY_FLOOR = 1e-5
MAX_STEP = 10e-6


def run(y0, p, t_end, t_eval, method="RK45", rtol=1e-6, atol=1e-9):
    """Integrate; returns (times, states (n, 18), wall seconds, n_rhs, n_events)."""
    mode, vimp = 0, IMPACT_VELOCITY_FLOOR
    t, y = 0.0, np.array(y0, float)
    ts, ys = [], []
    nfev = 0
    nev = 0
    start = time.perf_counter()
    while t < t_end:
        sign = 1.0 if mode == 0 else -1.0

        def event(tt, yy, *args):
            return penetration(yy, p)

        event.terminal = True
        event.direction = sign
        grid = t_eval[(t_eval > t) | ((t_eval == t) & (t == 0.0))]
        grid = grid[grid <= t_end]
        sol = solve_ivp(rhs_numpy, (t, t_end), y, method=method, rtol=rtol, atol=atol, t_eval=grid,
                        events=event, args=(p, mode, vimp), max_step=MAX_STEP)
        nfev += sol.nfev
        ts.append(sol.t)
        ys.append(np.asarray(sol.y, float).reshape(len(y0), -1).T)  # an empty t_eval gives []
        if sol.status == 1 and len(sol.t_events[0]):
            t = float(sol.t_events[0][0])
            y = sol.y_events[0][0].copy()
            nev += 1
            if mode == 0:
                mode = 1
                vimp = max(normal_velocity(y, p), IMPACT_VELOCITY_FLOOR)
            else:
                mode = 0
        elif sol.status == 0:
            break
        else:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
    wall = time.perf_counter() - start
    return np.concatenate(ts), np.concatenate(ys), wall, nfev, nev


def main() -> None:
    """The baseline as a whole process: read the parameters and the assembled initial state
    (``--problem``, an .npz with ``p`` and ``y0`` written by `process.py` from the compiled model),
    integrate ``--revolutions`` crank revolutions with outputs every 10 us, save the states."""
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--problem", required=True)
    ap.add_argument("--revolutions", type=float, default=5.0)
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--method", default="RK45")
    ap.add_argument("-o", "--output", required=True)
    args = ap.parse_args()
    with np.load(args.problem) as f:
        p, y0 = f["p"], f["y0"]
    t_end = args.revolutions * 2 * np.pi / p[P_OMEGA]
    grid = np.arange(0.0, t_end * (1 + 1e-12), 10e-6)
    ts, ys, wall, nfev, nev = run(y0, p, t_end, grid, method=args.method, rtol=args.rtol, atol=1e-3 * args.rtol)
    np.savez(args.output, t=ts, y=ys)
    print(f"time loop {wall:.3f} s, {nfev} rhs, {nev} events")


if __name__ == "__main__":
    main()
