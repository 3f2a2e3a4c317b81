"""One description per contact law, joint type, integrator, force element and driver.

Everything else is derived from these three tables: the integer enums of
`model` (`ContactLaw`, `JointType`, `Integrator`) and their groups, the
columns of the joints' settings (`model.JP`), the kernel's constants (number of
laws, rows per joint type, stage buffers, tableaux), the compiler's field tables,
how it reads a joint's settings and the allowed law arguments, the CLI's choices and
tables, the signal names, how `rerun_log` draws a joint, and the generated
lists in docs/language.md (`python -m planar_mbs.catalog --docs` rewrites them;
a test checks they are in step).

Adding an element is writing its formula (the kernel: `kernel/contact.py` for a
law, `kernel/constraints.py` for a joint type; an explicit Runge-Kutta integrator
is its tableau here and nothing else) and appending its description here with the
next free code (docs/architecture.md, "How to add things").  The descriptions are plain data, importable without numpy or numba.
"""
from __future__ import annotations

import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

# ------------------------------------------------------------------ contact laws


@dataclass(frozen=True)
class LawGroup:
    """What a family of contact laws reads from a clearance joint.

    ``takes``: the law settings allowed (in the joint or as the law's call
    arguments, ``law = flores(restitution = 0.9)``); ``needs``: those that must
    be given; ``one_of``: settings of which exactly one must be given (the law's
    dissipation: its own coefficient, the effective restitution it is to produce
    or a damping); ``compliance``: where the law's compliance comes from
    ("stiffness": K of F = K d^n, given or from the materials; "materials": sigma,
    the bearing length and the radii, no K); ``exponent``: the law's fixed n
    (None: the `exponent` setting, default 1.5)."""

    name: str
    takes: tuple[str, ...]
    needs: tuple[str, ...]
    compliance: str
    summary: str
    one_of: tuple[str, ...] = ()
    exponent: float | None = None


ELASTIC = LawGroup("elastic", ("restitution", "stiffness", "exponent"), (), "stiffness",
                   "F = K d^n, no dissipation")
DISSIPATIVE = LawGroup("dissipative", ("restitution", "effective_restitution", "stiffness", "exponent"), (),
                       "stiffness", "F = K d^n (1 + chi(ce) d'/d'(-)), clipped at F >= 0",
                       one_of=("restitution", "effective_restitution"))
CYLINDRICAL = LawGroup("cylindrical", ("restitution",), (), "materials",
                       "implicit in F, from the materials, the bearing length and the radii")
LINEAR = LawGroup("linear", ("restitution", "effective_restitution", "damping", "stiffness"), ("stiffness",),
                  "stiffness", "F = K d + c d', clipped at F >= 0; c given, or 2 zeta sqrt(K m) from a restitution",
                  one_of=("restitution", "effective_restitution", "damping"), exponent=1.0)
LAW_GROUPS = (ELASTIC, DISSIPATIVE, CYLINDRICAL, LINEAR)


@dataclass(frozen=True, kw_only=True)
class LawSpec:
    """A normal contact-force law of a clearance joint.  Every law reports the
    clearance joint's signals (`signals.CLEARANCE_QUANTITIES`)."""

    code: int  # ContactLaw value, the kernel's law code
    enum: str  # ContactLaw member name
    name: str  # as written in a .mbs file
    title: str  # as printed in figures and docs
    group: LawGroup
    formula: str
    reference: str

    @property
    def cylindrical(self) -> bool:
        return self.group is CYLINDRICAL

    @property
    def dissipative(self) -> bool:
        return self.group is DISSIPATIVE


LAWS: tuple[LawSpec, ...] = (
    LawSpec(code=0, enum="HERTZ", name="hertz", title="Hertz", group=ELASTIC, formula="F = K d^n",
            reference="Hertz 1881; Muvengei et al. eq. 17"),
    LawSpec(code=1, enum="LANKARANI_NIKRAVESH", name="lankarani_nikravesh", title="Lankarani–Nikravesh",
            group=DISSIPATIVE, formula="F = K d^n (1 + 3 (1 - ce^2)/4 d'/d'(-))",
            reference="Lankarani & Nikravesh 1990; Muvengei et al. eq. 21"),
    LawSpec(code=2, enum="DUBOWSKY_FREUDENSTEIN", name="dubowsky_freudenstein", title="Dubowsky–Freudenstein",
            group=CYLINDRICAL, formula="d = A F (ln(B/F) + 1), B = L^3 c / (h R_B R_J)",
            reference="Dubowsky & Freudenstein 1971; Muvengei et al. eq. 22"),
    LawSpec(code=3, enum="ESDU_78035", name="esdu78035", title="ESDU-78035", group=CYLINDRICAL,
            formula="d = A F (ln(B/F) + 1), B = 4 L c / h", reference="ESDU 78035 (1978); Muvengei et al. eq. 23"),
    LawSpec(code=4, enum="HUNT_CROSSLEY", name="hunt_crossley", title="Hunt–Crossley", group=DISSIPATIVE,
            formula="F = K d^n (1 + 3 (1 - ce)/2 d'/d'(-))", reference="Hunt & Crossley 1975"),
    LawSpec(code=5, enum="FLORES", name="flores", title="Flores et al.", group=DISSIPATIVE,
            formula="F = K d^n (1 + 8 (1 - ce)/(5 ce) d'/d'(-))", reference="Flores, Machado, Silva & Martins 2011"),
    LawSpec(code=6, enum="GONTHIER", name="gonthier", title="Gonthier et al.", group=DISSIPATIVE,
            formula="F = K d^n (1 + (1 - ce^2)/ce d'/d'(-))", reference="Gonthier, McPhee, Lange & Piedboeuf 2004"),
    LawSpec(code=7, enum="KELVIN_VOIGT", name="kelvin_voigt", title="Kelvin–Voigt", group=LINEAR,
            formula="F = K d + c d'", reference="Kelvin-Voigt spring-dashpot; Schwager & Poeschel 2007"),
)

# ------------------------------------------------------------------ joint types


@dataclass(frozen=True, kw_only=True)
class JointSetting:
    """A setting of a joint type: how the compiler reads it and which model column it fills.

    ``unit``: ``"direction"`` (a direction (ux, uy) in the first body's frame, normalised into the
    model's ``joint_axis``; one per joint type) or the dimension of a number, a `Dim` of
    `language/units.py` in lower case (``"angle"``, ``"length"``, ``"number"``), stored in the
    model's ``joint_param`` column named ``column`` (the columns are the names used here, in order of
    first use: joint types that share a column share its meaning).  ``default``: a number,
    ``"pose"`` (its value in the initial pose: the relative angle phi_j - phi_i for an angle, the
    distance of the two points for a length) or None (required).  ``positive``: only values > 0."""

    name: str  # as written in a .mbs file
    meaning: str  # as docs/language.md and the error messages show it
    unit: str
    column: str = ""
    default: float | str | None = None
    positive: bool = False


@dataclass(frozen=True, kw_only=True)
class JointSpec:
    """An ideal joint: ``rows`` constraint equations between two bodies.

    ``settings``: the `JointSetting`s it takes (the compiler reads and stores them from these
    alone).  ``moment``: it locks the relative rotation, so its reaction has a moment signal.
    ``draw``: "pin" (a pin at the joint point), "link" (its points join the body outlines, no pin)
    or "slide" (a sliding body: drawn as a box along the axis, with a guide when one side is
    ground; no outline point).  ``slider``: a body tied to ground by it is "the slider" (Poincaré
    section, slider plots)."""

    code: int  # JointType value, the kernel's joint code
    enum: str
    name: str  # as written in a .mbs file
    rows: int
    equations: str
    settings: tuple[JointSetting, ...] = ()
    moment: bool = False
    draw: str = "pin"
    slider: bool = False
    friction: str = ""  # "torque" (a pin: mu r |lambda|), "force" (a slide: mu |lambda_n|) or "" (none)
    example: str = ""  # the call as docs/language.md shows it

    @property
    def fields(self) -> dict[str, str]:
        """The settings it takes, name -> meaning (the compiler's field table, the docs)."""
        return {s.name: s.meaning for s in self.settings}


SETTING_DEFAULTS = ("pose",)  # the named defaults of a JointSetting besides numbers, None and another setting's name
_AXIS = JointSetting(name="axis", meaning="sliding axis (ux, uy) in the first body's frame", unit="direction")
_ANGLE = JointSetting(name="angle", meaning="relative angle kept (default: from the initial pose)", unit="angle",
                      column="phi0", default="pose")
# joint friction (docs/contact.md, "Friction in ideal joints"): Coulomb with stick, the normal load from the
# joint's own reaction in the constraint solve
_MU_J = JointSetting(name="friction", meaning="kinetic friction coefficient mu_k (default 0: frictionless)",
                     unit="number", column="friction", default=0.0)
_MU_S_J = JointSetting(name="static_friction", meaning="static coefficient mu_s >= mu_k (default mu_k)",
                       unit="number", column="static_friction", default="friction")
_PIN = JointSetting(name="pin_radius", meaning="pin radius r: the friction torque is mu r times the pin's "
                    "reaction (needed with friction)", unit="length", column="pin_radius", default=0.0)
_BLOCK = JointSetting(name="block_length", meaning="length l of the sliding block, centred on the second body's "
                      "point: the friction is mu max(normal reaction, 2 moment / l) (default 0: mu times the normal "
                      "reaction)",
                      unit="length", column="block_length", default=0.0)
JOINTS: tuple[JointSpec, ...] = (
    JointSpec(code=0, enum="REVOLUTE", name="revolute", rows=2, equations="P_i - P_j = 0",
              settings=(_MU_J, _MU_S_J, _PIN), friction="torque", example="revolute(a (p), b (p))"),
    JointSpec(code=1, enum="TRANSLATIONAL", name="translational", rows=2,
              equations="phi_j - phi_i - phi0 = 0;  n_i . (P_j - P_i) = 0",
              settings=(_AXIS, _ANGLE, _MU_J, _MU_S_J, _BLOCK), friction="force",
              moment=True, draw="slide", slider=True, example="translational(a (p), b (p), axis = (ux, uy))"),
    JointSpec(code=2, enum="WELD", name="weld", rows=3, equations="P_i - P_j = 0;  phi_j - phi_i - phi0 = 0",
              settings=(_ANGLE,), moment=True, example="weld(a (p), b (p))"),
    JointSpec(code=3, enum="REVOLUTE_REVOLUTE", name="revolute_revolute", rows=1,
              equations="((P_j - P_i).(P_j - P_i) - L^2) / 2 = 0",
              settings=(JointSetting(name="length", meaning="link length (default: from the initial pose)",
                                     unit="length", column="length", default="pose", positive=True),),
              draw="link", example="revolute_revolute(a (p), b (p))"),
    JointSpec(code=4, enum="REVOLUTE_TRANSLATIONAL", name="revolute_translational", rows=1,
              equations="n_i . (P_j - P_i) = 0",
              settings=(JointSetting(name="axis", meaning="line direction (ux, uy) in the first body's frame",
                                     unit="direction"),),
              example="revolute_translational(a (p), b (p), axis = ...)"),
    JointSpec(code=5, enum="BEAM_SLOPE", name="beam_slope", rows=1,
              equations="n_i . r'_j = 0: the slope r'_j of a beam's node along the axis of body i (n_i its normal)",
              settings=(JointSetting(name="axis", meaning="the slope's direction (ux, uy) in the first body's frame",
                                     unit="direction"),),
              moment=True, example="beam_slope(a, rod (start), axis = (1, 0))"),
)


def joint_param_columns() -> tuple[str, ...]:
    """The columns of the model's ``joint_param``: every setting's column, in order of first use."""
    cols: list[str] = []
    for spec in JOINTS:
        cols += [s.column for s in spec.settings if s.column and s.column not in cols]
    return tuple(cols)


@dataclass(frozen=True, kw_only=True)
class BeamSpec:
    """A flexible body of the language (`body NAME = beam { ... }`): its element, formulas and fields."""

    name: str
    title: str
    coordinates: str
    energy: str
    fields: dict[str, str]
    reference: str
    example: str


BEAM = BeamSpec(
    name="beam", title="planar ANCF cable element (thin beam: no shear, exact large rotations)",
    coordinates="per node (x, y, dx/ds, dy/ds); cubic Hermite shape functions; constant consistent mass",
    energy="EA/2 int eps^2 ds + EI/2 int kappa^2 ds, eps = (r'.r' - 1)/2, kappa = (x'y'' - y'x'')/|r'|^3 "
           "(5 Gauss points per element); damping: eta times the rates of both",
    fields={"length": "length of the centre line", "start": "(x, y) of its first end (default (0, 0))",
            "angle": "direction of the straight beam at the start (default 0)",
            "elements": "number of elements (default 8)",
            "section": "rectangle(width, height) (height in the plane of motion) | circle(radius)",
            "area": "cross-section area A (instead of section)",
            "second_moment": "second moment of area I (with area)",
            "material": "a material with E and density", "E": "Young's modulus (instead of material)",
            "density": "density (with E)",
            "damping": "time constant eta of the stiffness-proportional material damping (default 0)",
            "velocity": "initial velocity (vx, vy) of its start", "omega": "initial angular velocity about its start"},
    reference='Gerstmayr & Shabana, "Analysis of thin beams and cables using the absolute nodal co-ordinate '
              'formulation", Nonlinear Dynamics 45 (2006)',
    example="body rod = beam { length = 0.3 m  section = rectangle(10 mm, 5 mm)  material = steel  elements = 8 }")


# the clearance joint is a force element, not a constraint: its name is a joint type of the language
CLEARANCE_JOINT = "clearance_revolute"

# ------------------------------------------------------------------ contact elements
# Force elements written as joints (`joint NAME = TYPE(a (p), b (p)) { ... }`), compiled into one or more
# contact *pairs*; each pair is a geometry (`kernel/contact.py` computes its penetration, normal, slip and
# contact points) with a contact law, friction and its own located onsets (kernel/events.py).


@dataclass(frozen=True)
class PairSpec:
    """A contact geometry of the kernel: what touches what on the first body i and the second body j."""

    code: int  # clearance_param[k, CP_KIND]
    enum: str
    name: str
    penetration: str  # the event function delta (> 0: touching)


PAIRS: tuple[PairSpec, ...] = (
    PairSpec(0, "CIRCLE_IN_CIRCLE", "circle_in_circle",
             "delta = |P_j - P_i| - (R_i - R_j): a journal (circle) in a bearing (cavity)"),
    PairSpec(1, "LUBRICATED", "lubricated",
             "delta = |P_j - P_i| - eps_b c: the film breaks down at eccentricity ratio eps_b"),
    PairSpec(2, "CIRCLE_ON_LINE", "circle_on_line",
             "delta = R_j - (P_j - P_i) . m_i: a circle (R_j = 0: a point) against the line through P_i "
             "with outward normal m_i"),
    PairSpec(3, "CIRCLE_ON_CIRCLE", "circle_on_circle", "delta = R_i + R_j - |P_j - P_i|: two circles from outside"),
)


@dataclass(frozen=True)
class ElementSpec:
    """A contact element of the language: ``name`` as a joint type, the pairs it compiles into
    (``parts``: the suffix of each pair's signal entity, "" = the element's own name), the
    settings it takes besides those of every contact element (law, friction, materials)."""

    name: str
    pair: str  # PairSpec name (the `contact` element's `shape` chooses among several)
    parts: tuple[str, ...]
    summary: str
    fields: dict[str, str]
    reference: str
    example: str


ELEMENTS: tuple[ElementSpec, ...] = (
    ElementSpec("clearance_revolute", "circle_in_circle", ("",), "dry revolute clearance joint",
                {"clearance": "c = R_B - R_J", "bearing_radius": "R_B", "journal_radius": "R_J",
                 "length": "bearing length"},
                "Muvengei, Kihiu & Ikua, eqs. 3-16", "clearance_revolute(a (p), b (p)) { ... }"),
    ElementSpec("lubricated_revolute", "lubricated", ("",),
                "short journal bearing: hydrodynamic film force (wedge and squeeze), dry contact past "
                "the breakdown eccentricity ratio",
                {"clearance": "c = R_B - R_J", "bearing_radius": "R_B", "journal_radius": "R_J",
                 "length": "bearing length L", "viscosity": "dynamic viscosity mu of the oil",
                 "breakdown": "eccentricity ratio eps_b where the film breaks down (default 0.95)"},
                "Flores, Ambrosio, Claro & Lankarani, Mech. Mach. Theory 2006 (Pinkus & Sternlicht short bearing)",
                "lubricated_revolute(a (p), b (p)) { ... }"),
    ElementSpec("clearance_translational", "circle_on_line",
                ("rear_bottom", "rear_top", "front_bottom", "front_top"),
                "a block of `length` x `width` in a guide `clearance` wider: each corner against the guide "
                "surface on its side",
                {"axis": "guide direction (ux, uy) in the guide's frame", "clearance": "guide width - block width",
                 "length": "block length along the axis", "width": "block width",
                 "corner_radius": "radius of the block's rounded corners (default 0)",
                 "offset": "initial offset of the block's centre across the guide, along its left normal "
                           "(default: centred when the joint closes a loop, else as the pose states)",
                 "tilt": "initial angle of the block relative to the guide (default: as the bodies' angles state)",
                 "relative_velocity": "initial velocity of the block's centre across the guide, along its left "
                                      "normal (default: as the bodies' velocities state)",
                 "tilt_rate": "initial angular velocity of the block relative to the guide (default: as the "
                              "bodies' velocities state)"},
                "Flores, Ambrosio, Claro & Lankarani, Kinematics and Dynamics of Multibody Systems with "
                "Imperfect Joints (2008), ch. 5",
                "clearance_translational(guide (p), block (p), axis = (1, 0)) { ... }"),
    ElementSpec("contact", "circle_on_line", ("",),
                "contact between body outlines: `shape` = circle_on_line (a point when `radius = 0`), "
                "circle_on_circle (from outside) or circle_in_circle (a circle in a cavity)",
                {"shape": "circle_on_line | circle_on_circle | circle_in_circle",
                 "radius": "radius of the second body's circle (0: a point)",
                 "first_radius": "radius of the first body's circle or cavity",
                 "normal": "outward normal (nx, ny) of the first body's line, in its frame"},
                "Flores & Lankarani, Contact Force Models for Multibody Dynamics (2016)",
                "contact(a (p), b (p)) { shape = ... }"),
)
CONTACT_SHAPES = ("circle_on_line", "circle_on_circle", "circle_in_circle")


def pair(name: str) -> PairSpec:
    return _by_name(PAIRS, name, "contact geometry")


def element(name: str) -> ElementSpec:
    return _by_name(ELEMENTS, name, "contact element")

# ------------------------------------------------------------------ friction models


@dataclass(frozen=True)
class FrictionSetting:
    """A setting of a friction model: its name in a contact element, its unit kind (the compiler's
    unit table: "number", "velocity", "damping", "per_length", "time_per_length"), its default (None: required; a string: the value of
    that other setting) and what it means, with its symbol."""

    name: str
    unit: str
    default: float | str | None
    meaning: str


@dataclass(frozen=True, kw_only=True)
class FrictionSpec:
    """A friction model of the contact elements (`friction_model = NAME`; docs/contact.md, "Friction").

    ``stick``: the model holds a stuck contact by a stiff spring-damper to an anchor, with its slip and
    stick events located (kernel/events.py); without, the force is a function of the slip speed alone, or
    (``state``) of the slip speed and a state of the run that the integrator carries (LuGre's bristles)."""

    code: int  # FrictionModel value, clearance_param[k, CP_FRICTION_MODEL]
    enum: str
    name: str
    title: str
    formula: str
    settings: tuple[FrictionSetting, ...]
    stick: bool
    reference: str
    state: bool = False  # one state per contact element in the integrated state vector (the bristle z)


_MU = FrictionSetting("friction", "number", 0.0, "kinetic coefficient mu_k (0: frictionless)")
_MU_S = FrictionSetting("static_friction", "number", "friction", "static coefficient mu_s >= mu_k")
_STICK = (FrictionSetting("stick_stiffness", "number", 1.0,
                          "stiffness of a stuck contact along t as a multiple of the normal law's dF/dd "
                          "(Mindlin's ratio 2 (1 - nu)/(2 - nu) is 0.82 for steel)"),
          FrictionSetting("stick_damping", "number", 1.0,
                          "damping ratio zeta of the stuck contact's spring-damper (1: critical)"))
FRICTION_MODELS: tuple[FrictionSpec, ...] = (
    FrictionSpec(code=0, enum="AMBROSIO", name="ambrosio", title="Coulomb, Ambrósio's correction",
                 formula="F_T = -mu c_d(v) F_N sign(v), c_d = 0 below a slip speed v0, 1 above v1", stick=False,
                 settings=(_MU, FrictionSetting("friction_velocity", "velocity", 1e-4,
                                                "slip speed v0 below which friction is off"),
                           FrictionSetting("friction_velocity_full", "velocity", "2 friction_velocity",
                                           "slip speed v1 from which the full mu F_N acts")),
                 reference="Ambrósio, Impact of rigid and flexible multibody systems (2003)"),
    FrictionSpec(code=1, enum="COULOMB", name="coulomb", title="Coulomb with stick",
                 formula="stick: F_T = -(k_t s + c_t v) up to mu_s F_N; slip: F_T = -mu_k F_N sign(v)",
                 stick=True, settings=(_MU, _MU_S) + _STICK,
                 reference="Marques, Flores, Claro & Lankarani, Nonlinear Dyn 86 (2016)"),
    FrictionSpec(code=2, enum="STRIBECK", name="stribeck", title="Stribeck with stick",
                 formula="stick as coulomb; slip: F_T = -(mu_k + (mu_s - mu_k) exp(-(abs(v)/v_s)^d)) F_N "
                         "sign(v) - sigma_2 v", stick=True,
                 settings=(_MU, _MU_S, FrictionSetting("stribeck_velocity", "velocity", None,
                                                       "Stribeck velocity v_s"),
                           FrictionSetting("stribeck_exponent", "number", 2.0, "exponent d of the Stribeck curve"),
                           FrictionSetting("viscous_friction", "damping", 0.0, "viscous coefficient sigma_2"))
                 + _STICK,
                 reference="Marques, Flores, Claro & Lankarani, Nonlinear Dyn 86 (2016); Pennestri et al., "
                           "Nonlinear Dyn 83 (2016)"),
    FrictionSpec(code=3, enum="LUGRE", name="lugre", title="LuGre bristle model",
                 formula="dz/dt = v - sigma_0 abs(v) z / g(v), g(v) = mu_k + (mu_s - mu_k) exp(-(abs(v)/v_s)^d); "
                         "F_T = -F_N (sigma_0 z + sigma_1 dz/dt) - sigma_2 v, z a state of the run", stick=False, state=True,
                 settings=(_MU, _MU_S, FrictionSetting("stribeck_velocity", "velocity", None, "Stribeck velocity v_s"),
                           FrictionSetting("stribeck_exponent", "number", 2.0, "exponent d of the Stribeck curve"),
                           FrictionSetting("viscous_friction", "damping", 0.0, "viscous coefficient sigma_2"),
                           FrictionSetting("bristle_stiffness", "per_length", None,
                                           "bristle stiffness sigma_0 per unit normal force"),
                           FrictionSetting("bristle_damping", "time_per_length", 0.0,
                                           "bristle damping sigma_1 per unit normal force")),
                 reference="Canudas de Wit, Olsson, Astrom & Lischinsky, IEEE TAC 40 (1995)"),
)
FRICTION_UNIT_TEXT = {"number": "", "velocity": " m/s", "damping": " N*s/m", "per_length": " 1/m",
                      "time_per_length": " s/m"}  # as docs show a default
DEFAULT_FRICTION = "coulomb"  # a model that writes only `friction = 0.3` gets a contact that can stick


def friction_model(name: str) -> FrictionSpec:
    return _by_name(FRICTION_MODELS, name, "friction model")


def friction_settings() -> tuple[str, ...]:
    """Every setting of any friction model, each once, in order of first use."""
    return tuple(dict.fromkeys(s.name for m in FRICTION_MODELS for s in m.settings))


# ------------------------------------------------------------------ wear models


@dataclass(frozen=True)
class WearSetting:
    """A setting of a wear model (`wear = NAME(...)` on a revolute clearance joint): its name, unit kind
    ("number", "pressure", "time"), default (None: required) and meaning."""

    name: str
    unit: str
    default: float | None
    meaning: str


@dataclass(frozen=True, kw_only=True)
class WearSpec:
    """A wear model of a revolute clearance joint's bearing (docs/wear.md; run/wear.py runs it)."""

    name: str
    title: str
    formula: str
    settings: tuple[WearSetting, ...]
    reference: str


WEAR_MODELS: tuple[WearSpec, ...] = (
    WearSpec(name="archard", title="Archard's law, a Winkler pressure over the patch",
             formula="h' = (k / H) p v on the bearing's profile; profile updated every `update`, its wear x `factor`",
             settings=(WearSetting("coefficient", "number", None, "Archard's dimensionless wear coefficient k"),
                       WearSetting("hardness", "pressure", None, "hardness H of the bearing (k_d = k / H)"),
                       WearSetting("update", "time", None, "motion simulated per profile update (`2 rev / speed`)"),
                       WearSetting("factor", "number", 1.0, "cycles each update stands for per cycle simulated"),
                       WearSetting("updates", "number", 1.0, "profile updates of a wear run"),
                       WearSetting("nodes", "number", 360.0, "points of the profile on [0, 2 pi)"),
                       WearSetting("depth_step", "length", 0.0, "worn depth of the deepest node per update, "
                                   "instead of `factor` (0: off)")),
             reference="Archard, J. Appl. Phys. 24 (1953); Flores, Mech. Mach. Theory 44 (2009); "
                       "Mukras et al., Wear 268 (2010)"),
)


def wear_model(name: str) -> WearSpec:
    return _by_name(WEAR_MODELS, name, "wear model")


# ------------------------------------------------------------------ integrators


@dataclass(frozen=True)
class DenseRow:
    """One row of a continuous extension in Hairer's form (dopri5.f ``contd5``, dop853.f ``contd8``):
    ``F_r = dy (y1 - y0) + h sum_j k[j] k_j - prev F_(r-1)`` over the stages k_j of the step."""

    dy: float = 0.0
    k: tuple[float, ...] = ()
    prev: float = 0.0


@dataclass(frozen=True, kw_only=True)
class IntegratorSpec:
    """An explicit Runge-Kutta method of the time loop, as its Butcher tableau: the kernel
    (`kernel/integrators.py`) has one step, one error norm and one dense output for all of them.

    ``c``, ``a``: nodes and rows of A of every stage (``a[s]`` holds the s coefficients of stage s;
    stage 0 is f at the start of the step); ``b``: the solution's weights, whose length is the number
    of stages of a trial step; ``end_stage``: the stage holding f at the end of the step (FSAL: its row
    of A is ``b`` and its node 1; inside the trial step when ``len(b)`` exceeds it, else evaluated
    once the step is accepted); stages after it and after the trial step feed the dense output only
    (evaluated when a step needs it).  ``error``: weight rows of the embedded error estimate (b minus
    the embedded weights); ``error_rule``: how they make the error norm (``"rms"``: Hairer's DOPRI5
    norm of one row; ``"dop853"``: Hairer's DOP853 blend of a 5th- and a 3rd-order row; ``"none"``:
    fixed step); ``error_order``: order q of the estimate (step factor err^(-1/(q+1))).  ``dense``:
    ``"hermite"`` (the cubic through both ends and their derivatives), ``"rows"`` (Hairer's form with
    ``dense_rows``: y0 + x (F_0 + (1 - x) (F_1 + x (F_2 + ...)))) or ``"none"`` (the time loop then
    refuses the method: it writes outputs and finds events on the dense output)."""

    code: int  # Integrator value, cfg[CFG_METHOD]
    enum: str
    name: str  # as written in a .mbs file and on the command line
    order: int
    summary: str
    reference: str
    c: tuple[float, ...]
    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    end_stage: int
    error: tuple[tuple[float, ...], ...] = ()
    error_rule: str = "none"
    error_order: int = 0
    dense: str = "hermite"
    dense_rows: tuple[DenseRow, ...] = ()

    @property
    def stages(self) -> int:
        """Rows of the stage buffer ws.K it uses."""
        return len(self.c)

    @property
    def adaptive(self) -> bool:
        """Step size from the embedded error estimate (else the fixed ``step``)."""
        return self.error_rule != "none"


ERROR_RULES = ("none", "rms", "dop853")
DENSE_RULES = ("none", "hermite", "rows")


def _minus(x, y):
    return tuple(u - v for u, v in zip(x, y))


_DOPRI5_B = (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0)
_DOPRI5_BHAT = (5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40)
# Hairer's dense-output coefficients d_j (dopri5.f)
_DOPRI5_D = (-12715105075 / 11282082432, 0.0, 87487479700 / 32700410799, -10690763975 / 1880347072,
             701980252875 / 199316789632, -1453857185 / 822651844, 69997945 / 29380423)
# DOP853: Hairer's dop853.f as tabulated in SciPy (integrate/_ivp/dop853_coefficients.py, BSD-3)
_DOP853_C = (0.0, 0.05260015195876773, 0.0789002279381516, 0.1183503419072274, 0.2816496580927726,
             0.3333333333333333, 0.25, 0.3076923076923077, 0.6512820512820513, 0.6, 0.8571428571428571, 1.0,
             1.0, 0.1, 0.2, 0.7777777777777778)
_DOP853_A = (
    (),
    (0.05260015195876773,),
    (0.0197250569845379, 0.0591751709536137),
    (0.02958758547680685, 0.0, 0.08876275643042054),
    (0.2413651341592667, 0.0, -0.8845494793282861, 0.924834003261792),
    (0.037037037037037035, 0.0, 0.0, 0.17082860872947386, 0.12546768756682242),
    (0.037109375, 0.0, 0.0, 0.17025221101954405, 0.06021653898045596, -0.017578125),
    (0.03709200011850479, 0.0, 0.0, 0.17038392571223998, 0.10726203044637328, -0.015319437748624402,
     0.008273789163814023),
    (0.6241109587160757, 0.0, 0.0, -3.3608926294469414, -0.868219346841726, 27.59209969944671,
     20.154067550477894, -43.48988418106996),
    (0.47766253643826434, 0.0, 0.0, -2.4881146199716677, -0.590290826836843, 21.230051448181193,
     15.279233632882423, -33.28821096898486, -0.020331201708508627),
    (-0.9371424300859873, 0.0, 0.0, 5.186372428844064, 1.0914373489967295, -8.149787010746927,
     -18.52006565999696, 22.739487099350505, 2.4936055526796523, -3.0467644718982196),
    (2.273310147516538, 0.0, 0.0, -10.53449546673725, -2.0008720582248625, -17.9589318631188,
     27.94888452941996, -2.8589982771350235, -8.87285693353063, 12.360567175794303, 0.6433927460157636),
    (0.054293734116568765, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585,
     0.3111643669578199, -0.1521609496625161, 0.20136540080403034, 0.04471061572777259),
    (0.056167502283047954, 0.0, 0.0, 0.0, 0.0, 0.0, 0.25350021021662483, -0.2462390374708025,
     -0.12419142326381637, 0.15329179827876568, 0.00820105229563469, 0.007567897660545699, -0.008298),
    (0.03183464816350214, 0.0, 0.0, 0.0, 0.0, 0.028300909672366776, 0.053541988307438566, -0.05492374857139099,
     0.0, 0.0, -0.00010834732869724932, 0.0003825710908356584, -0.00034046500868740456, 0.1413124436746325),
    (-0.42889630158379194, 0.0, 0.0, 0.0, 0.0, -4.697621415361164, 7.683421196062599, 4.06898981839711,
     0.3567271874552811, 0.0, 0.0, 0.0, -0.0013990241651590145, 2.9475147891527724, -9.15095847217987),
)
_DOP853_E5 = (0.01312004499419488, 0.0, 0.0, 0.0, 0.0, -1.2251564463762044, -0.4957589496572502,
              1.6643771824549864, -0.35032884874997366, 0.3341791187130175, 0.08192320648511571,
              -0.022355307863886294)
_DOP853_E3 = (-0.18980075407240762, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003,
              -5.801203960010585, -0.4226823213237919, -0.1521609496625161, 0.20136540080403034,
              0.02265179219836082)
_DOP853_D = (
    (-8.428938276109013, 0.0, 0.0, 0.0, 0.0, 0.5667149535193777, -3.0689499459498917, 2.38466765651207,
     2.117034582445028, -0.871391583777973, 2.2404374302607883, 0.6315787787694688, -0.08899033645133331,
     18.148505520854727, -9.194632392478356, -4.436036387594894),
    (10.427508642579134, 0.0, 0.0, 0.0, 0.0, 242.28349177525817, 165.20045171727028, -374.5467547226902,
     -22.113666853125306, 7.733432668472264, -30.674084731089398, -9.332130526430229, 15.697238121770845,
     -31.139403219565178, -9.35292435884448, 35.81684148639408),
    (19.985053242002433, 0.0, 0.0, 0.0, 0.0, -387.0373087493518, -189.17813819516758, 527.8081592054236,
     -11.57390253995963, 6.8812326946963, -1.0006050966910838, 0.7777137798053443, -2.778205752353508,
     -60.19669523126412, 84.32040550667716, 11.99229113618279),
    (-25.69393346270375, 0.0, 0.0, 0.0, 0.0, -154.18974869023643, -231.5293791760455, 357.6391179106141,
     93.40532418362432, -37.45832313645163, 104.0996495089623, 29.8402934266605, -43.53345659001114,
     96.32455395918828, -39.17726167561544, -149.72683625798564),
)

INTEGRATORS: tuple[IntegratorSpec, ...] = (
    IntegratorSpec(
        code=0, enum="RK4", name="rk4", order=4, summary="classic 4-stage Runge-Kutta, fixed step",
        reference="Kutta (1901); Hairer, Norsett and Wanner, Solving ODEs I, Table II.1.2",
        c=(0.0, 0.5, 0.5, 1.0, 1.0),
        a=((), (0.5,), (0.0, 0.5), (0.0, 0.0, 1.0), (1 / 6, 1 / 3, 1 / 3, 1 / 6)),
        b=(1 / 6, 1 / 3, 1 / 3, 1 / 6), end_stage=4),
    IntegratorSpec(
        code=1, enum="DOPRI5", name="dopri5", order=5,
        summary="Dormand-Prince 5(4), adaptive, 4th-order dense output",
        reference="Dormand and Prince, A family of embedded Runge-Kutta formulae (1980); Hairer's dopri5.f",
        c=(0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0),
        a=((), (1 / 5,), (3 / 40, 9 / 40), (44 / 45, -56 / 15, 32 / 9),
           (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
           (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656), _DOPRI5_B[:6]),
        b=_DOPRI5_B, end_stage=6, error=(_minus(_DOPRI5_B, _DOPRI5_BHAT),), error_rule="rms", error_order=4,
        dense="rows", dense_rows=(DenseRow(dy=1.0), DenseRow(dy=-1.0, k=(1.0,)),
                                  DenseRow(dy=1.0, k=(0.0,) * 6 + (-1.0,), prev=1.0), DenseRow(k=_DOPRI5_D))),
    IntegratorSpec(
        code=2, enum="DOP853", name="dop853", order=8,
        summary="Dormand-Prince 8(5,3), adaptive, 7th-order dense output",
        reference="Prince and Dormand, High order embedded Runge-Kutta formulae (1981); Hairer's dop853.f",
        c=_DOP853_C, a=_DOP853_A, b=_DOP853_A[12], end_stage=12,
        error=(_DOP853_E5, _DOP853_E3), error_rule="dop853", error_order=7,
        dense="rows", dense_rows=(DenseRow(dy=1.0), DenseRow(dy=-1.0, k=(1.0,)),
                                  DenseRow(dy=2.0, k=(-1.0,) + (0.0,) * 11 + (-1.0,)),
                                  *(DenseRow(k=row) for row in _DOP853_D))),
    IntegratorSpec(
        code=3, enum="BS3", name="bs3", order=3,
        summary="Bogacki-Shampine 3(2), adaptive, cubic Hermite dense output",
        reference="Bogacki and Shampine, A 3(2) pair of Runge-Kutta formulas (1989)",
        c=(0.0, 1 / 2, 3 / 4, 1.0),
        a=((), (1 / 2,), (0.0, 3 / 4), (2 / 9, 1 / 3, 4 / 9)),
        b=(2 / 9, 1 / 3, 4 / 9, 0.0), end_stage=3,
        error=(_minus((2 / 9, 1 / 3, 4 / 9, 0.0), (7 / 24, 1 / 4, 1 / 3, 1 / 8)),), error_rule="rms",
        error_order=2),
)

# ------------------------------------------------------------------ force elements


@dataclass(frozen=True, kw_only=True)
class ForceSpec:
    """A force element: its description, read by the compiler, the run's checks and `set_load`.

    ``fill``: how the compiler reads it: "load" (one value on one body: `constant`, `torque`),
    "spring" (stiffness, damping, free value from the pose, an actuator that may be an expression),
    "expression" (one program per component) or "settings" (its `settings` alone, in order, one
    ``force_param`` column each: a new kind needs nothing else from the compiler).  ``bodies``: 1 or 2
    body references; ``points``: they take points.  ``columns``: what each ``force_param`` column holds
    (a ``<name>_program`` column holds 1 + the result row of an expression giving ``<name>``).
    ``potential``: ``kernel/forces.py``'s `force_potential` counts its energy; ``dissipative``: the
    columns that make it do work without a potential unless zero (a workless mechanism's energy check
    reads both).  ``settable``: the columns `Simulation.set_load` sets, in order.  ``signals``: the
    (quantity, unit) of each value its formula in ``kernel/forces.py``'s `force_element` reports
    (at most `N_FORCE_VALUES`, in order); every kind also records its power and work."""

    code: int  # ForceType value, the kernel's force code
    enum: str
    name: str  # as written in a .mbs file
    formula: str
    fill: str
    bodies: int = 1
    points: bool = True
    settings: tuple[JointSetting, ...] = ()
    columns: tuple[str, ...] = ()
    potential: bool = False
    dissipative: tuple[str, ...] = ()
    settable: tuple[str, ...] = ()
    signals: tuple[tuple[str, str], ...] = ()
    example: str = ""

    @property
    def fields(self) -> dict[str, str]:
        """The settings it takes, name -> meaning (the compiler's field table, the docs)."""
        return {x.name: x.meaning for x in self.settings}

    @property
    def param_columns(self) -> tuple[str, ...]:
        """The ``force_param`` columns, by name: `columns`, or one per setting."""
        return self.columns or tuple(x.name for x in self.settings)

    def column(self, name: str) -> int:
        return self.param_columns.index(name)

    def program_column(self, name: str) -> int | None:
        """The column of the expression that may give column `name`, or None."""
        cols = self.param_columns
        return cols.index(name + "_program") if name + "_program" in cols else None


FORCE_FILLS = ("load", "spring", "expression", "settings")


def _spring(code: int, enum: str, name: str, angle: bool) -> ForceSpec:
    """A translational or rotational spring-damper with an actuator (Nikravesh, "Computer-Aided
    Analysis of Mechanical Systems", sec. 4.9)."""
    free, unit = ("angle", "angle") if angle else ("length", "length")
    what = "torque" if angle else "force"
    return ForceSpec(
        code=code, enum=enum, name=name, fill="spring", bodies=2, points=not angle,
        formula=("T = k (a - a0) + c a' + t_act on a = phi_j - phi_i" if angle else
                 "tension f = k (l - l0) + c l' + f_act between P_i and P_j"),
        settings=(JointSetting(name="stiffness", meaning="N*m/rad" if angle else "N/m",
                               unit="rot_stiffness" if angle else "stiffness", default=0.0),
                  JointSetting(name="damping", meaning="N*m*s/rad" if angle else "N*s/m",
                               unit="rot_damping" if angle else "damping", default=0.0),
                  JointSetting(name=free, meaning=f"free {free} (default: initial)", unit=unit, default="pose"),
                  JointSetting(name="actuator", meaning=f"actuator {what}" + (" (tension positive)" if not angle
                               else "") + ": a constant or an expression", unit=what, default=0.0)),
        columns=("stiffness", "damping", free, "actuator", "actuator_program"), potential=True,
        dissipative=("damping", "actuator", "actuator_program"), settable=("actuator",),
        signals=(("torque", "N*m"), ("angle", "rad"), ("rate", "rad/s")) if angle else
        (("force", "N"), ("length", "m"), ("rate", "m/s")),
        example=f"{name}(a (p), b (p))" if not angle else f"{name}(a, b)")


FORCES: tuple[ForceSpec, ...] = (
    ForceSpec(code=0, enum="CONSTANT_FORCE", name="constant", fill="load", formula="F = (fx, fy), global, at P",
              settings=(JointSetting(name="force", meaning="(fx, fy) in the global frame", unit="force"),),
              columns=("fx", "fy"), potential=True, settable=("fx", "fy"),
              signals=(("fx", "N"), ("fy", "N")), example="constant(a (p), force = (fx, fy))"),
    ForceSpec(code=1, enum="CONSTANT_TORQUE", name="torque", fill="load", formula="T on the body", points=False,
              settings=(JointSetting(name="torque", meaning="e.g. 2 N*m", unit="torque"),),
              columns=("torque",), potential=True, settable=("torque",),
              signals=(("torque", "N*m"),), example="torque(a, torque = T)"),
    _spring(2, "SPRING_DAMPER", "spring_damper", angle=False),
    _spring(3, "ROTATIONAL_SPRING_DAMPER", "rotational_spring_damper", angle=True),
    ForceSpec(code=4, enum="EXPRESSION", name="expression", fill="expression",
              formula="(fx, fy) global at P and a torque, expressions of t, params and signals",
              settings=(JointSetting(name="fx", meaning="force along global x: an expression of t, params and "
                                     "signals", unit="force"),
                        JointSetting(name="fy", meaning="force along global y (the same)", unit="force"),
                        JointSetting(name="torque", meaning="torque on the body (the same)", unit="torque")),
              columns=("fx_program", "fy_program", "torque_program"),
              signals=(("fx", "N"), ("fy", "N"), ("torque", "N*m")), example="expression(a (p), fx = ...)"),
)
N_FORCE_PARAM = max(len(s.param_columns) for s in FORCES)  # force_param columns
N_FORCE_VALUES = 3  # values a force element reports (`ForceSpec.signals`), besides its power and work


def force_kind(code: int) -> ForceSpec:
    """The force element with kernel code `code`; an unknown code is an error, never a default."""
    if isinstance(code, bool) or not 0 <= int(code) < len(FORCES) or FORCES[int(code)].code != int(code):
        raise ValueError(f"unknown force kind {code!r}: the catalog has {choices(FORCES)}")
    return FORCES[int(code)]


# ------------------------------------------------------------------ drivers


@dataclass(frozen=True, kw_only=True)
class DriverSpec:
    """A driver: one constraint row g(q) - f(t) = 0 on a coordinate of the driven body."""

    code: int  # DriverType value
    enum: str
    name: str  # as written in a .mbs file
    equation: str


@dataclass(frozen=True, kw_only=True)
class MotionSpec:
    """A prescribed motion f(t) of a driver, its parameters in ``driver_motion_param``."""

    code: int  # MotionType value
    enum: str
    name: str  # as written in a .mbs file ("" for the motion written as `speed = ...`)
    formula: str


DRIVERS: tuple[DriverSpec, ...] = (
    DriverSpec(code=0, enum="ANGLE", name="rotation", equation="g = phi_j - phi_i (i = ground: phi_j)"),
    DriverSpec(code=1, enum="POSITION", name="translation", equation="g = u_i . (P_j - P_i)"),
)
MOTIONS: tuple[MotionSpec, ...] = (
    MotionSpec(code=0, enum="CONSTANT_SPEED", name="speed", formula="f = p0 + p1 t"),
    MotionSpec(code=1, enum="RAMP", name="ramp",
               formula="speed 0 -> p1 over p2 s: f = p0 + p1 t^2/(2 p2), then p0 + p1 (t - p2/2)"),
    MotionSpec(code=2, enum="HARMONIC", name="harmonic", formula="f = p0 + p1 sin(2 pi p2 t + p3)"),
    MotionSpec(code=3, enum="POLYNOMIAL", name="polynomial", formula="f = sum_k p_k t^k, k = 0..7"),
    MotionSpec(code=4, enum="EXPRESSION", name="expression",
               formula="f = program p0 of t (exact f', f'' by dual numbers)"),
)
N_MOTION_PARAM = 8  # driver_motion_param columns: the polynomial's coefficients, the most any motion takes

# ------------------------------------------------------------------ lookups


def law(name: str) -> LawSpec:
    return _by_name(LAWS, name, "contact law")


def joint(name: str) -> JointSpec:
    return _by_name(JOINTS, name, "joint type")


def integrator(name: str) -> IntegratorSpec:
    return _by_name(INTEGRATORS, name, "integrator")


def _by_name(table, name, what):
    for spec in table:
        if spec.name == str(name).lower():
            return spec
    raise ValueError(f"unknown {what} `{name}`; choose {choices(table)}")


def names(table) -> list[str]:
    return [spec.name for spec in table]


def choices(table) -> str:
    """'a, b or c' for messages and help texts."""
    n = names(table)
    return n[0] if len(n) == 1 else ", ".join(n[:-1]) + " or " + n[-1]


def _check_tableau(s: IntegratorSpec) -> None:
    """An integrator's tableau has the shape the kernel reads (its order conditions are tested)."""
    def pad(row):
        return tuple(row) + (0.0,) * (s.stages - len(row))

    assert len(s.a) == s.stages and all(len(row) == i for i, row in enumerate(s.a)) and s.c[0] == 0.0
    assert 1 <= len(s.b) <= s.stages and 0 < s.end_stage < s.stages, s.name
    assert pad(s.a[s.end_stage]) == pad(s.b) and s.c[s.end_stage] == 1.0, f"{s.name}: end stage is f(t + h, y1)"
    assert s.error_rule in ERROR_RULES and s.dense in DENSE_RULES, s.name
    assert len(s.error) == {"none": 0, "rms": 1, "dop853": 2}[s.error_rule], s.name
    assert all(len(row) == len(s.b) for row in s.error) and (s.error_order > 0) == s.adaptive, s.name
    assert bool(s.dense_rows) == (s.dense == "rows") and all(len(r.k) <= s.stages for r in s.dense_rows)
    assert s.dense == "rows" or s.stages == max(len(s.b), s.end_stage + 1), f"{s.name}: stages nothing reads"


def _check_force(s: ForceSpec) -> None:
    """A force kind is one the compiler can read and the checks can classify."""
    assert s.fill in FORCE_FILLS and s.bodies in (1, 2), s.name
    cols = s.param_columns
    assert len(set(cols)) == len(cols) and set(s.dissipative) | set(s.settable) <= set(cols), s.name
    assert s.fill != "settings" or not s.columns, f"{s.name}: a settings force stores its settings, in order"
    assert len(s.signals) <= N_FORCE_VALUES and all(q not in ("power", "work") for q, _ in s.signals), s.name


def _check_joint(s: JointSpec) -> None:
    """A joint type's settings are ones the compiler can read and store."""
    assert s.rows >= 1 and s.draw in ("pin", "link", "slide") and s.friction in ("", "torque", "force"), s.name
    assert not s.friction or {"friction", "static_friction"} <= {x.name for x in s.settings}, s.name
    directions = [x for x in s.settings if x.unit == "direction"]
    assert len(directions) <= 1 and not any(x.column or x.default is not None for x in directions), \
        f"{s.name}: one direction at most, stored in joint_axis"
    assert s.draw != "slide" or directions, f"{s.name}: a sliding joint is drawn along its direction"
    assert len({x.name for x in s.settings}) == len(s.settings), f"{s.name}: setting names must be unique"
    for x in s.settings:
        assert x.unit == "direction" or re.fullmatch(r"[a-z_][a-z0-9_]*", x.column), f"{s.name}.{x.name}: no column"
        assert (x.default is None or isinstance(x.default, (int, float)) or x.default in SETTING_DEFAULTS
                or x.default in [y.name for y in s.settings[:s.settings.index(x)]]), f"{s.name}.{x.name}: default"
        assert x.default != "pose" or x.unit in ("angle", "length"), f"{s.name}.{x.name}: no value in the pose"
    units = {}
    for spec in JOINTS:
        for x in spec.settings:
            assert units.setdefault(x.column, x.unit) == x.unit, f"column {x.column} holds one kind of value"


def check() -> None:
    """The tables are consistent: codes 0..n-1 in order, names unique."""
    for table in (LAWS, JOINTS, INTEGRATORS, PAIRS, FORCES, DRIVERS, MOTIONS, FRICTION_MODELS):
        assert [s.code for s in table] == list(range(len(table))), "codes must be 0..n-1 in order"
        assert len(set(names(table))) == len(table), "names must be unique"
        assert len({s.enum for s in table}) == len(table), "enum names must be unique"
    for s in JOINTS:
        _check_joint(s)
    for s in FORCES:
        _check_force(s)
    for s in INTEGRATORS:
        _check_tableau(s)
    for g in LAW_GROUPS:
        assert set(g.needs) <= set(g.takes) and set(g.one_of) <= set(g.takes), g.name
    assert DEFAULT_FRICTION in names(FRICTION_MODELS)
    assert ELEMENTS[0].name == CLEARANCE_JOINT and {e.pair for e in ELEMENTS} <= set(names(PAIRS))


check()

# ------------------------------------------------------------------ generated docs lists
# docs/language.md holds each list between `<!-- catalog:KEY -->` and `<!-- /catalog -->`


def _code(words) -> str:
    return ", ".join(f"`{w}`" for w in words)


def docs_lists() -> dict[str, str]:
    """The generated blocks of docs/language.md, by key."""
    joints = "\n".join(f"| `{s.example or s.name + '(a (p), b (p))'}` | {s.rows} | {s.equations} | "
                       + ("; ".join(f"`{k}`: {v}" for k, v in s.fields.items()) or "—") + " |" for s in JOINTS)
    return {
        "joints": "| type | rows | equations (P = r + A s) | settings |\n| --- | --- | --- | --- |\n" + joints
                  + "".join(f"\n| `{e.example}` | 0 | — | a force element, below |" for e in ELEMENTS),
        "laws": "| law | group | normal force | reference |\n| --- | --- | --- | --- |\n" + "\n".join(
            f"| `{s.name}` | {s.group.name} | {s.formula} | {s.reference} |" for s in LAWS),
        "law_groups": "\n".join(
            f"* {g.name} ({_code(s.name for s in LAWS if s.group is g) or 'none'}): {g.summary}; takes "
            f"{_code(g.takes)}" + (f", needs {_code(g.needs)}" if g.needs else "")
            + (f", needs one of {_code(g.one_of)}" if g.one_of else "") for g in LAW_GROUPS),
        "integrators": "| integrator | order | stages | step |\n| --- | --- | --- | --- |\n" + "\n".join(
            f"| `{s.name}` | {s.order} | {s.stages} | {s.summary} |" for s in INTEGRATORS),
        "friction": "| model | formula | settings |\n| --- | --- | --- |\n" + "\n".join(
            f"| `{m.name}` | {m.formula} | " + "; ".join(
                f"`{x.name}`: {x.meaning}" + ("" if x.default is None else f" (default {x.default}"
                                                   f"{FRICTION_UNIT_TEXT[x.unit]})")
                for x in m.settings) + " |" for m in FRICTION_MODELS),
        "wear": "| model | formula | settings |\n| --- | --- | --- |\n" + "\n".join(
            f"| `{m.name}` | {m.formula} | " + "; ".join(
                f"`{x.name}`: {x.meaning}" + ("" if x.default is None else f" (default {x.default:g})")
                for x in m.settings) + " |" for m in WEAR_MODELS),
        "beam": f"`{BEAM.example}`: the {BEAM.title} ({BEAM.reference}); {BEAM.coordinates}; energy "
                f"{BEAM.energy}.\n\n| field | meaning |\n| --- | --- |\n"
                + "\n".join(f"| `{k}` | {v} |" for k, v in BEAM.fields.items()),
        "forces": "| force | formula | settings | potential energy |\n| --- | --- | --- | --- |\n" + "\n".join(
            f"| `{s.example or s.name}` | {s.formula} | " + ("; ".join(f"`{k}`: {v}" for k, v in s.fields.items())
                                                          or "—") + f" | {'yes' if s.potential else 'no'} |"
            for s in FORCES),
    }


_BLOCK = re.compile(r"(<!-- catalog:(\w+) -->\n)(.*?)(<!-- /catalog -->)", re.S)


def render_docs(text: str) -> str:
    """`text` with every generated block replaced by the catalog's list."""
    lists = docs_lists()
    return _BLOCK.sub(lambda m: m.group(1) + lists[m.group(2)] + "\n" + m.group(4), text)


def doc_blocks(text: str) -> dict[str, str]:
    """The generated blocks as they stand in `text`."""
    return {m.group(2): m.group(3).rstrip("\n") for m in _BLOCK.finditer(text)}


if __name__ == "__main__":  # python -m planar_mbs.catalog --docs [docs/language.md]
    if sys.argv[1:2] == ["--docs"]:
        path = Path(sys.argv[2] if len(sys.argv) > 2 else Path(__file__).resolve().parents[1] / "docs" / "language.md")
        path.write_text(render_docs(path.read_text(encoding="utf-8")), encoding="utf-8")
        print(f"updated {path}")
    else:
        print("usage: python -m planar_mbs.catalog --docs [docs/language.md]")
