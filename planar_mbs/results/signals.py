"""Signal names: `<entity>.<quantity>`, mapped onto columns of the observation row.

One table serves the HDF5 file, the CLI, plots and the Python
API.  The kernel's `observe` fills rows in the layout of
`model.observation_layout`; `signal_table` says which column (or which
combination of columns) each named signal is.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import catalog
from ..mechanism import beams
from ..mechanism.model import (
    CS_E,
    CS_EX,
    CS_EY,
    CS_FN,
    CS_FRICTION,
    CS_FX,
    CS_FY,
    CS_IMPACT_VELOCITY,
    CS_IN_CONTACT,
    CS_PENETRATION,
    CS_SLIP,
    CS_STICK,
    CS_FRICTION_POWER,
    CS_BRISTLE,
    CS_FILM_PRESSURE,
    CS_POINT_X,
    CS_POINT_Y,
    CP_FRICTION,
    CP_FRICTION_MODEL,
    CP_STATIC_FRICTION,
    CP_STATE,
    CS_DISSIPATED,
    CS_WORK,
    FS_POWER,
    FS_VALUE,
    FS_WORK,
    N_FORCE_SIGNALS,
    OB_DRIVER_WORK,
    OB_FORCE,
    OBS_SKIP_LOADS,
    SYS_BALANCE,
    SYS_DISSIPATED,
    SYS_GRAVITY_POWER,
    SYS_GRAVITY_WORK,
    SYS_INPUT_WORK,
    CP_KIND,
    JS_FX,
    JS_FY,
    JS_MOMENT,
    N_CLEARANCE_SIGNALS,
    N_JOINT_SIGNALS,
    OBS_SKIP_CLEARANCE,
    OBS_SKIP_DYNAMICS,
    OBS_SKIP_ENERGY,
    OBS_SKIP_ERRORS,
    OB_CLEARANCE,
    OB_EFFORT,
    OB_JOINT,
    OB_POWER,
    OB_Q,
    OB_QD,
    OB_QDD,
    OB_SYSTEM,
    OB_JFRICTION,
    JF_FRICTION,
    JF_POWER,
    JF_RATE,
    JF_STICK,
    JF_WORK,
    N_JFRICTION_SIGNALS,
    SYS_KINETIC,
    SYS_POSITION_ERROR,
    SYS_POTENTIAL,
    SYS_VELOCITY_ERROR,
    DriverType,
    JointType,
    PairKind,
    Model,
    observation_layout,
)

BODY_QUANTITIES = [
    ("x", "m"), ("y", "m"), ("phi", "rad"),
    ("vx", "m/s"), ("vy", "m/s"), ("omega", "rad/s"),
    ("ax", "m/s^2"), ("ay", "m/s^2"), ("alpha", "rad/s^2"),
]
CLEARANCE_QUANTITIES = [
    ("ex", "m", CS_EX), ("ey", "m", CS_EY), ("e", "m", CS_E),
    ("penetration", "m", CS_PENETRATION), ("contact_force", "N", CS_FN),
    ("fx", "N", CS_FX), ("fy", "N", CS_FY), ("in_contact", "1", CS_IN_CONTACT),
    ("impact_velocity", "m/s", CS_IMPACT_VELOCITY),
]
# the work of its contact (and film) forces on both bodies, and the energy it dissipated, since the start
WORK_QUANTITIES = [("work", "J", CS_WORK), ("dissipated", "J", CS_DISSIPATED)]
FRICTION_QUANTITIES = [("friction_force", "N", CS_FRICTION), ("slip_velocity", "m/s", CS_SLIP),
                       ("friction_power", "W", CS_FRICTION_POWER)]
STICK_QUANTITIES = [("stick", "1", CS_STICK)]  # a friction model that sticks (catalog.FrictionSpec.stick)
_STICKS = {m.code for m in catalog.FRICTION_MODELS if m.stick}
BRISTLE_QUANTITIES = [("bristle", "m", CS_BRISTLE)]  # a friction model with a state (LuGre's deflection z)
# the contact point on the second body (journal, circle, corner), global frame; the film's peak pressure
POINT_QUANTITIES = [("contact_x", "m", CS_POINT_X), ("contact_y", "m", CS_POINT_Y)]
FILM_QUANTITIES = [("film_pressure", "Pa", CS_FILM_PRESSURE)]
# joints whose reaction includes a moment (they lock the relative rotation; catalog.JointSpec.moment)
MOMENT_JOINTS = tuple(JointType(s.code) for s in catalog.JOINTS if s.moment)
# a joint with friction (catalog.JointSpec.friction: "torque" for a pin, "force" for a slide)
_JOINT_FRICTION = {s.code: s.friction for s in catalog.JOINTS}


def _friction_signals(name: str, kind: str, col: int) -> list:
    """A friction joint's signals: its friction on the second body along the slip coordinate, the slip
    rate, the friction power (<= 0 while slipping), 1 while stuck, the friction's work since the start."""
    torque = kind == "torque"
    return [Signal(name, "friction_torque" if torque else "friction_force", "N*m" if torque else "N",
                   (col + JF_FRICTION,)),
            Signal(name, "slip_rate" if torque else "slip_velocity", "rad/s" if torque else "m/s", (col + JF_RATE,)),
            Signal(name, "friction_power", "W", (col + JF_POWER,)), Signal(name, "stick", "1", (col + JF_STICK,)),
            Signal(name, "friction_work", "J", (col + JF_WORK,))]
_KINDS = {s.code: s for s in catalog.FORCES}


@dataclass(frozen=True)
class Signal:
    """A named output: ``op`` combines ``columns`` ("col": the one column,
    "hypot": the magnitude of two columns, "sum": their sum)."""

    entity: str
    quantity: str
    unit: str
    columns: tuple[int, ...]
    op: str = "col"
    params: tuple = ()  # a beam's: ("strain" | "curvature" | "moment", Le, EI, xi) or ("energy", nel, Le, EA, EI)

    @property
    def name(self) -> str:
        return f"{self.entity}.{self.quantity}"

    def extract(self, rows: np.ndarray) -> np.ndarray:
        cols = rows[:, list(self.columns)]
        if self.op == "col":
            return cols[:, 0].copy()
        if self.op == "hypot":
            return np.hypot(cols[:, 0], cols[:, 1])
        if self.op == "beam":
            return _beam_values(cols, self.params)
        return cols.sum(axis=1)


def _beam_values(cols: np.ndarray, params: tuple) -> np.ndarray:
    """A beam's derived signal from its coordinates' columns (`mechanism.beams`)."""
    if params[0] == "energy":
        return beams.energy_rows(cols, *params[1:])
    what, Le, ei, xi = params
    eps, kap = beams.strains_rows(cols, Le, xi)
    return eps if what == "strain" else kap if what == "curvature" else ei * kap


def beam_signals(model: Model) -> list:
    """Per beam: each element's axial strain, curvature and bending moment EI kappa at its middle
    (`NAME_element<k>`), and the beam's strain energy (`NAME.elastic_energy`), from its node columns."""
    k = model.kernel
    out = []
    for bm, name in enumerate(model.beam_names):
        first, nel = int(k.beam_info[bm, 0]), int(k.beam_info[bm, 1])
        Le, ea, ei = (float(v) for v in k.beam_param[bm, :3])
        cols = tuple(beams.q_index(first, i) for i in range(beams.NODE_COORDS * (nel + 1)))
        for e in range(nel):
            ce = cols[beams.NODE_COORDS * e:beams.NODE_COORDS * e + 8]
            out += [Signal(f"{name}_element{e}", q, u, ce, "beam", (q, Le, ei, 0.5))
                    for q, u in (("strain", "1"), ("curvature", "1/m"), ("moment", "N*m"))]
        out.append(Signal(name, "elastic_energy", "J", cols, "beam", ("energy", nel, Le, ea, ei)))
    return out


def signal_table(model: Model) -> list[Signal]:
    """Every signal the model produces, in observation-row order (`model.observation_layout`)."""
    nb = model.nbody
    k = model.kernel
    lay = observation_layout(nb, model.njoint, model.ndriver, model.nclearance, model.nforce, model.njfriction)
    table: list[Signal] = []
    friction = {int(j): f for f, j in enumerate(k.joint_friction)}
    for b, name in enumerate(model.body_names):
        for block, (qty, unit) in enumerate(BODY_QUANTITIES):
            part, comp = divmod(block, 3)  # q, qd, qdd blocks of 3 nb columns
            table.append(Signal(name, qty, unit, (lay[(OB_Q, OB_QD, OB_QDD)[part]] + 3 * b + comp,)))
    for j, name in enumerate(model.joint_names):
        c = lay[OB_JOINT] + N_JOINT_SIGNALS * j
        table += [
            Signal(name, "fx", "N", (c + JS_FX,)),
            Signal(name, "fy", "N", (c + JS_FY,)),
            Signal(name, "force", "N", (c + JS_FX, c + JS_FY), "hypot"),
        ]
        if JointType(int(k.joint_type[j])) in MOMENT_JOINTS:
            table.append(Signal(name, "moment", "N*m", (c + JS_MOMENT,)))
        if j in friction:
            table += _friction_signals(name, _JOINT_FRICTION[int(k.joint_type[j])],
                                       lay[OB_JFRICTION] + N_JFRICTION_SIGNALS * friction[j])
    for d, name in enumerate(model.driver_names):
        angle = int(k.driver_type[d]) == DriverType.ANGLE
        effort = ("torque", "N*m") if angle else ("force", "N")
        table.append(Signal(name, effort[0], effort[1], (lay[OB_EFFORT] + d,)))
        table.append(Signal(name, "power", "W", (lay[OB_POWER] + d,)))
    for c, name in enumerate(model.clearance_names):
        col = lay[OB_CLEARANCE] + N_CLEARANCE_SIGNALS * c
        quantities = list(CLEARANCE_QUANTITIES)
        sticks = int(k.clearance_param[c, CP_FRICTION_MODEL]) in _STICKS and k.clearance_param[c, CP_STATIC_FRICTION] > 0
        if k.clearance_param[c, CP_FRICTION] > 0 or sticks:
            quantities += FRICTION_QUANTITIES + (STICK_QUANTITIES if sticks else [])
            quantities += BRISTLE_QUANTITIES if k.clearance_param[c, CP_STATE] > 0 else []
        quantities += POINT_QUANTITIES
        if int(k.clearance_param[c, CP_KIND]) == PairKind.LUBRICATED:
            quantities += FILM_QUANTITIES
        quantities += WORK_QUANTITIES
        table += [Signal(name, q, u, (col + off,)) for q, u, off in quantities]
    s = lay[OB_SYSTEM]
    table += [
        Signal("system", "kinetic_energy", "J", (s + SYS_KINETIC,)),
        Signal("system", "potential_energy", "J", (s + SYS_POTENTIAL,)),
        Signal("system", "total_energy", "J", (s + SYS_KINETIC, s + SYS_POTENTIAL), "sum"),
        Signal("system", "position_error", "1", (s + SYS_POSITION_ERROR,)),
        Signal("system", "velocity_error", "1", (s + SYS_VELOCITY_ERROR,)),
    ]
    if np.any(np.asarray(k.gravity) != 0.0):
        table += [Signal("gravity", "power", "W", (s + SYS_GRAVITY_POWER,)),
                  Signal("gravity", "work", "J", (s + SYS_GRAVITY_WORK,))]
    table += [
        Signal("system", "input_work", "J", (s + SYS_INPUT_WORK,)),
        Signal("system", "dissipated", "J", (s + SYS_DISSIPATED,)),
        Signal("system", "energy_balance", "J", (s + SYS_BALANCE,)),
    ]
    for e, name in enumerate(model.force_names):
        col = lay[OB_FORCE] + N_FORCE_SIGNALS * e
        spec = _KINDS.get(int(k.force_type[e]))  # an unknown kind: refused before a run (checks.known_force_kinds)
        values = spec.signals if spec is not None else ()
        table += [Signal(name, q, u, (col + FS_VALUE + i,)) for i, (q, u) in enumerate(values)]
        table += [Signal(name, "power", "W", (col + FS_POWER,)), Signal(name, "work", "J", (col + FS_WORK,))]
    for d, name in enumerate(model.driver_names):
        table.append(Signal(name, "work", "J", (lay[OB_DRIVER_WORK] + d,)))
    return table + beam_signals(model)


def skip_bits(model: Model, columns=None) -> int:
    """cfg[CFG_SKIP] for a run that keeps only these columns of the observation row (`columns`: the
    observation columns its stored signals read, as `simulation.select_signals` returns them; None =
    every column): the OBS_SKIP_* bit of each group none of them reads, whose work the time loop's
    `observe` then skips (a full `accelerations` per row for the q'' block, joint reactions and driver
    efforts).  0 when every signal is kept."""
    if columns is None:
        return 0
    lay = observation_layout(model.nbody, model.njoint, model.ndriver, model.nclearance, model.nforce,
                             model.njfriction)
    s = lay[OB_SYSTEM]
    jf = [lay[OB_JFRICTION] + N_JFRICTION_SIGNALS * f + i for f in range(model.njfriction) for i in (JF_FRICTION,
                                                                                                    JF_POWER)]
    loads = [lay[OB_FORCE] + N_FORCE_SIGNALS * e + i for e in range(model.nforce) for i in range(FS_WORK)]
    groups = (
        (OBS_SKIP_DYNAMICS, [*range(lay[OB_QDD], lay[OB_CLEARANCE]), *jf]),
        (OBS_SKIP_CLEARANCE, range(lay[OB_CLEARANCE], lay[OB_FORCE])),
        (OBS_SKIP_ENERGY, (s + SYS_KINETIC, s + SYS_POTENTIAL, s + SYS_INPUT_WORK, s + SYS_DISSIPATED,
                           s + SYS_BALANCE)),
        (OBS_SKIP_ERRORS, (s + SYS_POSITION_ERROR, s + SYS_VELOCITY_ERROR)),
        (OBS_SKIP_LOADS, [*loads, s + SYS_GRAVITY_POWER]),
    )
    used = {int(c) for c in columns}
    return sum(bit for bit, cols in groups if not used.intersection(cols))
