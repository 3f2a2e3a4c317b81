"""Any number of clearance joints, each with its own law, through the whole pipeline
(.mbs text -> compiler -> kernel -> named signals): every shipped clearance model runs with
every contact law, and with two clearance joints each joint reports its own signals."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs import catalog
from planar_mbs.errors import ModelError
from planar_mbs.mechanism.model import CONTACT_LAW_NAMES, ContactLaw

MODELS = Path(__file__).resolve().parent.parent / "models"
# shipped clearance models: (file, clearance joints, short t_end covering the first impacts)
SHIPPED = [
    ("slider_crank_clearance_a.mbs", ["A"], 2e-3),
    ("slider_crank_clearance_b.mbs", ["B"], 2e-3),
    ("slider_crank_clearance_ab.mbs", ["A", "B"], 2e-3),
    ("four_bar_clearance.mbs", ["B"], 5e-3),
    # chaotic from its start (docs/numerics.md): from about 3.4 ms a rounding-level change
    # (rtol 9e-7 instead of 1e-6, or the order of a sum in the multiplier solve) decides
    # whether O4's next impact passes the Dubowsky-Freudenstein law's deepest penetration
    # (no force solves it: the run stops, naming O4); the first impacts come before that
    ("four_bar_two_clearances.mbs", ["B", "O4"], 3e-3),
]
# every law that takes the models' stiffness (eq. 18 from their materials, N/m^1.5); Kelvin-Voigt's is linear
LAWS = [s.name for s in catalog.LAWS if s.group is not catalog.LINEAR]
CLEARANCE_QUANTITIES = ["ex", "ey", "e", "penetration", "contact_force", "fx", "fy", "in_contact",
                        "impact_velocity"]


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("name, joints, t_end", SHIPPED)
def test_shipped_model_runs_with_every_law(name, joints, t_end, law):
    model = mbs.load_model(MODELS / name, law=law)
    assert model.clearance_names == joints
    assert all(int(code) == ContactLaw[_enum_name(law)] for code in model.kernel.clearance_law)
    res = mbs.simulate(model, t_end=t_end)
    assert res.attrs["complete"] and res.attrs["n_contact_events"] >= 1
    for j in joints:
        for qty in CLEARANCE_QUANTITIES:
            assert np.all(np.isfinite(res[f"{j}.{qty}"]))
        assert f"{j}.friction_force" not in res.signals  # friction off by default
        assert res[f"{j}.contact_force"].max() > 0
    assert res["system.position_error"].max() < 1e-6


@pytest.mark.parametrize("name, joints, t_end", SHIPPED[:1])
def test_a_shipped_model_asks_kelvin_voigt_for_its_linear_stiffness(name, joints, t_end):
    """The shipped models' stiffness is a Hertz one: `law = kelvin_voigt` is refused until given its K in N/m."""
    assert {s.name for s in catalog.LAWS} - set(LAWS) == {"kelvin_voigt"}
    with pytest.raises(ModelError, match="law kelvin_voigt of clearance joint `A` needs `stiffness`"):
        mbs.load_model(MODELS / name, law="kelvin_voigt")


def _enum_name(law: str) -> str:
    return {v: k.name for k, v in CONTACT_LAW_NAMES.items()}[law]


def _world_point(res, body, s):
    """Global position of body point s (body frame) from the body's x, y, phi signals."""
    if body == "ground":
        return np.full_like(res.time, s[0]), np.full_like(res.time, s[1])
    x, y, phi = res[f"{body}.x"], res[f"{body}.y"], res[f"{body}.phi"]
    return x + np.cos(phi) * s[0] - np.sin(phi) * s[1], y + np.sin(phi) * s[0] + np.cos(phi) * s[1]


@pytest.mark.parametrize("name, joints, geometry", [
    ("slider_crank_clearance_ab.mbs", ["A", "B"],
     {"A": (("crank", (0.025, 0)), ("rod", (-0.06, 0)), 0.3e-3),
      "B": (("rod", (0.06, 0)), ("slider", (0, 0)), 0.1e-3)}),
    ("four_bar_two_clearances.mbs", ["B", "O4"],
     {"B": (("coupler_link", (0.04, 0)), ("rocker_link", (0.03, 0)), 0.2e-3),
      "O4": (("ground", (0.07, 0)), ("rocker_link", (-0.03, 0)), 0.05e-3)}),
])
def test_two_clearance_joints_report_their_own_signals(name, joints, geometry):
    """Each joint's eccentricity is its own journal centre minus its own bearing centre
    (recomputed from the body signals), its force follows its own law and clearance, and
    the two joints differ."""
    second = joints[1]
    overrides = {"law_b": "hertz", "clearance_b": "0.1 mm"} if second == "B" else \
        {"law_o4": "hertz", "clearance_o4": "0.05 mm"}
    model = mbs.load_model(MODELS / name, **overrides)
    assert [int(x) for x in model.kernel.clearance_law] == [ContactLaw.LANKARANI_NIKRAVESH, ContactLaw.HERTZ]
    res = mbs.simulate(model, t_end=4e-3 if second == "B" else 20e-3)
    assert res.attrs["complete"]
    for j in joints:
        (bi, si), (bj, sj), c = geometry[j]
        xi, yi = _world_point(res, bi, si)
        xj, yj = _world_point(res, bj, sj)
        np.testing.assert_allclose(res[f"{j}.ex"], xj - xi, atol=1e-12)
        np.testing.assert_allclose(res[f"{j}.ey"], yj - yi, atol=1e-12)
        e = np.hypot(xj - xi, yj - yi)
        np.testing.assert_allclose(res[f"{j}.penetration"], e - c, atol=1e-12)
        # frictionless: the joint force is the normal force, directed along -n on the journal
        np.testing.assert_allclose(np.hypot(res[f"{j}.fx"], res[f"{j}.fy"]), res[f"{j}.contact_force"],
                                   rtol=1e-12, atol=1e-9)
        inside = res[f"{j}.contact_force"] > 0
        assert inside.any()
        assert np.all(res[f"{j}.penetration"][inside] > 0)
        assert np.all(res[f"{j}.in_contact"][inside] == 1)
    a, b = joints
    assert not np.array_equal(res[f"{a}.contact_force"], res[f"{b}.contact_force"])
    assert not np.array_equal(res[f"{a}.in_contact"], res[f"{b}.in_contact"])
    # the Hertz joint's force is K d^1.5 of its own penetration and stiffness
    K = model.kernel.clearance_param[1, 4]
    pen = np.maximum(res[f"{b}.penetration"], 0)
    inside = res[f"{b}.contact_force"] > 0
    np.testing.assert_allclose(res[f"{b}.contact_force"][inside], K * pen[inside] ** 1.5, rtol=1e-10)


def test_friction_signals_per_joint():
    """friction_force and slip_velocity appear when friction > 0, per joint; the friction
    force never exceeds mu times the normal force and opposes the slip."""
    model = mbs.load_model(MODELS / "four_bar_two_clearances.mbs", friction="0.1")
    res = mbs.simulate(model, t_end=20e-3)
    for j in ("B", "O4"):
        ft, vt, fn = res[f"{j}.friction_force"], res[f"{j}.slip_velocity"], res[f"{j}.contact_force"]
        assert np.all(np.abs(ft) <= 0.1 * fn * (1 + 1e-12))
        assert np.all(ft * vt <= 0)
        assert np.abs(ft).max() > 0
        np.testing.assert_allclose(np.hypot(res[f"{j}.fx"], res[f"{j}.fy"]), np.hypot(fn, ft), rtol=1e-12,
                                   atol=1e-9)


def test_three_clearance_joints_on_a_four_bar():
    """A four-bar with clearance at A, B and O4 (text model), three different laws."""
    text = (MODELS / "four_bar.mbs").read_text()
    text += """
material steel { E = 207 GPa  nu = 0.3 }
override joint A = clearance_revolute(crank_link (crank / 2, 0), coupler_link (-coupler / 2, 0)) {
    clearance = 0.1 mm  bearing_radius = 5 mm  length = 10 mm  material = steel  law = esdu78035 }
override joint B = clearance_revolute(coupler_link (coupler / 2, 0), rocker_link (rocker / 2, 0)) {
    clearance = 0.2 mm  bearing_radius = 5 mm  material = steel  law = flores(restitution = 0.5) }
override joint O4 = clearance_revolute(ground (frame, 0), rocker_link (-rocker / 2, 0)) {
    clearance = 0.15 mm  bearing_radius = 4 mm  length = 10 mm  material = steel
    law = gonthier  restitution = 0.7  friction = 0.05 }
"""
    from planar_mbs.mechanism.compile import compile_text

    model = compile_text(text, str(MODELS / "three.mbs"))
    assert model.clearance_names == ["A", "B", "O4"] and model.dof == 9 - 3
    res = mbs.simulate(model, t_end=0.02)
    assert res.attrs["complete"]
    for j in ("A", "B", "O4"):
        assert res[f"{j}.contact_force"].max() > 0
    assert "O4.friction_force" in res.signals and "A.friction_force" not in res.signals
    # the crank keeps its prescribed speed (driver), the rocker still swings
    assert math.isfinite(res["crank_drive.torque"].max())
