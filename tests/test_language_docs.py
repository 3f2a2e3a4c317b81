"""Every ```mbs example of docs/language.md and docs/tutorial.md parses; complete
models (```mbs) also compile.

Blocks fenced as ```mbs fragment only need to parse (they use bodies defined
elsewhere); blocks fenced as ```mbs are whole models and are compiled as if
they lived in models/ (so an include of a shipped model resolves).
"""
import re
from pathlib import Path

import pytest

from planar_mbs import catalog
from planar_mbs.compile import compile_text
from planar_mbs.parse import parse_statements

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "language.md"
DOCS = [DOC, ROOT / "docs" / "tutorial.md"]
FENCE = re.compile(r"^```(mbs(?: fragment)?)[ \t]*\n(.*?)^```", re.S | re.M)


def examples(docs=(DOC,)):
    params = []
    for doc in docs:
        text = doc.read_text(encoding="utf-8")
        params += [pytest.param(m.group(1), m.group(2), id=f"{doc.stem}:{text[:m.start()].count(chr(10)) + 1}")
                   for m in FENCE.finditer(text)]
    return params


def test_there_are_examples_of_both_kinds():
    kinds = [p.values[0] for p in examples()]
    assert kinds.count("mbs") >= 2 and kinds.count("mbs fragment") >= 8


@pytest.mark.parametrize("kind, body", examples(DOCS))
def test_example(kind, body):
    statements = parse_statements(body, "docs/language.md")
    assert statements
    if kind == "mbs":
        model = compile_text(body, str(ROOT / "models" / "doc_example.mbs"))
        assert model.nbody >= 1


def test_every_keyword_and_element_type_is_documented():
    text = DOC.read_text(encoding="utf-8")
    words = ["param", "material", "body", "joint", "driver", "force", "gravity", "simulate", "include",
             "override", *catalog.names(catalog.JOINTS), catalog.CLEARANCE_JOINT,
             "rotation", "translation", "ramp", "harmonic", "polynomial", "constant",
             "torque", "spring_damper", "rotational_spring_damper", "bar", "box", "circle", "relative_to",
             "initial", *catalog.names(catalog.LAWS), *catalog.names(catalog.INTEGRATORS),
             "projection", "max_steps", "h_min", "h_max",
             "alpha", "beta", "output_step", "friction", "exponent", "stiffness", "restitution",
             "bearing_material", "journal_material", "journal_radius", "bearing_radius", "velocity", "omega"]
    missing = [w for w in words if f"`{w}" not in text and f"{w}(" not in text and f"{w} " not in text]
    assert not missing


def test_generated_lists_match_the_catalog():
    """The joint, law and integrator tables of language.md are the catalog's
    (regenerate them with `python -m planar_mbs.catalog --docs`)."""
    blocks = catalog.doc_blocks(DOC.read_text(encoding="utf-8"))
    assert blocks == catalog.docs_lists(), "run `python -m planar_mbs.catalog --docs`"
