"""End-to-end accuracy of text → model → assembly → compiled time loop, against
references derived independently in this file (closed forms, energy)."""
from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.mechanism.compile import compile_text
from planar_mbs.errors import SimulationError

MODELS = Path(__file__).resolve().parents[1] / "models"

R, L = 0.05, 0.12  # crank and rod length of Muvengei et al. (§III.A)
M_CRANK, M_ROD, M_SLIDER = 0.30, 0.21, 0.14
I_CRANK, I_ROD = 1e-5, 2.5e-4
OMEGA = 5000 * 2 * np.pi / 60


def slider_crank_closed_form(t):
    """Ideal slider-crank at constant crank speed, crank angle 0 at t = 0 (collinear).

    Returns positions, velocities and accelerations of the bodies from
    x = r cos θ + √(l² − r² sin² θ) and its time derivatives (θ' = ω, θ'' = 0).
    """
    th = OMEGA * t
    s, c = R * np.sin(th), R * np.cos(th)
    D = np.sqrt(L**2 - s**2)
    x = c + D
    vx = -OMEGA * s - OMEGA * s * c / D
    ax = -OMEGA**2 * c - OMEGA**2 * ((c**2 - s**2) / D + s**2 * c**2 / D**3)
    # connecting-rod angle psi: l sin psi = -r sin theta
    psi_d = -c * OMEGA / D
    psi_dd = s * OMEGA**2 * (D**2 - c**2) / D**3
    A_v = np.stack([-OMEGA * s, OMEGA * c])
    A_a = np.stack([-OMEGA**2 * c, -OMEGA**2 * s])
    B_v = np.stack([vx, 0 * vx])
    B_a = np.stack([ax, 0 * ax])
    return dict(x=x, vx=vx, ax=ax, psi_d=psi_d, psi_dd=psi_dd, A_v=A_v, A_a=A_a, B_v=B_v, B_a=B_a)


def inverse_dynamics_torque(t):
    """Crank torque by the power balance T ω = d/dt(kinetic energy) (no gravity, no friction):
    T = Σ (m v·a + I φ' φ'') / ω over the three bodies — independent of the solver's multipliers."""
    k = slider_crank_closed_form(t)
    crank = M_CRANK * np.sum(0.5 * k["A_v"] * 0.5 * k["A_a"], axis=0)
    rod_v, rod_a = 0.5 * (k["A_v"] + k["B_v"]), 0.5 * (k["A_a"] + k["B_a"])
    rod = M_ROD * np.sum(rod_v * rod_a, axis=0) + I_ROD * k["psi_d"] * k["psi_dd"]
    slider = M_SLIDER * k["vx"] * k["ax"]
    return (crank + rod + slider) / OMEGA


@pytest.fixture(scope="module")
def ideal_run():
    model = mbs.load_model(MODELS / "slider_crank.mbs")
    t_end = 2 * 2 * np.pi / OMEGA  # two revolutions
    return mbs.simulate(model, t_end=t_end, rtol=1e-10, integrator="dopri5", output_step=t_end / 400)


def test_ideal_slider_crank_matches_closed_form(ideal_run):
    res = ideal_run
    ref = slider_crank_closed_form(res.time)
    assert res.complete and len(res.time) == 401
    assert np.max(np.abs(res["slider.x"] - ref["x"])) <= 1e-9
    assert np.max(np.abs(res["slider.vx"] - ref["vx"])) <= 1e-6
    assert np.max(np.abs(res["slider.ax"] - ref["ax"])) <= 1e-6 * np.max(np.abs(ref["ax"]))


def test_ideal_slider_crank_torque_matches_inverse_dynamics(ideal_run):
    res = ideal_run
    torque = res["crank_speed.torque"]
    ref = inverse_dynamics_torque(res.time)
    assert np.max(np.abs(torque - ref)) <= 1e-6 * np.max(np.abs(ref))
    # the power the driver puts in is what it reports
    np.testing.assert_allclose(res["crank_speed.power"], torque * OMEGA, rtol=1e-9, atol=1e-9)


def test_ideal_joint_reaction_balances_slider(ideal_run):
    """Newton on the slider: the reactions of B and S on it (the slider is the second
    body of both) add up to m a; the translational joint S pushes only across its axis."""
    res = ideal_run
    fx = res["B.fx"] + res["S.fx"]
    fy = res["B.fy"] + res["S.fy"]
    scale = np.max(np.abs(fx))
    assert np.max(np.abs(res["S.fx"])) <= 1e-9 * scale
    np.testing.assert_allclose(fx, M_SLIDER * res["slider.ax"], rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(fy, 0.0, rtol=0, atol=1e-8 * scale)


DOUBLE_PENDULUM = """
body upper { mass = 1.0 kg  inertia = 0.02 kg*m^2  position = (0.25, 0) }
body lower { mass = 0.5 kg  inertia = 0.01 kg*m^2  position = (0.5, -0.2)  angle = -90 deg }
joint P = revolute(ground (0, 0), upper (-0.25, 0))
joint Q = revolute(upper (0.25, 0), lower (0.2, 0))
gravity (0, -9.81 m/s^2)
simulate { t_end = 10 s  rtol = 1e-10  atol = 1e-12  output_step = 10 ms }
"""


def test_undriven_double_pendulum_keeps_its_energy():
    model = compile_text(DOUBLE_PENDULUM, "double_pendulum.mbs")
    res = mbs.simulate(model)
    energy = res["system.total_energy"]
    scale = np.max(res["system.kinetic_energy"])  # energy exchanged during the motion
    assert scale > 1.0  # it really swings
    assert np.max(np.abs(energy - energy[0])) <= 1e-8 * scale
    assert np.max(res["system.position_error"]) < 1e-9


def test_clearance_model_runs_five_revolutions_and_journal_stays_inside():
    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    res = mbs.simulate(model)
    revs = res.time[-1] * OMEGA / (2 * np.pi)
    assert res.complete and revs == pytest.approx(5, rel=1e-9)
    c = 0.3e-3
    # Every impact is caught by the contact force: no journal tunnels through the wall.
    # (Peak penetrations are tens of µm: the first impact at ~3 m/s with K = 4.2e10 N/m^1.5
    # stores ~1 J at d = (2.5 E / K)^(2/5) ≈ 0.1 mm.)
    assert np.max(res["A.e"]) < 1.5 * c
    assert np.max(res["A.penetration"]) > 0  # it did hit the wall
    assert res.attrs["n_contact_events"] > 0
    # contact force only while in contact mode
    assert np.all(res["A.contact_force"][res["A.in_contact"] == 0] == 0)


def test_clearance_model_energy_balance_and_contact_force_from_the_published_law():
    """The flagship run (Lankarani-Nikravesh, ce = 0.9, 5 revolutions at 5000 rpm) at a tight
    tolerance, checked against two references derived here:

    * the contact force at every in-contact sample equals the published law
      F = K d^1.5 (1 + 3 (1 - ce^2)/4 d'/d'(-))  (Lankarani & Nikravesh 1990; Muvengei et al.
      eq. 21) with K from eq. 18 written out below (steel, R_B = 5 mm, c = 0.3 mm) and d' the
      numerical derivative of the penetration signal;
    * energy balance: the driver's work minus the change of total energy (kinetic, gravity,
      contact spring) equals the energy the contact's damping term dissipated,
      int (F - K d^1.5) d' dt.
    Measured: force within 4e-5 of the peak force, balance within 3e-4 of the dissipated energy."""
    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    res = mbs.simulate(model, rtol=1e-10, atol=1e-12, output_step=1e-6)
    t = res.time
    sigma = (1 - 0.3**2) / 207e9
    RB, c, ce = 5e-3, 0.3e-3, 0.9
    K = 4 / (3 * 2 * sigma) * np.sqrt(RB * (RB - c) / c)  # eq. 18, both parts steel
    F, d, v_imp = res["A.contact_force"], res["A.penetration"], res["A.impact_velocity"]
    touching = res["A.in_contact"] > 0
    d_dot = np.gradient(d, t)
    inner = touching & np.roll(touching, 1) & np.roll(touching, -1) & (d > 0)  # away from onsets
    assert inner.sum() > 1000
    published = K * d[inner] ** 1.5 * (1 + 0.75 * (1 - ce**2) * d_dot[inner] / v_imp[inner])
    assert np.max(np.abs(F[inner] - published)) < 1e-3 * F.max()

    def work(y):  # trapezoidal integral from t = 0
        return np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))])

    energy = res["system.total_energy"]
    driver_work = work(res["crank_speed.power"])
    damping = np.where(touching & (d > 0), F - K * np.maximum(d, 0) ** 1.5, 0.0)
    dissipated = work(damping * d_dot)
    assert dissipated[-1] > 1.0  # J: the impacts really dissipate
    balance = driver_work - (energy - energy[0]) - dissipated
    assert np.max(np.abs(balance)) < 1e-3 * dissipated[-1]


def test_failure_keeps_results_and_says_why(tmp_path):
    model = mbs.load_model(MODELS / "slider_crank.mbs")
    out = tmp_path / "fail.h5"
    with pytest.raises(SimulationError) as info:
        mbs.simulate(model, output=out, max_steps=20)
    assert "max_steps" in info.value.message
    kept = mbs.read_results(out)
    assert not kept.complete and kept.attrs["status"] == "max_steps"
    assert len(kept.time) >= 1


def test_journal_sinking_deeper_than_the_clearance_is_flagged(tmp_path):
    """1 µm of clearance with steel: the journal sinks ~7 µm at impacts (Hertz with K = 4e10 and
    ~0.1-1 J impacts), more than the clearance, so the run warns that it is not physical; the
    shipped 0.3 mm case does not warn."""
    soft = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs", clearance="1 um")
    with pytest.raises(SimulationError) as info:  # finished, but not physical: not complete
        mbs.simulate(soft, output=tmp_path / "soft.h5", t_end=0.01)
    res = info.value.results
    assert np.max(res["A.penetration"]) > 1e-6
    (warning,) = res.attrs["warnings"]
    assert "`A`" in warning and "not physical" in warning
    kept = mbs.read_results(tmp_path / "soft.h5")
    assert kept.attrs["warnings"] == [warning] and kept.attrs["status"] == "not_physical" and not kept.complete
    assert kept.attrs["t_reached"] == pytest.approx(0.01) and "not physical" in kept.attrs["message"]
    fine = mbs.simulate(mbs.load_model(MODELS / "slider_crank_clearance_a.mbs"), t_end=0.01)
    assert fine.attrs["warnings"] == []


INCLINE = """
gravity (0, -9.81 m/s^2)
body s { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0, 0)  angle = 30 deg }
joint S = translational(ground (0, 0), s (0.05, 0.02), axis = (1, 1))
simulate { t_end = 0.2 s  output_step = 1 ms  rtol = 1e-10  atol = 1e-12 }
"""


def test_reaction_moment_is_taken_about_the_joint_point_of_the_body():
    """A block held at 30 degrees on an inclined rail, its joint point off its centre: nothing turns it,
    so the constraint's moment about the centre is zero and the stored moment about the joint point is
    (centre - point) x force, with the point computed here from the stored pose (the observation row
    takes the bodies' cos/sin from the dynamics instead of computing them again)."""
    res = mbs.simulate(compile_text(INCLINE, "<incline>"))
    x, y, phi = res["s.x"], res["s.y"], res["s.phi"]
    assert np.allclose(phi, np.radians(30), atol=1e-9) and np.ptp(x) > 0.05  # it slides, it does not turn
    px = x + np.cos(phi) * 0.05 - np.sin(phi) * 0.02
    py = y + np.sin(phi) * 0.05 + np.cos(phi) * 0.02
    fx, fy = res["S.fx"], res["S.fy"]
    expected = (x - px) * fy - (y - py) * fx
    assert np.max(np.abs(expected)) > 0.1  # a moment worth checking: the point is off the centre
    np.testing.assert_allclose(res["S.moment"], expected, atol=1e-9 * np.max(np.abs(expected)))


# ---------------------------------------------------------------- only what the kept signals need
def test_signals_without_dynamics_skip_accelerations_and_match_the_closed_form(ideal_run, tmp_path):
    """Signals that read no acceleration, reaction or driver effort: the time loop skips their
    `accelerations` per row (their columns of the observation row stay NaN), and what is kept is
    still the closed form, and the very numbers of a run that keeps everything (the outputs never
    steer the integration).  The file reads as ever with plain h5py and pandas."""
    import h5py
    import pandas as pd

    from planar_mbs.mechanism.model import OBS_SKIP_DYNAMICS, OBS_SKIP_ERRORS
    from planar_mbs.results.signals import signal_table, skip_bits
    from planar_mbs.run.simulation import select_signals

    model = mbs.load_model(MODELS / "slider_crank.mbs")
    wanted = ["slider.x", "slider.vx", "crank.phi", "system.kinetic_energy"]
    _, cols = select_signals(signal_table(model), wanted)
    assert skip_bits(model, cols) & OBS_SKIP_DYNAMICS and skip_bits(model, cols) & OBS_SKIP_ERRORS
    t_end = ideal_run.time[-1]
    res = mbs.simulate(model, t_end=t_end, rtol=1e-10, integrator="dopri5", output_step=t_end / 400,
                       signals=wanted, output=tmp_path / "kin.h5")
    ref = slider_crank_closed_form(res.time)
    assert np.max(np.abs(res["slider.x"] - ref["x"])) <= 1e-9
    assert np.max(np.abs(res["slider.vx"] - ref["vx"])) <= 1e-6
    np.testing.assert_allclose(res["crank.phi"], OMEGA * res.time, rtol=0, atol=1e-9)
    k = slider_crank_closed_form(res.time)
    rod_v = 0.5 * (k["A_v"] + k["B_v"])
    kinetic = (0.5 * M_CRANK * np.sum((0.5 * k["A_v"]) ** 2, axis=0) + 0.5 * I_CRANK * OMEGA**2
               + 0.5 * M_ROD * np.sum(rod_v**2, axis=0) + 0.5 * I_ROD * k["psi_d"] ** 2
               + 0.5 * M_SLIDER * k["vx"] ** 2)
    np.testing.assert_allclose(res["system.kinetic_energy"], kinetic, rtol=1e-6)
    for name in wanted:
        np.testing.assert_array_equal(res[name], ideal_run[name])
    with h5py.File(tmp_path / "kin.h5", "r") as f:
        assert sorted(f["signals"]) == ["crank", "slider", "system"]
        np.testing.assert_array_equal(f["signals/slider"]["vx"], ideal_run["slider.vx"])
        frame = pd.DataFrame(f["signals/slider"][()])
    assert list(frame.columns) == ["x", "vx"] and np.all(np.isfinite(frame.to_numpy()))


def test_skipped_columns_of_the_observation_row_are_nan_and_the_rest_unchanged():
    """The kernel's own row: with every OBS_SKIP_* bit set only q and q' are computed, the other
    columns are NaN; q and q' are those of the full row; each bit alone blanks only its group."""
    from planar_mbs.kernel import make_workspace, observe
    from planar_mbs.mechanism.kinematics import assemble
    from planar_mbs.mechanism.model import (CFG_SKIP, OB_CLEARANCE, OB_QDD, OB_SYSTEM, OBS_SKIP_CLEARANCE,
                                  OBS_SKIP_DYNAMICS, OBS_SKIP_ENERGY, OBS_SKIP_ERRORS, OBS_SKIP_LOADS,
                                  SYS_BALANCE, SYS_DISSIPATED, SYS_GRAVITY_POWER, SYS_GRAVITY_WORK,
                                  SYS_INPUT_WORK, SYS_KINETIC, SYS_POTENTIAL, SYS_POSITION_ERROR,
                                  SYS_VELOCITY_ERROR, OB_FORCE, N_CONTACT_STATE, observation_layout,
                                  observation_size)

    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    km = model.kernel
    q, qd = assemble(model)
    y = np.concatenate([q, qd])
    lay = observation_layout(model.nbody, model.njoint, model.ndriver, model.nclearance, model.nforce)
    n = observation_size(model.nbody, model.njoint, model.ndriver, model.nclearance, model.nforce)
    contact = np.zeros((model.nclearance, N_CONTACT_STATE))

    def row(bits):
        cfg = model.settings.cfg()
        cfg[CFG_SKIP] = bits
        out = np.zeros(n)
        assert observe(km, cfg, 0.0, y, contact, make_workspace(km), out) == 0
        return out

    full = row(0)
    assert np.all(np.isfinite(full))
    groups = {OBS_SKIP_DYNAMICS: range(lay[OB_QDD], lay[OB_CLEARANCE]),
              OBS_SKIP_CLEARANCE: range(lay[OB_CLEARANCE], lay[OB_FORCE]),
              OBS_SKIP_ENERGY: [lay[OB_SYSTEM] + i for i in (SYS_KINETIC, SYS_POTENTIAL, SYS_INPUT_WORK, SYS_DISSIPATED, SYS_BALANCE)],
              OBS_SKIP_ERRORS: [lay[OB_SYSTEM] + i for i in (SYS_POSITION_ERROR, SYS_VELOCITY_ERROR)],
              OBS_SKIP_LOADS: [lay[OB_SYSTEM] + SYS_GRAVITY_POWER]}
    for bit, cols in groups.items():
        part = row(bit)
        blank = np.zeros(n, bool)
        blank[list(cols)] = True
        assert np.all(np.isnan(part[blank])) and np.array_equal(part[~blank], full[~blank])
    bare = row(sum(groups))
    works = [lay[OB_SYSTEM] + SYS_GRAVITY_WORK, *range(lay[OB_FORCE], lay[OB_SYSTEM])]  # no force here: drivers'
    assert model.nforce == 0
    blank = np.ones(n, bool)
    blank[:lay[OB_QDD]] = False
    blank[works] = False
    assert np.array_equal(bare[:lay[OB_QDD]], y) and np.all(np.isnan(bare[blank]))
    assert np.all(bare[works] == 0.0)  # the works, kept always: 0 at a run's start


def test_reactions_kept_alone_balance_the_slider_and_torque_matches_inverse_dynamics(ideal_run):
    """Joint reactions and the driver's torque kept without the bodies' signals: still computed
    (the row's `accelerations`), Newton on the slider against the closed-form acceleration and
    the torque against the power balance, both derived in this file."""
    model = mbs.load_model(MODELS / "slider_crank.mbs")
    t_end = ideal_run.time[-1]
    res = mbs.simulate(model, t_end=t_end, rtol=1e-10, integrator="dopri5", output_step=t_end / 400,
                       signals=["B", "S", "crank_speed.torque"])
    assert sorted(res.signals) == ["B.force", "B.fx", "B.fy", "S.force", "S.fx", "S.fy", "S.moment",
                                   "crank_speed.torque"]
    ax = slider_crank_closed_form(res.time)["ax"]
    fx, fy = res["B.fx"] + res["S.fx"], res["B.fy"] + res["S.fy"]
    scale = np.max(np.abs(fx))
    np.testing.assert_allclose(fx, M_SLIDER * ax, rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(fy, 0.0, rtol=0, atol=1e-8 * scale)
    ref = inverse_dynamics_torque(res.time)
    assert np.max(np.abs(res["crank_speed.torque"] - ref)) <= 1e-6 * np.max(np.abs(ref))
    np.testing.assert_allclose(res["B.force"], np.hypot(res["B.fx"], res["B.fy"]), rtol=1e-15)


def test_clearance_signals_kept_alone_match_the_full_run_and_the_step_api():
    """A clearance joint's signals without the dynamics' columns: the same numbers as the full
    run (contact detection is the time loop's, not the row's), through `simulate` and `Simulation`."""
    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    full = mbs.simulate(model, t_end=0.01)
    assert np.max(full["A.penetration"]) > 0  # an impact inside the window
    part = mbs.simulate(model, t_end=0.01, signals=["A", "system.total_energy"])
    with mbs.Simulation(model, t_end=0.01, signals=["A"]) as sim:
        stepped = sim.run()
    for name in part.signals:
        np.testing.assert_array_equal(part[name], full[name])
    for name in stepped.signals:
        np.testing.assert_array_equal(stepped[name], full[name])
