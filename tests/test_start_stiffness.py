"""The stiffness of a start (`mechanism/start_stiffness.py`) against closed forms derived here: a free
disc pressed into a floor (Hertz: omega^2 = n K d^(n-1) / m; Lankarani-Nikravesh at rest: lambda =
chi K d^n / (v_floor m)), the same circle on a hinged arm (the effective mass I / a^2 of the hinge),
and a free journal centred in a lubricated bearing (the squeeze film's pi mu R L^3 / (2 c^3 m))."""
from __future__ import annotations

import dataclasses
import math

import pytest

from planar_mbs.errors import ModelError
from planar_mbs.mechanism.compile import compile_text
from planar_mbs.mechanism.kinematics import assemble
from planar_mbs.mechanism.model import Integrator
from planar_mbs.mechanism.start_stiffness import STABLE_STEP, check_step_count, start_contacts, steps_needed

K, N, M, R, DEPTH = 2e9, 1.5, 2.0, 0.05, 1e-4
FLOOR = """
body disc {{ mass = {m} kg  inertia = 1e-3 kg*m^2  position = (0, {y} m) }}
joint floor = contact(ground (0, 0), disc) {{
    shape = circle_on_line  normal = (0, 1)  radius = {r} m  stiffness = {k} N/m^1.5  {law}
}}
simulate {{ t_end = 0.1 s }}
"""


def _contacts(text):
    model = compile_text(text)
    q, qd = assemble(model)
    return model, start_contacts(model, q, qd), q, qd


def test_an_elastic_contact_pressed_in_has_its_hertz_frequency():
    _, (c,), _, _ = _contacts(FLOOR.format(m=M, y=R - DEPTH, r=R, k=K, law="law = hertz"))
    assert c.depth == pytest.approx(DEPTH, rel=1e-9) and c.size == R and not c.deep
    assert c.stiff == "stiffness"
    assert c.rate == pytest.approx(math.sqrt(N * K * DEPTH ** (N - 1) / M), rel=1e-4)


def test_a_dissipative_contact_at_rest_has_the_damping_of_its_floored_impact_velocity():
    e = 0.8
    _, (c,), _, _ = _contacts(FLOOR.format(m=M, y=R - DEPTH, r=R, k=K,
                                           law=f"law = lankarani_nikravesh  restitution = {e}"))
    chi = 0.75 * (1 - e * e)
    assert c.stiff == "damping"
    assert c.rate == pytest.approx(chi * K * DEPTH ** N / (1e-5 * M), rel=1e-4)


def test_a_contact_apart_is_not_counted():
    _, contacts, _, _ = _contacts(FLOOR.format(m=M, y=R + 1e-3, r=R, k=K, law="law = hertz"))
    assert contacts == []


def test_the_hinge_gives_the_effective_mass_along_the_normal():
    """The circle at (a, 0) on an arm hinged at its centre: the contact point moves a theta' along the
    normal, so the mass it meets is I / a^2 (the arm's mass is held by the hinge)."""
    a, inertia = 0.1, 4e-3
    text = f"""
body arm {{ mass = 3 kg  inertia = {inertia} kg*m^2  position = (0, {R - DEPTH} m) }}
joint hinge = revolute(ground (0, {R - DEPTH}), arm (0, 0))
joint floor = contact(ground (0, 0), arm ({a}, 0)) {{
    shape = circle_on_line  normal = (0, 1)  radius = {R} m  stiffness = {K} N/m^1.5  law = hertz
}}
simulate {{ t_end = 0.1 s }}
"""
    _, (c,), _, _ = _contacts(text)
    assert c.rate == pytest.approx(math.sqrt(N * K * DEPTH ** (N - 1) * a * a / inertia), rel=1e-4)


def test_a_centred_lubricated_journal_has_its_squeeze_film_damping():
    mu, rb, length, cl, m = 0.04, 5e-3, 0.02, 3e-4, 0.2
    text = f"""
material steel {{ E = 207 GPa  nu = 0.3  density = 7800 kg/m^3 }}
body journal {{ mass = {m} kg  inertia = 1e-5 kg*m^2  position = (0, 0) }}
joint A = lubricated_revolute(ground (0, 0), journal (0, 0)) {{
    clearance = {cl} m  bearing_radius = {rb} m  length = {length} m  viscosity = {mu} Pa*s
    breakdown = 0.95  material = steel  law = lankarani_nikravesh  restitution = 0.9
}}
simulate {{ t_end = 0.1 s }}
"""
    model, (c,), q, qd = _contacts(text)
    rj = rb - cl
    assert c.depth < 0 and c.stiff == "damping" and c.kind == "clearance joint"
    assert c.rate == pytest.approx(math.pi * mu * rj * length ** 3 / (2 * cl ** 3 * m), rel=1e-4)
    steps, fastest = steps_needed(model.settings, [c])
    assert fastest is c and steps == pytest.approx(0.1 * c.rate / STABLE_STEP)
    check_step_count(model, model.settings, q, qd)  # 0.1 s of it: a few steps


def test_the_step_count_is_refused_beyond_max_steps_and_not_for_a_fixed_step():
    model, (c,), q, qd = _contacts(FLOOR.format(m=M, y=R - DEPTH, r=R, k=K, law="law = hertz"))
    limit = int(0.1 * c.rate / STABLE_STEP)
    with pytest.raises(ModelError, match="`floor` starts 0.1 mm inside"):
        check_step_count(model, dataclasses.replace(model.settings, max_steps=limit - 1), q, qd)
    check_step_count(model, dataclasses.replace(model.settings, max_steps=limit + 1), q, qd)
    rk4 = dataclasses.replace(model.settings, max_steps=1, integrator=Integrator.RK4, step=1e-3)
    check_step_count(model, rk4, q, qd)  # a fixed step's count is t_end / step (`settings_check`)
