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
from planar_mbs.mechanism.compile import compile_text
from planar_mbs.language.parse import parse_statements

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


# ---------------------------------------------------------------- every fragment compiles
# The elements fragments refer to without declaring them; a fragment's own declarations win.
STOCK = """
param speed = 5000 rpm
material steel { E = 207 GPa  nu = 0.3 }
body crank  { mass = 0.3 kg  inertia = 1e-5 kg*m^2  position = (0.025, 0) }
body rod    { mass = 0.2 kg  inertia = 2.5e-4 kg*m^2  position = (0.11, 0) }
body slider { mass = 0.1 kg  inertia = 1e-4 kg*m^2  position = (0.17, 0) }
body rocker { mass = 0.1 kg  inertia = 1e-4 kg*m^2  position = (0.1, 0.05) }
body frame  { mass = 1 kg  inertia = 1e-2 kg*m^2 }
body arm    { mass = 0.1 kg  inertia = 1e-4 kg*m^2  position = (0.15, 0) }
body guide  { mass = 0.1 kg  inertia = 1e-4 kg*m^2 }
body pin    { mass = 0.1 kg  inertia = 1e-4 kg*m^2 }
body wheel  { mass = 2 kg  inertia = 0.01 kg*m^2 }
"""


def _in_context(body: str) -> str:
    """The fragment after the stock elements it does not declare itself (none with an include)."""
    if re.search(r"^\s*include\b", body, re.M):
        return body
    own = {(s.kind, s.name) for s in parse_statements(body, "fragment")}
    own_names = {name for _, name in own}
    stock = [s for s in parse_statements(STOCK, "stock")]
    lines = STOCK.strip().splitlines()
    keep = [line for line, st in zip(lines, stock) if st.name not in own_names]
    return "\n".join(keep) + "\n" + body


@pytest.mark.parametrize("kind, body", [p for p in examples() if p.values[0] == "mbs fragment"])  # the tutorial: test_tutorial
def test_every_fragment_compiles_in_context(kind, body):
    model = compile_text(_in_context(body), str(ROOT / "models" / "doc_fragment.mbs"))
    assert model.nbody >= 1


# keywords a reader looks for: each appears in at least one example block, not only in prose
IN_EXAMPLES = ["max_steps", "h_min", "h_max", "atol", "exponent", "bearing_material", "journal_material",
               "velocity", "actuator", "motion =", "phase", "dop853", "rk4", "dopri5", "projection",
               "relative_to", "initial", "friction", "stiffness", "restitution", "journal_radius", "ramp",
               "harmonic", "polynomial", "spring_damper", "rotational_spring_damper", "constant(", "torque(",
               "weld", "revolute_revolute", "revolute_translational", "override", "include", "gravity",
               *catalog.names(catalog.LAWS)]


def test_every_keyword_has_an_example():
    code = "\n".join(p.values[1] for p in examples())
    assert [w for w in IN_EXAMPLES if not re.search(rf"(?<![\w]){re.escape(w)}", code)] == []
