"""The catalog (planar_mbs/catalog.py) is the one description of contact laws, joint
types and integrators: everything else follows it.

The last tests add a dummy law, joint type and two integrators to a temporary copy of the
package -- their descriptions, plus the joint's constraint formula (a joint type
cannot be assembled without one); an integrator is its tableau alone -- and see them accepted
by `mbs check`, listed in `--help` and in the docs' generated lists, with no other file touched;
`mbs run` integrates an oscillator with the added Heun-Euler 2(1) against its closed form, and
refuses the added method that has no dense output.
"""
from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planar_mbs import catalog
from planar_mbs.errors import ModelError
from planar_mbs.mechanism.compile import compile_text, JOINT_FIELDS, JOINT_TYPES, LAW_SETTINGS, LAWS, SIM_FIELDS
from planar_mbs.kernel import contact, integrators, workspace
from planar_mbs.kernel.constraints import _JOINT_ROWS
from planar_mbs.mechanism.model import (
    CYLINDRICAL_LAWS, DISSIPATIVE_LAWS, JOINT_ROWS, N_JOINT_PARAM, ContactLaw, Integrator, JointType, frozen,
)
from planar_mbs.results.signals import MOMENT_JOINTS

ROOT = Path(__file__).resolve().parents[1]


def test_enums_and_kernel_constants_follow_the_catalog():
    assert [(m.name, int(m)) for m in ContactLaw] == [(s.enum, s.code) for s in catalog.LAWS]
    assert [(m.name, int(m)) for m in JointType] == [(s.enum, s.code) for s in catalog.JOINTS]
    assert [(m.name, int(m)) for m in Integrator] == [(s.enum, s.code) for s in catalog.INTEGRATORS]
    assert contact.N_LAWS == len(catalog.LAWS)
    assert [bool(contact.is_cylindrical(s.code)) for s in catalog.LAWS] == [s.cylindrical for s in catalog.LAWS]
    assert not contact.is_cylindrical(len(catalog.LAWS)) and not contact.is_cylindrical(-1)
    assert {int(x) for x in CYLINDRICAL_LAWS} == {s.code for s in catalog.LAWS if s.group is catalog.CYLINDRICAL}
    assert {int(x) for x in DISSIPATIVE_LAWS} == {s.code for s in catalog.LAWS if s.group is catalog.DISSIPATIVE}
    assert JOINT_ROWS.tolist() == _JOINT_ROWS.tolist() == [s.rows for s in catalog.JOINTS]
    assert {int(j) for j in MOMENT_JOINTS} == {s.code for s in catalog.JOINTS if s.moment}
    assert integrators.END_STAGE.tolist() == [s.end_stage for s in catalog.INTEGRATORS]
    assert workspace.N_STAGES == max(s.stages for s in catalog.INTEGRATORS)


def test_compiler_tables_follow_the_catalog():
    assert set(LAWS) == set(catalog.names(catalog.LAWS))
    assert {n: int(t) for n, t in JOINT_TYPES.items()} == {s.name: s.code for s in catalog.JOINTS}
    for s in catalog.JOINTS:
        assert JOINT_FIELDS[s.name] == s.fields
    assert LAW_SETTINGS == {k for g in catalog.LAW_GROUPS for k in g.takes}
    assert all(n in SIM_FIELDS["integrator"] for n in catalog.names(catalog.INTEGRATORS))


def test_every_joint_type_has_its_rows_in_the_kernel():
    """kernel/constraints.py has rows for each catalog joint type, with a setting in every column the
    catalog names (status 0, `rows` rows, each with a Jacobian); a code past the table is refused."""
    from kernel_models import build
    from planar_mbs.pykernel.constraints import constraint_eval, constraint_rows

    q, qd = np.array([0.1, 0.2, 0.3, 0.4, -0.1, 0.7]), np.array([0.5, -0.2, 1.0, 0.3, 0.1, -2.0])
    for spec in catalog.JOINTS:
        joint = dict(type=spec.code, bodies=(0, 1), points=((0.1, 0.05), (-0.2, 0.03)), axis=(0.6, 0.8))
        joint.update({s.column: 0.5 for s in spec.settings if s.column})
        km = build([(1.0, 0.1), (2.0, 0.2)], joints=[joint])
        m = constraint_rows(km)
        C, Ct, g, Cq = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros((m, 6))
        assert constraint_eval(km, q, qd, 0.0, C, Cq, Ct, g) == 0 and m == spec.rows, spec.name
        assert np.all(np.abs(Cq).sum(axis=1) > 0) and np.all(np.isfinite(g)), spec.name
    jt = km.joint_type.copy()
    jt[0] = len(catalog.JOINTS)
    km = frozen(km._replace(joint_type=jt))
    assert constraint_eval(km, q, qd, 0.0, C, Cq, Ct, g) == 7  # Status.BAD_INPUT


def test_every_law_has_its_formula_and_every_integrator_its_tableau_in_the_kernel():
    """kernel/contact.py gives each catalog law a positive force at a small penetration (and refuses a
    code past the table); the kernel's arrays hold each integrator's tableau as the catalog writes it."""
    from planar_mbs.mechanism import model as M

    p = np.zeros(M.N_CLEARANCE_PARAM)
    p[[M.CP_CLEARANCE, M.CP_R_BEARING, M.CP_R_JOURNAL, M.CP_LENGTH]] = 1e-4, 5e-3, 4.9e-3, 1e-2
    p[[M.CP_STIFFNESS, M.CP_EXPONENT, M.CP_RESTITUTION, M.CP_SIGMA_SUM]] = 1e9, 1.5, 0.8, 2 * 0.91 / 207e9
    for s in catalog.LAWS:
        F, st = contact.normal_force(s.code, p, 1e-7, 0.1, 0.5, 0.0)
        assert st == 0 and 0 < F < np.inf, s.name
    assert contact.normal_force(len(catalog.LAWS), p, 1e-7, 0.1, 0.5, 0.0)[1] == 7
    for s in catalog.INTEGRATORS:
        for i, row in enumerate(s.a):
            assert integrators.RK_A[s.code, i, :len(row)].tolist() == list(row), s.name
        assert integrators.RK_C[s.code, :s.stages].tolist() == list(s.c)
        assert integrators.RK_B[s.code, :len(s.b)].tolist() == list(s.b)
        assert [integrators.RK_E[s.code, r, :len(row)].tolist() for r, row in enumerate(s.error)] == \
            [list(row) for row in s.error]
        assert integrators.ADAPTIVE[s.code] == s.adaptive and integrators.END_STAGE[s.code] == s.end_stage
        assert integrators.method_ok(s.code) == (s.dense != "none"), s.name
    assert not integrators.method_ok(len(catalog.INTEGRATORS))


def test_joint_settings_are_read_as_the_catalog_describes_them():
    """Every setting's unit is a dimension the compiler checks (or a direction); each number lands in
    its column, its default from the pose; a setting that must be positive is refused at its place."""
    from planar_mbs.language import units as U
    from planar_mbs.mechanism.model import JP

    for spec in catalog.JOINTS:
        for s in spec.settings:
            assert s.unit == "direction" or isinstance(getattr(U, s.unit.upper()), U.Dim), (spec.name, s.name)
            assert s.unit == "direction" or s.column in JP
    base = """body a { mass = 1 kg  inertia = 1 kg*m^2  position = (0.3, 0.4)  angle = 20 deg }
body b { mass = 1 kg  inertia = 1 kg*m^2  position = (0, 0) }
"""
    k = compile_text(base + "joint L = revolute_revolute(a, b)\njoint W = weld(a, b)\n").kernel
    by_type = {int(t): row for t, row in zip(k.joint_type, k.joint_param)}
    assert by_type[JointType.REVOLUTE_REVOLUTE][JP["length"]] == pytest.approx(0.5)
    assert by_type[JointType.WELD][JP["phi0"]] == pytest.approx(-np.radians(20))
    assert compile_text(base + "joint L = revolute_revolute(a, b, length = 2 cm)").kernel.joint_param[0, JP["length"]] \
        == pytest.approx(0.02)
    with pytest.raises(ModelError, match="the length of joint `L` .* must be positive") as info:
        compile_text(base + "joint L = revolute_revolute(a, b, length = -2 cm)")
    assert info.value.line == 3 and info.value.source_line.index("-2 cm") == info.value.column - 1
    with pytest.raises(ModelError, match="the length of joint `L` .* must be positive") as info:
        compile_text(base + "joint L = revolute_revolute(a (0, 0), b (0.3, 0.4))")
    assert "coincide" in info.value.hint


def test_the_dissipative_laws_are_the_ones_the_kernel_damps():
    """The group says which laws need restitution; the kernel's chi is nonzero exactly for them."""
    for s in catalog.LAWS:
        chi = contact.damping_factor(s.code, 0.5)
        assert (chi > 0) == s.dissipative, s.name


def test_unknown_names_are_refused_with_the_choices():
    with pytest.raises(ValueError, match=catalog.choices(catalog.INTEGRATORS)):
        catalog.integrator("euler")
    with pytest.raises(ValueError, match="hertz"):
        catalog.law("hertzz")


def test_the_library_refuses_an_unknown_integrator_with_the_choices(tmp_path):
    import planar_mbs as mbs
    from planar_mbs.sweep.scan import parse_param, run_sweep

    model = mbs.load_model(ROOT / "models" / "slider_crank.mbs")
    with pytest.raises(ModelError, match="unknown integrator `dopri4`") as info:
        mbs.simulate(model, integrator="dopri4")
    assert "did you mean `dopri5`" in info.value.hint and catalog.choices(catalog.INTEGRATORS) in info.value.hint
    with pytest.raises(ModelError, match="unknown integrator `rk5`"):
        run_sweep(ROOT / "models" / "slider_crank.mbs", [parse_param("speed=600rpm")], tmp_path / "s.h5",
                  settings={"integrator": "rk5"}, jobs=1)
    assert mbs.simulate(model, integrator="DOP853", t_end=1e-3).attrs["complete"]


# ------------------------------------------------------------ adding from the descriptions alone
# Each addition follows docs/architecture.md, "How to add things": its description in catalog.py and its
# formula in the kernel file the recipe names (none for an integrator), nothing else.
# A dissipative law F = K d^n (1 + chi d'/d'(-)) with its own chi = 2 (1 - ce): its formula is that chi
DUMMY_LAW = ('    LawSpec(code=NEW, enum="SOFT_DUMMY", name="soft_dummy", title="Soft dummy", group=DISSIPATIVE,\n'
             '            formula="F = K d^n (1 + 2 (1 - ce) d\'/d\'(-))", reference="test"),\n')
DUMMY_LAW_CODE = ("SOFT_DUMMY = int(ContactLaw.SOFT_DUMMY)\n",
                  "    if law == SOFT_DUMMY:\n        return 2.0 * (1.0 - ce)\n")
# a gear pair with its own setting: phi_j = ratio phi_i (one row, the ratio in a new joint_param column)
DUMMY_JOINT = ('    JointSpec(code=NEW, enum="GEAR_DUMMY", name="gear_dummy", rows=1, equations="phi_j - ratio phi_i = 0",\n'
               '              settings=(JointSetting(name="ratio", meaning="phi_j / phi_i", unit="number",\n'
               '                                     column="ratio", default=1.0),),\n'
               '              example="gear_dummy(a (p), b (p))"),\n')
DUMMY_JOINT_CODE = ('GEAR_DUMMY = int(JointType.GEAR_DUMMY)\nRATIO = JP["ratio"]\n',
                    "    elif typ == GEAR_DUMMY:\n"
                    "        _, _, phi_i, _, _, _ = body_state(q, qd, bi)\n"
                    "        _, _, phi_j, _, _, _ = body_state(q, qd, bj)\n"
                    "        C[r] = phi_j - km.joint_param[jt, RATIO] * phi_i\n"
                    "        if bj >= 0:\n            J[r, 1, 2] += 1.0\n"
                    "        if bi >= 0:\n            J[r, 0, 2] -= km.joint_param[jt, RATIO]\n")
# Heun-Euler 2(1): Heun's method with Euler's as the embedded one, cubic Hermite dense output (the default)
DUMMY_INTEGRATOR = ('    IntegratorSpec(code=NEW, enum="HEUN_EULER_DUMMY", name="heun_euler_dummy", order=2,\n'
                    '        summary="a dummy method", reference="test", c=(0.0, 1.0, 1.0), a=((), (1.0,), (0.5, 0.5)),\n'
                    '        b=(0.5, 0.5), end_stage=2, error=((-0.5, 0.5),), error_rule="rms", error_order=1),\n'
                    '    IntegratorSpec(code=NEW + 1, enum="EULER_DUMMY", name="euler_dummy", order=1, summary="no dense output",\n'
                    '        reference="test", c=(0.0, 1.0), a=((), (1.0,)), b=(1.0,), end_stage=1, dense="none"),\n')
# linear drag on a body's centre, F = -c v: a force kind read from its settings alone (no potential)
DUMMY_FORCE = ('    ForceSpec(code=NEW, enum="DRAG_DUMMY", name="drag_dummy", fill="settings", points=False,\n'
               '              formula="F = -c v at the centre of mass",\n'
               '              settings=(JointSetting(name="coefficient", meaning="c", unit="damping"),)),\n')
DUMMY_FORCE_CODE = ("DRAG_DUMMY = int(ForceType.DRAG_DUMMY)\n",
                    "    elif typ == DRAG_DUMMY:\n"
                    "        if bi >= 0:\n"
                    "            Qe[3 * bi] -= p[0] * qd[3 * bi]\n"
                    "            Qe[3 * bi + 1] -= p[0] * qd[3 * bi + 1]\n")

MODEL = """
material steel { E = 207 GPa  nu = 0.3 }
body crank { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0.05, 0) }
body disc { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0.1, 0) }
body wheel { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0.3, 0) }
joint O = revolute(ground (0, 0), crank (-0.05, 0))
joint W = revolute(ground (0.3, 0), wheel)
joint G = gear_dummy(crank, wheel, ratio = -2)
joint A = clearance_revolute(crank (0.05, 0), disc) {
    clearance = 0.3 mm  bearing_radius = 5 mm  material = steel  law = soft_dummy  restitution = 0.9
}
simulate { t_end = 1 ms  integrator = heun_euler_dummy }
"""
# a disc on a torsion spring, pivoted at its centre: phi = PHI0 cos(OMEGA t), OMEGA = sqrt(k / I)
PHI0, OMEGA = 0.2, 10.0
OSCILLATOR = f"""
body disc {{ mass = 1 kg  inertia = 0.01 kg*m^2  position = (0, 0)  angle = {PHI0} rad }}
joint O = revolute(ground (0, 0), disc (0, 0))
force spring = rotational_spring_damper(ground, disc) {{ stiffness = {OMEGA ** 2 * 0.01} N*m/rad  angle = 0 deg }}
simulate {{ t_end = 1 s  integrator = heun_euler_dummy  rtol = 1e-6  atol = 1e-8  output_step = 10 ms }}
"""
# a driven gear pair: a torque T on the pinion (inertia I1), the wheel (I2) turned at `ratio` times its
# angle; from rest, (I1 + ratio^2 I2) phi1'' = T
T, I1, I2, RATIO = 2.0, 0.01, 0.04, -0.5
GEARS = f"""
body pinion {{ mass = 1 kg  inertia = {I1} kg*m^2  position = (0, 0) }}
body wheel {{ mass = 1 kg  inertia = {I2} kg*m^2  position = (0.3 m, 0) }}
joint P = revolute(ground (0, 0), pinion)
joint W = revolute(ground (0.3 m, 0), wheel)
joint G = gear_dummy(pinion, wheel, ratio = {RATIO})
force T = torque(pinion, torque = {T} N*m)
simulate {{ t_end = 0.2 s  output_step = 10 ms }}
"""
# a disc (no gravity) thrown at a floor, touching it with the dummy law at exponent 1 (a linear spring)
V0, CE, K_LIN = 0.5, 0.6, 1e6
IMPACT = f"""
body disc {{ mass = 1 kg  inertia = 1e-3 kg*m^2  position = (0, 11 mm)  velocity = (0, -{V0} m/s) }}
joint floor = contact(ground (0, 0), disc) {{
    shape = circle_on_line  normal = (0, 1)  radius = 10 mm  stiffness = {K_LIN} N/m  exponent = 1
    law = soft_dummy  restitution = {CE}
}}
simulate {{ t_end = 20 ms  rtol = 1e-10  atol = 1e-13  output_step = 1 ms }}
"""
# a puck (no gravity) thrown along x into linear drag: x = v0 m / c (1 - exp(-c t / m))
M_PUCK, V_PUCK, C_DRAG = 2.0, 3.0, 0.5
DRAG = f"""
body puck {{ mass = {M_PUCK} kg  inertia = 1e-3 kg*m^2  position = (0, 0)  velocity = ({V_PUCK} m/s, 0) }}
force air = drag_dummy(puck, coefficient = {C_DRAG} N*s/m)
simulate {{ t_end = 2 s  rtol = 1e-10  atol = 1e-12  output_step = 0.1 s }}
"""
TOUCHED: dict[str, set[str]] = {}  # each addition: the files of the package it edited


def _insert(pkg: Path, what: str, rel: str, anchor: str, new: str, after: bool = False) -> None:
    """Insert `new` before (or after) `anchor` in pkg/rel, recording the file as touched by `what`."""
    path = pkg / rel
    text = path.read_text(encoding="utf-8")
    assert text.count(anchor) == 1, f"anchor {anchor!r} of {rel} moved: update this test"
    text = text.replace(anchor, anchor + new if after else new + anchor)
    path.write_text(text, encoding="utf-8")
    TOUCHED.setdefault(what, set()).add(rel)


@pytest.fixture(scope="module")
def extended(tmp_path_factory):
    """A copy of the package with a dummy law, joint type (with its own setting) and integrator added."""
    tmp = tmp_path_factory.mktemp("extended")
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc")
    pkg = tmp / "planar_mbs"
    shutil.copytree(ROOT / "planar_mbs", pkg, ignore=ignore)
    (tmp / "docs").mkdir()
    shutil.copy(ROOT / "docs" / "language.md", tmp / "docs" / "language.md")
    TOUCHED.clear()
    _insert(pkg, "law", "catalog.py", ")\n\n# ------------------------------------------------------------------ joint types",
            DUMMY_LAW.replace("NEW", str(len(catalog.LAWS))))
    _insert(pkg, "law", "kernel/contact.py", "GONTHIER = int(ContactLaw.GONTHIER)\n", DUMMY_LAW_CODE[0], after=True)
    _insert(pkg, "law", "kernel/contact.py", "    return 0.0\n\n\n@kernel\ndef cylinder_scales", DUMMY_LAW_CODE[1])
    _insert(pkg, "joint", "catalog.py", ")\n\n\ndef joint_param_columns", DUMMY_JOINT.replace("NEW", str(len(catalog.JOINTS))))
    _insert(pkg, "joint", "kernel/constraints.py", 'LENGTH = JP["length"]\n', DUMMY_JOINT_CODE[0], after=True)
    _insert(pkg, "joint", "kernel/constraints.py", "    else:  # a type code without rows here", DUMMY_JOINT_CODE[1])
    _insert(pkg, "force", "catalog.py", ")\nN_FORCE_PARAM = ", DUMMY_FORCE.replace("NEW", str(len(catalog.FORCES))))
    _insert(pkg, "force", "kernel/forces.py", "EXPRESSION = int(ForceType.EXPRESSION)\n", DUMMY_FORCE_CODE[0],
            after=True)
    _insert(pkg, "force", "kernel/forces.py", "    else:\n        return BAD_INPUT\n    return 0\n",
            DUMMY_FORCE_CODE[1])
    _insert(pkg, "integrator", "catalog.py", ")\n\n# ------------------------------------------------------------------ force elements",
            DUMMY_INTEGRATOR.replace("NEW", str(len(catalog.INTEGRATORS))))
    for name, text in (("dummy", MODEL), ("oscillator", OSCILLATOR), ("gears", GEARS), ("impact", IMPACT),
                       ("drag", DRAG)):
        (tmp / f"{name}.mbs").write_text(text, encoding="utf-8")
    return tmp


def test_each_addition_touches_its_description_and_its_formula_only(extended):
    """The extension table of docs/architecture.md, measured: a law is catalog.py + kernel/contact.py, a
    joint type with its own setting catalog.py + kernel/constraints.py, an integrator catalog.py alone;
    and no other file of the copy differs from the package."""
    assert TOUCHED == {"law": {"catalog.py", "kernel/contact.py"},
                       "joint": {"catalog.py", "kernel/constraints.py"}, "integrator": {"catalog.py"},
                       "force": {"catalog.py", "kernel/forces.py"}}
    ours = ROOT / "planar_mbs"
    files = {p.relative_to(ours).as_posix() for p in ours.rglob("*") if p.is_file() and "__pycache__" not in p.parts
             and p.suffix not in (".pyc", ".nbi", ".nbc")}
    copied = {p.relative_to(extended / "planar_mbs").as_posix() for p in (extended / "planar_mbs").rglob("*")
              if p.is_file() and "__pycache__" not in p.parts and p.suffix not in (".pyc", ".nbi", ".nbc")}
    assert copied == files
    differ = {f for f in files if (ours / f).read_bytes() != (extended / "planar_mbs" / f).read_bytes()}
    assert differ == {"catalog.py", "kernel/contact.py", "kernel/constraints.py", "kernel/forces.py"}


def _mbs(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(tmp), "NUMBA_CACHE_DIR": str(tmp / "numba_cache"),
           "COLUMNS": "200", "NO_COLOR": "1"}
    code = ("import sys, planar_mbs; assert planar_mbs.__file__.startswith(sys.argv[1]), planar_mbs.__file__; "
            "sys.argv = ['mbs'] + sys.argv[2:]; from planar_mbs.cli.app import main; main()")
    return subprocess.run([sys.executable, "-c", code, str(tmp), *args], cwd=tmp, env=env, capture_output=True,
                          text=True, timeout=900)


def test_an_added_law_joint_and_integrator_are_accepted_by_mbs_check(extended):
    r = _mbs(extended, "check", "dummy.mbs")
    assert r.returncode == 0, r.stderr + r.stdout
    assert "gear_dummy" in r.stdout and "soft_dummy" in r.stdout
    with pytest.raises(ModelError, match="unknown joint type `gear_dummy`"):  # the package itself refuses them
        compile_text(MODEL)
    r = _mbs(extended, "check", "gears.mbs")
    assert r.returncode == 0, r.stderr + r.stdout
    bad = GEARS.replace(f"ratio = {RATIO}", "ratio = 2 m")
    (extended / "bad_gears.mbs").write_text(bad, encoding="utf-8")
    r = _mbs(extended, "check", "bad_gears.mbs")
    assert r.returncode == 2 and "bad_gears.mbs:6:" in r.stderr + r.stdout, r.stderr + r.stdout


def test_the_kernel_constants_of_the_copy_follow_its_catalog(extended):
    """No hand-kept count or column: the copy's kernel knows one law and joint type and two integrators
    more, and its model one joint_param column more (the gear's ratio)."""
    env = {**os.environ, "PYTHONPATH": str(extended), "NUMBA_CACHE_DIR": str(extended / "numba_cache")}
    code = ("from planar_mbs.kernel import contact, constraints, integrators; from planar_mbs.mechanism import model; "
            "print(contact.N_LAWS, len(constraints._JOINT_ROWS), len(integrators.END_STAGE), "
            "len(model.ContactLaw), len(model.JointType), len(model.Integrator), model.N_JOINT_PARAM, "
            "bool(contact.is_cylindrical.py_func(contact.N_LAWS - 1)))")
    r = subprocess.run([sys.executable, "-c", code], cwd=extended, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    nl, nj, ni = len(catalog.LAWS) + 1, len(catalog.JOINTS) + 1, len(catalog.INTEGRATORS) + 2
    assert r.stdout.split() == [str(nl), str(nj), str(ni), str(nl), str(nj), str(ni), str(N_JOINT_PARAM + 1),
                                "False"]


def test_an_added_law_joint_and_integrator_are_listed_in_help(extended):
    check = _mbs(extended, "check", "--help").stdout
    for name in ("soft_dummy", "gear_dummy", "heun_euler_dummy"):
        assert name in check
    assert "heun_euler_dummy" in _mbs(extended, "run", "--help").stdout
    assert "heun_euler_dummy" in _mbs(extended, "sweep", "--help").stdout


def test_an_added_law_joint_and_integrator_appear_in_the_generated_docs(extended):
    env = {**os.environ, "PYTHONPATH": str(extended)}
    doc = extended / "docs" / "language.md"
    r = subprocess.run([sys.executable, "-m", "planar_mbs.catalog", "--docs", str(doc)], env=env, cwd=extended,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    text = doc.read_text(encoding="utf-8")
    assert "| `soft_dummy` | dissipative |" in text
    assert "| `gear_dummy(a (p), b (p))` | 1 | phi_j - ratio phi_i = 0 | `ratio`: phi_j / phi_i |" in text
    assert "| `heun_euler_dummy` | 2 | 3 |" in text and "| `euler_dummy` | 1 | 2 |" in text
    # and nothing else of the page changed
    before = (ROOT / "docs" / "language.md").read_text(encoding="utf-8").splitlines()
    added = [line for line in text.splitlines() if line not in before]
    assert "| `drag_dummy` | F = -c v at the centre of mass | `coefficient`: c | no |" in text
    assert len(added) == 6 and all("dummy" in line for line in added), added  # 5 rows + the group line
    assert np.all([line in text.splitlines() for line in before if "dissipative (`" not in line])


def _run(tmp: Path, model: str, *args: str):
    from planar_mbs.results.hdf5 import read_results

    out = model.replace(".mbs", ".h5")
    r = _mbs(tmp, "run", model, "-o", out, "-q", *args)
    assert r.returncode == 0, r.stderr + r.stdout
    return read_results(tmp / out)


@pytest.mark.slow  # compiles the copy's time loop (about a minute of CPU)
def test_an_added_integrator_runs_end_to_end(extended):
    """`mbs run` with the added Heun-Euler 2(1), a tableau and nothing else: the oscillator follows its
    closed form, in the many steps of a 2nd-order method (h ~ sqrt(2 tol / |phi''|) ~ 1.4e-4 s: several
    thousand over 1 s, where DOPRI5 takes a few dozen); the added method without dense output is refused
    with the reason (exit 3), never run with another method's interpolant."""
    res = _run(extended, "oscillator.mbs")
    t, phi = res.time, res["disc.phi"]
    assert t[-1] == pytest.approx(1.0) and len(t) == 101
    assert np.max(np.abs(phi - PHI0 * np.cos(OMEGA * t))) < 1e-5
    assert res.attrs["n_steps"] > 2000
    r = _mbs(extended, "run", "oscillator.mbs", "--integrator", "euler_dummy", "-o", "e.h5", "-q")
    assert r.returncode == 3, r.stderr + r.stdout
    assert "`euler_dummy` has no dense output" in r.stderr + r.stdout


@pytest.mark.slow  # the copy's time loop (compiled once for the three runs)
def test_an_added_joint_with_its_own_setting_runs_end_to_end(extended):
    """`mbs run` on a gear pair of the added joint type: from rest under a torque T on the pinion,
    (I1 + ratio^2 I2) phi1'' = T (the wheel's inertia seen through the ratio), so phi1 = T t^2 / (2 I)
    and the wheel turns at `ratio` times it; the setting reached the kernel from the model file."""
    res = _run(extended, "gears.mbs")
    t = res.time
    phi1 = T * t ** 2 / (2 * (I1 + RATIO ** 2 * I2))
    assert t[-1] == pytest.approx(0.2) and phi1[-1] > 1.0
    np.testing.assert_allclose(res["pinion.phi"], phi1, atol=1e-7)
    np.testing.assert_allclose(res["wheel.phi"], RATIO * phi1, atol=1e-7)


@pytest.mark.slow  # the copy's time loop (compiled once for the three runs)
def test_an_added_law_runs_end_to_end(extended):
    """`mbs run` with the added law, F = K d (1 + chi d'/d'(-)) with chi = 2 (1 - ce): a single impact of
    such a law rebounds with the e that solves chi (1 + e) = ln((1 + chi)/(1 - chi e)) (m u du / (1 + chi u/v)
    = -K d^n dd integrated over the impact, whose right side vanishes from d = 0 back to 0), whatever K,
    n and the mass: here e = 0.648 for ce = 0.6."""
    from scipy.optimize import brentq

    chi = 2 * (1 - CE)
    e = brentq(lambda x: chi * (1 + x) - math.log((1 + chi) / (1 - chi * x)), 1e-6, 1 - 1e-12)
    res = _run(extended, "impact.mbs")
    assert res["floor.in_contact"].max() == 1 and res["floor.in_contact"][-1] == 0  # one impact, over
    assert res["disc.vy"][-1] == pytest.approx(e * V0, rel=1e-6)
    assert abs(e - CE) > 0.03  # the restitution setting alone would not give it


def test_contact_md_describes_every_law():
    """docs/contact.md's table (equations, parameters, where each law holds) has a row per law."""
    text = (ROOT / "docs" / "contact.md").read_text(encoding="utf-8")
    rows = {line.split("|")[1].strip().strip("`") for line in text.splitlines() if line.startswith("| `")}
    assert set(catalog.names(catalog.LAWS)) <= rows


@pytest.mark.slow  # the copy's time loop (compiled once for the runs of the copy)
def test_an_added_force_kind_runs_end_to_end(extended):
    """`mbs run` with the added force kind, read by the compiler from its catalog settings alone: a puck
    thrown into linear drag follows x = v0 m / c (1 - exp(-c t / m)); no energy warning (the kind has no
    potential, so the energy check does not count its mechanism as workless), and `mbs check` takes it."""
    res = _run(extended, "drag.mbs")
    t = res.time
    x = V_PUCK * M_PUCK / C_DRAG * (1 - np.exp(-C_DRAG * t / M_PUCK))
    assert t[-1] == pytest.approx(2.0) and x[-1] > 2.0
    np.testing.assert_allclose(res["puck.x"], x, atol=1e-8)
    assert not res.attrs["warnings"]
    r = _mbs(extended, "check", "drag.mbs")
    assert r.returncode == 0 and "3 degrees of freedom" in r.stdout, r.stderr + r.stdout


def test_an_unknown_force_kind_is_refused_never_defaulted():
    """A force code the catalog does not describe is refused before a run (a hand-built model), and a
    hand-built catalog entry with a way of reading it the compiler does not know fails the catalog's check;
    the run's checks read the catalog, so nothing falls into a default."""
    import dataclasses

    import planar_mbs as mbs
    from planar_mbs.mechanism.model import frozen

    with pytest.raises(ValueError, match="unknown force kind 99"):
        catalog.force_kind(99)
    model = compile_text("""body disc { mass = 1 kg  inertia = 1 kg*m^2  position = (0, 0) }
joint O = revolute(ground (0, 0), disc)
force T = torque(disc, torque = 1 N*m)
simulate { t_end = 1 ms }
""")
    km = model.kernel._replace(force_type=np.array([99], dtype=np.int64))
    bad = dataclasses.replace(model, kernel=frozen(km))
    with pytest.raises(ModelError, match="force `T`: unknown force kind 99"):
        mbs.simulate(bad)
    spec = dataclasses.replace(catalog.FORCES[1], fill="bogus")
    with pytest.raises(AssertionError):
        catalog._check_force(spec)
