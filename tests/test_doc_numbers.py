"""Numbers the pages of docs/ state about the program, checked against the program: a page whose
number drifts from what the program gives fails here."""
from __future__ import annotations

import re
from pathlib import Path

import planar_mbs as mbs

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "models" / "slider_crank_clearance_a.mbs"


def test_the_complete_model_of_the_language_page_is_the_shipped_one():
    """docs/language.md §11 says its model is shipped as models/slider_crank_clearance_a.mbs: the same
    settings (integrator, tolerances, output step, end time) and values of the parameters it shows."""
    text = (ROOT / "docs" / "language.md").read_text(encoding="utf-8")
    section = text[text.index("## 11. A complete model"):text.index("## 12.")]
    block = re.search(r"```mbs\n(.*?)```", section, re.S)[1]
    page, shipped = mbs.compile_text(block, "page.mbs"), mbs.load_model(SHIPPED)
    assert page.settings == shipped.settings
    assert {k: shipped.parameters.get(k) for k in page.parameters} == page.parameters


def test_the_plots_page_states_the_shipped_tolerance():
    """docs/plots.md's performance section names the tolerance the model ships with."""
    text = (ROOT / "docs" / "plots.md").read_text(encoding="utf-8")
    stated = float(re.search(r"it now ships with rtol (\S+?) --", text)[1])
    assert stated == mbs.load_model(SHIPPED).settings.rtol
