"""Singular positions, redundant joints, the fill-reducing row order and RK4's drift check.

References are independent of the solver: the parallelogram chain's exact motion by
quadrature of its energy equation (`chains.crank_angle_reference`), the redundant
rails' closed form, the envelope's size counted from the graph.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import chains
import planar_mbs as mbs
from planar_mbs import catalog
from planar_mbs.cli.app import app
from planar_mbs.mechanism.compile import compile_text
from planar_mbs.kernel.workspace import envelope_size as profile

MODELS = Path(__file__).resolve().parents[1] / "models"
ADAPTIVE = [s.name for s in catalog.INTEGRATORS if s.adaptive]  # every adaptive method, none by hand
runner = CliRunner()


# ---------------------------------------------------------------- ordering
@pytest.mark.parametrize("held", [False, True])
def test_envelope_does_not_depend_on_the_order_of_the_text(held):
    sizes = {order: profile(compile_text(chains.parallelogram_chain(40, order=order, held=held)).kernel)
             for order in chains.ORDERS}
    assert max(sizes.values()) <= 1.1 * min(sizes.values()), sizes


def test_envelope_grows_linearly_with_the_chain():
    """A chain of four-bars is a band: rows x (a bandwidth independent of N)."""
    p20 = profile(compile_text(chains.parallelogram_chain(20, order="shuffled")).kernel)
    p160 = profile(compile_text(chains.parallelogram_chain(160, order="shuffled")).kernel)
    rows = lambda n: 2 * (3 * n + 1)  # noqa: E731  3N + 1 revolute joints
    assert p160 / rows(160) <= 1.1 * p20 / rows(20)
    assert p160 / rows(160) < 12  # a band of at most ~12 rows


def test_row_order_keeps_each_element_together_and_covers_every_row():
    k = compile_text(chains.parallelogram_chain(5, order="shuffled", held=True)).kernel
    rows = np.concatenate([k.joint_row, k.joint_row + 1, k.driver_row])
    assert sorted(rows.tolist()) == list(range(len(rows)))


# ---------------------------------------------------------------- singular positions
def tip_error(res, N):
    t = res.time
    phi = res["crank0.phi"]
    tip = np.stack([res["crank0.x"] + 0.5 * np.cos(phi), res["crank0.y"] + 0.5 * np.sin(phi)])
    theta, period = chains.crank_angle_reference(N, t)
    exact = np.stack([np.cos(theta), np.sin(theta)])
    passes = int(math.floor((math.pi / 2 - theta[-1]) / math.pi + 0.5))  # horizontal positions passed
    return float(np.max(np.hypot(*(tip - exact)))), passes


def test_reference_quadrature_is_self_consistent():
    """The reference itself: theta(t) satisfies the energy equation it came from."""
    N = 2
    t = np.linspace(0, 5, 2001)
    theta, period = chains.crank_angle_reference(N, t)
    rate = np.gradient(theta, t, edge_order=2)
    k = (2 * 9.81) * ((N + 1) / 2 + N) / ((N + 1) / 3 + N)
    np.testing.assert_allclose(rate[5:-5], -np.sqrt(1 + k * (1 - np.sin(theta[5:-5]))), rtol=2e-4)
    assert 1.5 < period < 2.5


def run_chain(N, integrator, rtol):
    text = chains.parallelogram_chain(N, integrator=integrator, rtol=rtol, atol=rtol * 1e-2, t_end=20.0,
                                      extra="projection = on ")
    return mbs.simulate(compile_text(text, f"parallelogram_{N}.mbs"))


@pytest.mark.parametrize("integrator", ADAPTIVE)
def test_parallelogram_passes_twenty_singular_positions_on_its_branch(integrator):
    res = run_chain(1, integrator, 1e-12)
    assert res.attrs["complete"]
    err, passes = tip_error(res, 1)
    assert passes >= 20
    assert err <= 1e-8
    assert np.abs(res["coupler0.phi"]).max() < 1e-9  # the couplers never turn: no other branch


@pytest.mark.parametrize("integrator", ADAPTIVE)
def test_parallelogram_chain_keeps_its_energy_through_every_passage(integrator):
    """Conservative, so the total energy is constant; the kinetic energy a projection removed after
    a withheld force (9e-9 J over 20 s with DOP853 without `restore_kinetic_energy`) is given back."""
    res = run_chain(2, integrator, 1e-12)
    E = res["system.total_energy"]
    assert tip_error(res, 2)[1] >= 20
    assert np.abs(E - E[0]).max() <= 2e-9  # 35.8 J: 6e-11 of it


@pytest.mark.slow
@pytest.mark.parametrize("integrator", ADAPTIVE)
@pytest.mark.parametrize("N, bound", [(2, 1e-8), (10, 1e-8)])
def test_longer_parallelogram_chains_pass_their_singular_positions(N, bound, integrator):
    res = run_chain(N, integrator, 1e-12)
    assert res.attrs["complete"]
    err, passes = tip_error(res, N)
    assert passes >= 20
    assert err <= bound
    assert max(np.abs(res[f"coupler{i}.phi"]).max() for i in range(N)) < 1e-7


def test_shipped_parallelogram_runs_through_with_exit_0(tmp_path):
    res = runner.invoke(app, ["run", str(MODELS / "parallelogram_chain.mbs"), "-o", str(tmp_path / "p.h5"),
                              "--t-end", "3 s"])
    assert res.exit_code == 0, res.output
    out = mbs.read_results(tmp_path / "p.h5")
    err, passes = tip_error(out, 3)
    assert passes >= 3 and err <= 1e-8


def test_rk4_that_leaves_the_constraints_stops_with_exit_3(tmp_path):
    """A 1 ms RK4 step: the chain cannot pass its singular position at that step (the step in two
    halves disagrees), or leaves its constraints there."""
    path = tmp_path / "p.mbs"
    path.write_text(chains.parallelogram_chain(1, integrator="rk4", extra="step = 1 ms "))
    res = runner.invoke(app, ["run", str(path), "-o", str(tmp_path / "p.h5")])
    assert res.exit_code == 3, res.output
    out = " ".join(res.output.split())
    assert "at t = " in out
    assert ("constraints drifted" in out and "joint `" in out) or "cannot resolve a singular position" in out


# ---------------------------------------------------------------- redundant joints
def test_check_names_the_redundant_joint():
    res = runner.invoke(app, ["check", str(MODELS / "redundant_rails.mbs")])
    assert res.exit_code == 0, res.output
    assert "rank 2" in res.output and "1 degree of freedom" in res.output
    assert "redundant at the initial pose: `rear`" in " ".join(res.output.split())


@pytest.mark.parametrize("text, redundant", [
    ("joint O = revolute(ground (0, 0), crank (-0.025, 0))\njoint O2 = revolute(ground (0, 0), crank (-0.025, 0))\n",
     "O2"),
    ("joint O = revolute(ground (0, 0), crank (-0.025, 0))\njoint W = weld(ground (0, 0), crank (-0.025, 0))\n",
     "W"),
])
def test_repeated_joints_are_accepted_and_named(tmp_path, text, redundant):
    path = tmp_path / "r.mbs"
    path.write_text("body crank { mass = 0.3 kg  inertia = 1e-5 kg*m^2  position = (0.025, 0) }\n" + text
                    + "gravity (0, -9.81 m/s^2)\nsimulate { t_end = 0.05 s }\n")
    res = runner.invoke(app, ["check", str(path)])
    assert res.exit_code == 0, res.output
    assert f"redundant at the initial pose: `{redundant}`" in " ".join(res.output.split())
    res = runner.invoke(app, ["run", str(path), "-o", str(tmp_path / "r.h5")])
    assert res.exit_code == 0, res.output


def test_damped_redundant_rails_with_projection_settle_like_the_closed_form():
    """Every factor of a redundant model is regularised, so every projection may give kinetic
    energy back: with a damper the carriage must still decay like the damped oscillator
    m s'' + c s' + k (s - s_eq) = 0 (s'(0) = 0) and stay at rest, not be kept moving."""
    text = (MODELS / "redundant_rails.mbs").read_text().replace("damping = 0 N*s/m", "damping = 4 N*s/m")
    text = text.replace("t_end = 2 s", "t_end = 20 s  projection = on")
    res = mbs.simulate(compile_text(text, "damped_rails.mbs"))
    assert res.attrs["complete"]
    mass, k, c, l0, s0, g, a = 2.0, 200.0, 4.0, 0.2, 0.3, 9.81, math.radians(30)
    s_eq = l0 - mass * g * math.sin(a) / k
    decay = c / (2 * mass)
    wd = math.sqrt(k / mass - decay ** 2)
    t = res.time
    s = s_eq + (s0 - s_eq) * np.exp(-decay * t) * (np.cos(wd * t) + decay / wd * np.sin(wd * t))
    np.testing.assert_allclose(res["carriage.x"], s * math.cos(a), atol=1e-9)
    np.testing.assert_allclose(res["carriage.y"], s * math.sin(a), atol=1e-9)
    assert np.abs(res["carriage.vx"][t > 18]).max() < 1e-7  # 0.1 m/s * 10 * e^-18 = 1.5e-8


def test_redundant_rails_match_the_closed_form():
    m = mbs.load_model(MODELS / "redundant_rails.mbs")
    res = mbs.simulate(m)
    assert res.attrs["complete"]
    mass, k, l0, s0, g, a = 2.0, 200.0, 0.2, 0.3, 9.81, math.radians(30)
    t = res.time
    s_eq = l0 - mass * g * math.sin(a) / k
    s = s_eq + (s0 - s_eq) * np.cos(math.sqrt(k / mass) * t)
    np.testing.assert_allclose(res["carriage.x"], s * math.cos(a), atol=1e-9)
    np.testing.assert_allclose(res["carriage.y"], s * math.sin(a), atol=1e-9)
    np.testing.assert_allclose(res["carriage.phi"], a, atol=1e-12)
    # the rails together: m g cos(slope) along the slope's normal, nothing along it
    n = np.array([-math.sin(a), math.cos(a)])
    fx = res["front.fx"] + res["rear.fx"]
    fy = res["front.fy"] + res["rear.fy"]
    np.testing.assert_allclose(fx * n[0] + fy * n[1], mass * g * math.cos(a), rtol=1e-9)
    np.testing.assert_allclose(fx * n[1] - fy * n[0], 0.0, atol=1e-8)
    # the minimum-norm split of two rails symmetric about the centre of mass is even
    np.testing.assert_allclose(res["front.fy"], res["rear.fy"], rtol=1e-6)
