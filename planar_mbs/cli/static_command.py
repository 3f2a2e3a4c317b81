"""`mbs static` and `mbs modes`: parse the options, call `planar_mbs.run.static` and
`planar_mbs.run.modes`, print; `mbs run --from-static` reads `start_at_rest`."""
from __future__ import annotations

import os
from pathlib import Path

from planar_mbs.errors import MbsError, ModelError
from planar_mbs.lazy import lazy

from .common import check_choice, check_output, fail_code, parse_sets, quantity
from .common import console as _console

compiler = lazy("planar_mbs.mechanism.compile")
static = lazy("planar_mbs.run.static")
linear = lazy("planar_mbs.run.modes")
modes_plot = lazy("planar_mbs.outputs.modes_plot")
mode_recording = lazy("planar_mbs.outputs.mode_recording")  # rerun: only a recording asked for loads it
h5py = lazy("h5py")


def _load(model: Path, sets: list[str], outputs: list[tuple[str, Path | None]]):
    """The compiled model, every output checked first (never the model or a file it includes, never
    an HDF5 file that holds anything but an equilibrium or modes)."""
    m = compiler.load_model(model, parse_sets(sets))
    inputs = [("the model file" if i == 0 else "a file the model includes", f)
              for i, f in enumerate(m.source_files or [model])]
    for option, path in outputs:
        if path is not None:
            check_output(path, option, inputs)
            if option == "--output":
                _refuse_replacing(path)
    return m


def _refuse_replacing(path: Path) -> None:
    """An existing HDF5 output may be replaced only when it holds an equilibrium or modes."""
    if not os.path.exists(path):
        return
    try:
        with h5py.File(path, "r") as f:
            kinds = set(f.keys())
    except OSError:
        kinds = {"?"}
    if not kinds <= {"static", "modes"}:
        raise ModelError(f"`--output {path}` holds other data (not an equilibrium or modes): not replacing it",
                         "--output", hint="choose another file name")


def _time(text: str | None) -> float:
    return 0.0 if text is None else float(quantity(text, "time", "--time"))


def static_model(model: Path, sets: list[str], output: Path | None, time: str | None) -> int:
    """`mbs static`: the equilibrium printed (and written); the exit code."""
    con = _console()
    try:
        m = _load(model, sets, [("--output", output)])
        eq = static.equilibrium(m, t=_time(time))
        for line in static.report(eq):
            con.print(line, markup=False, soft_wrap=True)
        if output is not None:
            static.write(eq, output)
            con.print(f"equilibrium → {output}", markup=False)
    except MbsError as err:
        return fail_code(err)
    return 0


def modes_model(model: Path, sets: list[str], output: Path | None, plot: Path | None, at: str, count: int,
                impact_velocity: float | None, time: str | None, rerun: Path | None = None, mode: int = 1) -> int:
    """`mbs modes`: the modes printed (written, drawn); the exit code."""
    con = _console()
    try:
        at = check_choice(at, ("static", "assembled"), "--at")
        m = _load(model, sets, [("--output", output), ("--plot", plot), ("--rerun", rerun)])
        md = linear.linearize(m, None if at == "static" else "assembled", t=_time(time),
                              impact_velocity=impact_velocity)
        if md.equilibrium is not None:
            con.print(static.report(md.equilibrium)[0], markup=False, soft_wrap=True)
        for line in linear.report(md, count):
            con.print(line, markup=False, soft_wrap=True)
        if output is not None:
            linear.write(md, output)
            con.print(f"modes → {output}", markup=False)
        if plot is not None:
            modes_plot.draw_modes(md, plot, count)
            con.print(f"mode shapes → {plot}", markup=False)
        if rerun is not None:
            _record(md, rerun, mode)
            con.print(f"mode {mode} recorded → {rerun}", markup=False)
    except MbsError as err:
        return fail_code(err)
    return 0


def _record(md, path: Path, mode: int) -> None:
    """`--rerun`: mode `mode` of `md` as a recording (exit 2 for a mode the linearisation lacks)."""
    count = len(md.modes())
    if mode > count:
        raise ModelError(f"--mode {mode}: the linearisation has {count} mode(s)", "--mode",
                         hint=f"give `--mode` between 1 and {count}")
    mode_recording.record_mode(md, path, mode)


def start_at_rest(m):
    """`mbs run --from-static`: the model started from its static equilibrium (a line says where)."""
    eq = static.equilibrium(m)
    _console().print(f"starting from the static equilibrium ({eq.iterations} iteration(s), reduced force "
                     f"{eq.reduced_residual:.3g} N)", markup=False)
    return static.at_rest(m, eq)
