"""One run, one state: the compiled model is read-only while it runs, and every trajectory owns its data.

Two runs of one model with expression switches and a table, interleaved (two `Simulation`s in turns,
two threads, Benettin's pair of `Stepper`s in either order), give results bit-identical to the same
runs made one after the other; the model's arrays hash the same before and after, and cannot be
written.
"""
from __future__ import annotations

import hashlib
import threading

import numpy as np
import pytest

import planar_mbs as mbs
from planar_mbs.mechanism.compile import compile_text
from planar_mbs.run.driver import RunData
from planar_mbs.run.lyapunov import floquet_exponent, mechanism_exponent
from planar_mbs.run.stepper import Stepper

# a 1-DOF oscillator on a slide, pushed back by a bang-bang force (a switch) and a tabulated one:
# both are state the expression interpreter keeps between steps (frozen switch modes, the table's piece)
SWITCHED = """
body m {{ mass = 1 kg  inertia = 1 kg*m^2  position = ({x0} m, 0)  velocity = ({v0} m/s, 0) }}
joint slide = translational(ground (0, 0), m, axis = (1, 0))
force bang = expression(m, fx = if(m.x > 0 m, -20 N, 20 N))
force tab = expression(m, fx = table(x = m.x, xs = (-0.2 m, -0.05 m, 0 m, 0.05 m, 0.2 m),
                                     ys = (1 N, 0.5 N, 0 N, -0.5 N, -1 N)))
simulate {{ t_end = 0.3 s  output_step = 1 ms  rtol = 1e-8  atol = 1e-11 }}
"""


def _model(x0=0.1, v0=0.0):
    return compile_text(SWITCHED.format(x0=x0, v0=v0))


def _hash(model) -> str:
    h = hashlib.sha256()
    for a in model.kernel:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def test_the_model_is_read_only():
    """Every array a kernel reads from the model refuses writes (numba compiles them as read-only, so a
    kernel that wrote into the model would not compile)."""
    model = _model()
    for name, a in model.kernel._asdict().items():
        assert not a.flags.writeable, name
    with pytest.raises(ValueError, match="read-only"):
        model.kernel.force_param[0, 0] = 1.0


def test_two_simulations_of_one_model_in_turns_match_separate_runs():
    """B alone against B in turns with A (other tolerances, so its switches flip at other times), both
    in 10 ms segments, on the same model: bit-identical, with the same steps; the model hashes the same
    after."""
    model = _model()
    digest = _hash(model)
    alone = mbs.Simulation(model, signals=["m.x", "m.vx"])
    for k in range(1, 31):  # the same 10 ms segments (each ends a step at its end)
        alone.run_until(k * 0.01)
    a = mbs.Simulation(model, signals=["m.x"], rtol=1e-5)  # other steps: the switches flip at other times
    b = mbs.Simulation(model, signals=["m.x", "m.vx"])
    for k in range(1, 31):
        a.step("10 ms")
        b.run_until(k * 0.01)
    assert np.array_equal(b["m.x"], alone["m.x"]) and np.array_equal(b["m.vx"], alone["m.vx"])
    assert not np.array_equal(a["m.x"], b["m.x"])  # A really was another motion
    assert b.results().attrs["n_steps"] == alone.results().attrs["n_steps"]
    assert np.ptp(alone["m.x"]) > 0.15  # it swung through the switch and the table's knots
    assert _hash(model) == digest


def test_two_threads_on_one_model_match_separate_runs():
    """Two runs of one model in two threads at once: each bit-identical to the same run alone."""
    model = _model()
    out: dict[int, np.ndarray] = {}

    together = threading.Barrier(2)

    def run(k, rtol, meet=False):
        sim = mbs.Simulation(model, signals=["m.x"], rtol=rtol)
        for j in range(1, 61):  # many short calls; in the threads, each waits for the other's
            sim.run_until(j * 0.005)
            if meet:
                together.wait(timeout=60)
        out[k] = sim["m.x"]

    run("alone", 1e-8)
    run("other alone", 1e-5)
    threads = [threading.Thread(target=run, args=(k, rtol, True)) for k, rtol in (("a", 1e-8), ("b", 1e-5))]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert np.array_equal(out["a"], out["alone"]) and np.array_equal(out["b"], out["other alone"])


def test_a_copy_of_a_run_shares_no_array():
    model = _model()
    st = Stepper(model)
    data = st.driver.data
    twin = data.copy()
    assert isinstance(twin, RunData)
    for a, b in zip((data.y, data.clock, data.contact, data.stats, *data.ws),
                    (twin.y, twin.clock, twin.contact, twin.stats, *twin.ws)):
        assert not np.shares_memory(a, b)


# a pendulum hanging from a driven crank, braked by a torque that switches with its spin and pushed by a
# tabulated one: a periodically forced orbit of a model with expression switches and a table
DRIVEN = """
body crank { mass = 0.5 kg  inertia = 1e-3 kg*m^2  position = (0.05, 0) }
body pend { mass = 0.2 kg  inertia = 1e-4 kg*m^2  position = (0.1, -0.1) }
joint O = revolute(ground (0, 0), crank (-0.05, 0))
joint P = revolute(crank (0.05, 0), pend (0, 0.1))
driver spin = rotation(crank, speed = 120 rpm)
force brake = expression(pend, torque = if(pend.omega > 0 rad/s, -2 mN*m, 2 mN*m))
force push = expression(pend, torque = table(x = pend.phi, xs = (-1 rad, 0 rad, 1 rad),
                                             ys = (10 mN*m, 0 mN*m, -10 mN*m)))
force damp = rotational_spring_damper(crank, pend) { damping = 1 mN*m*s/rad }
gravity (0, -9.81 m/s^2)
simulate { output_step = 10 ms  rtol = 1e-9  atol = 1e-12 }
"""


def test_benettin_and_floquet_do_not_depend_on_the_order_of_the_pair():
    """Benettin's pair (reference and companion of one model) advanced ref-then-companion or
    companion-then-ref give the same exponent bit for bit, and the Floquet exponent of the orbit is the
    same whichever trajectory ran before it."""
    from planar_mbs.run import lyapunov

    model = compile_text(DRIVEN)
    period = 0.5
    st = Stepper(model, output_step=period / 16, t_end=10 * period)
    st.run_to(2 * period)
    first = mechanism_exponent(st.copy(), period, 6, per_rev=4, discard=2)

    real = lyapunov.benettin

    def swapped(advance, ref, comp, *args):
        """Benettin's loop with each segment run companion first, then reference."""
        waiting = []

        def companion_first(s):
            if s is ref:  # the reference's turn: deferred until the companion has run
                waiting.append(s)
                return s
            advance(s)
            advance(waiting.pop())
            return s
        return real(companion_first, ref, comp, *args)

    lyapunov.benettin = swapped
    try:
        second = mechanism_exponent(st.copy(), period, 6, per_rev=4, discard=2)
    finally:
        lyapunov.benettin = real
    assert np.array_equal(first.logs, second.logs) and first.value == second.value
    f1 = floquet_exponent(st.copy(), period)
    noise = st.copy()
    noise.run_to(4 * period)  # another trajectory of the model ran in between
    f2 = floquet_exponent(st.copy(), period)
    assert f1.value == f2.value and np.array_equal(f1.multipliers, f2.multipliers)
