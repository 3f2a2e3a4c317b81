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
    CYLINDRICAL_LAWS, DISSIPATIVE_LAWS, JOINT_ROWS, ContactLaw, Integrator, JointType,
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
DUMMY_LAW = ('    LawSpec(len(LAWS) + 0, "SOFT_DUMMY", "soft_dummy", "Soft dummy", ELASTIC, "F = K d^n", "test"),\n')
DUMMY_JOINT = ('    JointSpec(5, "PIN_DUMMY", "pin_dummy", 2, "P_i - P_j = 0", {}, example="pin_dummy(a (p), b (p))"),\n')
# Heun-Euler 2(1): Heun's method with Euler's as the embedded one, cubic Hermite dense output (the default)
DUMMY_INTEGRATOR = ('    IntegratorSpec(code=NEW, enum="HEUN_EULER_DUMMY", name="heun_euler_dummy", order=2,\n'
                    '        summary="a dummy method", reference="test", c=(0.0, 1.0, 1.0), a=((), (1.0,), (0.5, 0.5)),\n'
                    '        b=(0.5, 0.5), end_stage=2, error=((-0.5, 0.5),), error_rule="rms", error_order=1),\n'
                    '    IntegratorSpec(code=NEW + 1, enum="EULER_DUMMY", name="euler_dummy", order=1, summary="no dense output",\n'
                    '        reference="test", c=(0.0, 1.0), a=((), (1.0,)), b=(1.0,), end_stage=1, dense="none"),\n')

MODEL = """
material steel { E = 207 GPa  nu = 0.3 }
body crank { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0.05, 0) }
body disc { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0.1, 0) }
joint O = pin_dummy(ground (0, 0), crank (-0.05, 0))
joint A = clearance_revolute(crank (0.05, 0), disc) {
    clearance = 0.3 mm  bearing_radius = 5 mm  material = steel  law = soft_dummy
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


def _insert_before(text: str, anchor: str, new: str) -> str:
    assert anchor in text, f"anchor {anchor!r} moved: update this test"
    return text.replace(anchor, new + anchor, 1)


@pytest.fixture(scope="module")
def extended(tmp_path_factory):
    """A copy of the package with a dummy law, joint type and integrator added."""
    tmp = tmp_path_factory.mktemp("extended")
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc")
    pkg = tmp / "planar_mbs"
    shutil.copytree(ROOT / "planar_mbs", pkg, ignore=ignore)
    (tmp / "docs").mkdir()
    shutil.copy(ROOT / "docs" / "language.md", tmp / "docs" / "language.md")
    cat = (pkg / "catalog.py").read_text(encoding="utf-8")
    cat = _insert_before(cat, ")\n\n# ------------------------------------------------------------------ joint types",
                         DUMMY_LAW.replace("len(LAWS) + 0", str(len(catalog.LAWS))))
    cat = _insert_before(cat, ")\n# the clearance joint is a force element", DUMMY_JOINT.replace(
        "JointSpec(5", f"JointSpec({len(catalog.JOINTS)}"))
    n = len(catalog.INTEGRATORS)
    cat = _insert_before(cat, ")\n\n# ------------------------------------------------------------------ lookups",
                         DUMMY_INTEGRATOR.replace("NEW", str(n)))
    (pkg / "catalog.py").write_text(cat, encoding="utf-8")
    # the joint's formula: the revolute one (a joint type cannot be assembled without a formula)
    cons = (pkg / "kernel" / "constraints.py").read_text(encoding="utf-8")
    anchor = "if typ == REVOLUTE or typ == WELD:"
    assert anchor in cons, "constraints.py changed: update this test"
    cons = cons.replace(anchor, f"if typ == REVOLUTE or typ == WELD or typ == {len(catalog.JOINTS)}:", 1)
    (pkg / "kernel" / "constraints.py").write_text(cons, encoding="utf-8")
    (tmp / "dummy.mbs").write_text(MODEL, encoding="utf-8")
    (tmp / "oscillator.mbs").write_text(OSCILLATOR, encoding="utf-8")
    return tmp


def _mbs(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(tmp), "NUMBA_CACHE_DIR": str(tmp / "numba_cache"),
           "COLUMNS": "200", "NO_COLOR": "1"}
    code = ("import sys, planar_mbs; assert planar_mbs.__file__.startswith(sys.argv[1]), planar_mbs.__file__; "
            "sys.argv = ['mbs'] + sys.argv[2:]; from planar_mbs.cli.app import main; main()")
    return subprocess.run([sys.executable, "-c", code, str(tmp), *args], cwd=tmp, env=env, capture_output=True,
                          text=True, timeout=600)


def test_an_added_law_joint_and_integrator_are_accepted_by_mbs_check(extended):
    r = _mbs(extended, "check", "dummy.mbs")
    assert r.returncode == 0, r.stderr + r.stdout
    assert "pin_dummy" in r.stdout and "soft_dummy" in r.stdout
    with pytest.raises(ModelError, match="unknown joint type `pin_dummy`"):  # the package itself refuses them
        compile_text(MODEL)


def test_the_kernel_constants_of_the_copy_follow_its_catalog(extended):
    """No hand-kept count: the copy's kernel knows one law and joint type and two integrators more."""
    env = {**os.environ, "PYTHONPATH": str(extended), "NUMBA_CACHE_DIR": str(extended / "numba_cache")}
    code = ("from planar_mbs.kernel import contact, constraints, integrators; from planar_mbs.mechanism import model; "
            "print(contact.N_LAWS, len(constraints._JOINT_ROWS), len(integrators.END_STAGE), "
            "len(model.ContactLaw), len(model.JointType), len(model.Integrator), "
            "bool(contact.is_cylindrical.py_func(contact.N_LAWS - 1)))")
    r = subprocess.run([sys.executable, "-c", code], cwd=extended, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    nl, nj, ni = len(catalog.LAWS) + 1, len(catalog.JOINTS) + 1, len(catalog.INTEGRATORS) + 2
    assert r.stdout.split() == [str(nl), str(nj), str(ni), str(nl), str(nj), str(ni), "False"]


def test_an_added_law_joint_and_integrator_are_listed_in_help(extended):
    check = _mbs(extended, "check", "--help").stdout
    for name in ("soft_dummy", "pin_dummy", "heun_euler_dummy"):
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
    assert "| `soft_dummy` | elastic |" in text
    assert "| `pin_dummy(a (p), b (p))` | 2 |" in text
    assert "| `heun_euler_dummy` | 2 | 3 |" in text and "| `euler_dummy` | 1 | 2 |" in text
    # and nothing else of the page changed
    before = (ROOT / "docs" / "language.md").read_text(encoding="utf-8").splitlines()
    added = [line for line in text.splitlines() if line not in before]
    assert len(added) == 5 and all("dummy" in line for line in added), added  # 4 rows + the group line
    assert np.all([line in text.splitlines() for line in before if "elastic (`hertz`)" not in line])



@pytest.mark.slow  # compiles the copy's time loop (about a minute of CPU)
def test_an_added_integrator_runs_end_to_end(extended):
    """`mbs run` with the added Heun-Euler 2(1), a tableau and nothing else: the oscillator follows its
    closed form, in the many steps of a 2nd-order method (h ~ sqrt(2 tol / |phi''|) ~ 1.4e-4 s: several
    thousand over 1 s, where DOPRI5 takes a few dozen); the added method without dense output is refused
    with the reason (exit 3), never run with another method's interpolant."""
    from planar_mbs.results.hdf5 import read_results

    r = _mbs(extended, "run", "oscillator.mbs", "-o", "osc.h5", "-q")
    assert r.returncode == 0, r.stderr + r.stdout
    res = read_results(extended / "osc.h5")
    t, phi = res.time, res["disc.phi"]
    assert t[-1] == pytest.approx(1.0) and len(t) == 101
    assert np.max(np.abs(phi - PHI0 * np.cos(OMEGA * t))) < 1e-5
    assert res.attrs["n_steps"] > 2000
    r = _mbs(extended, "run", "oscillator.mbs", "--integrator", "euler_dummy", "-o", "e.h5", "-q")
    assert r.returncode == 3, r.stderr + r.stdout
    assert "`euler_dummy` has no dense output" in r.stderr + r.stdout

def test_contact_md_describes_every_law():
    """docs/contact.md's table (equations, parameters, where each law holds) has a row per law."""
    text = (ROOT / "docs" / "contact.md").read_text(encoding="utf-8")
    rows = {line.split("|")[1].strip().strip("`") for line in text.splitlines() if line.startswith("| `")}
    assert set(catalog.names(catalog.LAWS)) <= rows
