"""Long runs clocked by the driver: a given number of revolutions, or until the motion settles.

`long_run` drives the compiled loop (`planar_mbs.run.stepper.Stepper`) one block of
revolutions at a time, so that it can report progress in revolutions, stop as
soon as the Poincaré points have settled (`planar_mbs.results.section.settling`), and
hand back the final kernel state (for a Lyapunov exponent from there, see
`planar_mbs.run.lyapunov`).  `run_until_settled` is `mbs run --until-settled`: that, with
the results written to a file.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ..mechanism.model import ST_CONTACT_EVENTS, ST_REJECTED, ST_RHS, ST_STEPS
from ..results.hdf5 import Results, write_beside
from ..results.section import driver_period, settling_of_results
from .simulation import signal_selection
from .stepper import Stepper

CHECK_EVERY = 50  # revolutions between two settling checks of a run --until-settled
PER_REV_UNTIL_SETTLED = 90  # output samples per revolution of a run until settled (`mbs run --until-settled`)


@dataclass
class LongRun:
    results: Results
    stepper: Stepper  # the final state
    period: float
    revolutions: int
    settled_at: int | None  # revolution from which the motion is settled (None: not settled)
    wall_time: float = 0.0  # s in the time loop and the settling checks


def long_run(model, revolutions: int, per_rev: int = 8, signals=None, *, until_settled: bool = False,
             min_revolutions: int = 200, progress: Callable[[int, int], None] | None = None,
             **settings) -> LongRun:
    """Run ``model`` for ``revolutions`` driver periods, ``per_rev`` output samples each
    (``until_settled``: stop at the first check, every `CHECK_EVERY` revolutions past
    ``min_revolutions``, where the section points have settled on a periodic orbit; chaotic
    motion runs to the end, since chaos can stop after hundreds of revolutions).  ``signals`` keeps only
    those signals (names or entities, as in `simulate`)."""
    found = driver_period(model)
    if found is None:
        raise ModelError("a run by revolutions needs a rotation driver at constant speed", model.source_path)
    period = found[0]
    st = Stepper(model, output_step=period / per_rev, t_end=revolutions * period, **settings)
    table, cols = signal_selection(model, signals, st.cfg)
    times, blocks = [], []
    settled, done = None, 0
    start = time.perf_counter()
    block = 10
    while done < revolutions:
        nxt = min(revolutions, done + block)
        t, rows = st.run_to(nxt * period)
        if len(times) and len(t) and t[0] <= times[-1][-1]:
            t, rows = t[1:], rows[1:]  # the segment start is the previous segment's last sample
        times.append(t)
        blocks.append(rows if cols is None else rows[:, cols])
        done = nxt
        if progress:
            progress(done, revolutions)
        if until_settled and done >= min_revolutions and done % CHECK_EVERY == 0:
            res = _results(model, table, times, blocks)
            settled = settling_of_results(res, model, periodic_only=True)
            if settled is not None:
                break
    res = _results(model, table, times, blocks)
    if settled is None:
        settled = settling_of_results(res, model, periodic_only=until_settled)
    return LongRun(res, st, period, done, settled, time.perf_counter() - start)


def run_until_settled(model, out, max_revolutions: int, progress: Callable[[int, int], None] | None = None,
                      overwrite: bool = False, **settings) -> LongRun:
    """`long_run` until the section settles (at most `max_revolutions`, `PER_REV_UNTIL_SETTLED`
    samples each), its results written to the file `out` with the run's statistics (`mbs run
    --until-settled`; ``overwrite`` and ``allow_unphysical`` as in `simulate`)."""
    run = long_run(model, max_revolutions, PER_REV_UNTIL_SETTLED, until_settled=True, progress=progress,
                   **settings)
    res, stats = run.results, run.stepper.stats
    res.attrs.update(t_reached=float(res.time[-1]), revolutions=run.revolutions, wall_time=run.wall_time,
                     settled_at=run.settled_at if run.settled_at is not None else -1,
                     n_steps=int(stats[ST_STEPS]), n_rejected=int(stats[ST_REJECTED]), n_rhs=int(stats[ST_RHS]),
                     n_contact_events=int(stats[ST_CONTACT_EVENTS]))
    if settings.get("allow_unphysical"):
        res.attrs["allow_unphysical"] = True
    write_beside(out, res, overwrite=overwrite, inputs=model.source_files)
    return run


def _results(model, table, times, blocks) -> Results:
    t = np.concatenate(times)
    rows = np.concatenate(blocks)
    return Results(time=t, signals={s.name: s.extract(rows) for s in table},
                   units={s.name: s.unit for s in table},
                   attrs={"parameters": model.parameters, "model_path": model.source_path,
                          "model_source": model.source_text, "complete": True})
