"""The compiled time loop driven segment by segment from a given state.

`simulate` runs a model from its assembled start to ``t_end`` in one go.  The
studies of `planar_mbs.results.lyapunov` and `planar_mbs.run.study` need more: run to the
next driver period, look at the state, change it (renormalise a perturbation,
copy a trajectory), go on.  A `Stepper` holds everything the kernel's
`advance` carries between calls (state, clock, contact modes and stored impact
velocities, statistics, workspace) and returns the observation rows of each
segment.  Each segment ends exactly at its ``t_stop`` (the last step is cut
there), so a segmented run is a valid integration whose steps differ from an
uninterrupted one only at the segment ends.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import SimulationError
from ..kernel import advance, make_workspace, project
from ..mechanism.kinematics import assemble
from ..mechanism.model import N_STATS, ST_INFO, ST_OUTPUTS, Model, Status, observation_size
from ..results.signals import signal_table
from .first_compile import first_call
from .simulation import _deepest, _failure_message, _physics_warnings, not_physical, run_settings

ROWS = 256  # observation rows fetched per kernel call


class Stepper:
    """One trajectory of ``model`` (settings as in `simulate`), advanced by `run_to`.
    ``allow_unphysical=True`` goes on where a journal has sunk deeper than its clearance (a numerical
    study of a contact too soft for its joint); by default `run_to` raises there, as `simulate` does."""

    def __init__(self, model: Model, allow_unphysical: bool = False, **settings_changes):
        self.model = model
        self.allow_unphysical = allow_unphysical
        self.settings = run_settings(model, **settings_changes)
        self.cfg = self.settings.cfg(model.size)
        q, qd = assemble(model)
        self.y = np.concatenate([q, qd])
        self.clock = np.zeros(3)  # t, current step (0 = automatic), t0 of the output grid
        self.contact = np.zeros((model.nclearance, 3))  # mode, stored impact velocity, ...
        self.stats = np.zeros(N_STATS, dtype=np.int64)
        self.ws = make_workspace(model.kernel)
        nobs = observation_size(model.nbody, model.njoint, model.ndriver, model.nclearance)
        self._out_t, self._out = np.zeros(ROWS), np.zeros((ROWS, nobs))
        self.table = signal_table(model)
        self.deepest: dict[str, float] = {}  # deepest penetration per clearance joint so far

    @classmethod
    def restore(cls, model: Model, y, contact, t: float, allow_unphysical: bool = False,
                **settings_changes) -> "Stepper":
        """A trajectory from a saved kernel state (``y``, ``contact`` of a run at time ``t``),
        its output grid ``k * output_step`` continued from ``t``."""
        st = cls(model, allow_unphysical, **settings_changes)
        st.y[:] = y
        st.contact[:] = contact
        st.clock[:] = (t, 0.0, 0.0)
        st.stats[ST_OUTPUTS] = int(round(t / st.settings.output_step)) + 1
        if st.settings.projection == "on":
            st._project()
        return st

    @property
    def t(self) -> float:
        return float(self.clock[0])

    def copy(self, projection: str | None = None) -> "Stepper":
        """An independent trajectory in the same state (a fresh workspace: the kernel keeps
        nothing in it between calls once a segment has ended at its ``t_stop``), with its
        `projection` setting changed where given ("on", "off", "auto")."""
        new = object.__new__(Stepper)
        new.__dict__.update(self.__dict__)
        for name in ("y", "clock", "contact", "stats", "cfg", "deepest"):
            setattr(new, name, getattr(self, name).copy())
        if projection is not None:
            new.settings = replace(self.settings, projection=projection)
            new.cfg = new.settings.cfg(self.model.size)
            if projection == "on":
                new._project()
        new.ws = make_workspace(self.model.kernel)
        new._out_t, new._out = self._out_t.copy(), self._out.copy()
        return new

    def _project(self) -> None:
        """Put the state on the constraints at once, as `projection = on` keeps it after every step: a state
        saved by a run at a looser tolerance may be off them by more than this run's bound, which its first
        step would report as "the constraints gave way"."""
        status = project(self.model.kernel, self.t, self.y, self.ws, self.stats)
        if status != 0:
            raise SimulationError(_failure_message(self.model, int(status), int(self.stats[ST_INFO]), self.t,
                                                   self.settings, self.contact), time=self.t)

    def run_to(self, t_stop: float) -> tuple[np.ndarray, np.ndarray]:
        """Integrate to ``t_stop``; returns the output times and observation rows written
        on the way (the output grid of the settings).  Raises `SimulationError`."""
        times, rows = [], []
        while True:
            status, n = first_call(advance, self.model.kernel, self.cfg, self.y, self.clock, self.contact,
                                   self.stats, self.ws, t_stop, self._out_t, self._out)
            if n:
                times.append(self._out_t[:n].copy())
                rows.append(self._out[:n].copy())
            if status == Status.DONE:
                break
            if status != Status.BUFFER_FULL:
                raise SimulationError(_failure_message(self.model, int(status), int(self.stats[ST_INFO]), self.t,
                                                       self.settings, self.contact), time=self.t)
        if not times:
            return np.zeros(0), np.zeros((0, self._out.shape[1]))
        times, rows = np.concatenate(times), np.concatenate(rows)
        self._check_physical(rows)
        return times, rows

    def _check_physical(self, rows: np.ndarray) -> None:
        """Raise where a journal has sunk deeper than its clearance so far, as `simulate` marks such
        results not physical: a study of them (a Lyapunov exponent, a settling revolution) would be
        one of a contact too soft for the joint."""
        _deepest(self.table, rows, self.deepest)
        unphysical = _physics_warnings(self.model, self.deepest)
        if unphysical and not self.allow_unphysical:
            raise SimulationError(not_physical(unphysical), time=self.t)

    def signals(self, rows: np.ndarray) -> dict[str, np.ndarray]:
        """Named signals of observation rows returned by `run_to`."""
        return {s.name: s.extract(rows) for s in self.table}
