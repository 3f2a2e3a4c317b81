"""Any model text of n bytes is accepted or refused in time linear in n: 1 MB of pathological
input (long numbers, names, units, lines; deep nesting; many statements, includes, errors)
parsed or refused within a 2 s hang bound, with exit 2 and a positioned message when refused.
A 100 000-digit number once took minutes (a regular expression retried every split of it)."""
from __future__ import annotations

import time

import pytest

from advhelp import assert_clean, mbs, snapshot
from planar_mbs.errors import ModelError
from planar_mbs.language.parse import parse_expression, parse_model

MB = 2**20
BOUND = 2.0  # s: a hang bound, not a speed requirement


def fill(unit: str, prefix: str = "param a = ", suffix: str = "\n") -> str:
    return prefix + unit * ((MB - len(prefix) - len(suffix)) // len(unit)) + suffix


PATHOLOGICAL = {
    "digits": fill("1"),
    "digits-then-e": fill("1", suffix="e\n"),
    "digits-then-dot-dot": fill("1", suffix=".5.\n"),
    "decimal-digits": fill("1", prefix="param a = 1."),
    "decimal-then-letter": fill("1", prefix="param a = 1.", suffix="x\n"),
    "exponent-digits": fill("9", prefix="param a = 1e"),
    "negative-exponent-digits": fill("9", prefix="param a = 1e-"),
    "digits-then-unit": fill("1", suffix=" mm\n"),
    "digits-in-name": fill("1", prefix="param a"),
    "long-name": fill("a", prefix="param "),
    "long-name-no-value": fill("a", prefix="param ", suffix=""),
    "long-unit": fill("m", prefix="param a = 1 "),
    "unit-product": fill("m*", prefix="param a = 1 ", suffix="m\n"),
    "unit-product-open": fill("m*", prefix="param a = 1 "),
    "unit-powers": fill("m^2*", prefix="param a = 1 ", suffix="s\n"),
    "spaces-after-number": fill(" ", prefix="param a = 1", suffix="=\n"),
    "tabs-in-line": fill("\t", prefix="param a = 1", suffix="x\n"),
    "parentheses": "param a = " + "(" * (MB // 2 - 8) + "1" + ")" * (MB // 2 - 8) + "\n",
    "open-parentheses": fill("("),
    "close-parentheses": fill(")"),
    "negations": fill("-", suffix="1\n"),
    "plus-chain": fill("1+", suffix="1\n"),
    "power-chain": fill("2^", suffix="1\n"),
    "product-chain": fill("1*", suffix="1\n"),
    "nested-calls": fill("f(", suffix="1\n"),
    "long-vector": fill("1,", prefix="param a = (", suffix="1)\n"),
    "comment": fill("x", prefix="# "),
    "unclosed-string": fill("x", prefix='include "'),
    "long-include-name": fill("x", prefix='include "', suffix='"\n'),
    "open-braces": fill("body b {"),
    "close-braces": fill("}", prefix=""),
    "fields": fill(" mass = 1 kg", prefix="body b {", suffix="}\n"),
    "many-params": "".join(f"param p{i} = {i} mm\n" for i in range(MB // 20))[:MB],
    "many-duplicate-params": "param a = 1\n" * (MB // 12),
    "many-errors": "param = \n" * (MB // 9),
    "newlines": fill("\n", prefix=""),
    "nul-bytes": fill("\0", prefix="param a = 1"),
    "semicolons": fill(";", prefix="param a = 1"),
    "keywords": fill("param ", prefix=""),
    "equals": fill("=", prefix="param a "),
    "commas": fill(",", prefix="param a = 1"),
    "dots": fill(".", prefix="param a = 1"),
}


def parse_or_refuse(text: str) -> tuple[str, float]:
    start = time.perf_counter()
    try:
        parse_model(text, "big.mbs")
        outcome = "accepted"
    except ModelError as err:
        outcome = str(err)
        assert "big.mbs" in outcome and "error" in outcome
    return outcome, time.perf_counter() - start


@pytest.mark.parametrize("name", sorted(PATHOLOGICAL))
def test_one_megabyte_parsed_or_refused_in_bounded_time(name):
    text = PATHOLOGICAL[name]
    assert MB - 64 <= len(text) <= MB + 64
    outcome, seconds = parse_or_refuse(text)
    assert seconds < BOUND, f"{name}: {seconds:.2f} s ({outcome[:200]})"


@pytest.mark.parametrize("name", ["digits", "nested-calls", "unit-product-open", "many-errors", "nul-bytes"])
def test_one_megabyte_through_mbs_check(sandbox, name):
    (sandbox / "big.mbs").write_text(PATHOLOGICAL[name])
    before = snapshot(sandbox)
    out = mbs("check", "big.mbs", cwd=sandbox)
    assert_clean(out, 2, "big.mbs", "error", before=before, folder=sandbox, bound=BOUND)
    assert len(out.output) < 5000  # a window of the line, not a megabyte of it


@pytest.mark.parametrize("value", ["1" * 100_000, "1." + "1" * 100_000, "1e" + "9" * 100_000, "(" * 100_000,
                                   "-" * 100_000 + "1", "1" + " m" * 50_000, "a" * 100_000])
def test_long_set_values(value):
    start = time.perf_counter()
    try:
        parse_expression(value)
    except ModelError as err:
        assert "--set" in str(err)
    assert time.perf_counter() - start < BOUND


# ---------------------------------------------------------------- many includes
def test_include_chain(tmp_path):
    """90 files each including the next: accepted."""
    for i in range(90):
        nxt = f'include "f{i + 1}.mbs"\n' if i < 89 else ""
        (tmp_path / f"f{i}.mbs").write_text(f"param p{i} = {i}\n" + nxt)
    start = time.perf_counter()
    spec = parse_model((tmp_path / "f0.mbs").read_text(), str(tmp_path / "f0.mbs"))
    assert len(spec.statements) == 90 and len(spec.include_files) == 89
    assert time.perf_counter() - start < BOUND


@pytest.mark.parametrize("count,message", [(101, "more than 100 included files"), (60_000, "too long")])
def test_too_many_includes_refused(tmp_path, count, message):
    (tmp_path / "p.mbs").write_text("# nothing\n")
    text = 'include "p.mbs"\n' * count
    (tmp_path / "m.mbs").write_text(text)
    start = time.perf_counter()
    with pytest.raises(ModelError, match=message):
        parse_model(text, str(tmp_path / "m.mbs"))
    assert time.perf_counter() - start < BOUND


def test_include_fan_out_refused(tmp_path):
    """Each of 10 files includes the next one 10 times: 10^10 inclusions, refused at once."""
    for i in range(10):
        body = f'include "f{i + 1}.mbs"\n' * 10 if i < 9 else "param a = 1\n"
        (tmp_path / f"f{i}.mbs").write_text(body)
    start = time.perf_counter()
    with pytest.raises(ModelError, match="more than 100 included files"):
        parse_model((tmp_path / "f0.mbs").read_text(), str(tmp_path / "f0.mbs"))
    assert time.perf_counter() - start < BOUND


def test_included_files_over_the_size_limit(tmp_path):
    big = tmp_path / "big.mbs"
    with open(big, "wb") as f:
        f.truncate(17 * MB)  # sparse: no disk used
    (tmp_path / "m.mbs").write_text('include "big.mbs"\n')
    with pytest.raises(ModelError, match="exceed 16 MB"):
        parse_model('include "big.mbs"\n', str(tmp_path / "m.mbs"))


def test_model_file_over_the_size_limit(sandbox):
    with open(sandbox / "huge.mbs", "wb") as f:
        f.truncate(100 * MB)
    before = snapshot(sandbox)
    out = mbs("check", "huge.mbs", cwd=sandbox)
    assert_clean(out, 2, "limited to 16 MB", before=before, folder=sandbox, bound=BOUND)
