"""One run of a model: its own data, and the one driver of the compiled time loop.

The compiled `Model` is read-only while it runs (its kernel arrays are not writeable).  Everything
the kernels write lives in a `RunData`, made from the model, one per trajectory, as MuJoCo keeps
``mjData`` apart from ``mjModel``: the state, the clock, the contact memory of the clearance joints,
the statistics and the workspace (scratch, expression registers and switch modes).  Two runs of one
model, interleaved in any order or in two threads, never see each other; copying a run copies its
data.

`Driver` is the only caller of `kernel.advance`.  `simulate`, `Simulation`, `Stepper` and the
sweep worker hand it a place for the rows (`Sink`); it allocates, compiles on the first call, calls
the loop until the end, a failure or a full buffer, turns statuses into messages and keeps what the
end-of-run checks read (the deepest penetration, the energy drift).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import time as _time
from dataclasses import dataclass

import numpy as np

from ..errors import SimulationError
from ..lazy import lazy
from ..mechanism.model import N_CONTACT_STATE, N_STATS, ST_OUTPUTS, ST_RHS, Model, Settings, Status
from .first_compile import first_call
from .checks import absurd_state, deepest_penetration, energy_drift, failure_message, known_force_kinds

# numba: `mbs check` and `import planar_mbs` read this module without loading the kernels
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from .. import kernel
    from ..kernel import workspace
else:  # each loaded on its first use (see the comments: not on the light paths)
    kernel = lazy("..kernel", __package__)
    workspace = lazy("..kernel.workspace", __package__)

CALL_SECONDS = 0.1  # wall time of one kernel call (a work budget in right-hand sides calibrated per call)
FIRST_BUDGET = 2000.0  # right-hand sides of the first call, before any calibration
BUFFER_ROWS = 2048  # observation rows per kernel call (at most)
# clock slots: t, current step (0 = automatic), t0 of the output grid, work budget of one call
CLOCK_T, CLOCK_H, CLOCK_T0, CLOCK_BUDGET = range(4)


@dataclass
class RunData:
    """Everything the kernels write during one trajectory (see the module docstring)."""

    y: np.ndarray  # (2n + nstate,) state (q, q', z): z the contact elements' own (LuGre's bristles)
    clock: np.ndarray  # (4,) CLOCK_* slots
    contact: np.ndarray  # (nclearance + njfriction, N_CONTACT_STATE) modes of the clearance and friction joints
    stats: np.ndarray  # (N_STATS,) int64 counters
    ws: object  # kernel.Workspace: scratch, expression registers and switch modes

    @classmethod
    def make(cls, model: Model, y0: np.ndarray) -> "RunData":
        clock = np.zeros(4)
        clock[CLOCK_BUDGET] = FIRST_BUDGET
        y = np.array(y0, dtype=np.float64)
        if y.shape[0] == 2 * model.ncoord and model.nstate:  # (q, q') given: the elements' own states start at 0
            y = np.concatenate([y, np.zeros(model.nstate)])
        return cls(y=y, clock=clock,
                   contact=np.zeros((model.contact_rows, N_CONTACT_STATE)),
                   stats=np.zeros(N_STATS, dtype=np.int64), ws=kernel.make_workspace(model.kernel))

    def copy(self) -> "RunData":
        """An independent trajectory in the same state: every array copied, nothing shared."""
        ws = type(self.ws)(*(a.copy() for a in self.ws))
        return RunData(self.y.copy(), self.clock.copy(), self.contact.copy(), self.stats.copy(), ws)

    @property
    def t(self) -> float:
        return float(self.clock[CLOCK_T])


def _next_budget(n_rhs: int, seconds: float, budget: float) -> float:
    """Right-hand sides for the next kernel call so that it lasts about CALL_SECONDS: the
    kernel returns to Python (signals, progress, the file) at least that often, however
    hard the run grinds between two outputs.  The run continues exactly across calls."""
    if n_rhs <= 0 or seconds <= 0.0:
        return budget
    return float(min(max(100.0, n_rhs / seconds * CALL_SECONDS), 4.0 * budget, 1e9))


class Sink:
    """Where the kernel's rows go: `room` gives the buffer slices the next call writes into, `take`
    receives the n rows written there (returns True to stop the run: a full disk)."""

    def room(self) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def take(self, n: int) -> bool:
        raise NotImplementedError


class MemorySink(Sink):
    """Rows kept in memory as blocks (the kept columns `cols` only), at most `cap` rows per call;
    `also` (a `ResultsWriter`) gets each block too."""

    def __init__(self, nobs: int, cols=None, cap: int = BUFFER_ROWS, also=None, watch=None):
        self.out_t, self.out = np.zeros(max(cap, BUFFER_ROWS)), np.zeros((max(cap, BUFFER_ROWS), nobs))
        self.cols, self.cap, self.also, self.watch = cols, cap, also, watch
        self.times: list[np.ndarray] = []
        self.blocks: list[np.ndarray] = []

    def room(self):
        return self.out_t[:self.cap], self.out[:self.cap]

    def take(self, n: int) -> bool:
        chunk_t = self.out_t[:n].copy()
        chunk = self.out[:n].copy() if self.cols is None else self.out[:n, self.cols]
        if self.watch is not None:
            self.watch(chunk)
        self.times.append(chunk_t)
        self.blocks.append(chunk)
        if self.also is not None:
            self.also.append(chunk_t, chunk)
        return False

    def clear(self) -> None:
        """Forget the blocks kept (the buffer stays: allocated once)."""
        self.times.clear()
        self.blocks.clear()

    def rows(self, width: int) -> tuple[np.ndarray, np.ndarray]:
        if not self.blocks:
            return np.zeros(0), np.zeros((0, width))
        return np.concatenate(self.times), np.concatenate(self.blocks)


class Driver:
    """The time loop of one trajectory of `model` under `settings` (see the module docstring).
    ``cfg`` is the settings array the caller has prepared (its skip bits set by the signals kept)."""

    def __init__(self, model: Model, settings: Settings, y0: np.ndarray, cfg: np.ndarray | None = None):
        known_force_kinds(model)
        self.model, self.settings = model, settings
        self.cfg = settings.cfg(model.size) if cfg is None else cfg
        self.y0 = np.array(y0, dtype=np.float64)
        self.data = RunData.make(model, y0)
        self.table = None  # the signal table the rows are read with (set by the caller for the checks)
        self.track: dict[str, float] = {}  # deepest penetration per joint, energy drift
        self.wall = 0.0
        self.status = int(Status.DONE)
        self._y_after = None  # the state the last call left (a state changed since restarts the energy balance)
        self.absurd = absurd_state(model, self.data.y, 0.0)  # beyond every physical bound: not worth a step
        self._compile()

    def _compile(self) -> None:
        """Compile (or load from the cache) outside the timed loop, on throw-away copies."""
        d = self.data.copy()
        one_t, one = np.zeros(1), np.zeros((1, self.nobs))
        first_call(kernel.advance, self.model.kernel, self.cfg, d.y, d.clock, d.contact, d.stats, d.ws, 0.0,
                   one_t, one)

    @property
    def nobs(self) -> int:
        return kernel.nobs(self.model.kernel)

    @property
    def t(self) -> float:
        return self.data.t

    def copy(self) -> "Driver":
        """A second trajectory in the same state: its own data, the same (read-only) model."""
        new = object.__new__(Driver)
        new.__dict__.update(self.__dict__)
        new.data, new.cfg, new.track = self.data.copy(), self.cfg.copy(), dict(self.track)
        new._y_after = None if self._y_after is None else self._y_after.copy()
        return new

    def watch(self, rows: np.ndarray) -> None:
        """What the end-of-run checks read, from rows of the signal table's columns."""
        if self.table is not None:
            deepest_penetration(self.table, rows, self.track)
            energy_drift(self.table, rows, self.track)

    def call(self, t_stop: float, out_t: np.ndarray, out: np.ndarray) -> tuple[int, int]:
        """One call of the compiled loop; its work budget calibrated for the next one."""
        d = self.data
        if self._y_after is not None and not np.array_equal(d.y, self._y_after):
            # a study set the state between calls: the works and the energy balance start again from it
            d.ws.flags[workspace.FL_ENERGY0] = 0
        start, rhs_before = _time.perf_counter(), int(d.stats[ST_RHS])
        status, n = kernel.advance(self.model.kernel, self.cfg, d.y, d.clock, d.contact, d.stats, d.ws, t_stop,
                                   out_t, out)
        seconds = _time.perf_counter() - start
        self._y_after = d.y.copy()
        self.wall += seconds
        d.clock[CLOCK_BUDGET] = _next_budget(int(d.stats[ST_RHS]) - rhs_before, seconds, d.clock[CLOCK_BUDGET])
        self.status = int(status)
        return self.status, int(n)

    def run(self, t_stop: float, sink: Sink, received=(), callback=None) -> int:
        """Call the loop until `t_stop`, a failure, a signal (`received`), a full sink or a state beyond
        every physical bound (`absurd`); ``callback()`` after every call may return True to stop.
        Returns the last status."""
        while not received and not self.absurd:
            out_t, out = sink.room()
            status, n = self.call(t_stop, out_t, out)
            full = sink.take(n) if n else False
            # after every call, the last one too: a short run ends in one call (Status.ABSURD leaves y beyond)
            self.absurd = absurd_state(self.model, self.data.y, self.t)
            if callback is not None and callback() is True:
                break
            if status != Status.BUFFER_FULL or full:
                break
        return self.status

    def failure(self, status: int | None = None) -> str:
        """Why the loop stopped with `status` (default: the last one), in words."""
        d = self.data
        return failure_message(self.model, self.settings, int(self.status if status is None else status), d,
                               self.y0)

    def raise_failure(self, status: int | None = None, results=None):
        raise SimulationError(self.failure(status), time=self.t, results=results)

    def resume_at(self, t: float) -> None:
        """Continue the output grid ``k * output_step`` from time `t` (a restored state)."""
        self.data.clock[:3] = (t, 0.0, 0.0)
        self.data.stats[ST_OUTPUTS] = int(round(t / self.settings.output_step)) + 1
