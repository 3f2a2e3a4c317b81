"""The typer commands `mbs static` and `mbs modes` (light: typer only, as `mbs --help` imports it; the
work is in `static_command`)."""
from pathlib import Path
from typing import Annotated, Optional

import typer

from planar_mbs.lazy import lazy

from .run_options import SET_HELP

static_command = lazy("planar_mbs.cli.static_command")  # numpy, the kernels: only when a command runs

ModelArg = Annotated[Path, typer.Argument(help="The .mbs model file.", show_default=False)]
SetOpt = Annotated[Optional[list[str]], typer.Option("--set", "-s", help=SET_HELP, show_default=False)]
TimeOpt = Annotated[Optional[str], typer.Option(
    "--time", help="The time whose driver values are held, with units (0.5ms).", show_default="0 s")]


def static(
    model: ModelArg,
    set_: SetOpt = None,
    output: Annotated[Optional[Path], typer.Option(
        "--output", "-o", help="Write the equilibrium to this HDF5 file (group /static: pose, multipliers, "
        "residuals, stiffness).", show_default="not written")] = None,
    time: TimeOpt = None,
) -> None:
    """Find where the mechanism rests: the static equilibrium under its loads, springs, gravity and
    contact forces (drivers held), from the assembled pose; print its pose, residuals and the
    reactions of its joints.  Exit 3 when there is none or it is not unique.  `mbs run --from-static`
    starts a run from it."""
    code = static_command.static_model(model, set_ or [], output, time)
    if code:
        raise typer.Exit(code)


def modes(
    model: ModelArg,
    set_: SetOpt = None,
    output: Annotated[Optional[Path], typer.Option(
        "--output", "-o", help="Write the state matrix, eigenvalues, frequencies, damping ratios and mode "
        "shapes to this HDF5 file (group /modes, and /static).", show_default="not written")] = None,
    plot: Annotated[Optional[Path], typer.Option(
        "--plot", help="Draw the mode shapes into this figure (.png, .svg, .pdf).", show_default="none")] = None,
    at: Annotated[str, typer.Option(
        "--at", help="static: about the static equilibrium (drivers held); assembled: about the assembled "
        "initial state, drivers moving.")] = "static",
    count: Annotated[int, typer.Option("--modes", help="Modes printed and drawn.", min=1)] = 6,
    impact_velocity: Annotated[Optional[float], typer.Option(
        "--impact-velocity", help="delta'(-) of the dissipative contact laws' damping, in m/s.",
        show_default="1e-5 m/s, as a run that starts at rest", min=0.0)] = None,
    time: TimeOpt = None,
    rerun: Annotated[Optional[Path], typer.Option(
        "--rerun", help="Write a rerun recording (.rrd) of one mode: the mechanism moving in it (`mbs view` "
        "opens recordings as `rerun FILE.rrd` does).", show_default="none")] = None,
    mode: Annotated[int, typer.Option("--mode", help="The mode --rerun records (1: the lowest).", min=1)] = 1,
) -> None:
    """Linearise the constrained motion in its minimal coordinates and print its modes: natural
    frequencies, damping ratios and what moves, about the static equilibrium or the assembled state.
    Exit 3 when the state cannot be found."""
    code = static_command.modes_model(model, set_ or [], output, plot, at, count, impact_velocity, time,
                                      rerun, mode)
    if code:
        raise typer.Exit(code)
