"""A wear run's file as a rerun recording (`mbs view WEAR.h5`): the worn bearing, update by update.

Everything goes on one sequence timeline, ``update`` (0: the unworn bearing).  Entity paths::

    model/source                  TextDocument, static: what is drawn, the magnification
    wear/<joint>/nominal          LineStrips2D, static: the unworn bearing circle (radius R_B, mm)
    wear/<joint>/profile          LineStrips2D: the worn profile R_B + magnify x depth, bearing frame (mm)
    wear/<joint>/deepest          Points2D: its deepest node, labelled with the depth (µm) and angle
    signals/<joint>/<quantity>    Scalars: worn_volume (mm²), max_wear_depth (µm), max_wear_angle (deg),
                                  peak_contact_force (N), worn_time (s; cycles where the run had a period)

The depth is magnified so that the deepest wear of the last update draws a quarter of the radius, unless
a magnification is given.  The file is written beside its name and moved over it once whole
(`rerun_log.record_run` does the same for a run).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..lazy import lazy
from . import rerun_log

wear = lazy("planar_mbs.run.wear")

TIMELINE = "update"
SHOWN = 0.25  # the deepest wear drawn as this share of the bearing's radius (automatic magnification)


def magnification(history, magnify: float | None = None) -> float:
    """`magnify`, or the factor that draws the deepest wear as SHOWN of the radius (1 if nothing wore)."""
    if magnify is not None:
        return float(magnify)
    deepest = max(float(np.max(d)) for d in history.depths)
    return SHOWN * history.radius / deepest if deepest > 0 else 1.0


def profile_points(history, i: int, magnify: float) -> np.ndarray:
    """The closed outline of update `i`'s profile, R_B + magnify x depth at each node, in mm."""
    r = (history.radius + magnify * np.asarray(history.depths[i])) * 1e3
    th = history.theta
    pts = np.stack([r * np.cos(th), r * np.sin(th)], 1)
    return np.vstack([pts, pts[:1]])


def _series(history, period: float) -> dict[str, np.ndarray]:
    sig = history.signals()
    j = history.joint
    worn = sig["worn_time"] / period if period else sig["worn_time"]
    return {"worn_volume": sig[f"{j}.worn_volume"] * 1e6, "max_wear_depth": sig[f"{j}.max_wear_depth"] * 1e6,
            "max_wear_angle": np.degrees(sig[f"{j}.max_wear_angle"]), "peak_contact_force":
            sig[f"{j}.peak_contact_force"], "worn_cycles" if period else "worn_time": worn}


def _log(rr, rec, history, facts: dict, magnify: float) -> int:
    """Log the static drawing, then each update's profile and signals; the number of updates logged."""
    j, n = history.joint, len(history.depths)
    rec.log("model/source", rr.TextDocument(
        f"wear of `{j}` in {facts.get('model', '') or 'a model'}: {n - 1} updates; the bearing's profile in its "
        f"own frame, the depth magnified {magnify:.4g} times", media_type="text/plain"), static=True)
    circle = profile_points(history, 0, 0.0)
    rec.log(f"wear/{j}/nominal", rr.LineStrips2D([circle], colors=[(160, 160, 160)]), static=True)
    for i in range(n):
        rec.set_time(TIMELINE, sequence=i)
        rec.log(f"wear/{j}/profile", rr.LineStrips2D([profile_points(history, i, magnify)], colors=[(214, 39, 40)]))
        k = int(np.argmax(history.depths[i]))
        rec.log(f"wear/{j}/deepest", rr.Points2D([profile_points(history, i, magnify)[k]], radii=rr.Radius.ui_points(4),
                labels=[f"{history.depths[i][k] * 1e6:.3g} µm at {math.degrees(history.theta[k]):.0f}°"]))
    cols = [rr.TimeColumn(TIMELINE, sequence=np.arange(n))]
    for name, values in _series(history, float(facts.get("period", 0.0))).items():
        rec.send_columns(f"signals/{j}/{name}", indexes=cols, columns=rr.Scalars.columns(scalars=values))
    return n


def record_wear(path, out, magnify: float | None = None, recording_id: str | None = None) -> tuple[int, float]:
    """Write the recording of the wear file `path` to `out` (.rrd); (updates logged, magnification)."""
    history = wear.load_history(path)
    facts = wear.saved_facts(path, history.joint)
    factor = magnification(history, magnify)
    rr = rerun_log._rerun()
    rec = rr.RecordingStream(rerun_log.APPLICATION_ID, recording_id=recording_id, send_properties=False)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    part, moved = rerun_log._part_beside(Path(out)), False
    try:
        rec.save(str(part))
        n = _log(rr, rec, history, facts, factor)
        rec.disconnect()
        rerun_log._move_into_place(part, Path(out))
        moved = True
    finally:
        if not moved:
            rec.disconnect()
            part.unlink(missing_ok=True)
    return n, factor
