"""Text → ModelSpec: the LALR parser of `planar_mbs/language/grammar/mbs.lark`, friendly syntax errors, includes.

The lark parser is built once per process (`parser()`); its trees become the
plain dataclasses of `spec`.  Syntax errors become `ModelError`s with the line,
a caret and a hint naming what was expected in words (the idea of lark's
``examples/advanced/error_reporting_lalr.py``, done by mapping terminal names).
``include "file.mbs"`` statements are expanded in place, relative to the
including file, with cycle detection.
"""
from __future__ import annotations

import functools
import hashlib
import itertools
import os
import re
import stat
import tempfile
from importlib.util import find_spec
from pathlib import Path

import lark
from lark import Lark, Token, Transformer, Tree, v_args
from lark.exceptions import UnexpectedCharacters, UnexpectedInput, UnexpectedToken, VisitError

from ..errors import ModelError, did_you_mean
from ..files import replace_atomically
from ..lazy import lazy
from .units import UnitError, parse_unit
from .spec import (
    BinOp,
    Call,
    Compare,
    Expr,
    Field,
    KwArg,
    ModelSpec,
    Name,
    Neg,
    Number,
    Pos,
    SignalRef,
    Statement,
    String,
    Vector,
)

resources = lazy("importlib.resources")  # the grammar's fallback reader: costs more than a parse

KEYWORDS = ("param", "material", "body", "joint", "driver", "force", "gravity",
            "simulate", "include", "override")
# atomic groups `(?>...)`: a failed match never retries shorter digit runs, so long numbers
# cost linear time (`\d+\.?\d*` tried every split of a 100 000-digit number: quadratic)
_NUMBER = re.compile(r"(?>\d+(?:\.\d*)?|\.\d+)(?>[eE][+-]?\d+)?")
# text that is neither a comment nor a quoted string (blanked out, positions kept)
_NOT_CODE = re.compile(r'"[^"\n]*"?|#[^\n]*')
_NOT_COMMENT = re.compile(r'("[^"\n]*"?)|#[^\n]*')  # comments (a quoted `#` is not one)


def _blank(m) -> str:
    return m.group(1) or " " * len(m.group(0))
# a number whose exponent has no digits (`1e`, `2.5e-`), or with two decimal points (`1.2.3`)
_BAD_NUMBER = re.compile(r"(?<![\w.])(?>\d+(?:\.\d*)?|\.\d+)(?:[eE][+-](?!\d)|[eE](?![+\-\w])|\.)")
MAX_DEPTH = 100  # nesting levels of one expression (deeper trees would exhaust Python's stack)


@functools.lru_cache(maxsize=None)
def parser() -> Lark:
    """The LALR parser, built once per process (start symbols: ``start`` for files, ``expr`` for
    `--set`).  Not lark's ``cache=True``: that loads a pickle from the shared temporary folder,
    where anyone could plant one.  The tables are kept instead in a private cache folder of the
    user (`_private_cache`); building them costs some 200 ms, loading them some 15 ms."""
    text, options = _grammar()
    cache = _private_cache(tables_name())
    if cache is not None:
        loaded = _load_tables(cache)
        if loaded is not None:
            return loaded
    built = Lark(text, **options)
    if cache is not None:
        _save_tables(built, cache)
    return built


@functools.lru_cache(maxsize=None)
def _grammar_text() -> str:
    """planar_mbs/language/grammar/mbs.lark, read from the package folder (importlib.resources, which also reads packages
    inside zip files, costs more to import than a model costs to parse; it is the fallback)."""
    spec = find_spec("planar_mbs.language.grammar")
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        try:
            return (Path(folder) / "mbs.lark").read_text(encoding="utf-8")
        except OSError:
            pass

    return resources.files("planar_mbs.language.grammar").joinpath("mbs.lark").read_text(encoding="utf-8")


def _grammar() -> tuple[str, dict]:
    text = _grammar_text()
    return text, dict(parser="lalr", lexer="contextual", propagate_positions=True, start=["start", "expr"],
                      maybe_placeholders=True)


def tables_name() -> str:
    """File name of the saved parser: changes with the grammar, its options and lark's version."""
    text, options = _grammar()
    return "grammar-" + hashlib.sha256(f"{text}\0{lark.__version__}\0{sorted(options.items())}".encode()
                                       ).hexdigest()[:24] + ".lark"


def _private_cache(name: str) -> str | None:
    """A path in the user's own cache folder ($XDG_CACHE_HOME or ~/.cache, then planar_mbs/),
    or None when that folder is not a real folder owned by this user with mode 0700."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    folder = os.path.join(base, "planar_mbs")
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        info = os.lstat(folder)
    except OSError:
        return None
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid() or info.st_mode & 0o077:
        return None
    return os.path.join(folder, name)


def _load_tables(path: str) -> Lark | None:
    """The parser saved at `path`, if that is a regular file (not a link) of this user that no
    one else may write; else None (and it is rebuilt)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError:
        return None
    with os.fdopen(fd, "rb") as f:
        info = os.fstat(f.fileno())
        if not stat.S_ISREG(info.st_mode) or info.st_uid != os.getuid() or info.st_mode & 0o022:
            return None
        try:
            return Lark.load(f)
        except Exception:  # noqa: BLE001  (a damaged cache is rebuilt)
            return None


def _save_tables(built: Lark, path: str) -> None:
    """Save the parser next to `path` and move it into place (readers never see half a file)."""
    try:
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix=".tmp-")
        with os.fdopen(fd, "wb") as f:
            built.save(f)
        replace_atomically(tmp, path, durable=False)  # a cache: rebuilt if a power cut loses it
    except Exception:  # noqa: BLE001  (no cache then: slower, not wrong)
        try:
            os.unlink(tmp)
        except (OSError, UnboundLocalError):
            pass


# ------------------------------------------------------------ tree → spec
@v_args(meta=True)
class _ToSpec(Transformer):
    """Turns lark trees into `spec` dataclasses, keeping positions."""

    def __init__(self, text: str, path: str):
        super().__init__()
        self.text = text
        self.path = path
        self.lines = text.splitlines() or [""]

    # positions
    def _pos(self, line, column, end_line, end_column, start, end) -> Pos:
        src = self.lines[line - 1] if 0 < line <= len(self.lines) else ""
        return Pos(self.path, line, column, end_line, end_column, src, self.text[start:end])

    def meta_pos(self, meta) -> Pos:
        return self._pos(meta.line, meta.column, meta.end_line, meta.end_column,
                         meta.start_pos, meta.end_pos)

    def tok_pos(self, tok: Token) -> Pos:
        return self._pos(tok.line, tok.column, tok.end_line, tok.end_column,
                         tok.start_pos, tok.end_pos)

    # statements
    def start(self, meta, children):
        return list(children)

    def _element(self, kind, meta, children):
        name, rest = children[0], children[1:]
        value = None
        fields: list[Field] = []
        for c in rest:
            if isinstance(c, list):
                fields = c
            elif c is not None:
                value = c
        return Statement(kind, str(name), value, fields, self.meta_pos(meta), self.tok_pos(name))

    def param(self, meta, children):
        return self._element("param", meta, children)

    def material(self, meta, children):
        return self._element("material", meta, children)

    def body(self, meta, children):
        return self._element("body", meta, children)

    def body_of_kind(self, meta, children):
        """`body rod = beam { ... }`: the kind is the statement's value, a name."""
        name, kind, fields = children
        return Statement("body", str(name), Name(self.tok_pos(kind), str(kind)), fields, self.meta_pos(meta),
                         self.tok_pos(name))

    def joint(self, meta, children):
        return self._element("joint", meta, children)

    def driver(self, meta, children):
        return self._element("driver", meta, children)

    def force(self, meta, children):
        return self._element("force", meta, children)

    def gravity(self, meta, children):
        return Statement("gravity", None, children[0], [], self.meta_pos(meta))

    def simulate(self, meta, children):
        return Statement("simulate", None, None, children[0], self.meta_pos(meta))

    def override(self, meta, children):
        st = children[0]
        st.override = True
        st.pos = self.meta_pos(meta)
        return st

    def include(self, meta, children):
        return Statement("include", None, str(children[0])[1:-1], [], self.meta_pos(meta))

    def block(self, meta, children):
        return list(children)

    def field(self, meta, children):
        key, value = children
        return Field(str(key), value, self.tok_pos(key))

    def key(self, meta, children):
        return children[0]

    # expressions
    def number(self, meta, children):
        tok = children[0]
        pos = self.tok_pos(tok)
        m = _NUMBER.match(tok)
        value = float(m.group(0))
        if value == float("inf"):
            raise pos.error(f"the number {_clip(m.group(0))} is too large",
                            hint="numbers must stay below about 1.8e308")
        unit = tok[m.end():].strip() or None
        return Number(pos, value, unit)

    def name(self, meta, children):
        return Name(self.tok_pos(children[0]), str(children[0]))

    def signal(self, meta, children):
        return SignalRef(self.meta_pos(meta), str(children[0]), str(children[1]))

    def string(self, meta, children):
        return String(self.tok_pos(children[0]), str(children[0])[1:-1])

    def _compare(self, op, meta, children):
        return Compare(self.meta_pos(meta), op, children[0], children[1])

    def lt(self, meta, children):
        return self._compare("<", meta, children)

    def le(self, meta, children):
        return self._compare("<=", meta, children)

    def gt(self, meta, children):
        return self._compare(">", meta, children)

    def ge(self, meta, children):
        return self._compare(">=", meta, children)

    def _binop(self, op, meta, children):
        return BinOp(self.meta_pos(meta), op, children[0], children[1])

    def add(self, meta, children):
        return self._binop("+", meta, children)

    def sub(self, meta, children):
        return self._binop("-", meta, children)

    def mul(self, meta, children):
        return self._binop("*", meta, children)

    def div(self, meta, children):
        return self._binop("/", meta, children)

    def pow(self, meta, children):
        return self._binop("^", meta, children)

    def neg(self, meta, children):
        return Neg(self.meta_pos(meta), children[0])

    def pos(self, meta, children):
        return children[0]

    def vector(self, meta, children):
        return Vector(self.meta_pos(meta), tuple(children))

    def kwarg(self, meta, children):
        key, value = children
        return KwArg(str(key), value, self.tok_pos(key))

    def call(self, meta, children):
        name, rest = children[0], [c for c in children[1:] if c is not None]
        args, kwargs = [], []
        for a in rest:
            if isinstance(a, KwArg):
                if any(k.name == a.name for k in kwargs):
                    raise a.pos.error(f"`{a.name}` is given twice in `{name}(...)`")
                kwargs.append(a)
            else:  # positional arguments may also follow keyword ones
                args.append(a)
        return Call(self.meta_pos(meta), str(name), self.tok_pos(name), tuple(args), tuple(kwargs))


# ------------------------------------------------------------ syntax errors
_WORDS = {"NAME": "a name", "QUANTITY": "a number", "STRING": 'a quoted file name ("file.mbs")',
          "$END": "the end of the file"}


def _readable(terminals) -> str:
    """Expected terminals in words: `=`, a name, a number, a statement, ..."""
    terminals = set(terminals)
    words = []
    kws = {t for t in terminals if t.lower() in KEYWORDS}
    if len(kws) >= 6:
        words.append("a statement (" + ", ".join(KEYWORDS) + ")")
        terminals -= kws
    lit = {t.name: t.pattern.value for t in parser().terminals if t.pattern.type == "str"}
    for t in sorted(terminals):
        if t in _WORDS:
            words.append(_WORDS[t])
        elif t in lit:
            words.append(f"`{lit[t]}`")
    if not words:
        return ""
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]


_SPACED_UNIT = re.compile(r"\d\s*([A-Za-z_]\w*(?:\s*[*/^]\s*[\w.]+)*)\s+([A-Za-z_]\w*)$")


def _spaced_unit(prev: str) -> tuple[str, str] | None:
    """(`kg`, `m`) when the text before an error ends in a number, a unit and, after a space,
    another unit: `inertia = 1e-5 kg m` (units are joined with `*`)."""
    m = _SPACED_UNIT.search(prev)
    if m is None:
        return None

    try:
        parse_unit(m.group(2))
    except (UnitError, Exception):  # not a unit: an ordinary missing `=`
        return None
    return m.group(1), m.group(2)


class _Site:
    """Where a syntax error is: the text, its code (comments and strings blanked), the line lark
    reported and the brackets still open at the error (`_open_brackets`)."""

    def __init__(self, text: str, code: str, line: int, offset: int):
        self.text, self.code, self.line = text, code, line
        self.stack = _open_brackets(code, offset)

    def where(self, off: int) -> str:
        ln = self.text.count("\n", 0, off) + 1
        return f"line {ln}, column {off - (self.text.rfind(chr(10), 0, off) + 1) + 1}"

    def unclosed(self, before_line: bool) -> str:
        """'the `{` opened on line 3 is still open' when a bracket opened earlier is unclosed."""
        if not self.stack:
            return ""
        b, off = self.stack[-1]
        if before_line and self.text.count("\n", 0, off) + 1 >= self.line:
            return ""
        close = "}" if b == "{" else ")"
        return f"is a `{close}` missing? the `{b}` at {self.where(off)} is still open"


def _error_offset(e: UnexpectedInput, text: str) -> int:
    """The offset in `text` of the error: the unexpected token's start, else lark's position, else the end."""
    offset = getattr(e, "pos_in_stream", None)
    if isinstance(e, UnexpectedToken) and e.token.type != "$END":
        offset = e.token.start_pos
    if offset is None or e.__class__ is UnexpectedToken and e.token.type == "$END":
        offset = len(text)
    return offset


def _syntax_error(e: UnexpectedInput, text: str, path: str, line_offset: int = 0,
                  code: str | None = None) -> ModelError:
    """A lark syntax error as a `ModelError` in words: what was found, what was expected instead
    (`_readable`), the likely cause (`_token_rules`, `_unclosed_block`), a caret under the text."""
    lines = text.splitlines() or [""]
    line = getattr(e, "line", None) or len(lines)
    column = getattr(e, "column", None) or 1
    src = lines[line - 1] if 0 < line <= len(lines) else ""
    width = 1
    site = _Site(text, _code(text) if code is None else code, line, _error_offset(e, text))
    if isinstance(e, UnexpectedToken) and e.token.type == "$END":
        line, column, src = len(lines), len(lines[-1].rstrip()) + 1, lines[-1]
        message = ("the value ends too early" if path == "--set"
                   else "the text ends in the middle of a statement")
        hint = f"expected {_readable(set(e.expected))}; " + (site.unclosed(False) or "is a `)` or `}` missing?")
    elif isinstance(e, UnexpectedToken):
        width = len(str(e.token))
        message, hint = _unexpected_token(site, e.token, set(e.expected))
    else:
        assert isinstance(e, UnexpectedCharacters)
        message, hint = _unexpected_character(text, e.pos_in_stream)
    return ModelError(message, path, line + line_offset, column, hint=hint, source_line=src,
                      width=width)


def _unexpected_token(site: _Site, tok: Token, expected: set[str]) -> tuple[str, str]:
    """(message, hint) for a token the grammar does not allow where it stands."""
    shown = f"`{_clip(str(tok))}`"
    prev = site.code[:tok.start_pos].rstrip()
    default = (f"unexpected {shown}", f"expected {_readable(expected)}")
    for rule in (_bracket_rules, _unit_rules, _statement_rules):
        found = rule(site, tok, expected, prev, shown, default[1])
        if found is not None:
            return _unclosed_block(site, tok, prev, shown, *found)
    return _unclosed_block(site, tok, prev, shown, *default)


def _bracket_rules(site: _Site, tok: Token, expected: set[str], prev: str, shown: str, hint: str):
    """A closing bracket that closes nothing or the wrong bracket; a comma where none belongs."""
    stack, code = site.stack, site.code
    if tok.type in ("RBRACE", "RPAR") and (not stack or stack[-1][0] != ("{" if tok.type == "RBRACE" else "(")):
        other = "{" if tok.type == "RBRACE" else "("
        if stack:
            return (f"this `{tok}` does not match the `{stack[-1][0]}` at {site.where(stack[-1][1])}",
                    f"close the `{stack[-1][0]}` first, or remove this `{tok}`")
        return f"this `{tok}` closes nothing", f"remove it, or add the `{other}` it should close; " + hint
    if tok.type == "COMMA" and prev[-1:].isdigit() and code[tok.end_pos:tok.end_pos + 1].isdigit():
        return f"unexpected {shown}", "decimals are written with a point (`1.5`), not a comma"
    if tok.type == "COMMA" and "RBRACE" in expected:
        return f"unexpected {shown}", "fields inside `{ }` are separated by spaces or new lines, not commas"
    return None


def _unit_rules(site: _Site, tok: Token, expected: set[str], prev: str, shown: str, hint: str):
    """A `=` read as the end of an expression; a unit after a space read as a field name or a second unit."""
    text = site.text
    if tok.type == "EQUAL" and re.search(r"([-+*/^])\s*(\w+)$", prev):
        op, name = re.search(r"([-+*/^])\s*(\w+)$", prev).groups()
        return (f"unexpected `=`: `{name}` was read as the operand of the `{op}` before it",
                f"the value before `{name}` ends with a trailing `{op}`: finish or remove it")
    if expected == {"EQUAL"} and _spaced_unit(prev):  # `1e-5 kg m^2`: `m` read as a field name
        unit, name = _spaced_unit(prev)
        tail = re.match(r"[*/^][\w.*/^]*", text[tok.start_pos:])  # the rest of the unit: `^2`
        return (f"unexpected {shown}: the unit `{name}` after `{unit}` was read as a new field",
                f"join units with `*`: `{unit}*{name}{tail.group(0) if tail else ''}`")
    if tok.type == "NAME" and "EQUAL" not in expected and _spaced_unit(f"{prev} {tok}"):  # `2 N m)`
        unit, name = _spaced_unit(f"{prev} {tok}")
        tail = re.match(r"[*/^][\w.*/^]*", text[tok.end_pos:])
        return (f"unexpected `{tok}`: a second unit after `{unit}`, separated by a space",
                f"join units with `*`: `{unit}*{name}{tail.group(0) if tail else ''}`")
    return None


def _statement_rules(site: _Site, tok: Token, expected: set[str], prev: str, shown: str, hint: str):
    """Quoted text, a statement that does not start with a keyword, a keyword or number used as a
    name, a missing `=`, a unit with spaces inside."""
    if tok.type == "STRING":
        return (f"unexpected {shown}",
                'quoted text is only used by `include "file.mbs"`; write names without quotes (`law = hertz`)')
    if tok.type == "QUANTITY" and "PARAM" in expected:
        return (f"unexpected `{tok}`: a statement starts with a keyword",
                "statements start with: " + ", ".join(KEYWORDS) + "; is this value part of the line before?")
    if tok.type == "NAME" and "PARAM" in expected:
        return (f"unexpected `{tok}`: a statement starts with a keyword",
                did_you_mean(str(tok), KEYWORDS) or "statements start with: " + ", ".join(KEYWORDS))
    if tok.type.lower() in KEYWORDS and "NAME" in expected:
        return f"`{tok}` is a keyword and cannot be used as a name here", "choose another name"
    word = re.match(r"\d+[A-Za-z_]\w*", site.text[tok.start_pos:]) if tok.type == "QUANTITY" else None
    if word and "NAME" in expected:  # `2crank` (one token) or `1a` (a number, then a name)
        return f"`{word.group(0)}` is not a name", "names start with a letter or `_` (letters, digits and `_` follow)"
    if tok.type == "QUANTITY" and expected == {"EQUAL"}:
        return (f"unexpected `{tok}`: a `=` is missing",
                "write `param NAME = value`" if re.search(r"(?:^|\W)param\s+\w+$", prev)
                else "write fields as `key = value`")
    if tok.type in ("LPAR", "QUANTITY") and "NAME" in expected and "EQUAL" not in expected:
        return (f"unexpected {shown}",
                "a unit goes right after its number without spaces inside (`2.5e-4 kg*m^2`); otherwise " + hint)
    return None


def _unclosed_block(site: _Site, tok: Token, prev: str, shown: str, message: str, hint: str) -> tuple[str, str]:
    """(message, hint) said again when a bracket opened on an earlier line is still open: a statement
    keyword read as a field name means the block before it was not closed."""
    missing = site.unclosed(True)
    kw_before = re.search(r"(?:^|[^\w])(" + "|".join(KEYWORDS) + r")\s*$", prev)
    if missing and site.stack[-1][0] == "{" and kw_before:
        return (f"unexpected {shown}: `{kw_before.group(1)}` starts a new statement, "
                f"but the block before it is not closed"), missing
    if missing and tok.type.lower() in KEYWORDS:
        return f"unexpected {shown}: a new statement starts, but the one before it is not finished", missing
    if missing and tok.type not in ("RBRACE", "RPAR"):
        return message, f"{hint}; {missing}"
    return message, hint


def _unexpected_character(text: str, pos: int) -> tuple[str, str]:
    """(message, hint) for a character no token starts with: `;`, a stray quote, a comma, a control
    character, bytes that are not UTF-8."""
    ch = text[pos] if pos < len(text) else "?"
    message = f"unexpected character `{ch}`" if ch.isprintable() else f"unexpected character {ch!r}"
    if ch == ";":
        return message, "no `;` is needed: separate statements and fields with spaces or new lines"
    if ch == '"' and '"' not in text[pos + 1:].split("\n", 1)[0]:
        return "the quoted file name is not closed", 'end it with `"` on the same line: `include "file.mbs"`'
    if ch == '"':
        return message, 'quoted text is only used by `include "file.mbs"`'
    if ch == ",":
        return message, "fields inside `{ }` are separated by spaces or new lines, not commas"
    if ch != "\n" and not ch.isprintable() and ch not in "\t\r":
        return message, "the file contains a control character: is it a text file? remove the character"
    if ch == "\ufffd":
        return "a character that is not valid UTF-8", "save the file as UTF-8"
    return message, "names are letters, digits and `_`; numbers may carry a unit like `0.3 mm`"


def _clip(word: str, n: int = 40) -> str:
    """A word shown in a message: long ones (a 100 000-digit number) cut in the middle."""
    return word if len(word) <= n else f"{word[:n // 2]}…{word[-n // 4:]} ({len(word):,} characters)"


def _code(text: str) -> str:
    """The text with comments and quoted strings blanked out (same length, same lines)."""
    return _NOT_CODE.sub(lambda m: " " * len(m.group(0)), text)


def _bad_number(text: str, path: str, code: str | None = None) -> ModelError | None:
    """The first malformed number (`1e`, `1e+`, `1.2.3`) outside comments, as an error."""
    m = _BAD_NUMBER.search(_code(text) if code is None else code)
    if m is None:
        return None
    line = text.count("\n", 0, m.start()) + 1
    column = m.start() - (text.rfind("\n", 0, m.start()) + 1) + 1
    src = (text.splitlines() or [""])[line - 1] if line <= len(text.splitlines()) else ""
    word = m.group(0)
    if word.count(".") > 1:
        word = re.match(r"[\d.]+", text[m.start():]).group(0)
        message, hint = f"`{word}` is not a number: it has more than one decimal point", "write e.g. `1.25`"
    else:
        message = f"`{word}` is not a number: the exponent after `{word.rstrip('+-')[-1]}` has no digits"
        hint = "write the exponent in full, e.g. `1e-3` or `2.5e4`, or drop the `e`"
    return ModelError(message, path, line, column, hint=hint, source_line=src, width=len(word))


def _open_brackets(code: str, end: int) -> list[tuple[str, int]]:
    """Brackets `{` `(` still open at offset `end` of the blanked code (innermost last), as
    (bracket, offset); a closing bracket that matches nothing is kept as such."""
    stack: list[tuple[str, int]] = []
    pairs = {"}": "{", ")": "("}
    for m in re.finditer(r"[{}()]", code[:end]):
        ch = m.group(0)
        if ch in "{(":
            stack.append((ch, m.start()))
        elif stack and stack[-1][0] == pairs[ch]:
            stack.pop()
        elif any(b == pairs[ch] for b, _ in stack):  # a closing bracket skips an open one
            while stack and stack[-1][0] != pairs[ch]:
                stack.pop()
            stack.pop()
    return stack


_CHAINS = ({"add", "sub"}, {"mul", "div"})  # `a + b - c ...`: a left-leaning chain of one rule
CHAIN_LINKS = 3  # links of such a chain that count as one level of nesting


def _weight(parent, child, i: int) -> int:
    """Thirds of a level that ``child`` (child ``i`` of ``parent``) lies deeper: one for the next term
    of a sum or product (a flat sum of 300 terms counts as 100 levels), three for anything else."""
    chained = i == 0 and any(parent.data in c and child.data in c for c in _CHAINS)
    return 1 if chained else CHAIN_LINKS


def _check_depth(tree, text: str, path: str) -> None:
    """Reject expressions nested deeper than MAX_DEPTH (without recursing ourselves)."""
    todo = [(tree, 0)]
    while todo:
        node, thirds = todo.pop()
        depth = thirds / CHAIN_LINKS
        if depth > MAX_DEPTH:
            meta = node.meta
            line = getattr(meta, "line", 1)
            src = (text.splitlines() or [""])[line - 1] if 0 < line <= len(text.splitlines()) else ""
            raise ModelError(f"this expression nests more than {MAX_DEPTH} levels deep (or sums or multiplies "
                             f"more than {MAX_DEPTH * CHAIN_LINKS} terms)", path, line,
                             getattr(meta, "column", 1), source_line=src,
                             hint="split it into several `param`s")
        todo.extend((c, thirds + _weight(node, c, i)) for i, c in enumerate(node.children) if isinstance(c, Tree))


# ------------------------------------------------------------ entry points
MAX_TOKENS = 100_000  # names, numbers and symbols of one model with its includes (shipped: up to ~600; a
# chain of a thousand bodies about 40 000): the parser takes some 50 µs a token, so at most about 5 s
_TOKEN = re.compile(r'"[^"\n]*"?|[\w.\u00b5\u03bc]+|[^\s\w#]')  # comments are skipped below


def _check_tokens(text: str, code: str, path: str, left: list[int]) -> None:
    """Refuse text with more than ``left[0]`` tokens (stopping at the first one too many), so that
    the parser's time -- linear, but some 50 µs a token -- stays bounded; subtract the count
    from ``left[0]``."""
    n = 0
    tokens = (m for m in _TOKEN.finditer(_NOT_COMMENT.sub(_blank, text)))
    for n, m in enumerate(itertools.islice(tokens, left[0] + 1), 1):
        if n > left[0]:
            line = text.count("\n", 0, m.start()) + 1
            start = text.rfind("\n", 0, m.start()) + 1
            end = text.find("\n", m.start())
            raise ModelError(f"the model is too long: more than {MAX_TOKENS:,} names, numbers and symbols "
                             "(with its included files)", path, line, m.start() - start + 1,
                             source_line=text[start:end if end >= 0 else len(text)],
                             hint="is this really a model file? The longest shipped model has about 600")
    left[0] -= n


# Statements of recently parsed texts, by (text, path): a sweep compiles the same model once per case
# (its values are `--set` overrides, applied by the compiler, not the parser), and lark's parse is most
# of a compile (about 0.02 s of a slider-crank's 0.025 s).  The statements are never changed once parsed.
PARSED_CACHE = 16  # entries kept
PARSED_CACHE_CHARS = 1 << 20  # longest text kept
_parsed: dict[tuple[str, str], list[Statement]] = {}


def parse_statements(text: str, path: str = "<string>", tokens: list[int] | None = None) -> list[Statement]:
    """Parse one file's text into statements (includes not expanded).  ``tokens`` holds the
    number of tokens still allowed (shared by a model and its includes)."""
    code = _code(text)
    _check_tokens(text, code, path, [MAX_TOKENS] if tokens is None else tokens)
    key = (text, path)
    if key in _parsed:
        return list(_parsed[key])
    statements = _parse_checked(text, path, code)
    if len(text) <= PARSED_CACHE_CHARS:
        if len(_parsed) >= PARSED_CACHE:
            del _parsed[next(iter(_parsed))]  # the oldest
        _parsed[key] = statements
    return list(statements)


def _parse_checked(text: str, path: str, code: str) -> list[Statement]:
    try:
        tree = parser().parse(text, start="start")
    except UnexpectedInput as e:
        err = _syntax_error(e, text, path, code=code)
        bad = _bad_number(text, path, code)
        if bad is not None and (bad.line, bad.column) <= (err.line, err.column):
            raise bad from None
        raise err from None
    bad = _bad_number(text, path, code)
    if bad is not None:
        raise bad
    _check_depth(tree, text, path)
    return _transform(tree, text, path)


def _transform(tree, text: str, path: str):
    try:
        return _ToSpec(text, path).transform(tree)
    except VisitError as e:
        if isinstance(e.orig_exc, ModelError):
            raise e.orig_exc from None
        raise


def parse_expression(text: str, path: str = "--set") -> Expr:
    """Parse a single expression (the value of a `--set NAME=VALUE` override)."""
    _check_tokens(text, _code(text), path, [MAX_TOKENS])
    try:
        tree = parser().parse(text, start="expr")
    except UnexpectedInput as e:
        raise _syntax_error(e, text, path) from None
    bad = _bad_number(text, path)
    if bad is not None:
        raise bad
    _check_depth(tree, text, path)
    return _transform(tree, text, path)


MAX_MODEL_BYTES = 16 * 2**20  # a model file, or all of its includes together
MAX_INCLUDES = 100  # included files of one model, counting repeats


def parse_model(text: str, path: str = "<string>", sources: dict[str, str] | None = None,
                main: str | None = None) -> ModelSpec:
    """Parse a model and expand its includes into one ModelSpec.

    ``sources`` (absolute path → text, as recorded in ``spec.includes`` of an earlier parse,
    with ``main`` its ``spec.key``) supplies the included files instead of the disk: a results
    file keeps them so that its model can be rebuilt anywhere.  ``spec.include_files`` lists
    the real files read (to refuse writing over any of them)."""
    main = main or (_lexical(path) if not path.startswith("<") else None)
    spec = ModelSpec([], path, text, key=main or "")
    spec.statements = _expand(text, path, (), main, spec, sources, [len(text), MAX_TOKENS])
    return spec


def _lexical(path: str) -> str:
    """An absolute path without resolving symlinks (the key of an included file's text)."""
    return os.path.normpath(os.path.abspath(path))


def _expand(text: str, path: str, stack: tuple[Path, ...], key: str | None, spec: ModelSpec,
            sources: dict[str, str] | None, budget: list[int]) -> list[Statement]:
    here = Path(path).resolve() if sources is None and not path.startswith("<") else None
    out = []
    tokens = budget[1:]
    statements = parse_statements(text, path, tokens)
    budget[1] = tokens[0]
    for st in statements:
        if st.kind != "include":
            out.append(st)
            continue
        base = here.parent if here is not None else Path(os.path.dirname(key)) if key else Path.cwd()
        sub_key = os.path.normpath(os.path.join(str(base) if key is None else os.path.dirname(key), st.value))
        try:
            target = Path(sub_key) if sources is not None else (base / st.value).resolve()
        except (RuntimeError, OSError) as exc:  # a symbolic link loop (RuntimeError before Python 3.13)
            raise st.pos.error(f"cannot follow the included file `{st.value}`: {getattr(exc, 'strerror', None) or exc}",
                               hint="is it a symbolic link that points (through others) back to itself?") from None
        chain = [*stack, *([here] if here else [Path(key)] if key and sources is not None else [])]
        if target in chain:
            names = " → ".join(p.name for p in chain[chain.index(target):]) + f" → {target.name}"
            raise st.pos.error(f"include cycle: {names}", hint="a file may not include itself, directly or not")
        if len(spec.include_files) >= MAX_INCLUDES:
            raise st.pos.error(f"more than {MAX_INCLUDES} included files",
                               hint="a model includes each file once; is a file included in a loop?")
        if sources is not None:
            if sub_key not in sources:
                raise st.pos.error(f"the included file `{st.value}` is not stored with the results",
                                   hint="run the model again to store all of its files")
            sub = sources[sub_key]
        else:
            sub = decode_model(_read_include(st, target, base, budget), str(_display(target)))
            spec.include_files.append(target)
        spec.includes[sub_key] = sub
        out.extend(_expand(sub, str(_display(target)), tuple(chain), sub_key, spec, sources, budget))
    return out


def _read_include(st: Statement, target: Path, base: Path, budget: list[int]) -> bytes:
    """The bytes of an included file: a regular file, within what is left of the size budget."""
    try:
        info = os.stat(target)
        if not stat.S_ISREG(info.st_mode):  # a folder, /dev/zero, a pipe: never opened
            raise IsADirectoryError(0, "a folder" if stat.S_ISDIR(info.st_mode) else "not a regular file")
        budget[0] += info.st_size
        if budget[0] > MAX_MODEL_BYTES:
            raise st.pos.error(f"the model and its includes exceed {MAX_MODEL_BYTES // 2**20} MB",
                               hint="is this included file really a model?")
        with open(target, "rb") as f:
            return f.read(MAX_MODEL_BYTES + 1)
    except OSError as err:
        raise st.pos.error(f"cannot read included file `{st.value}` ({err.strerror or err})",
                           hint=f"the path is relative to the including file's folder ({base})") from None


def decode_model(data: bytes, path: str) -> str:
    """A model file's bytes as text; bytes that are not UTF-8 are reported at their line and column."""
    if data.startswith(b"\xef\xbb\xbf"):  # a UTF-8 byte order mark (some Windows editors write one)
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        text = data.decode("utf-8", errors="replace")
        good = data[:err.start].decode("utf-8", errors="replace")
        line = good.count("\n") + 1
        column = len(good) - (good.rfind("\n") + 1) + 1
        src = text.splitlines()[line - 1] if line <= len(text.splitlines()) else ""
        raise ModelError(f"byte 0x{data[err.start]:02x} is not valid UTF-8 text", path, line, column,
                         source_line=src,
                         hint="model files are UTF-8 text: save the file as UTF-8 "
                              "(the caret marks the first bad byte, shown as \ufffd)") from None


def _display(p: Path) -> Path:
    """A path relative to the working directory when possible (shorter messages)."""
    try:
        return p.relative_to(Path.cwd())
    except ValueError:
        return p
