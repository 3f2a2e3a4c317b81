"""One description per contact law, joint type and integrator.

Everything else is derived from these three tables: the integer enums of
`model` (`ContactLaw`, `JointType`, `Integrator`) and their groups, the
kernel's constants (number of laws, rows per joint type, stage buffers), the
compiler's field tables and allowed law arguments, the CLI's choices and
tables, the signal names, how `rerun_log` draws a joint, and the generated
lists in docs/language.md (`python -m planar_mbs.catalog --docs` rewrites them;
a test checks they are in step).

Adding an element is writing its formula (the kernel: `kernel/contact.py` for a
law, `kernel/constraints.py` for a joint type, `kernel/integrators.py` and the
step branch of `kernel/loop.py` for an integrator) and appending its
description here with the next free code (docs/architecture.md, "How to add
things").  The descriptions are plain data, importable without numpy or numba.
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
    be given; ``compliance``: where the law's compliance comes from ("stiffness":
    K of F = K d^n, given or from the materials; "materials": sigma, the bearing
    length and the radii, no K)."""

    name: str
    takes: tuple[str, ...]
    needs: tuple[str, ...]
    compliance: str
    summary: str


ELASTIC = LawGroup("elastic", ("restitution", "stiffness", "exponent"), (), "stiffness",
                   "F = K d^n, no dissipation")
DISSIPATIVE = LawGroup("dissipative", ("restitution", "stiffness", "exponent"), ("restitution",), "stiffness",
                       "F = K d^n (1 + chi(ce) d'/d'(-)), clipped at F >= 0")
CYLINDRICAL = LawGroup("cylindrical", ("restitution",), (), "materials",
                       "implicit in F, from the materials, the bearing length and the radii")
LAW_GROUPS = (ELASTIC, DISSIPATIVE, CYLINDRICAL)


@dataclass(frozen=True)
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
    LawSpec(0, "HERTZ", "hertz", "Hertz", ELASTIC, "F = K d^n", "Hertz 1881; Muvengei et al. eq. 17"),
    LawSpec(1, "LANKARANI_NIKRAVESH", "lankarani_nikravesh", "Lankarani–Nikravesh", DISSIPATIVE,
            "F = K d^n (1 + 3 (1 - ce^2)/4 d'/d'(-))", "Lankarani & Nikravesh 1990; Muvengei et al. eq. 21"),
    LawSpec(2, "DUBOWSKY_FREUDENSTEIN", "dubowsky_freudenstein", "Dubowsky–Freudenstein", CYLINDRICAL,
            "d = A F (ln(B/F) + 1), B = L^3 c / (h R_B R_J)", "Dubowsky & Freudenstein 1971; Muvengei et al. eq. 22"),
    LawSpec(3, "ESDU_78035", "esdu78035", "ESDU-78035", CYLINDRICAL,
            "d = A F (ln(B/F) + 1), B = 4 L c / h", "ESDU 78035 (1978); Muvengei et al. eq. 23"),
    LawSpec(4, "HUNT_CROSSLEY", "hunt_crossley", "Hunt–Crossley", DISSIPATIVE,
            "F = K d^n (1 + 3 (1 - ce)/2 d'/d'(-))", "Hunt & Crossley 1975"),
    LawSpec(5, "FLORES", "flores", "Flores et al.", DISSIPATIVE,
            "F = K d^n (1 + 8 (1 - ce)/(5 ce) d'/d'(-))", "Flores, Machado, Silva & Martins 2011"),
    LawSpec(6, "GONTHIER", "gonthier", "Gonthier et al.", DISSIPATIVE,
            "F = K d^n (1 + (1 - ce^2)/ce d'/d'(-))", "Gonthier, McPhee, Lange & Piedboeuf 2004"),
)

# ------------------------------------------------------------------ joint types


@dataclass(frozen=True)
class JointSpec:
    """An ideal joint: ``rows`` constraint equations between two bodies.

    ``fields``: the settings it takes (name -> meaning).  The compiler fills them
    by name: ``axis`` -> joint_axis (unit, first body's frame), ``angle`` ->
    JP_PHI0 (default: the initial relative angle), ``length`` -> JP_LENGTH
    (default: the initial distance of the points).  ``moment``: it locks the
    relative rotation, so its reaction has a moment signal.  ``draw``: "pin"
    (a pin at the joint point), "link" (its points join the body outlines, no
    pin) or "slide" (a sliding body: drawn as a box along the axis, with a guide
    when one side is ground; no outline point).  ``slider``: a body tied to
    ground by it is "the slider" (Poincaré section, slider plots)."""

    code: int  # JointType value, the kernel's joint code
    enum: str
    name: str  # as written in a .mbs file
    rows: int
    equations: str
    fields: dict[str, str] = field(default_factory=dict)
    moment: bool = False
    draw: str = "pin"
    slider: bool = False
    example: str = ""  # the call as docs/language.md shows it


_AXIS = "sliding axis (ux, uy) in the first body's frame"
_ANGLE = "relative angle kept (default: from the initial pose)"
JOINTS: tuple[JointSpec, ...] = (
    JointSpec(0, "REVOLUTE", "revolute", 2, "P_i - P_j = 0", {}, example="revolute(a (p), b (p))"),
    JointSpec(1, "TRANSLATIONAL", "translational", 2, "phi_j - phi_i - phi0 = 0;  n_i . (P_j - P_i) = 0",
              {"axis": _AXIS, "angle": _ANGLE}, moment=True, draw="slide", slider=True,
              example="translational(a (p), b (p), axis = (ux, uy))"),
    JointSpec(2, "WELD", "weld", 3, "P_i - P_j = 0;  phi_j - phi_i - phi0 = 0", {"angle": _ANGLE}, moment=True,
              example="weld(a (p), b (p))"),
    JointSpec(3, "REVOLUTE_REVOLUTE", "revolute_revolute", 1, "((P_j - P_i).(P_j - P_i) - L^2) / 2 = 0",
              {"length": "link length (default: from the initial pose)"}, draw="link",
              example="revolute_revolute(a (p), b (p))"),
    JointSpec(4, "REVOLUTE_TRANSLATIONAL", "revolute_translational", 1, "n_i . (P_j - P_i) = 0",
              {"axis": "line direction (ux, uy) in the first body's frame"},
              example="revolute_translational(a (p), b (p), axis = ...)"),
)
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
                 "corner_radius": "radius of the block's rounded corners (default 0)"},
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

# ------------------------------------------------------------------ integrators


@dataclass(frozen=True)
class IntegratorSpec:
    """An explicit Runge-Kutta method of the time loop.

    ``stages``: rows of the stage buffer ws.K it uses; ``end_stage``: the row
    holding f at the end of an accepted step (FSAL); ``dense_rows``: rows of the
    dense-output coefficient buffer ws.F (0 = Hermite or built-in dense output);
    ``adaptive``: step size from an embedded error estimate (else fixed
    ``step``); ``error_order``: order q of that estimate (step factor err^(-1/(q+1)))."""

    code: int  # Integrator value, cfg[CFG_METHOD]
    enum: str
    name: str  # as written in a .mbs file and on the command line
    order: int
    stages: int
    end_stage: int
    dense_rows: int
    adaptive: bool
    error_order: int
    summary: str


INTEGRATORS: tuple[IntegratorSpec, ...] = (
    IntegratorSpec(0, "RK4", "rk4", 4, 5, 4, 0, False, 0, "classic 4-stage Runge-Kutta, fixed step"),
    IntegratorSpec(1, "DOPRI5", "dopri5", 5, 7, 6, 0, True, 4,
                   "Dormand-Prince 5(4), adaptive, 4th-order dense output"),
    IntegratorSpec(2, "DOP853", "dop853", 8, 16, 12, 7, True, 7,
                   "Dormand-Prince 8(5,3), adaptive, 7th-order dense output"),
)

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


def check() -> None:
    """The tables are consistent: codes 0..n-1 in order, names unique."""
    for table in (LAWS, JOINTS, INTEGRATORS, PAIRS):
        assert [s.code for s in table] == list(range(len(table))), "codes must be 0..n-1 in order"
        assert len(set(names(table))) == len(table), "names must be unique"
        assert len({s.enum for s in table}) == len(table), "enum names must be unique"
    for s in JOINTS:
        assert s.rows >= 1 and s.draw in ("pin", "link", "slide")
        assert s.draw != "slide" or "axis" in s.fields, "a sliding joint is drawn along its axis"
        assert set(s.fields) <= {"axis", "angle", "length"}, "the compiler fills axis, angle and length"
    for s in INTEGRATORS:
        assert 0 <= s.end_stage < s.stages
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
            f"{_code(g.takes)}" + (f", needs {_code(g.needs)}" if g.needs else "") for g in LAW_GROUPS),
        "integrators": "| integrator | order | stages | step |\n| --- | --- | --- | --- |\n" + "\n".join(
            f"| `{s.name}` | {s.order} | {s.stages} | {s.summary} |" for s in INTEGRATORS),
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
