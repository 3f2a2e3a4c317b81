"""A rerun recording of a run: the moving mechanism, forces, every signal, contact events.

Everything goes on one timeline, ``sim_time`` (a duration in seconds of simulated
time), through rerun's columnar ``send_columns`` API: one call per entity for the
whole run, no per-sample Python loop, so logging costs a small fraction of the
time loop (measured in docs/plots.md).

Entity paths::

    model/source                      TextDocument, static: the .mbs text
    mechanism/ground                  static: ground pins and slider guides
    mechanism/bodies/<body>           LineStrips2D: the link through its joint points
                                      (a box for a body on a translational joint)
    mechanism/com                     Points2D: centres of mass
    mechanism/joints                  Points2D: ideal-joint pins
    mechanism/clearance/<c>/bearing   Ellipses2D: bearing circle (radius R_J + magnify c)
    mechanism/clearance/<c>/journal   Ellipses2D: journal circle (radius R_J) at the
                                      bearing centre + magnify * eccentricity
    forces/joints/<joint>             Arrows2D: reaction on the joint's second body
    forces/contact/<c>                Arrows2D: contact force on the journal, drawn
                                      from the contact point
    signals/<entity>/<quantity>       Scalars: every signal, as a peak-preserving envelope
                                      (per frame bin the first sample, the min and the max)
    events/contact                    TextLog: contact onsets (with impact velocity)
    events/friction                   TextLog: where each element's friction sticks and slips
                                      (a stuck contact's force arrow is drawn green)
    poincare/<x>_vs_<y>               Points2D: Poincaré points, normalised to [-1, 1]
                                      (the scale is in poincare/axes)

Geometry is frame-decimated (`fps` frames per simulated second).  Scalars are
decimated by `envelope_indices`: per bin of 1/`signal_rate` simulated seconds (default:
the frame rate) the first sample, the minimum and the maximum, all exact stored samples;
``signals="full"`` keeps every sample, `signal_stride` > 1 every n-th.  rerun is imported lazily and its telemetry is
switched off before the import.
"""
from __future__ import annotations

import hashlib
import math
import mmap
import os
import re
import secrets
import subprocess
import sys
import tempfile
import time as _time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import catalog
from ..errors import MbsError
from ..files import replace_atomically
from ..lazy import lazy
from ..mechanism.model import CP_CLEARANCE, CP_KIND, CP_R_BEARING, CP_R_JOURNAL, PairKind
from ..results.section import AnalysisError, default_signals, slider_signals
from ..results.views import (
    PlotError,
    clearance_names,
    contact_onsets,
    driver_names,
    poincare,
    slider_body,
    stick_changes,
    sticking_elements,
    turning_body,
)

# rerun only once `_rerun` has switched its telemetry off (rerun.blueprint and rerun.chunk import it too)
rerun_sdk = lazy("rerun")
rrb = lazy("rerun.blueprint")
rerun_chunk = lazy("rerun.chunk")
pa = lazy("pyarrow")  # rerun's columns
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from ..mechanism import compile as compiler
    from ..mechanism import tables as table_reader
else:  # each loaded on its first use (see the comments: not on the light paths)
    compiler = lazy("..mechanism.compile", __package__)  # lark: only to rebuild a model from its results
    table_reader = lazy("..mechanism.tables", __package__)  # a run's stored tables, for that rebuild

if TYPE_CHECKING:  # pragma: no cover
    from ..mechanism.model import Model
    from ..results.hdf5 import Results

TIMELINE = "sim_time"
APPLICATION_ID = "planar_mbs"
FRAMES_PER_REVOLUTION = 90  # default frame rate when a body turns
DEFAULT_FRAMES = 1000  # default number of frames otherwise
MAX_FRAMES = 20_000
SIGNAL_MODES = ("envelope", "full")
PALETTE = [(31, 119, 180), (44, 160, 44), (148, 103, 189), (140, 86, 75), (227, 119, 194),
           (127, 127, 127), (188, 189, 34), (23, 190, 207)]
GROUND = (90, 90, 90)
BEARING = (60, 60, 60)
JOURNAL = (255, 127, 14)
REACTION = (31, 119, 180)
CONTACT = (214, 39, 40)
STUCK = (44, 160, 44)  # a contact force while its friction sticks


def _rerun():
    """rerun, imported (on first use) with its telemetry switched off."""
    os.environ.setdefault("RERUN_TELEMETRY_ENABLED", "false")
    os.environ["RERUN_TELEMETRY_ENABLED"] = "false"
    return rerun_sdk


@dataclass
class RecordingInfo:
    """What `record_run` wrote: for the CLI summary and the tests."""

    path: Path | None
    frames: int
    frame_times: np.ndarray
    signals: int
    contact_onsets: int
    poincare_points: int
    seconds: float
    entities: list[str] = field(default_factory=list)
    force_scale: dict[str, float] = field(default_factory=dict)  # m of arrow per N
    signal_mode: str = ""  # "envelope", "full" or "every nth sample"
    signal_rate: float = 0.0  # envelope bins per simulated second
    signal_samples: int = 0  # scalar samples logged, all signals together
    friction_events: int = 0  # stick and slip events logged


def model_from_results(results: "Results") -> "Model":
    """Rebuild the Model of a results file from its stored source text and resolved
    parameters (or from `model_path` when the source is not stored)."""
    attrs = results.attrs
    source = attrs.get("model_source") or ""
    mpath = str(attrs.get("model_path") or "")
    params = attrs.get("parameters") or {}
    params = {k: str(v) for k, v in params.items()} if isinstance(params, dict) else {}
    try:
        if source:
            includes = attrs.get("model_includes")
            if not isinstance(includes, dict) or not all(isinstance(v, str) for v in includes.values()):
                includes = None  # written before the included files were stored: read them from disk
            tables = attrs.get("model_tables")
            tables = ({p: t.encode("utf-8", "surrogateescape") for p, t in tables.items()}
                      if isinstance(tables, dict) and all(isinstance(t, str) for t in tables.values()) else {})
            with table_reader.provided(tables):  # the tables as the run read them: no file needed
                return compiler.compile_text(source, mpath or "<results>", overrides=params, includes=includes,
                                             key=str(attrs.get("model_key") or "") or None)
        if mpath and Path(mpath).exists():
            return compiler.load_model(mpath, params)
    except ImportError as exc:  # the compiler is not there (yet)
        raise PlotError(f"error: cannot rebuild the model to draw it: {exc}") from None
    except MbsError as exc:
        raise PlotError(f"error: the model stored in the results no longer compiles:\n{exc}") from None
    raise PlotError("error: the results file holds no model source and no readable model path; "
                    "cannot draw the mechanism\nhint: `mbs view --signals-only` records the signals alone")


# --------------------------------------------------------------------------- geometry


def _rgba(color) -> np.ndarray:
    """One colour as rerun's packed 0xRRGGBBAA (converting tuples costs rerun far more)."""
    r, g, b, *a = color
    return np.array([(r << 24) | (g << 16) | (b << 8) | (a[0] if a else 255)], dtype=np.uint32)


def _up(points) -> np.ndarray:
    """rerun's 2D views draw y downwards (rerun-io/rerun#1387): log y negated so up is up."""
    return np.asarray(points, dtype=float) * np.array([1.0, -1.0])


def _rot(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.cos(phi), np.sin(phi)


def _global(pose: dict, body: int, s, idx: np.ndarray) -> np.ndarray:
    """Global position (len(idx), 2) of local point `s` of `body` (-1 = ground)."""
    s = np.asarray(s, dtype=float)
    if body < 0:
        return np.broadcast_to(s, (len(idx), 2)).copy()
    x, y, phi = pose[body]
    c, sn = _rot(phi[idx])
    return np.stack([x[idx] + c * s[0] - sn * s[1], y[idx] + sn * s[0] + c * s[1]], 1)


def _angle(pose: dict, body: int, idx: np.ndarray) -> np.ndarray:
    return np.zeros(len(idx)) if body < 0 else pose[body][2][idx]


def frame_rate(results: "Results", model: "Model | None", fps: float | None = None,
               max_frames: int = MAX_FRAMES) -> float:
    """Frames per simulated second: `fps`, or 90 per revolution of the turning body where it turns
    at least once (else 1000 frames in all), lowered so that the run has at most `max_frames`."""
    t = results.time
    span = float(t[-1] - t[0]) if len(t) else 0.0
    if span <= 0:
        return 0.0
    if fps is None or fps <= 0:
        body = turning_body(results, model) if model is not None or results.signals else None
        rate = 0.0
        if body and f"{body}.omega" in results:
            omega = float(np.median(np.abs(results[f"{body}.omega"])))
            rate = omega / (2 * math.pi) * FRAMES_PER_REVOLUTION
        # a body that turns less than a revolution in the run (one held still by a zero-speed driver)
        # does not set the pace
        fps = rate if rate * span >= FRAMES_PER_REVOLUTION else DEFAULT_FRAMES / span
    if span * fps + 1 > max_frames:  # too many frames asked: spread max_frames over the run
        fps = (max_frames - 1) / span
    return float(fps)


def frame_indices(results: "Results", model: "Model | None", fps: float | None = None,
                  max_frames: int = MAX_FRAMES) -> np.ndarray:
    """Sample indices drawn as frames: the samples nearest a grid of `fps` frames per
    simulated second (default: 90 per revolution of the turning body, else 1000 in all)."""
    t = results.time
    n = len(t)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    fps = frame_rate(results, model, fps, max_frames)
    if fps <= 0:
        return np.array([0])
    span = float(t[-1] - t[0])
    count = int(math.floor(span * fps * (1 + 1e-12)) + 1)
    grid = t[0] + np.arange(count) / fps
    idx = np.clip(np.searchsorted(t, grid), 0, n - 1)
    prev = np.clip(idx - 1, 0, n - 1)
    idx = np.where(np.abs(t[prev] - grid) < np.abs(t[idx] - grid), prev, idx)
    return np.unique(idx)


def envelope_indices(t: np.ndarray, values: np.ndarray, rate: float) -> list[np.ndarray]:
    """Peak-preserving decimation of signals sampled at times `t`.

    `values` is (nsignal, n).  The run is cut into bins of 1/`rate` simulated seconds
    (bin k: t0 + k/rate <= t < t0 + (k+1)/rate); of each non-empty bin the first
    sample, the (first) minimum and the (first) maximum are kept, NaN ignored.  Returns,
    per signal, the kept sample indices in increasing order: at most three per bin,
    every one an exact stored sample.  With bins as fine as the samples, all are kept."""
    values = np.atleast_2d(np.asarray(values, dtype=float))
    nsig, n = values.shape
    everything = [np.arange(n)] * nsig
    if n == 0 or not rate or rate <= 0 or not np.isfinite(rate):
        return everything
    t = np.asarray(t, dtype=float)
    binno = np.floor((t - t[0]) * rate * (1 + 1e-12)).astype(np.int64)
    starts = np.flatnonzero(np.diff(binno, prepend=binno[0] - 1))  # first sample of each bin
    nb = len(starts)
    if 3 * nb >= n:
        return everything
    lens = np.diff(np.append(starts, n))
    width = int(lens.max())
    off = np.arange(width)[:, None]
    # (nsig, width, nb): the samples of every bin side by side, short bins padded with
    # their first sample (which is kept anyway); reducing over axis 1 is elementwise work
    grid = values[:, np.where(off < lens, starts + off, starts)]
    nan = np.isnan(grid)
    keep = np.empty((nsig, 3, nb), dtype=np.int64)
    keep[:, 0] = starts
    for row, (fill, reduce) in enumerate(((np.inf, np.min), (-np.inf, np.max)), 1):
        w = np.where(nan, fill, grid) if nan.any() else grid
        ext = reduce(w, axis=1)
        keep[:, row] = starts + np.where(w == ext[:, None, :], off, width).min(axis=1) % width
    keep = keep.reshape(nsig, 3 * nb)
    keep.sort(axis=1)
    new = np.ones(keep.shape, dtype=bool)
    new[:, 1:] = keep[:, 1:] != keep[:, :-1]
    return [keep[s][new[s]] for s in range(nsig)]


def _box(center: np.ndarray, axis: np.ndarray, width: float, height: float) -> np.ndarray:
    """(n, 5, 2) closed rectangles centred at `center` with long side along `axis`."""
    u = axis
    v = np.stack([-u[:, 1], u[:, 0]], 1)
    corners = [(+1, +1), (-1, +1), (-1, -1), (+1, -1), (+1, +1)]
    return np.stack([center + a * width / 2 * u + b * height / 2 * v for a, b in corners], 1)


def _order_outline(points: np.ndarray) -> np.ndarray:
    """Order a body's points (k, 2) in body frame for drawing: a segment for two, a
    closed polygon around the centroid for three or more."""
    if len(points) <= 2:
        return np.arange(len(points))
    c = points.mean(0)
    order = np.argsort(np.arctan2(points[:, 1] - c[1], points[:, 0] - c[0]))
    return np.concatenate([order, order[:1]])


def _arrow_scale(forces: list[np.ndarray], length: float) -> float:
    mags = np.concatenate([np.hypot(f[:, 0], f[:, 1]) for f in forces]) if forces else np.zeros(0)
    mags = mags[np.isfinite(mags)]
    ref = float(np.percentile(mags, 99)) if len(mags) else 0.0
    return length / ref if ref > 0 else 0.0


# --------------------------------------------------------------------------- recording


def record_run(
    results: "Results",
    model: "Model | None",
    path: str | Path | None = None,
    *,
    magnify: float = 10.0,
    fps: float | None = None,
    max_frames: int = MAX_FRAMES,
    signals: str = "envelope",
    signal_rate: float | None = None,
    signal_stride: int = 1,
    poincare_pair: tuple[str, str] | None = None,
    skip: int = 1,
    recording=None,
    spawn: bool = False,
    recording_id: str | None = None,
) -> RecordingInfo:
    """Log a run to rerun: write `path` (.rrd), or stream to a spawned viewer
    (``spawn=True``), or log into an existing ``RecordingStream`` (`recording`).

    `magnify` scales the eccentricity of clearance joints (and the drawn gap) so the
    journal's motion is visible; `fps` is frames per simulated second (None: 90 per
    revolution of the turning body).  With ``model=None`` only signals, events and
    Poincaré points are logged.  `signals` is "envelope" (the default: per bin of
    1/`signal_rate` s, default the frame rate, the first sample, the min and the max) or
    "full" (every sample); `signal_stride` > 1 logs every n-th sample instead.  A file is
    written beside `path` and moved over it once rerun's reader finds it whole, so a full disk or
    a kill never leaves half a recording there (a full disk raises `PlotError`).
    """
    rr = _rerun()
    start = _time.perf_counter()
    rec, part, moved = recording, None, False
    try:  # from before the part file exists: a SIGTERM as it is created still removes it
        if rec is None:
            rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
            blueprint = _blueprint(results, model, poincare_pair)
            if spawn:
                rec.spawn(default_blueprint=blueprint)
            elif path is not None:
                Path(path).parent.mkdir(parents=True, exist_ok=True)
                part = _part_beside(Path(path))
                rec.save(str(part), default_blueprint=blueprint)
            else:
                raise ValueError("record_run needs a path, spawn=True or a recording")
        info = _record_all(rr, rec, results, model, path, magnify, fps, max_frames, signals, signal_rate,
                           signal_stride, poincare_pair, skip)
        if recording is None:
            if part is not None:
                rec.disconnect()  # flushes everything to the file and closes it
                _move_into_place(part, Path(path))
                moved = True
            else:
                rec.flush()
    finally:
        if part is not None and not moved:  # stopped before the move: nothing replaces `path`
            rec.disconnect()  # rerun's writing thread has ended: the part cannot come back
            part.unlink(missing_ok=True)
    info.seconds = _time.perf_counter() - start
    return info


def recording_key(results_file) -> str:
    """The recording id `mbs` gives a recording of the results file `results_file` (``FILE.h5`` or
    ``FILE.h5:/cases/3``): a digest of its absolute path.  It is written into the .rrd, so that a
    recording about to be replaced can be told to be of the same results (`check_replace`)."""
    file, sep, group = str(results_file).partition(":/")
    where = str(Path(file).resolve()) + (sep + group if sep else "")
    return "mbs-" + hashlib.sha256(where.encode()).hexdigest()[:32]


def check_replace(path, key: str, force: bool, option: str = "--output") -> None:
    """Refuse (`PlotError`, exit 2), before anything runs, to replace an existing file at `path` that is
    not a recording of the same results (its `recording_key` is not in it), unless `force`: a recording
    of another run is not replaced without a word."""
    path = Path(path)
    if force or not path.is_file() or path.stat().st_size == 0:
        return
    try:
        with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
            if data.find(key.encode()) >= 0:
                return
    except (OSError, ValueError):
        pass
    raise PlotError(f"error: {option} {path} exists and is not a recording of these results (another run's, or "
                    f"another file)\nhint: give --force to replace it, or another name with {option}")


def _part_beside(path: Path) -> Path:
    """The hidden file a recording is written to before it replaces `path`."""
    return path.with_name(f".{path.name}.{secrets.token_hex(4)}.part")


def _move_into_place(part: Path, path: Path) -> None:
    """Move a finished recording over `path`, once rerun's own reader finds it whole (its footer,
    a few ms): rerun writes from a thread of its own and only logs a failed write (a full disk),
    so a recording cut short would otherwise replace a good one and be reported as written."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # "no footer": the write stopped before its end
            rerun_chunk.RrdReader(part).store()
    except Exception as exc:  # noqa: BLE001  (whatever the reader finds wrong, the file is not whole)
        reason = str(exc).split(". ")[0]
        raise PlotError(f"error: cannot write the rerun recording {path}: rerun could not write it whole ({reason})\n"
                        f"hint: is the disk full? `df -h {path.parent}`; nothing was written over {path.name}"
                        ) from None
    replace_atomically(part, path, durable=False)  # a recording is made again from its results


def _record_all(rr, rec, results, model, path, magnify, fps, max_frames, signals, signal_rate, signal_stride,
                poincare_pair, skip) -> RecordingInfo:
    """Log the model's source, the mechanism, the signals, the contacts and the Poincaré points."""
    entities: list[str] = []
    info = RecordingInfo(Path(path) if path else None, 0, np.zeros(0), 0, 0, 0, 0.0, entities)

    source = str(results.attrs.get("model_source") or "")
    if source:
        rec.log("model/source", rr.TextDocument(source, media_type="text/plain"), static=True)
        entities.append("model/source")

    if model is not None and len(results.time):
        _log_mechanism(rr, rec, results, model, magnify, fps, max_frames, info)
    if signals not in SIGNAL_MODES:
        raise ValueError(f"signals must be one of {SIGNAL_MODES}, not {signals!r}")
    _log_signals(rr, rec, results, model, signals, signal_rate, max(1, int(signal_stride)), fps, max_frames, info)
    _log_contacts(rr, rec, results, info)
    _log_friction(rr, rec, results, info)
    _log_poincare(rr, rec, results, model, poincare_pair, skip, info)
    return info


def _time_column(rr, t: np.ndarray):
    return [rr.TimeColumn(TIMELINE, duration=np.asarray(t, dtype=float))]


@dataclass
class _Scene:
    """What the mechanism's drawing functions share: the frames, each body's pose, the points
    drawn on each body, the magnified clearance geometry and the mechanism's size."""

    rr: Any
    rec: Any
    model: "Model"
    draw: list[str]  # per ideal joint: pin | link | slide (catalog)
    pose: dict  # body -> (x, y, phi) over all samples
    idx: np.ndarray  # sample index of each frame
    tcol: Any  # the frames' time column
    info: RecordingInfo
    body_points: dict = field(default_factory=dict)  # body -> [(label, local point)]
    journal_of: dict = field(default_factory=dict)  # (body, point number) -> clearance joint
    bearing_c: dict = field(default_factory=dict)  # clearance joint -> bearing centre per frame
    journal_c: dict = field(default_factory=dict)  # ... drawn journal centre (magnified eccentricity)
    normal: dict = field(default_factory=dict)
    radius_j: dict = field(default_factory=dict)
    radius_b: dict = field(default_factory=dict)
    size: float = 1.0

    @property
    def nf(self) -> int:
        return len(self.idx)

    def ui(self, r: float):
        return self.rr.Radius.ui_points(r)

    def send(self, path: str, columns) -> None:
        self.rec.send_columns(path, indexes=self.tcol, columns=columns)

    def center(self, b: int) -> np.ndarray:
        return np.stack([self.pose[b][0][self.idx], self.pose[b][1][self.idx]], 1)


def _log_mechanism(rr, rec, results, model, magnify, fps, max_frames, info: RecordingInfo) -> None:
    """The moving mechanism: bodies, centres of mass, pins and ground, clearance joints, force arrows."""
    names = model.body_names
    missing = [f"{b}.{q}" for b in names for q in ("x", "y", "phi") if f"{b}.{q}" not in results]
    if missing:
        raise PlotError(f"error: the results do not match the model: no signal `{missing[0]}`")
    pose = {b: (results[f"{n}.x"], results[f"{n}.y"], results[f"{n}.phi"]) for b, n in enumerate(names)}
    idx = frame_indices(results, model, fps, max_frames)
    t = results.time[idx]
    info.frames, info.frame_times = len(idx), t
    draw = [catalog.JOINTS[int(jt)].draw for jt in model.kernel.joint_type]
    scene = _Scene(rr, rec, model, draw, pose, idx, _time_column(rr, t), info)
    _body_points(scene)
    _clearance_geometry(scene, magnify)
    _mechanism_size(scene)
    for b, name in enumerate(names):
        _log_body(scene, b, name)
    _log_pins(scene)
    _log_clearances(scene)
    _log_forces(scene, results, magnify)


def _body_points(scene: _Scene) -> None:
    """The points drawn on each body: ideal joints (not translational), clearance joints, forces."""
    model, k = scene.model, scene.model.kernel
    body_points: dict[int, list[tuple[str, np.ndarray]]] = {b: [] for b in range(model.nbody)}
    for j in range(model.njoint):
        for side in (0, 1):
            b = int(k.joint_body[j, side])
            if b >= 0 and scene.draw[j] != "slide":
                body_points[b].append((f"joint{j}", k.joint_point[j, side]))
    for c in range(model.nclearance):
        for side in (0, 1):
            b = int(k.clearance_body[c, side])
            if b >= 0:
                body_points[b].append((f"clearance{c}:{side}", k.clearance_point[c, side]))
                if side == 1:
                    scene.journal_of[(b, len(body_points[b]) - 1)] = c
    for f in range(model.nforce):
        for side in (0, 1):
            b = int(k.force_body[f, side])
            if b >= 0:
                body_points[b].append((f"force{f}", k.force_point[f, side]))
    scene.body_points = body_points


def _clearance_geometry(scene: _Scene, magnify: float) -> None:
    """Bearing and (magnified) journal centres, contact normals and drawn radii per frame."""
    k, pose, idx = scene.model.kernel, scene.pose, scene.idx
    for c in range(scene.model.nclearance):
        bi, bj = int(k.clearance_body[c, 0]), int(k.clearance_body[c, 1])
        Pi = _global(pose, bi, k.clearance_point[c, 0], idx)
        Pj = _global(pose, bj, k.clearance_point[c, 1], idx)
        e = Pj - Pi
        clearance = float(k.clearance_param[c, CP_CLEARANCE])
        rj = float(k.clearance_param[c, CP_R_JOURNAL]) or float(k.clearance_param[c, CP_R_BEARING]) - clearance
        scene.bearing_c[c], scene.journal_c[c] = Pi, Pi + magnify * e
        elen = np.hypot(e[:, 0], e[:, 1])
        safe = np.where(elen > 0, elen, 1.0)[:, None]
        scene.normal[c] = np.where(elen[:, None] > 0, e / safe, np.array([1.0, 0.0]))
        scene.radius_j[c], scene.radius_b[c] = rj, rj + magnify * clearance
        if int(k.clearance_param[c, CP_KIND]) in (PairKind.CIRCLE_ON_LINE, PairKind.CIRCLE_ON_CIRCLE):
            # a contact between outlines (a corner of a translational clearance joint): drawn true to
            # size, the second body's circle (or corner) and the first body's circle (none for a line)
            scene.journal_c[c] = Pj
            scene.radius_j[c], scene.radius_b[c] = rj, float(k.clearance_param[c, CP_R_BEARING])


def _mechanism_size(scene: _Scene) -> None:
    """The mechanism's extent over the run, for boxes and arrows."""
    pose, idx, nb = scene.pose, scene.idx, scene.model.nbody
    allpts = [p for b in range(nb) for _, s in scene.body_points[b] for p in [_global(pose, b, s, idx)]]
    allpts += [scene.center(b) for b in range(nb)]
    cloud = np.concatenate(allpts) if allpts else np.zeros((1, 2))
    scene.size = float(np.max(np.ptp(cloud, axis=0))) or 1.0


def _slider_axis(scene: _Scene, b: int) -> int | None:
    """The translational joint whose axis a slider body is drawn along (None: not a slider)."""
    k = scene.model.kernel
    for j in range(scene.model.njoint):
        if scene.draw[j] == "slide":
            bi, bj = int(k.joint_body[j, 0]), int(k.joint_body[j, 1])
            if (bj if bj >= 0 else bi) == b:
                return j
    return None


def _body_strips(scene: _Scene, b: int, geom: dict) -> list[np.ndarray]:
    """Line strips (nf, k, 2) drawing body `b`: its shape, and the outline through its points."""
    k, pose, idx = scene.model.kernel, scene.pose, scene.idx
    kind = geom.get("kind", "")
    if kind in ("beam_node", "beam_slope"):  # a beam is drawn once, from its first node
        return _beam_strips(scene, b) if kind == "beam_node" and b in set(k.beam_info[:, 0]) else []
    center = scene.center(b)
    body_axis = np.stack(_rot(pose[b][2][idx]), 1)
    strips = []  # each (nf, k, 2)
    j = _slider_axis(scene, b)
    if kind == "box":
        strips.append(_box(center, body_axis, float(geom["width"]), float(geom["height"])))
    elif j is not None:
        ax_local = k.joint_axis[j]
        ca, sa = _rot(_angle(pose, int(k.joint_body[j, 0]), idx))
        axis = np.stack([ca * ax_local[0] - sa * ax_local[1], sa * ax_local[0] + ca * ax_local[1]], 1)
        strips.append(_box(center, axis, 0.16 * scene.size, 0.08 * scene.size))
    elif kind == "circle":
        r = float(geom["radius"])
        th = np.linspace(0, 2 * np.pi, 49)
        ring = np.stack([np.cos(th), np.sin(th)], 1) * r
        c, sn = body_axis[:, :1, None], body_axis[:, 1:, None]
        rot = np.concatenate([np.concatenate([c, -sn], 2), np.concatenate([sn, c], 2)], 1)  # (nf, 2, 2)
        strips.append(center[:, None, :] + ring @ rot.transpose(0, 2, 1))
        strips.append(np.stack([center, center + r * body_axis], 1))  # a spoke shows the rotation
    pts = scene.body_points[b]
    local = np.array([s for _, s in pts], dtype=float).reshape(-1, 2)
    _, keep = np.unique(np.round(local, 12), axis=0, return_index=True)  # a point may serve two joints
    keep = np.sort(keep)
    if len(keep) >= 2:
        coords = []
        for i in keep[_order_outline(local[keep])]:
            if (b, int(i)) in scene.journal_of:
                coords.append(scene.journal_c[scene.journal_of[(b, int(i))]])
            else:
                coords.append(_global(pose, b, pts[int(i)][1], idx))
        strips.append(np.stack(coords, 1))
    elif kind == "bar" or (not strips and len(keep) == 1):
        half = float(geom.get("length", 0.0)) / 2
        if half > 0:  # the bar along the body's x axis
            strips.append(np.stack([center - half * body_axis, center + half * body_axis], 1))
        elif len(keep) == 1:  # one point: from it to the centre of mass
            strips.append(np.stack([_global(pose, b, pts[int(keep[0])][1], idx), center], 1))
    return strips


def _beam_strips(scene: _Scene, b: int) -> list[np.ndarray]:
    """The bent centre line (nf, k, 2) of the beam whose first node is body b: each element's cubic
    Hermite curve (`kernel/beam.py`) through its nodes' positions and slopes, 8 segments each."""
    k = scene.model.kernel
    bm = int(np.flatnonzero(np.asarray(k.beam_info)[:, 0] == b)[0])
    nel, Le = int(k.beam_info[bm, 1]), float(k.beam_param[bm, 0])
    xi = np.linspace(0.0, 1.0, 9)[:, None, None]
    H = (1 - 3 * xi ** 2 + 2 * xi ** 3, Le * (xi - 2 * xi ** 2 + xi ** 3), 3 * xi ** 2 - 2 * xi ** 3, Le * (xi ** 3 - xi ** 2))
    parts = []
    for e in range(nel):
        r1, s1, r2, s2 = (scene.center(b + 2 * e + i) for i in range(4))  # (nf, 2) each
        seg = H[0] * r1 + H[1] * s1 + H[2] * r2 + H[3] * s2  # (9, nf, 2)
        parts.append(seg if e == 0 else seg[1:])
    return [np.concatenate(parts, 0).transpose(1, 0, 2)]


def _log_body(scene: _Scene, b: int, name: str) -> None:
    """One body as line strips over the frames, with its colour and width."""
    model, rr = scene.model, scene.rr
    geom = model.body_geometry[b] if b < len(model.body_geometry) and model.body_geometry[b] else {}
    strips = _body_strips(scene, b, geom)
    if not strips:
        return
    kind = geom.get("kind", "")
    color = PALETTE[b % len(PALETTE)]
    # one array (nf * nstrips, kmax, 2): strips padded by repeating their last point
    kmax = max(st.shape[1] for st in strips)
    padded = [np.concatenate([st, np.repeat(st[:, -1:], kmax - st.shape[1], 1)], 1) for st in strips]
    flat = _up(np.stack(padded, 1).reshape(-1, kmax, 2))
    scene.send(f"mechanism/bodies/{name}",
               rr.LineStrips2D.columns(strips=flat).partition(np.full(scene.nf, len(strips))))
    thick = kind == "bar" and float(geom.get("width", 0)) > 0
    scene.rec.log(f"mechanism/bodies/{name}", rr.LineStrips2D.from_fields(
        radii=float(geom["width"]) / 2 if thick else scene.ui(2.5),
        colors=_rgba((*color, 150) if thick else color), labels=[name], show_labels=False,
        draw_order=10.0), static=True)
    scene.info.entities.append(f"mechanism/bodies/{name}")


def _log_pins(scene: _Scene) -> None:
    """Centres of mass, ideal-joint pins (at the first body's point), ground pins and slide guides."""
    model, rr, rec, k, pose = scene.model, scene.rr, scene.rec, scene.model.kernel, scene.pose
    ent, nf, idx, size = scene.info.entities, scene.nf, scene.idx, scene.size
    shown = [b for b in range(model.nbody) if not (b < len(model.body_geometry) and model.body_geometry[b]
                                                   and model.body_geometry[b].get("kind") == "beam_slope")]
    com = np.stack([scene.center(b) for b in shown], 1)  # a beam's slope bodies are no points of the plane
    scene.send("mechanism/com", rr.Points2D.columns(positions=_up(com.reshape(-1, 2))).partition(np.full(nf, len(shown))))
    rec.log("mechanism/com", rr.Points2D.from_fields(radii=scene.ui(2.0), colors=_rgba((0, 0, 0)), draw_order=41.0),
            static=True)
    ent.append("mechanism/com")
    pins, ground_pts, guides = [], [], []
    for j in range(model.njoint):
        bi, bj = int(k.joint_body[j, 0]), int(k.joint_body[j, 1])
        if scene.draw[j] == "slide":
            if bi < 0 or bj < 0:
                g_side, s_body = (0, bj) if bi < 0 else (1, bi)
                p0 = np.asarray(k.joint_point[j, g_side], dtype=float)
                ax = np.asarray(k.joint_axis[j], dtype=float)
                xs = np.stack([pose[s_body][0], pose[s_body][1]], 1)
                proj = (xs - p0) @ ax
                lo, hi = float(proj.min()) - 0.12 * size, float(proj.max()) + 0.12 * size
                nrm = np.array([-ax[1], ax[0]])
                below = float(((xs - p0) @ nrm).min()) - 0.5 * 0.08 * size
                guides.append([p0 + lo * ax + below * nrm, p0 + hi * ax + below * nrm])
            continue
        if scene.draw[j] == "link":  # a massless link: its points join the outlines, no pin
            continue
        pins.append(_global(pose, bi, k.joint_point[j, 0], idx) if bi >= 0 else
                    _global(pose, bj, k.joint_point[j, 1], idx))
        if bi < 0 or bj < 0:
            ground_pts.append(k.joint_point[j, 0] if bi < 0 else k.joint_point[j, 1])
    if pins:
        arr = np.stack(pins, 1)
        scene.send("mechanism/joints", rr.Points2D.columns(positions=_up(arr.reshape(-1, 2))).partition(
            np.full(nf, len(pins))))
        rec.log("mechanism/joints", rr.Points2D.from_fields(radii=scene.ui(4.0), colors=_rgba((30, 30, 30)),
                                                            draw_order=40.0), static=True)
        ent.append("mechanism/joints")
    if ground_pts or guides:
        rec.log("mechanism/ground/pins", rr.Points2D(_up(np.array(ground_pts).reshape(-1, 2)), radii=scene.ui(6.0),
                                                     colors=_rgba(GROUND)), static=True)
        if guides:
            rec.log("mechanism/ground/guides", rr.LineStrips2D([_up(np.array(g)) for g in guides],
                                                               radii=scene.ui(1.5), colors=_rgba(GROUND)), static=True)
        ent.append("mechanism/ground")


def _log_clearances(scene: _Scene) -> None:
    """Each clearance joint's bearing and journal circles (clearance magnified)."""
    rr, rec, nf = scene.rr, scene.rec, scene.nf
    for c, cname in enumerate(scene.model.clearance_names):
        base = f"mechanism/clearance/{cname}"
        scene.send(f"{base}/bearing", rr.Ellipses2D.columns(
            centers=_up(scene.bearing_c[c]), half_sizes=np.full((nf, 2), scene.radius_b[c])))
        rec.log(f"{base}/bearing", rr.Ellipses2D.from_fields(line_radii=scene.ui(1.5), colors=_rgba(BEARING),
                                                             draw_order=30.0), static=True)
        scene.send(f"{base}/journal", rr.Ellipses2D.columns(
            centers=_up(scene.journal_c[c]), half_sizes=np.full((nf, 2), scene.radius_j[c])))
        rec.log(f"{base}/journal", rr.Ellipses2D.from_fields(line_radii=scene.ui(1.5), colors=_rgba(JOURNAL),
                                                             draw_order=31.0), static=True)
        scene.info.entities += [f"{base}/bearing", f"{base}/journal"]


def _log_forces(scene: _Scene, results, magnify: float) -> None:
    """Joint reactions and contact forces as arrows on one scale, and the drawing's legend."""
    model, rr, rec, k, pose, idx = scene.model, scene.rr, scene.rec, scene.model.kernel, scene.pose, scene.idx
    ent = scene.info.entities
    reactions = [(j, n) for j, n in enumerate(model.joint_names) if f"{n}.fx" in results and f"{n}.fy" in results]
    r_forces = [np.stack([results[f"{n}.fx"][idx], results[f"{n}.fy"][idx]], 1) for _, n in reactions]
    contacts = [(c, n) for c, n in enumerate(model.clearance_names) if f"{n}.fx" in results]
    c_forces = [np.stack([results[f"{n}.fx"][idx], results[f"{n}.fy"][idx]], 1) for _, n in contacts]
    scale = _arrow_scale(r_forces + c_forces, 0.25 * scene.size)  # one scale: arrows compare
    scene.info.force_scale["forces"] = scale
    for (j, n), F in zip(reactions, r_forces):
        bi, bj = int(k.joint_body[j, 0]), int(k.joint_body[j, 1])
        origin = _global(pose, bj, k.joint_point[j, 1], idx) if bj >= 0 else _global(pose, bi, k.joint_point[j, 0], idx)
        scene.send(f"forces/joints/{n}", rr.Arrows2D.columns(origins=_up(origin), vectors=_up(F * scale)))
        rec.log(f"forces/joints/{n}", rr.Arrows2D.from_fields(radii=scene.ui(1.5), colors=_rgba(REACTION),
                                                              draw_order=50.0), static=True)
        ent.append(f"forces/joints/{n}")
    for (c, n), F in zip(contacts, c_forces):
        origin = scene.journal_c[c] + scene.radius_j[c] * scene.normal[c]
        stuck = np.asarray(results[f"{n}.stick"])[idx] > 0.5 if f"{n}.stick" in results else np.zeros(len(idx), bool)
        colors = np.where(stuck, _rgba(STUCK)[0], _rgba(CONTACT)[0]).astype(np.uint32)
        scene.send(f"forces/contact/{n}", rr.Arrows2D.columns(origins=_up(origin), vectors=_up(F * scale),
                                                              colors=colors))
        rec.log(f"forces/contact/{n}", rr.Arrows2D.from_fields(radii=scene.ui(2.0), draw_order=51.0), static=True)
        ent.append(f"forces/contact/{n}")
    rec.log("mechanism/legend", rr.TextDocument(
        f"clearance magnified x{magnify:g}; force arrows (joint reactions and contact forces) "
        f"{scale * 1e3:.3g} mm/N; a contact force is green while its friction sticks"), static=True)


def _log_signals(rr, rec, results, model, mode: str, rate: float | None, stride: int, fps, max_frames,
                 info: RecordingInfo) -> None:
    """Every signal as a Scalars series: the peak-preserving envelope (`envelope_indices`,
    bins at `rate` per simulated second, default the frame rate), every sample
    (``mode="full"``) or every `stride`-th sample (stride > 1)."""
    t = results.time
    names = list(results.signals)
    info.signals = len(names)
    if not names or not len(t):
        return
    if stride > 1:
        kept = [np.arange(0, len(t), stride)] * len(names)
        info.signal_mode = f"every {stride}th sample"
    elif mode == "full":
        kept = [np.arange(len(t))] * len(names)
        info.signal_mode = "full"
    else:
        rate = float(rate) if rate and rate > 0 else frame_rate(results, model, fps, max_frames)
        values = np.stack([np.asarray(results.signals[k], dtype=float) for k in names])
        kept = envelope_indices(t, values, rate)
        info.signal_rate = rate
        info.signal_mode = "envelope"
    # straight to arrow (rerun's TimeColumnLike and ComponentBatchLike protocols): the
    # archetype helpers cost more Python time per series than rerun's own encoding
    ns = _nanoseconds(t)
    offsets = np.arange(len(t) + 1, dtype=np.int32)
    descriptor = _scalars_descriptor(rr)
    for name, idx in zip(names, kept):
        entity, _, qty = name.rpartition(".")
        path = f"signals/{entity}/{qty}"
        rec.send_columns(path, indexes=[_Arrow(ns[idx], TIMELINE)], columns=[rr.ComponentColumn(
            descriptor, _Arrow(np.asarray(results.signals[name], dtype=float)[idx]), offsets=offsets[:len(idx) + 1])])
        info.entities.append(path)
        info.signal_samples += len(idx)


class _Arrow:
    """A numpy array as an arrow array, for rerun's `TimeColumnLike` (a duration column of
    nanoseconds when `timeline` is set) and `ComponentBatchLike` protocols."""

    def __init__(self, values: np.ndarray, timeline: str | None = None):
        self.values, self.timeline = values, timeline

    def timeline_name(self) -> str:
        return self.timeline or ""

    def as_arrow_array(self):
        if self.timeline is not None:
            return pa.array(self.values, pa.duration("ns"))
        return pa.array(self.values, pa.float64())


def _nanoseconds(t: np.ndarray) -> np.ndarray:
    """Seconds to integer nanoseconds, as `rr.TimeColumn(duration=...)` converts them."""
    return (np.asarray(t, dtype=float) * 1e9).astype("timedelta64[ns]").astype(np.int64)


_DESCRIPTORS: dict[str, object] = {}


def _scalars_descriptor(rr):
    if "scalars" not in _DESCRIPTORS:
        _DESCRIPTORS["scalars"] = next(iter(rr.Scalars.columns(scalars=[0.0]))).component_descriptor()
    return _DESCRIPTORS["scalars"]


def _log_contacts(rr, rec, results, info: RecordingInfo) -> None:
    times, texts = [], []
    for c in clearance_names(results):
        v = results.signals.get(f"{c}.impact_velocity")
        for i in contact_onsets(results, c):
            times.append(results.time[i])
            extra = f", impact velocity {v[i]:.4g} m/s" if v is not None else ""
            texts.append(f"{c}: contact onset at t = {results.time[i]:.9g} s{extra}")
    _log_events(rr, rec, "events/contact", times, texts, info)
    info.contact_onsets = len(times)


def _log_events(rr, rec, path: str, times: list, texts: list, info: RecordingInfo) -> None:
    """Messages at their times (any order: sent sorted) as one TextLog entity, if there are any."""
    if times:
        order = np.argsort(times, kind="stable")
        rec.send_columns(path, indexes=_time_column(rr, np.asarray(times)[order]),
                         columns=rr.TextLog.columns(text=[texts[i] for i in order], level=["INFO"] * len(order)))
        info.entities.append(path)


def _log_friction(rr, rec, results, info: RecordingInfo) -> None:
    """Each stick and slip of every element whose friction can stick, at its sample's time."""
    times, texts = [], []
    for element in sticking_elements(results):
        for i, stuck in zip(*stick_changes(results, element)):
            times.append(results.time[i])
            texts.append(f"{element}: {'sticks' if stuck else 'slips'} at t = {results.time[i]:.9g} s")
    _log_events(rr, rec, "events/friction", times, texts, info)
    info.friction_events = len(times)


def _log_poincare(rr, rec, results, model, pair, skip, info: RecordingInfo) -> None:
    if pair is None:
        try:
            pair = default_signals(results, model)  # the slider along its axis, else the output link
        except AnalysisError:
            return
    clock = turning_body(results, model)
    if not clock or f"{clock}.phi" not in results:  # e.g. a sweep's case that kept no angle of its clock
        return
    ps = poincare(results, pair[0], pair[1], None, skip, model)
    if not len(ps.t):
        return

    def norm(v):
        mid, half = (v.max() + v.min()) / 2, (v.max() - v.min()) / 2 or 1.0
        return (v - mid) / half, mid, half

    x, xm, xh = norm(ps.x)
    y, ym, yh = norm(ps.y)
    path = f"poincare/{pair[0]}_vs_{pair[1]}".replace(".", "_")
    rec.send_columns(path, indexes=_time_column(rr, ps.t),
                     columns=rr.Points2D.columns(positions=_up(np.stack([x, y], 1))))
    rec.log(path, rr.Points2D.from_fields(radii=rr.Radius.ui_points(3.0), colors=_rgba(CONTACT)), static=True)
    rec.log("poincare/axes", rr.TextDocument(
        f"Poincaré map, one point per revolution of `{ps.body}` after the first {skip}.\n"
        f"x = ({pair[0]} - {xm:.6g}) / {xh:.6g}\ny = ({pair[1]} - {ym:.6g}) / {yh:.6g}\n"
        f"units: {results.units.get(pair[0], '')}, {results.units.get(pair[1], '')}"), static=True)
    info.entities.append(path)
    info.poincare_points = len(ps.t)


def _blueprint(results, model, pair):
    """The viewer layout: the mechanism on the left; key signals, the Poincaré map and the
    contact log on the right; playback slowed so that a revolution takes about 2 s."""
    slider = slider_body(results, model)
    series = []
    if slider:
        series += [rrb.TimeSeriesView(origin=f"/signals/{slider}", contents=[f"$origin/{n.rpartition('.')[2]}"],
                                      name=n) for n in slider_signals(results, model, slider) if n in results]
    for c in clearance_names(results):
        series.append(rrb.TimeSeriesView(origin=f"/signals/{c}", contents=["$origin/contact_force"],
                                         name=f"{c}.contact_force"))
    for d in driver_names(results):
        q = "torque" if f"{d}.torque" in results else "force"
        series.append(rrb.TimeSeriesView(origin=f"/signals/{d}", contents=[f"$origin/{q}"], name=f"{d}.{q}"))
    upto_cursor = rrb.VisibleTimeRange(TIMELINE, start=rrb.TimeRangeBoundary.infinite(),
                                       end=rrb.TimeRangeBoundary.cursor_relative())
    poincare_view = rrb.Spatial2DView(origin="/poincare", name="Poincaré map (normalised)", time_ranges=upto_cursor,
                                      visual_bounds=rrb.VisualBounds2D(x_range=[-1.15, 1.15], y_range=[-1.15, 1.15]))
    bounds = None
    if model is not None:
        xs = [results[f"{b}.x"] for b in model.body_names if f"{b}.x" in results]
        ys = [results[f"{b}.y"] for b in model.body_names if f"{b}.y" in results]
        if xs and len(xs[0]):
            x0, x1 = min(map(np.min, xs)), max(map(np.max, xs))
            y0, y1 = min(map(np.min, ys)), max(map(np.max, ys))
            m = 0.25 * max(x1 - x0, y1 - y0, 1e-9)
            bounds = rrb.VisualBounds2D(x_range=[x0 - m, x1 + m], y_range=[-y1 - m, -y0 + m])
    mechanism = rrb.Spatial2DView(origin="/", contents=["+ /mechanism/**", "+ /forces/**", "- /mechanism/legend"],
                                  name="mechanism", visual_bounds=bounds)
    right = rrb.Vertical(*series, rrb.Horizontal(poincare_view, rrb.TextLogView(origin="/events", name="contact events")),
                         row_shares=[1] * len(series) + [2])
    speed = None
    body = turning_body(results, model)
    if body and f"{body}.omega" in results and len(results.time):
        omega = float(np.median(np.abs(results[f"{body}.omega"])))
        if omega > 0:
            speed = (2 * math.pi / omega) / 2.0  # one revolution in about 2 s of playback
    return rrb.Blueprint(
        rrb.Horizontal(mechanism, right, column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="expanded", timeline=TIMELINE, playback_speed=speed, play_state="following"),
    )


VIEWER_WAIT = 3.0  # s: a viewer still running by then has started (one that cannot start ends in ~0.1 s)


def open_viewer(path: str | Path) -> None:
    """Start the rerun viewer on a recording, detached from this process.  A viewer that ends
    within `VIEWER_WAIT` with a failure (no display, no GPU) raises `PlotError` with its exit code
    and its own last error line: the recording is written, the viewer is not open."""
    env = dict(os.environ, RERUN_TELEMETRY_ENABLED="false")
    with tempfile.TemporaryFile() as log:
        proc = subprocess.Popen([sys.executable, "-m", "rerun", str(path)], env=env, start_new_session=True,
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=log)
        try:
            code = proc.wait(VIEWER_WAIT)
        except subprocess.TimeoutExpired:
            return  # running: the user's window
        if code == 0:
            return
        log.seek(0)
        lines = [re.sub(r"\x1b\[[0-9;]*m", "", ln).strip() for ln in log.read().decode(errors="replace").splitlines()]
    lines = [ln for ln in lines if ln]
    reason = next((ln for ln in reversed(lines) if ln.lower().startswith("error")), lines[-1] if lines else "")
    raise PlotError(f"error: the rerun viewer did not start (exit code {code})" + (f": {reason}" if reason else "")
                    + f"\nhint: the recording {path} is written; open it where there is a display: `rerun {path}`")
