"""The translational clearance joint (a block in a guide with a gap) against closed forms, a 1-D
integration of the contact law and the conservation of energy."""
from __future__ import annotations

import math

import numpy as np
import pytest

from planar_mbs import compile_text, simulate
from test_contact_outlines import law_impact

W, LEN, CL = 20e-3, 60e-3, 0.5e-3  # block width, length; guide width - block width
BLOCK = """
body block {{ mass = {m} kg  inertia = {I} kg*m^2  position = (0, {y0})  angle = {angle} rad
              velocity = ({vx}, {vy})  omega = {w}  shape = box(width = 60 mm, height = 20 mm) }}
joint S = clearance_translational(ground (0, 0), block, axis = (1, 0)) {{
    clearance = {cl} mm  length = 60 mm  width = 20 mm  law = {law}  stiffness = {K}  {extra}
}}
simulate {{ t_end = {t_end} s  rtol = 1e-10  atol = 1e-14  output_step = {dt} s }}
"""
CORNERS = ("rear_bottom", "rear_top", "front_bottom", "front_top")


def run(m=1.0, I=4e-4, y0=0.0, angle=0.0, vx=0.0, vy=0.0, w=0.0, law="hertz", K=1e9, extra="",
        t_end=0.01, dt=1e-6):
    text = BLOCK.format(m=m, I=I, y0=y0, angle=angle, vx=vx, vy=vy, w=w, cl=CL * 1e3, law=law, K=K,
                        extra=extra, t_end=t_end, dt=dt)
    return simulate(compile_text(text))


def test_block_dropped_flat_rebounds_with_the_law_restitution():
    """Both bottom corners strike together, each taking half the block: the rebound speed is the
    law's 1-D restitution for a mass m/2 per corner."""
    v, ce, K = 0.5, 0.7, 1e9
    res = run(vy=-v, law="lankarani_nikravesh", extra=f"restitution = {ce}", K=K, t_end=2e-3)
    e, tc = law_impact(0.5, v, K, ce=ce)
    after = res.time > CL / 2 / v + 2 * tc
    assert res["block.vy"][after][0] == pytest.approx(e * v, rel=1e-4)
    assert np.max(np.abs(res["block.omega"])) < 1e-9  # flat: no tilt
    for c in ("rear_top", "front_top"):
        assert res[f"S_{c}.in_contact"].max() == 0


@pytest.mark.parametrize("angle, first", [(0.004, "rear_bottom"), (-0.004, "front_bottom")])
def test_tilted_block_touches_first_with_the_predicted_corner(angle, first):
    """A block turned by a small angle and moving down: the lowest corner, y = -(L/2)|sin a| - (w/2) cos a
    below the centre, touches first, after (w + c)/2 - (L/2)|sin a| - (w/2) cos a over the speed."""
    v = 0.2
    res = run(angle=angle, vy=-v, vx=0.1, t_end=3e-3)
    gap = (W + CL) / 2 - LEN / 2 * abs(math.sin(angle)) - W / 2 * math.cos(angle)
    onset = {c: res.time[np.argmax(res[f"S_{c}.in_contact"] > 0)] if res[f"S_{c}.in_contact"].max() else np.inf
             for c in CORNERS}
    assert min(onset, key=onset.get) == first
    assert onset[first] == pytest.approx(gap / v, abs=2e-6)
    x_corner = -math.copysign(1, angle) * (LEN / 2 * math.cos(angle)) + W / 2 * math.sin(abs(angle)) * math.copysign(1, angle)
    k = np.argmax(res[f"S_{first}.in_contact"] > 0)
    assert res[f"S_{first}.contact_x"][k] == pytest.approx(0.1 * res.time[k] + x_corner, abs=1e-5)


def test_rattling_block_with_a_lossless_law_conserves_energy():
    """Undriven, no gravity, no friction, Hertz contact: many impacts on both surfaces, every corner."""
    res = run(vx=0.3, vy=0.4, w=3.0, t_end=0.05, dt=1e-5)
    E = res["system.total_energy"]
    assert sum(int(np.sum(np.diff(res[f"S_{c}.in_contact"]) > 0)) for c in CORNERS) > 20
    assert all(res[f"S_{c}.in_contact"].max() == 1 for c in CORNERS)
    assert np.max(np.abs(E - E[0])) / E[0] < 1e-6
    assert np.max(np.abs(res["block.vx"] - 0.3)) < 1e-9  # no friction: the slide is untouched


@pytest.mark.parametrize("fields, message", [
    ("clearance = 25 mm  length = 60 mm  width = 20 mm  stiffness = 1e9  law = hertz", "smaller than the block"),
    ("clearance = 0.5 mm  length = 60 mm  width = 20 mm  law = hertz", "sharp corner"),
    ("clearance = 0.5 mm  length = 60 mm  width = 20 mm  corner_radius = 15 mm  stiffness = 1e9  law = hertz",
     "half the block"),
])
def test_bad_translational_joints_are_refused_with_the_line(fields, message):
    from planar_mbs.errors import ModelError

    text = ("body b { mass = 1 kg  inertia = 1 kg*m^2 }\ngravity (0, -9.81)\n"
            f"joint S = clearance_translational(ground, b, axis = (1, 0)) {{ {fields} }}\n")
    with pytest.raises(ModelError) as err:
        compile_text(text, "bad.mbs")
    assert err.value.line == 3 and message in str(err.value)


def test_the_block_closing_a_loop_starts_centred_and_aligned():
    """In the slider-crank the assembly treats the joint as an ideal sliding joint: the slider starts on
    the guide's centre line, aligned, every corner 0.15 mm from its surface."""
    from planar_mbs import load_model
    from planar_mbs.mechanism.kinematics import assemble, start_gaps
    from pathlib import Path

    m = load_model(Path(__file__).resolve().parent.parent / "models" / "slider_crank_clearance_s.mbs")
    q, qd = assemble(m)
    assert start_gaps(m, q) == pytest.approx([0.15e-3] * 4, abs=1e-12)
    assert qd[m.body_names.index("slider") * 3 + 1] == pytest.approx(0.0, abs=1e-12)
