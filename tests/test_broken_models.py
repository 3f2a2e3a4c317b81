"""A corpus of broken models: each gets exit code 2 from `mbs check` and a compiler-style
message (file:line:col, the line, a caret, a hint), never a traceback.

Every `tests/broken_models/*.mbs` starts with `# expect: <part of the message>`, except the
empty file (table below).  Files under `tests/broken_models/lib/` are helpers for the
include cases (a valid pendulum, and a file with a mistake that must be reported there).
Very large and deeply nested inputs are generated here instead of being stored.
"""
from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from planar_mbs.cli.app import app
from planar_mbs.mechanism.compile import compile_text, load_model
from planar_mbs.errors import ModelError
from planar_mbs.mechanism.kinematics import assemble

CORPUS = Path(__file__).resolve().parent / "broken_models"
FILES = sorted(CORPUS.glob("*.mbs"))
# files that cannot carry an `# expect:` line
EXPECT = {"empty.mbs": "the model has no bodies"}
runner = CliRunner()

LOCATED = re.compile(r"^(?P<file>\S+):(?P<line>\d+):(?P<col>\d+): error: (?P<message>.+)$", re.M)


def expected(path: Path) -> str:
    if path.name in EXPECT:
        return EXPECT[path.name]
    m = re.match(rb"# expect: ([^\n]*)\n", path.read_bytes())
    assert m, f"{path.name} lacks its first line `# expect: ...`"
    return m.group(1).decode()


def assert_well_formed(out: str, file_part: str = "") -> re.Match:
    """file:line:col: error: message / the source line / a caret under it / hint: ..."""
    assert "Traceback" not in out and "internal error" not in out, out
    m = LOCATED.search(out)
    assert m, f"no file:line:col in\n{out}"
    if file_part:
        assert file_part in m.group("file"), out
    lines = out[m.end():].lstrip("\n").splitlines()
    assert len(lines) >= 3, out
    src, caret = lines[0], lines[1]
    assert src.startswith("    ") and re.fullmatch(r"    \s*\^+", caret), out
    col = int(m.group("col"))
    if not src[4:].startswith("…"):  # (long lines are shown as a window around the column)
        assert caret.index("^") == 4 + col - 1, out  # the caret sits under column `col`
    assert any(line.startswith("hint: ") and len(line) > 10 for line in lines[2:]), out
    return m


def test_corpus_is_large_enough():
    assert len(FILES) >= 50


def library_error(path: Path) -> ModelError:
    """The error the library raises for a file (load + assemble, as `mbs check` does)."""
    with pytest.raises(ModelError) as info:
        assemble(load_model(path))
    return info.value


def flat(text: str) -> str:
    return " ".join(text.split())


@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_broken_model_gets_exit_2_and_a_located_message(path):
    res = runner.invoke(app, ["check", str(path)])
    out = res.output
    assert res.exit_code == 2, out
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    assert "Traceback" not in out
    assert flat(expected(path)) in flat(out), out
    err = library_error(path)
    text = str(err)
    assert flat(text) == flat(out)  # the CLI prints the library's message
    m = assert_well_formed(text)
    if not path.name.startswith("inc_"):  # include errors may point into another file
        assert Path(m.group("file")).name == path.name


def test_include_error_points_into_the_included_file():
    m = assert_well_formed(str(library_error(CORPUS / "inc_error_inside.mbs")), "lib/bad_dimension.mbs")
    assert m.group("line") == "2"


# ------------------------------------------------------------ generated inputs
class Checked:
    """`mbs check` on a generated file: exit code, output and the library's message."""

    def __init__(self, path: Path):
        t0 = time.perf_counter()
        res = runner.invoke(app, ["check", str(path)])
        self.seconds = time.perf_counter() - t0
        self.exit_code, self.output = res.exit_code, res.output
        self.message = str(library_error(path)) if self.exit_code == 2 else ""


def check_text(tmp_path, text: str | bytes, name="big.mbs"):
    path = tmp_path / name
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
    res = Checked(path)
    return res, res.seconds


PIN = ("body crank { mass = 0.3 kg  inertia = 1e-5 kg*m^2  position = (0.025, 0) }\n"
       "joint O = revolute(ground (0, 0), crank (-0.025, 0))\n")


def test_five_megabytes_of_comments_then_an_error(tmp_path):
    text = ("# " + "x" * 76 + "\n") * 65_000 + PIN + "bogus = 3\n"
    assert len(text) > 5_000_000
    res, seconds = check_text(tmp_path, text)
    assert res.exit_code == 2 and seconds < 10, (seconds, res.output[:500])
    m = assert_well_formed(res.message)
    assert m.group("line") == "65003" and "a statement starts with a keyword" in res.output


def test_five_thousand_params_then_an_error(tmp_path):
    text = "".join(f"param p{i} = {i} mm\n" for i in range(5_000)) + PIN + \
        "body rod { mass = p4999  inertia = 1e-5 kg*m^2 }\n"
    res, seconds = check_text(tmp_path, text)
    assert res.exit_code == 2 and seconds < 20, (seconds, res.output[:500])
    assert_well_formed(res.message)
    assert "a mass was expected, got a length" in res.output


def test_thirty_thousand_params_are_too_long(tmp_path):
    """Past MAX_TOKENS the model is refused before the parser sees it (bounded time)."""
    text = "".join(f"param p{i} = {i} mm\n" for i in range(30_000)) + PIN
    res, seconds = check_text(tmp_path, text)
    assert res.exit_code == 2 and seconds < 20, (seconds, res.output[:500])
    assert_well_formed(res.message)
    assert "too long" in res.output


def test_a_five_megabyte_line(tmp_path):
    res, seconds = check_text(tmp_path, PIN + "param x = 1" + " " * 5_000_000 + "+\n")
    assert res.exit_code == 2 and seconds < 10
    assert "ends in the middle" in res.output and len(res.output) < 2000  # the line is not echoed whole?


def test_deeply_nested_expression(tmp_path):
    for text in ("param x = " + "-" * 5000 + "1\n" + PIN,
                 "param x = " + " + ".join(["1 mm"] * 5000) + "\n" + PIN,
                 "param x = " + "(" * 5000 + "1" + ")" * 5000 + " + " + "sqrt(" * 500 + "1" + ")" * 500 + "\n" + PIN):
        res, seconds = check_text(tmp_path, text)
        assert res.exit_code == 2 and seconds < 10, res.output[:300]
        assert_well_formed(res.message)
        assert "nests more than" in res.output


def test_long_chain_of_forward_references_compiles(tmp_path):
    """Params used before they are defined, 3000 deep: resolved without exhausting the stack."""
    text = "".join(f"param p{i} = p{i + 1} + 1 mm\n" for i in range(3000)) + "param p3000 = 1 mm\n" + \
        PIN.replace("(0.025, 0)", "(p0 - 2975 mm, 0)")
    m = compile_text(text, "chain.mbs")
    assert m.q0[0] == pytest.approx(0.026)


def test_long_param_cycle_is_named(tmp_path):
    text = "".join(f"param p{i} = p{(i + 1) % 2000} + 1 mm\n" for i in range(2000)) + PIN
    res, _ = check_text(tmp_path, text)
    assert res.exit_code == 2 and "cycle" in res.output
    assert_well_formed(res.message)


def test_many_bodies_assemble_in_seconds():
    text = "".join(f"body b{i} {{ mass = 1 kg  inertia = 1 kg*m^2  position = ({i}, 0) }}\n"
                   f"joint j{i} = revolute(ground ({i}, 0), b{i})\n" for i in range(300))
    t0 = time.perf_counter()
    assemble(compile_text(text, "many.mbs"))
    assert time.perf_counter() - t0 < 10


def test_utf8_byte_order_mark_is_accepted(tmp_path):
    res, _ = check_text(tmp_path, "\ufeff".encode() + PIN.encode())
    assert res.exit_code == 0, res.output


def test_free_body_under_gravity_is_legal():
    """A body connected to nothing is only an error when nothing acts on it."""
    m = compile_text("body ball { mass = 1 kg  inertia = 1e-3 kg*m^2 }\ngravity (0, -9.81 m/s^2)\n", "b.mbs")
    q, qd = assemble(m)
    assert m.dof == 3
    with pytest.raises(ModelError, match="connected to nothing"):
        assemble(compile_text("body ball { mass = 1 kg  inertia = 1e-3 kg*m^2 }\n", "b.mbs"))


def test_under_constrained_mechanism_is_legal():
    """dof > 0 without a driver is a legal model (a pendulum swings)."""
    m = compile_text(PIN + "gravity (0, -9.81 m/s^2)\n", "p.mbs")
    assemble(m)
    assert m.dof == 1
