"""The compiled right-hand side at one state, called from Python: generalized forces and accelerations.

`StateRhs` calls `kernel.accelerations` (the function the time loop's right-hand side calls) at a
state (q, q', t) and returns the generalized applied forces Qe (loads, springs, gravity, the contact
and film forces of the clearance elements), the accelerations q'' and the multipliers.  The
equilibrium (`run/static.py`) and the linearisation (`run/modes.py`) read the mechanism only
through it, so they see the forces and the constrained dynamics exactly as a run does, with two
differences that make the result a function of the state alone:

* no Baumgarte feedback (alpha = beta = 0): on the constraints it is zero, and the chart
  (`run/manifold.py`) keeps every state on them to rounding;
* every clearance element is in contact mode, so a penetrating one pushes and one apart does not,
  whatever happened before; the impact velocity delta'(-) that the dissipative laws' hysteresis damping
  divides by is given (``contact``) or, as where a run starts in penetration (`kernel/events.py`,
  `init_modes`), the floor `IMPACT_VELOCITY_FLOOR`.  An expression's comparisons are evaluated afresh
  at each call (no frozen switch).

`length_scale` is the length over which the forces change at a state, which sets the steps of the
central differences (`difference_step`: the rule docs/studies.md states).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import sys
from types import SimpleNamespace

import numpy as np

from ..errors import SimulationError
from ..lazy import lazy
from ..mechanism.kinematics import start_gaps
from ..mechanism.model import (CFG_ALPHA, CFG_BETA, CP_CLEARANCE, CP_R_JOURNAL, CT_IMPACT_VELOCITY, CT_MODE,
                               N_CONTACT_STATE, N_STATS, TOUCHING, Model)
from .checks import failure_message
from .first_compile import cache_is_cold

if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from .. import kernel
    from ..kernel import contact as kcontact
else:  # each loaded on its first use (see the comments: not on the light paths)
    kernel = lazy("..kernel", __package__)  # numba: loaded by a study that evaluates forces
    kcontact = lazy("..kernel.contact", __package__)

EPS = float(np.finfo(np.float64).eps)
COLD_NOTE = ("note: compiling the right-hand side for Python calls (numba, once: later studies load it from "
             "the cache; about a minute)")


def contact_memory(model: Model, impact_velocity: float | None = None) -> np.ndarray:
    """Every clearance element in contact mode with the impact velocity given (default: the floor)."""
    contact = np.zeros((model.contact_rows, N_CONTACT_STATE))
    contact[:, CT_MODE] = TOUCHING
    floor = float(kcontact.IMPACT_VELOCITY_FLOOR)
    contact[:, CT_IMPACT_VELOCITY] = floor if impact_velocity is None else max(float(impact_velocity), floor)
    return contact


class StateRhs:
    """The compiled `accelerations` of ``model`` at given states (see the module docstring)."""

    def __init__(self, model: Model, contact: np.ndarray | None = None):
        self.model = model
        self.cfg = model.settings.cfg(model.size)
        self.cfg[CFG_ALPHA] = self.cfg[CFG_BETA] = 0.0
        self.ws = kernel.make_workspace(model.kernel)
        self.stats = np.zeros(N_STATS, dtype=np.int64)
        self.contact = contact_memory(model) if contact is None else np.array(contact, dtype=np.float64)
        self.calls = 0
        if cache_is_cold(kernel.accelerations):  # a first study waits a minute: say why at once
            print(COLD_NOTE, file=sys.stderr, flush=True)

    def __call__(self, q: np.ndarray, qd: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Qe, q'', multipliers) at (q, q', t), copies; SimulationError where the kernel fails."""
        q = np.ascontiguousarray(q, dtype=np.float64)
        qd = np.ascontiguousarray(qd, dtype=np.float64)
        status = kernel.accelerations(self.model.kernel, self.cfg, float(t), q, qd, self.contact, self.ws,
                                      self.stats)
        self.calls += 1
        if status != 0:
            data = SimpleNamespace(t=float(t), stats=self.stats, contact=self.contact, ws=self.ws,
                                   y=np.concatenate([q, qd]))
            raise SimulationError(failure_message(self.model, self.model.settings, int(status), data), time=t)
        return self.ws.Qe.copy(), self.ws.qdd.copy(), self.ws.lam.copy()

    def forces(self, q: np.ndarray, t: float) -> np.ndarray:
        """Qe at rest (q' = 0)."""
        return self(q, np.zeros_like(q), t)[0]


def length_scale(model: Model, q: np.ndarray) -> float:
    """The length over which the forces change at pose q: the mechanism's size, or less where a
    clearance element is near or in contact (its gap or its penetration, whichever holds; at least
    1e-6 of its clearance, or of its journal's radius for an outline contact)."""
    scale = model.size
    params = np.asarray(model.kernel.clearance_param)
    for k, gap in enumerate(start_gaps(model, q)):
        c = params[k, CP_CLEARANCE] if params[k, CP_CLEARANCE] > 0 else params[k, CP_R_JOURNAL]
        floor = 1e-6 * c if c > 0 else 1e-9 * model.size
        scale = min(scale, max(abs(float(gap)), floor))
    return float(scale)


def coordinate_scale(model: Model, q: np.ndarray) -> float:
    """The magnitude of the positions (m): the mechanism's size, or its largest coordinate."""
    xy = np.abs(np.asarray(q, dtype=float).reshape(-1, 3)[:, :2])
    return float(max(model.size, xy.max() if xy.size else 0.0))


def difference_step(model: Model, q: np.ndarray) -> float:
    """The central-difference step of a minimal coordinate (a length, m): h = (eps L l^2)^(1/3), with l
    the `length_scale` of the forces and L the `coordinate_scale` of the positions.  It balances the
    truncation error of central differences, (h / l)^2, against rounding, eps L / h (a position of
    magnitude L is known to eps L); with l = L it is the textbook eps^(1/3) L."""
    l, big = length_scale(model, q), coordinate_scale(model, q)
    return float((EPS * big * l * l) ** (1.0 / 3.0))


def velocity_step(qd_scale: float, model: Model) -> float:
    """The central-difference step of a minimal velocity (m/s): eps^(1/3) max(|z'|, size / 1 s)."""
    return float(EPS ** (1.0 / 3.0) * max(qd_scale, model.size))
