"""What every `mbs` command shares: the exit codes, the console, user-facing errors,
`--set` pairs and values with units.  Imports nothing heavy (typer only in `fail`); the rest loads on use."""
from __future__ import annotations

import codecs
import errno
import os
import stat
import sys
import unicodedata
from enum import IntEnum
from pathlib import Path
from typing import Optional

from planar_mbs.errors import MbsError, ModelError, did_you_mean
from planar_mbs.language.units import parse_quantity
from planar_mbs.lazy import lazy
from planar_mbs.run.settings_check import MAX_T_END  # one bound for the CLI and the API
from planar_mbs.run.settings_check import check_number as checked

# on the light paths (`mbs check`, a plain `mbs run` that first says the solver compiles): loaded on use
rich_console = lazy("rich.console")
typer = lazy("typer")  # pydantic: the plain check and run never load it
compiler = lazy("planar_mbs.mechanism.compile")  # lark: only to read a model's includes
parser = lazy("planar_mbs.language.parse")


class ExitCode(IntEnum):
    OK = 0
    BAD_MODEL = 2
    SIMULATION_FAILED = 3
    INTERRUPTED = 130  # 128 + SIGINT; SIGTERM gives 143


# ---------------------------------------------------------------- standard streams
_ASCII = {"→": "->", "←": "<-", "λ": "lambda", "µ": "u", "μ": "u", "²": "^2", "³": "^3", "×": "x", "≈": "~",
          "…": "...", "—": "--", "–": "-", "°": " deg", "φ": "phi", "≤": "<=", "≥": ">=", "±": "+/-", "·": "*",
          "─": "-", "│": "|", "━": "-", "┃": "|", "•": "*", "✓": "ok", "✗": "x", "Δ": "d", "π": "pi", "ω": "w",
          "\ufffd": "?"}


def _to_ascii(err):
    """Codec error handler "mbs-ascii": a character the stream's encoding lacks is written in ASCII
    (→ as ->, µ as u, λ as lambda, accents dropped, anything else as ?)."""
    bad = err.object[err.start:err.end]
    out = []
    for ch in bad:
        plain = _ASCII.get(ch)
        if plain is None:
            plain = unicodedata.normalize("NFKD", ch).encode("ascii", "ignore").decode() or "?"
        out.append(plain)
    return "".join(out), err.end


class _GuardedStream:
    """stdout or stderr, whose failed writes (a closed stream, /dev/full, an I/O error) are noted
    instead of raised: the command finishes its work (its files are whole) and `stream_failure`
    says afterwards why the output was lost.  A broken pipe (the reader went away) is raised as
    before: the command stops at its next line of output."""

    def __init__(self, wrapped, name: str):
        self.wrapped, self.name, self.wrote = wrapped, name, False
        self.failure = "" if wrapped is not None else "it is closed"

    def _guard(self, call, *args):
        if self.wrapped is None:
            return None
        try:
            return call(*args)
        except OSError as exc:
            if exc.errno == errno.EPIPE:
                raise
            self.failure = self.failure or (exc.strerror or str(exc))
            return None
        except ValueError:  # closed
            self.failure = self.failure or "it is closed"
            return None

    def write(self, text):
        self.wrote = self.wrote or bool(text)
        if self.wrapped is None:
            return len(text)
        self._guard(self.wrapped.write, text)
        return len(text)

    def flush(self):
        if self.wrapped is not None:
            self._guard(self.wrapped.flush)

    def isatty(self) -> bool:
        return bool(self.wrapped is not None and self._guard(self.wrapped.isatty))

    def fileno(self):
        if self.wrapped is None:
            raise OSError(9, "stream closed")
        return self.wrapped.fileno()

    @property
    def encoding(self):
        return getattr(self.wrapped, "encoding", None) or "utf-8"

    def __getattr__(self, attr):
        return getattr(self.wrapped, attr)


def guard_streams() -> None:
    """Make stdout and stderr safe to write whatever happens to them: characters their encoding
    lacks degrade to ASCII (PYTHONIOENCODING=ascii, a C locale), and a closed stream or a full
    device (`>&-`, `>/dev/full`) is noted, not a traceback (`stream_failure`).  Called once by
    `entry.main`."""
    codecs.register_error("mbs-ascii", _to_ascii)
    for name in ("stdout", "stderr"):
        stream = getattr(sys, name)
        if isinstance(stream, _GuardedStream):
            continue
        try:
            if stream is not None and hasattr(stream, "reconfigure"):
                "→µλ".encode(stream.encoding or "utf-8")
        except (UnicodeError, LookupError):
            stream.reconfigure(errors="mbs-ascii")
        setattr(sys, name, _GuardedStream(stream, name))


def stream_failure() -> str:
    """Why the command's output could not be written to stdout ('' if it was, or nothing was)."""
    out = sys.stdout
    return f"cannot write the command's output: {out.failure}" if isinstance(out, _GuardedStream) and \
        out.failure and out.wrote else ""


STYLES = {"bold": "1", "yellow": "33"}


def say(text: str, *, stderr: bool = False, style: str = "") -> None:
    """Write one line as it is, in ``style`` on a terminal that takes colours (not under NO_COLOR or
    TERM=dumb): the run's summary and warnings, without loading rich (about 20 ms of a short run's start)."""
    stream = sys.stderr if stderr else sys.stdout
    if style and stream.isatty() and "NO_COLOR" not in os.environ and os.environ.get("TERM") != "dumb":
        text = f"\033[{STYLES[style]}m{text}\033[0m"
    stream.write(text + "\n")


def console(stderr: bool = False):
    stream = sys.stderr if stderr else sys.stdout
    width = None if stream.isatty() else 160  # no terminal (pipes, tests): do not cut names
    return rich_console.Console(stderr=stderr, highlight=False, width=width)


def fail_code(err) -> int:
    """Print a user-facing error (never a traceback); return its exit code."""
    code = err.exit_code if isinstance(err, MbsError) else ExitCode.BAD_MODEL
    console(stderr=True).print(str(err), markup=False, soft_wrap=True)  # never re-wrap: the caret must stay aligned
    return int(code)


def fail(err) -> None:
    """Print a user-facing error (never a traceback) and exit with its code."""
    raise typer.Exit(fail_code(err))


class Stopping:
    """The signal that is ending this command (set by the SIGTERM handler before it raises), or 0."""
    signum = 0


def internal_error(exc: Exception) -> int:
    """A bug's one-line report instead of a traceback (exit code 1); MBS_TRACEBACK=1 raises it instead.
    An error raised while SIGTERM was ending the command is that signal's exit (143), not a bug: C code
    that catches whatever its callback raised and raises its own error (numpy's comparison of structured
    arrays turns any exception into a TypeError) can swallow the handler's SystemExit."""
    if Stopping.signum:
        return 128 + Stopping.signum
    if os.environ.get("MBS_TRACEBACK"):
        raise exc
    limit = resource_limit(exc)
    if limit:
        console(stderr=True).print(limit, markup=False)
        return int(ExitCode.SIMULATION_FAILED)
    console(stderr=True).print(f"internal error: {type(exc).__name__}: {exc}\n"
                               "hint: this is a bug in planar_mbs; please report it with the command "
                               "(MBS_TRACEBACK=1 shows where it happened)", markup=False)
    return 1


def resource_limit(exc: BaseException) -> str:
    """The sentence for an error that is a limit of this machine or process, not a bug (too many
    open files, no memory, a full disk, a file-size limit); '' for anything else.  Exit code 3."""
    if isinstance(exc, MemoryError):
        return ("error: not enough memory for this command\nhint: free memory, or ask for less (a shorter "
                "t_end, a larger output step, fewer cases at once: -j)")
    if not isinstance(exc, OSError):
        return ""
    hints = {
        errno.EMFILE: "this process may open too few files (`ulimit -n`); raise the limit, e.g. `ulimit -n 1024`, "
                      "or run fewer jobs at once (-j)",
        errno.ENFILE: "the system has too many open files; close some programs and run again",
        errno.ENOSPC: "the disk is full; free some space or write elsewhere (-o)",
        errno.EDQUOT: "the disk quota is used up; free some space or write elsewhere (-o)",
        errno.EFBIG: "a file reached the file-size limit of this process (`ulimit -f`); raise it or write less",
        errno.ENOMEM: "free memory, or ask for less",
    }
    if exc.errno not in hints:
        return ""
    return f"error: {exc.strerror or exc}\nhint: {hints[exc.errno]}"


def parse_sets(sets: list[str]) -> dict[str, str]:
    """`--set NAME=VALUE` pairs (VALUE keeps its units, e.g. `speed=2500rpm`)."""
    overrides = {}
    for item in sets:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise ModelError(
                f"`--set {item}` is not NAME=VALUE", "--set",
                hint="write e.g. `--set speed=2500rpm` or `--set \"clearance=0.1 mm\"`",
            )
        overrides[name.strip()] = value.strip()
    return overrides


def quantity(text: Optional[str], dimension: str, option: str) -> Optional[float]:
    if text is None:
        return None
    return parse_quantity(text, dimension, where=option)


# ---------------------------------------------------------------- option values, checked before anything runs
MAX_JOBS = 1024
MAX_REVOLUTIONS = 1e7  # driver periods of one run


def _option_error(option: str, message: str, hint: str):
    return ModelError(message, option, hint=hint)


def check_number(value: Optional[float], option: str, *, low: Optional[float] = None, high: Optional[float] = None,
                 low_ok: bool = False, high_ok: bool = True, hint: str = "") -> Optional[float]:
    """`value` if it is a finite number in the interval (low, high] (``low_ok``/``high_ok``
    close or open either end); None passes.  Raises `ModelError` naming the option otherwise
    (worded as the Python API words its settings: `planar_mbs.run.settings_check`)."""
    return checked(value, option, low=low, high=high, low_ok=low_ok, high_ok=high_ok, hint=hint)


def positive_time(text: Optional[str], option: str, high: float = MAX_T_END) -> Optional[float]:
    """A time option with units (`60ms`, "0.06 s"): finite, > 0 and at most `high` seconds."""
    value = quantity(text, "time", option)
    return check_number(value, option, low=0.0, high=high,
                        hint=f"give a positive time with units, e.g. `{option} 60ms`"
                             + (f" (at most {high:g} s)" if high is not None else ""))


def check_rtol(value: Optional[float], option: str = "--rtol") -> Optional[float]:
    """A relative tolerance: 0 < rtol < 1."""
    return check_number(value, option, low=0.0, high=1.0, high_ok=False,
                        hint=f"a relative tolerance lies between 0 and 1, e.g. `{option} 1e-8`")


def check_choice(value: Optional[str], choices, option: str) -> Optional[str]:
    """`value` (lower-cased) if it is one of `choices`; else a `ModelError` with a did-you-mean."""
    if value is None:
        return None
    if value.lower() in choices:
        return value.lower()
    close = did_you_mean(value, choices)
    raise _option_error(option, f"unknown {option} `{value}`",
                        (close + " " if close else "") + "choose " + ", ".join(choices))


# ---------------------------------------------------------------- files: never write over an input
def same_file(a, b) -> bool:
    """True if `a` and `b` are the same file: same inode (symlinks, hard links) or, for files
    that do not exist yet, the same path once symlinks in it are resolved."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def check_output(path, option: str, inputs=(), others=(), folder: bool = False, make_parents: bool = False) -> None:
    """Refuse, before anything runs, an output that would overwrite an input (compared as files),
    that names the same file as another output, or that cannot be written: a folder (or, with
    `folder`, a file), a FIFO or device, a missing or read-only parent folder.

    ``inputs`` and ``others`` are (description, path) pairs; `make_parents`: missing folders are
    made by the command (as `results/`), so the first existing one is checked instead."""
    path = Path(path)
    shown = f"{option} {path}"
    for what, other in inputs:
        if other is not None and os.path.lexists(path) and same_file(path, other):
            raise _option_error(option, f"`{shown}` is {what}: writing there would destroy it",
                                "choose another output file")
    for what, other in others:
        if other is not None and same_file(path, other):
            raise _option_error(option, f"`{shown}` is also {what}", "give each output its own file")
    try:
        info = os.stat(path)
    except FileNotFoundError:
        info = None
    except NotADirectoryError:
        raise _option_error(option, f"a part of the path `{shown}` is a file, not a folder",
                            "choose another output") from None
    except OSError as exc:
        raise _option_error(option, f"cannot use `{shown}`: {exc.strerror or exc}", "choose another output") from None
    if info is not None:
        if folder and not stat.S_ISDIR(info.st_mode):
            raise _option_error(option, f"`{shown}` exists and is not a folder", "give a folder for the figures")
        if not folder and stat.S_ISDIR(info.st_mode):
            raise _option_error(option, f"`{shown}` is a folder", f"give a file name, e.g. `{option} "
                                f"{path / 'results.h5'}`")
        if not folder and not stat.S_ISREG(info.st_mode):
            raise _option_error(option, f"`{shown}` is not a regular file", "give the name of a file to write")
        if not os.access(path, os.W_OK | (os.X_OK if folder else 0)):
            raise _option_error(option, f"`{shown}` is not writable", "choose another output, or change its mode")
        return
    parent = path.parent
    if folder or make_parents:  # folders created as needed: find the first one that exists
        while not os.path.lexists(parent) and parent != parent.parent:
            parent = parent.parent
    if not parent.exists():
        raise _option_error(option, f"the folder `{parent}` of `{shown}` does not exist",
                            f"create it first (`mkdir -p {parent}`) or choose another output")
    if not parent.is_dir():
        raise _option_error(option, f"`{parent}` in `{shown}` is not a folder", "choose another output")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise _option_error(option, f"cannot write in the folder `{parent}` of `{shown}` (read-only)",
                            "choose an output in a folder you can write")


def model_files(path) -> list:
    """The model file and every file it includes (resolved paths): the inputs an output may not
    overwrite.  Unreadable or broken models give [path] (their errors come when they load)."""
    try:
        if not stat.S_ISREG(os.stat(path).st_mode) or os.stat(path).st_size > compiler.MAX_MODEL_BYTES:
            return [Path(path)]
        spec = parser.parse_model(parser.decode_model(Path(path).read_bytes(), str(path)), str(path))
    except (OSError, MbsError):
        return [Path(path)]
    return [Path(path), *spec.include_files]


def print_model_warnings(model) -> None:
    """What the compiler took but warns about (`Model.warnings`: a number without a unit), on stderr."""
    for text in getattr(model, "warnings", None) or []:
        console(stderr=True).print(text, markup=False, style="yellow", soft_wrap=True)


def print_assembly(changes) -> None:
    """What the assembly changed in the stated initial state (beyond the tolerance): `mbs check` and
    `mbs run` print it."""
    for line in changes:
        say(line)
