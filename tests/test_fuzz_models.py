"""Property-based fuzzing of the front end: random text and random mutations of the shipped
models go through parse → compile → assemble, and nothing but `ModelError` may come out.

Every `ModelError` must also be a good one: located (file:line:col), with a hint, and not
the compiler's "internal error" catch-all (which would hide a bug).

The default suite is derandomized (the same inputs on every run, ~2400 in all, about
20 s); set MBS_FUZZ_EXAMPLES=20000 to search longer with fresh random inputs.  Inputs that
once crashed are kept in `tests/broken_models/` as regressions.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from planar_mbs import catalog
from planar_mbs.mechanism.compile import compile_text
from planar_mbs.errors import ModelError
from planar_mbs.mechanism.kinematics import assemble

MODELS = Path(__file__).resolve().parents[1] / "models"
SHIPPED = {p.name: p.read_text(encoding="utf-8") for p in sorted(MODELS.glob("*.mbs"))}
N = int(os.environ.get("MBS_FUZZ_EXAMPLES", "0"))
FUZZ = settings(
    max_examples=N or 1200,
    deadline=None,
    derandomize=not N,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large],
)

KEYWORDS = ["param", "material", "body", "joint", "driver", "force", "gravity", "simulate", "include",
            "override"]
NAMES = ["crank", "rod", "slider", "ground", "steel", "speed", "clearance", "law", "x", "pi", "system",
         *catalog.names(catalog.JOINTS), catalog.CLEARANCE_JOINT, *catalog.names(catalog.LAWS),
         *catalog.names(catalog.INTEGRATORS), "rotation", "translation", "constant", "torque",
         "spring_damper", "rotational_spring_damper", "ramp", "harmonic", "polynomial", "bar", "box", "circle",
         "sqrt", "sin", "atan2", "mass", "inertia", "position", "angle", "velocity", "omega", "shape", "axis",
         "length", "E", "nu", "bearing_radius", "journal_radius", "restitution", "stiffness", "exponent",
         "friction", "t_end", "integrator", "rtol", "step", "max_steps", "relative_to", "motion", "nan",
         "inf"]
NUMBERS = ["0", "1", "-1", "0.3 mm", "5000 rpm", "207 GPa", "2.5e-4 kg*m^2", "1e-5", "1e400", "1e-400",
           "1e", "2.5e-", "1.2.3", "0,3", "9.81 m/s^2", "10 1/s", "4e10 N/m^1.5", "30 deg", "5 rev",
           "1 furlong", "3 mmm", ".5", "1e308", "0 kg", "1 kg", "1 s"]
PUNCT = ["{", "}", "(", ")", "=", ",", "+", "-", "*", "/", "^", ";", "#", '"', "\n", " ", "\t", "·",
         "\x00", "\ufeff", "é", "µ"]
INCLUDES = ['include "missing.mbs"', 'include "', 'include "models"', 'include "/dev/null"']
TOKENS = KEYWORDS + NAMES + NUMBERS + PUNCT + INCLUDES


def check(text: str, path: str = "<fuzz>") -> None:
    """Parse, compile and assemble; only a well-formed ModelError may escape."""
    try:
        assemble(compile_text(text, path))
    except ModelError as err:
        message = str(err)
        assert "internal error" not in err.message, message
        assert err.line > 0 and err.column > 0, message
        assert err.hint, message
        assert re.match(r"^\S.*:\d+:\d+: error: ", message), message


# ------------------------------------------------------------ (1) random text
token = st.one_of(
    st.sampled_from(TOKENS),
    st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=4),
    st.from_regex(r"[0-9]{1,4}(\.[0-9]{0,3})?([eE][+-]?[0-9]{0,3})?", fullmatch=True),
)
separator = st.sampled_from([" ", " ", "\n", "", "  "])


@st.composite
def random_text(draw):
    parts = draw(st.lists(st.tuples(token, separator), max_size=40))
    return "".join(t + s for t, s in parts)


@FUZZ
@given(random_text())
@example("")
@example("body")
@example("body x {")
@example('include "')
@example("param x = (" * 50)
def test_random_text_gives_only_model_errors(text):
    check(text)


@settings(FUZZ, max_examples=(N or 1200) // 3)
@given(st.text(max_size=200))
def test_arbitrary_unicode_gives_only_model_errors(text):
    check(text)


# ------------------------------------------------------------ (2) mutated shipped models
LEX = re.compile(r'#[^\n]*|"[^"\n]*"|\d+\.?\d*(?:[eE][+-]?\d+)?|\w+|\s+|.', re.S)


def tokens_of(text: str) -> list[str]:
    return LEX.findall(text)


def replacement(draw, tok: str) -> str:
    if re.fullmatch(r"\d+\.?\d*(?:[eE][+-]?\d+)?", tok):
        return draw(st.one_of(
            st.sampled_from(["0", "-0", "1e400", "1e-400", "1e", "00", "0.0", "1.", "-1", "1e308", "3.3.3"]),
            st.floats(allow_nan=False, allow_infinity=False).map(repr),
            st.integers(-10**6, 10**6).map(str)))
    if re.fullmatch(r"\w+", tok):
        return draw(st.sampled_from(NAMES + KEYWORDS))
    return draw(st.sampled_from(TOKENS))


@st.composite
def mutated_model(draw):
    name = draw(st.sampled_from(sorted(SHIPPED)))
    toks = tokens_of(SHIPPED[name])
    assert "".join(toks) == SHIPPED[name]
    for _ in range(draw(st.integers(1, 4))):
        if not toks:
            break
        i = draw(st.integers(0, len(toks) - 1))
        op = draw(st.sampled_from(["delete", "duplicate", "swap", "replace", "replace", "insert", "number"]))
        if op == "delete":
            del toks[i]
        elif op == "duplicate":
            toks.insert(i, toks[i])
        elif op == "swap":
            j = draw(st.integers(0, len(toks) - 1))
            toks[i], toks[j] = toks[j], toks[i]
        elif op == "replace":
            toks[i] = replacement(draw, toks[i])
        elif op == "insert":
            toks.insert(i, draw(st.sampled_from(TOKENS)) + draw(separator))
        else:  # change a number somewhere
            nums = [k for k, t in enumerate(toks) if re.fullmatch(r"\d+\.?\d*(?:[eE][+-]?\d+)?", t)]
            if nums:
                k = draw(st.sampled_from(nums))
                toks[k] = replacement(draw, toks[k])
    return name, "".join(toks)


@pytest.mark.slow  # 1200 compiled models (~10 s); the random-text fuzz stays in the default run
@pytest.mark.filterwarnings("error::RuntimeWarning")  # a hostile number must not leak numpy's warnings
@FUZZ
@given(mutated_model())
def test_mutated_shipped_models_give_only_model_errors(case):
    name, text = case
    check(text, str(MODELS / name))  # includes resolve next to the shipped models


def test_shipped_models_pass_the_same_check():
    for name, text in SHIPPED.items():
        assemble(compile_text(text, str(MODELS / name)))


@settings(FUZZ, max_examples=(N or 1200) // 6)
@given(st.binary(max_size=120), st.sampled_from(sorted(SHIPPED)))
def test_bytes_spliced_into_a_model_give_only_model_errors(junk, name):
    """Arbitrary bytes (not necessarily UTF-8) spliced into a shipped model, as `load_model` reads them."""
    from planar_mbs.language.parse import decode_model

    data = SHIPPED[name].encode()
    cut = len(junk) * 7 % (len(data) + 1)
    path = str(MODELS / name)
    try:
        text = decode_model(data[:cut] + junk + data[cut:], path)
    except ModelError as err:
        assert err.line > 0 and err.hint and "UTF-8" in err.message
        return
    check(text, path)
