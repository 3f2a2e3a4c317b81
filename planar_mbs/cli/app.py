"""The `mbs` command line: thin typer commands over library functions.

Exit codes (one table, also in README and `mbs --help`):

====  ==========================================================
0     success
1     an internal error (a bug), or the reader of the output went away (`| head`)
2     bad model file, bad `--set` value or bad command-line usage
3     the simulation failed or is not physical, or a limit was reached (results kept)
130   interrupted by Ctrl-C (143: by SIGTERM); results so far kept
====  ==========================================================

The modules that define typer commands (this one, `plot_commands`, `sweep_commands`) do not use
``from __future__ import annotations``: typer would evaluate every option's annotation from its
text again, twice per command, on each start (about 0.02 s of `mbs --help`).
"""
from pathlib import Path
from typing import Annotated, Optional

import typer

from planar_mbs import catalog

from .common import internal_error
from .help_text import ReadableCommand, ReadableGroup, use_one_error_style

_INTEGRATOR_HELP = "; ".join(f"{s.name}: {s.summary}" for s in catalog.INTEGRATORS) + "."
EPILOG = ("Exit codes: 0 success · 1 an internal error (a bug), or the reader of the output went away "
          "(| head) · 2 bad model, bad value or bad usage · 3 the simulation failed or is not physical, or a "
          "limit was reached (results kept) · "
          "130/143 interrupted by Ctrl-C/SIGTERM (results kept).")


app = typer.Typer(
    name="mbs",
    help=(
        "planar_mbs: planar multibody dynamics with revolute clearance joints.\n\n"
        "Describe a mechanism in a .mbs file, check it, run it and keep the results in HDF5:\n\n"
        "  mbs check models/slider_crank_clearance_a.mbs\n\n"
        "  mbs run models/slider_crank_clearance_a.mbs -o a.h5 --set speed=2500rpm"
    ),
    epilog=EPILOG,
    no_args_is_help=True,
    add_completion=True,
    rich_markup_mode="rich",
    pretty_exceptions_enable=False,
    cls=ReadableGroup,
    context_settings={"help_option_names": ["-h", "--help"]},
)
use_one_error_style()


def _version(value: bool) -> None:
    if value:
        from planar_mbs import __version__

        print(f"mbs (planar_mbs) {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[bool, typer.Option("--version", help="Print the version and exit.", callback=_version,
                                          is_eager=True)] = False,
) -> None:
    """planar_mbs: planar multibody dynamics with revolute clearance joints."""


ModelArg = Annotated[Path, typer.Argument(help="The .mbs model file.", show_default=False)]
SetOpt = Annotated[
    Optional[list[str]],
    typer.Option("--set", "-s", help="Override a `param` of the model: NAME=VALUE with units, e.g. speed=2500rpm, "
                 "\"clearance=0.1 mm\", law=hertz. Repeatable.", show_default=False),
]


_CHECK_HELP = (
    "Compile a model and print its bodies, coordinates, constraints, degrees of freedom and clearance "
    "joints (or its errors, with file:line:col).\n\n"
    f"Joint types: {', '.join(catalog.names(catalog.JOINTS) + [catalog.CLEARANCE_JOINT])}.\n\n"
    f"Contact laws: {', '.join(catalog.names(catalog.LAWS))}.\n\n"
    f"Integrators: {', '.join(catalog.names(catalog.INTEGRATORS))}.")


@app.command(help=_CHECK_HELP, cls=ReadableCommand)
def check(model: ModelArg, set_: SetOpt = None) -> None:
    """Compile a model and print it (help text: _CHECK_HELP, from the catalog)."""
    from .check_command import check_model

    code = check_model(model, set_ or [])
    if code:
        raise typer.Exit(code)


@app.command(cls=ReadableCommand)
def run(
    model: ModelArg,
    output: Annotated[Optional[Path], typer.Option(
        "--output", "-o", help="HDF5 results file.",
        show_default="results/<model name>.h5, with the --set values in the name; when that file holds a run with "
                     "other settings, beside it with the options given in the name (results/a_n=100.h5)")] = None,
    set_: SetOpt = None,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="End time, with units (\"0.06 s\", 60ms).",
                     show_default="the model's simulate block")] = None,
    revolutions: Annotated[Optional[float], typer.Option(
        "--revolutions", "-n", help="End time as a number of periods of the crank's driver (instead of --t-end).",
        show_default=False)] = None,
    output_step: Annotated[Optional[str], typer.Option(
        "--output-step", help="Time between stored samples, with units (100us); a coarser step keeps files small.",
        show_default="the model's simulate block")] = None,
    per_rev: Annotated[Optional[int], typer.Option(
        "--per-rev", help="Stored samples per period of the crank's driver (instead of --output-step).", min=1,
        show_default=False)] = None,
    integrator: Annotated[Optional[str], typer.Option(help=_INTEGRATOR_HELP,
                          show_default="the model's simulate block, else dopri5")] = None,
    rtol: Annotated[Optional[float], typer.Option(help="Relative tolerance of the adaptive integrator "
                    "(floor: 10 x machine epsilon, 2.2e-15).",
                    show_default="the model's simulate block, else 1e-6")] = None,
    atol: Annotated[Optional[float], typer.Option(help="Absolute tolerance of the adaptive integrator (> 0; "
                    "SI units of each coordinate, e.g. 1e-3 x rtol).",
                    show_default="the model's simulate block, else 1e-9")] = None,
    step: Annotated[Optional[str], typer.Option(help="Fixed step of rk4 (first trial step of dopri5), with units "
                    "(1us).", show_default="the model's simulate block, else 1us")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
    rerun: Annotated[Optional[Path], typer.Option("--rerun", help="Also write a rerun recording of the run "
                     "(.rrd): the moving mechanism, forces, every signal.", show_default=False)] = None,
    magnify: Annotated[float, typer.Option(help="Clearance magnification in the rerun drawing.", min=0.0)] = 10.0,
    fps: Annotated[Optional[float], typer.Option(help="rerun frames per simulated second.",
                   show_default="90 per revolution of the driven body")] = None,
    open_: Annotated[bool, typer.Option("--open", help="Open the rerun viewer on the --rerun recording (as "
                     "`mbs view --open`).")] = False,
    view_: Annotated[bool, typer.Option("--view", hidden=True, help="The old name of --open.")] = False,
    rerun_signals: Annotated[str, typer.Option("--rerun-signals", help="envelope: per frame the first, smallest "
                             "and largest sample of each signal (peaks kept); full: every output sample.")]
    = "envelope",
    force: Annotated[bool, typer.Option("--force", help="Run even when the estimated output is beyond 10^8 rows "
                     "or larger than the free disk space (the run then stops cleanly if the disk fills); replace "
                     "a --rerun file that is not a recording of these results.")] = False,
    until_settled: Annotated[bool, typer.Option("--until-settled", help="Run revolution by revolution until the "
                             "Poincaré points have settled on a periodic orbit (checked every 50 revolutions), at "
                             "most --max-revolutions; see docs/sweeps.md.")] = False,
    max_revolutions: Annotated[int, typer.Option("--max-revolutions", help="Upper bound of --until-settled.",
                               min=1)] = 2000,
    keep: Annotated[Optional[str], typer.Option("--keep", help="Comma-separated signals to store (slider.vx); an "
                    "entity name (slider) keeps all its signals.  Fewer signals make smaller files and cheaper "
                    "output rows (no accelerations computed unless kept).", show_default="all")] = None,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace the output even when it is not the "
                         "results of a run (a sweep file, any other file); never the model or its includes.")]
    = False,
) -> None:
    """Simulate a model and write its signals to an HDF5 file; print a summary.

    Example: mbs run models/slider_crank_clearance_a.mbs --revolutions 60 --per-rev 720 --set speed=2500rpm
    """
    from .run_command import run_model

    code = run_model(model, output=output, set_=set_, t_end=t_end, revolutions=revolutions, output_step=output_step,
                     per_rev=per_rev, integrator=integrator, rtol=rtol, atol=atol, step=step, quiet=quiet,
                     rerun=rerun, magnify=magnify, fps=fps, view_=open_ or view_, rerun_signals=rerun_signals,
                     force=force, until_settled=until_settled, max_revolutions=max_revolutions, keep=keep,
                     overwrite=overwrite)
    if code:
        raise typer.Exit(code)


from .plot_commands import plot, view  # noqa: E402  (light: imports only typer)
from .sweep_commands import analyze, route, sweep, sweep_merge, sweep_replay  # noqa: E402  (light: typer)

for _command in (plot, view, sweep, analyze):
    app.command(cls=ReadableCommand)(_command)
app.command("sweep-replay", hidden=True, cls=ReadableCommand)(sweep_replay)
app.command("sweep-merge", hidden=True, cls=ReadableCommand)(sweep_merge)


def main() -> None:
    """The `mbs` entry point.  Every expected failure is reported by the commands themselves;
    anything else (a bug) still ends with one message instead of a traceback, unless
    MBS_TRACEBACK=1 asks for it."""
    import sys

    route(sys.argv)
    try:
        app()
    except Exception as exc:  # noqa: BLE001  (the last line of defence: never a traceback)
        sys.exit(internal_error(exc))
