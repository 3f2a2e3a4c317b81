"""`mbs analyze FILE --spectrum SIGNAL`: parse the options, compute (`planar_mbs.results.spectrum`), print.

Also the `--from`/`--to`/`--resolution` parsing `mbs plot --spectrum` shares.
"""
from __future__ import annotations

from pathlib import Path

from planar_mbs.lazy import lazy

from .common import check_choice, check_number, check_output
from .common import console as _console
from .common import quantity as _quantity

spectra = lazy("planar_mbs.results.spectrum")
hdf5 = lazy("planar_mbs.results.hdf5")
np = lazy("numpy")

KINDS = ("amplitude", "psd", "order")  # planar_mbs.results.spectrum.KINDS (not imported by `mbs --help`)


def spectrum_options(kind, window, resolution, t_from, t_to, clock) -> dict:
    """The keyword arguments of `spectrum.spectrum` that the options give, each checked."""
    kind = check_choice(kind, KINDS, "--kind")
    opts: dict = {"kind": kind, "window": window}
    opts["t_from"] = check_number(_quantity(t_from, "time", "--from"), "--from", low=0.0, low_ok=True,
                                  hint="the end of the transient, a time from the start of the run, e.g. `--from 0.1s`")
    opts["t_to"] = check_number(_quantity(t_to, "time", "--to"), "--to", low=0.0,
                                hint="a time from the start of the run, e.g. `--to 0.5s`")
    if resolution is not None:
        if kind != "psd":
            raise spectra.SpectrumError(f"--resolution is the Welch segments' bin width: it takes --kind psd, "
                                        f"not {kind}")
        opts["resolution"] = check_number(_quantity(resolution, "frequency", "--resolution"), "--resolution",
                                          low=0.0, hint="a frequency, e.g. `--resolution 5Hz`")
    if clock:
        if kind != "order":
            raise spectra.SpectrumError("--clock with --spectrum names the body of an order spectrum: "
                                        "it takes --kind order")
        opts["clock"] = clock
    return opts


def print_spectrum(results: Path, name: str, opts: dict, peaks: int = 5, csv: Path | None = None) -> None:
    """Compute and print the spectrum; write it as CSV to ``csv`` when given."""
    if csv is not None:
        check_output(csv, "--csv", [("the results file", Path(str(results).split(":/", 1)[0]))])
    res = hdf5.read_results(results)
    opts = dict(opts)
    spec = spectra.spectrum(res, name, opts.pop("kind"), **opts)
    con = _console()
    for line in spectra.report(spec, peaks):
        con.print(line, markup=False, soft_wrap=True)
    if csv is not None:
        write_csv(spec, csv)
        con.print(f"spectrum → {csv}", markup=False)


def write_csv(spec, path: Path) -> None:
    """Two columns, x and y, under a header of comment lines stating how the spectrum was computed."""
    xname = "order" if spec.kind == "order" else "frequency [Hz]"
    header = f"{spec.describe()}\n{xname},{spec.signal} [{spec.y_unit}]"
    np.savetxt(path, np.column_stack([spec.x, spec.y]), delimiter=",", header=header, fmt="%.10g")
