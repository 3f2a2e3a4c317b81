"""What a scan's progress line says: cases done and failed, the CPU its cases get, and when it ends.

Fed by `run_sweep`'s ``progress(done, total, outcome)`` calls; knows nothing of how it is shown.
The estimate of the end uses only the cases finished in this call (a resumed scan's earlier cases
took no time here) and sharpens as they finish: until as many cases as there are workers have
finished, the mean wall time of a finished case divided among the workers (a first case that
finished says little about the rate of a pool that has several running); from then on the rate the
cases actually finished at since the first started, which also counts what the pool loses (a
machine shared with other work, the parent's gathering, cores that wait).  Cases run longest
expected first and equal ones in an order spread over the parameters (`scan.run_order`), so the
cases finished so far are a fair sample of those left.  Between two cases the estimate counts down
from the last one made (never below zero).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Optional


@dataclass
class ProgressTally:
    """Counts of a running scan; ``workers`` is the local pool's size (None on a cluster: unknown)."""

    workers: Optional[int] = None
    clock: Callable[[], float] = time.monotonic
    total: int = 0
    done: int = 0
    failed: int = 0
    ran: int = 0  # finished in this call
    cpu: float = 0.0  # CPU seconds of the cases finished in this call
    wall: float = 0.0  # their wall seconds, each in its worker
    started: Optional[float] = field(default=None)
    updated: Optional[float] = field(default=None)  # the clock at the last update

    def update(self, done: int, total: int, outcome=None) -> None:
        """One `run_sweep` progress call: the first (outcome None) starts the clock."""
        self.updated = self.clock()
        if self.started is None:
            self.started = self.updated
        self.done, self.total = done, total
        if outcome is None:
            return
        self.ran += 1
        self.failed += outcome.status != "finished"
        self.cpu += float(outcome.cpu_time or 0.0)
        self.wall += float(outcome.wall_time or 0.0)

    def elapsed(self) -> float:
        return 0.0 if self.started is None else self.clock() - self.started

    def cpu_share(self) -> Optional[float]:
        """CPU seconds per wall second of the finished cases in their workers (1.0: each had a core to itself)."""
        return self.cpu / self.wall if self.wall > 0 else None

    def remaining_seconds(self) -> Optional[float]:
        """Seconds until the last case finishes; None before any case finished in this call."""
        left = self.total - self.done
        if left <= 0:
            return 0.0
        if self.ran == 0:
            return None
        if self.workers and self.ran < self.workers:
            estimate = self.wall / self.ran * left / min(self.workers, left)
        else:
            estimate = (self.updated - self.started) / self.ran * left
        return max(estimate - (self.clock() - self.updated), 0.0)

    def line(self) -> str:
        """e.g. ``12/1000 cases, 1 failed, 2 workers at 97% CPU, 0:03:10 elapsed, about 4:12:00 left``."""
        parts = [f"{self.done}/{self.total} cases"]
        if self.failed:
            parts.append(f"{self.failed} failed")
        share = self.cpu_share()
        if share is not None:
            who = f"{self.workers} worker{'s' * (self.workers != 1)}" if self.workers else "cases"
            parts.append(f"{who} at {share:.0%} CPU")
        parts.append(f"{_clock(self.elapsed())} elapsed")
        left = self.remaining_seconds()
        parts.append("time left unknown until a case finishes" if left is None else f"about {_clock(left)} left")
        return ", ".join(parts)


def _clock(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"
