"""Joints that wear: Archard's law on a revolute clearance joint's bearing, coupled to the motion.

Archard's law, local form: the worn depth of the bearing grows at h' = k_d p v, with p the contact
pressure, v the sliding speed of the two surfaces and k_d = k / H the dimensional wear coefficient
(k dimensionless, H the hardness of the softer surface; Archard, "Contact and rubbing of flat
surfaces", J. Appl. Phys. 24 (1953)).  Integrated over the surface per unit width it is
V' = k_d (F / L) v whatever the pressure distribution: the worn volume per unit width after a
sliding distance s at load F is k_d F s / L.

**Pressure over the patch: a Winkler foundation.**  The contact law gives the total normal force F;
how it spreads over the bearing is the overlap of the journal circle with the bearing profile
(rigid bodies on a bed of independent springs, Winkler's foundation, as Flores (2009) and Mukras et al.
(2010) use for the wear of clearance joints): at node i of the profile, at angle theta_i in the bearing
frame, the overlap is delta_i = rho(theta_i) - r_i (rho the journal's boundary along the ray, r_i the
worn bearing radius), and p_i = (F / L) delta_i^+ / (R_B dtheta sum_j delta_j^+) so that the pressures
of the nodes add up to F / L exactly (the sum of node depths times R_B dtheta is the worn volume per
unit width, so V = k_d F s / L holds on the nodes, not only in the limit).  For the circle
delta(psi) = e cos(psi) - c (psi from the line of centres): a pressure nearly parabolic in psi, over
|psi| < arccos(c / e).  A patch narrower than the node spacing (no node overlapped) puts the load on
the node that comes closest.  The choice over Hertz's elliptical pressure: it needs no second
elastic constant, follows the worn shape without a closed form, and is the one of the papers compared.

**Two time scales** (the iterative scheme of Mukras et al.): the motion runs on a fixed profile for
`interval` seconds (a stated number of revolutions) while the wear of each output sample accumulates
on the nodes (the rectangle rule on the output grid: output_step sets its accuracy); the wear of the
interval, multiplied by `factor` (the cycles one update stands for per cycle simulated), is added to
the profile, the profile is given to the kernel (`kernel.wear`) and the motion goes on from its state.
`factor = 1` is plain integration with the profile updated every interval.  With `depth_step` the factor
of each update is chosen instead so that the deepest node wears `depth_step` (the profile is updated
every stated worn depth, the extrapolation step following the wear rate).  `halving_check` runs the
same worn time with the extrapolation step halved.

The profile lives in the run's contact memory (columns past N_CONTACT_STATE, `kernel.wear`), never in
the compiled model; a profile that is zero everywhere is given as the circle, so a joint that does not
wear runs the unworn code bit for bit.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from .. import catalog
from ..errors import ModelError
from ..files import replace_atomically
from ..lazy import lazy
from ..mechanism.model import (CP_KIND, CP_LENGTH, CP_R_BEARING, CP_R_JOURNAL, CS_EX, CS_EY, CS_FN, CS_IN_CONTACT, CS_SLIP,
                               CT_WEAR_NODES, CT_WEAR_TABLE, N_CLEARANCE_SIGNALS, N_CONTACT_STATE, OB_CLEARANCE,
                               OB_Q, Model, PairKind, observation_layout)
from ..results.section import driver_period
from .stepper import Stepper

h5py = lazy("h5py")  # heavy: `import planar_mbs.run.wear` for the geometry alone loads no h5py

WINDOW = 1.0 / 12.0  # half-width of the nodes searched for the patch around the journal's direction (a turn)


@dataclass(frozen=True)
class Archard:
    """Archard wear of one revolute clearance joint's bearing.

    coefficient: k_d = k / H [1/Pa]; nodes: N points of the profile on [0, 2 pi); interval: seconds of
    motion per profile update; factor: the interval's wear is multiplied by it before each update
    (extrapolation); updates: how many; depth_step (m, 0: off): each update's factor chosen so that the
    deepest node wears this much instead."""

    coefficient: float
    interval: float
    factor: float = 1.0
    updates: int = 1
    nodes: int = 360
    depth_step: float = 0.0

    @classmethod
    def of(cls, model: Model, joint: str) -> "Archard":
        """The wear the model writes on `joint` (`wear = archard(...)`)."""
        w = model.clearance_wear.get(joint)
        if w is None:
            raise ModelError(f"clearance joint `{joint}` has no `wear`",
                             hint="add `wear = archard(coefficient = 1e-4, hardness = 2 GPa, update = 2 rev / speed)`")
        return cls(w["coefficient"], w["update"], w["factor"], int(w["updates"]), int(w["nodes"]),
                   w.get("depth_step", 0.0))

    def __post_init__(self):
        if not (self.coefficient >= 0 and math.isfinite(self.coefficient)):
            raise ModelError(f"wear coefficient must be >= 0 (got {self.coefficient})")
        if not (self.interval > 0 and self.factor > 0 and self.updates >= 1 and self.nodes >= 8
                and self.depth_step >= 0):
            raise ModelError("wear needs interval > 0, factor > 0, updates >= 1 and at least 8 nodes",
                             hint="e.g. Archard(coefficient=1e-14, interval=2 * 60 / 5000, factor=100, updates=10)")


def spline_moments(y: np.ndarray) -> np.ndarray:
    """Second derivatives (in theta) of the periodic cubic spline through y at theta_i = 2 pi i / N:
    M_{i-1} + 4 M_i + M_{i+1} = 6 (y_{i-1} - 2 y_i + y_{i+1}) / h^2, circulant, solved by FFT."""
    n = len(y)
    h = 2.0 * math.pi / n
    lam = 2.0 * np.cos(2.0 * math.pi * np.arange(n) / n)
    return np.real(np.fft.ifft(np.fft.fft(y) * (6.0 / (h * h)) * (lam - 2.0) / (4.0 + lam)))


def profile_columns(depth: np.ndarray) -> np.ndarray:
    """The contact-memory columns past N_CONTACT_STATE of a worn depth (N nodes): [N, w_i, w''_i];
    [0, ...] (the circle) when the depth is zero everywhere."""
    y = np.asarray(depth, dtype=np.float64)
    out = np.zeros(1 + 2 * len(y))
    if np.any(y != 0.0):
        out[0] = len(y)
        out[1:1 + len(y)] = y
        out[1 + len(y):] = spline_moments(y)
    return out


def with_profile(contact: np.ndarray, k: int, depth: np.ndarray) -> np.ndarray:
    """A contact memory wide enough for the profile, joint k's set to `depth` (others kept)."""
    cols = profile_columns(depth)
    width = max(contact.shape[1], CT_WEAR_NODES + len(cols))
    out = np.zeros((contact.shape[0], width))
    out[:, :contact.shape[1]] = contact
    out[k, CT_WEAR_NODES:CT_WEAR_NODES + len(cols)] = cols
    return out


def spline_at(depth: np.ndarray, theta) -> np.ndarray:
    """The periodic cubic spline through `depth` at angles theta (for plots and checks)."""
    n = len(depth)
    h = 2.0 * math.pi / n
    m = spline_moments(depth)
    u = np.asarray(theta, dtype=float) / h
    i = np.floor(u).astype(int) % n
    t = u - np.floor(u)
    j = (i + 1) % n
    s = 1.0 - t
    return s * depth[i] + t * depth[j] + h * h / 6.0 * ((s ** 3 - s) * m[i] + (t ** 3 - t) * m[j])


def patch_weights(rb: float, rj: float, depth: np.ndarray, px, py):
    """(nodes, weights): for each sample (rows of px, py: the journal centre in the bearing frame) the
    node indices within WINDOW of its direction and the Winkler overlaps delta_i^+ there, each row
    scaled to sum 1 (the node that comes closest takes all where none overlaps)."""
    n = len(depth)
    h = 2.0 * math.pi / n
    m = max(1, int(n * WINDOW))
    te = np.arctan2(py, px)
    i0 = np.floor(te / h + 0.5).astype(int)
    idx = i0[:, None] + np.arange(-m, m + 1)[None, :]
    th = idx * h
    nodes = idx % n
    along = px[:, None] * np.cos(th) + py[:, None] * np.sin(th)
    across = -px[:, None] * np.sin(th) + py[:, None] * np.cos(th)
    rho = along + np.sqrt(np.maximum(rj * rj - across * across, 0.0))
    overlap = rho - (rb + depth[nodes])
    w = np.maximum(overlap, 0.0)
    total = w.sum(axis=1)
    none = total <= 0.0
    if np.any(none):
        best = np.argmax(overlap[none], axis=1)
        w[none] = 0.0
        w[np.flatnonzero(none), best] = 1.0
        total = w.sum(axis=1)
    return nodes, w / total[:, None]


@dataclass
class WearHistory:
    """The profiles of one wearing run: after each update, the motion's time, the worn time it stands
    for (motion time x factor) and the node depths (m)."""

    joint: str
    wear: Archard
    radius: float
    times: list = field(default_factory=list)
    worn_times: list = field(default_factory=list)
    depths: list = field(default_factory=list)
    peak_forces: list = field(default_factory=list)  # largest contact force of each update's motion (N; NaN first)
    in_contact: list = field(default_factory=list)  # share of its samples in contact (NaN first)

    @property
    def theta(self) -> np.ndarray:
        return 2.0 * math.pi * np.arange(self.wear.nodes) / self.wear.nodes

    def volume(self, i: int = -1) -> float:
        """Worn volume per unit width (m^2): R_B times the integral of the depth (first order in depth/R_B;
        the periodic spline's integral equals the node sum)."""
        return float(self.radius * np.sum(self.depths[i]) * 2.0 * math.pi / self.wear.nodes)

    def max_depth(self, i: int = -1) -> float:
        return float(np.max(self.depths[i]))

    def max_angle(self, i: int = -1) -> float:
        """Angle (rad, bearing frame) of the deepest node."""
        return float(self.theta[int(np.argmax(self.depths[i]))])

    def signals(self) -> dict[str, np.ndarray]:
        """Per update: worn volume per unit width, maximum depth and its angle."""
        r = range(len(self.depths))
        return {"worn_time": np.array(self.worn_times), "time": np.array(self.times),
                f"{self.joint}.worn_volume": np.array([self.volume(i) for i in r]),
                f"{self.joint}.max_wear_depth": np.array([self.max_depth(i) for i in r]),
                f"{self.joint}.max_wear_angle": np.array([self.max_angle(i) for i in r]),
                f"{self.joint}.peak_contact_force": np.array(self.peak_forces),
                f"{self.joint}.in_contact_share": np.array(self.in_contact)}


def clearance_index(model: Model, joint: str) -> int:
    if joint not in model.clearance_names:
        raise ModelError(f"no clearance joint `{joint}` (the model has {', '.join(model.clearance_names) or 'none'})")
    k = model.clearance_names.index(joint)
    p = model.kernel.clearance_param[k]
    if int(p[CP_KIND]) != PairKind.CIRCLE_IN_CIRCLE:
        raise ModelError(f"`{joint}` is not a revolute clearance joint: only a bearing wears here")
    if not (p[CP_LENGTH] > 0.0):
        raise ModelError(f"wear of clearance joint `{joint}` needs its `length` (the wear is per unit width)")
    return k


def _layout(model: Model) -> tuple:
    km = model.kernel
    return observation_layout(len(km.body_mass), len(km.joint_type), len(km.driver_type), model.nclearance,
                              len(km.force_type))


def wear_increment(model: Model, k: int, t_start: float, times: np.ndarray, rows: np.ndarray, depth: np.ndarray,
                   coefficient: float) -> np.ndarray:
    """Worn depth per node over the rows of one interval on the fixed profile `depth`: the sum over
    samples of k_d p_i |v_T| dt (rectangle rule, dt from the previous sample or the interval's start)."""
    p = model.kernel.clearance_param[k]
    rb, rj, length = float(p[CP_R_BEARING]), float(p[CP_R_JOURNAL]), float(p[CP_LENGTH])
    km = model.kernel
    lay = _layout(model)
    col = lay[OB_CLEARANCE] + N_CLEARANCE_SIGNALS * k
    bi = int(km.clearance_body[k, 0])
    F = rows[:, col + CS_FN]
    dt = np.diff(np.concatenate([[t_start], times]))
    on = (F > 0.0) & (dt > 0.0)
    out = np.zeros(len(depth))
    if coefficient == 0.0 or not np.any(on):
        return out
    phi = rows[on, lay[OB_Q] + 3 * bi + 2] if bi >= 0 else np.zeros(int(on.sum()))
    ex, ey = rows[on, col + CS_EX], rows[on, col + CS_EY]
    c, s = np.cos(phi), np.sin(phi)
    nodes, w = patch_weights(rb, rj, depth, c * ex + s * ey, -s * ex + c * ey)
    arc = rb * 2.0 * math.pi / len(depth)
    amount = coefficient * F[on] / length * np.abs(rows[on, col + CS_SLIP]) * dt[on] / arc
    np.add.at(out, nodes.ravel(), (w * amount[:, None]).ravel())
    return out


STEPPER_SETTINGS = ("integrator", "rtol", "atol", "step", "output_step")  # saved, for a resumed run to go on alike


def run_facts(model: Model, stepper: Stepper) -> dict:
    """What a saved wear run records of its making: the model file (absolute path), its parameters (JSON),
    the driver's period (s, 0: none) and the integration settings of the trajectory."""
    found = driver_period(model)
    s = stepper.settings
    facts = {"model": os.path.abspath(model.source_path) if model.source_path else "",
             "parameters": json.dumps(model.parameters, sort_keys=True), "period": found[0] if found else 0.0}
    facts.update({f"settings.{k}": getattr(s, k) for k in STEPPER_SETTINGS if k != "integrator"})
    facts["settings.integrator"] = catalog.INTEGRATORS[int(s.integrator)].name
    return facts


class WearRun:
    """One trajectory whose joint wears (`Archard`), advanced update by update (see the module
    docstring); `history` holds the profiles."""

    def __init__(self, model: Model, joint: str, wear: Archard | None = None, stepper: Stepper | None = None,
                 **settings):
        wear = Archard.of(model, joint) if wear is None else wear
        self.model, self.wear = model, wear
        self.k = clearance_index(model, joint)
        self.stepper = Stepper(model, **settings) if stepper is None else stepper
        self.depth = np.zeros(wear.nodes)
        self.history = WearHistory(joint, wear, float(model.kernel.clearance_param[self.k, CP_R_BEARING]))
        self._record(0.0)
        self.install()

    def install(self) -> None:
        """Give the kernel the current profile (the circle while nothing is worn)."""
        d = self.stepper.driver.data
        d.contact = with_profile(d.contact[:, :N_CONTACT_STATE] if d.contact.shape[1] > N_CONTACT_STATE
                                 else d.contact, self.k, self.depth)

    def _record(self, worn_time: float) -> None:
        self.history.times.append(self.stepper.t)
        self.history.worn_times.append(worn_time)
        self.history.depths.append(self.depth.copy())
        if len(self.history.depths) == 1:
            self.history.peak_forces.append(math.nan)
            self.history.in_contact.append(math.nan)

    def step(self) -> np.ndarray:
        """One update: the motion of one interval on the fixed profile, its wear x factor added.
        Returns the interval's wear (before the factor)."""
        t0 = self.stepper.t
        times, rows = self.stepper.run_to(t0 + self.wear.interval)
        col = _layout(self.model)[OB_CLEARANCE] + N_CLEARANCE_SIGNALS * self.k
        self.history.peak_forces.append(float(np.max(rows[:, col + CS_FN], initial=0.0)))
        self.history.in_contact.append(float(np.mean(rows[:, col + CS_IN_CONTACT] > 0)) if len(rows) else math.nan)
        dh = wear_increment(self.model, self.k, t0, times, rows, self.depth, self.wear.coefficient)
        factor = self.wear.factor
        if self.wear.depth_step > 0 and dh.max() > 0:
            factor = self.wear.depth_step / dh.max()
        self.depth = self.depth + factor * dh
        self.install()
        self._record(self.history.worn_times[-1] + self.wear.interval * factor)
        return dh

    def run(self, callback=None, output=None) -> WearHistory:
        """The updates still to do (all of `wear.updates` from the start); ``callback(self)`` after each;
        with `output`, the history and the state written there after each (`save`), so that a long run
        stopped at any point goes on from its file (`WearRun.resume`)."""
        while len(self.history.depths) <= self.wear.updates:
            self.step()
            if output is not None:
                self.save(output)
            if callback is not None:
                callback(self)
        return self.history

    def save(self, path) -> None:
        """The profiles so far, the wear's settings, the trajectory's state (y, contact memory, t) and what
        made the run (`run_facts`), in group ``wear/<joint>`` of an HDF5 file written whole (a kill leaves
        the previous one)."""
        path = str(path)
        h, d = self.history, self.stepper.driver.data
        with h5py.File(path + ".part", "w") as f:
            g = f.create_group(f"wear/{h.joint}")
            g["theta"], g["depth"] = h.theta, np.array(h.depths)
            g["time"], g["worn_time"] = np.array(h.times), np.array(h.worn_times)
            g["peak_contact_force"], g["in_contact_share"] = np.array(h.peak_forces), np.array(h.in_contact)
            g["state/y"], g["state/contact"] = d.y, d.contact[:, :N_CONTACT_STATE]
            g["state"].attrs["t"] = self.stepper.t
            for key in ("coefficient", "interval", "factor", "updates", "nodes", "depth_step"):
                g.attrs[key] = getattr(self.wear, key)
            g.attrs["radius"] = h.radius
            for key, value in run_facts(self.model, self.stepper).items():
                g.attrs[key] = value
        replace_atomically(path + ".part", path)

    @classmethod
    def resume(cls, model: Model, path, updates: int | None = None, **settings) -> "WearRun":
        """The wear run saved in `path` (`save`), continued from its last update; `updates`: a new total."""
        h = load_history(path)
        with h5py.File(str(path), "r") as f:
            g = f[f"wear/{h.joint}/state"]
            y, contact, t = g["y"][()], g["contact"][()], float(g.attrs["t"])
        wear = h.wear if updates is None else Archard(h.wear.coefficient, h.wear.interval, h.wear.factor, updates,
                                                      h.wear.nodes, h.wear.depth_step)
        run = cls(model, h.joint, wear, Stepper.restore(model, y, contact, t, **settings))
        run.history = h
        run.history.wear = wear
        run.depth = h.depths[-1].copy()
        run.install()
        return run


def load_history(path, joint: str | None = None) -> WearHistory:
    """The `WearHistory` a wear run saved (`WearRun.save`); `joint`: which, where the file holds several."""
    with h5py.File(str(path), "r") as f:
        joints = list(f["wear"]) if "wear" in f else []
        if not joints or (joint is not None and joint not in joints):
            raise ModelError(f"{path} holds no wear history" + (f" of `{joint}`" if joint else ""))
        g = f[f"wear/{joint or joints[0]}"]
        a = g.attrs
        wear = Archard(float(a["coefficient"]), float(a["interval"]), float(a["factor"]), int(a["updates"]),
                       int(a["nodes"]), float(a.get("depth_step", 0.0)))
        return WearHistory(joint or joints[0], wear, float(a["radius"]), list(g["time"][()]),
                           list(g["worn_time"][()]), list(g["depth"][()]), list(g["peak_contact_force"][()]),
                           list(g["in_contact_share"][()]))


def saved_facts(path, joint: str) -> dict:
    """The attributes a wear run saved for `joint` (its settings and `run_facts`)."""
    with h5py.File(str(path), "r", locking=False) as f:
        return dict(f[f"wear/{joint}"].attrs)


def run_wear(model: Model, joint: str, wear: Archard | None = None, **settings) -> WearHistory:
    """The profiles of `joint` after each of `wear.updates` updates (settings as in `simulate`)."""
    return WearRun(model, joint, wear, **settings).run()


def halving_check(model: Model, joint: str, wear: Archard, start=None, **settings) -> dict:
    """The same worn time with the extrapolation factor halved (twice the updates): the final worn
    volume and maximum depth of both, and their relative changes.  ``start()``, where given, makes
    the trajectory each run begins from (a `Stepper`; default: the model's assembled start)."""
    half = Archard(wear.coefficient, wear.interval, wear.factor / 2, 2 * wear.updates, wear.nodes, wear.depth_step / 2)
    a, b = (WearRun(model, joint, w, None if start is None else start(), **settings).run() for w in (wear, half))
    return {"volume": (a.volume(), b.volume()), "max_depth": (a.max_depth(), b.max_depth()),
            "volume_change": abs(a.volume() - b.volume()) / b.volume(),
            "depth_change": abs(a.max_depth() - b.max_depth()) / b.max_depth(),
            "profile_change": float(np.max(np.abs(a.depths[-1] - b.depths[-1])) / b.max_depth())}
