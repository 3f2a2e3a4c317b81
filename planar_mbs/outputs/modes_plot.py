"""Mode shapes drawn with matplotlib: the mechanism at its state and displaced along each mode.

Each body is drawn through the points the model gives it (joint, clearance, driver and force points,
and its centre of mass), at the state linearised about (grey) and displaced along a mode (colour):
q + a Re(phi), with the amplitude a chosen so that the largest displacement of a drawn point is a
tenth of the mechanism's size.  A panel per mode, titled with its frequency and damping ratio.
"""
from __future__ import annotations

import os
import secrets
from pathlib import Path

import numpy as np

from ..files import replace_atomically
from ..lazy import lazy

mpl_figure = lazy("matplotlib.figure")  # matplotlib: only a figure being drawn loads it

AMPLITUDE = 0.1  # largest displacement drawn, as a fraction of the mechanism's size


def body_outlines(model) -> list[list[np.ndarray]]:
    """Per body, the polylines drawn (body frame): through its centre of mass and every point an element
    puts on it, in order of angle about the centre (a line for two points), and its `shape` outline
    (a box's rectangle, a circle)."""
    k = model.kernel
    pts: list[list] = [[(0.0, 0.0)] for _ in range(model.nbody)]
    for points, bodies in ((k.joint_point, k.joint_body), (k.clearance_point, k.clearance_body),
                           (k.driver_point, k.driver_body), (k.force_point, k.force_body)):
        points = np.asarray(points, dtype=float).reshape(-1, 2, 2)
        for p, b in zip(points, np.asarray(bodies).reshape(-1, 2)):
            for side in (0, 1):
                if b[side] >= 0:
                    pts[b[side]].append(tuple(p[side]))
    out = []
    for b, p in enumerate(pts):
        p = np.unique(np.round(np.array(p), 12), axis=0)
        if len(p) > 2:
            p = p[np.argsort(np.arctan2(p[:, 1], p[:, 0]))]
            p = np.vstack([p, p[:1]])
        geom = model.body_geometry[b] if b < len(model.body_geometry) and model.body_geometry[b] else {}
        out.append([p] + _shape(geom))
    return out


def _shape(geom: dict) -> list[np.ndarray]:
    """A box's rectangle or a circle (body frame); a bar is drawn through its points."""
    if geom.get("kind") == "box":
        w, h = float(geom["width"]) / 2, float(geom["height"]) / 2
        return [np.array([(-w, -h), (w, -h), (w, h), (-w, h), (-w, -h)])]
    if geom.get("kind") == "circle":
        a = np.linspace(0.0, 2.0 * np.pi, 49)
        return [float(geom["radius"]) * np.column_stack([np.cos(a), np.sin(a)])]
    return []


def placed(q: np.ndarray, local: list[list[np.ndarray]]) -> list[np.ndarray]:
    """Every body's polylines at pose q (global frame), in one list."""
    out = []
    for b, lines in enumerate(local):
        c, s = np.cos(q[3 * b + 2]), np.sin(q[3 * b + 2])
        out += [q[3 * b:3 * b + 2] + p @ np.array([[c, s], [-s, c]]) for p in lines]
    return out


def _draw(ax, lines: list[np.ndarray], style: dict) -> None:
    for p in lines:
        ax.plot(p[:, 0], p[:, 1], **style)


def display_amplitude(model, q: np.ndarray, shape: np.ndarray, local) -> float:
    """a such that the largest point displacement of q + a shape (to first order) is AMPLITUDE x size."""
    eps = 1e-6
    moved = placed(q + eps * shape, local)
    base = placed(q, local)
    d = max(float(np.max(np.hypot(*(m - b).T))) for m, b in zip(moved, base)) / eps
    return AMPLITUDE * model.size / d if d > 0 else 0.0


def mode_title(m) -> str:
    if m.kind == "oscillating":
        zeta = m.damping_ratio
        return f"mode {m.index}: {m.frequency:.4g} Hz, ζ = " + ("0" if abs(zeta) < 1e-9 else f"{zeta:.3g}")
    return f"mode {m.index}: {m.kind}, |λ| = {m.omega:.3g} 1/s"


def figure(modes, count: int = 4, title: str | None = None):
    """A matplotlib Figure: one panel per mode (the first `count`)."""
    model, shown = modes.model, modes.modes()[:count]
    local = body_outlines(model)
    cols = max(1, min(len(shown), 2))
    rows = max(1, -(-len(shown) // cols))
    fig = mpl_figure.Figure(figsize=(5.0 * cols, 3.6 * rows), layout="constrained", dpi=110)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    base = placed(modes.q, local)
    for ax, m in zip(axes, shown):
        shape = np.real(m.shape)
        a = display_amplitude(model, modes.q, shape, local)
        _draw(ax, base, dict(color="0.6", lw=3, solid_capstyle="round"))
        _draw(ax, placed(modes.q + a * shape, local), dict(color="tab:blue", lw=1.8, marker="o", ms=3))
        ax.plot([0], [0], marker="^", color="k", ms=7, ls="none")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(mode_title(m), fontsize=10)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(alpha=0.3)
    for ax in axes[len(shown):]:
        ax.set_visible(False)
    fig.suptitle(title or f"{Path(model.source_path).name or 'model'}: mode shapes (grey: at rest; blue: "
                 f"displaced, a largest move of {AMPLITUDE:.0%} of the size)", fontsize=10)
    return fig


def save(fig, path: str | Path) -> Path:
    """The figure written beside `path` (its suffix gives the format) and moved over it whole."""
    path = Path(path)
    part = path.with_name(f".{path.name}.{secrets.token_hex(4)}.part")
    try:
        with open(part, "wb") as f:
            fig.savefig(f, format=path.suffix[1:] or "png")
        replace_atomically(part, path, durable=False)
    finally:
        if os.path.lexists(part):
            part.unlink()
    return path


def draw_modes(modes, path: str | Path, count: int = 4, title: str | None = None) -> Path:
    """Draw the first `count` mode shapes of a `run.modes.Modes` into `path` (png, svg, pdf)."""
    return save(figure(modes, count, title), path)
