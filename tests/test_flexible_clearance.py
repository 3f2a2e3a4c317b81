"""models/slider_crank_flexible_rod_clearance.mbs, the clearance slider-crank of Muvengei, Kihiu and Ikua
with its connecting rod a steel beam whose start node is the journal of the clearance joint A: its rod
has the rigid rod's mass, a very stiff beam reproduces the rigid rod's clearance model until the chaotic
motion parts them (the deviation is the beam's compliance: it falls as 1/E), the shipped model closes its
energy balance, and the numbers docs/beams.md quotes are what docs/scripts/flexible_clearance.py computes."""
from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.mechanism.compile import compile_text
from planar_mbs.run.checks import BALANCE_PER_RTOL

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
FLEXIBLE = MODELS / "slider_crank_flexible_rod_clearance.mbs"
RIGID = MODELS / "slider_crank_clearance_a.mbs"
sys.path.insert(0, str(ROOT / "docs" / "scripts"))

import flexible_clearance as F  # noqa: E402

# the rod of the model file: steel 7800 kg/m^3, 0.12 m, 22.44 mm by 10 mm
RHO, L, W, H = 7800.0, 0.12, 22.44e-3, 10e-3
CLEARANCE = 0.3e-3


def _rigid_rod(model):
    """(mass, inertia) of the rigid body `rod` of a compiled model."""
    k = model.body_names.index("rod")
    return float(model.kernel.body_mass[k]), float(model.kernel.body_inertia[k])


def test_the_beam_rod_has_the_rigid_rod_s_mass_and_nearly_its_inertia():
    """rho W H L from the section of the file is the compiled beam's mass (rho A times its length), within
    0.05 % of the rigid rod's 0.21 kg; its inertia m L^2 / 12 (no rotary inertia of the section) within 1 %
    of the rigid rod's, as the model's comment says.  Four elements: node 2 is the midpoint."""
    beam = mbs.load_model(FLEXIBLE)
    length, rho_a = beam.kernel.beam_param[0, 0], beam.kernel.beam_param[0, 4]
    elements = int(beam.kernel.beam_info[0, 1])
    assert elements % 2 == 0 and length * elements == pytest.approx(L, rel=1e-12)
    m = RHO * W * H * L
    assert rho_a * L == pytest.approx(m, rel=1e-12)
    m_rigid, i_rigid = _rigid_rod(mbs.load_model(RIGID))
    assert abs(m / m_rigid - 1) < 5e-4
    assert abs(m * L ** 2 / 12 / i_rigid - 1) < 1e-2


def _onsets(res) -> np.ndarray:
    """The output samples at which joint A's contact starts."""
    on = np.asarray(res["A.in_contact"]) > 0.5
    return np.flatnonzero(on[1:] & ~on[:-1]) + 1


def test_a_very_stiff_beam_rod_is_the_rigid_rod_until_the_motion_diverges():
    """The beam at 100 and 1000 times steel's modulus against the rigid clearance model given the beam's
    mass and inertia (m = rho A L, m L^2 / 12), over the first 1.2 ms: four impacts, before the chaotic
    motion amplifies the smallest difference into another impact sequence.  The beam's elastic
    displacements (axial F L / EA, bending F L^3 / EI) are first order in 1/E, and so, while they are
    small against the clearance, is the deviation they cause however the impacts amplify it: tenfold E,
    a tenth of the deviation.  Second-order terms are of the deviation over the clearance (about 2 % at
    100 E) and the integration's error at rtol 1e-8 (~1e-9 m on the slider's 0.17 m) is under 1 % of the
    stiffer beam's deviation, so the ratio is 10 within 10 %.  A deviation the stiffness does not explain
    pulls it below: a journal sized or placed unlike the rigid rod's end, or even the shipped rigid rod's
    inertia, 0.8 % below the beam's (the reason the reference here is given the beam's).  At 1000 E the
    slider stays within a hundredth of the clearance of the rigid rod's, and the contacts start at the
    same output samples (to one)."""
    m = RHO * W * H * L
    rigid = compile_text(f'include "{RIGID.name}"\noverride body rod {{ mass = {m!r} kg  '
                         f'inertia = {m * L ** 2 / 12!r} kg*m^2  position = (0.110 m, 0) }}\n',
                         str(MODELS / "stiff_limit.mbs"))
    t_end = 1.2e-3
    ref = mbs.simulate(rigid, t_end=t_end)
    x_ref = np.asarray(ref["slider.x"])
    deviation = {}
    for factor in (100, 1000):
        res = mbs.simulate(mbs.load_model(FLEXIBLE, rod_modulus=f"{207 * factor} GPa"), t_end=t_end)
        deviation[factor] = np.abs(np.asarray(res["slider.x"]) - x_ref).max()
        on, on_ref = _onsets(res), _onsets(ref)
        assert len(on_ref) >= 4 and len(on) == len(on_ref) and np.abs(on - on_ref).max() <= 1, (on, on_ref)
    assert deviation[1000] < CLEARANCE / 100, deviation
    assert 9 < deviation[100] / deviation[1000] < 11, deviation


def test_the_shipped_model_closes_its_energy_balance():
    """Two revolutions at the model's own settings: the energy balance (T + V - (T + V)(0) - input work +
    dissipated) stays within the run's check, BALANCE_PER_RTOL rtol of the run's energy scale, with no
    warning; and the check is not idle: the contact's hysteresis dissipates over a hundred times that
    bound, which the balance would miss if the beam node's contact work went unbooked."""
    model = mbs.load_model(FLEXIBLE)
    res = mbs.simulate(model, revolutions=2, signals=["system", "A"])
    assert not res.attrs.get("warnings"), res.attrs.get("warnings")
    scale = max(np.abs(np.asarray(res[f"system.{q}"])).max() for q in ("kinetic_energy", "input_work", "dissipated"))
    bound = BALANCE_PER_RTOL * model.settings.rtol * scale
    assert np.abs(np.asarray(res["system.energy_balance"])).max() < bound
    assert np.asarray(res["A.dissipated"])[-1] > 100 * bound


def test_the_midpoint_deflection_is_the_distance_from_the_chord():
    """`flexible_clearance.midpoint_deflection` on nodes placed on a circular arc of radius R and angle
    2a, turned and shifted: the middle node's distance from the chord is the sagitta R (1 - cos a), on the
    chord's left for an arc bending to the left; an odd element count has no middle node."""
    R, a, turn, shift = 0.3, 0.2, 0.7, np.array([0.05, -0.02])
    res = {}
    for k, s in enumerate(np.linspace(-a, a, 5)):  # 4 elements; the arc's centre to the chord's left
        p = np.array([R * math.sin(s), R * (1 - math.cos(s))])
        p = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]]) @ p + shift
        res[f"rod_node{k}.x"], res[f"rod_node{k}.y"] = np.array([p[0]]), np.array([p[1]])
    assert F.midpoint_deflection(res)[0] == pytest.approx(-R * (1 - math.cos(a)), rel=1e-12)
    del res["rod_node4.x"], res["rod_node4.y"]
    with pytest.raises(ValueError, match="even count"):
        F.midpoint_deflection(res)


def test_the_numbers_of_the_beams_page_are_the_script_s():
    """docs/beams.md "A flexible rod in a clearance joint" quotes the sentence the figure's script makes
    of its two runs (largest midpoint deflection, peak contact forces)."""
    flexible, rigid = F.runs()
    text = " ".join((ROOT / "docs" / "beams.md").read_text(encoding="utf-8").split())
    assert F.prose(F.summary(flexible, rigid)) in text


def test_the_page_s_model_text_is_the_shipped_model_s():
    """The model text docs/beams.md shows in that section is line by line the shipped model's."""
    page = (ROOT / "docs" / "beams.md").read_text(encoding="utf-8")
    section = page[page.index("## A flexible rod in a clearance joint"):]
    block = re.search(r"```mbs fragment\n(.*?)```", section, re.S).group(1)
    norm = lambda line: " ".join(line.split("#")[0].split())  # noqa: E731
    shipped = {norm(line) for line in FLEXIBLE.read_text(encoding="utf-8").splitlines()}
    lines = [norm(line) for line in block.splitlines() if norm(line)]
    assert len(lines) >= 8 and [line for line in lines if line not in shipped] == []


@pytest.mark.slow
def test_the_shipped_tolerance_gives_the_first_revolution_to_a_tenth_of_a_percent():
    """The criterion the rigid model's rtol was chosen by (docs/numerics.md): the first revolution's slider
    velocity at the shipped settings within 0.1 % of its largest value from DOP853 at rtol 1e-11."""
    from planar_mbs.results.section import driver_period

    model = mbs.load_model(FLEXIBLE)
    T = driver_period(model)[0]
    assert T == pytest.approx(60 / 5000)
    kw = dict(t_end=T, output_step=T / 1200, signals=["slider.vx"])
    v = np.asarray(mbs.simulate(model, **kw)["slider.vx"])
    ref = np.asarray(mbs.simulate(model, integrator="dop853", rtol=1e-11, atol=1e-14, **kw)["slider.vx"])
    assert np.abs(v - ref).max() < 1e-3 * np.abs(ref).max()
