"""run/stepper.py: a trajectory driven segment by segment, copied and restored from a saved state."""
from __future__ import annotations

import numpy as np
import pytest

from planar_mbs import compile_text
from planar_mbs.errors import SimulationError
from planar_mbs.kernel import constraint_eval, constraint_rows
from planar_mbs.run.stepper import Stepper

ARM = """
body arm { mass = 1 kg  inertia = 0.01 kg*m^2  position = (0.1 m, 0) }
joint O = revolute(ground (0, 0), arm (-0.1 m, 0))
force hinge = rotational_spring_damper(ground, arm) { stiffness = 2 N*m/rad  damping = 0.12 N*m*s/rad  angle = 0 deg }
simulate { t_end = 1 s  integrator = dop853  rtol = 1e-10  atol = 1e-13 }
"""


def _residual(model, y, t):
    n = 3 * model.nbody
    m = constraint_rows(model.kernel)
    C, Ct, g, Cq = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros((m, n))
    constraint_eval(model.kernel, y[:n], y[n:], t, C, Cq, Ct, g)
    return np.abs(C).max(), np.abs(Cq @ y[n:] + Ct).max()


ARM_DEFAULTS = ARM.replace("simulate { t_end = 1 s  integrator = dop853  rtol = 1e-10  atol = 1e-13 }\n", "")


def _swinging(text=ARM):
    model = compile_text(text)
    st = Stepper(model)
    st.y[3 * model.nbody + 2] = 3.0  # the arm swings at 3 rad/s about its hinge
    st.y[3 * model.nbody:3 * model.nbody + 2] = (0.0, 0.3)
    st.run_to(0.05)
    return model, st


def test_a_state_off_the_constraints_is_projected_when_the_projection_is_on():
    """A state saved by a looser run (here the arm 1 µm off its hinge, 8 x this run's bound of 10 rtol of
    the size) is put back on the constraints by `projection = on` before the first step, where it used to
    stop at once with "the constraints gave way"; with `projection = off` it still stops (the bound)."""
    model, st = _swinging()
    y = st.y.copy()
    y[0] += 1e-6
    assert _residual(model, y, st.t)[0] > 10 * 1e-10 * model.size
    on = Stepper.restore(model, y, st.contact, st.t, projection="on")
    assert max(_residual(model, on.y, on.t)) < 1e-14
    on.run_to(0.2)
    assert max(_residual(model, on.y, on.t)) < 1e-14
    off = Stepper.restore(model, y, st.contact, st.t, projection="off")
    with pytest.raises(SimulationError, match="constraints gave way"):
        off.run_to(0.2)
    copied = Stepper.restore(model, y, st.contact, st.t, projection="off").copy(projection="on")
    assert max(_residual(model, copied.y, copied.t)) < 1e-14


@pytest.mark.parametrize("text, atol", [(ARM, 1e-9), (ARM_DEFAULTS, None)], ids=["rtol 1e-10", "defaults"])
def test_a_segmented_run_is_the_run_in_one_go(text, atol):
    """Segments end exactly at their t_stop; a run cut in 40 pieces ends where the uncut run ends, within
    the tolerance (their steps differ only at the cuts), and a copy goes on independently.  With no
    solver setting named, within 10 rtol of the state's largest component."""
    model, st = _swinging(text)
    if atol is None:
        assert "rtol" not in text
        atol = 10 * st.settings.rtol * np.abs(st.y).max()
    whole, pieces = st.copy(), st.copy()
    whole.run_to(1.0)
    for t in np.linspace(st.t, 1.0, 41)[1:]:
        pieces.run_to(t)
    assert pieces.t == whole.t == 1.0
    assert np.allclose(pieces.y, whole.y, rtol=0, atol=atol)
    assert st.t == pytest.approx(0.05)  # the copies did not move the original


def test_a_journal_sunk_deeper_than_its_clearance_stops_the_stepper_as_simulate_marks_it():
    """A contact too soft for its joint (the printed 207 MPa of Muvengei et al. at 800 rpm): the journal
    sinks deeper than the 0.3 mm clearance (read from `simulate`'s penetration signal, against the model's
    clearance), so a study driven by `Stepper` (Lyapunov exponents, settling) must stop with the reason
    instead of analysing it; with steel's 207 GPa it goes on."""
    from pathlib import Path

    import planar_mbs as mbs

    path = Path(__file__).resolve().parents[1] / "models" / "slider_crank_clearance_a.mbs"
    soft = mbs.load_model(path, youngs_modulus="207MPa", speed="800rpm")
    clearance = 0.3e-3
    with pytest.raises(SimulationError, match="not physical") as failed:
        mbs.simulate(soft, t_end=0.2)
    assert np.nanmax(failed.value.results.signals["A.penetration"]) > clearance  # the results kept
    with pytest.raises(SimulationError, match=r"not physical: clearance joint `A`: the journal sank"):
        Stepper(soft).run_to(0.2)
    Stepper(soft, allow_unphysical=True).copy().run_to(0.2)  # named for what it risks: goes on
    steel = mbs.load_model(path, youngs_modulus="207GPa", speed="800rpm")
    st = Stepper(steel)
    times, rows = st.run_to(0.2)
    assert np.nanmax(st.signals(rows)["A.penetration"]) < clearance
