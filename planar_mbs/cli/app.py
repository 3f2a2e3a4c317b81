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
import inspect
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Optional

import typer

from planar_mbs import catalog
from planar_mbs.version import __version__
from planar_mbs.lazy import lazy

from .common import internal_error
from .help_text import ReadableCommand, ReadableGroup, TwoWordCommand, use_one_error_style
from .run_options import RUN_OPTIONS, SET_HELP, Opt, merged

# lark, numpy, the kernels: loaded when a command runs, never by `mbs --help`
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from . import check_command
    from . import run_command
else:  # each loaded on its first use (see the comments: not on the light paths)
    check_command = lazy(".check_command", __package__)
    run_command = lazy(".run_command", __package__)

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
    typer.Option("--set", "-s", help=SET_HELP, show_default=False),
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
    code = check_command.check_model(model, set_ or [])
    if code:
        raise typer.Exit(code)


_KINDS = {"path": Path, "list": list[str], "str": str, "float": float, "int": int, "flag": bool}


def _option(opt: Opt):
    """The typer annotation of one option of `RUN_OPTIONS`."""
    kind = _KINDS[opt.kind] if opt.default is not None else Optional[_KINDS[opt.kind]]
    extra = {} if opt.show_default is True else {"show_default": opt.show_default}
    if opt.low is not None:
        extra["min"] = opt.low
    if opt.hidden:
        extra["hidden"] = True
    return Annotated[kind, typer.Option(*opt.flags, help=opt.help, **extra)]


def _run(**options) -> None:
    """Simulate a model and write its signals to an HDF5 file; print a summary.

    A model whose clearance joint declares `wear` makes a wear run instead: its file saved after each
    update, one line per update, --resume to go on (docs/wear.md).

    Example: mbs run models/slider_crank_clearance_a.mbs --revolutions 60 --per-rev 720 --set speed=2500rpm
    """
    code = run_command.run_model(**merged(options))
    if code:
        raise typer.Exit(code)


def _run_command():
    """`mbs run` as a typer command whose parameters are `RUN_OPTIONS` (the table `plain_run` reads too)."""
    keyword = inspect.Parameter.POSITIONAL_OR_KEYWORD
    params = [inspect.Parameter("model", keyword, annotation=ModelArg)]
    params += [inspect.Parameter(o.param, keyword, default=o.default, annotation=_option(o)) for o in RUN_OPTIONS]
    _run.__signature__ = inspect.Signature(params)
    _run.__annotations__ = {p.name: p.annotation for p in params}
    _run.__name__ = "run"
    return _run


run = app.command(cls=ReadableCommand)(_run_command())


from .plot_commands import plot, view  # noqa: E402  (light: imports only typer)
from .sweep_commands import analyze, route, sweep, sweep_merge, sweep_replay  # noqa: E402  (light: typer)
from .study_options import sweep_stats  # noqa: E402  (light: typer)
from .static_options import modes, static  # noqa: E402  (light: typer)

for _command in (plot, view, sweep, analyze, static, modes):
    app.command(cls=ReadableCommand)(_command)
app.command("sweep-replay", hidden=True, cls=TwoWordCommand)(sweep_replay)
app.command("sweep-merge", hidden=True, cls=TwoWordCommand)(sweep_merge)
app.command("sweep-stats", hidden=True, cls=TwoWordCommand)(sweep_stats)


def main() -> None:
    """The `mbs` entry point.  Every expected failure is reported by the commands themselves;
    anything else (a bug) still ends with one message instead of a traceback, unless
    MBS_TRACEBACK=1 asks for it."""
    route(sys.argv)
    try:
        app()
    except Exception as exc:  # noqa: BLE001  (the last line of defence: never a traceback)
        sys.exit(internal_error(exc))
