"""`mbs sweep --sample ...` and `mbs sweep stats`: parse, call `planar_mbs.sweep.sampling`, print."""
from __future__ import annotations

import typer

from planar_mbs.errors import MbsError, ModelError
from planar_mbs.lazy import lazy

from .common import ExitCode, check_choice, check_output
from .common import console as _console
from .common import fail as _fail

sampling = lazy("planar_mbs.sweep.sampling")
sweep_scan = lazy("planar_mbs.sweep.scan")
hdf5 = lazy("planar_mbs.results.hdf5")
study_plot = lazy("planar_mbs.outputs.study_plot")  # matplotlib: only with --plot

SAMPLERS = ("mc", "lhs", "sobol")  # planar_mbs.sweep.sampling.SAMPLERS
FORMATS = ("png", "svg", "pdf")  # planar_mbs.outputs.plot.FORMATS


def study_options(param, sample, cases, sampler, seed, sobol_indices, output=None) -> dict | None:
    """The keyword arguments of `sampling.run_study` (None: a grid sweep, --param); a table file no
    longer there is read from the study in ``output`` being resumed."""
    if param and sample:
        raise ModelError("give --param (a grid) or --sample (a sampled study), not both", "--sample")
    if not param and not sample:
        raise ModelError("give the parameters to sweep: --param NAME=VALUES (a grid) or --sample "
                         "NAME=DISTRIBUTION (a sampled study)", "--param",
                         hint="e.g. `--param speed=800rpm,1200rpm` or `--sample crank=normal(50mm,0.1mm) --cases 64`")
    if not sample:
        return None
    if cases is None:
        raise ModelError("a sampled study needs --cases N", "--cases", hint="e.g. `--cases 64`")
    stored = sampling.stored_study(output) if output is not None and any("table" in t for t in sample) else None
    return {"distributions": [sampling.parse_distribution(t, stored) for t in sample], "n": cases,
            "sampler": check_choice(sampler, SAMPLERS, "--sampler"), "seed": seed, "sobol_indices": sobol_indices}


def design(param, sample, cases, sampler, seed, sobol_indices, output):
    """(the study's options, None for a grid; the grid's axes, none for a study)."""
    study = study_options(param, sample, cases, sampler, seed, sobol_indices, output)
    return study, ([] if study else [sweep_scan.parse_param(p) for p in param])


def start(study: dict | None, model, axes, output, **options):
    """`sampling.run_study` for a study, else `scan.run_sweep`."""
    if study is None:
        return sweep_scan.run_sweep(model, axes, output, **options)
    study = dict(study)
    return sampling.run_study(model, study.pop("distributions"), output, **study, **options)


def report(summary, output) -> None:
    """Failures in a sentence each, the counts, how to read the statistics; exit 3 when a case failed."""
    err = _console(stderr=True)
    for r in summary.rows:
        if r["index"] in summary.failed and r.get("message"):
            vals = ", ".join(f"{k}={v}" for k, v in r["values"].items())
            err.print(f"case {r['index']} ({vals}) failed: {r['message']}", markup=False, soft_wrap=True)
    failed = [r["index"] for r in summary.rows if r["status"] == "failed"]
    _console().print(f"{len(summary.ran)} case(s) run, {len(summary.skipped)} already in the file, {len(failed)} "
                     f"failed → {summary.path}  ({summary.wall_time:.1f} s); statistics: `mbs sweep stats "
                     f"{summary.path} SIGNAL:max`", markup=False, soft_wrap=True)
    if failed:
        raise typer.Exit(ExitCode.SIMULATION_FAILED)


def print_stats(path, outputs, confidence: float, plot=None, bands=()) -> None:
    """`mbs sweep stats`: the report of each output, and with ``plot`` its figure (`study_plot`)."""
    try:
        hdf5.check_results_file(path)
        if bands and plot is None:
            raise ModelError("--band draws a figure: give --plot FIG.png too", "--band")
        if not outputs and not (plot and bands):
            raise ModelError("name the outputs to describe (e.g. `slider.x:max`), or --band SIGNAL with --plot",
                             "OUTPUT", hint="e.g. `mbs sweep stats study.h5 slider.x@4ms --plot study.png`")
        if plot is not None:
            check_choice(plot.suffix[1:].lower() or "png", FORMATS, "--plot")
            check_output(plot, "--plot", [("the study file", path)])
        con = _console()
        for i, output in enumerate(outputs):
            lines = sampling.study_report(path, output, confidence).lines()
            for line in lines[1 if i else 0:]:  # the design once
                con.print(line, markup=False, soft_wrap=True)
        if plot is not None:
            con.print(f"figure → {study_plot.draw_study(path, plot, outputs, bands, confidence)}", markup=False)
    except MbsError as err:
        _fail(err)
