"""The compiled time loop driven segment by segment from a given state.

`simulate` runs a model from its assembled start to ``t_end`` in one go.  The
studies of `planar_mbs.run.lyapunov` and `planar_mbs.run.study` need more: run to the
next driver period, look at the state, change it (renormalise a perturbation,
copy a trajectory), go on.  A `Stepper` is one trajectory: a `driver.Driver` and its own
`driver.RunData` (state, clock, contact modes and stored impact velocities, statistics,
workspace with the expressions' registers and switch modes), and returns the observation rows of
each segment.  Each segment ends exactly at its ``t_stop`` (the last step is cut there), so a
segmented run is a valid integration whose steps differ from an uninterrupted one only at the
segment ends.  Copies are independent: two trajectories of one model never share data.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import replace

import numpy as np

from ..errors import SimulationError
from ..lazy import lazy
from ..mechanism.kinematics import assemble
from ..mechanism.model import Model, Status
from ..results.signals import signal_table
from .checks import not_physical, physics_warnings
from .driver import Driver, MemorySink
from .simulation import run_settings

if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from .. import kernel
else:  # each loaded on its first use (see the comments: not on the light paths)
    kernel = lazy("..kernel", __package__)

ROWS = 256  # observation rows fetched per kernel call


class Stepper:
    """One trajectory of ``model`` (settings as in `simulate`), advanced by `run_to`.
    ``allow_unphysical=True`` goes on where a journal has sunk deeper than its clearance (a numerical
    study of a contact too soft for its joint); by default `run_to` raises there, as `simulate` does."""

    def __init__(self, model: Model, allow_unphysical: bool = False, **settings_changes):
        self.model = model
        self.allow_unphysical = allow_unphysical
        self.settings = run_settings(model, **settings_changes)
        q, qd = assemble(model)
        self.driver = Driver(model, self.settings, np.concatenate([q, qd]))
        self.table = signal_table(model)
        self.driver.table = self.table
        self._sink = MemorySink(self.driver.nobs, cap=ROWS)  # reused by every segment

    @classmethod
    def restore(cls, model: Model, y, contact, t: float, allow_unphysical: bool = False,
                **settings_changes) -> "Stepper":
        """A trajectory from a saved kernel state (``y``, ``contact`` of a run at time ``t``),
        its output grid ``k * output_step`` continued from ``t``."""
        st = cls(model, allow_unphysical, **settings_changes)
        st.y[:] = y
        st.driver.data.contact[:] = contact
        st.driver.resume_at(t)
        if st.settings.projection == "on":
            st._project()
        return st

    @property
    def t(self) -> float:
        return self.driver.t

    @property
    def y(self) -> np.ndarray:
        """The state (q, q', z), the trajectory's own array (a study may change it between segments); z,
        LuGre's bristles (`Model.nstate`), is empty in most models."""
        return self.driver.data.y

    @y.setter
    def y(self, value) -> None:
        """A whole state, or (q, q') alone: the bristles then start relaxed (z = 0)."""
        y = self.driver.data.y
        value = np.asarray(value, dtype=np.float64)
        if value.shape[0] == 2 * self.model.ncoord < y.shape[0]:
            y[:value.shape[0]] = value
            y[value.shape[0]:] = 0.0
        else:
            y[:] = value

    @property
    def contact(self) -> np.ndarray:
        return self.driver.data.contact

    @property
    def clock(self) -> np.ndarray:
        return self.driver.data.clock

    @property
    def stats(self) -> np.ndarray:
        return self.driver.data.stats

    @property
    def cfg(self) -> np.ndarray:
        """The settings array the loop reads (its skip bits may be set by a study that keeps fewer signals)."""
        return self.driver.cfg

    @property
    def deepest(self) -> dict[str, float]:
        return self.driver.track

    def copy(self, projection: str | None = None) -> "Stepper":
        """An independent trajectory in the same state (its own copy of every array the kernels
        write), with its `projection` setting changed where given ("on", "off", "auto")."""
        new = object.__new__(Stepper)
        new.__dict__.update(self.__dict__)
        new.driver = self.driver.copy()
        new._sink = MemorySink(self.driver.nobs, cap=ROWS)
        if projection is not None:
            new.settings = replace(self.settings, projection=projection)
            new.driver.settings = new.settings
            new.driver.cfg = new.settings.cfg(self.model.size)
            if projection == "on":
                new._project()
        return new

    def _project(self) -> None:
        """Put the state on the constraints at once, as `projection = on` keeps it after every step: a state
        saved by a run at a looser tolerance may be off them by more than this run's bound, which its first
        step would report as "the constraints gave way"."""
        d = self.driver.data
        status = kernel.project(self.model.kernel, self.t, d.y, d.ws, d.stats)
        if status != 0:
            self.driver.raise_failure(int(status))

    def run_to(self, t_stop: float) -> tuple[np.ndarray, np.ndarray]:
        """Integrate to ``t_stop``; returns the output times and observation rows written
        on the way (the output grid of the settings).  Raises `SimulationError`."""
        sink = self._sink
        sink.clear()
        status = self.driver.run(t_stop, sink)
        if self.driver.absurd:
            raise SimulationError(self.driver.absurd, time=self.t)
        if status != Status.DONE:
            self.driver.raise_failure(status)
        times, rows = sink.rows(self.driver.nobs)
        self._check_physical(rows)
        return times, rows

    def _check_physical(self, rows: np.ndarray) -> None:
        """Raise where a journal has sunk deeper than its clearance so far, as `simulate` marks such
        results not physical: a study of them (a Lyapunov exponent, a settling revolution) would be
        one of a contact too soft for the joint."""
        self.driver.watch(rows)
        unphysical = physics_warnings(self.model, self.driver.track)
        if unphysical and not self.allow_unphysical:
            raise SimulationError(not_physical(unphysical), time=self.t)

    def signals(self, rows: np.ndarray) -> dict[str, np.ndarray]:
        """Named signals of observation rows returned by `run_to`."""
        return {s.name: s.extract(rows) for s in self.table}
