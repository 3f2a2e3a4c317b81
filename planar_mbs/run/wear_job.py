"""A wear run as `mbs run` makes it (run/wear.py does the work): the joint that wears, the checks of a file
to continue or to replace, and Ctrl-C/SIGTERM, which stop the run where it is and leave the file of the
last finished update (each update's file replaces the previous one whole)."""
from __future__ import annotations

import json
import math
import os
from contextlib import contextmanager
from pathlib import Path

from ..errors import ModelError
from ..lazy import lazy
from ..mechanism.model import Model
from .wear import STEPPER_SETTINGS, Archard, WearRun, load_history, saved_facts

h5py = lazy("h5py")
hdf5 = lazy("planar_mbs.results.hdf5")
simulation = lazy("planar_mbs.run.simulation")

COMPARED = ("coefficient", "interval", "factor", "nodes", "depth_step")  # what a resumed run must share


def wearing_joint(model: Model) -> str | None:
    """The clearance joint that declares `wear` (None: none does); a model with several is refused."""
    names = list(model.clearance_wear)
    if len(names) > 1:
        raise ModelError(f"joints {', '.join(f'`{n}`' for n in names)} all declare `wear`: a wear run wears one "
                         "joint", model.source_path, hint="keep `wear = archard(...)` on one joint, e.g. with an "
                         "`override joint` in a model that includes this one")
    return names[0] if names else None


def holds_wear(path) -> bool:
    """True if `path` is an HDF5 file with a wear history (`WearRun.save`)."""
    return hdf5.results_kind(Path(path)) == "wear"


def saved_settings(path, joint: str) -> dict:
    """The integration settings the saved run used (`simulate`'s keywords; {} for a file without them)."""
    a = saved_facts(path, joint)
    return {k: a[f"settings.{k}"] for k in STEPPER_SETTINGS if f"settings.{k}" in a}


def _refuse(path, message: str, hint: str):
    return ModelError(f"cannot resume {path}: {message}", "--resume", hint=hint)


def _same_model(model: Model, path, joint: str) -> None:
    """Refuse a file made from another model file, with other parameters or another wear of the joint."""
    a = saved_facts(path, joint)
    saved = str(a.get("model", ""))
    now = os.path.abspath(model.source_path) if model.source_path else ""
    new = "start a new wear run in another file (-o), or resume with the model it was made from"
    if saved and now and os.path.realpath(saved) != os.path.realpath(now):
        raise _refuse(path, f"it was made from {saved}, not {now}", new)
    before = json.loads(a.get("parameters", "{}"))
    changed = [f"{k} = {before.get(k)} there, {v} here" for k, v in model.parameters.items() if before.get(k, v) != v]
    if changed:
        raise _refuse(path, "the parameters differ: " + "; ".join(changed), "give the --set values of the run, or "
                      + new)
    with h5py.File(str(path), "r", locking=False) as f:
        shape = f[f"wear/{joint}/state/y"].shape, f[f"wear/{joint}/state/contact"].shape[0]
    if shape != ((2 * model.ncoord + model.nstate,), model.nclearance):
        raise _refuse(path, "its saved state is not one of this model (other bodies or joints)", new)
    wear = Archard.of(model, joint)
    differ = [f"{k} = {a.get(k, 0.0):g} there, {getattr(wear, k):g} here" for k in COMPARED
              if not math.isclose(float(a.get(k, 0.0)), float(getattr(wear, k)), rel_tol=1e-12)]
    if differ:
        raise _refuse(path, f"the wear of `{joint}` differs: " + "; ".join(differ), new)


def check_resume(model: Model, path, updates: int | None) -> tuple[str, int]:
    """(joint, total updates) of a wear run in `path` that `model` may continue to `updates` (None: the
    larger of the file's total and the model's): refused (`ModelError`, exit 2) for a missing file, one
    without a wear history, one made from another model, or a total it already holds."""
    joint = wearing_joint(model)
    if not Path(path).is_file():
        raise _refuse(path, "no such file", "start the wear run without --resume (or name its file with -o)")
    if not holds_wear(path):
        raise _refuse(path, "it holds no wear history", "give the file a wear run wrote (`mbs run MODEL -o FILE`)")
    history = load_history(path)
    if history.joint != joint:
        raise _refuse(path, f"it holds the wear of `{history.joint}`, the model wears `{joint}`",
                      "start a new wear run in another file (-o)")
    _same_model(model, path, joint)
    done = len(history.depths) - 1
    total = updates or max(history.wear.updates, Archard.of(model, joint).updates)
    if total <= done:
        raise _refuse(path, f"it holds {done} updates already", f"give a larger total, e.g. `--updates {2 * done}`")
    return joint, total


def check_fresh(path, model: Model, overwrite: bool) -> bool:
    """True if `path` holds a wear history (which a new wear run replaces); an unfinished one of this
    model's joint is refused without `overwrite` (`--resume` continues it)."""
    if not holds_wear(path):
        return False
    history = load_history(path)
    if not overwrite and history.joint == wearing_joint(model) and len(history.depths) <= history.wear.updates:
        raise ModelError(f"{path} holds an unfinished wear run ({len(history.depths) - 1} of {history.wear.updates} "
                         "updates); a new run would replace it", "--output",
                         hint="continue it with --resume, or pass --overwrite to start again")
    return True


def start(model: Model, joint: str, path, resume: bool, updates: int | None, **settings) -> WearRun:
    """The wear run to make: continued from `path` (its saved settings unless given), or a new one
    (`updates`: its total instead of the model's)."""
    if resume:
        given = {k: v for k, v in settings.items() if v is not None}
        saved = {k: v for k, v in saved_settings(path, joint).items()
                 if not ("per_rev" in given and k == "output_step")}  # --per-rev replaces the saved output step
        settings = {**saved, **given}
        return WearRun.resume(model, path, updates=updates, **settings)
    wear = Archard.of(model, joint)
    if updates is not None:
        wear = Archard(wear.coefficient, wear.interval, wear.factor, updates, wear.nodes, wear.depth_step)
    return WearRun(model, joint, wear, **settings)


def left_behind(path) -> None:
    """Remove the half-written file of an update that a signal stopped (`WearRun.save` writes PATH.part)."""
    part = Path(f"{path}.part")
    if part.is_file():
        part.unlink()


@contextmanager
def stoppable():
    """While a wear run works, SIGINT and SIGTERM raise `simulation.RunInterrupted` where it is (between
    two calls of the kernel): the file on disk stays that of the last finished update
    (`simulation.interrupts_handled`: only the main thread installs handlers)."""
    def stop(signum, frame):
        raise simulation.RunInterrupted(signum)

    with simulation.interrupts_handled(stop):
        yield
