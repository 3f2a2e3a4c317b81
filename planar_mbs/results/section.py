"""The one Poincaré section of the project: plots, rerun, `mbs analyze` and sweeps all use it.

Rules (docs/plots.md and docs/sweeps.md describe them for users):

* **Clock.** The section is clocked by a body's angle: the body of the model's
  first absolute rotation driver when the model is known, else the body whose
  angle turns most over the run (the crank of a slider-crank).  `clock_body`.
* **Crossings.** A point is taken each time the clock's angle passes a level:
  ``phi − phi(0) = 2πk`` by default (once per revolution from the start), or
  ``phi = angle + 2πk`` for a given ``angle``.  Every level crossed between two
  output samples gives a point, located by linear interpolation of the angle
  (`crossings`); for a driver at constant speed these are exactly ``t = kT``.
  With an explicit ``period`` (a system without a turning body) the section is
  stroboscopic, ``t = t0 + kT``.
* **Transient.** The first ``transient`` crossings are dropped (default 1: the
  end of the first revolution, which still carries the start).  Where the motion
  really settles is measured afterwards, on the points (`settling`).
* **Sampling.** Signals are interpolated linearly at the crossing times; on the
  output grid (times within 1e-6 of an output step) the integrator's own values
  are used (``method = "grid"``), else the interpolation error is estimated from
  the local second difference (``interp_error``, relative to each signal's spread).
* **The slider.** The default section plane is the slider's velocity against its
  acceleration (as in the figures of Muvengei, Kihiu and Ikua, "Effects of input
  speed on the dynamic response of planar multi-body systems with differently
  located frictionless revolute clearance joints"); the slider is the body a
  translational joint (a joint marked `slider` in the catalog) ties to ground, else the
  one body that moves without turning, else a body named like a slider (`slider_body`).
  Its velocity and acceleration are taken along its joint's axis: ``vy``/``ay`` for a
  slider that moves along y (a vertical cam follower), ``vx``/``ax`` along x; on an inclined
  axis the component nearer to it (the slider moves along its axis only, so that component
  is the speed along the axis times a constant factor: the same section, scaled)
  (`slider_signals`).
* **The output link.** A mechanism without a slider (a four-bar) is sectioned by its output
  link: the body other than the clock that a joint pivots on ground (the last such body of the
  model), its angle against its angular velocity (``phi``, ``omega``; ``omega``, ``alpha`` when
  it turns full revolutions itself) (`output_body`).  Without the model, a body whose motion is
  a rotation about a fixed point.
* **What the results record.**  A run stores these facts of its mechanism in its results
  (attribute ``mechanism``, `mechanism_facts`), so that plots and `mbs analyze` choose as the
  model would without compiling it.

numpy only.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .. import catalog
from ..errors import MbsError
from ..mechanism.model import CP_KIND, DriverType, MotionType

SLIDER_WORDS = ("slider", "piston", "block", "carriage", "cart", "ram", "crosshead")
TOL_PERIODIC = 1e-3  # recurrence residual / spread below which two section points coincide
MAX_PERIOD = 16  # longest period looked for (in revolutions)
MIN_SETTLED = 20  # fewest section points a settled part must have
SETTLED_SPREAD = 1e-2  # a settled orbit's points: each of its p points stays within this (relative to the run's spread)
STATIONARY_TOL = 0.15  # window mean/spread differences (in units of the run's spread) for stationarity


class AnalysisError(MbsError, ValueError):
    """The section cannot be taken (no clock, too short a run, unknown signal): exit code 2."""

    exit_code = 2


# ---------------------------------------------------------------- which body
def driver_period(model) -> tuple[float, str] | None:
    """``(T, body name)`` of the model's first absolute rotation driver at constant speed, else None."""
    k = model.kernel
    for d in range(model.ndriver):
        if (k.driver_type[d] == DriverType.ANGLE and k.driver_body[d, 0] < 0
                and k.driver_motion[d] == MotionType.CONSTANT_SPEED):
            w = float(k.driver_motion_param[d, 1])
            if w != 0.0:
                return 2 * math.pi / abs(w), model.body_names[int(k.driver_body[d, 1])]
    return None


def _bodies(results) -> list[str]:
    return [n[:-4] for n in results.signals if n.endswith(".phi")]


def clock_body(results, model=None) -> str | None:
    """The body whose revolutions clock the section: the body of the model's first absolute
    rotation driver (from the model, or as the results recorded it: `mechanism_facts`), else the
    body whose angle turns most over the run (None: no angle)."""
    if model is not None:
        k = model.kernel
        for d in range(model.ndriver):
            if int(k.driver_type[d]) == DriverType.ANGLE and int(k.driver_body[d, 0]) < 0:
                return model.body_names[int(k.driver_body[d, 1])]
        if results is None:
            return None
    stored = getattr(results, "attrs", {}).get("mechanism") if model is None else None
    if isinstance(stored, dict) and stored.get("clock"):
        return str(stored["clock"])
    best, turn = None, -1.0
    for b in _bodies(results):
        phi = results[f"{b}.phi"]
        net = abs(float(phi[-1] - phi[0])) if len(phi) else 0.0
        if net > turn:
            best, turn = b, net
    return best


def mechanism_facts(model) -> dict:
    """What the figures and sections choose by, read from the model once and stored with its
    results (attribute ``mechanism``): the slider and its axis in the global frame, the clock
    body, the output link and the contact geometry of each clearance element (catalog.PAIRS)."""
    k = model.kernel
    slider, axis = None, None
    for j in range(model.njoint):
        if catalog.JOINTS[int(k.joint_type[j])].slider:
            i1, i2 = (int(b) for b in k.joint_body[j])
            if i1 < 0 <= i2 or i2 < 0 <= i1:
                slider = model.body_names[max(i1, i2)]
                phi = 0.0 if i1 < 0 else float(np.asarray(model.q0, float)[3 * i1 + 2])
                ux, uy = (float(u) for u in k.joint_axis[j])
                c, s = math.cos(phi), math.sin(phi)
                axis = [c * ux - s * uy, s * ux + c * uy]
                break
    clock = clock_body(None, model)
    return {"slider": slider, "slider_axis": axis, "clock": clock, "output": _pivoted_output(model, clock),
            "contacts": {n: catalog.PAIRS[int(k.clearance_param[c, CP_KIND])].name
                         for c, n in enumerate(model.clearance_names)}}


def facts(results, model=None) -> dict | None:
    """`mechanism_facts` of the model when given, else as the results recorded them (None: a file
    written before they were)."""
    if model is not None:
        return mechanism_facts(model)
    stored = getattr(results, "attrs", {}).get("mechanism") if results is not None else None
    return stored if isinstance(stored, dict) else None


def _pivoted_output(model, clock) -> str | None:
    """The last body of the model, other than the clock, that a joint or a clearance element ties
    to ground by a pin (the rocker of a four-bar); None when there is none."""
    k = model.kernel
    pairs = [tuple(int(b) for b in k.joint_body[j]) for j in range(model.njoint)
             if not catalog.JOINTS[int(k.joint_type[j])].slider]
    pairs += [tuple(int(b) for b in k.clearance_body[c]) for c in range(model.nclearance)]
    found = [max(a, b) for a, b in pairs if (a < 0) != (b < 0) and model.body_names[max(a, b)] != clock]
    return model.body_names[max(found)] if found else None


def slider_body(results, model=None) -> str | None:
    """The body shown as "the slider": the body a joint marked `slider` in the catalog (the
    translational one) ties to ground (from the model, or as the results recorded it); else the
    one body that moves without turning; else a body named like a slider; else None (a mechanism
    without a slider: the output link is sectioned instead, `output_body`)."""
    known = facts(results, model)
    if known and known.get("slider"):
        return str(known["slider"])
    bodies = _bodies(results) if results is not None else list(model.body_names if model else [])
    if not bodies:
        return None
    if results is None:
        still = []
    else:
        still = [b for b in bodies if f"{b}.x" in results and np.ptp(results[f"{b}.phi"]) < 1e-9
                 and np.ptp(results[f"{b}.x"]) + np.ptp(results[f"{b}.y"]) > 0]
    if len(still) == 1:
        return still[0]
    named = [b for b in (still or bodies) if any(w in b.lower() for w in SLIDER_WORDS)]
    return named[0] if named else None


def slider_signals(results, model=None, body: str | None = None) -> tuple[str, str]:
    """``(velocity, acceleration)`` of the slider along its axis: ``(<b>.vy, <b>.ay)`` when its joint's
    axis is nearer y than x, else ``(<b>.vx, <b>.ax)``; without a recorded axis, along the
    coordinate in which the body moves more in the results."""
    body = body or slider_body(results, model)
    known = facts(results, model)
    axis = known.get("slider_axis") if known and known.get("slider") == body else None
    if axis is not None:
        along_y = abs(float(axis[1])) > abs(float(axis[0]))
    elif results is not None and f"{body}.x" in results and f"{body}.y" in results:
        along_y = float(np.ptp(results[f"{body}.y"])) > float(np.ptp(results[f"{body}.x"]))
    else:
        along_y = False
    c = "y" if along_y else "x"
    return f"{body}.v{c}", f"{body}.a{c}"


def _turns(results, body) -> bool:
    return results is not None and f"{body}.phi" in results and float(np.ptp(results[f"{body}.phi"])) > 2 * math.pi


def _pivots_on_ground(results, body, tol: float = 1e-6) -> bool:
    """Is the body's motion in the results a rotation about a fixed point, (x, y) = c + R(phi) d?
    (Least squares for c and d; the residual relative to the motion's size.)"""
    names = [f"{body}.{q}" for q in ("x", "y", "phi")]
    if any(n not in results for n in names):
        return False
    x, y, phi = (np.asarray(results[n], float) for n in names)
    if np.ptp(phi) < 1e-3 or len(x) < 4:
        return False
    c, s, one, zero = np.cos(phi), np.sin(phi), np.ones_like(phi), np.zeros_like(phi)
    a = np.block([[one[:, None], zero[:, None], c[:, None], -s[:, None]],
                  [zero[:, None], one[:, None], s[:, None], c[:, None]]])
    rhs = np.concatenate([x, y])
    sol, *_ = np.linalg.lstsq(a, rhs, rcond=None)
    size = max(float(np.hypot(sol[2], sol[3])), 1e-12)
    return float(np.max(np.abs(a @ sol - rhs))) <= tol * size


def output_body(results, model=None) -> str | None:
    """The output link sectioned when there is no slider (module docstring): from the model or as
    the results recorded it, else the last body of the results, other than the clock, whose motion
    is a rotation about a fixed point."""
    known = facts(results, model)
    if known is not None:
        return known.get("output") or None
    if results is None:
        return None
    clock = clock_body(results)
    found = [b for b in _bodies(results) if b != clock and _pivots_on_ground(results, b)]
    return found[-1] if found else None


def default_signals(results, model=None) -> tuple[str, str]:
    """The default section plane: the slider's velocity and acceleration along its axis
    (`slider_signals`), else the output link's angle and angular velocity (`output_body`);
    `AnalysisError` naming ``-p X:Y`` when the results hold neither."""
    body = slider_body(results, model)
    names = slider_signals(results, model, body) if body else None
    if body is None:
        out = output_body(results, model)
        if out is not None:
            names = (f"{out}.omega", f"{out}.alpha") if _turns(results, out) else (f"{out}.phi", f"{out}.omega")
            if results is None or all(n in results for n in names):
                return names
    if names is not None and (results is None or all(n in results for n in names)):
        return names
    bodies = _bodies(results) if results is not None else list(model.body_names if model else [])
    other = next((b for b in reversed(bodies) if b != clock_body(results, model)), "crank")
    what = (f"no slider signals ({', '.join(names)})" if body else
            "no slider in this mechanism (and no output link pivoted on ground)")
    raise AnalysisError(f"{what} to take the Poincaré section of; name two signals with `-p X:Y` "
                        f"(e.g. `-p {other}.omega:{other}.alpha`)")


# ---------------------------------------------------------------- when
def crossings(t: np.ndarray, phi: np.ndarray, angle: float | None = None) -> np.ndarray:
    """Times at which the clock angle passes a level: ``phi − phi[0] = 2πk`` (k ≥ 1) when
    ``angle`` is None, else ``phi = angle + 2πk``, in the direction of the net turn.
    Every level crossed between two samples counts, located by linear interpolation."""
    if len(phi) < 2:
        return np.zeros(0)
    sign = 1.0 if phi[-1] >= phi[0] else -1.0
    if angle is None:
        s = sign * (phi - phi[0]) / (2 * math.pi)
        lvl = np.floor(s + 1e-9)  # a turn completed to round-off at the last sample counts
    else:
        s = sign * (phi - angle) / (2 * math.pi)
        lvl = np.floor(s)
    out = []
    for i in np.nonzero(np.diff(lvl) > 0)[0]:
        for level in range(int(lvl[i]) + 1, int(lvl[i + 1]) + 1):
            f = (level - s[i]) / (s[i + 1] - s[i])
            out.append(t[i] + f * (t[i + 1] - t[i]))
    return np.asarray(out, float)


def section_times(t: np.ndarray, period: float, transient: float = 1.0, phase: float = 0.0) -> np.ndarray:
    """Stroboscopic section times ``t0 + phase + kT`` inside the run, the first ``transient``
    dropped (k ≥ transient + 1)."""
    if len(t) == 0:
        return np.zeros(0)
    t0, t1 = float(t[0]), float(t[-1])
    k0 = math.ceil(transient - 1e-9) + 1
    k1 = math.floor((t1 - t0 - phase) / period * (1 + 1e-12) + 1e-9)
    if k1 < k0:
        return np.zeros(0)
    return np.minimum(t0 + phase + period * np.arange(k0, k1 + 1), t1)


def snap_to_grid(t: np.ndarray, ts: np.ndarray, rel: float = 1e-6) -> tuple[np.ndarray, bool]:
    """Replace section times by the output times they coincide with (within ``rel`` of the
    output step); True if all of them do."""
    if len(ts) == 0 or len(t) < 2:
        return ts, True
    dt = float(np.min(np.diff(t)))
    idx = np.clip(np.searchsorted(t, ts), 1, len(t) - 1)
    near = np.where(np.abs(t[idx] - ts) < np.abs(t[idx - 1] - ts), idx, idx - 1)
    hit = np.abs(t[near] - ts) <= rel * dt
    return np.where(hit, t[near], ts), bool(hit.all())


def sample(t: np.ndarray, x: np.ndarray, ts: np.ndarray) -> tuple[np.ndarray, float]:
    """Values of ``x`` at times ``ts`` (linear interpolation; exact on the grid) and the
    largest interpolation error estimated from the local second difference (|x''| h²/8)."""
    if len(ts) == 0:
        return np.zeros(0), 0.0
    idx = np.clip(np.searchsorted(t, ts), 1, len(t) - 1)
    lo, hi = t[idx - 1], t[idx]
    frac = (ts - lo) / (hi - lo)
    vals = x[idx - 1] + frac * (x[idx] - x[idx - 1])
    i0 = np.clip(idx - 1, 1, len(t) - 2) if len(t) > 2 else idx - 1
    d2 = np.abs(x[i0 + 1] - 2 * x[i0] + x[i0 - 1]) if len(t) > 2 else np.zeros(len(ts))
    on_grid = (np.minimum(frac, 1 - frac) * (hi - lo)) <= 1e-9 * (hi - lo) + 1e-12 * np.abs(ts)
    vals = np.where(ts == hi, x[idx], np.where(ts == lo, x[idx - 1], vals))  # output values exactly
    return vals, float(np.where(on_grid, 0.0, d2 / 8).max())


# ---------------------------------------------------------------- the section
@dataclass
class PoincareSection:
    """Section points of a run: ``points[name]`` sampled at ``time``; ``revolution[i]`` is the
    crossing number of point i counted from the start of the run (1 = end of the first)."""

    time: np.ndarray
    points: dict[str, np.ndarray]
    period: float | None  # mean time between crossings (s); the driver period at constant speed
    transient: float  # crossings dropped
    method: str  # "grid" (section times are output times) or "interpolated"
    kind: str = "revolution"  # "revolution", "angle" or "stroboscopic"
    angle: float | None = None  # rad, for kind == "angle"
    clock: str | None = None  # the body whose angle clocks the section
    interp_error: dict[str, float] = field(default_factory=dict)  # relative, per signal
    scale: dict[str, float] = field(default_factory=dict)  # spread of each signal after the transient
    revolution: np.ndarray | None = None

    def __post_init__(self):
        if self.revolution is None:
            self.revolution = np.arange(len(self.time)) + int(math.ceil(self.transient - 1e-9)) + 1

    @property
    def names(self) -> list[str]:
        return list(self.points)

    def array(self, names: Sequence[str] | None = None) -> np.ndarray:
        names = list(names or self.names)
        return np.column_stack([self.points[n] for n in names]) if len(self.time) else np.zeros((0, len(names)))

    def __len__(self) -> int:
        return len(self.time)

    def attrs(self) -> dict:
        return {
            "period": self.period if self.period is not None else float("nan"),
            "transient": self.transient, "method": self.method, "kind": self.kind,
            "angle": self.angle if self.angle is not None else float("nan"),
            "clock": self.clock or "", "signals": self.names,
            "interp_error": self.interp_error, "scale": self.scale,
        }


def poincare_section(results, signals: Sequence[str] | None = None, *, period: float | None = None,
                     angle: float | None = None, clock: str | None = None, transient: float = 1.0,
                     model=None) -> PoincareSection:
    """Sample ``signals`` (default: `default_signals`) of a run at the section (module
    docstring): once per revolution of the clock body, at its ``angle``, or every
    ``period`` seconds when a period is given; the first ``transient`` crossings dropped."""
    t = results.time
    if len(t) < 2:  # before choosing signals: an empty run has no motion to choose by
        raise AnalysisError(f"the run holds {len(t)} output time{'s' if len(t) != 1 else ''}: a section needs "
                            "at least two (it stopped at once, or was written empty)")
    signals = (signals,) if isinstance(signals, str) else tuple(signals) if signals else \
        default_signals(results, model)
    for name in signals:
        results[name]  # KeyError with a suggestion
    if period is not None and angle is None and period < (t[-1] - t[0]) / (len(t) - 1) * (1 - 1e-9):
        raise AnalysisError(f"the period {period:.6g} s is shorter than the output step "
                            f"{(t[-1] - t[0]) / (len(t) - 1):.6g} s: the section would only interpolate between "
                            "samples (and hold more points than the run has rows)",
                            )
    if period is not None and angle is None:
        ts, kind = section_times(t, period, transient), "stroboscopic"
        first = math.ceil(transient - 1e-9) + 1
    else:
        clock = clock or clock_body(results, model)
        if clock is None or f"{clock}.phi" not in results:
            raise AnalysisError(f"no body angle `{clock}.phi` to clock the Poincaré section" if clock else
                                "the results hold no body angle to clock a Poincaré section; give a period")
        ts = crossings(t, results[f"{clock}.phi"], angle)
        skip = math.ceil(transient - 1e-9)
        ts, kind, first = ts[skip:], ("revolution" if angle is None else "angle"), skip + 1
        if len(ts) > 1:
            period = float(np.mean(np.diff(ts)))
    ts, on_grid = snap_to_grid(t, ts)
    points, errors, scale = {}, {}, {}
    start = np.searchsorted(t, ts[0]) if len(ts) else len(t)
    for name in signals:
        x = results[name]
        vals, err = sample(t, x, ts)
        spread = float(np.ptp(x[start:])) if start < len(t) else 0.0
        points[name], scale[name] = vals, spread
        errors[name] = err / spread if spread > 0 else 0.0
    return PoincareSection(time=np.asarray(ts, float), points=points, period=period, transient=transient,
                           method="grid" if on_grid else "interpolated", kind=kind, angle=angle, clock=clock,
                           interp_error=errors, scale=scale, revolution=np.arange(len(ts)) + first)


# ---------------------------------------------------------------- where the motion settles
def normalise(points: np.ndarray, scale: Sequence[float] | None = None) -> np.ndarray:
    """Points divided by each column's spread (``scale``, else the points' own range)."""
    points = np.asarray(points, float)
    if points.ndim == 1:
        points = points[:, None]
    s = np.asarray(scale if scale is not None else np.ptp(points, axis=0), float)
    s = np.where(s > 0, s, 1.0)
    return (points - points.mean(axis=0)) / s


def periodic_from(x: np.ndarray, p: int, tol: float = TOL_PERIODIC, spread: float = SETTLED_SPREAD) -> int | None:
    """First index from which the points are on a period-``p`` orbit, on a normalised sequence:
    every later point recurs after ``p`` iterations (``|x[k+p] − x[k]| < tol``), and the later
    points of each of the ``p`` phases stay within ``spread`` of each other (the diagonal of
    their bounding box: a slow drift whose steps are below ``tol`` is no orbit).  None if that
    window is shorter than `MIN_SETTLED` points or than 3p."""
    n = len(x)
    if n <= p:
        return None
    bad = np.nonzero(np.linalg.norm(x[p:] - x[:-p], axis=1) >= tol)[0]
    start = int(bad[-1]) + 1 if len(bad) else 0
    wide = np.nonzero(phase_extent(x, p) >= spread)[0]
    start = max(start, int(wide[-1]) + 1 if len(wide) else 0)
    return start if n - start >= max(MIN_SETTLED, 3 * p) else None


def phase_extent(x: np.ndarray, p: int) -> np.ndarray:
    """``e[i]``: the extent (bounding-box diagonal) of the points ``x[i], x[i+p], x[i+2p], …``
    (point i and the later points of its phase)."""
    e = np.zeros(len(x))
    for r in range(min(p, len(x))):
        tail = x[r::p][::-1]
        hi, lo = np.maximum.accumulate(tail, axis=0), np.minimum.accumulate(tail, axis=0)
        e[r::p] = np.linalg.norm(hi - lo, axis=1)[::-1]
    return e


def stationary_window(n: int) -> int:
    """Points per window of the stationarity test on ``n`` points."""
    return max(MIN_SETTLED, n // 10)


def stationary_from(x: np.ndarray, tol: float = STATIONARY_TOL) -> int | None:
    """Start of the first window of points from which every later window has the mean and
    the spread (standard deviation) of the last half, within ``tol`` of the normalised
    scale (windows of max(MIN_SETTLED, n/10) points), and whose two halves agree too.
    None when there is no such part or it is shorter than a quarter of the run."""
    n = len(x)
    w = stationary_window(n)
    if n < 2 * w:
        return None
    ref = x[n // 2:]
    mean, std = ref.mean(axis=0), ref.std(axis=0)
    starts = list(range(0, n - w + 1, w))
    ok = [bool(np.all(np.abs(x[s:s + w].mean(axis=0) - mean) < tol)
               and np.all(np.abs(x[s:s + w].std(axis=0) - std) < tol)) for s in starts]
    first = None
    for s, good in zip(reversed(starts), reversed(ok)):
        if not good:
            break
        first = s
    if first is None or n - first < n // 4:
        return None
    a, b = np.array_split(x[first:], 2)  # no trend inside the stationary part either
    same = np.all(np.abs(a.mean(axis=0) - b.mean(axis=0)) < tol) and np.all(np.abs(a.std(axis=0) - b.std(axis=0)) < tol)
    return first if same else None


def settling(points, scale: Sequence[float] | None = None, *, tol_periodic: float = TOL_PERIODIC,
             max_period: int = MAX_PERIOD) -> tuple[int | None, int | None]:
    """``(index, period)`` where the section points settle: the earliest index from which
    they are on an orbit of the smallest period p ≤ ``max_period`` (`periodic_from`;
    ``period = p``), else the start of the stationary part (`stationary_from`; ``period =
    None``: steady statistics, not an orbit); ``(None, None)``: not settled."""
    x = normalise(points, scale)
    for p in range(1, max_period + 1):
        s = periodic_from(x, p, tol_periodic)
        if s is not None:
            return s, p
    return stationary_from(x), None


def settling_of_results(results, model=None, periodic_only: bool = False) -> int | None:
    """The revolution from which the default section of a run has settled (None: not yet);
    ``periodic_only``: settled on a periodic orbit (chaos can look stationary for hundreds
    of revolutions before it stops, so a run that waits for settling waits for this)."""
    sec = poincare_section(results, model=model)
    if len(sec) < MIN_SETTLED:
        return None
    idx, period = settling(sec.array(), [sec.scale[n] for n in sec.names])
    if idx is None or (periodic_only and period is None):
        return None
    return int(sec.revolution[idx])
