"""Figures of a worn bearing (run/wear.py): the profile's depth over angle in polar axes, one curve per
chosen update, and the worn volume and maximum depth against the cycles worn."""
from __future__ import annotations

import numpy as np

from ..lazy import lazy

mpl_figure = lazy("matplotlib.figure")  # matplotlib: only a figure being drawn loads it


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
