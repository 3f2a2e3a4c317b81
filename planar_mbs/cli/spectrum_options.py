"""The typer options of a spectrum, shared by `mbs analyze --spectrum` and `mbs plot --spectrum`
(light: typer only, as `mbs --help` imports it)."""
from typing import Annotated, Optional

import typer

KindOpt = Annotated[str, typer.Option(
    "--kind", help="With --spectrum: amplitude (FFT), psd (Welch) or order (against revolutions of the clock "
    "body).")]
WindowOpt = Annotated[Optional[str], typer.Option(
    "--window", help="With --spectrum: a scipy.signal window (hann, flattop, boxcar, ...).",
    show_default="hann; boxcar over whole revolutions for --kind order")]
ResolutionOpt = Annotated[Optional[str], typer.Option(
    "--resolution", help="With --kind psd: the bin width of the Welch segments (5Hz).",
    show_default="about 8 segments, 50 % overlap")]
