"""Figures of a run or a sweep: time series, Poincaré maps, journal orbits, case grids.

The figures are drawn with matplotlib (imported inside the functions, on
``matplotlib.figure.Figure`` objects with the Agg canvas, so no GUI backend and no
global pyplot state): `series_figure`, `poincare_figure`, `orbit_figure`,
`sweep_grid_figure`, `poincare_grid_figure`, `bifurcation_figure`, and
`plot_file`, which the ``mbs plot`` command calls.  What they draw is read from the results
by `planar_mbs.results.views` (which signals exist, which body is the slider and which one
turns, Poincaré samples once per revolution, the clearance radius of a joint), which the
rerun recordings use too.

Poincaré sampling: `planar_mbs.results.section`, the one section of the project (the same
points as a sweep's stored verdict and `mbs analyze`): once per revolution of the
clock body (the body of the rotation driver, else the body that turns most),
crossings located by interpolation, the first ``skip`` crossings dropped.  For a
constant-speed driver this is exactly sampling at ``t = k T``, ``T = 2 pi / omega``.
"""
from __future__ import annotations

import json
import math
import os
import re
import secrets
import stat
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import did_you_mean
from ..files import replace_atomically
from ..lazy import lazy
from ..results.analysis import VERDICT_COLOURS, read_section
from ..results.hdf5 import HDF5_SIGNATURE, SIGNALS, open_results, read_results
from ..results.section import AnalysisError, crossings, default_signals, facts, output_body, slider_signals
from ..results.views import (
    PlotError,
    PoincareSet,
    check_signals,
    clearance_names,
    clearance_radius,
    driver_names,
    is_journal,
    poincare,
    slider_body,
    time_window,
    turning_body,
)

# figures only: `import planar_mbs.outputs.plot` (and `mbs plot --list`) loads no matplotlib
matplotlib = lazy("matplotlib")
mpl_figure = lazy("matplotlib.figure")
plt = lazy("matplotlib.pyplot")
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from ..results import spectrum
    from ..sweep import scan
else:  # each loaded on its first use (see the comments: not on the light paths)
    spectrum = lazy("..results.spectrum", __package__)  # scipy.signal: only for a spectrum figure
    scan = lazy("..sweep.scan", __package__)  # 0.1 s of sockets and threads: only the verdicts of a sweep's cases

if TYPE_CHECKING:  # pragma: no cover
    from ..mechanism.model import Model
    from ..results.hdf5 import Results

FORMATS = ("png", "svg", "pdf")
MAX_LINE_POINTS = 50_000  # longer series are reduced to a min/max envelope (peaks kept)


# the orbit is drawn through the output samples: when the journal turns more than this
# between two samples along the wall, the straight chords visibly cut into the clearance circle
# (a chord of 15 degrees dips 0.9 % of the clearance inside it)
ORBIT_MAX_TURN_DEG = 15.0


def orbit_resolution_warning(results: "Results", joint: str) -> str | None:
    """A warning when the output step is too coarse to draw the journal's orbit: along the
    bearing wall (e >= 0.98 c) the journal turns more than ORBIT_MAX_TURN_DEG between
    consecutive samples in more than 5 % of them."""
    ex, ey = np.asarray(results[f"{joint}.ex"]), np.asarray(results[f"{joint}.ey"])
    c = clearance_radius(results, joint)
    if len(ex) < 3 or not c > 0:
        return None
    near = np.hypot(ex, ey) >= 0.98 * c
    both = near[1:] & near[:-1]
    if both.sum() < 10:
        return None
    turn = np.degrees(np.abs(np.angle(np.exp(1j * np.diff(np.arctan2(ey, ex))))))[both]
    coarse = turn > ORBIT_MAX_TURN_DEG
    if coarse.mean() <= 0.05:
        return None
    dt = float(np.median(np.diff(results.time)))
    worst = float(np.percentile(turn, 95))
    finer = dt * ORBIT_MAX_TURN_DEG / worst
    return (f"the orbit of `{joint}` is drawn from output samples {dt:.3g} s apart, between which the journal "
            f"turns up to {worst:.0f}° along the bearing wall: straight chords cut across the clearance circle. "
            f"Rerun with a finer output step (e.g. --output-step {finer:.2g}s) to draw it faithfully")


def default_panels(results: "Results", model: "Model | None" = None) -> list[tuple[str, list[str]]]:
    """Muvengei et al.'s figures from the signals present: slider velocity, slider acceleration (along
    its axis: `slider_signals`), or without a slider the output link's angle and angular velocity
    (`output_body`), then clearance-joint forces, driver torques (or forces)."""
    panels: list[tuple[str, list[str]]] = []
    slider = slider_body(results, model)
    out = None if slider else output_body(results, model)
    if slider:
        v, a = slider_signals(results, model, slider)
        panels += [(f"{slider}_velocity", [v]), (f"{slider}_acceleration", [a])]
    elif out:
        panels += [(f"{out}_angle", [f"{out}.phi"]), (f"{out}_angular_velocity", [f"{out}.omega"])]
    panels = [(f, names) for f, names in panels if all(n in results for n in names)]
    forces = [f"{c}.contact_force" for c in clearance_names(results) if f"{c}.contact_force" in results]
    if forces:
        panels.append(("contact_force", forces))
    efforts = [f"{d}.torque" if f"{d}.torque" in results else f"{d}.force" for d in driver_names(results)]
    if efforts:
        panels.append(("driver_torque", efforts))
    return panels


_UNIT_PRETTY = {"m/s^2": "m/s²", "rad/s^2": "rad/s²", "N*m": "N·m", "kg*m^2": "kg·m²", "1": ""}


def pretty_unit(unit: str) -> str:
    return _UNIT_PRETTY.get(unit, unit.replace("*", "·").replace("^2", "²").replace("^3", "³"))


# what each quantity is, in words (a figure's y label: "slider velocity x (slider.vx) [m/s]")
QUANTITY_WORDS = {
    "x": "position x", "y": "position y", "phi": "angle", "vx": "velocity x", "vy": "velocity y",
    "omega": "angular velocity", "ax": "acceleration x", "ay": "acceleration y", "alpha": "angular acceleration",
    "fx": "force x", "fy": "force y", "force": "force", "moment": "moment", "torque": "torque", "power": "power",
    "contact_force": "contact force", "penetration": "penetration", "e": "eccentricity", "ex": "eccentricity x",
    "ey": "eccentricity y", "impact_velocity": "impact velocity", "in_contact": "in contact",
    "kinetic_energy": "kinetic energy", "potential_energy": "potential energy", "total_energy": "total energy",
    "position_error": "position error", "velocity_error": "velocity error",
}


def label(name: str, unit: str) -> str:
    u = pretty_unit(unit)
    return f"{name} [{u}]" if u else name


def axis_label(name: str, unit: str) -> str:
    """An axis label in words with its unit, on one line: ``slider velocity x [m/s]`` (the entity and
    its quantity in words; a quantity without words keeps the signal's name)."""
    entity, _, quantity = name.rpartition(".")
    words = QUANTITY_WORDS.get(quantity)
    return label(f"{entity} {words}" if words and entity else name, unit)


def words_label(name: str, unit: str) -> str:
    """A y label in words with the signal's name under it: ``slider velocity x`` / ``(slider.vx) [m/s]``
    (two lines, so that it fits beside a panel of a few inches)."""
    entity, _, quantity = name.rpartition(".")
    words = QUANTITY_WORDS.get(quantity)
    text = f"{entity} {words}\n({name})" if words and entity else name
    u = pretty_unit(unit)
    return f"{text} [{u}]" if u else text


def axis_values(results: "Results", name: str | None) -> tuple[np.ndarray, str]:
    """x values and label: time [s], or a signal; angles in degrees wrapped to [0, 360)
    with NaN breaks where they wrap, so successive revolutions overlay."""
    if name is None:
        return results.time, "time [s]"
    check_signals(results, [name])
    v = results[name]
    unit = results.units.get(name, "")
    if unit == "rad":
        deg = np.degrees(v)
        if np.ptp(deg) > 360:
            deg = np.mod(deg, 360.0)
            breaks = np.nonzero(np.abs(np.diff(deg)) > 180)[0] + 1
            deg = np.insert(deg.astype(float), breaks, np.nan)
            return deg, axis_label(name, "deg, mod 360")
        return deg, axis_label(name, "deg")
    return v, axis_label(name, unit)


def _with_breaks(x: np.ndarray, y: np.ndarray, n_time: int) -> np.ndarray:
    """Insert NaNs into y where `axis_values` inserted them into x."""
    if len(x) == n_time:
        return y
    nan_at = np.nonzero(np.isnan(x))[0]
    positions = nan_at - np.arange(len(nan_at))
    return np.insert(y.astype(float), positions, np.nan)


def envelope(x: np.ndarray, y: np.ndarray, max_points: int = MAX_LINE_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """Reduce a long monotone-x series to the min and max of each bucket (peaks survive)."""
    n = len(x)
    if n <= max_points or np.isnan(x).any():
        return x, y
    buckets = max_points // 2
    size = n // buckets
    m = buckets * size
    yb = y[:m].reshape(buckets, size)
    lo = yb.argmin(1) + np.arange(buckets) * size
    hi = yb.argmax(1) + np.arange(buckets) * size
    idx = np.sort(np.concatenate([lo, hi, np.arange(m, n)]))
    return x[idx], y[idx]


# --------------------------------------------------------------------------- figures


def _figure(width: float = 8.0, height: float = 4.0):
    return mpl_figure.Figure(figsize=(width, height), layout="constrained", dpi=110)


def _title(results: "Results", width: float = 8.0) -> str:
    """The run's title, short: the model file and the parameters that fit on one line of a figure
    `width` inches wide (a sweep case's own values first; "…" for those left out: the results file and
    `mbs plot --list` hold them all), then an incomplete run or a time window on a second line."""
    chars = int(width * 10)  # ~10 characters per inch at 10 pt
    params = results.attrs.get("parameters") or {}
    case = results.attrs.get("case_values") or {}
    values = {**(case if isinstance(case, dict) else {}), **(params if isinstance(params, dict) else {})}
    head = Path(str(results.attrs.get("model_path", "") or "")).name
    for i, (k, v) in enumerate(values.items()):
        piece = ("" if not head else " · " if i == 0 else ", ") + f"{k} = {v}"
        if len(head) + len(piece) > chars - 3:
            head += " …" if i == 0 else ", …"
            break
        head += piece
    state = []
    if not results.complete:
        state.append(f"incomplete: {results.attrs.get('message', '')}")
    if results.attrs.get("window"):
        t0, t1 = results.attrs["window"]
        state.append(f"t = {t0:.6g} … {t1:.6g} s")
    second = " · ".join(state)
    if len(second) > chars:
        second = second[:chars - 1] + "…"
    text = "\n".join(line for line in (head, second) if line)
    return text.replace("$", r"\$")  # a `$` in a file name or value is text, not mathtext


def wrap_pairs(bits: Sequence[str], width: int) -> str:
    """``bits`` joined with " · " (each bit's own "k = v, k = v" kept), in lines of at most `width`
    characters broken only between two pairs or two bits, never inside ``key = value``."""
    units: list[str] = []  # the pieces a line may end after
    for i, bit in enumerate(bits):
        pairs = bit.split(", ") if " = " in bit else [bit]
        for j, pair in enumerate(pairs):
            last = j == len(pairs) - 1
            units.append(pair + ("" if last and i == len(bits) - 1 else " ·" if last else ","))
    lines, line = [], ""
    for unit in units:
        if line and len(line) + 1 + len(unit) > width:
            lines.append(line)
            line = unit
        else:
            line = f"{line} {unit}" if line else unit
    lines.append(line)
    return "\n".join(lines)


LONG_RUN_REVOLUTIONS = 10  # a time plot of more revolutions marks the start-up and scales to what follows it


def startup_end(results: "Results", transient: int = 1, model: "Model | None" = None) -> float | None:
    """End of the start-up of a long run (more than `LONG_RUN_REVOLUTIONS` revolutions of the turning
    body): the time of its `transient`-th revolution; None for a short run or one that does not turn."""
    body = turning_body(results, model)
    if body is None or f"{body}.phi" not in results or transient < 1:
        return None
    times = crossings(results.time, results[f"{body}.phi"])
    return float(times[transient - 1]) if len(times) > LONG_RUN_REVOLUTIONS else None


def series_figure(results: "Results", panels: Sequence[Sequence[str]], against: str | None = None,
                  title: str | None = None, startup: float | None = None):
    """One subplot per panel (sharing x); the signals of a panel share its axes.  ``startup`` (s,
    time plots only): the start-up is shaded and each panel's y range fits what comes after it,
    so that one start-up impact does not flatten a long run into a band."""
    names = [n for p in panels for n in p]
    check_signals(results, names)
    x, xlabel = axis_values(results, against)
    fig = _figure(8.0, 1.0 + 2.3 * len(panels))
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    scatter = against is not None and results.units.get(against, "") != "rad"
    degrees = against is not None and results.units.get(against, "") == "rad"  # x in degrees: angles too
    shown_unit = lambda n: "deg" if degrees and results.units.get(n, "") == "rad" else results.units.get(n, "")  # noqa: E731
    for ax, panel in zip(axes, panels):
        units = {shown_unit(n) for n in panel}
        for name in panel:
            v = np.degrees(results[name]) if shown_unit(name) == "deg" else results[name]
            y = _with_breaks(x, v, len(results.time))
            if scatter:
                ax.plot(x, y, ".", ms=1.0, label=name)
            else:
                xs, ys = envelope(x, y)
                ax.plot(xs, ys, lw=0.7, label=name)
        if startup is not None and against is None:
            _mark_startup(ax, results, panel, startup)
        stuck = _mark_stick(ax, results, panel) if against is None else False
        if len(panel) == 1:
            ax.set_ylabel(words_label(panel[0], shown_unit(panel[0])))
        else:
            ax.set_ylabel(f"[{pretty_unit(units.pop())}]" if len(units) == 1 else "")
        if len(panel) > 1 or stuck:
            ax.legend(loc="upper right", fontsize="small")
        ax.grid(True, lw=0.3, alpha=0.6)
    axes[-1].set_xlabel(xlabel)
    fig.suptitle(title if title is not None else _title(results), fontsize="medium")
    return fig


STUCK = (0.17, 0.63, 0.17)  # as the rerun timeline draws a stuck contact's force


def _mark_stick(ax, results: "Results", panel: Sequence[str]) -> bool:
    """Shade the samples at which the friction of an element the panel shows sticks (its ``stick``
    signal), one shade per element, from each stuck sample to the next sample; True if any."""
    t = np.asarray(results.time, float)
    shaded = False
    for element in dict.fromkeys(n.rsplit(".", 1)[0] for n in panel):
        if f"{element}.stick" not in results:
            continue
        stuck = np.asarray(results[f"{element}.stick"]) > 0.5
        if stuck.any():
            through_next = stuck.copy()
            through_next[1:] |= stuck[:-1]
            ax.fill_between(t, 0, 1, where=through_next, step="post", transform=ax.get_xaxis_transform(),
                            color=STUCK, alpha=0.18, lw=0, zorder=0, label=f"{element} stuck")
            shaded = True
    return shaded


def _mark_startup(ax, results: "Results", panel: Sequence[str], startup: float) -> None:
    """Shade the start-up and fit the y range to the samples after it (5 % margin)."""
    after = np.asarray(results.time) > startup
    values = np.concatenate([np.asarray(results[n], float)[after] for n in panel])
    values = values[np.isfinite(values)]
    ax.axvspan(float(results.time[0]), startup, color="0.85", lw=0, zorder=0, label="start-up")
    ax.text(startup, 0.98, " ← start-up (its peaks off scale)", transform=ax.get_xaxis_transform(), ha="left",
            va="top", fontsize="x-small", color="0.35")
    if len(values) and np.ptp(values) > 0:
        pad = 0.05 * np.ptp(values)
        ax.set_ylim(values.min() - pad, values.max() + pad)


def poincare_figure(results: "Results", x: str, y: str, body: str | None = None, skip: int = 1,
                    model: "Model | None" = None, ax=None, window: tuple[float, float] | None = None):
    """Poincaré map of a run; with `window` (t0, t1) only the points in it (the section is still
    counted in revolutions from the start of the run)."""
    ps = poincare(results, x, y, body, skip, model)
    if window is not None:
        keep = (ps.t >= window[0]) & (ps.t <= window[1])
        ps = PoincareSet(ps.x[keep], ps.y[keep], ps.t[keep], ps.x_name, ps.y_name, ps.body, ps.skip)
        results = time_window(results, *window)
    fig = None
    if ax is None:
        fig = _figure(5.5, 5.0)
        ax = fig.subplots()
        fig.suptitle(_title(results, 5.5), fontsize="medium")
    ax.plot(ps.x, ps.y, "o", ms=2.5, color="C3")
    ax.set_xlabel(axis_label(x, results.units.get(x, "")))
    ax.set_ylabel(axis_label(y, results.units.get(y, "")))
    ax.set_title(f"Poincaré map: {len(ps.t)} points, once per revolution\nof {ps.body} (first {skip} skipped)",
                 fontsize="small")
    ax.grid(True, lw=0.3, alpha=0.6)
    return fig if fig is not None else ax


def orbit_figure(results: "Results", joint: str):
    """The journal centre's path (ex, ey) inside the clearance circle, in mm."""
    check_signals(results, [f"{joint}.ex", f"{joint}.ey"])
    c = clearance_radius(results, joint)
    fig = _figure(5.5, 5.5)
    ax = fig.subplots()
    ex, ey = results[f"{joint}.ex"] * 1e3, results[f"{joint}.ey"] * 1e3
    ax.plot(ex, ey, lw=0.5, color="C0", label="journal centre")
    ax.plot(ex[:1], ey[:1], "o", ms=4, color="C2", label="start")
    th = np.linspace(0, 2 * np.pi, 361)
    ax.plot(c * 1e3 * np.cos(th), c * 1e3 * np.sin(th), "--", color="k", lw=1.0, label=f"clearance c = {c * 1e3:g} mm")
    lim = 1.2 * max(c * 1e3, float(np.max(np.hypot(ex, ey), initial=0.0)))
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal")
    ax.set_xlabel(axis_label(f"{joint}.ex", "mm"))
    ax.set_ylabel(axis_label(f"{joint}.ey", "mm"))
    ax.set_title(f"journal orbit in clearance joint {joint}", fontsize="small")
    ax.legend(loc="upper right", fontsize="x-small")
    ax.grid(True, lw=0.3, alpha=0.6)
    if orbit_resolution_warning(results, joint):
        ax.text(0.5, 0.01, "coarse output step: chords cut the circle", transform=ax.transAxes, ha="center",
                va="bottom", fontsize="x-small", color="C3")
    fig.suptitle(_title(results, 5.5), fontsize="medium")
    return fig


# ----- sweeps


def is_sweep(path: str | Path) -> bool:
    with open_results(path) as f:
        return "cases" in f and SIGNALS not in f


def sweep_cases(path: str | Path) -> list[tuple[str, "Results"]]:
    """``(case key, Results)`` of every ``/cases/<k>`` group, in numeric order."""
    with open_results(path) as f:
        keys = sorted(f["cases"].keys(), key=lambda k: (not k.isdigit(), int(k) if k.isdigit() else 0, k))
        if keys and all("signals" not in f["cases"][k] for k in keys):
            raise PlotError(f"error: the cases of {path} hold no signals (a sweep stores sections, verdicts and "
                            "statistics unless --keep)\nhint: sweep again with `--keep slider,crank` (or "
                            "`--keep all`), or `mbs sweep replay SWEEP.h5 CASE -o case.h5` for one case")
    return [(k, read_results(f"{path}:/cases/{k}")) for k in keys]


def varying_parameters(cases: Sequence[tuple[str, "Results"]]) -> list[str]:
    """Parameter names whose value differs between cases."""
    values: dict[str, set[str]] = {}
    for _, res in cases:
        params = res.attrs.get("parameters") or {}
        if isinstance(params, str):
            params = json.loads(params) if params else {}
        for k, v in params.items():
            values.setdefault(k, set()).add(str(v))
    return [k for k, v in values.items() if len(v) > 1]


def case_label(res: "Results", keys: Sequence[str], fallback: str) -> str:
    params = res.attrs.get("parameters") or {}
    return ", ".join(f"{k} = {params.get(k)}" for k in keys) if keys else f"case {fallback}"


_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*)$")


def parameter_value(text) -> tuple[float, str] | None:
    """``"2500 rpm"`` -> ``(2500.0, "rpm")``; None when the value is not a plain number."""
    m = _NUMBER.match(str(text))
    return (float(m.group(1)), m.group(2).strip()) if m else None


SUBPLOT_CHARS = 44  # characters of a title line that fit a 4-inch subplot at the "small" font size


def _grid(n: int):
    ncols = min(n, 2 if n <= 4 else math.ceil(math.sqrt(n)))
    return math.ceil(n / ncols), ncols


def spectrum_figure(results: "Results", spec):
    """A `planar_mbs.results.spectrum.Spectrum`: amplitude against frequency or order (linear), a PSD on
    a log scale; its method, window and resolution under the run's title, its highest peaks marked."""
    fig = _figure(8.0, 4.0)
    ax = fig.subplots()
    x, y = np.asarray(spec.x), np.asarray(spec.y)
    if spec.kind == "psd":
        ax.semilogy(x[1:], y[1:], lw=0.8)  # DC: ~0 after the mean is removed
    else:
        ax.plot(x, y, lw=0.8)
        seen = np.nonzero(y > 1e-3 * y.max())[0] if len(y) and y.max() > 0 else []
        if len(seen):  # up to half as far again as the last visible component
            ax.set_xlim(0, min(x[-1], max(1.5 * x[seen[-1]], 10 * spec.resolution)))
    for px, py in spec.peaks(5):
        ax.plot(px, py, "v", ms=4, color="C3")
        ax.annotate(f"{px:.3g}", (px, py), textcoords="offset points", xytext=(3, 3), fontsize="x-small")
    ax.set_xlabel("order (cycles per revolution of " + str(spec.meta.get("clock")) + ")" if spec.kind == "order"
                  else "frequency [Hz]")
    what = {"amplitude": "amplitude", "psd": "PSD", "order": "order amplitude"}[spec.kind]
    ax.set_ylabel(f"{spec.signal} {what} [{pretty_unit(spec.y_unit)}]")
    ax.grid(True, lw=0.3, alpha=0.6)
    res = f"{spec.resolution:.3g} " + ("orders" if spec.kind == "order" else "Hz")
    ax.set_title(_title(results) + f"\n{spec.kind}: {spec.window} window, resolution {res}, "
                 f"t = {spec.t_from:.4g} … {spec.t_to:.4g} s", fontsize="small")
    return fig


def sweep_spectrum_figure(cases, name: str, options: dict):
    """One subplot per case: the spectrum of ``name`` (`spectrum.spectrum` with ``options``), its peaks marked."""
    keys = varying_parameters(cases)
    nrows, ncols = _grid(len(cases))
    fig = _figure(4.0 * ncols, 0.8 + 2.6 * nrows)
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    spec = None
    for ax, (k, res) in zip(axes, cases):
        opts = dict(options)
        spec = spectrum.spectrum(res, name, opts.pop("kind"), **opts)
        x, y = np.asarray(spec.x), np.asarray(spec.y)
        (ax.semilogy(x[1:], y[1:], lw=0.7) if spec.kind == "psd" else ax.plot(x, y, lw=0.7))
        seen = np.nonzero(y > 1e-3 * y.max())[0] if spec.kind != "psd" and len(y) and y.max() > 0 else []
        if len(seen):
            ax.set_xlim(0, min(x[-1], max(1.5 * x[seen[-1]], 10 * spec.resolution)))
        for px, py in spec.peaks(3):
            ax.plot(px, py, "v", ms=3, color="C3")
            ax.annotate(f"{px:.3g}", (px, py), textcoords="offset points", xytext=(3, 2), fontsize="x-small")
        res_text = f"{spec.resolution:.3g} " + ("orders" if spec.kind == "order" else "Hz")
        ax.set_title(wrap_pairs([case_label(res, keys, k), f"resolution {res_text}"], SUBPLOT_CHARS),
                     fontsize="small")
        ax.set_xlabel("order" if spec.kind == "order" else "frequency [Hz]", fontsize="small")
        ax.set_ylabel(f"{spec.signal} [{pretty_unit(spec.y_unit)}]", fontsize="small")
        ax.grid(True, lw=0.3, alpha=0.6)
    for ax in axes[len(cases):]:
        ax.set_visible(False)
    what = {"amplitude": "amplitude spectrum", "psd": "PSD", "order": "order spectrum"}[spec.kind]
    fig.suptitle(f"{name}: {what} per case ({spec.window} window)", fontsize="medium")
    return fig, spec.kind


def sweep_grid_figure(cases, name: str, against: str | None = None):
    """One subplot per case of one signal (Muvengei et al.'s Figs. 9-11)."""
    keys = varying_parameters(cases)
    nrows, ncols = _grid(len(cases))
    fig = _figure(4.0 * ncols, 0.6 + 2.6 * nrows)
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax, (k, res) in zip(axes, cases):
        check_signals(res, [name])
        x, xlabel = axis_values(res, against)
        xs, ys = envelope(x, _with_breaks(x, res[name], len(res.time)))
        ax.plot(xs, ys, lw=0.6)
        ax.set_title(wrap_pairs([case_label(res, keys, k)], SUBPLOT_CHARS), fontsize="small")
        ax.set_xlabel(xlabel, fontsize="small")
        ax.set_ylabel(axis_label(name, res.units.get(name, "")), fontsize="small")
        ax.grid(True, lw=0.3, alpha=0.6)
    for ax in axes[len(cases):]:
        ax.set_visible(False)
    fig.suptitle(f"{name} per case", fontsize="medium")
    return fig


def poincare_grid_figure(cases, x: str, y: str, body: str | None = None, skip: int = 1):
    keys = varying_parameters(cases)
    nrows, ncols = _grid(len(cases))
    fig = _figure(4.0 * ncols, 0.6 + 3.4 * nrows)
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax, (k, res) in zip(axes, cases):
        ps = poincare(res, x, y, body, skip)
        ax.plot(ps.x, ps.y, "o", ms=2.5, color="C3")
        ax.set_title(wrap_pairs([case_label(res, keys, k), f"{len(ps.t)} points"], SUBPLOT_CHARS), fontsize="small")
        ax.set_xlabel(axis_label(x, res.units.get(x, "")), fontsize="small")
        ax.set_ylabel(axis_label(y, res.units.get(y, "")), fontsize="small")
        ax.grid(True, lw=0.3, alpha=0.6)
    for ax in axes[len(cases):]:
        ax.set_visible(False)
    fig.suptitle(f"Poincaré maps per case (once per revolution, first {skip} skipped)", fontsize="medium")
    return fig


def bifurcation_figure(cases, name: str, body: str | None = None, skip: int = 1):
    """Poincaré samples of `name` against the one swept parameter (None if the sweep
    does not vary exactly one numeric parameter)."""
    keys = varying_parameters(cases)
    if len(keys) != 1:
        return None
    key = keys[0]
    values = [parameter_value((res.attrs.get("parameters") or {}).get(key)) for _, res in cases]
    if any(v is None for v in values):
        return None
    fig = _figure(7.0, 4.5)
    ax = fig.subplots()
    for (k, res), (p, _) in zip(cases, values):
        ps = poincare(res, name, name, body, skip)
        ax.plot(np.full(len(ps.x), p), ps.x, "o", ms=1.5, color="k")
    unit = values[0][1]
    ax.set_xlabel(f"{key} [{unit}]" if unit else key)
    ax.set_ylabel(axis_label(name, cases[0][1].units.get(name, "")))
    ax.set_title(f"bifurcation diagram: {name} once per revolution (first {skip} skipped)", fontsize="small")
    ax.grid(True, lw=0.3, alpha=0.6)
    return fig


# --------------------------------------------------------------------------- the `mbs plot` driver


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_")[:80] or "figure"


class Written(list):
    """The figure files written, and the `style` every figure is given before it is saved."""

    def __init__(self, style: dict | None = None):
        super().__init__()
        self.style = check_style(style)


STYLE_KEYS = ("title", "xlabel", "ylabel", "size")


def check_style(style: dict | None) -> dict:
    """The figure options of `mbs plot` (``--title``, ``--xlabel``, ``--ylabel``, ``--size W,H`` in
    inches), checked: unknown keys and sizes that are not two positive numbers are a `PlotError`."""
    style = {k: v for k, v in (style or {}).items() if v is not None}
    unknown = set(style) - set(STYLE_KEYS)
    if unknown:
        raise PlotError(f"error: unknown figure option {', '.join(sorted(unknown))}\nhint: "
                        f"the figure options are {', '.join(STYLE_KEYS)}")
    if "size" in style:
        size = style["size"]
        if isinstance(size, str):
            parts = re.split(r"\s*[x,×]\s*", size.strip().lower().removesuffix("in").strip())
            try:
                size = tuple(float(p) for p in parts)
            except ValueError:
                size = ()
        if len(size) != 2 or not all(math.isfinite(v) and 0.5 <= v <= 100 for v in size):
            raise PlotError(f"error: `--size {style['size']}` is not a figure size\nhint: width and height in "
                            "inches, each from 0.5 to 100, e.g. `--size 8x4`")
        style["size"] = (float(size[0]), float(size[1]))
    return style


def restyle(fig, style: dict) -> None:
    """Give a figure the asked title (the figure's title, else its one axes' title), axis labels (the
    x label of the bottom axes, the y label of every axes) and size."""
    axes = [ax for ax in fig.axes if ax.get_visible()]
    if "title" in style:
        text = str(style["title"]).replace("$", r"\$")
        if fig._suptitle is not None or len(axes) != 1:
            fig.suptitle(text, fontsize="medium")
        else:
            axes[0].set_title(text, fontsize="medium")
    if "xlabel" in style and axes:
        bottom = min(ax.get_position().y0 for ax in axes)
        for ax in axes:
            if ax.get_position().y0 <= bottom + 1e-9 or len(axes) == 1:
                ax.set_xlabel(style["xlabel"])
    for ax in axes if "ylabel" in style else ():
        ax.set_ylabel(style["ylabel"])
    if "size" in style:
        fig.set_size_inches(*style["size"])


def _save(fig, path: Path, written: list[Path]) -> None:
    """Save a figure (given the style of `written` when it is a `Written`); never over a folder, a
    FIFO or device, or a file that holds HDF5 data.  The figure is written beside `path` and moved
    over it once whole, so a full disk or a kill leaves the previous figure (or none), never half a
    file in its place."""
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.part")
    restyle(fig, getattr(written, "style", {}))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if os.path.lexists(path):
            if not stat.S_ISREG(os.stat(path).st_mode):
                raise PlotError(f"error: {path} exists and is not a regular file; not writing a figure there")
            with open(path, "rb") as f:
                if f.read(len(HDF5_SIGNATURE)) == HDF5_SIGNATURE:
                    raise PlotError(f"error: {path} holds HDF5 data; not writing a figure over it\n"
                                    "hint: choose another --output folder")
        with open(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666), "wb") as f:  # mode as umask says
            fig.savefig(f, format=path.suffix[1:])
        replace_atomically(tmp, path, durable=False)  # a figure is drawn again in a moment
    except OSError as exc:
        raise PlotError(f"error: cannot write {path}: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)
        tmp.unlink(missing_ok=True)
    written.append(path)


def parse_panels(signals: Sequence[str]) -> list[list[str]]:
    """Each argument is a panel; ``A.fx,A.fy`` puts several signals on one panel."""
    return [[s.strip() for s in arg.split(",") if s.strip()] for arg in signals if arg.strip()]


def parse_pair(text: str, option: str = "--poincare") -> tuple[str, str]:
    x, sep, y = text.partition(":")
    if not sep or not x.strip() or not y.strip():
        raise PlotError(f"error: `{option} {text}` is not X:Y\nhint: write e.g. `{option} slider.vx:slider.ax`")
    return x.strip(), y.strip()


def plot_file(
    path: str | Path,
    signals: Sequence[str] = (),
    against: str | None = None,
    poincare_pair: str | None = None,
    outdir: str | Path | None = None,
    fmt: str = "png",
    skip: int = 1,
    body: str | None = None,
    orbit: Sequence[str] = (),
    model: "Model | None" = None,
    t_from: float | None = None,
    t_to: float | None = None,
    notes: list[str] | None = None,
    spectra: Sequence[str] = (),
    spectrum_options: dict | None = None,
    style: dict | None = None,
) -> list[Path]:
    """Draw the figures `mbs plot` makes and return the files written.  ``style``: the title, axis
    labels and size every figure is given (`check_style`).

    With no `signals`, `poincare_pair` or `orbit`, draw the default set (see
    `default_panels`, plus each clearance joint's orbit and the slider's
    velocity-acceleration Poincaré map).  A sweep file (``/cases/<k>``) gives one grid
    per signal, a grid of Poincaré maps and a bifurcation diagram.
    """
    path = Path(path)
    if fmt not in FORMATS:
        raise PlotError(f"error: unknown format `{fmt}`\nhint: choose one of {', '.join(FORMATS)}")
    if not path.exists():
        raise PlotError(f"error: no such file: {path}")
    try:
        sweep = is_sweep(path)
    except OSError as exc:
        raise PlotError(f"error: {path} is not an HDF5 results file ({exc})") from None
    outdir = Path(outdir) if outdir is not None else path.parent / f"{path.stem}_plots"
    stem = path.stem
    if sweep and spectra:  # a grid of each case's spectrum
        written = Written(style)
        for name in spectra:
            opts = {"kind": "amplitude", **(spectrum_options or {}), "t_from": t_from, "t_to": t_to}
            fig, kind = sweep_spectrum_figure(sweep_cases(path), name, opts)
            _save(fig, outdir / f"{stem}_{kind}_grid_{_slug(name)}.{fmt}", written)
        return written
    if sweep:
        panels = parse_panels(signals)
        pair = parse_pair(poincare_pair) if poincare_pair else None
        return _plot_sweep(path, panels, against, pair, outdir, fmt, skip, body, Written(style), notes)
    try:
        results = read_results(path)
    except (KeyError, OSError) as exc:
        raise PlotError(f"error: {path} is not a results file written by `mbs run` ({exc})") from None
    return plot_results(results, stem, signals, against, poincare_pair, outdir, fmt, skip, body, orbit, model,
                        t_from, t_to, notes, spectra, spectrum_options, style)


def plot_results(
    results: "Results",
    stem: str,
    signals: Sequence[str] = (),
    against: str | None = None,
    poincare_pair: str | None = None,
    outdir: str | Path = ".",
    fmt: str = "png",
    skip: int = 1,
    body: str | None = None,
    orbit: Sequence[str] = (),
    model: "Model | None" = None,
    t_from: float | None = None,
    t_to: float | None = None,
    notes: list[str] | None = None,
    spectra: Sequence[str] = (),
    spectrum_options: dict | None = None,
    style: dict | None = None,
) -> list[Path]:
    """The figures of one run (already loaded); file names start with `stem`; ``style`` as `plot_file`.
    ``t_from`` / ``t_to`` (s) cut every figure to a time window; warnings (a too-coarse orbit) go to
    `notes`.  ``spectra``: a spectrum figure of each signal named (`spectrum_figure`; ``spectrum_options`` as
    `planar_mbs.results.spectrum.spectrum` takes them, over the same window)."""
    if fmt not in FORMATS:
        raise PlotError(f"error: unknown format `{fmt}`\nhint: choose one of {', '.join(FORMATS)}")
    outdir = Path(outdir)
    panels = parse_panels(signals)
    pair = parse_pair(poincare_pair) if poincare_pair else None
    written = Written(style)
    if len(results.time) == 0:
        raise PlotError("error: the results hold no samples")
    full = results
    results = time_window(results, t_from, t_to)
    window = results.attrs.get("window") if results is not full else None
    if against:
        check_signals(results, [against])
    defaults = not panels and pair is None and not orbit and not spectra
    for name in spectra:
        opts = {"kind": "amplitude", **(spectrum_options or {}), "t_from": t_from, "t_to": t_to}
        spec = spectrum.spectrum(full, name, opts.pop("kind"), **opts)
        _save(spectrum_figure(full, spec), outdir / f"{stem}_{spec.kind}_{_slug(name)}.{fmt}", written)
    if defaults:
        startup = startup_end(results, skip, model) if window is None else None  # a long run, no window asked
        for fname, names in default_panels(results, model):
            _save(series_figure(results, [names], against, startup=startup),
                  outdir / f"{stem}_{_slug(fname)}.{fmt}", written)
        if startup is not None and notes is not None:
            notes.append(f"a long run: the start-up (to t = {startup:.3g} s, shaded) is off the y scale of the "
                         "time plots; `--from`/`--to` draws a window")
        orbit = [c for c in clearance_names(results) if is_journal(model, c, results)]
        pair = _default_pair(full, model, body, skip, notes)
    if panels:
        check_signals(results, [n for p in panels for n in p])
        name = "_".join("+".join(p) for p in panels) + (f"_vs_{against}" if against else "")
        _save(series_figure(results, panels, against), outdir / f"{stem}_{_slug(name)}.{fmt}", written)
    if pair:
        fig = poincare_figure(full, pair[0], pair[1], body, skip, model, window=window)
        _save(fig, outdir / f"{stem}_poincare_{_slug(pair[0] + '_' + pair[1])}.{fmt}", written)
    for joint in orbit:
        if joint not in clearance_names(results):
            hint = did_you_mean(joint, clearance_names(results))
            raise PlotError(f"error: `{joint}` is not a clearance joint of this run"
                            + (f"\nhint: {hint}" if hint else f"\nhint: clearance joints: "
                               f"{', '.join(clearance_names(results)) or 'none'}"))
        if not is_journal(model, joint, results):
            pair = (facts(results, model) or {}).get("contacts", {}).get(joint, "contact")
            raise PlotError(f"error: `{joint}` is a {pair} contact, not a journal in a bearing: it has no orbit "
                            f"inside a clearance circle\nhint: draw its signals instead, e.g. "
                            f"`mbs plot FILE {joint}.e {joint}.penetration`")
        _save(orbit_figure(results, joint), outdir / f"{stem}_orbit_{_slug(joint)}.{fmt}", written)
        warning = orbit_resolution_warning(results, joint)
        if warning and notes is not None:
            notes.append(warning)
    return written


def _default_pair(results: "Results", model, body, skip, notes) -> tuple[str, str] | None:
    """The default Poincaré map's signals (`default_signals`: the slider along its axis, else the output
    link), None with a note saying why when there is none or the run gives it no point."""
    try:
        plane = default_signals(results, model)
    except AnalysisError as err:
        if notes is not None:
            notes.append(f"no Poincaré map: {err}")
        return None
    if not (body or turning_body(results, model)):
        return None
    return plane if len(poincare(results, *plane, body, skip, model).t) else None


def _plot_sweep(path, panels, against, pair, outdir, fmt, skip, body, written, notes=None):
    """The figures of a sweep file: a grid per signal kept and the Poincaré maps from the kept signals
    when asked (or when they hold the clock); with no signal named, the sections the sweep stored,
    drawn as a bifurcation diagram (`stored_bifurcation_figures`), which need no `--keep`."""
    stem = path.stem
    defaults = not panels and pair is None
    if defaults and not _cases_keep_signals(path):
        figures = stored_bifurcation_figures(path)
        if not figures:
            raise PlotError(f"error: the cases of {path} hold no signals and no Poincaré sections to draw\n"
                            "hint: sweep with a section (without --no-section; `-p X:Y` names its signals) or "
                            "keep signals (`--keep slider,crank`, `--keep all`)")
        for name, fig in figures:
            _save(fig, outdir / f"{stem}_bifurcation_{_slug(name)}.{fmt}", written)
        return written
    cases = sweep_cases(path)
    if not cases:
        raise PlotError(f"error: {path} holds no cases")
    first = cases[0][1]
    if defaults:
        panels = [names[:1] for _, names in default_panels(first)]
        clock = body or turning_body(first)  # its angle not kept: the stored sections below instead
        pair = _default_pair(first, None, body, skip, None) if clock and f"{clock}.phi" in first else None
        if clock and f"{clock}.phi" not in first and notes is not None:
            kept = sorted({n.rpartition(".")[0] for n in first.signals})
            notes.append(f"the cases keep no angle of `{clock}`, which clocks the Poincaré section: its stored "
                         f"sections are drawn instead of maps of the kept signals (`--keep {','.join(kept + [clock])}` "
                         "keeps it)")
    for panel in panels:
        for name in panel:
            for _, res in cases:
                check_signals(res, [name] + ([against] if against else []))
            _save(sweep_grid_figure(cases, name, against), outdir / f"{stem}_grid_{_slug(name)}.{fmt}", written)
    if pair:
        _save(poincare_grid_figure(cases, pair[0], pair[1], body, skip),
              outdir / f"{stem}_poincare_grid_{_slug(pair[0] + '_' + pair[1])}.{fmt}", written)
        fig = bifurcation_figure(cases, pair[0], body, skip)
        if fig is not None:
            _save(fig, outdir / f"{stem}_bifurcation_{_slug(pair[0])}.{fmt}", written)
    elif defaults:
        for name, fig in stored_bifurcation_figures(path):
            _save(fig, outdir / f"{stem}_bifurcation_{_slug(name)}.{fmt}", written)
    if not written:
        raise PlotError(f"error: nothing to draw from the cases of {path}: no signal kept makes a default figure "
                        "and the cases store no Poincaré section\nhint: name signals the cases keep "
                        f"(`mbs plot --list {path}`), or sweep again with `--keep slider,crank`")
    return written


def _cases_keep_signals(path) -> bool:
    with open_results(path) as f:
        cases = f.get("cases")
        return cases is not None and any("signals" in cases[k] for k in cases)


def _section_unit(group, name: str) -> str:
    """The unit of section signal `name` from a case's summary statistics (every signal's unit)."""
    g = group.get("summary")
    if g is None or "name" not in g or "unit" not in g:
        return ""
    text = lambda v: v.decode() if isinstance(v, bytes) else str(v)  # noqa: E731
    units = dict(zip((text(n) for n in g["name"][()]), (text(u) for u in g["unit"][()])))
    return units.get(name, "")


def stored_bifurcation_figures(sweep_path) -> list[tuple[str, object]]:
    """``(signal, figure)``: each signal of the stored sections against each numeric parameter the
    sweep varies (`verdict_bifurcation_figure`); [] when the cases store no section."""
    rows = scan.read_case_table(sweep_path)
    params = [k for k in (rows[0]["values"] if rows else {})
              if len({r["values"].get(k) for r in rows}) > 1
              and all(scan.parameter_number(r["values"].get(k, "")) is not None for r in rows)]
    names: list[str] = []
    with open_results(sweep_path) as f:
        for row in rows:
            g = f.get(f"cases/{row['index']}")
            if g is not None and "poincare" in g:
                names = read_section(g)[0].names
                break
    out = []
    for param in params[:2]:
        others = [k for k in params if k != param]
        title = f"all values of {', '.join(others)}" if others else ""
        out += [(name if len(params) == 1 else f"{name}_vs_{param}",
                 verdict_bifurcation_figure(sweep_path, param, name, title=title)) for name in names]
    return out


def verdict_bifurcation_figure(sweep_path, param: str, signal: str | None = None, *, scale: float = 1.0,
                       unit: str = "", title: str = "", ax=None, where: dict | None = None):
    """Poincaré samples of ``signal`` (default: the first section signal) against the swept
    parameter ``param``, from the ``poincare`` groups of a sweep file; points coloured by the
    verdict of their case (the stored sections: the points `mbs plot` draws for the same file).  ``where`` keeps only cases whose other parameters have these
    values (text, as in the case table).  ``scale`` multiplies the parameter (e.g. to rpm)."""
    matplotlib.use("Agg")
    table = scan.read_case_table(sweep_path)
    # plot numbers in the unit the values were given in when they share one, else in SI
    parsed = [scan.parameter_number(r["values"].get(param, "")) for r in table]
    units = {p[1] for p in parsed if p is not None}
    same_unit = len(units) == 1 and None not in parsed
    if same_unit and not unit:
        unit = units.pop()
    fig = None
    if ax is None:
        fig, ax = plt.subplots(figsize=(8, 4))
    seen, y_unit, name = set(), "", signal
    with open_results(sweep_path) as f:
        for row in table:
            if where and any(row["values"].get(k) != v for k, v in where.items()):
                continue
            g = f.get(f"cases/{row['index']}")
            if g is None or "poincare" not in g:
                continue
            sec, verdict = read_section(g)
            name = signal or sec.names[0]
            y_unit = y_unit or _section_unit(g, name)
            text = row["values"][param]
            p = (scan.parameter_number(text)[0] if same_unit else scan.parameter_si(text)) * scale
            v = verdict.verdict if verdict else "undetermined"
            ax.plot(np.full(len(sec), p), sec.points[name], ".", ms=2, color=VERDICT_COLOURS[v],
                    label=v if v not in seen else None)
            seen.add(v)
    ax.set_xlabel(f"{param}" + (f" [{pretty_unit(unit)}]" if unit else ""))
    words = axis_label(name, "") + " at the Poincaré section" if name else "the Poincaré section"
    ax.set_ylabel(f"{words} [{pretty_unit(y_unit)}]" if y_unit and pretty_unit(y_unit) else words)
    if title:
        ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8, markerscale=4)
    return fig or ax.figure
