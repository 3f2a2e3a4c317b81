"""One mode of `mbs modes` as a rerun recording: the mechanism moving in that mode.

The pose of frame t is the linear motion of the mode, q(t) = q0 + a Re(phi e^(i w t)), with phi the
mode's shape in the body coordinates (`run.modes.Mode.shape`), w its damped angular frequency (an
oscillating mode) or 2 pi 1/s (a real one, shown as its shape swinging once a second), and a the
amplitude of the mode-shape figure (`outputs.modes_plot`: the largest point moves a tenth of the
mechanism's size).  The decay is left out: the recording shows the shape, which the eigenvalue's real
part (the damping ratio, in the recording's text) then shrinks.  The frames go through the one
recorder of runs (`outputs.rerun_log.record_run`), so bodies, pins and clearance joints are drawn as
they are for a run, on the run's timeline.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..results.hdf5 import Results
from . import modes_plot, rerun_log

FRAMES_PER_PERIOD = 48  # frames of one period of the mode
PERIODS = 4  # periods recorded


def mode_motion(modes, index: int = 1, periods: int = PERIODS, frames: int = FRAMES_PER_PERIOD) -> Results:
    """The motion of mode `index` (1 = the lowest, as `mbs modes` numbers them) as a run's results:
    every body's x, y, phi over `periods` periods, `frames` per period (the module docstring)."""
    shown = modes.modes()
    if not 1 <= index <= len(shown):
        raise ValueError(f"mode {index} does not exist: the linearisation has modes 1 to {len(shown)}")
    mode, model = shown[index - 1], modes.model
    freq = mode.damped_frequency if mode.kind == "oscillating" and mode.damped_frequency > 0 else 1.0
    t = np.arange(periods * frames + 1) / (frames * freq)
    a = modes_plot.display_amplitude(model, modes.q, np.real(mode.shape), modes_plot.body_outlines(model))
    q = modes.q[None, :] + a * np.real(np.exp(2j * math.pi * freq * t)[:, None] * mode.shape[None, :])
    signals, units = {}, {}
    for b, name in enumerate(model.body_names):
        for k, (quantity, unit) in enumerate((("x", "m"), ("y", "m"), ("phi", "rad"))):
            signals[f"{name}.{quantity}"] = q[:, 3 * b + k]
            units[f"{name}.{quantity}"] = unit
    attrs = {"model_source": f"{modes_plot.mode_title(mode)} (shape shown, decay left out)\n\n{model.source_text}",
             "mode": index, "mode_frequency": freq, "mode_amplitude": a}
    return Results(t, signals, units, attrs)


def record_mode(modes, path: str | Path, index: int = 1) -> rerun_log.RecordingInfo:
    """Write mode `index` of `modes` (a `run.modes.Modes`) as a rerun recording (.rrd) at `path`."""
    res = mode_motion(modes, index)
    fps = FRAMES_PER_PERIOD * float(res.attrs["mode_frequency"])
    return rerun_log.record_run(res, modes.model, path, magnify=1.0, fps=fps, max_frames=len(res.time))
