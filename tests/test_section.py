"""The one Poincaré section (planar_mbs.results.section): crossings, the clock and slider rules."""
from __future__ import annotations

import math

import numpy as np
import pytest

from planar_mbs.results.hdf5 import Results
from planar_mbs.results.section import AnalysisError, clock_body, crossings, default_signals, poincare_section, slider_body


def test_every_level_crossed_between_two_samples_counts():
    """A clock sampled coarsely (2.5 turns per sample) still gives one crossing per turn,
    each at its interpolated time; the former angle rule kept one per sample interval."""
    w = 2 * math.pi * 10.0  # 10 turns per second
    t = np.arange(0, 1.0001, 0.25)  # 2.5 turns per sample
    got = crossings(t, w * t)
    np.testing.assert_allclose(got, np.arange(1, 11) / 10.0, atol=1e-12)
    got = crossings(t, w * t, angle=math.pi)  # phi = pi + 2 pi k
    np.testing.assert_allclose(got, (np.arange(0, 10) + 0.5) / 10.0, atol=1e-12)
    np.testing.assert_allclose(crossings(t, -w * t), np.arange(1, 11) / 10.0, atol=1e-12)  # turning backwards


def _run(bodies: dict[str, tuple], t):
    sig = {}
    for b, (x, y, phi) in bodies.items():
        sig.update({f"{b}.x": x, f"{b}.y": y, f"{b}.phi": phi, f"{b}.vx": np.gradient(x, t), f"{b}.ax": 0 * t})
    return Results(time=t, signals=sig, units={k: "" for k in sig}, attrs={})


def test_clock_and_slider_from_the_signals():
    t = np.linspace(0, 1, 1001)
    res = _run({"wheel": (0 * t, 0 * t, 20 * t), "piston": (np.cos(20 * t), 0 * t, 0 * t),
                "link": (np.cos(20 * t) / 2, np.sin(20 * t) / 2, 0.3 * np.sin(20 * t))}, t)
    assert clock_body(res) == "wheel"
    assert slider_body(res) == "piston"
    assert default_signals(res) == ("piston.vx", "piston.ax")
    sec = poincare_section(res)
    assert sec.clock == "wheel" and sec.names == ["piston.vx", "piston.ax"]
    assert len(sec) == math.floor(20 / (2 * math.pi)) - 1


def test_no_slider_asks_for_signals():
    """With no translating body (a four-bar) no other body is taken for the slider: the error names
    `-p X:Y` with a body of the mechanism; a slider whose signals are not in the file, the same."""
    t = np.linspace(0, 1, 101)
    res = _run({"wheel": (0 * t, 0 * t, 20 * t), "arm": (np.cos(t), 0 * t, np.sin(t))}, t)
    assert slider_body(res) is None
    with pytest.raises(AnalysisError, match=r"no slider in this mechanism.*-p X:Y.*-p arm\.omega:arm\.alpha"):
        default_signals(res)
    res = _run({"wheel": (0 * t, 0 * t, 20 * t), "ram": (np.cos(t), 0 * t, 0 * t)}, t)
    assert default_signals(res) == ("ram.vx", "ram.ax")
    del res.signals["ram.vx"], res.signals["ram.ax"]
    with pytest.raises(AnalysisError, match="-p X:Y"):
        default_signals(res)
