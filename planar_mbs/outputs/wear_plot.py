"""Figures of a worn bearing (run/wear.py): the profile's depth over angle in polar axes, one curve per
chosen update, and the worn volume and maximum depth against the cycles worn; `plot_wear_file` draws
the file of a wear run (`mbs plot WEAR.h5`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..lazy import lazy

mpl_figure = lazy("matplotlib.figure")  # matplotlib: only a figure being drawn loads it
modes_plot = lazy("planar_mbs.outputs.modes_plot")  # `save`: a figure written whole
wear = lazy("planar_mbs.run.wear")


def wear_figure(history, period: float | None = None, curves: int = 5, title: str = ""):
    """Left: depth (µm) against the bearing-frame angle, polar, for `curves` updates spread over the run;
    right: worn volume per unit width and maximum depth against the worn time, in cycles where `period`
    (s per cycle) is given.  Returns a matplotlib Figure (Agg)."""
    fig = mpl_figure.Figure(figsize=(10, 4.4))
    ax = fig.add_subplot(1, 2, 1, projection="polar")
    n = len(history.depths)
    picks = sorted(set(np.linspace(1, n - 1, min(curves, n - 1)).round().astype(int))) if n > 1 else [0]
    th = np.append(history.theta, 2 * np.pi)
    scale = 1.0 / period if period else 1.0
    unit = "cycles" if period else "s"
    if period and history.worn_times[-1] * scale >= 1e4:
        scale, unit = scale / 1e3, "10³ cycles"
    for i in picks:
        d = np.append(history.depths[i], history.depths[i][0]) * 1e6
        ax.plot(th, d, lw=1.2, label=f"{history.worn_times[i] * scale:.3g} {unit}")
    ax.set_title(f"worn depth of `{history.joint}` [µm], bearing frame", fontsize=9)
    ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(-0.25, -0.12))
    ax2 = fig.add_subplot(1, 2, 2)
    t = np.array(history.worn_times) * scale
    sig = history.signals()
    ax2.plot(t, sig[f"{history.joint}.worn_volume"] * 1e9, "C0.-", label="worn volume / width [10⁻³ mm²]")
    ax2.plot(t, sig[f"{history.joint}.max_wear_depth"] * 1e6, "C3.-", label="maximum depth [µm]")
    ax2.set_xlabel(f"worn time [{unit}]")
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def plot_wear_file(path, outdir=None, fmt: str = "png", title: str | None = None, size=None) -> Path:
    """`mbs plot WEAR.h5`: `wear_figure` of the file's history (in cycles where the run had a driver
    period), written whole to ``<outdir>/<stem>_wear.<fmt>`` (outdir: the file's folder); the path."""
    path = Path(path)
    h = wear.load_history(path)
    facts = wear.saved_facts(path, h.joint)
    model = Path(str(facts.get("model", ""))).name or "model"
    fig = wear_figure(h, float(facts.get("period", 0.0)) or None,
                      title=f"{model}: wear of `{h.joint}`, {len(h.depths) - 1} updates" if title is None else title)
    if size is not None:
        fig.set_size_inches(*size)
    out = Path(outdir or path.parent) / f"{path.stem}_wear.{fmt}"
    Path(out.parent).mkdir(parents=True, exist_ok=True)
    return modes_plot.save(fig, out)
