"""Load signals and the energy balance (docs/signals.md, "Work and the energy balance"): every force
kind's power integrates to its work (against a trapezoid of its power and a closed form), the balance
closes at tight tolerances on a motor-driven and a clearance model, and the energy check warns
whenever the balance exceeds its stated bound."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.run.checks import BALANCE_PER_RTOL

MODELS = Path(__file__).resolve().parents[1] / "models"

# one body of each kind's loads, no gravity but one, no constraint: closed forms for every work
KINDS = """
body disc { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0, 0)  velocity = (0.2 m/s, 0.1 m/s)  omega = 1 rad/s }
body bob { mass = 2 kg  inertia = 0.02 kg*m^2  position = (1, 0)  velocity = (0, 0.3 m/s) }
force push = constant(disc (0.1, 0), force = (1 N, -2 N))
force turn = torque(disc, torque = 0.5 N*m)
force spring = spring_damper(ground (1, -1), bob (0, 0)) { stiffness = 40 N/m  length = 0.8 m }
force damper = spring_damper(ground (2, 0), bob (0, 0)) { stiffness = 0 N/m  damping = 3 N*s/m }
force twist = rotational_spring_damper(ground, disc) { stiffness = 2 N*m/rad  damping = 0.1 N*m*s/rad  angle = 0 deg }
force drag = expression(bob, fx = -0.5 N*s/m * bob.vx, fy = 1 N * sin(t * 3 rad/s), torque = 0.1 N*m)
gravity (0, -9.81 m/s^2)
simulate { t_end = 1 s  rtol = 1e-10  atol = 1e-13  output_step = 1 ms }
"""


@pytest.fixture(scope="module")
def kinds(tmp_path_factory):
    path = tmp_path_factory.mktemp("kinds") / "kinds.mbs"
    path.write_text(KINDS)
    return mbs.simulate(mbs.load_model(path))


@pytest.mark.parametrize("name", ["push", "turn", "spring", "damper", "twist", "drag", "gravity"])
def test_every_kind_power_integrates_to_its_work(kinds, name):
    """The cumulative work (integrated by the time loop) against the trapezoid of the recorded power at
    1 ms (its error ~ dt^2 w^2 / 12 ~ 2e-5 of the work, w ~ 14 rad/s the torsion spring's frequency)."""
    t, P, W = kinds.time, kinds[f"{name}.power"], kinds[f"{name}.work"]
    trap = np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1]) * np.diff(t))])
    assert W[0] == 0.0 and np.abs(W).max() > 1e-3
    np.testing.assert_allclose(W, trap, atol=1e-4 * np.abs(W).max())


def test_works_against_closed_forms(kinds):
    """Constant torque: T dphi; constant force: F . dP; spring: -dV; gravity: -m g dy; damper: -c int l'^2."""
    r = kinds
    np.testing.assert_allclose(r["turn.work"], 0.5 * (r["disc.phi"] - r["disc.phi"][0]), atol=1e-9)
    px = r["disc.x"] + 0.1 * np.cos(r["disc.phi"])
    py = r["disc.y"] + 0.1 * np.sin(r["disc.phi"])
    np.testing.assert_allclose(r["push.work"], 1.0 * (px - px[0]) - 2.0 * (py - py[0]), atol=1e-9)
    V = 0.5 * 40 * (r["spring.length"] - 0.8) ** 2
    np.testing.assert_allclose(r["spring.work"], -(V - V[0]), atol=1e-9)
    assert r["spring.force"] == pytest.approx(40 * (r["spring.length"] - 0.8))
    m = 3.0  # disc and bob
    dy = 1.0 * (r["disc.y"] - r["disc.y"][0]) + 2.0 * (r["bob.y"] - r["bob.y"][0])
    np.testing.assert_allclose(r["gravity.work"], -9.81 * dy, atol=1e-9 * m)
    t, rate = r.time, r["damper.rate"]
    trap = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] ** 2 + rate[:-1] ** 2) * np.diff(t))])
    np.testing.assert_allclose(r["damper.work"], -3.0 * trap, atol=1e-5 * abs(trap[-1]))  # a trapezoid too
    assert np.abs(r["system.energy_balance"]).max() < 1e-9 * r["system.kinetic_energy"].max()


@pytest.mark.parametrize("model", ["slider_crank_motor", "slider_crank_clearance_a"])
def test_balance_closes_at_tight_tolerances(model):
    """rtol 1e-10: the balance within 1e-9 of the run's energy scale; the motor's (or the driver's) work
    is in it, and the clearance joint's dissipation."""
    res = mbs.simulate(mbs.load_model(MODELS / f"{model}.mbs"), t_end="15 ms", rtol=1e-10, atol=1e-13)
    b = res["system.energy_balance"]
    scale = max(res["system.kinetic_energy"].max(), np.abs(res["system.input_work"]).max())
    assert np.abs(b).max() < 1e-9 * scale, np.abs(b).max() / scale
    inputs = "motor.work" if model == "slider_crank_motor" else "crank_speed.work"
    assert abs(res[inputs][-1]) > 1e-3 * scale  # work was done, and counted
    assert res["A.dissipated"][-1] > 0.0 and res["A.dissipated"][-1] == pytest.approx(res["system.dissipated"][-1])
    if model == "slider_crank_motor":
        assert res["motor.power"] == pytest.approx(res["motor.torque"] * res["flywheel.omega"], rel=1e-12)


RATTLE = """
material steel { E = 207 GPa  nu = 0.3  density = 7800 kg/m^3 }
body block { mass = 0.14 kg  inertia = 1e-5 kg*m^2  position = (0, 0)  velocity = (0.3 m/s, 0.2 m/s)  omega = 1 rad/s }
joint S = clearance_translational(ground (0, 0), block (0, 0), axis = (1, 0)) {
    clearance = 0.1 mm  length = 30 mm  width = 15 mm  corner_radius = 1 mm
    material = steel  law = hertz
}
simulate { t_end = 0.1 s }
"""


@pytest.mark.parametrize("rtol", [None, 1e-3])
def test_rattling_block_keeps_the_balance_or_warns(tmp_path, rtol):
    """An undriven, frictionless, elastic block rattling in its guide: under the defaults (and a loose
    rtol) the run either keeps its balance within BALANCE_PER_RTOL rtol of its energy scale or warns."""
    path = tmp_path / "rattle.mbs"
    path.write_text(RATTLE)
    res = mbs.simulate(mbs.load_model(path), **({} if rtol is None else {"rtol": rtol}))
    assert res.attrs["n_contact_events"] > 50
    scale = res["system.kinetic_energy"].max()
    off = np.abs(res["system.energy_balance"]).max()
    assert np.all(res["system.input_work"] == 0.0)  # nothing drives it: the balance is its energy's error
    warned = any("total energy" in w for w in res.attrs["warnings"])
    assert warned == (off > BALANCE_PER_RTOL * (rtol or 1e-6) * scale), (off / scale, res.attrs["warnings"])
