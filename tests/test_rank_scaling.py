"""The rank test at any size, order and mass ratio: a regular chain never reports that its constraints
lost rank, while a singular position and redundant joints still do.  The pivots of a regular chain's
Schur complement shrink with its length (like 1/N) and with the mass ratio of its links; the test
that counts only pivots the regularised solve may withhold (`kernel/dynamics.py`, `withholds`) must
tell them from a singular position.  Each case is also run with the old rule (every pivot below TAU
counts, `PLANAR_MBS_SOLVER`'s seventh value set to TAU) to show that the case can fail."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs
from chains import ORDERS, crank_angle_reference, parallelogram_chain, pendulum_chain, pendulum_tree

MODELS = Path(__file__).resolve().parents[1] / "models"
OLD_RULE = "1e-8,2,0,1e-3,1,0.03,1e-3,0"  # REG, REFINE, REFINE_TOL, TAU, RESTORE, RATE, WITHHELD = TAU, no UNIT_MASS


def lost_rank(res) -> bool:
    return any("lost rank" in str(w) for w in res.attrs.get("warnings", []))


def alternating_chain(N: int, ratio: float, order: str) -> str:
    """`pendulum_chain(N)` whose odd bars weigh `ratio` times the even ones, for 2 ms."""
    lines = []
    for line in pendulum_chain(N, order, t_end=0.002, output_step=0.001).splitlines(True):
        m = re.match(r"body bar(\d+) ", line)
        if m and int(m.group(1)) % 2:
            line = line.replace("mass = 0.1 kg", f"mass = {0.1 * ratio!r} kg")
        lines.append(line)
    return "".join(lines)


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("N,ratio", [(10, 1e4), (20, 1e3), (100, 1e2)])
def test_a_chain_of_unequal_links_has_not_lost_rank(monkeypatch, N, ratio, order):
    text = alternating_chain(N, ratio, order)
    res = mbs.simulate(mbs.compile_text(text))
    assert not lost_rank(res)
    assert max(res["system.position_error"]) < 1e-6 * 0.1 * N  # it kept its joints
    monkeypatch.setenv("PLANAR_MBS_SOLVER", OLD_RULE)
    assert lost_rank(mbs.simulate(mbs.compile_text(text)))  # the old rule said it had


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("N", [10, 100])
def test_a_uniform_chain_has_not_lost_rank(N, order):
    assert not lost_rank(mbs.simulate(mbs.compile_text(pendulum_chain(N, order, t_end=0.002, output_step=0.001))))


@pytest.mark.slow  # the assembly of 800 and 1000 bars takes 15-40 s a model
@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("N", [800, 1000])
def test_a_long_uniform_chain_has_not_lost_rank(monkeypatch, N, order):
    text = pendulum_chain(N, order, t_end=0.002, output_step=0.001)
    assert not lost_rank(mbs.simulate(mbs.compile_text(text)))
    if order == "chain":
        monkeypatch.setenv("PLANAR_MBS_SOLVER", OLD_RULE)
        assert lost_rank(mbs.simulate(mbs.compile_text(text)))  # pivots near 1e-3 of their diagonal


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("depth", [4, 7])
def test_a_tree_has_not_lost_rank(depth, order):
    """Binary trees of 15 and 127 bars in four text orders: no loss of rank reported, the joints kept."""
    res = mbs.simulate(mbs.compile_text(pendulum_tree(depth, order)))
    assert not lost_rank(res)
    assert max(res["system.position_error"]) < 1e-6 * 0.1 * depth


@pytest.mark.slow  # the assembly of a thousand bars takes tens of seconds
def test_a_thousand_bar_tree_has_not_lost_rank():
    res = mbs.simulate(mbs.compile_text(pendulum_tree(10, "shuffled")))
    assert not lost_rank(res)
    assert max(res["system.position_error"]) < 1e-6


@pytest.mark.parametrize("coupler", [1e-4, 1e-6])
def test_light_couplers_still_lose_rank_at_the_singular_position(coupler):
    """Mass ratios do not hide a real loss of rank: the IFToMM chain with light couplers still reports
    it, near the closed form's first singular position."""
    text = parallelogram_chain(2, t_end=1.0, integrator="dop853", rtol=1e-12, atol=1e-14, output_step=0.001,
                               coupler_mass=coupler)
    res = mbs.simulate(mbs.compile_text(text))
    assert lost_rank(res)


def test_redundant_joints_have_lost_rank():
    assert lost_rank(mbs.simulate(mbs.load_model(MODELS / "redundant_rails.mbs"), t_end=0.01))


@pytest.mark.parametrize("order", ["chain", "shuffled"])
def test_a_parallelogram_chain_loses_rank_at_its_first_singular_position(order):
    """Its bars line up horizontally every half turn: the first time when the crank angle of the closed
    form (`crank_angle_reference`) reaches 0; the loss of rank is reported within 10 ms before it (the
    pivot falls below 1e-6 of its diagonal within about 1e-3 rad of the position at 1 rad/s)."""
    res = mbs.simulate(mbs.compile_text(parallelogram_chain(2, order, t_end=1.0, output_step=0.01)))
    t = np.linspace(0.0, 1.0, 100_001)
    singular = t[np.argmax(crank_angle_reference(2, t)[0] <= 0.0)]
    said = re.search(r"lost rank at t = ([0-9.e+-]+) s", " ".join(map(str, res.attrs.get("warnings", []))))
    assert said, res.attrs.get("warnings")
    assert singular - 0.01 < float(said.group(1)) <= singular
