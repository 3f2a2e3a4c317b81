"""Figures of a sampled study (`mbs sweep stats STUDY.h5 OUTPUT ... --plot FIG.png`).

One row per OUTPUT: the histogram of its values over the study's samples (the bins numpy's
``"auto"`` rule gives, `np.histogram_bin_edges`), its 5th, 50th and 95th percentiles marked, and, for
a study with Saltelli's design, its first-order and total Sobol indices as bars with their
bootstrap intervals as error bars (the numbers `mbs sweep stats` prints); then one row per
``--band`` signal: its 5–95 % band and median over time across the samples (`sampling.kept_band`).
Drawn on a ``matplotlib.figure.Figure`` (Agg canvas, no pyplot state).
"""
from __future__ import annotations

import textwrap
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..lazy import lazy
from .modes_plot import save

mpl_figure = lazy("matplotlib.figure")  # matplotlib: only a figure being drawn loads it
if TYPE_CHECKING:
    from ..sweep import sampling
else:
    sampling = lazy("..sweep.sampling", __package__)  # scipy.stats: only a study's figure

BAND = (5.0, 50.0, 95.0)


def _unit(unit: str) -> str:
    return f" [{unit}]" if unit not in ("", "1") else ""


def histogram(ax, report) -> None:
    """The histogram of one output's finite values, with its percentiles as vertical lines."""
    y = np.asarray(report.values, float)
    y = y[np.isfinite(y)]
    edges = np.histogram_bin_edges(y, bins="auto") if len(y) else np.array([0.0, 1.0])
    ax.hist(y, bins=edges, color="tab:blue", alpha=0.75, edgecolor="white", label=f"{len(y)} samples")
    for (p, iv), style in zip(report.statistics.percentiles.items(), (":", "-", ":")):
        if np.isfinite(iv.value):
            ax.axvline(iv.value, color="k", ls=style, lw=1.0, label=f"p{p:g} = {iv.value:.4g}")
    ax.set_xlabel(report.output + _unit(report.unit))
    ax.set_ylabel("cases")
    ax.set_title(f"{report.output}: mean {report.statistics.mean.value:.4g}, std {report.statistics.std.value:.3g}",
                 fontsize="small")
    ax.legend(fontsize="x-small")
    ax.grid(alpha=0.3)


def sobol_bars(ax, sobol) -> None:
    """First-order and total indices per parameter, side by side, each with its bootstrap interval."""
    x = np.arange(len(sobol.names))
    for k, (ivs, label, colour) in enumerate(((sobol.first, "first order S", "tab:blue"),
                                              (sobol.total, "total ST", "tab:orange"))):
        v = np.array([iv.value for iv in ivs])
        err = np.array([[iv.value - iv.low for iv in ivs], [iv.high - iv.value for iv in ivs]])
        ax.bar(x + (k - 0.5) * 0.38, v, width=0.38, color=colour, label=label,
               yerr=np.where(np.isfinite(err), err, 0.0), capsize=3, gid=label)
    ax.set_xticks(x, sobol.names)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_ylabel("Sobol index")
    ax.set_title(f"Sobol indices, {sobol.n} base samples, {100 * sobol.confidence:g} % bootstrap intervals",
                 fontsize="small")
    ax.legend(fontsize="x-small")
    ax.grid(alpha=0.3, axis="y")


def band(ax, t, bands, signal: str, unit: str, n: int) -> None:
    """The 5–95 % band over time and the median of a kept signal across the samples."""
    ax.fill_between(t, bands[0], bands[2], color="tab:blue", alpha=0.3, lw=0, label="5 % to 95 %")
    ax.plot(t, bands[1], color="tab:blue", lw=1.2, label="median")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(signal + _unit(unit))
    ax.set_title(f"{signal}: percentiles over {n} samples at each time", fontsize="small")
    ax.legend(fontsize="x-small")
    ax.grid(alpha=0.3)


def figure(path, outputs: Sequence[str], bands: Sequence[str] = (), confidence: float = 0.95):
    """The study's figure: a row per output (histogram; Sobol bars beside it when designed for) and a
    row per band signal."""
    reports = [sampling.study_report(path, o, confidence) for o in outputs]
    drawn = [sampling.kept_band(path, s, BAND) for s in bands]
    cols = 2 if any(r.sobol is not None for r in reports) else 1
    rows = max(1, len(reports) + len(drawn))
    width = 5.2 * cols if cols > 1 else 8.0
    fig = mpl_figure.Figure(figsize=(width, 3.4 * rows), layout="constrained", dpi=110)
    grid = fig.add_gridspec(rows, cols)
    for i, r in enumerate(reports):
        histogram(fig.add_subplot(grid[i, 0]), r)
        if r.sobol is not None:
            sobol_bars(fig.add_subplot(grid[i, 1]), r.sobol)
    for j, (s, (t, b, unit, n)) in enumerate(zip(bands, drawn)):
        band(fig.add_subplot(grid[len(reports) + j, :]), t, b, s, unit, n)
    study = (reports[0].study if reports else sampling.stored_study(path))
    size = (f"{study.n} base samples (Saltelli's design)" if study.sobol_indices else f"{study.n} samples")
    fig.suptitle(textwrap.fill(f"{Path(path).name}: {study.sampler} study, {size}; "
                               + "; ".join(d.describe() for d in study.distributions), int(14 * width)),
                 fontsize="small")
    return fig


def draw_study(path, fig_path, outputs: Sequence[str], bands: Sequence[str] = (), confidence: float = 0.95) -> Path:
    """Draw `figure` into ``fig_path`` (png, svg, pdf: its suffix), written whole."""
    return save(figure(path, outputs, bands, confidence), fig_path)
