"""Signal names: `<entity>.<quantity>`, mapped onto columns of the observation row.

One table serves the HDF5 file, the CLI, plots and the Python
API.  The kernel's `observe` fills rows in the layout of
`model.observation_size`; `signal_table` says which column (or which
combination of columns) each named signal is.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import catalog
from .model import (
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
    CP_FRICTION,
    N_CLEARANCE_SIGNALS,
    DriverType,
    JointType,
    Model,
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
FRICTION_QUANTITIES = [("friction_force", "N", CS_FRICTION), ("slip_velocity", "m/s", CS_SLIP)]
# joints whose reaction includes a moment (they lock the relative rotation; catalog.JointSpec.moment)
MOMENT_JOINTS = tuple(JointType(s.code) for s in catalog.JOINTS if s.moment)


@dataclass(frozen=True)
class Signal:
    """A named output: ``op`` combines ``columns`` ("col": the one column,
    "hypot": the magnitude of two columns, "sum": their sum)."""

    entity: str
    quantity: str
    unit: str
    columns: tuple[int, ...]
    op: str = "col"

    @property
    def name(self) -> str:
        return f"{self.entity}.{self.quantity}"

    def extract(self, rows: np.ndarray) -> np.ndarray:
        cols = rows[:, list(self.columns)]
        if self.op == "col":
            return cols[:, 0].copy()
        if self.op == "hypot":
            return np.hypot(cols[:, 0], cols[:, 1])
        return cols.sum(axis=1)


def signal_table(model: Model) -> list[Signal]:
    """Every signal the model produces, in observation-row order."""
    nb, nj, nd, nc = model.nbody, model.njoint, model.ndriver, model.nclearance
    k = model.kernel
    table: list[Signal] = []
    for b, name in enumerate(model.body_names):
        for block, (qty, unit) in enumerate(BODY_QUANTITIES):
            part, comp = divmod(block, 3)  # q, qd, qdd blocks of 3 nb columns
            table.append(Signal(name, qty, unit, (part * 3 * nb + 3 * b + comp,)))
    base = 9 * nb
    for j, name in enumerate(model.joint_names):
        c = base + 3 * j
        table += [
            Signal(name, "fx", "N", (c,)),
            Signal(name, "fy", "N", (c + 1,)),
            Signal(name, "force", "N", (c, c + 1), "hypot"),
        ]
        if JointType(int(k.joint_type[j])) in MOMENT_JOINTS:
            table.append(Signal(name, "moment", "N*m", (c + 2,)))
    base += 3 * nj
    for d, name in enumerate(model.driver_names):
        angle = int(k.driver_type[d]) == DriverType.ANGLE
        effort = ("torque", "N*m") if angle else ("force", "N")
        table.append(Signal(name, effort[0], effort[1], (base + d,)))
        table.append(Signal(name, "power", "W", (base + nd + d,)))
    base += 2 * nd
    for c, name in enumerate(model.clearance_names):
        col = base + N_CLEARANCE_SIGNALS * c
        quantities = list(CLEARANCE_QUANTITIES)
        if k.clearance_param[c, CP_FRICTION] > 0:
            quantities += FRICTION_QUANTITIES
        table += [Signal(name, q, u, (col + off,)) for q, u, off in quantities]
    base += N_CLEARANCE_SIGNALS * nc
    table += [
        Signal("system", "kinetic_energy", "J", (base,)),
        Signal("system", "potential_energy", "J", (base + 1,)),
        Signal("system", "total_energy", "J", (base, base + 1), "sum"),
        Signal("system", "position_error", "1", (base + 2,)),
        Signal("system", "velocity_error", "1", (base + 3,)),
    ]
    return table
