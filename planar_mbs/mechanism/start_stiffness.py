"""How stiff a model is where it starts: every contact element already touching (and every lubricated
film, which acts at any eccentricity), how deep it starts and how fast its force acts there; from the
fastest of them, the steps an explicit run needs at least (`start_contacts`, `check_step_count`).

The normal force F(q, q') of element k pushes the bodies along d = P G^T, where G = d delta'/dq' is
the normal velocity's Jacobian and P = M^-1 - M^-1 Cq^T (Cq M^-1 Cq^T)^+ Cq M^-1 the inverse mass of
the mechanism as its ideal joints and drivers hold it.  Along that motion, q = q0 + s d, the law gives
s'' = -F(q0 + s d, s' d): linearised, a frequency omega^2 = dF/ds (the contact's stiffness over its
effective mass) and a decay rate lambda = dF/ds' (its damping over the mass), measured here by
differences of the law itself (`kernel/contact.py` run as plain Python, `planar_mbs.pykernel`).  An
explicit Runge-Kutta step is stable only while h max(omega, lambda) stays below a few units (about 2.8
for RK4, 3.3 for DOPRI5, 6 for DOP853); `STABLE_STEP` takes the largest, so the count is a lower bound
for as long as the contact stays as stiff as at the start.

A disc started 10 mm inside a steel floor with a dissipative law is the case this is for: its impact
velocity is zero, the law's damping K d^n chi / d'(-) is floored at d'(-) = 1e-5 m/s, and the disc creeps
out at 1e-12 s steps (0.5 s of it would take days).  So is a lubricated journal of 1000 km radius,
whose squeeze film damps the journal in 1e-11 s.  `mbs check` names such contacts; a run refuses them
before it starts when the count is beyond its ``max_steps`` (it would stop there after hours).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
from dataclasses import dataclass

import numpy as np

from .. import catalog
from ..lazy import lazy
from . import beams
from .kinematics import _evaluate, _model_error, assembly_kernel, start_gaps
from .model import CP_CLEARANCE, CP_KIND, CP_R_BEARING, CP_R_JOURNAL, CT_IMPACT_VELOCITY, CT_MODE, \
    N_CONTACT_STATE, TOUCHING, Model, PairKind, Settings

# the contact kernels' source run as plain Python: only a model with contacts needs it (`mbs check` stays light)
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from ..pykernel import constraints as pyconstraints
    from ..pykernel import contact as pycontact
else:  # each loaded on its first use (see the comments: not on the light paths)
    pyconstraints = lazy("..pykernel.constraints", __package__)
    pycontact = lazy("..pykernel.contact", __package__)

STABLE_STEP = 6.0  # h * rate an explicit method of the catalog stays stable at, at most (DOP853's real axis)
DEEP_FRACTION = 0.1  # a start deeper than this part of the contact's size is named by `mbs check`
PROBE = 1e-6  # relative change of the penetration (or its rate) the differences are taken over


@dataclass(frozen=True)
class StartContact:
    name: str
    depth: float  # m, the penetration at the start (<= 0: apart, a lubricated film)
    size: float  # m, what the depth is compared with: a disc's radius, a joint's radial clearance
    size_name: str  # "radius", "clearance"
    kind: str  # "contact" (a circle on a line or a circle), "clearance joint"
    rate: float  # 1/s, max(omega, lambda) of the module docstring
    stiff: str  # which of the two it is: "stiffness" or "damping"

    @property
    def deep(self) -> bool:
        return self.depth > DEEP_FRACTION * self.size > 0

    def describe(self) -> str:
        where = (f"starts {_length(self.depth)} inside ({self.depth / self.size:.3g} of its {self.size_name}, "
                 f"{_length(self.size)})" if self.depth > 0 else "has its film acting from the start")
        return f"{self.kind} `{self.name}` {where}; its law's {self.stiff} acts within {1 / self.rate:.2g} s"


def start_contacts(model: Model, q: np.ndarray, qd: np.ndarray) -> list[StartContact]:
    """The contact elements that act at the assembled start (q, q'), with their depth and rate."""
    k = model.kernel
    gaps = start_gaps(model, q)  # without the contact kernels: most models start apart
    acting = [c for c in range(model.nclearance)
              if int(k.clearance_param[c, CP_KIND]) == PairKind.LUBRICATED or gaps[c] < 0]
    if not acting:
        return []
    P = _inverse_mass(model, q, qd)
    return [_start_contact(model, c, q, qd, P) for c in acting]


def _inverse_mass(model: Model, q, qd) -> np.ndarray:
    """P of the module docstring: the inverse mass matrix on the motions the ideal constraints allow."""
    Minv = beams.inverse_mass_matrix(model.kernel)  # a beam's block besides the rigid bodies' diagonal
    km, owners = assembly_kernel(model, use=[], slides=False)
    if not owners:
        return Minv
    _, Cq, _ = _evaluate(km, q, qd, 0.0, len(owners))
    if not np.all(np.isfinite(Cq)):
        return Minv
    A = Cq @ Minv
    return Minv - A.T @ np.linalg.pinv(A @ Cq.T) @ A


def _start_contact(model: Model, c: int, q, qd, P) -> StartContact:
    k = model.kernel
    p = k.clearance_param[c]
    n = len(q)
    contact = np.zeros((model.contact_rows, N_CONTACT_STATE))
    G = np.array([pycontact.pair_kinematics(k, c, q, e, contact)[6] for e in np.eye(n)])  # vn is linear in q'
    d = P @ G
    w = float(G @ d)  # 1 / the effective mass along the normal
    kin = pycontact.pair_kinematics(k, c, q, qd, contact)
    depth, vn = float(kin[3]), float(kin[6])
    if depth > 0:  # as the time loop starts it (`kernel.events.init_modes`)
        contact[c, CT_MODE] = TOUCHING
        contact[c, CT_IMPACT_VELOCITY] = max(vn, pycontact.IMPACT_VELOCITY_FLOOR)
    kind = int(p[CP_KIND])
    if kind == PairKind.CIRCLE_ON_LINE:
        size, size_name, what = float(p[CP_R_JOURNAL]), "radius", "contact"
    elif kind == PairKind.CIRCLE_ON_CIRCLE:
        size, size_name, what = float(min(p[CP_R_BEARING], p[CP_R_JOURNAL])), "radius", "contact"
    else:
        size, size_name, what = float(p[CP_CLEARANCE]), "clearance", "clearance joint"
    omega2 = lam = 0.0
    if w > 0 and np.isfinite(w):
        ds = PROBE * max(abs(depth), size) / w  # s moves the penetration by w ds
        dv = PROBE * max(abs(vn), pycontact.IMPACT_VELOCITY_FLOOR) / w
        f0 = _force(model, c, q, qd, contact)
        omega2 = (_force(model, c, q + ds * d, qd, contact) - f0) / ds
        lam = (_force(model, c, q, qd + dv * d, contact) - f0) / dv
    omega = math.sqrt(omega2) if omega2 > 0 and math.isfinite(omega2) else 0.0
    lam = lam if lam > 0 and math.isfinite(lam) else 0.0
    return StartContact(model.clearance_names[c], depth, size, size_name, what, max(omega, lam),
                        "damping" if lam > omega else "stiffness")


def _force(model: Model, c: int, q, qd, contact) -> float:
    """The normal force of element c (the film's radial force with it), NaN where its law has none."""
    cs = np.zeros((model.nbody, 2))
    pyconstraints.body_trig(q, cs)
    with np.errstate(all="ignore"):
        try:
            z = np.zeros(model.nstate)  # LuGre's bristles at rest: they change no normal force
            out = pycontact.clearance_force(model.kernel, c, q, qd, cs, contact, z, z.copy())
        except (ZeroDivisionError, OverflowError, ValueError):
            return math.nan
    return float(out[0]) if out[5] == 0 else math.nan


def steps_needed(settings: Settings, contacts: list[StartContact]) -> tuple[float, StartContact | None]:
    """(steps, the fastest contact) of an adaptive run of `settings` from a start with `contacts`: at
    least t_end * rate / STABLE_STEP; (0, None) for a fixed-step method (its count is t_end / step)."""
    if not catalog.INTEGRATORS[int(settings.integrator)].adaptive or not contacts:
        return 0.0, None
    fastest = max(contacts, key=lambda s: s.rate)
    return float(settings.t_end) * fastest.rate / STABLE_STEP, fastest


def check_step_count(model: Model, settings: Settings, q: np.ndarray, qd: np.ndarray) -> None:
    """Refuse (ModelError, exit 2, at the contact's statement) a run that needs more than ``max_steps``
    steps from its start (`steps_needed`): it would crawl for hours and stop at the step limit."""
    contacts = start_contacts(model, q, qd)
    message = step_count_message(model, settings, contacts)
    if message:
        fastest = steps_needed(settings, contacts)[1]
        raise _model_error(model, message, [fastest.name], hint=_hint(fastest))


def step_count_message(model: Model, settings: Settings, contacts: list[StartContact]) -> str:
    """Why a run of `settings` from `contacts` would not end (beyond ``max_steps``), or ''."""
    steps, fastest = steps_needed(settings, contacts)
    if fastest is None or steps <= settings.max_steps:
        return ""
    return (f"{fastest.describe()}: the run would need at least {steps:.2g} steps of {STABLE_STEP / fastest.rate:.2g} s "
            f"to reach t_end = {settings.t_end:g} s, more than max_steps = {settings.max_steps:,} (it would crawl "
            "for hours and stop there)")


def _hint(contact: StartContact) -> str:
    start = ("start the body outside the contact (touching at most: its static penetration is µm for steel)"
             if contact.depth > 0 else "check the joint's geometry and units (bearing radius, length, clearance) "
             "and the oil's viscosity")
    return f"{start}; check the law's stiffness and restitution; a larger max_steps runs it anyway"


def _length(x: float) -> str:
    return f"{x * 1e3:.3g} mm" if abs(x) >= 1e-4 else f"{x * 1e6:.3g} µm"
