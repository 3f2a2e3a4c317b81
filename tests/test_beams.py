"""Beams in the time loop, against closed forms derived here: a clamped cantilever released under
its weight against Euler-Bernoulli's modal solution, a flexible pendulum released horizontally
conserving its energy to the integrator's tolerance, and a very stiff beam reproducing a rigid
connecting rod.  The models state no solver setting where accuracy is claimed but the tolerances
named."""
from __future__ import annotations

import math

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.errors import ModelError

STEEL = "material steel { E = 210 GPa  nu = 0.3  density = 7800 kg/m^3 }\n"


def cantilever_modal(t, L, ei, rho_a, g, modes=6, static=False):
    """Tip deflection of a clamped-free Euler-Bernoulli beam whose weight is switched on at t = 0, from
    rest: y(L, t) = sum_n (g int phi_n / int phi_n^2) phi_n(L) / omega_n^2 (1 - cos omega_n t), with
    phi_n = cosh - cos - sigma_n (sinh - sin), int phi_n^2 = L, int phi_n = 2 sigma_n / beta_n,
    phi_n(L) = 2 (-1)^(n+1); beta_n L the roots of cos x cosh x = -1 (bisection).  `static`: the sum
    without (1 - cos), the static deflection."""
    y = np.zeros_like(t)
    f = lambda x: math.cos(x) * math.cosh(x) + 1.0
    for n in range(modes):
        lo, hi = (1.0, 3.0) if n == 0 else ((n + 0.5) * math.pi - 0.5, (n + 0.5) * math.pi + 0.5)
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if f(lo) * f(mid) <= 0 else (mid, hi)
        x = 0.5 * (lo + hi)
        beta = x / L
        sigma = (math.cosh(x) + math.cos(x)) / (math.sinh(x) + math.sin(x))
        w = beta ** 2 * math.sqrt(ei / rho_a)
        y += g * (2 * sigma / beta) / L * 2 * (-1) ** n / w ** 2 * (1.0 if static else 1 - np.cos(w * t))
    return y


def test_cantilever_under_its_weight_follows_the_modal_solution():
    """A steel cantilever (welded to ground) released straight under gravity swings about its static
    deflection w L^4 / (8 EI); its tip follows the modal sum of the continuum (six modes) to 1 % of that
    deflection over two periods of the first mode (4 elements: the first frequency is 3e-5 high)."""
    L, w, h = 0.5, 0.01, 0.02
    ei, rho_a, g = 210e9 * w * h ** 3 / 12, 7800 * w * h, 9.81
    T1 = 2 * math.pi / (1.8751041 ** 2 * math.sqrt(ei / (rho_a * L ** 4)))
    text = STEEL + f"""
body rod = beam {{ length = {L} m  section = rectangle({w * 1e3} mm, {h * 1e3} mm)  material = steel  elements = 4 }}
joint clamp = weld(ground (0, 0), rod (start))
gravity (0, -{g} m/s^2)
simulate {{ t_end = {2 * T1} s  output_step = {T1 / 200} s  rtol = 1e-8  atol = 1e-13 }}
"""
    res = mbs.simulate(mbs.compile_text(text))
    t = np.asarray(res.time)
    exact = -cantilever_modal(t, L, ei, rho_a, g)
    static = rho_a * g * L ** 4 / (8 * ei)
    # the modal sum itself: its static part is w L^4 / (8 EI)
    assert cantilever_modal(np.zeros(1), L, ei, rho_a, g, 40, static=True)[0] == pytest.approx(static, rel=1e-6)
    assert np.abs(res["rod_node4.y"] - exact).max() < 1e-2 * static
    assert np.abs(res["rod_node0.x"]).max() < 1e-12 and np.abs(res["rod_slope0.y"]).max() < 1e-10  # clamped


def _pendulum(rtol):
    text = """
material nylon { E = 2 GPa  nu = 0.4  density = 1100 kg/m^3 }
body rod = beam { length = 0.5 m  section = rectangle(10 mm, 2 mm)  material = nylon  elements = 4 }
joint pin = revolute(ground (0, 0), rod (start))
gravity (0, -9.81 m/s^2)
simulate { t_end = 0.3 s  output_step = 1 ms }
"""
    return mbs.simulate(mbs.compile_text(text), rtol=rtol, atol=rtol * 1e-3)


def test_flexible_pendulum_conserves_its_energy_to_the_tolerance():
    """A floppy nylon beam pinned at one end and released horizontally bends as it falls (its middle
    leaves the chord to its tip); its energy (kinetic, strain and weight) stays constant to a
    drift that shrinks with the tolerance."""
    drifts = []
    for rtol in (1e-6, 1e-9):
        res = _pendulum(rtol)
        E = np.asarray(res["system.total_energy"])
        scale = 0.011 * 9.81 * 0.25  # m g L / 2
        drifts.append(np.abs(E - E[0]).max() / scale)
        x4, y4, x2, y2 = (np.asarray(res[f"rod_node{n}.{c}"]) for n in (4, 2) for c in "xy")
        sag = np.abs(x4 * y2 - y4 * x2) / np.hypot(x4, y4)  # the middle node off the chord to the tip
        assert sag.max() > 1e-3  # it bends
        assert res["system.kinetic_energy"].max() > 0.5 * scale
        # the strain energy signal is the potential less the weight's: rho A g int y ds, the Hermite
        # cubic of each element integrated by Simpson's rule (exact for cubics)
        y = lambda n: np.asarray(res[f"rod_node{n}.y"])
        dy = lambda n: np.asarray(res[f"rod_slope{n}.y"])
        Le = 0.125
        int_y = sum(Le / 6 * (y(k) + y(k + 1) + 4 * ((y(k) + y(k + 1)) / 2 + Le / 8 * (dy(k) - dy(k + 1))))
                    for k in range(4))
        rho_a_g = 1100 * 2e-5 * 9.81
        assert np.allclose(res["rod.elastic_energy"], res["system.potential_energy"] - rho_a_g * int_y,
                           rtol=0, atol=1e-12)
        assert res["rod.elastic_energy"].max() > 1e-4 * scale  # it bends
        assert np.allclose(res["rod_element0.moment"], 2e9 * 0.01 * 0.002 ** 3 / 12 * res["rod_element0.curvature"])
    assert drifts[1] < 1e-6 and drifts[1] < drifts[0] / 30, drifts



def test_a_damped_beam_s_lost_energy_is_what_its_damping_dissipated():
    """The steel cantilever released under its weight, with material damping eta = 2 zeta / omega_1
    (zeta = 0.05 in its first mode): its swing decays, the energy lost is the damping's work
    -eta int (EA eps_dot^2 + EI kappa_dot^2) ds dt (system.dissipated, which only grows), and the
    balance T + V - (T + V)(0) + dissipated stays at the integration's error (the run's own check,
    100 rtol of the energy scale), far below the loss."""
    L, w, h = 0.5, 0.01, 0.02
    ei, rho_a = 210e9 * w * h ** 3 / 12, 7800 * w * h
    omega1 = 1.8751041 ** 2 * math.sqrt(ei / (rho_a * L ** 4))
    text = STEEL + f"""
body rod = beam {{ length = {L} m  section = rectangle({w * 1e3} mm, {h * 1e3} mm)  material = steel  elements = 4
                  damping = {2 * 0.05 / omega1} s }}
joint clamp = weld(ground (0, 0), rod (start))
gravity (0, -9.81 m/s^2)
simulate {{ t_end = {4 * math.pi / omega1} s  output_step = {math.pi / omega1 / 50} s }}
"""
    res = mbs.simulate(mbs.compile_text(text))
    E = np.asarray(res["system.total_energy"])
    dissipated = np.asarray(res["system.dissipated"])
    scale = np.asarray(res["system.kinetic_energy"]).max()
    assert dissipated[-1] > 0.3 * scale  # two periods at zeta = 0.05: 1 - exp(-0.4 pi) of the swing
    assert np.all(np.diff(dissipated) >= -1e-12 * scale)
    np.testing.assert_allclose(E[0] - E, dissipated, rtol=0, atol=100 * 1e-6 * scale)
    assert not any("energy" in str(w) for w in res.attrs.get("warnings", []))

SLIDER_CRANK = STEEL.replace("{", "{{").replace("}", "}}") + """
param speed = 600 rpm
body crank  {{ mass = 0.3 kg  inertia = 1e-4 kg*m^2  position = (0.025 m, 0) }}
{rod}
body slider {{ mass = 0.14 kg  inertia = 1e-4 kg*m^2  position = (0.17 m, 0) }}
joint O = revolute(ground (0, 0), crank (-0.025 m, 0))
joint A = revolute(crank (0.025 m, 0), {a})
joint B = revolute({b}, slider (0, 0))
joint S = translational(ground, slider, axis = (1, 0))
driver drive = rotation(crank, speed = speed)
simulate {{ t_end = 0.05 s  output_step = 0.5 ms  rtol = 1e-9  atol = 1e-12 }}
"""


def test_a_stiff_beam_reproduces_the_rigid_connecting_rod():
    """A connecting rod of steel, 0.12 m, 10 x 10 mm, as a beam of 2 elements (started in the rigid rod's
    motion, lightly damped) and as the rigid rod of the same mass and inertia m L^2 / 12: once the start's
    ringing has died out, the crank's driving torque agrees to 0.5 % of its range."""
    m = 7800 * 1e-4 * 0.12
    rigid = SLIDER_CRANK.format(rod=f"body rod {{ mass = {m} kg  inertia = {m * 0.12 ** 2 / 12} kg*m^2  "
                                       "position = (0.11 m, 0) }", a="rod (-0.06 m, 0)", b="rod (0.06 m, 0)")
    va = 600 * 2 * math.pi / 60 * 0.05  # the crank pin's speed at the dead centre: the rod turns about B
    flexible = SLIDER_CRANK.format(rod="body rod = beam { length = 0.12 m  start = (0.05 m, 0)  "
                                       "section = rectangle(10 mm, 10 mm)  material = steel  elements = 2  "
                                       f"velocity = (0, {va} m/s)  omega = {-va / 0.12} rad/s  damping = 10 us }}",
                                   a="rod (start)", b="rod (end)")
    r1 = mbs.simulate(mbs.compile_text(rigid))
    r2 = mbs.simulate(mbs.compile_text(flexible))
    late = np.asarray(r1.time) > 0.025  # the beam's start, unstrained under its inertia, rings: damped by then
    tq1, tq2 = np.asarray(r1["drive.torque"])[late], np.asarray(r2["drive.torque"])[late]
    assert np.ptp(tq1) > 0
    assert np.abs(tq2 - tq1).max() < 5e-3 * np.ptp(tq1), np.abs(tq2 - tq1).max() / np.ptp(tq1)
    assert np.abs(r2["slider.x"] - r1["slider.x"]).max() < 1e-6


BEAM = "body rod = beam {{ length = 1 m  section = rectangle(1 mm, 1 mm)  material = steel  {extra} }}\n"


@pytest.mark.parametrize("text, message", [
    ("body rod = bream { length = 1 m }", "unknown kind of body `bream`"),
    ("body rod = beam { length = 1 m  material = steel }", "beam `rod` needs `section`"),
    (BEAM.format(extra="elements = 2") + "joint p = revolute(ground, rod (5))", "has nodes 0 to 2, not `5`"),
    (BEAM.format(extra="") + "joint p = revolute(ground, rod)", "names beam `rod` without a node"),
    (BEAM.format(extra="elements = 2.5"), "must be a whole number"),
    (BEAM.format(extra="area = 1 mm^2"), "has a `section` and `area`"),
    (BEAM.format(extra="length = 2 m"), "given twice"),
    ("material soft { E = 1 GPa  nu = 0.3 }\nbody rod = beam { length = 1 m  section = circle(1 mm)  material = soft }",
     "needs a `density`"),
])
def test_bad_beams_are_model_errors(text, message):
    with pytest.raises(ModelError, match=message.replace("(", r"\(").replace(")", r"\)")):
        mbs.compile_text(STEEL + text)


def test_check_counts_four_coordinates_per_node_and_the_weld_its_slope_row():
    """Two rigid bodies (3 each) and a beam of 3 elements (4 nodes of 4 coordinates): 22 coordinates;
    a revolute (2 rows) and a weld on the beam (2 + 1 rows): 17 degrees of freedom."""
    m = mbs.compile_text(STEEL + BEAM.format(extra="elements = 3") + """
body a { mass = 1 kg  inertia = 1 kg*m^2 }
body b { mass = 1 kg  inertia = 1 kg*m^2  position = (1 m, 0) }
joint p = revolute(a, rod (start))
joint w = weld(rod (end), b)
gravity (0, -9.81 m/s^2)
""")
    assert m.ncoord == 22 and m.nconstraint == 5 and m.dof == 17
    assert m.joint_names == ["p", "w", "w_slope"]
    assert m.body_names[2:4] == ["rod_node0", "rod_slope0"]
