"""How many output rows and bytes a run will write, known before it starts.

A typo in ``output_step`` (1e-6 µs for 1 µs) asks for 10^8 rows or more; 1e-300 µs for 10^303.
`estimate` counts them from ``t_end`` and ``output_step``; `check_output` refuses (exit 2, before
anything runs) a run beyond `MAX_ROWS` rows or larger than the free space of the disk it writes to,
unless the user insists (``--force``).  `mbs check` prints the estimate.
"""
from __future__ import annotations

import math
import shutil
from dataclasses import dataclass
from pathlib import Path

from ..errors import ModelError
from ..results.signals import signal_table

MAX_ROWS = 10**8  # output rows of one run beyond which we ask the user to insist (about 5 GB per 8 signals)
ROW_BYTES = 8  # float64 per signal per row
CHUNK_ROWS = 4096  # rows per HDF5 chunk of a run's datasets (results.ResultsWriter.CHUNK)
GRID_TOL = 1e-9  # as the time loop: an output time this close (in output steps) to t_end is t_end's row


@dataclass(frozen=True)
class OutputEstimate:
    rows: float  # output rows (may be astronomically large: a float)
    columns: int  # datasets written per row: time and every signal
    t_end: float
    output_step: float

    @property
    def bytes(self) -> float:
        """Uncompressed size of a run's results file: the data in whole chunks of `CHUNK_ROWS` rows
        (as `results.ResultsWriter` stores it) and HDF5's per-dataset overhead."""
        chunks = math.ceil(self.rows / CHUNK_ROWS) if math.isfinite(self.rows) else math.inf
        return chunks * CHUNK_ROWS * self.columns * ROW_BYTES + self.columns * 4096 + (1 << 16)

    def describe(self) -> str:
        return (f"{_count(self.rows)} output rows (t_end = {self.t_end:.6g} s every {self.output_step:.6g} s) "
                f"× {self.columns} columns ≈ {_size(self.bytes)}")


def estimate(model, settings, columns: int | None = None) -> OutputEstimate:
    """The rows and file size of a run of `model` with `settings` (`simulation.run_settings`)."""
    t_end, dt = float(settings.t_end), float(settings.output_step)
    ratio = t_end / dt if dt > 0 else math.inf
    if not math.isfinite(ratio):
        rows = math.inf
    elif ratio <= 0:
        rows = 1
    else:  # the grid t = k * output_step up to t_end, and a last row at t_end when it is off the grid
        n = math.floor(ratio + GRID_TOL)
        rows = n + 1 + (1 if ratio - n > GRID_TOL else 0)
    if columns is None:
        columns = len(signal_table(model)) + 1
    return OutputEstimate(float(rows), columns, t_end, dt)


def free_bytes(path: str | Path) -> float:
    """Free space where `path` would be written (its first existing parent folder).  The file it
    replaces is not counted: it stays until the new one, written beside it, is moved into place.
    Infinite when the disk cannot be asked."""
    p = Path(path).absolute()
    replaced = 0
    folder = p.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    try:
        return shutil.disk_usage(folder).free + replaced
    except OSError:
        return math.inf


def check_output(est: OutputEstimate, path: str | Path | None, source: str = "", count: int = 1,
                 force: bool = False) -> None:
    """Refuse (`ModelError`, exit 2) `count` runs of `est` that ask for more than `MAX_ROWS` rows
    each, or more bytes than the disk holding `path` has free; ``force`` lets them through."""
    if force:
        return
    hint_step = "check `output_step` and `t_end` in the simulate block (a unit typo?)"
    if est.rows > MAX_ROWS:
        raise ModelError(f"the run would write {est.describe()}, beyond the limit of {_count(MAX_ROWS)} rows",
                         source,
                         hint=f"{hint_step}; pass --force to run it anyway")
    if path is not None:
        total, free = est.bytes * count, free_bytes(path)
        if total > free:
            what = f"{count} cases of " if count > 1 else ""
            raise ModelError(f"the results ({what}{est.describe()}; {_size(total)} in all) do not fit on the disk "
                             f"holding {path} ({_size(free)} free)", source,
                             hint=f"write elsewhere (-o), make room or {hint_step}; pass --force to run it anyway "
                                  "(it stops cleanly when the disk is full)")


def _count(n: float) -> str:
    if not math.isfinite(n):
        return "infinitely many"
    return f"{n:,.0f}" if n < 1e12 else f"{n:.3g}"


def _size(nbytes: float) -> str:
    if not math.isfinite(nbytes):
        return "an infinite size"
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}" if nbytes < 1e15 else f"{nbytes / 1e12:.3g} TB"
    return f"{nbytes:.0f} B"
