"""Regenerate every figure and every generated table of docs/replication.md.

    .venv/bin/python docs/scripts/replicate.py                # everything, ~2 cores
    .venv/bin/python docs/scripts/replicate.py --jobs 4 --work /tmp/rep
    .venv/bin/python docs/scripts/replicate.py --quick        # a smoke run: few speeds, short runs

The runs are `mbs sweep`s (planar_mbs.sweep.run_sweep) kept in ``--work``
(default build/replication/); rerunning resumes them, ``--fresh`` starts over.
Figures go to docs/images/replication_*.png; the tables between the
``<!-- BEGIN generated:... -->`` / ``<!-- END generated:... -->`` markers of
docs/replication.md are rewritten, including the wall time of the run.
"""
from __future__ import annotations

import argparse
import json
import math
import re
import shutil
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from planar_mbs import read_results  # noqa: E402
from planar_mbs.analysis import VERDICT_COLOURS, bifurcation_figure, section_figure  # noqa: E402
from planar_mbs.sweep import Axis, read_case_table, run_sweep, sweep_sections  # noqa: E402

IMAGES = ROOT / "docs" / "images"
PAGE = ROOT / "docs" / "replication.md"
MODELS = {"A": ROOT / "models" / "slider_crank_clearance_a.mbs", "B": ROOT / "models" / "slider_crank_clearance_b.mbs"}
LAWS = ["hertz", "dubowsky_freudenstein", "esdu78035", "lankarani_nikravesh"]
LAW_TITLES = {"hertz": "Hertz", "dubowsky_freudenstein": "Dubowsky–Freudenstein", "esdu78035": "ESDU-78035",
              "lankarani_nikravesh": "Lankarani–Nikravesh"}
SPEEDS = ["800rpm", "1200rpm", "2500rpm", "5000rpm"]
MODULI = {"GPa": "207GPa", "MPa": "207MPa"}
REVOLUTIONS = 101  # 1 transient + 100 section points
PER_REV_SERIES = 1440  # output samples per revolution of the runs whose time series are drawn
PER_REV_BIF = 360
SHOWN = (1, 5)  # revolutions drawn: "four cycles after the first" (Muvengei et al. §III.A)
PAPER_CLAIMS = {  # §III.C
    "A": {"800rpm": "chaotic", "1200rpm": "quasi-periodic", "2500rpm": "quasi-periodic", "5000rpm": "periodic"},
    "B": {"800rpm": "periodic", "1200rpm": "quasi-periodic", "2500rpm": "quasi-periodic", "5000rpm": "chaotic"},
}


def available_laws() -> list[str]:
    from planar_mbs import load_model
    from planar_mbs.errors import ModelError

    out = []
    for law in LAWS:
        try:
            load_model(MODELS["A"], law=law)
            out.append(law)
        except ModelError:
            pass
    return out


def signal_of(joint: str) -> str:
    return f"{joint}.contact_force"


# ---------------------------------------------------------------- runs
def run_all(work: Path, jobs: int, quick: bool, fresh: bool) -> dict:
    work.mkdir(parents=True, exist_ok=True)
    if fresh:
        for f in work.glob("*.h5"):
            f.unlink()
    revs = 21 if quick else REVOLUTIONS
    n_bif = {"GPa": 5 if quick else 45, "MPa": 4 if quick else 23}
    laws = available_laws()
    files = {"laws": {}, "speeds": {}, "bif": {}}

    def progress(tag):
        def cb(done, total, outcome):
            if outcome is not None:
                v = outcome.verdict.label() if outcome.verdict else ""
                print(f"  [{tag}] {done}/{total} {outcome.values} {outcome.status} {v} ({outcome.wall_time:.1f} s)",
                      flush=True)
        return cb

    for joint, model in MODELS.items():
        keep = ["slider.vx", "slider.ax", "crank_speed.torque", signal_of(joint)]
        out = work / f"laws_{joint}.h5"
        print(f"laws at {joint}: {', '.join(laws)}", flush=True)
        run_sweep(model, [Axis("law", tuple(laws))], out, revolutions=SHOWN[1], per_rev=PER_REV_SERIES, keep=keep,
                  section=None, jobs=jobs, progress=progress(f"laws {joint}"))
        files["laws"][joint] = out
        for tag, modulus in MODULI.items():
            out = work / f"speeds_{joint}_{tag}.h5"
            print(f"speeds at {joint}, E = {modulus}", flush=True)
            run_sweep(model, [Axis("speed", tuple(SPEEDS))], out, sets={"youngs_modulus": modulus},
                      revolutions=revs, per_rev=PER_REV_SERIES, keep=keep, section={}, jobs=jobs,
                      progress=progress(f"speeds {joint} {tag}"))
            files["speeds"][(joint, tag)] = out
    for tag, modulus in MODULI.items():
        for joint, model in MODELS.items():
            out = work / f"bifurcation_{joint}_{tag}.h5"
            print(f"bifurcation at {joint}, E = {modulus}: {n_bif[tag]} speeds", flush=True)
            run_sweep(model, [Axis("speed", _speeds(500, 6000, n_bif[tag]))], out,
                      sets={"youngs_modulus": modulus}, revolutions=revs, per_rev=PER_REV_BIF, keep=[],
                      section={}, jobs=jobs, progress=progress(f"bif {joint} {tag}"))
            files["bif"][(joint, tag)] = out
    return files


def _speeds(lo: float, hi: float, n: int) -> tuple[str, ...]:
    return tuple(f"{v:.6g}rpm" for v in np.linspace(lo, hi, n))


# ---------------------------------------------------------------- figures
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _cases(path: Path) -> list[tuple[dict, object]]:
    return [(row, read_results(f"{path}:/cases/{row['index']}")) for row in read_case_table(path)]


def _window(res, revs=SHOWN):
    from planar_mbs.analysis import driver_period  # noqa: F401  (period from the speed parameter)

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


def poincare_grid(path: Path, title: str, out: Path) -> None:
    plt = _plt()
    secs = sweep_sections(path)
    fig, axes = plt.subplots(2, 2, figsize=(8.5, 7.5))
    for ax, (i, (row, sec, verdict)) in zip(axes.flat, enumerate(secs)):
        section_figure(sec, verdict, title=f"({chr(97 + i)}) {row['values']['speed']}", ax=ax)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def bifurcation(path: Path, title: str, out: Path) -> None:
    plt = _plt()
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    bifurcation_figure(path, "speed", "slider.vx", unit="rpm", ax=axes[0], title=title)
    bifurcation_figure(path, "speed", "slider.ax", unit="rpm", ax=axes[1])
    axes[0].set_xlabel("")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def make_figures(files: dict, laws: list[str]) -> list[Path]:
    IMAGES.mkdir(parents=True, exist_ok=True)
    written = []

    def save(name):
        p = IMAGES / f"replication_{name}.png"
        written.append(p)
        return p

    pending = [LAW_TITLES[law] for law in LAWS if law not in laws]
    law_label = lambda row: LAW_TITLES.get(row["values"]["law"], row["values"]["law"])  # noqa: E731
    for joint, fig_v, fig_t in (("A", 5, 6), ("B", 7, 8)):
        path = files["laws"][joint]
        series_grid(path, [("slider.vx", "m/s"), ("slider.ax", "m/s²")], law_label,
                    f"Fig. {fig_v}: slider velocity and acceleration, 0.3 mm clearance at {joint}, 5000 rpm, "
                    "E = 207 GPa, revolutions 2–5", save(f"fig{fig_v:02d}_{joint}_laws_slider"), pending)
        series_grid(path, [("crank_speed.torque", "N m")], law_label,
                    f"Fig. {fig_t}: driving torque, 0.3 mm clearance at {joint}, 5000 rpm, E = 207 GPa",
                    save(f"fig{fig_t:02d}_{joint}_laws_torque"), pending)
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
            poincare_grid(path, f"Fig. {base + 3}: Poincaré maps (slider vx against ax, once per revolution, "
                          f"revolutions 2–{REVOLUTIONS}), 0.3 mm clearance at {joint}, E = {modulus}",
                          save(f"fig{base + 3:02d}_{joint}_poincare_{tag}"))
    for (joint, tag), path in files["bif"].items():
        bifurcation(path, f"Bifurcation diagram, 0.3 mm clearance at {joint}, E = {MODULI[tag]}:\nslider vx and ax "
                    f"once per revolution (revolutions 2–{REVOLUTIONS}) against crank speed",
                    save(f"bifurcation_{joint}_{tag}"))
    return written


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


def tables(files: dict, laws: list[str], wall: float, figures: list[Path], fresh: bool = True) -> dict[str, str]:
    gen = {}
    # verdicts per speed
    lines = ["| joint | E | speed | paper says | our verdict | K | λ per rev | D2 | recurrence | N | agrees with paper |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    data = {"verdicts": [], "peaks": {}, "laws": {}}
    for (joint, tag), path in files["speeds"].items():
        for row, sec, v in sweep_sections(path):
            speed = row["values"]["speed"]
            claim = PAPER_CLAIMS[joint][speed]
            ok = "yes" if v.verdict == claim else "no"
            lam = "–" if v.lyapunov != v.lyapunov else f"{v.lyapunov:.2f}"
            lines.append(f"| {joint} | {MODULI[tag]} | {speed} | {claim} | **{v.label()}** | {v.K:.2f} | {lam} | "
                         f"{v.dimension:.2f} | {v.recurrence:.1e} | {v.n_points} | {ok} |")
            data["verdicts"].append({"joint": joint, "E": MODULI[tag], "speed": speed, **v.as_dict()})
    gen["verdicts"] = "\n".join(lines)
    # peaks against speed
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
    # laws
    lines = ["| joint | law | max abs slider ax [m/s²] | max contact force [N] | max abs torque [N m] |",
             "| --- | --- | --- | --- | --- |"]
    for joint, path in files["laws"].items():
        p = peaks(path, joint)
        data["laws"][joint] = p
        for law in LAWS:
            if law in p:
                lines.append(f"| {joint} | {LAW_TITLES[law]} | {p[law]['ax']:.4g} | {p[law]['force']:.4g} | "
                             f"{p[law]['torque']:.4g} |")
            else:
                lines.append(f"| {joint} | {LAW_TITLES[law]} | pending | pending | pending |")
    gen["laws"] = "\n".join(lines)
    # bifurcation summary: verdict counts
    lines = ["| joint | E | speeds | periodic | quasi-periodic | chaotic | undetermined |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for (joint, tag), path in files["bif"].items():
        rows = read_case_table(path)
        count = lambda v: sum(1 for r in rows if r["verdict"].startswith(v))  # noqa: E731
        lines.append(f"| {joint} | {MODULI[tag]} | {len(rows)} | {count('periodic')} | {count('quasi')} | "
                     f"{count('chaotic')} | {count('undetermined')} |")
        data.setdefault("bifurcation", {})[f"{joint}_{tag}"] = [
            {"speed": r["values"]["speed"], "verdict": r["verdict"], "K": r["K"], "lyapunov": r["lyapunov"],
             "dimension": r["dimension"]} for r in rows]
    gen["bifurcation"] = "\n".join(lines)
    pending = [LAW_TITLES[law] for law in LAWS if law not in laws]
    gen["run"] = (f"Last regeneration: {len(figures)} figures, wall time **{wall / 60:.1f} min** "
                  f"({wall:.0f} s) on this machine (2 cores, `--fresh --jobs 2`, {sum(len(read_case_table(p)) for d in files.values() for p in d.values())} runs of 5 to {REVOLUTIONS} crank revolutions)"
                  + (f"; pending (law not implemented): {', '.join(pending)}" if pending else "") + ".")
    (ROOT / "docs" / "replication_data.json").write_text(json.dumps(data, indent=1, default=float))
    if not fresh:  # a resumed run only redraws: the page keeps its from-scratch wall time
        print(gen.pop("run") + " (resumed run: the page keeps its from-scratch wall time; use --fresh)")
    return gen


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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--jobs", type=int, default=None, help="parallel processes (default: cores)")
    ap.add_argument("--work", type=Path, default=ROOT / "build" / "replication", help="where the sweep files go")
    ap.add_argument("--quick", action="store_true", help="a smoke run (short runs, few speeds): figures go to WORK/images, the page is not touched")
    ap.add_argument("--fresh", action="store_true", help="delete the sweep files first (from scratch)")
    args = ap.parse_args()
    global IMAGES
    if args.quick:
        IMAGES = args.work / "images"
    start = time.perf_counter()
    laws = available_laws()
    files = run_all(args.work, args.jobs, args.quick, args.fresh)
    figures = make_figures(files, laws)
    wall = time.perf_counter() - start
    gen = tables(files, laws, wall, figures, fresh=args.fresh)
    if not args.quick:
        fill_page(gen)
    else:
        print("\n\n".join(gen.values()))
    print(f"{len(figures)} figures in {IMAGES}, wall time {wall:.0f} s")


if __name__ == "__main__":
    main()
