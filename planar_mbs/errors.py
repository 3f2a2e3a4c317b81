"""Errors users see: a bad model (exit code 2) and a failed simulation (exit code 3).

A `ModelError` carries the file, line and column of the offending text and a
hint; ``str(err)`` renders it the way a compiler would::

    models/bad.mbs:4:12: error: a mass was expected, got a length (3 m)
        body crank { mass = 3 m }
                            ^
    hint: write the mass in kg, e.g. `mass = 0.3 kg`
"""
from __future__ import annotations

import difflib
from pathlib import Path


MAX_SHOWN = 120  # characters of a long source line shown around the error


class MbsError(Exception):
    """Base of every error planar_mbs reports to users without a traceback."""

    exit_code = 1


class ModelError(MbsError):
    """The model text (or a `--set` override) is wrong; points at the place."""

    exit_code = 2

    def __init__(
        self,
        message: str,
        file: str = "",
        line: int = 0,
        column: int = 0,
        hint: str = "",
        source_line: str | None = None,
        width: int = 1,
    ):
        self.message = message
        self.file = file
        self.line = line
        self.column = column
        if not hint and line > 0:  # every positioned error carries a hint, if only where to look
            hint = "docs/language.md describes every statement, field and unit"
        self.hint = hint
        self.width = max(1, width)
        if source_line is None and file and line > 0:
            source_line = _read_line(file, line)
        self.source_line = source_line
        super().__init__(self.render())

    def render(self) -> str:
        where = ""
        if self.file:
            where = f"{self.file}:{self.line}:{self.column}: " if self.line else f"{self.file}: "
        message = self.message if len(self.message) <= 4 * MAX_SHOWN else \
            self.message[:2 * MAX_SHOWN] + " … " + self.message[-MAX_SHOWN:]  # never a megabyte of it
        text = f"{where}error: {message}"
        if self.source_line is not None and self.line:
            line = self.source_line.rstrip("\n").expandtabs(1)
            col, width = max(0, self.column - 1), self.width
            if len(line) > MAX_SHOWN:  # a window around the column, not a 5 MB line
                start = max(0, min(col - MAX_SHOWN // 2, len(line) - MAX_SHOWN))
                window = line[start:start + MAX_SHOWN]
                lead = "…" if start > 0 else ""
                line = lead + window + ("…" if start + MAX_SHOWN < len(line) else "")
                col = col - start + len(lead)
                width = max(1, min(width, MAX_SHOWN - (col - len(lead))))
            line = "".join(c if c.isprintable() else "\ufffd" for c in line)  # NUL, ESC, ... shown as one mark
            text += f"\n    {line}\n    {' ' * col}{'^' * width}"
        if self.hint:
            text += f"\nhint: {self.hint}"
        return text

    def __str__(self) -> str:
        return self.render()


def as_warning(err: ModelError) -> str:
    """A `ModelError`'s text worded as a warning (``file:line:col: warning: ...``, its line, caret and
    hint): what the model says was taken, but may not be what was meant."""
    text = err.render()
    where = text.index("error: ")
    return text[:where] + "warning: " + text[where + len("error: "):]


class SimulationError(MbsError):
    """The time loop stopped before t_end; results up to `time` are kept."""

    exit_code = 3

    def __init__(self, message: str, time: float = float("nan"), results=None):
        self.message = message
        self.time = time
        self.results = results
        super().__init__(message)


def did_you_mean(name: str, candidates) -> str:
    """A hint naming the closest candidate(s), or '' when nothing is close."""
    if not isinstance(name, str):
        return ""
    close = difflib.get_close_matches(name, [c for c in candidates if isinstance(c, str)], n=3, cutoff=0.6)
    if not close:
        return ""
    if len(close) == 1:
        return f"did you mean `{close[0]}`?"
    return "did you mean " + ", ".join(f"`{c}`" for c in close[:-1]) + f" or `{close[-1]}`?"


def _read_line(file: str, line: int) -> str | None:
    try:
        lines = Path(file).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    return lines[line - 1] if 0 < line <= len(lines) else None
