"""Where a run's results go when no output is named: results/<model name>.h5, never over another run.

`default_output` names the file after the model and the ``--set`` values; `beside_another_run`
moves a run whose settings differ from the run already in that file to a name beside it carrying
the options given (results/a_n=100.h5); `make_results_folder` makes results/, ignored by git.
"""
from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

from ..errors import ModelError
from ..results.hdf5 import read_results
from .simulation import run_settings

_COMPARED = ("t_end", "output_step", "integrator", "rtol", "atol", "step")  # a run that differs only in its time


def _tag(pairs) -> str:
    """``_name=value`` for each pair, each value kept to letters, digits and ``.+-`` (a file name)."""
    return "".join(f"_{name}={re.sub(r'[^A-Za-z0-9.+-]', '', value)}" for name, value in pairs)


def default_output(model: Path, sets: dict[str, str]) -> Path:
    """results/<model name>.h5, with the --set values in the name (results/a_speed=2500rpm.h5), so a
    run with other values never replaces the previous one; results/ is ignored by git."""
    return Path("results") / f"{model.stem}{_tag(sets.items())}.h5"


def beside_another_run(out: Path, model, changes: dict, given: dict) -> Path:
    """The default output `out`; or, when it holds a run with settings other than the `model`'s with
    its `changes` (another `-n`, `--t-end`, step or tolerance), a name beside it carrying the options
    `given` (results/a_n=100.h5): a default name never replaces the results of a run that differs in
    more than its time."""
    if not out.is_file():
        return out
    try:
        before = dict(read_results(out).attrs.get("settings") or {})
    except Exception:  # noqa: BLE001  (not a results file: the checks of the output deal with it)
        return out
    settings = run_settings(model, **changes)
    now = {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}
    if all(k in before and (before[k] == now[k] or (isinstance(now[k], float) and math.isclose(before[k], now[k])))
           for k in _COMPARED):
        return out
    text = lambda v: f"{v:g}" if isinstance(v, float) else str(v)  # noqa: E731  (-n 100 -> n=100)
    tag = _tag((opt, text(v)) for opt, v in given.items() if v is not None)
    return out.with_name(f"{out.stem}{tag or '_other'}{out.suffix}")


def make_results_folder(folder: Path) -> None:
    """The default output's folder (results/), ignored by git; a folder that cannot be made is exit 2."""
    try:
        folder.mkdir(parents=True)
        (folder / ".gitignore").write_text("# made by `mbs run`: outputs are not sources\n*\n")
    except OSError as exc:
        raise ModelError(f"cannot create the folder `{folder}` for the results: {exc.strerror or exc}",
                         "--output", hint="run from a folder you can write, or give an output with -o") from None
