"""The Python API's arguments checked with the CLI's kind of message (a `ModelError` naming the argument and
a hint), never a traceback from deep inside: each case below failed with a raw TypeError, AttributeError,
MemoryError or a misleading message before these checks."""
from __future__ import annotations

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.errors import ModelError

MODEL = """body m { mass = 1 kg  inertia = 1 kg*m^2  position = (0, 0) }
joint O = revolute(ground (0, 0), m (0.1, 0))
gravity (0, -9.81 m/s^2)
simulate { t_end = 10 ms }
"""


@pytest.fixture(scope="module")
def model():
    return mbs.compile_text(MODEL)


@pytest.mark.parametrize("given, hint", [("model.mbs", "load_model"), (None, "compile_text"), (42, "compile_text")])
def test_simulate_needs_a_compiled_model(given, hint):
    for run in (mbs.simulate, mbs.Simulation):
        with pytest.raises(ModelError, match="runs a compiled model") as err:
            run(given)
        assert hint in err.value.hint


def test_signal_names_are_text(model):
    with pytest.raises(ModelError, match="signals are named by text"):
        mbs.simulate(model, signals=[1])
    with pytest.raises(ModelError, match="signals are named by text"):
        mbs.Simulation(model, signals=["m.x", None])


def test_a_one_element_array_is_a_number_and_a_longer_one_is_refused(model):
    assert mbs.simulate(model, t_end=np.array(0.002)).time[-1] == pytest.approx(0.002)
    with pytest.raises(ModelError, match="is not a number"):
        mbs.simulate(model, t_end=np.array([0.001, 0.002]))
    with pytest.raises(ModelError, match="`rtol` takes a number"):
        mbs.simulate(model, rtol=[1e-6])


@pytest.mark.parametrize("dt", [float("nan"), float("inf"), "x", [1]])
def test_a_step_that_is_not_a_finite_time_is_refused(model, dt):
    sim = mbs.Simulation(model)
    with pytest.raises(ModelError) as err:
        sim.step(dt)
    assert "past the end" not in str(err.value)


def test_results_indexed_by_a_number_say_signals_are_named(model):
    res = mbs.simulate(model)
    with pytest.raises(KeyError, match="no signal 0"):
        res[0]


def test_simulate_without_a_file_refuses_rows_that_cannot_fit_in_memory(model):
    """As `Simulation` does, before it starts (here 1e11 rows), instead of a MemoryError mid-run."""
    with pytest.raises(ModelError, match="would not fit"):
        mbs.simulate(model, t_end="100 s", output_step="1 ns", max_rows=float("inf"))
