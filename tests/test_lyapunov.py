"""Benettin's method (planar_mbs.run.lyapunov.benettin) against known largest Lyapunov exponents:
the Hénon map (a = 1.4, b = 0.3): 0.419 per iteration; the Lorenz system (σ = 10, ρ = 28,
β = 8/3): 0.906 per unit time (Sprott, "Chaos and Time-Series Analysis", 2003, table A.1)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planar_mbs.run.lyapunov import benettin

ROOT = Path(__file__).resolve().parents[1]


def _euclid(a, b):
    return float(np.linalg.norm(b - a))


def _pull(a, b, s):
    return a + s * (b - a)


def henon(x):
    return np.array([1 - 1.4 * x[0] ** 2 + x[1], 0.3 * x[0]])


def test_henon_map():
    x = np.array([0.1, 0.1])
    for _ in range(1000):
        x = henon(x)
    e = benettin(henon, x, x + np.array([1e-9, 0.0]), _euclid, _pull, 1e-9, 50_000, discard=100)
    assert e.value == pytest.approx(0.419, rel=0.02)
    # convergence: the running mean over the last half stays within 2 % as well
    assert np.all(np.abs(e.running[len(e.running) // 2:] / 0.419 - 1) < 0.02)


def test_lorenz_flow():
    from numba import njit

    @njit
    def flow(x, tau, dt):
        for _ in range(int(round(tau / dt))):
            k1 = np.array([10.0 * (x[1] - x[0]), x[0] * (28.0 - x[2]) - x[1], x[0] * x[1] - 8.0 / 3.0 * x[2]])
            u = x + dt / 2 * k1
            k2 = np.array([10.0 * (u[1] - u[0]), u[0] * (28.0 - u[2]) - u[1], u[0] * u[1] - 8.0 / 3.0 * u[2]])
            u = x + dt / 2 * k2
            k3 = np.array([10.0 * (u[1] - u[0]), u[0] * (28.0 - u[2]) - u[1], u[0] * u[1] - 8.0 / 3.0 * u[2]])
            u = x + dt * k3
            k4 = np.array([10.0 * (u[1] - u[0]), u[0] * (28.0 - u[2]) - u[1], u[0] * u[1] - 8.0 / 3.0 * u[2]])
            x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return x

    x = flow(np.array([1.0, 1.0, 1.0]), 50.0, 0.005)
    e = benettin(lambda u: flow(u, 1.0, 0.005), x, x + np.array([1e-8, 0.0, 0.0]), _euclid, _pull, 1e-8, 1500,
                 discard=10)
    assert e.value == pytest.approx(0.906, rel=0.02)


def test_a_contraction_has_its_exponent():
    """A linear map x -> 0.5 x: exponent ln 0.5 whatever d0 (the method is exact when linear)."""
    e = benettin(lambda x: 0.5 * x, np.zeros(2), np.array([1e-3, 0.0]), _euclid, _pull, 1e-3, 50, discard=0)
    assert e.value == pytest.approx(np.log(0.5), rel=1e-12)


OSCILLATOR = """
# A carriage on a rail held by a spring-damper at its rest length: m s'' + c s' + k (s - l0) = 0
param m = 2 kg
param k = 200 N/m
param c = 2 N*s/m
body carriage { mass = m  inertia = 0.02 kg*m^2  position = (0.2 m, 0) }
joint rail = translational(ground (0, 0), carriage (0, 0), axis = (1, 0))
force spring = spring_damper(ground (0, 0), carriage) { stiffness = k  damping = c  length = 0.2 m }
simulate { t_end = 1 s }
"""


def test_mechanism_exponent_of_a_damped_oscillator(tmp_path):
    """`mechanism_exponent` through the compiled time loop, against the closed form: after one damped
    period T_d = 2 pi / (w sqrt(1 - z^2)) every perturbation of m s'' + c s' + k s = 0 comes back to its
    own direction times exp(-c T_d / 2m), so each period's log growth is exactly -c T_d / 2m.  The
    companion is pulled back 16 times per period and both trajectories resume from where they stopped,
    so this also checks that a resumed trajectory continues from the state it was given."""
    from planar_mbs import load_model
    from planar_mbs.run.lyapunov import mechanism_exponent
    from planar_mbs.run.stepper import Stepper

    path = tmp_path / "oscillator.mbs"
    path.write_text(OSCILLATOR)
    m, k, c = 2.0, 200.0, 2.0
    w_d = np.sqrt(k / m - (c / (2 * m)) ** 2)
    period = 2 * np.pi / w_d
    expected = -c / (2 * m) * period  # -0.316 per period
    stepper = Stepper(load_model(path), integrator="dop853", rtol=1e-12, atol=1e-14, output_step=period / 16)
    e = mechanism_exponent(stepper, period, 16, seed=3, discard=2)
    assert e.value == pytest.approx(expected, rel=1e-6)
    assert np.allclose(e.logs, expected, rtol=1e-6)


PENDULUM = """
# A hinged arm on a torsion spring-damper: I_O th'' + c th' + k th = 0, I_O = 0.01 + 1 * 0.1^2 kg m^2
body arm { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0.1 m, 0) }
joint O = revolute(ground (0, 0), arm (-0.1 m, 0))
force hinge = rotational_spring_damper(ground, arm) { stiffness = 2 N*m/rad  damping = 0.12 N*m*s/rad  angle = 0 deg }
simulate { t_end = 1 s }
"""


@pytest.mark.parametrize("periods", [1, 2])
def test_floquet_and_benettin_of_a_damped_pendulum(tmp_path, periods):
    """A hinged arm (two constraint rows, so the perturbations must keep to the joint) whose angle obeys
    I th'' + c th' + k th = 0: both multipliers of any period map have modulus exp(-c T / 2I), and over
    the damped period T_d the map is exp(-c T_d / 2I) times the identity.  Floquet's finite differences
    and Benettin's renormalised companion must both give -c T / 2I per period (here about -0.99 over
    half the damped period), from any period, the rest position being periodic with every period."""
    from planar_mbs import load_model
    from planar_mbs.run.lyapunov import floquet_exponent, mechanism_exponent
    from planar_mbs.run.stepper import Stepper

    path = tmp_path / "pendulum.mbs"
    path.write_text(PENDULUM)
    inertia, k, c = 0.02, 2.0, 0.12
    period = np.pi / np.sqrt(k / inertia - (c / (2 * inertia)) ** 2)  # half the damped period
    expected = -c / (2 * inertia) * period
    stepper = Stepper(load_model(path), integrator="dop853", rtol=1e-11, atol=1e-14, output_step=period / 16)
    fl = floquet_exponent(stepper, period, periods)
    assert fl.value == pytest.approx(expected, rel=1e-6)
    assert np.allclose(np.abs(fl.multipliers), np.exp(expected * periods), rtol=1e-6)
    assert fl.closure == 0.0  # the rest position
    e = mechanism_exponent(stepper, period, 12, seed=1, discard=2)
    assert e.value == pytest.approx(expected, rel=1e-4)


@pytest.mark.parametrize("settings", [{"integrator": "dop853", "rtol": 1e-10, "atol": 1e-13}, {}],
                         ids=["tight", "shipped"])
@pytest.mark.parametrize("speed, law", [("5000rpm", "lankarani_nikravesh"), ("2500rpm", "lankarani_nikravesh")])
def test_benettin_and_floquet_agree_on_a_settled_journal(speed, law, settings):
    """The shipped slider-crank with clearance at A, soft (207 MPa) so that the journal settles in permanent
    contact within a few revolutions: on the periodic orbit it settles on, Benettin's companion (renormalised,
    both trajectories resumed 16 times a revolution) and Floquet's central differences (fresh copies, one
    revolution each) must give the same strongly negative exponent.  A companion allowed to drift off the
    constraints gave about 0 here (the drift is neutral), which no closed form of a single joint shows.
    Both at tight tolerances and with the model's own settings (no solver setting named).  The soft contact is
    not physical (the journal sinks millimetres into a 0.3 mm clearance): allowed here, as a check of the two
    methods on a settled orbit."""
    from planar_mbs import load_model
    from planar_mbs.run.lyapunov import floquet_exponent, mechanism_exponent
    from planar_mbs.run.stepper import Stepper

    model = load_model(ROOT / "models" / "slider_crank_clearance_a.mbs", speed=speed, youngs_modulus="207MPa", law=law)
    period = 60.0 / float(speed[:-3])  # one crank revolution
    stepper = Stepper(model, allow_unphysical=True, output_step=period / 16, **settings)
    stepper.run_to(30 * period)
    fl = floquet_exponent(stepper, period)
    assert fl.closure < 1e-6  # settled on a period-1 orbit
    e = mechanism_exponent(stepper, period, 20, discard=5)
    assert fl.value < -0.5 and e.value < -0.5
    assert e.value == pytest.approx(fl.value, rel=0.1)


@pytest.mark.slow
def test_benettin_after_a_long_transient_neither_stops_nor_drifts():
    """The case of docs/replication.md whose companion used to stop: clearance at A, 207 GPa, 5000 rpm, 1000
    revolutions at rtol 1e-6 (chaotic for hundreds, then the journal closes for good), Benettin from the
    final state at the Lyapunov settings.  A reference left unprojected carried a residual just below the
    bound, and a pull-back by s put (1 - s) times it into the companion: "the constraints gave way" for one
    perturbed direction in five.  Every direction must now run and agree with Floquet's estimate (with
    its default difference step, which must resolve multipliers of about 3e-3 above the integration
    error)."""
    from planar_mbs import load_model
    from planar_mbs.run.lyapunov import floquet_exponent, mechanism_exponent
    from planar_mbs.run.stepper import Stepper
    from planar_mbs.run.study import long_run

    model = load_model(ROOT / "models" / "slider_crank_clearance_a.mbs", speed="5000rpm", youngs_modulus="207GPa",
                       law="lankarani_nikravesh")
    run = long_run(model, 1000, 8, ["slider.vx", "slider.ax", "crank.phi"], rtol=1e-6, atol=1e-9)
    period = run.period
    stepper = Stepper.restore(model, run.stepper.y, run.stepper.contact, run.stepper.t,
                              integrator="dop853", rtol=1e-10, atol=1e-13, output_step=period / 16)
    values = [mechanism_exponent(stepper, period, 60, seed=seed).value for seed in range(5)]
    settled = stepper.copy()
    settled.run_to(stepper.t + 10 * period)  # onto the orbit of these settings
    fl = floquet_exponent(settled, period)
    assert fl.closure < 1e-6
    assert fl.value < -1.0
    assert np.allclose(values, fl.value, rtol=0.05)


def test_a_mechanism_without_freedom_is_refused_in_words(tmp_path):
    """A crank turned by its driver has no motion of its own: no exponent and no multipliers, said in words."""
    from planar_mbs import load_model
    from planar_mbs.run.lyapunov import floquet_exponent, mechanism_exponent
    from planar_mbs.run.stepper import Stepper

    path = tmp_path / "crank.mbs"
    path.write_text("body crank { mass = 1 kg  inertia = 1 kg*m^2  position = (0.5, 0) }\n"
                    "joint O = revolute(ground (0, 0), crank (-0.5, 0))\n"
                    "driver turn = rotation(crank, speed = 60 rpm)\nsimulate { t_end = 1 s }\n")
    with pytest.raises(ValueError, match="no Lyapunov exponent or Floquet multiplier"):
        floquet_exponent(Stepper(load_model(path)), 1.0)
    with pytest.raises(ValueError, match="no Lyapunov exponent or Floquet multiplier"):
        mechanism_exponent(Stepper(load_model(path)), 1.0, 12)
