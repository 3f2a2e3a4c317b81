"""Regenerate every figure and every generated table of docs/replication.md.

    .venv/bin/python docs/scripts/replicate.py            # runs what is missing, then draws and fills the page
    .venv/bin/python docs/scripts/replicate.py --draw     # only draw and fill, from the runs in --work
    .venv/bin/python docs/scripts/replicate.py --full     # also the tighter-tolerance runs of 1200 and 800 rpm,
                                                          # of 207 MPa, and the 207 MPa bifurcation scans
    .venv/bin/python docs/scripts/replicate.py --short    # only the short sweeps: Figs. 5-11 and 13-15, the
                                                          # peaks and laws tables (minutes; no long run)

The claims of Muvengei, Kihiu and Ikua, "Effects of input speed on the dynamic response of
planar multi-body systems with differently located frictionless revolute clearance joints",
are checked on long runs (docs/scripts/replication_runs.py: 1000 crank revolutions each,
cached in ``--work``, default build/replication/): the verdict on the settled part of the
run, the settling revolution, Benettin's Lyapunov exponent from 5 perturbed states, and the
verdict at a tighter tolerance.  The figures of revolutions 2–5 come from short, finely
sampled sweeps (`planar_mbs.sweep.scan.run_sweep`).  Figures go to docs/images/replication_*.png;
the tables between ``<!-- BEGIN generated:... -->`` / ``<!-- END generated:... -->`` markers of
docs/replication.md are rewritten; the numbers to docs/replication_data.json.
"""
from __future__ import annotations

import argparse
import json
import math
import re
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "docs" / "scripts"))

import replication_runs as R  # noqa: E402
from planar_mbs import read_results  # noqa: E402
from planar_mbs.results.analysis import VERDICT_COLOURS, classify  # noqa: E402
from planar_mbs.results.hdf5 import Results  # noqa: E402
from planar_mbs.results.section import poincare_section  # noqa: E402
from planar_mbs.sweep.scan import Axis, read_case_table, run_sweep  # noqa: E402,F401

IMAGES = ROOT / "docs" / "images"
PAGE = ROOT / "docs" / "replication.md"
MODELS = R.MODELS
LAWS = ["hertz", "dubowsky_freudenstein", "esdu78035", "lankarani_nikravesh"]
ELASTIC = ["hertz", "dubowsky_freudenstein", "esdu78035"]  # Hertz first: the others are compared with it
LAW_TITLES = {"hertz": "Hertz", "dubowsky_freudenstein": "Dubowsky–Freudenstein", "esdu78035": "ESDU-78035",
              "lankarani_nikravesh": "Lankarani–Nikravesh"}
SPEEDS = ["800rpm", "1200rpm", "2500rpm", "5000rpm"]
MODULI = {"GPa": "207GPa", "MPa": "207MPa"}
REVOLUTIONS = 1000
BIF_SPEEDS = [f"{v}rpm" for v in range(500, 6001, 250)]
PER_REV_SERIES = 1440  # output samples per revolution of the runs whose time series are drawn
SHOWN = (1, 5)  # revolutions drawn: "four cycles after the first" (the paper, §III.A)
PAPER_CLAIMS = {  # §III.C
    "A": {"800rpm": "chaotic", "1200rpm": "quasi-periodic", "2500rpm": "quasi-periodic", "5000rpm": "periodic"},
    "B": {"800rpm": "periodic", "1200rpm": "quasi-periodic", "2500rpm": "quasi-periodic", "5000rpm": "chaotic"},
}
TIGHT = {"rtol": 1e-8, "atol": 1e-11}


def signal_of(joint: str) -> str:
    return f"{joint}.contact_force"


# ---------------------------------------------------------------- runs
def long_jobs(full: bool) -> tuple[list[tuple], list[tuple]]:
    """(long-run jobs, Lyapunov cases), most important first."""
    jobs, lyap = [], []
    for tag in ("GPa", "MPa"):
        for s in reversed(SPEEDS):
            for j in "AB":
                jobs.append(("long", j, MODULI[tag], s, REVOLUTIONS))
                lyap.append((j, MODULI[tag], s))
    for s in reversed(SPEEDS):
        for j in "AB":
            if full or s in ("5000rpm", "2500rpm"):
                jobs.append(("tight", j, "207GPa", s, REVOLUTIONS, TIGHT))
    for tag in ("GPa", "MPa") if full else ("GPa",):
        coarse = [s for s in BIF_SPEEDS if int(s[:-3]) % 500 == 0]  # every 500 rpm first, then the rest
        for s in coarse[::-1] + [s for s in BIF_SPEEDS if s not in coarse][::-1]:
            for j in "AB":
                jobs.append(("long", j, MODULI[tag], s, REVOLUTIONS))
    if full:
        for s in SPEEDS:
            for j in "AB":
                jobs.append(("tight", j, "207MPa", s, REVOLUTIONS, TIGHT))
    seen, out = set(), []
    for job in jobs:
        if R.job_name(*job[:4]) not in seen:
            seen.add(R.job_name(*job[:4]))
            out.append(job)
    return out, lyap


def short_sweeps(work: Path, jobs: int | None) -> dict:
    """The finely sampled 5-revolution sweeps behind the time-series figures and the peaks."""
    files = {"laws": {}, "speeds": {}}
    for joint, model in MODELS.items():
        keep = ["slider.vx", "slider.ax", "crank_speed.torque", signal_of(joint)]
        out = work / f"laws_{joint}.h5"
        run_sweep(model, [Axis("law", tuple(LAWS))], out, revolutions=SHOWN[1], per_rev=PER_REV_SERIES, keep=keep,
                  section=None, jobs=jobs)
        files["laws"][joint] = out
        for tag, modulus in MODULI.items():
            out = work / f"series_{joint}_{tag}.h5"
            run_sweep(model, [Axis("speed", tuple(SPEEDS))], out, sets={"youngs_modulus": modulus},
                      revolutions=SHOWN[1], per_rev=PER_REV_SERIES, keep=keep, section=None, jobs=jobs)
            files["speeds"][(joint, tag)] = out
    return files


# ---------------------------------------------------------------- reading the long runs
def load_run(work: Path, kind: str, joint: str, modulus: str, speed: str) -> tuple[Results, dict] | None:
    path = work / f"{R.job_name(kind, joint, modulus, speed)}.npz"
    if not path.exists():
        return None
    d = np.load(path)
    meta = json.loads(str(d["meta"]))
    sig = {k: d[k] for k in d.files if "." in k}
    t = d["time"]
    cont = path.with_name(path.stem + "_cont.npz")
    if cont.exists():  # a continuation from the saved final state (replication_runs.continue_run)
        c = np.load(cont)
        meta = json.loads(str(c["meta"]))
        keep = c["time"] > t[-1]
        t = np.concatenate([t, c["time"][keep]])
        sig = {k: np.concatenate([v, c[k][keep]]) for k, v in sig.items()}
    return Results(time=t, signals=sig, units={k: "" for k in sig}, attrs={}), meta


def continue_disagreeing(work: Path, jobs: list[tuple], more: int = REVOLUTIONS) -> None:
    """A case periodic after its transient at rtol 1e-6 whose tighter run is not periodic after its 1000
    revolutions is run on for ``more``: chaos there may be a longer transient."""
    for job in jobs:
        if job[0] != "tight":
            continue
        loose, tight = (load_run(work, kind, *job[1:4]) for kind in ("long", "tight"))
        if loose and tight and verdict_of(loose[0])[1].verdict == "periodic" != verdict_of(tight[0])[1].verdict:
            print(time.strftime("%H:%M:%S"), R.continue_run(work, *job[:4], more), flush=True)


def verdict_of(res: Results):
    sec = poincare_section(res, ("slider.vx", "slider.ax"))
    return sec, classify(sec)


def lyapunov_of(work: Path, joint: str, modulus: str, speed: str) -> dict | None:
    path = work / f"{R.job_name('lyap', joint, modulus, speed)}.json"
    if not path.exists():
        return None
    d = json.loads(path.read_text())
    main = [r for r in d["runs"] if r["d0"] == R.LYAP_D0 and r["value"] is not None]
    small = [r for r in d["runs"] if r["d0"] != R.LYAP_D0 and r["value"] is not None]
    vals = np.array([r["value"] for r in main])
    return {"mean": float(vals.mean()) if len(vals) else float("nan"), "std": float(vals.std()) if len(vals) else float("nan"),
            "n": len(vals), "values": vals.tolist(), "small_d0": small[0]["value"] if small else None,
            "revolutions": d["revolutions"], "from_revolution": d["from_revolution"], "runs": d["runs"]}


def floquet_of(work: Path, joint: str, modulus: str, speed: str, periods: int | None) -> dict | None:
    """The Floquet exponents (both difference steps) over the verdict's period, if the case is periodic."""
    path = work / f"{R.job_name('floquet', joint, modulus, speed)}.json"
    if periods is None or not path.exists():
        return None
    runs = [r for r in json.loads(path.read_text())["runs"] if r.get("periods") == periods]
    return {"periods": periods, "values": {f"{r['eps']:g}": r["value"] for r in runs},
            "closure": max((r["closure"] for r in runs), default=float("nan"))} if runs else None


def case_summary(work: Path, joint: str, modulus: str, speed: str) -> dict | None:
    got = load_run(work, "long", joint, modulus, speed)
    if got is None:
        return None
    res, meta = got
    sec, v = verdict_of(res)
    out = {"joint": joint, "E": modulus, "speed": speed, "revolutions": meta["revolutions"],
           "settled_revolution": v.settled_revolution, "verdict": v.label(), "class": v.verdict, **{
               k: getattr(v, k) for k in ("K", "lyapunov", "dimension", "recurrence", "n_points", "agree", "note")},
           "rtol": meta["rtol"], "cpu": meta["cpu"], "commit": meta["commit"]}
    tight = load_run(work, "tight", joint, modulus, speed)
    if tight is not None:
        _, vt = verdict_of(tight[0])
        out["tight"] = {"rtol": tight[1]["rtol"], "verdict": vt.label(), "class": vt.verdict,
                        "revolutions": tight[1]["revolutions"],
                        "settled_revolution": vt.settled_revolution, "cpu": tight[1]["cpu"]}
    out["benettin"] = lyapunov_of(work, joint, modulus, speed)
    out["floquet"] = floquet_of(work, joint, modulus, speed, v.period if v.verdict == "periodic" else None)
    return out


# ---------------------------------------------------------------- time series (short sweeps)
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _cases(path: Path) -> list[tuple[dict, object]]:
    return [(row, read_results(f"{path}:/cases/{row['index']}")) for row in read_case_table(path)]


def _window(res, revs=SHOWN):
    speed = float(re.match(r"[\d.eE+-]+", res.attrs["parameters"]["speed"]).group()) / 60.0  # rev/s
    period = 1.0 / speed
    t = res.time
    m = (t >= revs[0] * period) & (t <= revs[1] * period)
    return m, period


def series_grid(path: Path, signals: list[tuple[str, str]], label_of, title: str, out: Path, pending=()):
    """One row per case (plus pending rows), one column per signal; time in ms over revolutions 2–5."""
    plt = _plt()
    cases = _cases(path)
    rows = len(cases) + len(pending)
    fig, axes = plt.subplots(rows, len(signals), figsize=(4.2 * len(signals), 1.9 * rows), squeeze=False)
    for i, (row, res) in enumerate(cases):
        m, period = _window(res)
        for j, (name, unit) in enumerate(signals):
            ax = axes[i, j]
            ax.plot(res.time[m] * 1e3, res[name][m], lw=0.7)
            ax.set_ylabel(f"{name} [{unit}]", fontsize=7)
            ax.set_title(f"({chr(97 + i)}) {label_of(row)}", fontsize=8, loc="left")
            ax.tick_params(labelsize=7)
    for k, name in enumerate(pending):
        for j in range(len(signals)):
            ax = axes[len(cases) + k, j]
            ax.text(0.5, 0.5, f"{name}: pending (law not implemented yet)", ha="center", va="center", fontsize=8)
            ax.set_axis_off()
    for ax in axes[-1]:
        ax.set_xlabel("time [ms]", fontsize=8)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------- figures
def poincare_grid(work: Path, joint: str, modulus: str, title: str, out: Path) -> None:
    """Fig. 12 / 16 again: the Poincaré map of each speed from the 1000-revolution run; the
    settled points in the verdict's colour, the transient in grey."""
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(9, 8))
    for i, (ax, speed) in enumerate(zip(axes.flat, SPEEDS)):
        got = load_run(work, "long", joint, modulus, speed)
        if got is None:
            ax.text(0.5, 0.5, f"{speed}: not run", ha="center", va="center")
            ax.set_axis_off()
            continue
        sec, v = verdict_of(got[0])
        first = v.settled_at if v.settled_at is not None else len(sec) // 2
        vx, axx = sec.points["slider.vx"], sec.points["slider.ax"]
        ax.plot(vx[:first], axx[:first], ".", ms=1.5, color="0.75", label=f"before revolution {sec.revolution[first]}")
        ax.plot(vx[first:], axx[first:], "o" if v.verdict == "periodic" else ".", ms=4 if v.verdict == "periodic" else 2,
                color=VERDICT_COLOURS[v.verdict], label=v.label())
        settle = f"settled at rev. {v.settled_revolution}" if v.settled_revolution else "not settled"
        ax.set_title(f"({chr(97 + i)}) {speed}: {v.label()}, {settle}\n({len(sec)} points, revolutions 2–{sec.revolution[-1]})",
                     fontsize=8)
        ax.set_xlabel("slider.vx [m/s]", fontsize=8)
        ax.set_ylabel("slider.ax [m/s²]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7, markerscale=2)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def bifurcation(work: Path, joint: str, modulus: str, title: str, out: Path) -> list[dict]:
    """Settled Poincaré values of slider vx and ax against crank speed, coloured by verdict;
    the transient points in light grey."""
    plt = _plt()
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    rows, seen = [], set()
    for speed in BIF_SPEEDS:
        got = load_run(work, "long", joint, modulus, speed)
        if got is None:
            continue
        sec, v = verdict_of(got[0])
        rpm = float(speed[:-3])
        first = v.settled_at if v.settled_at is not None else len(sec) // 2
        for ax, name in zip(axes, ("slider.vx", "slider.ax")):
            y = sec.points[name]
            ax.plot(np.full(first, rpm), y[:first], ".", ms=1, color="0.85")
            ax.plot(np.full(len(y) - first, rpm), y[first:], ".", ms=2, color=VERDICT_COLOURS[v.verdict],
                    label=v.verdict if (v.verdict not in seen and name == "slider.vx") else None)
        seen.add(v.verdict)
        rows.append({"speed": speed, "verdict": v.label(), "class": v.verdict, "settled_revolution": v.settled_revolution,
                     "revolutions": got[1]["revolutions"], "K": v.K, "lyapunov": v.lyapunov, "note": v.note})
    axes[0].set_ylabel("slider.vx at the section [m/s]")
    axes[1].set_ylabel("slider.ax at the section [m/s²]")
    axes[1].set_xlabel("crank speed [rpm]")
    axes[0].set_title(title, fontsize=9)
    if seen:
        axes[0].legend(fontsize=8, markerscale=4)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return rows


def convergence_figure(summaries: list[dict], out: Path) -> None:
    """Running mean of Benettin's exponent for every perturbed state, per case."""
    plt = _plt()
    cases = [s for s in summaries if s.get("benettin")]
    if not cases:
        return
    n = len(cases)
    cols = 4
    fig, axes = plt.subplots(math.ceil(n / cols), cols, figsize=(12, 2.4 * math.ceil(n / cols)), squeeze=False)
    for ax, s in zip(axes.flat, cases):
        for r in s["benettin"]["runs"]:
            if r["value"] is None:
                continue
            logs = np.array(r["logs"])[r["discard"]:]
            style = "-" if r["d0"] == R.LYAP_D0 else "k--"
            ax.plot(np.arange(1, len(logs) + 1), np.cumsum(logs) / np.arange(1, len(logs) + 1), style, lw=0.8)
        ax.axhline(0, color="0.5", lw=0.5)
        ax.set_title(f"{s['joint']}, {s['E']}, {s['speed']}: {s['verdict']}", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[n:]:
        ax.set_axis_off()
    fig.supxlabel("revolutions after the start state (first 10 discarded)", fontsize=8)
    fig.supylabel("running mean of λ per revolution", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def make_figures(work: Path, files: dict, summaries: list[dict]) -> tuple[list[Path], dict]:
    IMAGES.mkdir(parents=True, exist_ok=True)
    written = []

    def save(name):
        p = IMAGES / f"replication_{name}.png"
        written.append(p)
        return p

    series_figures(files, save)
    for joint, base in (("A", 9), ("B", 13)):
        for tag, modulus in MODULI.items():
            poincare_grid(work, joint, modulus, f"Fig. {base + 3}: Poincaré maps (slider vx against ax, once per "
                          f"revolution, {REVOLUTIONS}-revolution runs), 0.3 mm clearance at {joint}, E = {modulus}",
                          save(f"fig{base + 3:02d}_{joint}_poincare_{tag}"))
    bif = {}
    for tag, modulus in MODULI.items():
        for joint in "AB":
            if not any((work / f"{R.job_name('long', joint, modulus, s)}.npz").exists() for s in BIF_SPEEDS
                       if s not in SPEEDS):
                continue
            bif[f"{joint}_{tag}"] = bifurcation(
                work, joint, modulus, f"Bifurcation diagram, 0.3 mm clearance at {joint}, E = {modulus}: slider vx "
                f"and ax once per revolution\nafter the motion settled (grey: before), {REVOLUTIONS}-revolution runs",
                save(f"bifurcation_{joint}_{tag}"))
    convergence_figure(summaries, save("lyapunov_convergence"))
    return written, bif


def series_figures(files: dict, save) -> None:
    """Figs. 5-11 and 13-15: the time series of the short sweeps (revolutions 2-5)."""
    law_label = lambda row: LAW_TITLES.get(row["values"]["law"], row["values"]["law"])  # noqa: E731
    for joint, fig_v, fig_t in (("A", 5, 6), ("B", 7, 8)):
        path = files["laws"][joint]
        series_grid(path, [("slider.vx", "m/s"), ("slider.ax", "m/s²")], law_label,
                    f"Fig. {fig_v}: slider velocity and acceleration, 0.3 mm clearance at {joint}, 5000 rpm, "
                    "E = 207 GPa, revolutions 2–5", save(f"fig{fig_v:02d}_{joint}_laws_slider"))
        series_grid(path, [("crank_speed.torque", "N m")], law_label,
                    f"Fig. {fig_t}: driving torque, 0.3 mm clearance at {joint}, 5000 rpm, E = 207 GPa",
                    save(f"fig{fig_t:02d}_{joint}_laws_torque"))
    speed_label = lambda row: row["values"]["speed"]  # noqa: E731
    for joint, base in (("A", 9), ("B", 13)):
        for tag, modulus in MODULI.items():
            path = files["speeds"][(joint, tag)]
            e = f"0.3 mm clearance at {joint}, E = {modulus.replace('207', '207 ')}, revolutions 2–5"
            series_grid(path, [("slider.ax", "m/s²")], speed_label, f"Fig. {base}: slider acceleration, {e}",
                        save(f"fig{base:02d}_{joint}_acceleration_{tag}"))
            series_grid(path, [(signal_of(joint), "N")], speed_label, f"Fig. {base + 1}: joint reaction force, {e}",
                        save(f"fig{base + 1:02d}_{joint}_force_{tag}"))
            series_grid(path, [("crank_speed.torque", "N m")], speed_label, f"Fig. {base + 2}: crank torque, {e}",
                        save(f"fig{base + 2:02d}_{joint}_torque_{tag}"))


# ---------------------------------------------------------------- numbers
def peaks(path: Path, joint: str, from_rev: int = 1) -> dict[str, dict[str, float]]:
    out = {}
    for row, res in _cases(path):
        m, _ = _window(res, (from_rev, math.inf))
        key = row["values"].get("speed") or row["values"].get("law")
        out[key] = {"ax": float(np.max(np.abs(res["slider.ax"][m]))),
                    "force": float(np.max(res[signal_of(joint)][m])),
                    "torque": float(np.max(np.abs(res["crank_speed.torque"][m])))}
    return out


# ---------------------------------------------------------------- tables
def _lam(b: dict | None) -> str:
    if not b:
        return "not run"
    if not b["n"]:
        return f"failed ({len(b['runs'])} of {len(b['runs'])} directions stopped)"
    return f"{b['mean']:.3g} ± {b['std']:.2g} ({b['n']} states, {b['revolutions'] - 10} rev)"


def _floquet(f: dict | None) -> str:
    """Floquet's exponent at the difference step 1e-6, that at 1e-5 beside it."""
    if not f or "1e-06" not in f["values"]:
        return "–"
    other = f"; ε 1e-5: {f['values']['1e-05']:.3g}" if "1e-05" in f["values"] else ""
    return f"{f['values']['1e-06']:.3g} ({f['periods']}T{other})"


def _settled(cls: str, rev, revolutions: int, short: bool = False) -> str:
    if rev is None:
        return f"not settled after {revolutions}"
    if cls == "periodic":
        return f"from revolution {rev}" if short else f"{rev}"
    return f"stationary from revolution {rev}" if short else f"{rev} (stationary {cls})"


def _agree_lyapunov(s: dict) -> str:
    """Where Benettin's exponent and the verdict (nearest-neighbour λ, recurrence) disagree."""
    b = s.get("benettin")
    if not b or not b["n"]:
        return ""
    positive = b["mean"] - b["std"] > 0.1
    negative = b["mean"] + b["std"] < 0
    if s["class"] == "periodic" and not negative:
        return "Benettin λ not negative on a periodic orbit"
    f = (s.get("floquet") or {}).get("values", {}).get("1e-06")
    if s["class"] == "periodic" and f is not None and not 0.5 < b["mean"] / f < 2:
        return f"Benettin and Floquet differ ({b['mean']:.2f} vs {f:.2f})"
    if s["class"] == "chaotic" and not positive:
        return "Benettin λ not clearly positive"
    if s["class"] == "chaotic" and not math.isnan(s["lyapunov"]) and abs(b["mean"] - s["lyapunov"]) > 0.5 * abs(b["mean"]):
        return f"both positive, magnitudes differ ({b['mean']:.1f} vs {s['lyapunov']:.1f})"
    if b.get("small_d0") is not None and b["mean"] > 0 and abs(b["small_d0"] - b["mean"]) > 0.25 * abs(b["mean"]) + 2 * b["std"]:
        return f"depends on d0 (d0/100: {b['small_d0']:.2f})"
    return ""


def short_tables(files: dict) -> tuple[dict[str, str], dict]:
    """The "peaks" and "laws" tables (and their numbers) from the short sweeps of `short_sweeps`."""
    gen, data = {}, {"peaks": {}, "laws": {}}
    lines = ["| joint | E | quantity | " + " | ".join(SPEEDS) + " | grows with speed |",
             "| --- | --- | --- | " + " | ".join("---" for _ in SPEEDS) + " | --- |"]
    for (joint, tag), path in files["speeds"].items():
        p = peaks(path, joint)
        data["peaks"][f"{joint}_{tag}"] = p
        for q, unit in (("ax", "m/s²"), ("force", "N"), ("torque", "N m")):
            vals = [p[s][q] for s in SPEEDS if s in p]
            mono = "yes" if all(b > a for a, b in zip(vals, vals[1:])) else "no"
            lines.append(f"| {joint} | {MODULI[tag]} | max {q} [{unit}] | " + " | ".join(f"{x:.4g}" for x in vals)
                         + f" | {mono} |")
    gen["peaks"] = "\n".join(lines)
    lines = ["| joint | law | max abs slider ax [m/s²] | max contact force [N] | max abs torque [N m] |",
             "| --- | --- | --- | --- | --- |"]
    for joint, path in files["laws"].items():
        p = peaks(path, joint)
        data["laws"][joint] = p
        for law in LAWS:
            lines.append(f"| {joint} | {LAW_TITLES[law]} | {p[law]['ax']:.4g} | {p[law]['force']:.4g} | "
                         f"{p[law]['torque']:.4g} |")
    gen["laws"] = "\n".join(lines)
    gen["laws_claims"] = laws_claims(data["laws"])
    return gen, data


def _ratio_span(p: dict, q: str, over: str, under: str | None = None) -> str:
    """The span of the elastic laws' peak q over the peak of `over` (or of `over` over them)."""
    r = [p[law][q] / p[over][q] for law in ELASTIC] if under is None else [p[under][q] / p[law][q] for law in ELASTIC]
    return f"{min(r):.1f}–{max(r):.1f}×"


def laws_claims(laws: dict) -> str:
    """The verdicts on the paper's §III.B claims, with their numbers, from the laws table."""
    A, B = laws["A"], laws["B"]
    ln = "lankarani_nikravesh"
    lower = all(p[ln][q] < p[law][q] for p in (A, B) for q in ("ax", "torque") for law in ELASTIC)
    ratios = [p[law]["ax"] / p["hertz"]["ax"] for p in (A, B) for law in ELASTIC]
    spread = max(max(ratios), 1 / min(ratios))
    above = ", ".join(f"{LAW_TITLES[law]} {100 * (A[law]['ax'] / A['hertz']['ax'] - 1):+.0f} % (A) and "
                      f"{100 * (B[law]['ax'] / B['hertz']['ax'] - 1):+.0f} % (B)" for law in ELASTIC[1:])
    b_over_a = all(B[law]["ax"] > A[law]["ax"] for law in LAWS)
    a_over_b = all(A[law]["torque"] > B[law]["torque"] for law in LAWS)
    rows = [
        ("Lankarani–Nikravesh gives much lower slider-acceleration and torque peaks than the elastic laws",
         "**reproduced** (A and B)" if lower else "**not reproduced**",
         f"peak ax {_ratio_span(A, 'ax', ln)} lower at A, {_ratio_span(B, 'ax', ln)} at B; peak torque "
         f"{_ratio_span(A, 'torque', ln)} lower at A, {_ratio_span(B, 'torque', ln)} at B"),
        ("the velocity is a staircase (free flight, impacts) with the elastic laws and smoother, with long "
         "continuous-contact stretches, with Lankarani–Nikravesh", "**reproduced**",
         "Figs. 5 and 7: steps in `vx` and impact spikes in `ax` with the three elastic laws; smooth stretches "
         "with Lankarani–Nikravesh"),
        ("no great difference between the three elastic laws",
         f"**partly**: same shape, peaks within a factor {spread:.2g}",
         f"peak ax against Hertz: {above}"),
        ("slider-acceleration peaks higher with clearance at B than at A",
         "**reproduced**, every law" if b_over_a else "**not reproduced** for every law",
         f"e.g. Lankarani–Nikravesh {B[ln]['ax']:.3g} vs {A[ln]['ax']:.3g} m/s²"),
        ("crank-torque peaks higher with clearance at A than at B",
         "**reproduced**, every law" if a_over_b else "**not reproduced** for every law",
         f"e.g. Lankarani–Nikravesh {A[ln]['torque']:.3g} vs {B[ln]['torque']:.3g} N m"),
    ]
    return "\n".join(["| paper's claim (§III.B) | our verdict | numbers (table above) |", "| --- | --- | --- |"]
                     + [f"| {c} | {v} | {n} |" for c, v, n in rows])


def class_claims() -> list[tuple[str, tuple[str, ...], str]]:
    """§III.C's claims about the class of motion as the paper words them: (joint, speeds, class), the
    speeds of one joint with the same class in one claim (from `PAPER_CLAIMS`)."""
    claims = []
    for joint, by_speed in PAPER_CLAIMS.items():
        speeds_of: dict[str, list[str]] = {}
        for speed, cls in by_speed.items():
            speeds_of.setdefault(cls, []).append(speed)
        claims += [(joint, tuple(speeds), cls) for cls, speeds in speeds_of.items()]
    return claims


def _case_words(s: dict) -> str:
    """One case of the claims table in words: class, settling, exponents, the tighter tolerance."""
    rev = s["settled_revolution"]
    if s["class"] == "periodic":
        what = f"{s['verdict']} from revolution {rev}" if rev is not None else s["verdict"]
        if rev is not None and rev > 10:
            what = f"chaotic for {rev - 1} revolutions, then {what}"
    else:
        what = f"{s['class']} over all {s['revolutions']} revolutions" + (" (stationary from the start)" if rev == 2 else "")
    b, f = s.get("benettin"), (s.get("floquet") or {}).get("values", {}).get("1e-06")
    if b and b["n"]:
        what += f"; Benettin λ = {b['mean']:.3g} ± {b['std']:.1g} per revolution" + (f" (Floquet {f:.3g})" if f is not None else "")
    t = s.get("tight")
    if t:
        what += f"; rtol {t['rtol']:.0e}: {t['verdict']}".replace("e-0", "e-") + (
            f" from revolution {t['settled_revolution']}" if t["class"] == "periodic" and t["settled_revolution"] else "")
        if t["revolutions"] != s["revolutions"]:
            what += f" ({t['revolutions']} revolutions)"
    return what


def _claim_cell(cases: list[dict], claim: str) -> str:
    """Verdict on a claim about the class of motion, from its cases, with their numbers."""
    if not cases:
        return "not run"
    classes = {c["class"] for c in cases}
    late = [c for c in cases if c["class"] == "periodic" and (c["settled_revolution"] or 0) > 10]
    if any(c.get("tight") and c["tight"]["class"] != c["class"] for c in cases):
        word = "not decided (the two tolerances disagree)"
    elif classes == {claim}:
        word = "reproduced after a chaotic transient" if late else "reproduced"
    elif claim == "chaotic" and late and classes == {"periodic"}:
        word = "only as a transient"
    else:
        word = "not reproduced"
    return f"**{word}**: " + "; ".join((f"{c['speed'][:-3]} rpm: " if len(cases) > 1 else "") + _case_words(c)
                                       for c in cases)


def claims_table(summaries: list[dict], peaks: dict, bif: dict) -> str:
    """The claims of §III.C with our verdict at each modulus, every number from the runs."""
    lines = ["| paper's claim (§III.C) | 207 GPa (steel) | 207 MPa (as printed) |", "| --- | --- | --- |"]
    for joint in "AB":
        cells = []
        for tag in MODULI:
            p = peaks.get(f"{joint}_{tag}", {})
            grows = all(all(p[b][q] > p[a][q] for a, b in zip(SPEEDS, SPEEDS[1:])) for q in ("ax", "force", "torque"))
            cells.append("**reproduced** (table above)" if p and grows else "**not reproduced** (table above)")
        lines.append(f"| peaks of slider acceleration, joint reaction force and crank torque grow with crank speed, "
                     f"clearance at {joint} | " + " | ".join(cells) + " |")
    for joint, speeds, claim in class_claims():
        cells = [_claim_cell([s for s in summaries if s["joint"] == joint and s["E"] == MODULI[tag]
                              and s["speed"] in speeds], claim) for tag in MODULI]
        lines.append(f"| {joint}: {claim} at {' and '.join(x[:-3] for x in speeds)} rpm | " + " | ".join(cells) + " |")
    cells = []
    for tag in MODULI:
        found = [f"{s['joint']} {s['speed']}" for s in summaries if s["E"] == MODULI[tag] and s["class"] == "quasi-periodic"]
        found += [f"{k.split('_')[0]} {r['speed']}" for k, rows in bif.items() if k.endswith(tag)
                  for r in rows if r["class"] == "quasi-periodic"]
        cells.append(f"**found** at {', '.join(sorted(set(found)))}" if found else
                     "**not found** at the paper's speeds nor anywhere in the bifurcation scan below")
    lines.append("| quasi-periodic motion at intermediate speeds | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def verdict_table(summaries: list[dict]) -> str:
    """The case-by-case table of §III.C's speeds: verdicts, settling, exponents, the tighter tolerance."""
    lines = ["| joint | E | speed | paper says | verdict after the transient | settled at revolution | revolutions run "
             "| λ Benettin per rev (mean ± sd) | λ Floquet per rev (ε 1e-6) | λ nearest-neighbour | K | rtol 1e-8 gives "
             "| agrees with paper | note |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for s in summaries:
        paper = PAPER_CLAIMS[s["joint"]][s["speed"]]
        ok = "yes" if s["class"] == paper else "no"
        nn = "–" if s["lyapunov"] != s["lyapunov"] else f"{s['lyapunov']:.2f}"
        settled = _settled(s["class"], s["settled_revolution"], s["revolutions"])
        t = s.get("tight")
        tight = (f"{t['verdict']}, {_settled(t['class'], t['settled_revolution'], t['revolutions'], True)}"
                 + (f" ({t['revolutions']} rev)" if t["revolutions"] != s["revolutions"] else "")) if t else "not run"
        note = "; ".join(filter(None, [_agree_lyapunov(s), s["note"] if not s["agree"] else ""]))
        lines.append(f"| {s['joint']} | {s['E']} | {s['speed']} | {paper} | **{s['verdict']}** | {settled} | "
                     f"{s['revolutions']} | {_lam(s.get('benettin'))} | {_floquet(s.get('floquet'))} | {nn} | "
                     f"{s['K']:.2f} | {tight} | {ok} | {note} |")
    return "\n".join(lines)


def bifurcation_table(bif: dict) -> str:
    """Counts of each class per joint and modulus, then every speed's verdict and settling revolution."""
    lines = ["| joint | E | speeds run | periodic | quasi-periodic | chaotic | not settled |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for key, rows in bif.items():
        joint, tag = key.split("_")
        c = lambda k: sum(1 for r in rows if r["class"] == k)  # noqa: E731
        lines.append(f"| {joint} | {MODULI[tag]} | {len(rows)} of {len(BIF_SPEEDS)} | {c('periodic')} | "
                     f"{c('quasi-periodic')} | {c('chaotic')} | {sum(1 for r in rows if r['settled_revolution'] is None)} |")
    lines += ["", "| speed | " + " | ".join(f"{k.replace('_', ', ')}" for k in bif) + " |",
              "| --- | " + " | ".join("---" for _ in bif) + " |"]
    for speed in BIF_SPEEDS:
        cells = []
        for rows in bif.values():
            r = next((r for r in rows if r["speed"] == speed), None)
            cells.append("not run" if r is None else f"{r['verdict']}" + (
                f" (from {r['settled_revolution']})" if r["settled_revolution"] is not None else " (not settled)"))
        lines.append(f"| {speed} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def case_tables(data: dict) -> dict[str, str]:
    """The page's tables of the long runs, from the numbers of docs/replication_data.json (so a test can
    render them again and compare them with the page)."""
    return {"verdicts": verdict_table(data["cases"]), "claims": claims_table(data["cases"], data["peaks"], data["bifurcation"]),
            "bifurcation": bifurcation_table(data["bifurcation"])}


def tables(work: Path, files: dict, summaries: list[dict], bif: dict, figures: list[Path], wall: float) -> dict[str, str]:
    data = {"cases": summaries, "bifurcation": bif}
    gen, short_data = short_tables(files)
    data.update(short_data)
    gen.update(case_tables(data))
    commits = sorted({json.loads(str(np.load(p)["meta"]))["commit"] for p in work.glob("*.npz")})
    n_long = len([p for p in work.glob("long_*.npz") if not p.stem.endswith("_cont")])
    n_tight = len([p for p in work.glob("tight_*.npz") if not p.stem.endswith("_cont")])
    n_lyap = len(list(work.glob("lyap_*.json")))
    cpu = sum(json.loads(str(np.load(p)["meta"]))["cpu"] for p in work.glob("*.npz"))
    cpu += sum(json.loads(p.read_text())["cpu"] for p in [*work.glob("lyap_*.json"), *work.glob("floquet_*.json")])
    gen["run"] = (f"Runs behind this page: {n_long} runs of {REVOLUTIONS} revolutions, {n_tight} of them again at "
                  f"rtol 1e-8, Benettin and Floquet exponents of {n_lyap} cases; {cpu / 60:.0f} min of CPU in the time loops "
                  f"(runs made from {_made_from(commits)}; each run's commit is in docs/replication_data.json); "
                  f"{len(figures)} figures; "
                  f"drawing and analysis {wall:.0f} s.")
    data["commits"] = commits
    (ROOT / "docs" / "replication_data.json").write_text(json.dumps(data, indent=1, default=_json))
    return gen


def _made_from(commits: list[str]) -> str:
    """Which versions of the repository the runs were made from, in words."""
    if len(commits) == 1:
        return f"one version of this repository, commit {commits[0][:10]}"
    return f"{len(commits)} versions of this repository (commits " + ", ".join(c[:10] for c in commits) + ")"


def fill_page(gen: dict[str, str]) -> None:
    if not PAGE.exists():
        print(f"{PAGE} missing; generated tables:\n" + "\n\n".join(gen.values()))
        return
    text = PAGE.read_text(encoding="utf-8")
    for name, body in gen.items():
        pat = re.compile(rf"(<!-- BEGIN generated:{name} -->)\n.*?(<!-- END generated:{name} -->)", re.S)
        text, n = pat.subn(lambda m: m.group(1) + "\n" + body + "\n" + m.group(2), text)
        if not n:
            print(f"note: no generated:{name} block in {PAGE.name}")
    PAGE.write_text(text, encoding="utf-8")


def _json(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def main_short(jobs: int | None) -> None:
    """`--short`: the short sweeps run afresh, Figs. 5-11 and 13-15 drawn, the "peaks" and "laws" blocks of
    the page and their numbers in docs/replication_data.json replaced; the long runs' results stay."""
    import tempfile

    with tempfile.TemporaryDirectory() as work:
        files = short_sweeps(Path(work), jobs)
        series_figures(files, lambda name: IMAGES / f"replication_{name}.png")
        gen, numbers = short_tables(files)
    path = ROOT / "docs" / "replication_data.json"
    data = json.loads(path.read_text(encoding="utf-8"))
    data.update(numbers)
    path.write_text(json.dumps(data, indent=1, default=_json))
    if "cases" in data:
        gen.update(case_tables(data))  # the claims about the peaks read them
    fill_page(gen)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--jobs", type=int, default=2, help="parallel processes for the runs")
    ap.add_argument("--work", type=Path, default=ROOT / "build" / "replication", help="where the runs are kept")
    ap.add_argument("--draw", action="store_true", help="run nothing: draw and fill the page from the runs in --work")
    ap.add_argument("--full", action="store_true", help="also the optional runs (see the module docstring)")
    ap.add_argument("--short", action="store_true", help="only the short sweeps: their figures, the peaks and laws "
                    "tables (no long run needed; fresh sweeps in a temporary folder)")
    args = ap.parse_args()
    if args.short:
        return main_short(args.jobs)
    jobs, lyap = long_jobs(args.full)
    if not args.draw:
        R.main(jobs, args.work, args.jobs)
        R.main_lyapunov(lyap, args.work)
        continue_disagreeing(args.work, jobs)
    files = short_sweeps(args.work, args.jobs)
    start = time.perf_counter()
    summaries = [s for s in (case_summary(args.work, j, MODULI[tag], sp) for tag in MODULI for j in "AB"
                             for sp in SPEEDS) if s is not None]
    figures, bif = make_figures(args.work, files, summaries)
    gen = tables(args.work, files, summaries, bif, figures, time.perf_counter() - start)
    fill_page(gen)
    print(gen["run"])


if __name__ == "__main__":
    main()
