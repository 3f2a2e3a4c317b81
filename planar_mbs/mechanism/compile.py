"""ModelSpec → Model: the compiler as a straight list of named passes.

    collect        merge included statements, apply `override`, reject duplicates
    resolve_params apply `--set` overrides, evaluate params in dependency order
    assign_ids     number bodies, sort joints into ideal / clearance, index the rest
    size           counts and constraint rows (`JOINT_ROWS`, drivers after joints)
    allocate       zero arrays of the right shapes (also when a kind is absent)
    fill           evaluate every field with its dimension check, fill the arrays
    check          whole-model checks

Each pass raises `ModelError` naming the element and its line.  Expressions are
evaluated by `evaluate.Evaluator` (values, units, field readers), never by Python's eval.
"""
from __future__ import annotations

import math
import os
import stat
from pathlib import Path

import numpy as np

from .. import catalog
from ..language import units as U
from ..errors import ModelError, did_you_mean
from ..language.evaluate import (
    FUNCTIONS,
    CallVal,
    Evaluator,
    Fields,
    Scalar,
    Symbol,
    Vec,
    _chain,
    _format_value,
    scalar_si,
    symbol_of,
    vector_si,
)
from .model import (
    CONTACT_LAW_NAMES,
    CP_BREAKDOWN,
    CP_CLEARANCE,
    CP_DAMPING,
    CP_EXPONENT,
    CP_KIND,
    CP_NX,
    CP_NY,
    CP_VISCOSITY,
    PairKind,
    CP_FRICTION,
    CP_FRICTION_V0,
    CP_LENGTH,
    CP_FRICTION_V1,
    CP_FRICTION_MODEL,
    CP_STATIC_FRICTION,
    CP_STICK_DAMPING,
    CP_STICK_STIFFNESS,
    CP_STRIBECK_EXPONENT,
    CP_STRIBECK_VELOCITY,
    CP_VISCOUS_FRICTION,
    CP_BRISTLE_DAMPING,
    CP_BRISTLE_STIFFNESS,
    CP_STATE,
    CP_R_BEARING,
    CP_R_JOURNAL,
    CP_RESTITUTION,
    CP_SIGMA_SUM,
    CP_STIFFNESS,
    JOINT_ROWS,
    JP,
    N_CLEARANCE_PARAM,
    N_FORCE_PARAM,
    N_JOINT_PARAM,
    N_MOTION_PARAM,
    ContactLaw,
    INTEGRATOR_NAMES,
    DriverType,
    Integrator,
    JointType,
    KernelModel,
    frozen,
    Model,
    MotionType,
    Settings,
    SourceRef,
)
from .expressions import FUNCTIONS as EXPRESSION_FUNCTIONS, Context, Programs
from . import beams as B
from .beam_pass import _BeamPass, is_beam
from .ordering import reorder
from .portable import rotate
from . import restitution as R
from ..language.parse import KEYWORDS, MAX_MODEL_BYTES, decode_model, parse_expression, parse_model
from ..language.spec import BinOp, Call, Expr, Field, ModelSpec, Name, Neg, Number, Pos, Statement, Vector

__all__ = ["load_model", "compile_text"]


# ------------------------------------------------------------------ entry points
def load_model(path: str | Path, overrides: dict[str, str] | None = None) -> Model:
    """Read, parse and compile a `.mbs` file; `overrides` are `--set NAME=VALUE` pairs."""
    path = str(path)
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):  # a folder, /dev/zero, a pipe: never opened
            raise IsADirectoryError(0, "a folder" if stat.S_ISDIR(info.st_mode) else "not a regular file")
        if info.st_size > MAX_MODEL_BYTES:
            raise ModelError(f"the model file is {info.st_size / 2**20:.0f} MB; models are limited to "
                             f"{MAX_MODEL_BYTES // 2**20} MB", path, hint="is this really a model file?")
        with open(path, "rb") as f:
            data = f.read(MAX_MODEL_BYTES + 1)
    except OSError as e:
        raise ModelError(f"cannot read the model file ({getattr(e, 'strerror', None) or e})", path,
                         hint="check the path") from None
    model = compile_text(decode_model(data, path), path, overrides)
    model.source_files.insert(0, Path(path).resolve())
    return model


def compile_text(text: str, path: str = "<string>", overrides: dict[str, str] | None = None,
                 includes: dict[str, str] | None = None, key: str | None = None) -> Model:
    """Parse and compile model text; every user mistake raises `ModelError`.  ``includes`` and
    ``key`` (a model's `source_includes` and `source_key`) supply its included files from memory."""
    try:
        spec = parse_model(text, path, sources=includes, main=key)
        return Compiler(spec, overrides or {}).run()
    except ModelError:
        raise
    except RecursionError:
        raise ModelError("the model nests too deeply to compile", path,
                         hint="split deeply nested expressions into several `param`s") from None
    except Exception as e:  # the contract: users only ever see ModelError
        raise ModelError(f"internal error while compiling ({type(e).__name__}: {e})", path,
                         hint="this is a bug in planar_mbs; please report it with the model") from None


# ------------------------------------------------------------------ element kinds
MIN_INERTIA = 1e-200  # SI: a mass or inertia below it is a typo; its inverse (and its square) overflow
BODY_FIELDS = {"mass": "kg", "inertia": "kg*m^2", "position": "(x, y) of the centre of mass",
               "angle": "deg or rad", "velocity": "(vx, vy)", "omega": "angular velocity",
               "shape": "bar(length, width) | box(width, height) | circle(radius)"}
MATERIAL_FIELDS = {"E": "Young's modulus, e.g. 207 GPa", "nu": "Poisson's ratio, e.g. 0.3",
                   "density": "e.g. 7800 kg/m^3"}
# the friction models' settings (catalog.FRICTION_MODELS), the first meaning of each name
FRICTION_FIELDS = {"friction_model": f"{catalog.choices(catalog.FRICTION_MODELS)} (default {catalog.DEFAULT_FRICTION})",
                   **{x.name: x.meaning for m in reversed(catalog.FRICTION_MODELS) for x in m.settings}}
FRICTION_UNITS = {"number": U.NUMBER, "velocity": U.VELOCITY, "damping": U.DAMPING, "per_length": U.PER_LENGTH,
                  "time_per_length": U.TIME_PER_LENGTH}
FRICTION_COLUMNS = {"friction": CP_FRICTION, "static_friction": CP_STATIC_FRICTION,
                    "friction_velocity": CP_FRICTION_V0, "friction_velocity_full": CP_FRICTION_V1,
                    "stick_stiffness": CP_STICK_STIFFNESS, "stick_damping": CP_STICK_DAMPING,
                    "stribeck_velocity": CP_STRIBECK_VELOCITY, "stribeck_exponent": CP_STRIBECK_EXPONENT,
                    "viscous_friction": CP_VISCOUS_FRICTION, "bristle_stiffness": CP_BRISTLE_STIFFNESS,
                    "bristle_damping": CP_BRISTLE_DAMPING}
_CONTACT_FIELDS = {  # every contact element (catalog.ELEMENTS) takes these
    "material": "material of both parts", "law": "contact law name", "restitution": "coefficient of restitution",
    "effective_restitution": "the rebound the law is to give (its own coefficient found from it)",
    "damping": "c of the Kelvin-Voigt law F = K d + c d'",
    "stiffness": "K of F = K d^n", "exponent": "n (default 1.5)", **FRICTION_FIELDS,
}
JOINT_FIELDS = {  # per joint type (catalog.JOINTS), then the clearance joint
    **{spec.name: dict(spec.fields) for spec in catalog.JOINTS},
    "clearance_revolute": {
        "clearance": "radial clearance c = R_B - R_J", "bearing_radius": "R_B", "journal_radius": "R_J",
        "length": "bearing length", "material": "material of both parts",
        "bearing_material": "material of the bearing", "journal_material": "material of the journal",
        "law": "contact law name", "restitution": "coefficient of restitution",
        "effective_restitution": "the rebound the law is to give (its own coefficient found from it)",
        "damping": "c of the Kelvin-Voigt law F = K d + c d'",
        "stiffness": "K of F = K d^n", "exponent": "n (default 1.5)",
        **FRICTION_FIELDS,
        "offset": "initial journal centre minus bearing centre (dx, dy) in the bearing's frame (default: "
                  "centred when the joint closes a loop)",
        "relative_velocity": "initial velocity of the journal centre relative to the bearing centre (vx, vy), "
                             "bearing frame"},
}
JOINT_FIELDS["lubricated_revolute"] = {**JOINT_FIELDS["clearance_revolute"],
                                       **catalog.element("lubricated_revolute").fields}
JOINT_FIELDS["clearance_revolute"]["wear"] = (f"{catalog.choices(catalog.WEAR_MODELS)}(coefficient, hardness, update, "
                                            "factor, updates, nodes, depth_step): the bearing wears (docs/wear.md)")
JOINT_FIELDS["clearance_translational"] = {**catalog.element("clearance_translational").fields, **_CONTACT_FIELDS}
JOINT_FIELDS["contact"] = {**catalog.element("contact").fields, **_CONTACT_FIELDS}
CONTACT_ELEMENTS = tuple(e.name for e in catalog.ELEMENTS)
JOINT_TYPES = {spec.name: JointType(spec.code) for spec in catalog.JOINTS}
LAWS = {name: law for law, name in CONTACT_LAW_NAMES.items()}
LAW_SETTINGS = frozenset(key for g in catalog.LAW_GROUPS for key in g.takes)  # a law's call arguments
DRIVER_KINDS = tuple(catalog.names(catalog.DRIVERS))
DRIVER_FIELDS = {"speed": "constant speed",
                 "motion": "ramp(...) | harmonic(...) | polynomial(...) | an expression of t",
                 "relative_to": "reference body (default ground)", "axis": "axis (ux, uy) (translation)",
                 "initial": "value of the coordinate at t = 0 (default: from the initial pose)"}
MOTIONS = ("ramp", "harmonic", "polynomial")  # the motion calls (catalog.MOTIONS; speed and expressions are fields)
FORCE_KINDS = tuple(catalog.names(catalog.FORCES))
FORCE_FIELDS = {s.name: s.fields for s in catalog.FORCES}
SIM_FIELDS = {"t_end": "end time", "integrator": " | ".join(catalog.names(catalog.INTEGRATORS)), "rtol": "relative tolerance",
              "atol": "absolute tolerance", "step": "RK4 step / first trial step", "h_min": "smallest step",
              "h_max": "largest step", "output_step": "time between outputs",
              "alpha": "Baumgarte alpha (1/s)", "beta": "Baumgarte beta (1/s)",
              "projection": "auto | on | off", "max_steps": "step limit"}
# every name that may be called in a model (the rest are unknown functions)
_CALL_NAMES = {*FUNCTIONS, *JOINT_FIELDS, *DRIVER_KINDS, *FORCE_KINDS, *MOTIONS, *LAWS, "bar", "box", "circle", "rectangle"}
RESERVED = {"ground": "the fixed body", "system": "the name of the system signals", "pi": "the constant pi"}
SINGLETONS = ("gravity", "simulate")


def heaviest_metric(minv: np.ndarray, mass: np.ndarray) -> np.ndarray:
    """The inverse masses of the bodies at the heaviest one's mass, each keeping its radius of gyration:
    ``minv_b m_b / m_max`` (km.unit_minv).  The Schur complement in this metric has the geometry's
    conditioning without the mass ratios (`kernel.dynamics.scaled_by_masses`); with equal masses it is
    S itself, bit for bit (the factor is exactly 1).  A beam's node bodies (no mass of their own) get 0."""
    heaviest = float(mass.max(initial=0.0))
    if heaviest <= 0.0:
        return np.zeros_like(minv)
    return minv * np.repeat(mass / heaviest, 3)


# ------------------------------------------------------------------ the passes
# Each pass is a small class of methods over one shared state (`self`: the spec, the resolved
# params, the element lists, the arrays `self.a`); `Compiler` at the end joins them and runs
# them in order.  Names: symbols and params, layout (ids, sizes, arrays), bodies, joints,
# clearance joints, drivers, forces, settings, checks.

class _SymbolPasses:
    """Passes 1-2: one statement per name, then every param resolved."""

    # 1. collect ------------------------------------------------------------
    def pass_collect(self):
        """One statement per name (or singleton); `override` replaces in place."""
        self.elements: dict[str, Statement] = {}
        for st in self.spec.statements:
            key = st.kind if st.kind in SINGLETONS else st.name
            where = st.name_pos or st.pos
            if st.kind not in SINGLETONS and key in RESERVED:
                raise where.error(f"the name `{key}` is reserved ({RESERVED[key]})",
                                  hint="choose another name")
            if st.kind not in SINGLETONS and key in KEYWORDS:
                raise where.error(f"`{key}` is a keyword and cannot name an element",
                                  hint="choose another name")
            old = self.elements.get(key)
            if st.override:
                if old is None:
                    names = [n for n, s in self.elements.items() if s.kind == st.kind]
                    what = f"`{st.kind}`" if st.kind in SINGLETONS else f"{st.kind} `{key}`"
                    raise where.error(f"`override` of {what}, which is not defined before",
                                      hint=did_you_mean(key, names) or
                                      "override replaces an element defined earlier (e.g. in an included file)")
                if old.kind != st.kind:
                    raise where.error(f"`{key}` is a {old.kind}, so `override {st.kind}` cannot replace it",
                                      hint=f"write `override {old.kind} {key} ...`")
                self.elements[key] = st
            elif old is not None:
                prev = f"{old.pos.file}:{old.pos.line}"
                if st.kind in SINGLETONS:
                    raise where.error(f"a second `{st.kind}` statement (the first is at {prev})",
                                      hint=f"write `override {st.kind} ...` to replace it")
                raise where.error(f"`{key}` is already defined (a {old.kind} at {prev})",
                                  hint=f"choose another name, or write `override {st.kind} {key} ...` to replace it")
            else:
                self.elements[key] = st
        self.kind_of = {n: s.kind for n, s in self.elements.items() if s.kind not in SINGLETONS}

    def _of(self, kind: str) -> list[Statement]:
        return [s for s in self.elements.values() if s.kind == kind]

    # 2. resolve params -----------------------------------------------------
    def pass_resolve_params(self):
        """Apply `--set` overrides, then evaluate every param (dependency order, cycles reported)."""
        params = {s.name: s for s in self._of("param")}
        exprs: dict[str, Expr] = {}
        for name, text in self.cli_overrides.items():
            name, text = str(name).strip(), str(text).strip()
            if name not in params:
                raise ModelError(f"`--set {name}=...`: the model has no param `{name}`", "--set", 1, 1,
                                 source_line=f"{name}={text}", width=len(name),
                                 hint=did_you_mean(name, params) or
                                 ("params: " + ", ".join(params) if params else "the model declares no params"))
            exprs[name] = parse_expression(text, "--set")
        self.ev = Evaluator(params, {}, self.kind_of, _CALL_NAMES)
        original = {}
        if exprs:
            for name in _param_order(params, {}):  # dependencies first: no deep recursion
                self.ev.param(name)
        for name in exprs:  # the model's own value, to check the override against
            original[name] = self.ev.param(name)
        self.ev = Evaluator(params, exprs, self.kind_of, _CALL_NAMES)
        for name in _param_order(params, exprs):
            self.ev.param(name)
        self.parameters: dict[str, str] = {}
        for name, st in params.items():
            value = self.ev.param(name)
            if name in exprs:
                self._check_override(name, exprs[name], original[name], value, st)
                self.parameters[name] = exprs[name].pos.text
            elif isinstance(st.value, Number) or (isinstance(st.value, Name) and isinstance(value, Symbol)):
                self.parameters[name] = st.value.pos.text
            else:
                self.parameters[name] = _format_value(value)

    def _check_override(self, name, expr, old, new, st):
        def kind(v):
            return {Scalar: "number", Vec: "vector", Symbol: "name"}.get(type(v), "value")

        where = f"line {st.pos.line}"
        text = expr.pos.text

        def error(message: str, hint: str) -> ModelError:  # at the value of `--set NAME=VALUE`, shown whole
            return ModelError(message, "--set", 1, len(name) + 2, hint=hint, source_line=f"{name}={text}",
                              width=len(text))

        if kind(old) != kind(new):
            raise error(f"`--set {name}={text}`: the model's `{name}` is a {kind(old)} ({where}), "
                        f"the override gives a {kind(new)}", hint=f"the model has `param {name} = {st.value.pos.text}`")
        if isinstance(old, Scalar) and not old.plain and old.q.dimensionality and new.plain \
                and new.q.magnitude != 0:  # a number without the unit the model's value has
            unit = U.format_quantity(old.q).split(" ", 1)[1]
            raise error(f"`--set {name}={text}`: `{name}` is {U.describe(old.q.dimensionality)}, and {text} "
                        "has no unit", hint=f"give it a unit, e.g. `--set {name}={text}{unit}` (the model has "
                                            f"`param {name} = {st.value.pos.text}`, {where})")
        if isinstance(old, Scalar) and not old.plain and not new.plain \
                and old.q.dimensionality != new.q.dimensionality:
            raise error(f"`--set {name}={text}`: {U.describe(old.q.dimensionality)} was expected, "
                        f"got {U.describe(new.q.dimensionality)} ({text})",
                        hint=f"the model has `param {name} = {st.value.pos.text}`")


class _LayoutPasses:
    """Passes 3-6: number the elements, size and allocate the arrays, fill them kind by kind."""

    # 3. assign ids ---------------------------------------------------------
    def pass_assign_ids(self):
        """Bodies get ids 0..nbody-1; joints split into ideal and clearance by their type."""
        self.materials = {s.name: s for s in self._of("material")}
        self.bodies = [s for s in self._of("body") if not is_beam(s)]  # rigid bodies; beams after them
        self.beam_statements = [s for s in self._of("body") if is_beam(s)]
        self.nrigid = len(self.bodies)
        self.body_names = self._beam_layout(self.bodies, self.beam_statements)
        self.body_id = {n: i for i, n in enumerate(self.body_names)}
        self.ideal, self.clearance = [], []
        for st in self._of("joint"):
            jt = st.value.name
            if jt in CONTACT_ELEMENTS:
                self.clearance.append(st)
            elif jt in JOINT_TYPES:
                self.ideal.append(st)
            else:
                raise st.value.name_pos.error(f"unknown joint type `{jt}`",
                                              hint=did_you_mean(jt, JOINT_FIELDS) or
                                              "joint types: " + ", ".join(JOINT_FIELDS))
        self.joint_parts = [part for st in self.ideal for part in self._joint_parts(st)]
        # contact pairs: one per clearance element, four for a translational clearance joint
        self.pairs = []
        for st in self.clearance:
            parts = catalog.element(st.value.name).parts
            self.pairs += [(f"{st.name}_{part}" if part else st.name, st) for part in parts]
        for name, st in self.pairs:
            if name != st.name and name in self.kind_of:
                raise (st.name_pos or st.pos).error(
                    f"the corner `{name}` of `{st.name}` has the name of another element",
                    hint="rename one of them")
        self.drivers = self._of("driver")
        for st in self.drivers:
            if st.value.name not in DRIVER_KINDS:
                raise st.value.name_pos.error(f"unknown driver `{st.value.name}`",
                                              hint=did_you_mean(st.value.name, DRIVER_KINDS) or
                                              "drivers: rotation(...) or translation(...)")
        self.forces = self._of("force")
        for st in self.forces:
            if st.value.name not in FORCE_KINDS:
                raise st.value.name_pos.error(f"unknown force `{st.value.name}`",
                                              hint=did_you_mean(st.value.name, FORCE_KINDS) or
                                              "forces: " + ", ".join(FORCE_KINDS))

    # 4. size ---------------------------------------------------------------
    def pass_size(self):
        """Counts and first constraint rows: joints in order, then drivers (one row each)."""
        self.nbody, self.njoint = len(self.body_names), len(self.joint_parts)
        self.ndriver, self.nclear, self.nforce = len(self.drivers), len(self.pairs), len(self.forces)
        types = [jt for _, jt, _ in self.joint_parts]
        rows = JOINT_ROWS[np.array(types, dtype=np.int64)] if types else np.zeros(0, np.int64)
        self.joint_row = np.concatenate([[0], np.cumsum(rows)[:-1]]).astype(np.int64) if types \
            else np.zeros(0, np.int64)
        first = int(rows.sum())
        self.driver_row = np.arange(first, first + self.ndriver, dtype=np.int64)

    # 5. allocate -----------------------------------------------------------
    def pass_allocate(self):
        nb, nj, nd, nc, nf = self.nbody, self.njoint, self.ndriver, self.nclear, self.nforce
        f, i = np.float64, np.int64
        self.a = dict(
            body_mass=np.zeros(nb, f), body_inertia=np.zeros(nb, f), minv=np.zeros(3 * nb, f), unit_minv=np.zeros(3 * nb, f),
            gravity=np.zeros(2, f),
            joint_type=np.zeros(nj, i), joint_body=np.full((nj, 2), -1, i),
            joint_point=np.zeros((nj, 2, 2), f), joint_axis=np.zeros((nj, 2), f),
            joint_param=np.zeros((nj, N_JOINT_PARAM), f), joint_row=self.joint_row,
            driver_type=np.zeros(nd, i), driver_body=np.full((nd, 2), -1, i),
            driver_point=np.zeros((nd, 2, 2), f), driver_axis=np.zeros((nd, 2), f),
            driver_motion=np.zeros(nd, i), driver_motion_param=np.zeros((nd, N_MOTION_PARAM), f),
            driver_row=self.driver_row,
            clearance_body=np.full((nc, 2), -1, i), clearance_point=np.zeros((nc, 2, 2), f),
            clearance_law=np.zeros(nc, i), clearance_param=np.zeros((nc, N_CLEARANCE_PARAM), f),
            force_type=np.zeros(nf, i), force_body=np.full((nf, 2), -1, i),
            force_point=np.zeros((nf, 2, 2), f), force_param=np.zeros((nf, N_FORCE_PARAM), f),
        )
        self.q0, self.qd0 = np.zeros(3 * nb), np.zeros(3 * nb)
        self.clearance_start = np.full((nc, 4), np.nan)  # offset (x, y), relative velocity (x, y); NaN: not given
        self.geometry: list[dict] = []

    # 6. fill ---------------------------------------------------------------
    def pass_fill(self):
        for k, st in enumerate(self.bodies):
            self._fill_body(k, st)
        self._sigma_cache: dict[str, float] = {}
        for st in self.materials.values():
            self._sigma(st.name, st.name_pos)
        self._fill_beams()
        self.jfriction: list[int] = []
        for k, (st, jt, name) in enumerate(self.joint_parts):
            self._fill_joint(k, st, jt, name)
        self.a["joint_friction"] = np.array(self.jfriction, dtype=np.int64)
        self.clearance_assembly = []
        self.clearance_wear = {}
        for st in self.clearance:
            self._fill_element(len(self.clearance_assembly), st)
        self.programs = Programs(self.ev, self._expression_context())
        for k, st in enumerate(self.drivers):
            self._fill_driver(k, st)
        for k, st in enumerate(self.forces):
            self._fill_force(k, st)
        g = self.elements.get("gravity")
        if g is not None:
            self.a["gravity"][:] = vector_si(self.ev, g.value, U.ACCELERATION, "")
        self._beam_weights()
        self.settings = self._settings(self.elements.get("simulate"))

    def _expression_context(self) -> Context:
        """What the expressions of loads and motions may name (`expressions.Context`)."""
        a = self.a
        clearance = {st.name: (int(a["clearance_body"][k, 0]), tuple(a["clearance_point"][k, 0]),
                               int(a["clearance_body"][k, 1]), tuple(a["clearance_point"][k, 1]),
                               float(a["clearance_param"][k, CP_CLEARANCE]))
                     for k, st in enumerate(self.clearance)}
        return Context(self.body_id, self.q0, self.qd0, clearance, self.kind_of)

    def _fields(self, st: Statement, label: str, allowed: dict, call: Call | None = None) -> Fields:
        extra = tuple(Field(k.name, k.value, k.pos) for k in call.kwargs) if call else ()
        return Fields(self.ev, st, label, allowed, extra)

class _BodyPass:
    """Bodies: mass, inertia, the initial pose and velocity, the drawing shape; and the body
    references (`body (x, y)`) every other element uses."""

    def _fill_body(self, k: int, st: Statement):
        f = self._fields(st, f"body `{st.name}`", BODY_FIELDS)
        m = f.scalar("mass", U.MASS, positive=True)
        inertia = f.scalar("inertia", U.INERTIA, positive=True)
        for key, value, unit in (("mass", m, "kg"), ("inertia", inertia, "kg*m^2")):
            if value < MIN_INERTIA:  # 1/value overflows or loses every digit (subnormal): no dynamics left
                raise f.expr(key).pos.error(f"`{key}` of body `{st.name}` is {value:.3g} {unit}, too small to "
                                            f"compute with (below {MIN_INERTIA:g} {unit}, its inverse overflows)",
                                            hint=f"a unit typo? e.g. `{key} = 0.3 {unit}`")
        self.a["body_mass"][k], self.a["body_inertia"][k] = m, inertia
        self.a["minv"][3 * k:3 * k + 3] = (1.0 / m, 1.0 / m, 1.0 / inertia)
        self.q0[3 * k:3 * k + 2] = f.vector("position", U.LENGTH, (0.0, 0.0))
        self.q0[3 * k + 2] = f.scalar("angle", U.ANGLE, 0.0)
        self.qd0[3 * k:3 * k + 2] = f.vector("velocity", U.VELOCITY, (0.0, 0.0))
        self.qd0[3 * k + 2] = f.scalar("omega", U.ANGULAR_VELOCITY, 0.0)
        self.geometry.append(self._shape(f.expr("shape")) if f.has("shape") else {})

    SHAPES = {"bar": ("length", "width"), "box": ("width", "height"), "circle": ("radius",)}

    def _shape(self, e: Expr) -> dict:
        v = self.ev.value(e)
        if not isinstance(v, CallVal) or v.call.name not in self.SHAPES:
            name = v.call.name if isinstance(v, CallVal) else e.pos.text
            raise e.pos.error(f"unknown shape `{name}`",
                              hint=did_you_mean(name, self.SHAPES) or
                              "shapes: bar(length, width), box(width, height), circle(radius)")
        c = v.call
        keys = self.SHAPES[c.name]
        given = self._call_args(c, keys)
        out = {"kind": c.name}
        for key in keys:
            if key not in given:
                raise c.pos.error(f"`{c.name}(...)` needs `{key}`", hint=f"`{c.name}({', '.join(keys)})`")
            value = scalar_si(self.ev, given[key], U.LENGTH, key)
            if not value > 0:
                raise given[key].pos.error(f"`{key}` of a shape must be positive", hint="e.g. `10 mm`")
            out[key] = value
        return out

    def _call_args(self, c: Call, keys) -> dict[str, Expr]:
        """Positional and keyword arguments of `c` matched to `keys`."""
        if len(c.args) > len(keys):
            raise c.args[len(keys)].pos.error(f"`{c.name}` takes at most {len(keys)} arguments: {', '.join(keys)}",
                                              hint="remove the extra arguments")
        given = dict(zip(keys, c.args))
        for kw in c.kwargs:
            if kw.name not in keys:
                raise kw.pos.error(f"unknown argument `{kw.name}` of `{c.name}`",
                                   hint=did_you_mean(kw.name, keys) or f"arguments: {', '.join(keys)}")
            if kw.name in given:
                raise kw.pos.error(f"`{kw.name}` of `{c.name}` is given twice", hint="keep one of them")
            given[kw.name] = kw.value
        return given

    # body references and the initial pose
    def _body(self, name: str, pos: Pos) -> int:
        if name == "ground":
            return -1
        if name in self.body_id:
            return self.body_id[name]
        if name in self.kind_of and self.kind_of[name] != "param":
            raise pos.error(f"`{name}` is a {self.kind_of[name]}, not a body",
                            hint="name a body here (or `ground`)")
        raise pos.error(f"unknown body `{name}`",
                        hint=did_you_mean(name, [*self.body_id, "ground"]) or
                        "declare it with `body NAME { mass = ...  inertia = ... }` or use `ground`")

    def _ref(self, e: Expr, what: str, point=True) -> tuple[int, tuple[float, float]]:
        """`crank`, `crank (0.025, 0)` or `crank (p)` → (body id, point in the body frame)."""
        if isinstance(e, Name) and e.name in self.beam_first:
            raise e.pos.error(f"{what} names beam `{e.name}` without a node",
                              hint=f"`{e.name} (start)`, `{e.name} (end)` or `{e.name} (k)`")
        if isinstance(e, Call) and e.name in self.beam_first:
            return self._beam_node(e), (0.0, 0.0)
        if isinstance(e, Name):
            name = e.name
            if e.name in self.ev.params:
                v = self.ev.param(e.name)
                if isinstance(v, Symbol):
                    name = v.name
            return self._body(name, e.pos), (0.0, 0.0)
        if isinstance(e, Call) and e.name not in FUNCTIONS and not e.kwargs:
            body = self._ref(Name(e.name_pos, e.name), what)[0]
            if not point:
                raise e.pos.error(f"{what} takes bodies without points", hint=f"write just `{e.name}`")
            if len(e.args) == 2:
                xy = (scalar_si(self.ev, e.args[0], U.LENGTH, "x", note=False),
                      scalar_si(self.ev, e.args[1], U.LENGTH, "y", note=False))
                if any(self.ev.number(self.ev.value(a), a).plain and v != 0 for a, v in zip(e.args, xy)):
                    self.ev.note_plain(e, list(xy), U.LENGTH)
                return body, xy
            if len(e.args) == 1:
                return body, vector_si(self.ev, e.args[0], U.LENGTH, "point")
            if not e.args:
                return body, (0.0, 0.0)
        raise e.pos.error(f"{what} expects a body, optionally with a point in its frame; got `{e.pos.text}`",
                          hint="e.g. `crank (0.025, 0)` or `ground`")

    def _angle0(self, b: int) -> float:
        return 0.0 if b < 0 else float(self.q0[3 * b + 2])

    def _world(self, b: int, s) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        if b < 0:
            return s
        return self.q0[3 * b:3 * b + 2] + rotate(self.q0[3 * b + 2], s)

    def _two_refs(self, st: Statement, what: str, point=True):
        c: Call = st.value
        if len(c.args) != 2:
            raise c.pos.error(f"{what} connects two bodies: `{c.name}(a (x, y), b (x, y))`, "
                              f"got {len(c.args)} positional argument{'s' if len(c.args) != 1 else ''}",
                              hint="e.g. `revolute(ground (0, 0), crank (-0.025, 0))`; use `ground` for the frame")
        (bi, pi), (bj, pj) = self._ref(c.args[0], what, point), self._ref(c.args[1], what, point)
        if bi == bj:
            raise c.pos.error(f"{what} connects `{c.args[0].pos.text}` to itself" if bi >= 0 else
                              f"{what} connects ground to ground",
                              hint="the two sides must be different bodies")
        return bi, pi, bj, pj

    def _unit_axis(self, f: Fields, name: str) -> tuple[float, float]:
        """A direction `(ux, uy)`, normalised; any common unit (or none) is accepted."""
        if not f.has(name):
            raise f.missing(name)
        e = f.expr(name)
        v = self.ev.value(e)
        if not isinstance(v, Vec) or len(v.items) != 2:
            raise e.pos.error(f"`{name}` must be a direction `(ux, uy)`, got `{e.pos.text}`", hint=f"e.g. `{name} = (1, 0)`")
        x, y = v.items
        if not (x.plain or y.plain) and x.q.dimensionality != y.q.dimensionality:
            raise e.pos.error(f"the components of `{name}` have different dimensions", hint=f"e.g. `{name} = (1, 0)`")
        ax = [float(s.q.magnitude if s.plain else s.q.to_base_units().magnitude) for s in v.items]
        n = math.hypot(*ax)
        if n == 0:
            raise e.pos.error(f"`{name}` must not be the zero vector", hint=f"give a direction, e.g. `{name} = (1, 0)`")
        return ax[0] / n, ax[1] / n

class _JointPass:
    """Ideal joints: bodies, points, axes and the relative angle or length they keep."""

    def _fill_joint(self, k: int, st: Statement, jt: JointType, name: str):
        c: Call = st.value
        label = f"joint `{name}` ({c.name})"
        f = self._fields(st, label, JOINT_FIELDS[c.name], c)
        bi, pi, bj, pj = self._two_refs(st, label)
        a = self.a
        if jt == JointType.BEAM_SLOPE:
            self._fill_slope(k, st, label, f, bi, bj)
            return
        a["joint_type"][k] = int(jt)
        a["joint_body"][k] = (bi, bj)
        a["joint_point"][k] = (pi, pj)
        spec = catalog.JOINTS[int(jt)]
        values: dict[str, float] = {}
        for setting in spec.settings:  # read and stored as the catalog says
            if setting.unit == "direction":
                a["joint_axis"][k] = self._unit_axis(f, setting.name)
            else:
                values[setting.name] = self._joint_setting(f, st, label, setting, bi, pi, bj, pj, values)
                a["joint_param"][k, JP[setting.column]] = values[setting.name]
        if spec.friction:
            self._joint_friction(f, st, label, spec, values, k)

    def _joint_friction(self, f: Fields, st: Statement, label: str, spec, values: dict, k: int) -> None:
        """A joint's friction settings are physical: mu_k >= 0, mu_s >= mu_k, a pin radius when a pin has
        friction (docs/contact.md, "Friction in ideal joints")."""
        mu, mus = values["friction"], values["static_friction"]
        if mu < 0:
            raise f.expr("friction").pos.error(f"the friction of {label} must not be negative",
                                               hint="a coefficient such as `friction = 0.1`")
        if mus < mu:
            where = f.expr("static_friction").pos if f.has("static_friction") else f.expr("friction").pos
            raise where.error(f"the static friction of {label} ({mus:g}) is below its kinetic friction ({mu:g})",
                              hint="give `static_friction` at least `friction` (it defaults to it)")
        if spec.friction == "torque" and mus > 0 and not values["pin_radius"] > 0:
            raise (f.expr("pin_radius").pos if f.has("pin_radius") else st.name_pos).error(
                f"{label} has friction but no pin radius", hint="give the pin's radius, e.g. `pin_radius = 10 mm`")
        if values.get("block_length", 0.0) < 0:
            raise f.expr("block_length").pos.error(f"the block length of {label} must not be negative",
                                                   hint="the length of the sliding block, e.g. `block_length = 50 mm`")
        on_beam = [b for b in self.a["joint_body"][k] if b >= 0 and len(self.a.get("body_beam", ())) > b
                   and self.a["body_beam"][b] >= 0]
        if mus > 0 and on_beam:
            raise (f.expr("friction").pos if f.has("friction") else st.name_pos).error(f"{label} joins a beam: joint friction is for rigid bodies only",
                                               hint="put the friction on a joint between rigid bodies, or remove it")
        if mus > 0:
            self.jfriction.append(k)

    def _joint_setting(self, f: Fields, st: Statement, label: str, setting, bi, pi, bj, pj,
                       values: dict | None = None) -> float:
        """A number setting of a joint or force (catalog.JointSetting) in SI, its default taken from the pose
        or from a setting read before it (`values`, a joint's settings so far)."""
        default = setting.default
        if isinstance(default, str) and default in (values or {}):
            default = values[default]
        elif default == "pose":
            default = (self._angle0(bj) - self._angle0(bi) if setting.unit == "angle"
                       else float(np.linalg.norm(self._world(bj, pj) - self._world(bi, pi))))
        dim = getattr(U, setting.unit.upper())
        value = f.scalar(setting.name, dim) if default is None else f.scalar(setting.name, dim, default)
        if setting.positive and not value > 0:
            where = f.expr(setting.name).pos if f.has(setting.name) else st.name_pos
            hint = (f"give a value greater than zero, e.g. `{setting.name} = ...`" if f.has(setting.name) else
                    f"the two points coincide in the initial pose; give `{setting.name} = ...`"
                    if setting.unit == "length" else f"give `{setting.name} = ...`")
            raise where.error(f"the {setting.name} of {label} must be positive", hint=hint)
        return value


class _ClearancePass:
    """Revolute clearance joints: radii, materials, the contact law and its stiffness, friction."""

    def _sigma(self, name: str, pos: Pos) -> float:
        """sigma = (1 - nu^2) / E of a material (Muvengei et al. eq. 18)."""
        if name in self._sigma_cache:
            return self._sigma_cache[name]
        if name not in self.materials:
            if name in self.kind_of:
                raise pos.error(f"`{name}` is a {self.kind_of[name]}, not a material",
                                hint="declare a material: `material steel { E = 207 GPa  nu = 0.3 }`")
            raise pos.error(f"unknown material `{name}`",
                            hint=did_you_mean(name, self.materials) or
                            "declare it with `material NAME { E = 207 GPa  nu = 0.3 }`")
        st = self.materials[name]
        f = self._fields(st, f"material `{name}`", MATERIAL_FIELDS)
        E = f.scalar("E", U.PRESSURE, positive=True)
        nu = f.scalar("nu", U.NUMBER)
        if not -1 < nu < 0.5:
            raise f.expr("nu").pos.error(f"Poisson's ratio must lie in (-1, 0.5), got {f.expr('nu').pos.text}",
                                          hint="steel is about 0.3, rubber almost 0.5")
        f.scalar("density", U.DENSITY, None, positive=True)
        self._sigma_cache[name] = (1 - nu * nu) / E
        return self._sigma_cache[name]

    def _material(self, f: Fields, key: str) -> tuple[str, Pos]:
        e = f.expr(key)
        v = self.ev.value(e)
        if not isinstance(v, Symbol):
            raise e.pos.error(f"`{key}` takes the name of a material, got `{e.pos.text}`",
                              hint=f"e.g. `{key} = steel` with `material steel {{ E = 207 GPa  nu = 0.3 }}`")
        return v.name, e.pos

    def _fill_element(self, k: int, st: Statement):
        """The contact pairs of one contact element, from pair k on (catalog.ELEMENTS)."""
        kind = st.value.name
        if kind in ("clearance_revolute", "lubricated_revolute"):
            self._fill_clearance(k, st)
        elif kind == "clearance_translational":
            self._fill_translational(k, st)
        else:
            self._fill_contact(k, st)

    def _fill_clearance(self, k: int, st: Statement):
        """A revolute clearance joint: a force element (Muvengei et al. §II.A–C), stiffness from eq. 18;
        lubricated, it adds the short-bearing film (Flores et al. 2006) and its dry contact begins at
        the breakdown eccentricity ratio."""
        lubricated = st.value.name == "lubricated_revolute"
        label = f"{'lubricated' if lubricated else 'clearance'} joint `{st.name}`"
        bi, pi, bj, pj = self._two_refs(st, label)
        f = self._clearance_fields(st, label)
        name = f.symbol("law", list(LAWS))
        law = LAWS[name]
        group = catalog.law(name).group
        cl, rb, rj = self._clearance_radii(f, st, label)
        length = f.scalar("length", U.LENGTH, 0.0, positive=True)
        sigma_sum = self._clearance_sigma(f, st, label)
        stiffness, exponent, ce, damping = self._clearance_law(f, st, label, name, group, rb, rj, sigma_sum, length,
                                                               self._effective_mass(bi, bj))
        p = self.a["clearance_param"][k]
        p[CP_CLEARANCE], p[CP_R_BEARING], p[CP_R_JOURNAL], p[CP_LENGTH] = cl, rb, rj, length
        p[CP_STIFFNESS], p[CP_EXPONENT], p[CP_RESTITUTION], p[CP_SIGMA_SUM] = stiffness, exponent, ce, sigma_sum
        p[CP_DAMPING] = damping
        self._clearance_friction(f, p)
        self._clearance_start(f, k, cl)
        self.a["clearance_body"][k] = (bi, bj)
        self.a["clearance_point"][k] = (pi, pj)
        self.a["clearance_law"][k] = int(law)
        self.clearance_assembly.append(("revolute",))
        if f.has("wear"):
            self.clearance_wear[st.name] = self._clearance_wear(f.expr("wear"), label, length, f)
        if lubricated:
            p[CP_KIND] = int(PairKind.LUBRICATED)
            if not length > 0:
                raise f.missing("length")
            p[CP_VISCOSITY] = f.scalar("viscosity", U.VISCOSITY, positive=True)
            eb = p[CP_BREAKDOWN] = f.scalar("breakdown", U.NUMBER, 0.95)
            if not 0 < eb < 1:
                raise f.expr("breakdown").pos.error(
                    f"the breakdown eccentricity ratio must lie in (0, 1), got {f.expr('breakdown').pos.text}",
                    hint="the film breaks down before the journal touches the bearing (ratio 1), e.g. 0.95")

    def _contact_law(self, f: Fields, st: Statement, label: str, r_eff: float, bodies):
        """(law, K, n, c_e, sigma, c) of a contact element of a plane geometry between `bodies`: a
        cylindrical law needs a bearing, and without `stiffness` K = 4 / (3 (sigma_1 + sigma_2)) sqrt(R)
        (Hertz, a circle of effective radius R on a plane or on another circle; no default for a sharp
        corner, R = 0)."""
        name = f.symbol("law", list(LAWS))
        group = catalog.law(name).group
        if group.compliance == "materials":
            raise f.expr("law").pos.error(f"law {name} is for a journal in a bearing; {label} is no bearing",
                                          hint="use hertz or a dissipative law, e.g. lankarani_nikravesh")
        sigma_sum = self._clearance_sigma(f, st, label)
        if not f.has("stiffness") and not r_eff > 0:
            raise (st.name_pos or st.pos).error(f"{label} touches at a sharp corner: give its `stiffness`",
                                                hint="e.g. `stiffness = 1e9` (N/m^1.5), or a `corner_radius`")
        if not f.has("stiffness") and sigma_sum == 0:
            raise (st.name_pos or st.pos).error(f"{label} needs `material` (or `stiffness`)",
                                                hint="e.g. `material = steel`")
        # the bearing radii only set _clearance_law's default stiffness, replaced here
        K, n, ce, c = self._clearance_law(f, st, label, name, group, 2.0, 1.0, sigma_sum, 0.0,
                                          self._effective_mass(*bodies))
        if not f.has("stiffness"):
            K = 4.0 / (3.0 * sigma_sum) * math.sqrt(r_eff)
        return LAWS[name], K, n, ce, sigma_sum, c

    def _effective_mass(self, bi: int, bj: int) -> float:
        """m_i m_j / (m_i + m_j) of a contact pair (ground: the other body's mass), the translational
        masses alone: what the Kelvin-Voigt law's damping from a restitution is sized for."""
        w = sum(1.0 / self._translational_mass(b) for b in (bi, bj) if b >= 0)
        return 1.0 / w if w > 0 else math.inf

    def _translational_mass(self, b: int) -> float:
        """A body's mass; a beam's node: the mass a force there moves (`beams.node_mass`)."""
        if b >= self.nrigid:
            return B.node_mass(KernelModel(**{k: v for k, v in self.a.items() if k in KernelModel._fields}), b)
        return float(self.a["body_mass"][b])

    def _fill_pair(self, k: int, kind: int, bodies, points, law, K, n, ce, sigma, c, f: Fields, **cols):
        p = self.a["clearance_param"][k]
        p[CP_KIND], p[CP_STIFFNESS], p[CP_EXPONENT], p[CP_RESTITUTION], p[CP_SIGMA_SUM] = kind, K, n, ce, sigma
        p[CP_DAMPING] = c
        for col, v in cols.items():
            p[globals()[col]] = v
        self._clearance_friction(f, p)
        self.a["clearance_body"][k] = bodies
        self.a["clearance_point"][k] = points
        self.a["clearance_law"][k] = int(law)

    def _fill_translational(self, k: int, st: Statement):
        """A block of `length` x `width` in a guide `clearance` wider (Flores et al. 2008, ch. 5): four
        pairs, each corner (a circle of `corner_radius`, 0: sharp) against the guide surface on its side."""
        label = f"translational clearance joint `{st.name}`"
        bi, pi, bj, pj = self._two_refs(st, label)
        f = self._clearance_fields(st, label)
        ax = np.array(self._unit_axis(f, "axis"))
        cl = f.scalar("clearance", U.LENGTH, positive=True)
        length = f.scalar("length", U.LENGTH, positive=True)
        width = f.scalar("width", U.LENGTH, positive=True)
        rc = f.scalar("corner_radius", U.LENGTH, 0.0, nonneg=True)
        if not cl < width:
            raise f.expr("clearance").pos.error(f"the clearance of {label} must be smaller than the block's width",
                                                hint="a corner could then reach the far guide surface")
        if not 2 * rc < min(length, width):
            raise f.expr("corner_radius").pos.error("the corners' radius must be less than half the block's sides")
        law, K, n, ce, sigma, c = self._contact_law(f, st, label, rc, (bi, bj))
        start = self._translational_start(f, cl, length, width, rc)
        phi0 = 0.0  # the block's sides lie along `axis` in its own frame too: aligned at equal angles
        ab = ax
        ng, nb = np.array([-ax[1], ax[0]]), np.array([-ab[1], ab[0]])
        half = 0.5 * (width + cl)
        for i, (sa, sn) in enumerate(((-1, -1), (-1, 1), (1, -1), (1, 1))):
            line = np.asarray(pi) + sn * half * ng
            corner = np.asarray(pj) + sa * (0.5 * length - rc) * ab + sn * (0.5 * width - rc) * nb
            self._fill_pair(k + i, int(PairKind.CIRCLE_ON_LINE), (bi, bj), (line, corner), law, K, n, ce, sigma, c, f,
                            CP_CLEARANCE=cl, CP_R_JOURNAL=rc, CP_NX=-sn * ng[0], CP_NY=-sn * ng[1], CP_LENGTH=length)
            self.clearance_assembly.append(
                ("translational", bi, bj, tuple(pi), tuple(pj), tuple(ax), phi0, st.name, start) if i == 0
                else ("none",))

    @staticmethod
    def _translational_start(f: Fields, cl: float, length: float, width: float, rc: float) -> tuple:
        """The block's initial (offset, tilt, relative_velocity, tilt_rate) as written, NaN where not
        given (`kinematics.assemble` keeps what the pose and the velocities state there); refused where
        a corner would start beyond its guide surface."""
        nan = math.nan
        offset = f.scalar("offset", U.LENGTH, nan)
        tilt = f.scalar("tilt", U.ANGLE, nan)
        start = (offset, tilt, f.scalar("relative_velocity", U.VELOCITY, nan),
                 f.scalar("tilt_rate", U.ANGULAR_VELOCITY, nan))
        if f.has("offset") or f.has("tilt"):
            o, th = np.nan_to_num(offset), np.nan_to_num(tilt)
            reach = abs(o) + abs((0.5 * length - rc) * math.sin(th)) + abs((0.5 * width - rc) * math.cos(th))
            room = 0.5 * (width + cl) - rc
            if reach > room * (1 + 1e-9):
                where = f.expr("offset" if f.has("offset") else "tilt")
                raise where.pos.error(
                    f"the block starts with a corner beyond its guide surface: offset {o * 1e3:g} mm and tilt "
                    f"{math.degrees(th):g} deg reach {reach * 1e3:g} mm from the guide's middle, the surface is at "
                    f"{room * 1e3:g} mm", hint=f"the block starts inside its guide: |offset| <= {cl / 2 * 1e3:g} mm "
                    "when it is not tilted, less when it is")
        return start

    def _fill_contact(self, k: int, st: Statement):
        """Contact between two bodies' outlines: a circle (or point) on a line, two circles from outside,
        or a circle in a cavity."""
        label = f"contact `{st.name}`"
        bi, pi, bj, pj = self._two_refs(st, label)
        f = self._clearance_fields(st, label)
        shape = f.symbol("shape", list(catalog.CONTACT_SHAPES))
        takes = {"circle_on_line": ("normal", "radius"), "circle_on_circle": ("radius", "first_radius"),
                 "circle_in_circle": ("radius", "first_radius")}[shape]
        for key in ("normal", "radius", "first_radius"):
            if f.has(key) and key not in takes:
                raise f.expr(key).pos.error(f"shape {shape} takes no `{key}`", hint="it takes " + _chain(takes))
        if shape == "circle_on_line":
            r = f.scalar("radius", U.LENGTH, 0.0, nonneg=True)
            m = self._unit_axis(f, "normal")
            law, K, n, ce, sigma, c = self._contact_law(f, st, label, r, (bi, bj))
            self._fill_pair(k, int(PairKind.CIRCLE_ON_LINE), (bi, bj), (pi, pj), law, K, n, ce, sigma, c, f,
                            CP_R_JOURNAL=r, CP_NX=m[0], CP_NY=m[1])
        else:
            r = f.scalar("radius", U.LENGTH, positive=True)
            r1 = f.scalar("first_radius", U.LENGTH, positive=True)
            inside = shape == "circle_in_circle"
            if inside and not r < r1:
                raise f.expr("radius").pos.error(f"the circle (radius {r:g} m) must be smaller than the cavity "
                                                 f"(first_radius {r1:g} m)")
            law, K, n, ce, sigma, c = self._contact_law(f, st, label, r * r1 / (r1 - r if inside else r1 + r),
                                                        (bi, bj))
            kind = PairKind.CIRCLE_IN_CIRCLE if inside else PairKind.CIRCLE_ON_CIRCLE
            self._fill_pair(k, int(kind), (bi, bj), (pi, pj), law, K, n, ce, sigma, c, f,
                            CP_R_BEARING=r1, CP_R_JOURNAL=r, CP_CLEARANCE=r1 - r if inside else 0.0)
        self.clearance_assembly.append(("none",))

    WEAR_UNITS = {"number": U.NUMBER, "pressure": U.PRESSURE, "time": U.TIME, "length": U.LENGTH}

    def _clearance_wear(self, e: Expr, label: str, length: float, f: Fields) -> dict:
        """`wear = archard(coefficient = k, hardness = H, update = T, factor, updates, nodes)`: the settings of
        a wear run (run/wear.py) in SI, with k_d = k / H."""
        v = self.ev.value(e)
        names = catalog.names(catalog.WEAR_MODELS)
        if not isinstance(v, CallVal) or v.call.name not in names:
            name = v.call.name if isinstance(v, CallVal) else e.pos.text
            raise e.pos.error(f"unknown wear model `{name}` of {label}", hint=did_you_mean(name, names) or
                              "e.g. `wear = archard(coefficient = 1e-4, hardness = 2 GPa, update = 2 rev / speed)`")
        spec = catalog.wear_model(v.call.name)
        given = self._call_args(v.call, [x.name for x in spec.settings])
        out = {"model": spec.name}
        for x in spec.settings:
            if x.name not in given:
                if x.default is None:
                    raise v.call.pos.error(f"`{spec.name}(...)` of {label} needs `{x.name}`",
                                           hint=f"{x.name}: {x.meaning}")
                out[x.name] = float(x.default)
                continue
            out[x.name] = scalar_si(self.ev, given[x.name], self.WEAR_UNITS[x.unit], x.name)
            bad = out[x.name] < 0 if x.name in ("coefficient", "depth_step") else not out[x.name] > 0
            if bad or (x.name in ("updates", "nodes") and out[x.name] != int(out[x.name])):
                raise given[x.name].pos.error(f"`{x.name}` of the wear of {label} must be "
                                              + ("a whole number > 0" if x.name in ("updates", "nodes") else
                                                 ">= 0" if x.name in ("coefficient", "depth_step") else "> 0"),
                                              hint=x.meaning)
        if out["nodes"] < 8:
            raise given["nodes"].pos.error("a worn profile needs at least 8 nodes", hint="e.g. `nodes = 360`")
        if not length > 0:
            raise f.missing("length")
        out["coefficient"] = out["coefficient"] / out.pop("hardness")  # k_d = k / H [1/Pa]
        return out

    def _clearance_start(self, f: Fields, k: int, cl: float):
        """The journal's initial `offset` and `relative_velocity` (bearing frame), when given."""
        if f.has("offset"):
            ox, oy = f.vector("offset", U.LENGTH, (0.0, 0.0))
            self.clearance_start[k, :2] = ox, oy
            if math.hypot(ox, oy) > cl * (1 + 1e-9):
                raise f.expr("offset").pos.error(
                    f"the journal's offset ({math.hypot(ox, oy) * 1e3:g} mm) exceeds the clearance ({cl * 1e3:g} mm)",
                    hint="the journal starts inside its bearing: |offset| <= clearance")
        if f.has("relative_velocity"):
            self.clearance_start[k, 2:] = f.vector("relative_velocity", U.VELOCITY, (0.0, 0.0))

    def _clearance_fields(self, st: Statement, label: str) -> Fields:
        """The joint's fields, with the settings a law call carries
        (``law = lankarani_nikravesh(restitution = 0.9)``) added to them."""
        c: Call = st.value
        allowed = JOINT_FIELDS[c.name]
        f = self._fields(st, label, allowed, c)
        if not f.has("law"):
            return f
        lv = self.ev.value(f.expr("law"))
        if not isinstance(lv, CallVal):
            return f
        law_call = lv.call
        settings = LAW_SETTINGS  # the chosen law's group checks them later
        extra = []
        for kw in law_call.kwargs:
            if kw.name not in settings:
                raise kw.pos.error(f"unknown argument `{kw.name}` of the contact law",
                                   hint=did_you_mean(kw.name, settings) or "arguments: " + ", ".join(sorted(settings)))
            extra.append(Field(kw.name, kw.value, kw.pos))
        if law_call.args:
            raise law_call.pos.error("contact law arguments are named, e.g. `restitution = 0.9`")
        return Fields(self.ev, st, label, allowed,
                      tuple(Field(kw.name, kw.value, kw.pos) for kw in c.kwargs) + tuple(extra))

    def _clearance_radii(self, f: Fields, st: Statement, label: str) -> tuple[float, float, float]:
        """(c, R_B, R_J) from any two of `clearance`, `bearing_radius`, `journal_radius`."""
        given = {key: f.scalar(key, U.LENGTH, positive=True)
                 for key in ("clearance", "bearing_radius", "journal_radius") if f.has(key)}
        if len(given) < 2:
            raise (st.name_pos or st.pos).error(
                f"{label} needs two of `clearance`, `bearing_radius`, `journal_radius`",
                hint="e.g. `clearance = 0.3 mm  bearing_radius = 5 mm`")
        rb = given.get("bearing_radius")
        rj = given.get("journal_radius")
        cl = given.get("clearance")
        if rb is None:
            rb = rj + cl
        elif rj is None:
            rj = rb - cl
        elif cl is None:
            cl = rb - rj
        elif abs(rb - rj - cl) > 1e-9 * rb:
            raise f.expr("clearance").pos.error(
                "`bearing_radius - journal_radius` differs from `clearance`", hint="give only two of the three")
        if not rj < rb:
            key = "journal_radius" if f.has("journal_radius") else "clearance"
            raise f.expr(key).pos.error(
                f"the journal (radius {rj * 1e3:g} mm) must be smaller than the bearing (radius {rb * 1e3:g} mm)",
                hint="the clearance c = R_B - R_J must be positive")
        if not rj > 0:
            raise f.expr("clearance").pos.error(
                f"the clearance leaves no journal (journal radius {rj * 1e3:g} mm)",
                hint="the clearance must be smaller than the bearing radius")
        return cl, rb, rj

    def _clearance_sigma(self, f: Fields, st: Statement, label: str) -> float:
        """sigma_1 + sigma_2 of the bearing and journal materials (0 when none is given)."""
        if f.has("material") and (f.has("bearing_material") or f.has("journal_material")):
            raise f.expr("material").pos.error("give `material` or `bearing_material` + `journal_material`, not both")
        if f.has("bearing_material") != f.has("journal_material"):
            raise (st.name_pos or st.pos).error(f"{label} needs both `bearing_material` and `journal_material`")
        if f.has("material"):
            return 2 * self._sigma(*self._material(f, "material"))
        if f.has("bearing_material"):
            return self._sigma(*self._material(f, "bearing_material")) + \
                self._sigma(*self._material(f, "journal_material"))
        return 0.0

    def _clearance_law(self, f: Fields, st: Statement, label: str, name: str, group, rb: float, rj: float,
                       sigma_sum: float, length: float, m_eff: float) -> tuple[float, float, float, float]:
        """(K, n, c_e, c) of the contact law, checked against what the law's group reads; m_eff: the pair's
        effective mass (`_effective_mass`)."""
        for key in sorted(LAW_SETTINGS - set(group.takes)):  # settings the law's group does not read
            if f.has(key):
                why = (": its compliance comes from the materials, the bearing length and the radii"
                       if group.compliance == "materials" else f" (a {group.name} law)")
                other = next(s.name for s in catalog.LAWS if key in s.group.takes)
                raise f.expr(key).pos.error(f"law {name} takes no `{key}`{why}",
                                            hint=f"remove it, or use a law that takes it, such as {other}")
        for key in group.needs:
            if not f.has(key):
                raise (st.name_pos or st.pos).error(f"law {name} of {label} needs `{key}`",
                                                    hint=f"add `{key} = ...` ({f.allowed[key]})")
        if group.compliance == "materials":
            # implicit cylindrical laws (Muvengei et al. eqs. 22, 23): compliance from sigma, L and the radii
            if not length > 0:
                raise (st.name_pos or st.pos).error(f"law {name} of {label} needs the bearing `length`",
                                                    hint="e.g. `length = 20 mm`")
            if sigma_sum == 0:
                raise (st.name_pos or st.pos).error(
                    f"law {name} of {label} needs `material` (or `bearing_material` + `journal_material`)",
                    hint="e.g. `material = steel` with `material steel { E = 207 GPa  nu = 0.3 }`")
        exponent = group.exponent or f.scalar("exponent", U.NUMBER, 1.5, positive=True)
        if group.compliance == "materials":
            stiffness = hertz_stiffness(rb, rj, sigma_sum)  # not used by the law; kept for reference
        elif f.has("stiffness"):
            stiffness = f.scalar("stiffness", U.contact_stiffness(exponent), positive=True)
        else:
            if sigma_sum == 0:
                raise (st.name_pos or st.pos).error(
                    f"{label} needs `material` (or `stiffness`) to compute the contact stiffness",
                    hint="e.g. `material = steel` with `material steel { E = 207 GPa  nu = 0.3 }`")
            if exponent != 1.5:
                raise f.expr("exponent").pos.error(
                    "the default stiffness (Muvengei et al. eq. 18) holds for exponent 1.5; give `stiffness` too")
            stiffness = hertz_stiffness(rb, rj, sigma_sum)
        ce, damping = self._law_dissipation(f, st, label, name, group, stiffness, m_eff)
        return stiffness, exponent, ce, damping

    def _law_dissipation(self, f: Fields, st: Statement, label: str, name: str, group, K: float,
                         m_eff: float) -> tuple[float, float]:
        """(c_e, c): the law's restitution and the Kelvin-Voigt damping, from the one of `group.one_of`
        given: the law's own coefficient, the effective restitution it is to give (its coefficient
        found from it, `restitution.py`) or the damping."""
        given = [key for key in group.one_of if f.has(key)]
        if len(given) > 1:
            raise f.expr(given[1]).pos.error(f"give `{given[0]}` or `{given[1]}` to law {name}, not both",
                                             hint="each sets the law's dissipation")
        if group.one_of and not given:
            keys = [f"`{key}`" for key in group.one_of]
            raise (st.name_pos or st.pos).error(f"law {name} of {label} needs one of {', '.join(keys[:-1])} or {keys[-1]}",
                                                hint="e.g. `restitution = 0.9` or `effective_restitution = 0.9`")
        values = {key: self._restitution(f, key) for key in ("restitution", "effective_restitution") if f.has(key)}
        ce = values.get("restitution", 1.0)
        if group is catalog.LINEAR:
            damping = f.scalar("damping", U.DAMPING, nonneg=True) if f.has("damping") else R.kelvin_voigt_damping(
                K, m_eff, values.get("restitution"), values.get("effective_restitution"))
            return ce, damping
        if "effective_restitution" in values:
            try:
                ce = R.dissipative_coefficient(int(LAWS[name]), values["effective_restitution"])
            except ValueError as e:
                raise f.expr("effective_restitution").pos.error(
                    str(e), hint="use flores or gonthier, which reach any restitution") from None
        return ce, 0.0

    def _no_second_body(self, extra: list, driven: Expr, label: str) -> None:
        """A body written as a driver's second argument (`rotation(a, b, ...)`) is a reference body in
        the wrong place, not a motion: say how to write it."""
        for e in extra:
            name = e.name if isinstance(e, Name) or isinstance(e, Call) and not e.kwargs else None
            if name in self.body_id:
                first = getattr(driven, "name", "body")
                raise e.pos.error(f"{label}: `{name}` is a body, not a motion: a driver names the body it moves "
                                  "first and the body it moves relative to as `relative_to`",
                                  hint=f"write `{first}, relative_to = {name}` (or the other way round)")

    def _restitution(self, f: Fields, key: str) -> float:
        """A coefficient of restitution in (0, 1]."""
        e = f.scalar(key, U.NUMBER)
        if not 0 < e <= 1:
            raise f.expr(key).pos.error(
                f"the coefficient of restitution must lie in (0, 1], got {f.expr(key).pos.text}")
        return e

    def _clearance_friction(self, f: Fields, p: np.ndarray) -> None:
        """The friction model (catalog.FRICTION_MODELS) and its settings into the joint's parameter row.
        Without `friction_model`, a setting of Ambrosio's ramp chooses it, else the default."""
        implied = "ambrosio" if f.has("friction_velocity") or f.has("friction_velocity_full") else None
        name = f.symbol("friction_model", catalog.names(catalog.FRICTION_MODELS),
                        implied or catalog.DEFAULT_FRICTION)
        model = catalog.friction_model(name)
        p[CP_FRICTION_MODEL] = model.code
        own = {x.name for x in model.settings}
        for other in catalog.friction_settings():
            if other not in own and f.has(other):
                users = [m.name for m in catalog.FRICTION_MODELS if other in {x.name for x in m.settings}]
                raise f.expr(other).pos.error(f"`{other}` is a setting of friction_model = {' or '.join(users)}, "
                                              f"not of {name}", hint=f"add `friction_model = {users[0]}`")
        for x in model.settings:
            default = x.default
            if isinstance(default, str):  # "NAME" or "FACTOR NAME": another setting's value
                *factor, other = default.split()
                default = float(factor[0] if factor else 1.0) * p[FRICTION_COLUMNS[other]]
            extra = () if default is None else (default,)  # None: the model needs it
            p[FRICTION_COLUMNS[x.name]] = f.scalar(x.name, FRICTION_UNITS[x.unit], *extra,
                                                   positive=x.name in _POSITIVE_FRICTION, nonneg=True)
        if name == "ambrosio":
            self._ambrosio_ramp(f, p)
        elif model.state and not p[CP_FRICTION] > 0:
            raise (f.expr("friction").pos if f.has("friction") else f.expr("friction_model").pos).error(
                f"friction_model = {name} needs `friction` > 0 (its Stribeck curve g(v) divides its bristles' rate)",
                hint="give the kinetic coefficient, e.g. `friction = 0.3`")
        elif p[CP_STATIC_FRICTION] < p[CP_FRICTION]:
            raise f.expr("static_friction").pos.error(
                "`static_friction` must not be below `friction` (the kinetic coefficient)",
                hint="a contact sticks with up to mu_s F_N and slides with mu_k F_N, mu_s >= mu_k")

    def _ambrosio_ramp(self, f: Fields, p: np.ndarray) -> None:
        """Ambrosio's slip-speed ramp v0 -> v1."""
        v0, v1 = p[CP_FRICTION_V0], p[CP_FRICTION_V1]
        if v0 == 0 and not f.has("friction_velocity_full"):
            raise f.expr("friction_velocity").pos.error(
                "with `friction_velocity = 0` give `friction_velocity_full` (the slip speed of full friction)")
        if not v1 > v0:
            raise f.expr("friction_velocity_full").pos.error(
                "`friction_velocity_full` must exceed `friction_velocity`",
                hint="friction ramps from 0 at friction_velocity to its full value at friction_velocity_full")


_POSITIVE_FRICTION = ("friction_velocity_full", "stribeck_velocity", "stribeck_exponent", "stick_stiffness",
                      "bristle_stiffness")


class _DriverPass:
    """Drivers: the driven coordinate and its prescribed motion."""

    def _fill_driver(self, k: int, st: Statement):
        c: Call = st.value
        label = f"driver `{st.name}` ({c.name})"
        rotation = c.name == "rotation"
        allowed = {n: d for n, d in DRIVER_FIELDS.items() if rotation is False or n != "axis"}
        f = self._fields(st, label, allowed, c)
        if not c.args or len(c.args) > 2:
            raise c.pos.error(f"{label} drives one body: `{c.name}(body{'' if rotation else ' (x, y)'}, speed = ...)`")
        bj, pj = self._ref(c.args[0], label, point=not rotation)
        if bj < 0:
            raise c.args[0].pos.error("the ground cannot be driven", hint="drive a body")
        bi, p_i = -1, (0.0, 0.0)
        if f.has("relative_to"):
            bi, p_i = self._ref(f.expr("relative_to"), label, point=not rotation)
            if bi == bj:
                raise f.expr("relative_to").pos.error("a body cannot be driven relative to itself",
                                                     hint="name another body, or leave `relative_to` out (ground)")
        a = self.a
        a["driver_body"][k] = (bi, bj)
        a["driver_point"][k] = (p_i, pj)
        if rotation:
            a["driver_type"][k] = int(DriverType.ANGLE)
            coord, rate = U.ANGLE, U.ANGULAR_VELOCITY
            p0 = self._angle0(bj) - self._angle0(bi)
        else:
            a["driver_type"][k] = int(DriverType.POSITION)
            coord, rate = U.LENGTH, U.VELOCITY
            axis = self._unit_axis(f, "axis")
            a["driver_axis"][k] = axis
            u = rotate(self._angle0(bi), axis)
            p0 = float((u * (self._world(bj, pj) - self._world(bi, p_i))).sum())
        # motion: speed = X | motion = m(...) | a positional m(...)
        motions = [e for e in (f.expr("motion"), *c.args[1:]) if e is not None]
        self._no_second_body(c.args[1:], c.args[0], label)
        if f.has("speed"):
            if motions:
                raise f.expr("speed").pos.error("give either `speed = ...` or a motion, not both",
                                                hint="remove one of them")
            mtype, mp = MotionType.CONSTANT_SPEED, [p0, f.scalar("speed", rate)]
        else:
            if len(motions) != 1:
                raise (motions[1].pos if motions else c.pos).error(
                    f"{label} needs one motion",
                    hint="`speed = ...`, `ramp(speed = ..., time = ...)`, `harmonic(amplitude = ..., "
                         "frequency = ...)` or `polynomial(c0, c1, ...)`")
            e = motions[0]
            if isinstance(e, Call) and e.name not in EXPRESSION_FUNCTIONS or \
                    isinstance(e, Name) and e.name in self.ev.params:
                mtype, mp = self._motion(e, coord, rate, p0)
            else:  # an expression of t: its program, derivatives by dual numbers
                mtype, mp = MotionType.EXPRESSION, [self.programs.program(e, coord, label, state=False)]
        if f.has("initial"):
            if mtype in (MotionType.POLYNOMIAL, MotionType.EXPRESSION):
                raise f.expr("initial").pos.error("`initial` does not apply to a polynomial or an expression; "
                                                  "its value at t = 0 is the start value",
                                                  hint="remove `initial`")
            mp[0] = f.scalar("initial", coord)
        a["driver_motion"][k] = int(mtype)
        a["driver_motion_param"][k, :len(mp)] = mp

    def _motion(self, e: Expr, coord: U.Dim, rate: U.Dim, p0: float):
        v = self.ev.value(e)
        if not isinstance(v, CallVal) or v.call.name not in MOTIONS:
            name = v.call.name if isinstance(v, CallVal) else e.pos.text
            raise e.pos.error(f"unknown motion `{name}`",
                              hint=did_you_mean(name, MOTIONS) or "motions: ramp, harmonic, polynomial, or an "
                                                                  "expression of t (`30 deg * sin(2 * pi * 1 Hz * t)`)")
        c = v.call
        if c.name == "polynomial":
            if c.kwargs or not 1 <= len(c.args) <= N_MOTION_PARAM:
                raise c.pos.error(f"`polynomial(c0, c1, ...)` takes 1 to {N_MOTION_PARAM} positional coefficients")
            coeffs = []
            for kk, arg in enumerate(c.args):
                si = U.Dim(f"{coord.words} per second^{kk}" if kk else coord.words,
                           f"{coord.si}/s**{kk}", f"{coord.example}/s^{kk}" if kk else coord.example)
                coeffs.append(scalar_si(self.ev, arg, si, f"c{kk}"))
            return MotionType.POLYNOMIAL, coeffs
        keys = {"ramp": ("speed", "time"), "harmonic": ("amplitude", "frequency", "phase")}[c.name]
        given = self._call_args(c, keys)
        for key in keys:
            if key not in given and key != "phase":
                raise c.pos.error(f"`{c.name}(...)` needs `{key}`", hint=f"`{c.name}({', '.join(keys)})`")
        if c.name == "ramp":
            t = scalar_si(self.ev, given["time"], U.TIME, "time")
            if not t > 0:
                raise given["time"].pos.error("the ramp time must be positive", hint="e.g. `time = 0.1 s`")
            return MotionType.RAMP, [p0, scalar_si(self.ev, given["speed"], rate, "speed"), t]
        amp = scalar_si(self.ev, given["amplitude"], coord, "amplitude")
        freq = scalar_si(self.ev, given["frequency"], U.FREQUENCY, "frequency")
        phase = scalar_si(self.ev, given["phase"], U.ANGLE, "phase") if "phase" in given else 0.0
        return MotionType.HARMONIC, [p0, amp, freq, phase]

class _ForcePass:
    """Applied forces: constant forces and torques, translational and rotational spring-dampers."""

    def _fill_force(self, k: int, st: Statement):
        """A force element, read as its catalog entry says (`catalog.ForceSpec.fill`)."""
        c: Call = st.value
        label = f"force `{st.name}` ({c.name})"
        f = self._fields(st, label, FORCE_FIELDS[c.name], c)
        spec = catalog.FORCES[FORCE_KINDS.index(c.name)]
        self.a["force_type"][k] = spec.code
        fill = {"load": self._fill_load, "spring": self._fill_spring, "expression": self._fill_expression_force,
                "settings": self._fill_settings_force}[spec.fill]
        fill(k, st, c, f, label, spec)

    def _fill_load(self, k: int, st: Statement, c: Call, f: Fields, label: str, spec) -> None:
        """`constant(body (p), force = (fx, fy))` or `torque(body, torque = T)`."""
        a = self.a
        key = spec.settings[0].name
        dim = getattr(U, spec.settings[0].unit.upper())
        if not 1 <= len(c.args) <= 2 or (len(c.args) == 2 and f.has(key)):
            raise c.pos.error(f"`{c.name}(body, {key} = ...)` acts on one body")
        b, p = self._ref(c.args[0], label, point=spec.points)
        if b < 0:
            raise c.args[0].pos.error("a force on the ground has no effect", hint="apply it to a body")
        e = c.args[1] if len(c.args) == 2 else f.expr(key)
        if e is None:
            raise f.missing(key)
        value = vector_si(self.ev, e, dim, key) if len(spec.param_columns) == 2 else (scalar_si(self.ev, e, dim, key),)
        a["force_body"][k] = (b, -1)
        a["force_point"][k, 0] = p
        a["force_param"][k, :len(value)] = value

    def _fill_spring(self, k: int, st: Statement, c: Call, f: Fields, label: str, spec) -> None:
        """A translational or rotational spring-damper: (k, c, free value, actuator, its program)."""
        a = self.a
        rotational = not spec.points
        bi, pi, bj, pj = self._two_refs(st, label, point=not rotational)
        if rotational:
            free0 = self._angle0(bj) - self._angle0(bi)
            params = (f.scalar("stiffness", U.ROT_STIFFNESS, 0.0, nonneg=True),
                      f.scalar("damping", U.ROT_DAMPING, 0.0, nonneg=True),
                      f.scalar("angle", U.ANGLE, free0), *self._actuator(f, U.TORQUE, label))
        else:
            free0 = float(np.linalg.norm(self._world(bj, pj) - self._world(bi, pi)))
            params = (f.scalar("stiffness", U.STIFFNESS, 0.0, nonneg=True),
                      f.scalar("damping", U.DAMPING, 0.0, nonneg=True),
                      f.scalar("length", U.LENGTH, free0, nonneg=True), *self._actuator(f, U.FORCE, label))
        a["force_body"][k] = (bi, bj)
        a["force_point"][k] = (pi, pj)
        a["force_param"][k] = params

    def _actuator(self, f: Fields, dim: U.Dim, label: str) -> tuple[float, float]:
        """(constant actuator, 1 + result row of its expression or 0): a constant stays a number, an
        expression of t or the state becomes a load's program (`expressions`)."""
        e = f.expr("actuator")
        if e is None:
            return 0.0, 0.0
        value, prog = self.programs.constant_or_program(e, dim, f"{label}'s `actuator`")
        return (value, 0.0) if prog is None else (0.0, float(self.programs.result_row(prog) + 1))

    def _fill_settings_force(self, k: int, st: Statement, c: Call, f: Fields, label: str, spec) -> None:
        """A force kind read from its catalog settings alone, one ``force_param`` column each, in order."""
        if spec.bodies == 2:
            bi, pi, bj, pj = self._two_refs(st, label, point=spec.points)
        else:
            if len(c.args) != 1:
                raise c.pos.error(f"`{c.name}(body, ...)` acts on one body")
            (bi, pi), (bj, pj) = self._ref(c.args[0], label, point=spec.points), (-1, (0.0, 0.0))
            if bi < 0:
                raise c.args[0].pos.error("a force on the ground has no effect", hint="apply it to a body")
        self.a["force_body"][k] = (bi, bj)
        self.a["force_point"][k] = (pi, pj)
        for i, setting in enumerate(spec.settings):
            self.a["force_param"][k, i] = self._joint_setting(f, st, label, setting, bi, pi, bj, pj)

    def _fill_expression_force(self, k: int, st: Statement, c: Call, f: Fields, label: str, spec) -> None:
        """`expression(body (p), fx = ..., fy = ..., torque = ...)`: a program per component given."""
        if len(c.args) != 1:
            raise c.pos.error(f"`expression(body, fx = ..., fy = ..., torque = ...)` acts on one body",
                              hint="e.g. `expression(slider, fx = if(slider.vx < 0 m/s, -800 N, 0 N))`")
        b, p = self._ref(c.args[0], label, point=True)
        if b < 0:
            raise c.args[0].pos.error("a force on the ground has no effect", hint="apply it to a body")
        dims = {"fx": U.FORCE, "fy": U.FORCE, "torque": U.TORQUE}
        if not any(f.has(key) for key in dims):
            raise c.pos.error(f"{label} needs `fx`, `fy` or `torque`",
                              hint="e.g. `fx = -800 N * step(slider.vx, -0.01 m/s, 1, 0 m/s, 0)`")
        progs = [self.programs.result_row(self.programs.program(f.expr(key), dim, f"{label}'s `{key}`"))
                 if f.has(key) else -1 for key, dim in dims.items()]
        a = self.a
        a["force_body"][k] = (b, -1)
        a["force_point"][k, 0] = p
        a["force_param"][k, :3] = progs


class _SettingsPass:
    """The `simulate` block."""

    def _settings(self, st: Statement | None) -> Settings:
        s = Settings()
        if st is None:
            return s
        f = self._fields(st, "`simulate`", SIM_FIELDS)
        s.t_end = f.scalar("t_end", U.TIME, s.t_end, positive=True)
        name = f.symbol("integrator", catalog.names(catalog.INTEGRATORS), INTEGRATOR_NAMES[s.integrator])
        s.integrator = Integrator(catalog.integrator(name).code)
        s.rtol = f.scalar("rtol", U.NUMBER, s.rtol, positive=True)
        s.atol = f.scalar("atol", U.NUMBER, s.atol, positive=True)
        s.step = f.scalar("step", U.TIME, s.step, positive=True)
        s.h_min = f.scalar("h_min", U.TIME, s.h_min, nonneg=True)
        s.h_max = f.scalar("h_max", U.TIME, s.h_max, nonneg=True)
        s.output_step = f.scalar("output_step", U.TIME, s.output_step, positive=True)
        if s.rtol >= 1.0:  # as `--rtol` and simulate(rtol=...): planar_mbs.run.settings_check
            raise f.expr("rtol").pos.error(f"`rtol = {s.rtol:g}` must be less than 1",
                                           hint="a relative tolerance lies between 0 and 1, e.g. `rtol = 1e-8`")
        if 0.0 < s.h_max < s.h_min:
            raise f.expr("h_min").pos.error(f"`h_min = {s.h_min:g} s` is larger than `h_max = {s.h_max:g} s`: no "
                                            "step can be taken", hint="give h_min below h_max (h_max = 0: no "
                                            "largest step)")
        s.alpha = f.scalar("alpha", U.RATE, s.alpha, nonneg=True)
        s.beta = f.scalar("beta", U.RATE, s.beta, nonneg=True)
        p = f.symbol("projection", ["auto", "on", "off", "true", "false", "yes", "no"], s.projection)
        s.projection = {"true": "on", "yes": "on", "false": "off", "no": "off"}.get(p, p)
        n = f.scalar("max_steps", U.NUMBER, float(s.max_steps), positive=True)
        if n != int(n) or n > 2**62:
            raise f.expr("max_steps").pos.error("`max_steps` must be a whole number", hint="e.g. `max_steps = 1e6`")
        s.max_steps = int(n)
        return s

def _number_states(cp: np.ndarray) -> None:
    """Each contact element whose friction model has a state of its own (catalog.FrictionSpec.state:
    LuGre's bristle deflection) gets the next place after (q, q') in the integrated state: CP_STATE = 1 + j."""
    stateful = {m.code for m in catalog.FRICTION_MODELS if m.state}
    j = 0
    for k in range(cp.shape[0]):
        cp[k, CP_STATE] = 0.0
        if int(cp[k, CP_FRICTION_MODEL]) in stateful and cp[k, CP_FRICTION] > 0:
            j += 1
            cp[k, CP_STATE] = float(j)


class _CheckPass:
    """Pass 7: whole-model checks, then the `Model`."""

    # 7. check --------------------------------------------------------------
    def pass_check(self):
        """Whole-model checks, then the Model."""
        if self.nbody == 0:
            raise ModelError("the model has no bodies", self.spec.path, 1, 1, source_line=_first_line(self.spec),
                             hint="declare one: `body crank { mass = 0.3 kg  inertia = 1e-5 kg*m^2 }`")
        for name, arr in self.a.items():
            if arr.dtype == np.float64 and not np.all(np.isfinite(arr)):  # pragma: no cover - guarded above
                raise ModelError(f"non-finite values in {name}", self.spec.path, hint="this is a bug in planar_mbs")
        self.a.update(self.programs.arrays())
        self.a["unit_minv"] = heaviest_metric(self.a["minv"], self.a["body_mass"])
        _number_states(self.a["clearance_param"])
        kernel = frozen(reorder(KernelModel(**{k: np.ascontiguousarray(v) for k, v in self.a.items()})))

        def refs(sts):
            return [SourceRef(s.pos.file, s.pos.line, s.pos.column) for s in sts]

        self.model = Model(
            kernel=kernel, settings=self.settings, q0=self.q0, qd0=self.qd0,
            body_names=list(self.body_names), joint_names=[name for _, _, name in self.joint_parts],
            driver_names=[s.name for s in self.drivers], clearance_names=[n for n, _ in self.pairs],
            force_names=[s.name for s in self.forces], body_geometry=self.geometry,
            body_source=refs(self.bodies + [s for s in self.beam_statements
                                            for _ in range(2 * (self.beam_elements[s.name] + 1))]),
            joint_source=refs([st for st, _, _ in self.joint_parts]),
            beam_names=[s.name for s in self.beam_statements],
            driver_source=refs(self.drivers), clearance_source=refs([s for _, s in self.pairs]),
            clearance_assembly=self.clearance_assembly, clearance_wear=self.clearance_wear,
            parameters=self.parameters, source_text=self.spec.text, source_path=self.spec.path,
            source_key=self.spec.key, source_includes=dict(self.spec.includes),
            source_files=list(self.spec.include_files), source_tables=dict(self.programs.table_files),
            clearance_start=self.clearance_start, warnings=list(self.ev.warnings),
        )


# ------------------------------------------------------------------ the compiler
class Compiler(_SymbolPasses, _LayoutPasses, _BodyPass, _BeamPass, _JointPass, _ClearancePass, _DriverPass, _ForcePass,
               _SettingsPass, _CheckPass):
    """Runs the passes in order over one ModelSpec."""

    MATERIAL_FIELDS_ = MATERIAL_FIELDS
    PASSES = ("collect", "resolve_params", "assign_ids", "size", "allocate", "fill", "check")

    def __init__(self, spec: ModelSpec, overrides: dict[str, str]):
        self.spec = spec
        self.cli_overrides = dict(overrides)

    def run(self) -> Model:
        for name in self.PASSES:
            getattr(self, f"pass_{name}")()
        return self.model


def _names_in(e: Expr) -> list[str]:
    """The names an expression refers to (walked without recursion)."""
    out, todo = [], [e]
    while todo:
        x = todo.pop()
        if isinstance(x, Name):
            out.append(x.name)
        elif isinstance(x, BinOp):
            todo += [x.left, x.right]
        elif isinstance(x, Neg):
            todo.append(x.operand)
        elif isinstance(x, Vector):
            todo += list(x.items)
        elif isinstance(x, Call):
            todo += [*x.args, *(k.value for k in x.kwargs)]
    return out


def _param_order(params: dict[str, Statement], overrides: dict[str, Expr]) -> list[str]:
    """Params ordered so that each comes after the params it uses (an iterative depth-first
    search, so a long chain `p1 = p2 + 1`, `p2 = p3 + 1`, ... cannot exhaust the stack).
    A cycle is reported naming its params, at the first one's name."""
    deps = {n: [d for d in _names_in(overrides.get(n, st.value)) if d in params]
            for n, st in params.items()}
    order, state = [], {}  # state: 1 = on the path, 2 = done
    for root in params:
        if state.get(root):
            continue
        state[root] = 1
        stack = [(root, iter(deps[root]))]
        while stack:
            node, it = stack[-1]
            nxt = None
            for d in it:
                if state.get(d) == 1:
                    path = [n for n, _ in stack]
                    path = path[path.index(d):] + [d]
                    cycle = _chain(path)
                    raise params[d].name_pos.error(f"parameters depend on each other in a cycle: {cycle}",
                                                   hint="give one of them a value that does not use the others")
                if not state.get(d):
                    nxt = d
                    break
            if nxt is None:
                stack.pop()
                state[node] = 2
                order.append(node)
            else:
                state[nxt] = 1
                stack.append((nxt, iter(deps[nxt])))
    return order


def hertz_stiffness(r_bearing: float, r_journal: float, sigma_sum: float) -> float:
    """K = 4 / (3 (sigma_1 + sigma_2)) * sqrt(R_B R_J / (R_B - R_J))  (Muvengei et al. eq. 18, bearing concave:
    R_1 = -R_B, R_2 = R_J turn R_1 R_2 / (R_1 + R_2) into R_B R_J / (R_B - R_J))."""
    return 4.0 / (3.0 * sigma_sum) * math.sqrt(r_bearing * r_journal / (r_bearing - r_journal))


def _first_line(spec: ModelSpec) -> str:
    return (spec.text.splitlines() or [""])[0]
