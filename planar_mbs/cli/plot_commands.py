"""`mbs plot` and `mbs view`: thin typer commands over `planar_mbs.outputs.plot` and
`planar_mbs.outputs.rerun_log`, plus `record_run`, which `mbs run --rerun OUT.rrd` calls.

Registered in `app.py` with ``app.command()(plot)`` and ``app.command()(view)``.
Errors are printed without a traceback; bad usage (unknown signal, not a results
file, unknown format) exits with code 2.
"""
from pathlib import Path
from typing import Annotated, Optional

import typer

from planar_mbs.errors import MbsError
from planar_mbs.lazy import lazy

from .common import check_choice, check_number, check_output
from .spectrum_options import KindOpt, ResolutionOpt, WindowOpt
from .common import console as _console
from .common import fail as _fail
from .common import quantity as _quantity

# numpy, h5py, matplotlib, rerun: loaded when a command runs, never by `mbs --help` (which imports this module)
hdf5 = lazy("planar_mbs.results.hdf5")
figures = lazy("planar_mbs.outputs.plot")
views = lazy("planar_mbs.results.views")
rerun_log = lazy("planar_mbs.outputs.rerun_log")
wear_plot = lazy("planar_mbs.outputs.wear_plot")
wear_recording = lazy("planar_mbs.outputs.wear_recording")
rich_table = lazy("rich.table")
spectrum_command = lazy("planar_mbs.cli.spectrum_command")


def _results_path(text: Path) -> Path:
    """The file part of `FILE.h5` or `FILE.h5:/cases/3`, checked to be a regular HDF5 file
    (a FIFO or a device is never opened)."""
    return hdf5.check_results_file(Path(str(text).split(":/", 1)[0]))


ResultsArg = Annotated[Path, typer.Argument(help="HDF5 results file written by `mbs run` (or a sweep file; "
                                            "one case of a sweep: FILE.h5:/cases/3; a wear run's file).",
                                            show_default=False)]


OrbitOpt = Annotated[Optional[list[str]], typer.Option(
    "--orbit", help="Journal orbit of this clearance joint inside its clearance circle. Repeatable.",
    show_default=False)]
PlotFromOpt = Annotated[Optional[str], typer.Option(
    "--from", help="Start of the time window drawn, with units (0.2s).", show_default="the start of the run")]
PlotToOpt = Annotated[Optional[str], typer.Option(
    "--to", help="End of the time window drawn, with units (250ms).", show_default="the end of the run")]
TitleOpt = Annotated[Optional[str], typer.Option(
    "--title", help="Title of every figure drawn.", show_default="the model and the parameters that fit one line")]
XLabelOpt = Annotated[Optional[str], typer.Option(
    "--xlabel", help="Label of the x axis.", show_default="the quantity in words, with its unit")]
YLabelOpt = Annotated[Optional[str], typer.Option(
    "--ylabel", help="Label of the y axis (of every panel).", show_default="the quantity in words, with its unit")]
SizeOpt = Annotated[Optional[str], typer.Option(
    "--size", help="Figure size WIDTHxHEIGHT in inches (8x4).", show_default="each figure's own")]


def plot(
    results: ResultsArg,
    signals: Annotated[Optional[list[str]], typer.Argument(
        help="Signals to plot, one panel each; join names with commas to share a panel (A.fx,A.fy). "
             "None: the default figures.", show_default=False)] = None,
    against: Annotated[Optional[str], typer.Option(
        "--against", "-x", help="Plot against this signal instead of time (angles in degrees, mod 360: "
                                "--against crank.phi).", show_default=False)] = None,
    poincare: Annotated[Optional[str], typer.Option(
        "--poincare", "-p", help="Poincaré map X:Y, sampled once per revolution of the driven body "
                                 "(e.g. slider.vx:slider.ax).", show_default=False)] = None,
    orbit: OrbitOpt = None,
    output: Annotated[Optional[Path], typer.Option(
        "--output", "-o", help="Directory for the figures.",
        show_default="<results>_plots/ next to the results file")] = None,
    fmt: Annotated[str, typer.Option("--format", "-f", help="png, svg or pdf.")] = "png",
    transient: Annotated[int, typer.Option("--transient", help="Revolutions dropped at the start before "
                                           "Poincaré sampling (as `mbs analyze --transient`).", min=0)] = 1,
    skip: Annotated[Optional[int], typer.Option("--skip", hidden=True, min=0, help="The old name of --transient.")]
    = None,
    body: Annotated[Optional[str], typer.Option(
        "--clock", help="Body whose revolutions clock the Poincaré section.",
        show_default="the body that turns most, i.e. the driven crank")] = None,
    list_: Annotated[bool, typer.Option("--list", "-l", help="List the signals in the file and exit.")] = False,
    t_from: PlotFromOpt = None,
    t_to: PlotToOpt = None,
    spectrum: Annotated[Optional[list[str]], typer.Option(
        "--spectrum", help="A spectrum figure of this signal over the --from/--to window. Repeatable.",
        show_default="none")] = None,
    kind: KindOpt = "amplitude",
    window_name: WindowOpt = None,
    resolution: ResolutionOpt = None,
    title: TitleOpt = None,
    xlabel: XLabelOpt = None,
    ylabel: YLabelOpt = None,
    size: SizeOpt = None,
) -> None:
    """Draw figures of a run or a sweep (PNG, SVG or PDF).

    Time series (one panel per SIGNAL), Poincaré maps, journal orbits; for a sweep file, a grid
    per signal and a bifurcation diagram.  With no SIGNAL: Muvengei et al.'s default figures.  A wear
    run's file: the worn profile and the wear against the cycles, in <file>_wear.png beside it.

    Examples: mbs plot a.h5 · mbs plot a.h5 slider.ax A.contact_force --against crank.phi ·
    mbs plot a.h5 --poincare slider.vx:slider.ax --transient 2 · mbs plot a.h5 --orbit A -f svg ·
    mbs plot a.h5 --orbit A --from 0.2s --to 0.25s · mbs plot a.h5 slider.vx --title "800 rpm" --size 6x3
    """
    skip = transient if skip is None else skip
    try:
        fmt = check_choice(fmt, figures.FORMATS, "--format")
        file = _results_path(results)
        if ":/" not in str(results) and hdf5.results_kind(file) == "wear":
            return _plot_wear(file, output, fmt, title, size, [signals, against, poincare, orbit, spectrum, t_from,
                                                              t_to, list_, xlabel, ylabel])
        if list_:
            _list_signals(results)
            return
        window = _window(t_from, t_to)
        notes: list[str] = []
        spectra = spectrum_command.spectrum_options(kind, window_name, resolution, None, None, None) \
            if spectrum else None
        check_output(output or file.parent / f"{file.stem}_plots", "--output", [("the results file", file)],
                     folder=True)
        extra = {"spectra": spectrum or [], "spectrum_options": _with_clock(spectra, body),
                 "style": figures.check_style(dict(title=title, xlabel=xlabel, ylabel=ylabel, size=size))}
        if ":/" in str(results):  # one case of a sweep: plot it like a run
            written = _plot_case(results, signals, against, poincare, orbit, output, fmt, skip, body, window, notes,
                                 extra)
        else:
            written = figures.plot_file(file, signals or [], against, poincare, output, fmt, skip, body, orbit or [],
                                notes=notes, **window, **extra)
    except MbsError as err:
        _fail(err)
    for note in notes:
        _console(stderr=True).print(f"warning: {note}", markup=False, style="yellow")
    con = _console()
    for path in written:
        con.print(str(path), markup=False)
    if not written:
        con.print("nothing to plot", markup=False)


def _window(t_from, t_to) -> dict:
    """The --from/--to window of `mbs plot`, checked."""
    return dict(t_from=check_number(_quantity(t_from, "time", "--from"), "--from", low=0.0, low_ok=True,
                                    hint="a time from the start of the run, e.g. `--from 0.2s`"),
                t_to=check_number(_quantity(t_to, "time", "--to"), "--to", low=0.0,
                                  hint="a time from the start of the run, e.g. `--to 0.25s`"))


_RUN_PLOT_OPTIONS = ("SIGNAL", "--against", "--poincare", "--orbit", "--spectrum", "--from", "--to", "--list",
                     "--xlabel", "--ylabel")  # what `_plot_wear` refuses, in the order it is given them


def _plot_wear(file: Path, output, fmt: str, title, size, others: list) -> None:
    """`mbs plot WEAR.h5`: the worn profile over the updates and the volume and depth against the cycles
    (`outputs.wear_plot`), beside the file or in the --output folder; the options of a run's plots refused."""
    given = [flag for flag, value in zip(_RUN_PLOT_OPTIONS, others) if value not in (None, False, [])]
    if given:
        raise views.PlotError(f"error: {given[0]} does not apply to the file of a wear run\nhint: `mbs plot "
                              f"{file}` draws its figure; --output, --format, --title and --size shape it")
    check_output(output or file.parent, "--output", [("the wear file", file)], folder=True)
    style = figures.check_style(dict(size=size))
    _console().print(str(wear_plot.plot_wear_file(file, output, fmt, title, style.get("size"))), markup=False,
                     soft_wrap=True)


def _with_clock(spectra, body):
    """The spectrum options, with `--clock` as the order spectrum's body."""
    if spectra is None:
        return None
    if body and spectra["kind"] == "order":
        spectra["clock"] = body
    return spectra


def _plot_case(results, signals, against, poincare, orbit, output, fmt, skip, body, window, notes, extra):
    """`mbs plot sweep.h5:/cases/3 ...`: plot one case of a sweep like a run."""
    try:
        res = hdf5.read_results(results)
    except KeyError as exc:
        raise views.PlotError(f"error: no group {exc} in {str(results).split(':/', 1)[0]}") from None
    file, group = str(results).split(":", 1)
    stem = f"{Path(file).stem}_case{group.rstrip('/').rsplit('/', 1)[-1]}"
    out = output or Path(file).parent / f"{stem}_plots"
    return figures.plot_results(res, stem, signals or [], against, poincare, out, fmt, skip, body, orbit or [],
                        notes=notes, **window, **extra)


def _list_signals(results: Path) -> None:
    if ":/" not in str(results) and figures.is_sweep(results):
        cases = figures.sweep_cases(results)
        _console().print(f"sweep with {len(cases)} cases; signals of case {cases[0][0]}:", markup=False)
        res = cases[0][1]
    else:
        res = hdf5.read_results(results)
    table = rich_table.Table("signal", "unit", title=f"{len(res.signals)} signals, {len(res.time):,} samples",
                  title_justify="left")
    for name in sorted(res.signals):
        table.add_row(name, res.units.get(name, ""))
    _console().print(table)


def view(
    results: ResultsArg,
    output: Annotated[Optional[Path], typer.Option(
        "--output", "-o", help="The rerun recording to write.",
        show_default="<results>.rrd next to the results file")] = None,
    open_: Annotated[bool, typer.Option("--open", help="Open the rerun viewer on the recording.")] = False,
    magnify: Annotated[Optional[float], typer.Option(
        help="Magnification of the clearance (eccentricity and gap) in the drawing; of a wear file, of the "
             "worn depth.", min=0.0, show_default="10; a wear file: the deepest wear drawn as a quarter of the "
                                                  "radius")] = None,
    fps: Annotated[Optional[float], typer.Option(
        help="Frames per simulated second.",
        show_default="90 per revolution of the driven body", min=0.0)] = None,
    signals: Annotated[str, typer.Option(
        "--signals", help="Scalar series: `envelope` (per frame bin the first sample, the min and the max; "
                          "peaks kept, far smaller and faster) or `full` (every sample).")] = "envelope",
    signal_rate: Annotated[Optional[float], typer.Option(
        help="Envelope bins per simulated second.", show_default="the frame rate", min=0.0)] = None,
    signal_stride: Annotated[int, typer.Option(help="Keep every n-th sample of the scalar signals instead "
                                                    "(no envelope).", min=1)] = 1,
    signals_only: Annotated[bool, typer.Option("--signals-only", help="Do not rebuild the model; log the "
                                               "signals, contact events and Poincaré points only.")] = False,
    force: Annotated[bool, typer.Option("--force", help="Replace the output even when it is not a recording of "
                                        "these results (another run's).")] = False,
) -> None:
    """Turn a results file into a rerun recording (.rrd) and optionally open the viewer.

    The moving mechanism (clearance magnified), joint reactions and contact forces as arrows,
    every signal, contact onsets and Poincaré points, on a `sim_time` timeline.  A wear run's file:
    the worn bearing's profile (magnified) and its wear per update, on a timeline `update`.

    Example: mbs view a.h5 -o a.rrd --open
    """
    try:
        signals = check_choice(signals, ("envelope", "full"), "--signals")
        check_number(magnify, "--magnify", low=0.0, low_ok=True, hint="e.g. `--magnify 10`")
        check_number(fps, "--fps", low=0.0, hint="frames per simulated second, e.g. `--fps 600`")
        check_number(signal_rate, "--signal-rate", low=0.0, hint="bins per simulated second, e.g. 2000")
        file = _results_path(results)
        out = output or file.with_suffix(".rrd")
        check_output(out, "--output", [("the results file", file)], make_parents=True)
        key = rerun_log.recording_key(results)
        rerun_log.check_replace(out, key, force)
        if ":/" not in str(results) and hdf5.results_kind(file) == "wear":
            return _view_wear(file, out, open_, magnify, key, [fps, signal_rate, signal_stride != 1, signals_only,
                                                               signals != "envelope"])
        res = hdf5.read_results(results)
        if not len(res.time):
            raise views.PlotError(f"error: {results} holds no samples: nothing to record")
        model = None if signals_only else rerun_log.model_from_results(res)
        record_run(res, model, out, magnify=10.0 if magnify is None else magnify, fps=fps,
                   signal_stride=signal_stride, open_viewer=open_, signals=signals, signal_rate=signal_rate,
                   recording_id=key)
    except MbsError as err:
        _fail(err)
    except OSError as err:
        _fail(f"error: {err}")


def _view_wear(file: Path, out: Path, open_: bool, magnify, key: str, others: list) -> None:
    """`mbs view WEAR.h5`: the worn profile per update on a rerun timeline `update` (`outputs.wear_recording`);
    the options of a run's recording refused."""
    flags = ("--fps", "--signal-rate", "--signal-stride", "--signals-only", "--signals")
    given = [flag for flag, value in zip(flags, others) if value not in (None, False)]
    if given:
        raise views.PlotError(f"error: {given[0]} does not apply to the file of a wear run\nhint: `mbs view "
                              f"{file}` records its profile per update; --output, --magnify, --open and --force apply")
    n, factor = wear_recording.record_wear(file, out, magnify, recording_id=key)
    _console().print(f"rerun recording → {out}: the worn profile at {n} updates (timeline `update`), the depth "
                     f"magnified {factor:.4g} times", markup=False, soft_wrap=True)
    if open_:
        rerun_log.open_viewer(out)


def record_run(results, model, path, magnify: float = 10.0, fps: float | None = None, signal_stride: int = 1,
               open_viewer: bool = False, quiet: bool = False, signals: str = "envelope",
               signal_rate: float | None = None, recording_id: str | None = None):
    """Write a rerun recording of `results` (drawn with `model`; None = signals only) to
    `path`, print one summary line, optionally open the viewer.  `mbs run --rerun` calls this
    (`signals="full"` for every sample of every signal, e.g. from a `--rerun-signals full`)."""
    info = rerun_log.record_run(results, model, path, magnify=magnify, fps=fps, signal_stride=signal_stride,
                   signals=signals, signal_rate=signal_rate, recording_id=recording_id)
    if not quiet:
        loop = float(results.attrs.get("wall_time") or 0.0)
        # a share of the time loop only when it is one: short runs pay rerun's fixed start-up cost
        share = (f", {100 * info.seconds / loop:.0f} % of the time loop" if 0 < info.seconds <= loop
                 else f"; the time loop took {loop:.2f} s" if loop > 0 else "")
        _console().print(
            f"rerun recording → {path}: {info.frames:,} frames, {info.signals} signals, "
            f"{info.signal_samples:,} scalar samples ({info.signal_mode}), "
            f"{info.contact_onsets:,} contact onsets, {info.poincare_points} Poincaré points "
            f"({info.seconds:.2f} s{share})", markup=False)
    if open_viewer:
        rerun_log.open_viewer(path)
    return info
