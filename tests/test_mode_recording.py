"""A mode as a rerun recording (`outputs/mode_recording.py`), read back with rerun's own reader: the
pendulum's centre of mass swings at the compound-pendulum frequency w^2 = m g L / (I + m L^2), along
the tangent of its circle, by the stated amplitude (the largest point move a tenth of the size)."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest
from typer.testing import CliRunner

os.environ["RERUN_TELEMETRY_ENABLED"] = "false"

import planar_mbs as mbs  # noqa: E402
from planar_mbs.cli.app import app  # noqa: E402
from planar_mbs.outputs import mode_recording, modes_plot  # noqa: E402

G = 9.81
M, I, L = 1.3, 0.02, 0.3
PENDULUM = f"""
body bob {{ mass = {M} kg  inertia = {I} kg*m^2  position = (0.1 m, -0.2 m) }}
joint pin = revolute(ground (0, 0), bob (0 m, {L} m))
gravity (0, -{G} m/s^2)
"""


def com_track(path):
    """(times in s, centre of mass (x, y) per frame) from the recording's `mechanism/com`."""
    from rerun.chunk import RrdReader
    import pyarrow as pa

    times, points = [], []
    for chunk in RrdReader(path).stream():
        if chunk.entity_path.lstrip("/") != "mechanism/com" or chunk.is_static:
            continue
        rb = chunk.to_record_batch()
        times.append(rb.column("sim_time").cast(pa.int64()).to_numpy())
        points += [np.array(p, dtype=float).reshape(-1, 2) for p in rb.column("Points2D:positions").to_pylist()]
    order = np.argsort(np.concatenate(times), kind="stable")
    return np.concatenate(times)[order] * 1e-9, np.array([points[i][0] for i in order])


def test_the_recorded_mode_swings_at_the_closed_form_frequency(tmp_path):
    model = mbs.compile_text(PENDULUM, path="pendulum.mbs")
    modes = mbs.linearize(model, mbs.equilibrium(model))
    path = tmp_path / "mode.rrd"
    info = mode_recording.record_mode(modes, path, 1)
    t, com = com_track(path)
    w = math.sqrt(M * G * L / (I + M * L * L))
    assert len(t) == info.frames == mode_recording.PERIODS * mode_recording.FRAMES_PER_PERIOD + 1
    assert t[-1] == pytest.approx(mode_recording.PERIODS * 2 * math.pi / w, rel=1e-8)
    x, y = com[:, 0], -com[:, 1]  # the recording logs y negated (rerun draws y downwards)
    f32 = 4 * float(np.finfo(np.float32).eps) * L  # rerun keeps positions in float32
    assert y == pytest.approx(-L, abs=f32)  # to first order the bob moves along the tangent at the bottom
    amp = float(np.max(np.abs(x)))
    np.testing.assert_allclose(x, amp * np.cos(w * t) * np.sign(x[0]), atol=f32)
    # the amplitude is the figure's (`modes_plot.display_amplitude`), applied to the shape's x component
    a = modes_plot.display_amplitude(model, modes.q, np.real(modes.modes()[0].shape), modes_plot.body_outlines(model))
    assert amp == pytest.approx(a * abs(np.real(modes.modes()[0].shape[0])), abs=f32)


def test_the_command_records_a_mode_and_refuses_one_that_is_not_there(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "pendulum.mbs").write_text(PENDULUM)
    r = CliRunner().invoke(app, ["modes", "pendulum.mbs", "--rerun", "m.rrd"])
    assert r.exit_code == 0, r.output
    assert "mode 1 recorded" in r.output and (tmp_path / "m.rrd").stat().st_size > 0
    r = CliRunner().invoke(app, ["modes", "pendulum.mbs", "--rerun", "m2.rrd", "--mode", "2"])
    assert r.exit_code == 2, r.output
    assert "--mode 2" in r.output and "between 1 and 1" in r.output
    assert not (tmp_path / "m2.rrd").exists()
