"""The compiler's pass for beams: `body NAME = beam { ... }` into node bodies and the beam's arrays.

A beam of n ANCF cable elements (`kernel/beam.py`) has n + 1 nodes; node k becomes two bodies of the
rigid-body layout without mass of their own, ``NAME_node<k>`` (its position: ``NAME_node<k>.x``,
``.y`` are the node's signals) and ``NAME_slope<k>`` (its slope dx/ds, dy/ds), so that the joints,
contact elements and signals of rigid bodies reach a beam's nodes unchanged.  A joint names a node as
``NAME (start)``, ``NAME (end)`` or ``NAME (k)``.  The beam's mass, its inverse and its weight are
formed here once (`mechanism/beams.py`).
"""
from __future__ import annotations

import math

import numpy as np

from .. import catalog
from ..errors import did_you_mean
from ..language import units as U
from ..language.evaluate import CallVal, scalar_si
from ..language.spec import Call, Name, Statement
from . import beams as B
from .model import JointType, N_BEAM_PARAM, BP_EA, BP_EI, BP_ETA, BP_LENGTH, BP_RHO_A

BEAM = catalog.BEAM
BEAM_FIELDS = dict(BEAM.fields)
AREA = U.Dim("an area", "m**2", "1 cm^2")
SECOND_MOMENT = U.Dim("a second moment of area", "m**4", "8.3e-10 m^4")
SECTIONS = {"rectangle": ("width", "height"), "circle": ("radius",)}
ENDS = {"start": 0, "end": -1}
MAX_ELEMENTS = 400


def is_beam(st: Statement) -> bool:
    return st.kind == "body" and isinstance(st.value, Name)


def check_kind(st: Statement) -> None:
    if st.value.name != BEAM.name:
        raise st.value.pos.error(f"unknown kind of body `{st.value.name}`",
                                 hint=did_you_mean(st.value.name, [BEAM.name]) or
                                 f"`body {st.name} = beam {{ ... }}`, or a rigid body `body {st.name} {{ mass = ... }}`")


def _beyond_floats(st: Statement):
    return st.name_pos.error(f"beam `{st.name}`: its size, section, material or motion give masses, stiffnesses "
                             "or a start beyond floating point", hint="give the beam's fields in physical units, "
                             "e.g. `length = 0.3 m  section = rectangle(width = 20 mm, height = 10 mm)`")


def _require_finite(st: Statement, *values) -> None:
    if not all(np.isfinite(v).all() for v in values):
        raise _beyond_floats(st)


class _BeamPass:
    """Beams: their node bodies (numbered after the rigid bodies), sections, materials, arrays."""

    def _beam_layout(self, rigid: list[Statement], beams: list[Statement]) -> list[str]:
        """Number the node bodies after the rigid ones; returns every body's name."""
        names = [s.name for s in rigid]
        self.beam_first, self.beam_elements = {}, {}
        for st in beams:
            check_kind(st)
            f = self._fields(st, f"beam `{st.name}`", BEAM_FIELDS)
            n = f.scalar("elements", U.NUMBER, 8.0, positive=True)
            if n != int(n) or n > MAX_ELEMENTS:
                raise f.expr("elements").pos.error(f"`elements` of beam `{st.name}` must be a whole number "
                                                   f"from 1 to {MAX_ELEMENTS}", hint="e.g. `elements = 8`")
            self.beam_first[st.name], self.beam_elements[st.name] = len(names), int(n)
            for k in range(int(n) + 1):
                for part in ("node", "slope"):
                    name = f"{st.name}_{part}{k}"
                    if name in self.kind_of:
                        raise st.name_pos.error(f"the node body `{name}` of beam `{st.name}` has the name of "
                                                "another element", hint="rename one of them")
                    names.append(name)
        return names

    def _fill_beams(self):
        """The node bodies of every beam and the beam arrays but the weight (`_beam_weights`)."""
        if not self.beam_statements:
            return
        self.geometry.extend({} for _ in range(self.nbody - len(self.geometry)))
        nbeam = len(self.beam_statements)
        info = np.zeros((nbeam, 4), np.int64)
        param = np.zeros((nbeam, N_BEAM_PARAM))
        mass, minv, band = [], [], []
        body_beam = np.full(self.nbody, -1, np.int64)
        mo = wo = 0
        for bm, st in enumerate(self.beam_statements):
            first, nel = self.beam_first[st.name], self.beam_elements[st.name]
            try:  # a size beyond floats: Python's powers raise, numpy's give inf, the mass is no longer definite
                with np.errstate(all="ignore"):
                    p = self._beam_params(st)
                    Le = p["length"] / nel
                    M = B.beam_mass(nel, Le, p["rho_a"])
                    L = B.band_factor(M)
                    Minv = B.inverse_mass(L)
                    self._beam_start(first, nel, p)
                    stiff = np.array([p["EA"] / Le, p["EI"] / Le ** 3, p["eta"] * p["EA"] / Le])
            except (OverflowError, np.linalg.LinAlgError):
                raise _beyond_floats(st) from None
            span = slice(3 * first, 3 * (first + 2 * (nel + 1)))
            _require_finite(st, M, Minv, L, stiff, self.q0[span], self.qd0[span])
            param[bm, [BP_LENGTH, BP_EA, BP_EI, BP_ETA, BP_RHO_A]] = (Le, p["EA"], p["EI"], p["eta"], p["rho_a"])
            info[bm] = (first, nel, mo, wo)
            mass.append(M.ravel())
            minv.append(Minv.ravel())
            band.append(L.ravel())
            mo, wo = mo + M.size, wo + M.shape[0]
            body_beam[first:first + 2 * (nel + 1)] = bm
        self.a.update(beam_info=info, beam_param=param, beam_mass=np.concatenate(mass),
                      beam_minv=np.concatenate(minv), beam_band=np.concatenate(band), body_beam=body_beam)

    def _beam_weights(self):
        """Every beam's constant generalised weight, once gravity is known."""
        if self.beam_statements:
            with np.errstate(over="ignore", invalid="ignore"):
                weights = [B.gravity_force(int(nel), Le, rho_a, self.a["gravity"])
                           for (_, nel, _, _), (Le, _, _, _, rho_a) in zip(self.a["beam_info"], self.a["beam_param"])]
            for st, w in zip(self.beam_statements, weights):
                _require_finite(st, w)
            self.a["beam_weight"] = np.concatenate(weights)

    def _fill_slope(self, k: int, st: Statement, label: str, f, bi: int, bj: int) -> None:
        """A `beam_slope` row: its axis given, or for a weld the node's slope at the start in body i's frame."""
        bi, bj = self._slope_sides(st, label, bi, bj)
        a = self.a
        a["joint_type"][k] = int(JointType.BEAM_SLOPE)
        a["joint_body"][k] = (bi, bj)
        if st.value.name == "weld":
            c, s = math.cos(self._angle0(bi)), math.sin(self._angle0(bi))
            sx, sy = self.q0[3 * bj:3 * bj + 2]
            u = np.array([c * sx + s * sy, -s * sx + c * sy])
            a["joint_axis"][k] = u / np.linalg.norm(u)
        else:
            a["joint_axis"][k] = self._unit_axis(f, "axis")

    def _beam_start(self, first: int, nel: int, p: dict) -> None:
        """The straight start of a beam: node positions and slopes, a rigid motion about its start."""
        e = B.straight_coordinates(nel, p["length"], p["start"], p["angle"])
        v, w = np.asarray(p["velocity"]), p["omega"]
        for k in range(nel + 1):
            b = first + 2 * k
            r, s = e[4 * k:4 * k + 2], e[4 * k + 2:4 * k + 4]
            self.q0[3 * b:3 * b + 2], self.q0[3 * b + 3:3 * b + 5] = r, s
            d = r - np.asarray(p["start"])
            self.qd0[3 * b:3 * b + 2] = v + w * np.array([-d[1], d[0]])
            self.qd0[3 * b + 3:3 * b + 5] = w * np.array([-s[1], s[0]])
            self.geometry[b] = {"kind": "beam_node"}
            self.geometry[b + 1] = {"kind": "beam_slope"}

    def _beam_params(self, st: Statement) -> dict:
        f = self._fields(st, f"beam `{st.name}`", BEAM_FIELDS)
        A, I = self._section(f, st)
        E, rho = self._beam_material(f, st)
        return dict(length=f.scalar("length", U.LENGTH, positive=True), start=f.vector("start", U.LENGTH, (0.0, 0.0)),
                    angle=f.scalar("angle", U.ANGLE, 0.0), EA=E * A, EI=E * I, rho_a=rho * A,
                    eta=f.scalar("damping", U.TIME, 0.0, nonneg=True),
                    velocity=f.vector("velocity", U.VELOCITY, (0.0, 0.0)),
                    omega=f.scalar("omega", U.ANGULAR_VELOCITY, 0.0))

    def _section(self, f, st: Statement) -> tuple[float, float]:
        """(A, I) from `section = rectangle(width, height) | circle(radius)` or `area` and `second_moment`."""
        if f.has("section"):
            for key in ("area", "second_moment"):
                if f.has(key):
                    raise f.expr(key).pos.error(f"beam `{st.name}` has a `section` and `{key}`",
                                                hint="give one of them")
            e = f.expr("section")
            v = self.ev.value(e)
            if not isinstance(v, CallVal) or v.call.name not in SECTIONS:
                raise e.pos.error(f"unknown section `{e.pos.text}`",
                                  hint="sections: rectangle(width, height), circle(radius)")
            c = v.call
            given = self._call_args(c, SECTIONS[c.name])
            dims = []
            for key in SECTIONS[c.name]:
                if key not in given:
                    raise c.pos.error(f"`{c.name}(...)` needs `{key}`", hint=f"`{c.name}({', '.join(SECTIONS[c.name])})`")
                value = scalar_si(self.ev, given[key], U.LENGTH, key)
                if not value > 0:
                    raise given[key].pos.error(f"`{key}` of a section must be positive", hint="e.g. `5 mm`")
                dims.append(value)
            if c.name == "rectangle":  # the height lies in the plane of motion
                return dims[0] * dims[1], dims[0] * dims[1] ** 3 / 12.0
            return math.pi * dims[0] ** 2, math.pi * dims[0] ** 4 / 4.0
        if not f.has("area"):
            raise f.missing("section")
        return f.scalar("area", AREA, positive=True), f.scalar("second_moment", SECOND_MOMENT, positive=True)

    def _beam_material(self, f, st: Statement) -> tuple[float, float]:
        """(E, density) from `material = NAME` or the beam's own `E` and `density`."""
        if f.has("material"):
            name, pos = self._material(f, "material")
            self._sigma(name, pos)  # known, and its fields checked
            mf = self._fields(self.materials[name], f"material `{name}`", self.MATERIAL_FIELDS_)
            for key in ("E", "density"):
                if f.has(key):
                    raise f.expr(key).pos.error(f"beam `{st.name}` has a `material` and `{key}`",
                                                hint="give one of them")
            if not mf.has("density"):
                raise (self.materials[name].name_pos or pos).error(
                    f"material `{name}` needs a `density` for beam `{st.name}`", hint="e.g. `density = 7800 kg/m^3`")
            return mf.scalar("E", U.PRESSURE, positive=True), mf.scalar("density", U.DENSITY, positive=True)
        return f.scalar("E", U.PRESSURE, positive=True), f.scalar("density", U.DENSITY, positive=True)

    # joints on beams ----------------------------------------------------------
    def _beam_node(self, c: Call) -> int:
        """`rod (start)`, `rod (end)`, `rod (k)`: the position body of that node."""
        name, first, nel = c.name, self.beam_first[c.name], self.beam_elements[c.name]
        hint = f"name a node: `{name} (start)`, `{name} (end)` or `{name} (k)`, k from 0 to {nel}"
        if len(c.args) != 1 or c.kwargs:
            raise c.pos.error(f"a joint on beam `{name}` names one of its nodes", hint=hint)
        a = c.args[0]
        if isinstance(a, Name) and a.name in ENDS:
            k = ENDS[a.name] % (nel + 1)
        else:
            k = scalar_si(self.ev, a, U.NUMBER, "node")
            if k != int(k) or not 0 <= k <= nel:
                raise a.pos.error(f"beam `{name}` has nodes 0 to {nel}, not `{a.pos.text}`", hint=hint)
        return first + 2 * int(k)

    def _beam_ref(self, e) -> bool:
        """Whether the reference `e` names a beam (a node of it)."""
        return isinstance(e, Call) and e.name in getattr(self, "beam_first", {}) or \
            isinstance(e, Name) and e.name in getattr(self, "beam_first", {})

    def _joint_parts(self, st: Statement) -> list[tuple[Statement, JointType, str]]:
        """An ideal joint as kernel joints: a weld on a beam's node is a revolute joint on its position
        and a `beam_slope` row on its slope (named NAME_slope)."""
        jt = JointType(catalog.joint(st.value.name).code)
        if st.value.name == "weld" and any(self._beam_ref(a) for a in st.value.args):
            return [(st, JointType.REVOLUTE, st.name), (st, JointType.BEAM_SLOPE, f"{st.name}_slope")]
        return [(st, jt, st.name)]

    def _slope_sides(self, st: Statement, label: str, bi, bj):
        """A slope row's sides: (rigid body or ground, the slope body of the beam's node)."""
        bb = lambda b: b >= 0 and self.body_is_node(b)
        if bb(bi) and not bb(bj):
            bi, bj = bj, bi
        if not bb(bj) or bb(bi):
            raise st.value.pos.error(f"{label} ties a beam's node to a rigid body or ground",
                                     hint="e.g. `weld(crank (0.1, 0), rod (start))`")
        return bi, bj + 1

    def body_is_node(self, b: int) -> bool:
        return b >= self.nrigid

