"""Work-precision benchmarks, rhs cost, start-up, scaling, skipped work and stress tests.

One command regenerates everything in docs/benchmarks.md and docs/images/bench_*.png:

    .venv/bin/python benchmarks/run.py            # every section (about 10-15 minutes on 2 cores)
    .venv/bin/python benchmarks/run.py --only wp_clearance,ratios   # some sections; others kept

Measured numbers go to docs/benchmarks_data.json (one entry per section, with
the machine); the Markdown is written from that file, so a partial run keeps
the other sections' last numbers.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))
DOCS = ROOT / "docs"
IMAGES = DOCS / "images"
DATA = DOCS / "benchmarks_data.json"
MODELS = ROOT / "models"
PY = sys.executable

import planar_mbs as mbs  # noqa: E402
from rhs_cost import section_rhs  # noqa: E402

RPM5000 = 5000 * 2 * math.pi / 60
REV = 2 * math.pi / RPM5000  # one crank revolution at 5000 rpm [s]
RK4_STEPS = [1e-4, 3e-5, 1e-5, 3e-6, 1e-6, 3e-7, 1e-7]
RTOLS = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12]
SCIPY_RTOLS = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
ATOL_FACTOR = 1e-3  # atol = 1e-3 rtol (positions ~0.1 m, eccentricities ~1e-4 m)


# ---------------------------------------------------------------- helpers
def machine() -> dict:
    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numba
    import scipy

    return dict(cpu=cpu, cores=os.cpu_count(), python=platform.python_version(), numpy=np.__version__,
                numba=numba.__version__, scipy=scipy.__version__, system=f"{platform.system()} {platform.release()}",
                date=time.strftime("%Y-%m-%d %H:%M"))


def timed_run(model, repeat=1, **settings):
    """simulate() several times; the time-loop wall time is the smallest of the repeats."""
    best, res = math.inf, None
    for _ in range(repeat):
        try:
            r = mbs.simulate(model, **settings)
        except mbs_errors().SimulationError as err:
            return None, err.message
        best = min(best, r.attrs["wall_time"])
        res = r
    res.attrs["wall_time"] = best
    return res, None


def mbs_errors():
    from planar_mbs import errors

    return errors


def method_runs():
    """(label, method, settings) of the work-precision sweep."""
    out = []
    for h in RK4_STEPS:
        out.append((f"RK4 h={h:g}", "RK4", dict(integrator="rk4", step=h)))
    for m in ("dopri5", "dop853"):
        for rtol in RTOLS:
            out.append((f"{m.upper()} rtol={rtol:g}", m.upper(), dict(integrator=m, rtol=rtol, atol=ATOL_FACTOR * rtol)))
    return out


def stats(res):
    a = res.attrs
    return dict(wall=a["wall_time"], steps=a["n_steps"], rejected=a["n_rejected"], rhs=a["n_rhs"],
                events=a.get("n_contact_events", 0))


def repeats_for(settings, t_end):
    """Repeat quick runs (timing noise), not slow ones."""
    if settings.get("integrator") == "rk4":
        return 3 if settings["step"] >= 1e-6 else 1
    return 3


# ---------------------------------------------------------------- (a) ideal slider-crank
def slider_x_closed_form(t, r=0.05, l=0.12, omega=RPM5000):
    th = omega * t
    return r * np.cos(th) + np.sqrt(l * l - (r * np.sin(th)) ** 2)


def section_wp_ideal() -> dict:
    model = mbs.load_model(MODELS / "slider_crank.mbs")
    t_end = 5 * REV
    rows = []
    for label, method, s in method_runs():
        res, fail = timed_run(model, repeat=repeats_for(s, t_end), t_end=t_end, output_step=50e-6, **s)
        if res is None:
            rows.append(dict(label=label, method=method, failed=fail))
            continue
        err = float(np.max(np.abs(res["slider.x"] - slider_x_closed_form(res.time))))
        rows.append(dict(label=label, method=method, error=err, **stats(res)))
        print(f"  ideal {label:24s} err {err:9.3g}  wall {rows[-1]['wall']:.4f}", flush=True)
    return dict(t_end=t_end, rows=rows,
                measure="max |slider.x - closed form| over 5 revolutions at 5000 rpm, outputs every 50 us [m]")


# ---------------------------------------------------------------- (b) double pendulum
DOUBLE_PENDULUM = """
body upper { mass = 1.0 kg  inertia = 0.02 kg*m^2  position = (0.25, 0) }
body lower { mass = 0.5 kg  inertia = 0.01 kg*m^2  position = (0.5, -0.2)  angle = -90 deg }
joint P = revolute(ground (0, 0), upper (-0.25, 0))
joint Q = revolute(upper (0.25, 0), lower (0.2, 0))
gravity (0, -9.81 m/s^2)
simulate { t_end = 10 s  rtol = 1e-10  atol = 1e-12  output_step = 10 ms }
"""


def section_wp_pendulum() -> dict:
    from planar_mbs.mechanism.compile import compile_text

    model = compile_text(DOUBLE_PENDULUM, "double_pendulum.mbs")
    t_end = 10.0
    rows = []
    for label, method, s in method_runs():
        if method == "RK4" and s["step"] < 1e-6:
            continue  # 10 s at 0.1 us: 1e8 steps
        res, fail = timed_run(model, repeat=1 if method == "RK4" and s["step"] <= 1e-6 else 3, t_end=t_end,
                              output_step=10e-3, **s)
        if res is None:
            rows.append(dict(label=label, method=method, failed=fail))
            continue
        E = res["system.total_energy"]
        scale = float(np.max(res["system.kinetic_energy"]))
        err = float(np.max(np.abs(E - E[0])) / scale)
        rows.append(dict(label=label, method=method, error=err, **stats(res)))
        print(f"  pendulum {label:24s} err {err:9.3g}  wall {rows[-1]['wall']:.4f}", flush=True)
    return dict(t_end=t_end, rows=rows,
                measure="max |E(t) - E(0)| / max kinetic energy over 10 s (undriven double pendulum, outputs every 10 ms)")


# ---------------------------------------------------------------- (c) clearance slider-crank
OUT_STEP_C = 20e-6


def ecc(res):
    return np.stack([res["A.ex"], res["A.ey"]], axis=1)


def section_wp_clearance() -> dict:
    import scipy_baseline
    import slider_crank_equations as E

    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    t_long = 5 * REV
    # three references; the horizon is where the two tighter ones stop agreeing
    refs = {}
    for rtol in (1e-12, 1e-13, 1e-14):
        res, fail = timed_run(model, t_end=t_long, output_step=OUT_STEP_C, integrator="dop853", rtol=rtol,
                              atol=ATOL_FACTOR * rtol)
        assert res is not None, fail
        refs[rtol] = res
    t = refs[1e-12].time
    d_tight = np.linalg.norm(ecc(refs[1e-13]) - ecc(refs[1e-14]), axis=1)
    d_ref = np.linalg.norm(ecc(refs[1e-12]) - ecc(refs[1e-13]), axis=1)
    agree_tol = 1e-9  # m: 3e-6 of the 0.3 mm clearance
    bad = np.nonzero(np.maximum(d_tight, d_ref) > agree_tol)[0]
    horizon = float(t[bad[0] - 1]) if len(bad) else float(t[-1])
    horizon = max(horizon, 4 * OUT_STEP_C)
    n_h = int(np.searchsorted(t, horizon, side="right"))
    floor = float(max(d_tight[:n_h].max(), d_ref[:n_h].max()))
    # divergence curve for the plot (every 10th sample)
    div = dict(t=t[::10].tolist(), d_tight=d_tight[::10].tolist(), d_ref=d_ref[::10].tolist())
    ref = ecc(refs[1e-12])[:n_h]
    events_h = int(np.sum(np.diff(refs[1e-12]["A.in_contact"][:n_h]) > 0.5))
    print(f"  clearance horizon {horizon * 1e3:.3f} ms ({horizon / REV:.2f} rev), floor {floor:.3g} m, "
          f"{events_h} impacts", flush=True)

    rows = []
    for label, method, s in method_runs():
        res, fail = timed_run(model, repeat=repeats_for(s, horizon), t_end=horizon, output_step=OUT_STEP_C, **s)
        if res is None:
            rows.append(dict(label=label, method=method, failed=fail))
            print(f"  clearance {label:24s} FAILED {fail}", flush=True)
            continue
        got = ecc(res)
        if not np.all(np.isfinite(got)) or len(got) < n_h:
            rows.append(dict(label=label, method=method, failed="non-finite or short output"))
            continue
        err = float(np.max(np.linalg.norm(got[:n_h] - ref, axis=1)))
        rows.append(dict(label=label, method=method, error=err, **stats(res)))
        print(f"  clearance {label:24s} err {err:9.3g}  wall {rows[-1]['wall']:.4f}  rhs {rows[-1]['rhs']}",
              flush=True)

    # scipy baseline
    p = E.parameters(model)
    from planar_mbs.mechanism.kinematics import assemble

    q, qd = assemble(model)
    y0 = np.concatenate([q, qd])
    t_eval = t[:n_h]
    for meth in ("RK45", "DOP853"):
        for rtol in SCIPY_RTOLS:
            label = f"scipy {meth} rtol={rtol:g}"
            try:
                ts, ys, wall, nfev, nev = scipy_baseline.run(y0, p, horizon, t_eval, method=meth, rtol=rtol,
                                                             atol=ATOL_FACTOR * rtol)
            except Exception as exc:  # noqa: BLE001 - record and continue
                rows.append(dict(label=label, method=f"scipy {meth}", failed=str(exc)))
                continue
            # the journal eccentricity from the state, on the same grid
            a, b = p[E.P_A], p[E.P_B]
            ex = ys[:, 3] - b * np.cos(ys[:, 5]) - ys[:, 0] - a * np.cos(ys[:, 2])
            ey = ys[:, 4] - b * np.sin(ys[:, 5]) - ys[:, 1] - a * np.sin(ys[:, 2])
            # an event time that is also a grid time appears twice: keep the last
            keep = np.r_[np.diff(ts) > 0, True]
            got = np.stack([ex, ey], axis=1)[keep]
            if len(got) != n_h:
                rows.append(dict(label=label, method=f"scipy {meth}", failed=f"{len(got)} samples, expected {n_h}"))
                continue
            err = float(np.max(np.linalg.norm(got - ref, axis=1)))
            rows.append(dict(label=label, method=f"scipy {meth}", error=err, wall=wall, rhs=int(nfev), events=nev))
            print(f"  clearance {label:24s} err {err:9.3g}  wall {wall:.3f}  rhs {nfev}", flush=True)
    return dict(horizon=horizon, horizon_rev=horizon / REV, floor=floor, agree_tol=agree_tol, t_long=t_long,
                impacts=events_h, divergence=div, rows=rows,
                ref_stats={f"{k:g}": stats(v) for k, v in refs.items()},
                measure="max |e(t) - e_ref(t)| of the journal eccentricity vector of joint A over [0, horizon], "
                        "outputs every 20 us [m]; reference DOP853 rtol 1e-12")


def section_ratios(data) -> dict:
    """At equal or better error: our fastest adaptive run vs each baseline point."""
    rows = data["wp_clearance"]["rows"]
    floor = data["wp_clearance"]["floor"]
    ours = [r for r in rows if r["method"] in ("DOPRI5", "DOP853") and "error" in r]
    out = []
    baselines = [r for r in rows if r["method"].startswith("scipy") and "error" in r]
    baselines += [r for r in rows if r["label"] == "RK4 h=1e-06" and "error" in r]
    for b in baselines:
        target = max(b["error"], floor)
        ok = [r for r in ours if r["error"] <= target]
        if not ok:
            out.append(dict(baseline=b["label"], error=b["error"], wall=b["wall"], ours=None))
            continue
        best = min(ok, key=lambda r: r["wall"])
        out.append(dict(baseline=b["label"], error=b["error"], wall=b["wall"], ours=best["label"],
                        ours_error=best["error"], ours_wall=best["wall"], ratio=b["wall"] / best["wall"]))
    return dict(rows=out)


# ---------------------------------------------------------------- rhs cost vs the yardstick
# ---------------------------------------------------------------- plots and Markdown
def plot_wp(sec, name, title, xlabel="time-loop wall time [s]", ylabel="error"):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    styles = {"RK4": ("o-", "C0"), "DOPRI5": ("s-", "C1"), "DOP853": ("^-", "C2"),
              "scipy RK45": ("s--", "C3"), "scipy DOP853": ("^--", "C4")}
    fig, ax = plt.subplots(figsize=(7, 4.8))
    for method, (st, col) in styles.items():
        # (the clearance section's DOP853 rtol 1e-12 run is the reference itself: error ~0, not plotted)
        pts = [(r["wall"], r["error"]) for r in sec["rows"] if r["method"] == method and "error" in r
               and not ("floor" in sec and r["error"] < 1e-15)]
        if not pts:
            continue
        x, y = zip(*pts)
        ax.loglog(x, np.maximum(y, 1e-17), st, color=col, label=method, ms=4)
    for r in sec["rows"]:
        if r["label"] == "RK4 h=1e-06" and "error" in r:
            ax.loglog([r["wall"]], [r["error"]], "*", color="k", ms=14, label="Muvengei et al.'s way: RK4, 1 us")
    if "floor" in sec:
        ax.axhline(sec["floor"], color="gray", lw=0.8, ls=":", label="reference floor")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(IMAGES / f"bench_{name}.png", dpi=110)
    plt.close(fig)


def plot_divergence(sec):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = sec["divergence"]
    t = np.array(d["t"]) / REV
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.semilogy(t, np.maximum(d["d_tight"], 1e-16), label="DOP853 1e-13 vs 1e-14")
    ax.semilogy(t, np.maximum(d["d_ref"], 1e-16), label="DOP853 1e-12 vs 1e-13")
    ax.axhline(sec["agree_tol"], color="gray", ls=":", lw=0.8)
    ax.axvline(sec["horizon_rev"], color="k", ls="--", lw=0.8, label="horizon")
    ax.set_xlabel("crank revolutions")
    ax.set_ylabel("|e - e'| [m]")
    ax.set_title("Clearance slider-crank: distance between references (journal eccentricity)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(IMAGES / "bench_clearance_divergence.png", dpi=110)
    plt.close(fig)


SECTIONS = ["rhs", "wp_ideal", "wp_pendulum", "wp_clearance", "ratios", "startup", "skip", "scaling", "stress", "process",
            "memory"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", default="", help="comma-separated sections: " + ", ".join(SECTIONS))
    ap.add_argument("--no-write", action="store_true", help="measure only, do not rewrite the Markdown")
    ap.add_argument("--report-only", action="store_true", help="no measurement: redraw figures and Markdown")
    args = ap.parse_args()
    wanted = [] if args.report_only else ([s for s in args.only.split(",") if s] or SECTIONS)
    data = json.loads(DATA.read_text()) if DATA.exists() else {}
    if wanted:
        data["machine"] = machine()
    IMAGES.mkdir(parents=True, exist_ok=True)
    import extra_sections

    for sec in wanted:
        print(f"== {sec}", flush=True)
        t0 = time.perf_counter()
        if sec == "rhs":
            data[sec] = section_rhs()
        elif sec == "wp_ideal":
            data[sec] = section_wp_ideal()
        elif sec == "wp_pendulum":
            data[sec] = section_wp_pendulum()
        elif sec == "wp_clearance":
            data[sec] = section_wp_clearance()
        elif sec == "ratios":
            data[sec] = section_ratios(data)
        elif sec == "order_scaling":
            import order_scaling

            data[sec] = order_scaling.measure()
        elif sec == "process":
            import process

            data[sec] = process.section_process()
        elif sec == "memory":
            import memory

            data[sec] = memory.section_memory()
        else:
            data[sec] = getattr(extra_sections, f"section_{sec}")()
        data.setdefault("section_seconds", {})[sec] = time.perf_counter() - t0
        DATA.write_text(json.dumps(data, indent=1))
    if "wp_ideal" in data:
        plot_wp(data["wp_ideal"], "ideal_slider_crank", "Ideal slider-crank, 5 rev at 5000 rpm, vs closed form",
                ylabel="max |slider x error| [m]")
    if "wp_pendulum" in data:
        plot_wp(data["wp_pendulum"], "double_pendulum", "Undriven double pendulum, 10 s, energy conservation",
                ylabel="max |E - E0| / max T")
    if "wp_clearance" in data:
        sec = data["wp_clearance"]
        plot_wp(sec, "clearance_slider_crank",
                f"Clearance slider-crank (A, 5000 rpm) over {sec['horizon'] * 1e3:.2f} ms, vs DOP853 1e-12",
                ylabel="max |eccentricity error| [m]")
        plot_divergence(sec)
    extra_sections.plots(data)
    if not args.no_write:
        import report

        report.write(data)


if __name__ == "__main__":
    main()
