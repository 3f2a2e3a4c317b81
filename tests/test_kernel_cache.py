"""The compiled-code cache follows every kernel source: changing a contact law in a copy of
the package (whose numba cache holds the time loop compiled with the old law) gives the new
physics, not the cached old one."""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import kernel_models as K
import planar_mbs
from planar_mbs.kernel import make_workspace, nobs
from planar_mbs.kernel.loop import observe
from planar_mbs.model import ContactLaw

TESTS = Path(__file__).resolve().parent
# the contact force over K delta^n of a penetrating Hertz journal, read from `observe` (loop.py)
PROBE = """
import json, numpy as np, kernel_models as K
from planar_mbs.kernel import make_workspace, nobs
from planar_mbs.kernel.loop import observe
from planar_mbs.model import CP_EXPONENT, CP_STIFFNESS, ContactLaw
km, q0, qd0 = K.free_journal(law=ContactLaw.HERTZ, offset=(1.01e-4, 0.0))
row = np.zeros(nobs(km))
contact = np.array([[1.0, 1.0, 0.0]])
st = observe(km, K.cfg(), 0.0, np.concatenate([q0, qd0]), contact, make_workspace(km), row)
p = km.clearance_param[0]
print(json.dumps([int(st), row[9 + 4] / (p[CP_STIFFNESS] * row[9 + 3] ** p[CP_EXPONENT])]))
"""


def probe(root: Path) -> float:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), str(TESTS)])}
    res = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=900, env=env,
                         cwd=root)
    assert res.returncode == 0, res.stderr
    st, ratio = json.loads(res.stdout.strip().splitlines()[-1])
    assert st == 0
    return ratio


@pytest.mark.slow
def test_changed_contact_law_is_recompiled(tmp_path):
    # warm the cache of the installed package (observe and everything it calls), then copy it
    # together with that cache
    km, q0, qd0 = K.free_journal(law=ContactLaw.HERTZ, offset=(1.01e-4, 0.0))
    observe(km, K.cfg(), 0.0, np.concatenate([q0, qd0]), np.array([[1.0, 1.0, 0.0]]), make_workspace(km),
            np.zeros(nobs(km)))
    src = Path(planar_mbs.__file__).resolve().parent
    shutil.copytree(src, tmp_path / "planar_mbs")
    assert probe(tmp_path) == pytest.approx(1.0, rel=1e-12)  # the copy runs (from its cache)
    contact = tmp_path / "planar_mbs" / "kernel" / "contact.py"
    text = contact.read_text()
    new, n = re.subn(r"(    if law == HERTZ:[^\n]*\n        return )dn, 0\n", r"\g<1>2.0 * dn, 0\n", text)
    assert n == 1
    contact.write_text(new)
    assert probe(tmp_path) == pytest.approx(2.0, rel=1e-12)  # the new law, not the cached one
