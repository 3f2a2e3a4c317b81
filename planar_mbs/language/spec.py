"""ModelSpec: the model text as plain dataclasses, straight from the parser.

Nothing here is evaluated yet: expressions stay trees (`Number`, `Name`,
`BinOp`, `Neg`, `Vector`, `Call`; in expressions of loads and motions also `Compare`,
`SignalRef` and `String`) so that parameters can be overridden and
resolved in dependency order by the compiler.  Every node keeps its `Pos`
(file, line, column, the source line and the exact text) so any later pass can
point back at what the user wrote.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import ModelError


@dataclass(frozen=True)
class Pos:
    """A place in a source file: 1-based line/column, the line itself and the text spanned."""

    file: str
    line: int
    column: int
    end_line: int
    end_column: int
    source_line: str
    text: str

    @property
    def width(self) -> int:
        if self.end_line == self.line:
            return max(1, self.end_column - self.column)
        return max(1, len(self.source_line) - self.column + 1)

    def error(self, message: str, hint: str = "") -> ModelError:
        """A `ModelError` pointing at this place (to be raised by the caller)."""
        return ModelError(
            message, self.file, self.line, self.column, hint=hint,
            source_line=self.source_line, width=self.width,
        )


# ---------------------------------------------------------------- expressions
@dataclass(frozen=True)
class Expr:
    pos: Pos


@dataclass(frozen=True)
class Number(Expr):
    value: float
    unit: str | None  # unit text as written (`kg*m^2`), None for a plain number


@dataclass(frozen=True)
class Name(Expr):
    name: str


@dataclass(frozen=True)
class BinOp(Expr):
    op: str  # one of + - * / ^
    left: Expr
    right: Expr


@dataclass(frozen=True)
class Compare(Expr):
    """``left op right`` with op one of < <= > >=: 1 or 0 (in expressions of loads and motions)."""

    op: str
    left: Expr
    right: Expr


@dataclass(frozen=True)
class SignalRef(Expr):
    """``entity.quantity``, a signal of the model (``slider.vx``), in expressions of loads and motions."""

    entity: str
    quantity: str


@dataclass(frozen=True)
class String(Expr):
    """A quoted text (a table's file name)."""

    value: str


@dataclass(frozen=True)
class Neg(Expr):
    operand: Expr


@dataclass(frozen=True)
class Vector(Expr):
    items: tuple[Expr, ...]


@dataclass(frozen=True)
class KwArg:
    name: str
    value: Expr
    pos: Pos  # position of the name


@dataclass(frozen=True)
class Call(Expr):
    name: str
    name_pos: Pos
    args: tuple[Expr, ...]
    kwargs: tuple[KwArg, ...]


# ----------------------------------------------------------------- statements
@dataclass(frozen=True)
class Field:
    """`key = expr` inside a block (or a keyword argument of the defining call)."""

    name: str
    value: Expr
    pos: Pos  # position of the key


@dataclass
class Statement:
    """One top-level statement.

    kind: param, material, body, joint, driver, force, gravity, simulate, include.
    name: the element name (None for gravity, simulate, include).
    value: the param expression, the defining call (`revolute(...)`), the
    gravity vector, or for include the path string.
    """

    kind: str
    name: str | None
    value: Expr | str | None
    fields: list[Field]
    pos: Pos  # the whole statement
    name_pos: Pos | None = None
    override: bool = False


@dataclass
class ModelSpec:
    """All statements in source order, includes expanded in place."""

    statements: list[Statement] = field(default_factory=list)
    path: str = "<string>"
    text: str = ""
    key: str = ""  # the absolute path of the file, symlinks kept: the base of `includes` keys
    includes: dict[str, str] = field(default_factory=dict)  # absolute path -> text of each included file
    include_files: list = field(default_factory=list)  # the real (resolved) paths of the included files
