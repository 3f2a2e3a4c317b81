"""The typer options of a sampled study (`mbs sweep --sample`) and `mbs sweep stats` (light: typer
only, as `mbs --help` imports it; the work is in `study_command`)."""
from pathlib import Path
from typing import Annotated, Optional

import typer

from planar_mbs.lazy import lazy

study_command = lazy("planar_mbs.cli.study_command")

SampleOpt = Annotated[Optional[list[str]], typer.Option(
    "--sample", help="NAME=DISTRIBUTION: normal(MEAN,STD), uniform(LOW,HIGH), truncnormal(MEAN,STD,LOW,HIGH), "
    "with units (crank=normal(50mm,0.1mm)), or table(FILE.csv,UNIT): measured values, one a line. Repeatable; a sampled study instead of the --param grid.",
    show_default="none: --param")]
CasesOpt = Annotated[Optional[int], typer.Option(
    "--cases", help="With --sample: the number of samples (with --sobol-indices, base samples: "
    "(parameters + 2) cases each).", min=2, show_default="none")]
SamplerOpt = Annotated[str, typer.Option("--sampler", help="With --sample: mc (Monte Carlo), lhs (Latin "
                                         "hypercube) or sobol (scrambled Sobol' sequence).")]
SeedOpt = Annotated[int, typer.Option("--random-state", help="With --sample: the random generator's state (an "
                                      "integer); the same number gives the same cases.", min=0)]
SobolOpt = Annotated[bool, typer.Option("--sobol-indices", help="With --sample: Saltelli's design, for first-order "
                                        "and total Sobol indices (`mbs sweep stats`).")]


def sweep_stats(
    study: Annotated[Path, typer.Argument(help="The sampled study's HDF5 file (`mbs sweep --sample`).",
                                          show_default=False)],
    outputs: Annotated[Optional[list[str]], typer.Argument(
        help="Outputs: SIGNAL:min, SIGNAL:max, SIGNAL:rms (stored for every case) or SIGNAL@TIME of a kept "
             "signal (slider.x@15ms).", show_default=False)] = None,
    confidence: Annotated[float, typer.Option("--confidence", help="Confidence of the intervals.",
                                              min=0.5, max=0.999)] = 0.95,
    plot: Annotated[Optional[Path], typer.Option(
        "--plot", help="Draw the study into this figure (png, svg, pdf): a histogram of each OUTPUT, its Sobol "
        "indices as bars (with --sobol-indices), the percentile band of each --band signal.",
        show_default="none")] = None,
    band: Annotated[Optional[list[str]], typer.Option(
        "--band", help="With --plot: the 5, 50 and 95 % percentiles over time of this kept signal across the "
        "samples. Repeatable.", show_default="none")] = None,
) -> None:
    """Statistics of each OUTPUT over the cases of a sampled study: mean, standard deviation and
    percentiles with confidence intervals, how they narrow as cases are added, and first-order and
    total Sobol indices when the study was run with --sobol-indices; with --plot, their figure."""
    study_command.print_stats(study, outputs or [], confidence, plot, band or [])
