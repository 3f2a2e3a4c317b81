"""A clearance joint whose journal is a beam's node: the beam's own mobility there sizes the contact
(the node body has no mass of its own), checked against the inverse of the element's mass matrix
formed here; a flexible rod hanging in a clearance joint swings through repeated impacts (before,
the first impact of a node ended in a step-size underflow) and keeps the energy an elastic contact
and an undamped beam must keep, to a drift that shrinks with the tolerance."""
from __future__ import annotations

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.kernel import beam as kbeam
from planar_mbs.mechanism import beams

HANGING = """
material steel {{ E = 207 GPa  nu = 0.3  density = 7800 kg/m^3 }}
gravity (0, -9.81 m/s^2)
body rod = beam {{ length = 0.2 m  start = (0, 0.1 mm)  angle = -60 deg  section = rectangle(width = 10 mm, height = 5 mm)
                  material = steel  elements = {nel} }}
joint A = clearance_revolute(ground (0, 0), rod (start)) {{
    clearance = 0.3 mm  bearing_radius = 5 mm  length = 10 mm  material = steel  law = {law}  restitution = 0.9
}}
simulate {{ t_end = 50 ms }}
"""


def hanging(law="hertz", nel=2):
    return mbs.compile_text(HANGING.format(law=law, nel=nel))


@pytest.mark.parametrize("node", [0, 1, 2])
def test_a_node_s_mobility_is_the_node_block_of_the_inverse_mass_matrix(node):
    """n^T (M^-1)_node n for a few directions n, M^-1 by numpy's inverse of the consistent mass
    matrix assembled here (rho A times the Hermite products, `beams.beam_mass`)."""
    model = hanging(nel=2)
    km = model.kernel
    rho_a = 7800 * 0.01 * 0.005
    minv = np.linalg.inv(beams.beam_mass(2, 0.1, rho_a))
    block = minv[4 * node:4 * node + 2, 4 * node:4 * node + 2]
    b = int(km.beam_info[0, 0]) + 2 * node
    for angle in np.linspace(0, np.pi, 7):
        n = np.array([np.cos(angle), np.sin(angle)])
        assert kbeam.beam_node_mobility(km, b, n[0], n[1]) == pytest.approx(n @ block @ n, rel=1e-12)
    # a free beam's end moves more under a point force than its whole mass would (rigid rod: 4/m)
    assert 1.0 / kbeam.beam_node_mobility(km, int(km.beam_info[0, 0]), 1.0, 0.0) < rho_a * 0.2 / 3.9


def _contacts(res):
    on = np.asarray(res["A.in_contact"]) > 0.5
    return int(np.sum(on[1:] & ~on[:-1]))


def test_a_beam_node_swings_through_impacts_in_its_bearing_keeping_its_energy():
    """Hertz's law stores and returns its energy and the beam is undamped: the total energy (kinetic,
    strain, weight and contact) stays what it was, to a drift that shrinks with the tolerance, over
    tens of impacts of the node on the bearing."""
    drifts = []
    for rtol in (1e-6, 1e-9):
        res = mbs.simulate(hanging("hertz"), rtol=rtol, atol=rtol * 1e-3)
        assert _contacts(res) >= 10
        E = np.asarray(res["system.total_energy"])
        scale = np.asarray(res["system.kinetic_energy"]).max()
        assert scale > 1e-3  # it swings: m g (drop of its centre) ~ 2e-3 J
        drifts.append(np.abs(E - E[0]).max() / scale)
    assert drifts[0] < 1e-3 and drifts[1] < drifts[0] / 30, drifts


def test_a_dissipative_law_on_a_beam_node_closes_the_energy_balance():
    """Lankarani-Nikravesh's hysteresis takes energy at each impact (A.dissipated grows), and what it
    takes is what the mechanism loses: the balance stays within the run's own check (100 rtol)."""
    res = mbs.simulate(hanging("lankarani_nikravesh"))
    assert _contacts(res) >= 5
    dissipated = np.asarray(res["system.dissipated"])
    scale = np.asarray(res["system.kinetic_energy"]).max()
    assert dissipated[-1] > 1e-6 * scale
    assert np.abs(np.asarray(res["system.energy_balance"])).max() < 100 * 1e-6 * scale
