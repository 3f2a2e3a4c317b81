"""Start-up, skipped work, scaling and stress sections of benchmarks/run.py."""
from __future__ import annotations

import json
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
PY = sys.executable
MBS = str(Path(PY).with_name("mbs"))
HEAVY = ("h5py", "rerun", "matplotlib", "dask", "scipy", "numba", "pint", "lark")


def _wall(cmd, env=None, cwd=None):
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    wall = time.perf_counter() - t0
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-2000:])
    return wall, out.stdout


def _loop_time(stdout):
    m = re.search(r"time-loop wall time ([0-9.]+) s", stdout)
    return float(m.group(1)) if m else float("nan")


def section_startup() -> dict:
    out = {}
    tmp = Path(tempfile.mkdtemp())
    model = str(MODELS / "slider_crank_clearance_a.mbs")
    # mbs --help
    out["help"] = statistics.median(_wall([MBS, "--help"])[0] for _ in range(7))
    # warm cache: total wall minus the time loop
    runs = []
    for _ in range(5):
        wall, stdout = _wall([MBS, "run", model, "-o", str(tmp / "a.h5"), "-q"])
        runs.append((wall - _loop_time(stdout), wall, _loop_time(stdout)))
    runs.sort()
    out["run_warm_overhead"], out["run_warm_total"], out["run_warm_loop"] = runs[len(runs) // 2]
    # phases inside one process (warm cache)
    code = r"""
import json, time; T0 = time.perf_counter(); laps = {}
def lap(k, t=[T0]):
    now = time.perf_counter(); laps[k] = now - t[0]; t[0] = now
import numpy; lap("python + numpy")
import planar_mbs as mbs
from planar_mbs.language import parse; parse.parser(); lap("lark parser")
m = mbs.load_model(%r); lap("rest of load_model (units from our table: no pint)")
from planar_mbs.mechanism.kinematics import assemble; assemble(m); lap("assembly (constraint kernels as plain Python)")
import numba; lap("numba import")
from planar_mbs import kernel; lap("kernel modules (dispatchers, not yet loaded)")
r = mbs.simulate(m, output=%r); lap("simulate: first compiled call (numba target + cache load), time loop, HDF5")
laps["of which time loop"] = r.attrs["wall_time"]
print(json.dumps(laps))
""" % (model, str(tmp / "b.h5"))
    wall, stdout = _wall([PY, "-c", code])
    out["phases"] = json.loads(stdout.strip().splitlines()[-1])
    # first run: an empty numba cache directory
    cold = tmp / "numba_cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cold))
    wall, stdout = _wall([MBS, "run", model, "-o", str(tmp / "c.h5"), "-q"], env=env)
    out["run_cold_total"] = wall
    out["run_cold_loop"] = _loop_time(stdout)
    wall, stdout = _wall([MBS, "run", model, "-o", str(tmp / "d.h5"), "-q"], env=env)
    out["run_cache_dir_second"] = wall - _loop_time(stdout)
    out["cache_files"] = sum(1 for _ in cold.rglob("*.nbi"))
    return out


def _modules_after(code):
    res = subprocess.run([PY, "-c", code + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"],
                         capture_output=True, text=True)
    import json

    mods = json.loads(res.stdout.strip().splitlines()[-1])
    return {h: any(m == h or m.startswith(h + ".") for m in mods) for h in HEAVY}


def imports_table() -> dict:
    model = str(MODELS / "slider_crank_clearance_a.mbs")
    cases = {
        "import planar_mbs": "import planar_mbs",
        "mbs --help": "import sys; sys.argv = ['mbs', '--help']\nfrom planar_mbs.cli.app import main\ntry: main()\n"
                      "except SystemExit: pass",
        "mbs check": f"import sys; sys.argv = ['mbs', 'check', {model!r}]\nfrom planar_mbs.cli.app import main\n"
                     "try: main()\nexcept SystemExit: pass",
        "load_model + simulate (no file)": f"import planar_mbs as m; m.simulate(m.load_model({model!r}), t_end=1e-3)",
        "mbs run (no --rerun)": f"import sys, tempfile; sys.argv = ['mbs', 'run', {model!r}, '-q', '--t-end', '1ms', "
                                "'-o', tempfile.mktemp(suffix='.h5')]\nfrom planar_mbs.cli.app import main\n"
                                "try: main()\nexcept SystemExit: pass",
    }
    return {name: _modules_after(code) for name, code in cases.items()}


def section_skip() -> dict:
    import planar_mbs as mbs

    out = {}
    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    # nothing stored that no one asked for: all signals vs a few, with an HDF5 file
    tmp = Path(tempfile.mkdtemp())
    for label, sig in (("all signals", None), ("slider and A only", ["slider", "A"])):
        best = math.inf
        for _ in range(3):
            t0 = time.perf_counter()
            r = mbs.simulate(model, output=tmp / "s.h5", signals=sig)
            best = min(best, time.perf_counter() - t0)
        out[label] = dict(total=best, loop=r.attrs["wall_time"], signals=len(r.signals),
                          mbytes=sum(v.nbytes for v in r.signals.values()) / 1e6,
                          file_mbytes=(tmp / "s.h5").stat().st_size / 1e6)
    # outputs: every 10 us vs only the final state (output_step = t_end)
    for label, dt in (("outputs every 10 us", 10e-6), ("outputs every 1 ms", 1e-3), ("only the end", 0.06)):
        best = math.inf
        for _ in range(3):
            r = mbs.simulate(model, output_step=dt)
            best = min(best, r.attrs["wall_time"])
        out[label] = dict(loop=best, rows=len(r.time), steps=r.attrs["n_steps"])
    out["imports"] = imports_table()
    return out


# ---------------------------------------------------------------- scaling
def chain(N, L=0.1, m=0.1):
    """N-link pendulum: uniform bars hinged in series at the origin, released horizontal."""
    sys.path.insert(0, str(ROOT / "tests"))
    import kernel_models as K
    from planar_mbs.mechanism.model import JointType

    bodies = [(m, m * L * L / 12)] * N
    joints = [dict(type=JointType.REVOLUTE, bodies=(-1, 0), points=((0, 0), (-L / 2, 0)))]
    joints += [dict(type=JointType.REVOLUTE, bodies=(i, i + 1), points=((L / 2, 0), (-L / 2, 0))) for i in range(N - 1)]
    km = K.build(bodies, joints=joints, gravity=(0.0, -9.81))
    q0 = np.zeros(3 * N)
    q0[0::3] = L / 2 + L * np.arange(N)
    return km, q0, np.zeros(3 * N)


def section_scaling() -> dict:
    from numba import njit

    from planar_mbs.kernel import make_workspace
    from planar_mbs.kernel.dynamics import rhs
    from planar_mbs.mechanism.model import N_STATS
    sys.path.insert(0, str(ROOT / "tests"))
    import kernel_models as K

    @njit(cache=False)
    def loop(km, cfg, y, contact, ws, stats, ydot, n):
        for i in range(n):
            rhs(km, cfg, 1e-3, y, contact, ws, stats, ydot)

    rows = []
    for N in (2, 5, 10, 20, 50, 100, 200):
        km, q0, qd0 = chain(N)
        cfg = K.cfg()
        y = np.concatenate([q0, qd0])
        contact = np.zeros((0, 3))
        stats = np.zeros(N_STATS, np.int64)
        ydot = np.zeros(2 * 3 * N)
        row = dict(N=N, m=2 * N)
        for label in ("envelope", "dense"):
            ws = make_workspace(km)
            if label == "dense":  # the same code with a full envelope = a dense Cholesky
                ws.first[:] = 0
                ws.lastrow[:] = len(ws.first) - 1
            loop(km, cfg, y, contact, ws, stats, ydot, 2)
            n = max(20, int(200_000 / N ** (1.0 if label == "envelope" else 2.0)))
            best = math.inf
            for _ in range(3):
                t0 = time.perf_counter()
                loop(km, cfg, y, contact, ws, stats, ydot, n)
                best = min(best, (time.perf_counter() - t0) / n)
            row[label] = best * 1e6
        # cost per accepted DOPRI5 step over 0.2 s of the falling chain
        st, _, _, _, stt, _ = K.run(km, q0, qd0, K.cfg(rtol=1e-6, atol=1e-9, output_step=0.05), 0.01)
        t0 = time.perf_counter()
        st, _, _, _, stt, _ = K.run(km, q0, qd0, K.cfg(rtol=1e-6, atol=1e-9, output_step=0.05), 0.2)
        row["per_step"] = (time.perf_counter() - t0) / max(1, stt[0]) * 1e6
        row["steps"] = int(stt[0])
        rows.append(row)
        print(f"  chain N={N}: rhs {row['envelope']:.2f} us (dense {row['dense']:.2f} us), step {row['per_step']:.1f} us",
              flush=True)
    return dict(rows=rows)


def section_stress() -> dict:
    sys.path.insert(0, str(ROOT / "tests"))
    import test_stress as T

    rows = []
    for case in T.CASES:
        r = T.run_case(case)
        rows.append(r)
        print(f"  {r['name']}: {r['outcome']} ({r['wall']:.2f} s)", flush=True)
    long = T.long_run()
    print(f"  1000 revolutions: {long}", flush=True)
    return dict(rows=rows, long=long)


def plots(data) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    images = ROOT / "docs" / "images"
    if "scaling" in data:
        rows = data["scaling"]["rows"]
        N = [r["N"] for r in rows]
        fig, ax = plt.subplots(figsize=(6.5, 4.2))
        ax.loglog(N, [r["dense"] for r in rows], "o--", label="rhs, dense Cholesky (full envelope)")
        ax.loglog(N, [r["envelope"] for r in rows], "s-", label="rhs, envelope Cholesky (library)")
        ax.loglog(N, [r["per_step"] for r in rows], "^-", label="DOPRI5 accepted step (library)")
        ax.loglog(N, [rows[0]["envelope"] * n / N[0] for n in N], ":", color="gray", label="O(N)")
        ax.set_xlabel("bodies N (N-link pendulum)")
        ax.set_ylabel("wall time [us]")
        ax.set_title("Cost per right-hand side and per step vs chain length", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(images / "bench_scaling.png", dpi=110)
        plt.close(fig)
