"""Every complete model (```mbs) of docs/contact.md compiles and runs a few steps."""
import re
from pathlib import Path

import pytest

from planar_mbs import compile_text, simulate

DOC = Path(__file__).resolve().parent.parent / "docs" / "contact.md"
FENCE = re.compile(r"^```mbs[ \t]*\n(.*?)^```", re.S | re.M)
BLOCKS = FENCE.findall(DOC.read_text(encoding="utf-8"))


def test_contact_md_has_an_example_of_each_new_element():
    text = "\n".join(BLOCKS)
    for element in ("lubricated_revolute", "clearance_translational", "contact"):
        assert f"= {element}(" in text


@pytest.mark.parametrize("text", BLOCKS)
def test_every_model_of_contact_md_compiles_and_runs(text):
    model = compile_text(text, "contact_md.mbs")
    res = simulate(model, t_end="2 ms")
    assert res.attrs["complete"]
