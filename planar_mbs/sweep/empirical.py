"""A distribution "from a table": measured values, sampled through their empirical inverse CDF.

``--sample clearance=table(measured.csv, mm)`` reads the file once, when the study starts: one
number per line (``#`` comments, blank lines and one header line of words allowed), in the unit
given (none: plain numbers, for a parameter without a unit).  The values are stored, sorted, with
the study's design in the sweep file, so that a resumed study or a replayed case needs no file.

The inverse CDF is the piecewise-linear one through the order statistics (Hyndman and Fan,
"Sample quantiles in statistical packages", Am. Stat. 50 (1996), their definition 7, numpy's
default ``np.quantile``): with the n values sorted, x_(1) ≤ … ≤ x_(n), the probability u maps to
position h = (n − 1) u and to ``x_(⌊h⌋+1) + (h − ⌊h⌋) (x_(⌊h⌋+2) − x_(⌊h⌋+1))``.  So the sample lies in
[min, max], u = k/(n−1) gives the (k+1)-th smallest value exactly, and the p-th quantile of a large
sample is the table's p-th empirical quantile.  Ties stay: a value measured k times is k order
statistics, on which the inverse CDF is flat over (k − 1)/(n − 1) of the probability, so it is drawn
about k times as often as a value measured once; between two different values it interpolates
linearly (no value outside the measured range is drawn).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import ModelError
from ..mechanism.tables import MAX_TABLE_BYTES, is_number, read_table_file

MAX_VALUES = 2000  # stored in the sweep file's `study` attribute (HDF5 keeps attributes under 64 KiB)


def read_values(path: str | Path) -> np.ndarray:
    """The measured values of ``path`` (one a line), sorted; a bad file is a `ModelError` at its line."""
    try:
        data = read_table_file(Path(path))
    except OSError as err:
        raise ModelError(f"cannot read the table `{path}` of --sample ({err.strerror or err})", "--sample",
                         hint="the path is relative to the current folder") from None
    if len(data) > MAX_TABLE_BYTES:
        raise ModelError(f"the table `{path}` is larger than {MAX_TABLE_BYTES >> 20} MB", "--sample")
    return parse_values(data.decode("utf-8", errors="replace").removeprefix("\ufeff"), str(path))


def parse_values(text: str, path: str) -> np.ndarray:
    """One finite number per line; a header of words first and `#` comments allowed."""
    values, lines, first = [], text.splitlines(), True
    for i, raw in enumerate(lines, 1):
        line = raw.split("#", 1)[0].strip().rstrip(",;")
        if not line:
            continue

        def fail(message, hint):
            return ModelError(message, path, i, 1, hint=hint, source_line=raw, width=max(1, len(raw)))
        cells = [c for c in line.replace(";", ",").replace("\t", ",").replace(" ", ",").split(",") if c]
        number = [is_number(c) for c in cells]
        if first and not any(number):
            first = False
            continue  # a header
        first = False
        if len(cells) != 1:
            raise fail(f"a table of measured values holds one number a line, this one holds {len(cells)} cells",
                       "one measured value per line (a column of the measurements: write it to its own file)")
        if not number[0]:
            raise fail(f"`{cells[0]}` is not a number", "one measured value per line, e.g. `0.213`; only the "
                       "first line may be a header of words")
        v = float(cells[0])
        if not math.isfinite(v):
            raise fail("the table holds a value that is not a finite number (NaN or infinity)",
                       "remove the line, or fill in the measured value")
        values.append(v)
    if len(values) < 2:
        raise ModelError(f"a table of measured values needs at least two values ({len(values)} found)", path, 1, 1,
                         source_line=lines[0] if lines else "", hint="one measured value per line")
    if len(values) > MAX_VALUES:
        raise ModelError(f"a table of measured values holds at most {MAX_VALUES} values ({len(values)} found)",
                         path, 1, 1, source_line=lines[0] if lines else "",
                         hint="its quantiles describe it as well: keep every k-th of the sorted values")
    return np.sort(np.array(values))


def ppf(values, u) -> np.ndarray:
    """The inverse empirical CDF (definition 7 above) of the sorted ``values`` at probabilities ``u``."""
    x = np.asarray(values, float)
    return np.interp(np.asarray(u, float), np.linspace(0.0, 1.0, len(x)), x)


def variance(values) -> float:
    """The variance of the distribution `ppf` samples: ∫ Q² du − (∫ Q du)² over its linear pieces."""
    x = np.asarray(values, float)
    a, b = x[:-1], x[1:]
    w = 1.0 / (len(x) - 1)
    mean = w * float(np.sum((a + b) / 2))
    return w * float(np.sum((a * a + a * b + b * b) / 3)) - mean ** 2
