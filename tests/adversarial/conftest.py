"""Fixtures of the adversarial suite: a sandbox folder holding a model (with an include), a
finished run and a finished sweep of it, all copied fresh for each case."""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from advhelp import mbs, write_model  # noqa: E402


@pytest.fixture(scope="session")
def _made(tmp_path_factory):
    """One run and one sweep of the sandbox model, computed once per session."""
    base = tmp_path_factory.mktemp("adversarial_base")
    model = write_model(base)
    out = mbs("run", model, "-o", base / "run.h5", "-q", cwd=base, timeout=300)
    assert out.code == 0, out.output
    out = mbs("sweep", model, "-P", "speed=3000rpm,4000rpm", "-o", base / "sweep.h5", "-q", "-j", "1",
              "--t-end", "1ms", "--no-section", cwd=base, timeout=300)
    assert out.code == 0, out.output
    return base


@pytest.fixture
def sandbox(tmp_path, _made):
    """A fresh folder with mech.mbs (including parts/bodies.mbs), run.h5 and sweep.h5."""
    box = tmp_path / "box"
    shutil.copytree(_made, box, symlinks=True)
    return box
