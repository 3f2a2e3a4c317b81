"""The README's first command: its Poincaré map has enough points for a verdict."""
import re
import shlex
from pathlib import Path

import numpy as np

from planar_mbs.results.analysis import classify

ROOT = Path(__file__).resolve().parents[1]


def test_readme_job_runs_enough_revolutions_for_a_poincare_map():
    first = re.search(r"```bash\n(.*?)\n```", (ROOT / "README.md").read_text(encoding="utf-8"), re.S).group(1)
    run = next(c for c in first.split("&&") if " run " in c)
    args = shlex.split(run)
    revolutions = float(args[args.index("--revolutions") + 1])
    # the default figures skip the first revolution: one section point per revolution after it
    points = int(revolutions) - 1
    assert points >= 20  # `mbs analyze` needs 20 section points for a verdict
    assert classify(np.zeros((points, 2)), [1.0, 1.0]).verdict != "undetermined"
