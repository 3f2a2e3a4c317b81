"""The whole process as users feel it: start-up, sweeps on two cores, output cost, a 40-link chain.

Every target is a *ratio* of two times measured in this one run (the machine is shared,
absolute seconds move from run to run; the ratios much less):

    .venv/bin/python benchmarks/process.py            # prints the table, stores docs/benchmarks_data.json "process"
                                                      # and rewrites that section of docs/benchmarks.md
    .venv/bin/python benchmarks/process.py --only sweep,output   # some parts, printed only
    .venv/bin/python benchmarks/run.py --only process  # the same as the first, and rewrites all of docs/benchmarks.md

Commands are run as separate processes, interleaved round by round (so a burst of load hits
all of them alike), and each time is the median over the rounds.  The package runs as installed:
its modules' byte-code is written first (`byte_compile`), as pip does when it installs a wheel.
"""
from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
PY = sys.executable
MBS = str(Path(PY).with_name("mbs"))
DATA = ROOT / "docs" / "benchmarks_data.json"
RPM5000 = 5000 * 2 * math.pi / 60
REV = 2 * math.pi / RPM5000


def wall(cmd, cwd=None, env=None) -> float:
    """Wall-clock seconds of one process; raises with its stderr if it fails."""
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd, env=env)
    dt = time.perf_counter() - t0
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed ({out.returncode}):\n{out.stderr[-3000:]}")
    return dt


def wall_and_cpu(cmd) -> tuple[float, float]:
    """Wall-clock seconds of one command and the CPU seconds of its whole process tree: this process is
    made a subreaper (prctl PR_SET_CHILD_SUBREAPER), so descendants that outlive the command (a sweep's
    fork server, its workers) are reparented here and reaped, and their CPU time is counted too."""
    import ctypes
    import resource

    ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)  # 36 = PR_SET_CHILD_SUBREAPER
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    dt = wall(cmd)
    while True:  # the orphans of the command, reparented here: wait for their end
        try:
            os.waitpid(-1, 0)
        except ChildProcessError:
            break
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return dt, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def interleaved(cmds: dict[str, list], rounds: int, cwd=None) -> dict[str, float]:
    """Median wall time of each command, run round-robin ``rounds`` times after one warm-up each."""
    for cmd in cmds.values():
        wall(cmd, cwd=cwd)
    times = {k: [] for k in cmds}
    for _ in range(rounds):
        for k, cmd in cmds.items():
            times[k].append(wall(cmd, cwd=cwd))
    return {k: statistics.median(v) for k, v in times.items()}


def exudyn_available() -> bool:
    return subprocess.run([PY, "-c", "import exudyn"], capture_output=True).returncode == 0


# ---------------------------------------------------------------- start-up
def scipy_problem(tmp: Path) -> Path:
    """The scipy baseline's input: parameters and assembled initial state of the clearance model
    (rtol 1e-6, atol 1e-9, 5 revolutions, outputs every 10 µs: the model file's own settings)."""
    out = subprocess.run([PY, "-c", f"""
import sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r})
import numpy as np, planar_mbs as mbs, slider_crank_equations as E
from planar_mbs.mechanism.kinematics import assemble
m = mbs.load_model({str(MODELS / 'slider_crank_clearance_a.mbs')!r})
q, qd = assemble(m)
np.savez({str(tmp / 'problem.npz')!r}, p=E.parameters(m), y0=np.concatenate([q, qd]))
"""], capture_output=True, text=True)
    if out.returncode:
        raise RuntimeError(out.stderr[-3000:])
    return tmp / "problem.npz"


def byte_compile() -> None:
    """Write the byte-code of planar_mbs's modules (``__pycache__``), as pip does when it installs
    the package.  An editable install run with PYTHONDONTWRITEBYTECODE=1 (or from a read-only
    checkout) never writes it, and then every `mbs` process compiles the package's sources again
    (`mbs check`: 1.57× a bare ``import numpy`` instead of 1.29×, docs/benchmarks.md)."""
    import compileall

    compileall.compile_dir(str(ROOT / "planar_mbs"), quiet=1)


def startup(tmp: Path, rounds: int = 7) -> dict:
    clearance = str(MODELS / "slider_crank_clearance_a.mbs")
    cmds = {
        "import numpy": [PY, "-c", "import numpy"],
        "import numba": [PY, "-c", "import numba"],
        "mbs --help": [MBS, "--help"],
        "mbs check": [MBS, "check", clearance],
        "mbs run slider_crank": [MBS, "run", str(MODELS / "slider_crank.mbs"), "-q", "-o", str(tmp / "sc.h5")],
        "mbs run clearance A 5 rev": [MBS, "run", clearance, "-q", "-o", str(tmp / "a.h5")],
        "scipy baseline clearance A 5 rev": [PY, str(ROOT / "benchmarks" / "scipy_baseline.py"), "--problem",
                                             str(scipy_problem(tmp)), "--rtol", "1e-6", "--revolutions", "5",
                                             "-o", str(tmp / "scipy.npz")],
    }
    if exudyn_available():
        cmds["exudyn slider_crank"] = [PY, str(ROOT / "benchmarks" / "exudyn_slider_crank.py")]
    byte_compile()
    t = interleaved(cmds, rounds)
    errors = {}
    if "exudyn slider_crank" in t:
        out = subprocess.run(cmds["exudyn slider_crank"] + ["--error"], capture_output=True, text=True)
        errors["exudyn slider_crank"] = float(out.stdout.strip().splitlines()[-1])
        errors["mbs run slider_crank"] = slider_error(tmp / "sc.h5")
    ratios = {
        "mbs check / import numpy": (t["mbs check"] / t["import numpy"], 2.0, "≤"),
        "mbs --help / import numpy": (t["mbs --help"] / t["import numpy"], 1.5, "≤"),
        "mbs run slider_crank / import numba": (t["mbs run slider_crank"] / t["import numba"], 1.5, "≤"),
        "scipy baseline / mbs run (clearance A, 5 rev, whole process)":
            (t["scipy baseline clearance A 5 rev"] / t["mbs run clearance A 5 rev"], None, "≥"),
    }
    if "exudyn slider_crank" in t:
        ratios["exudyn / mbs run (slider_crank, whole process)"] = (
            t["exudyn slider_crank"] / t["mbs run slider_crank"], None, "≥")
    return dict(times=t, ratios={k: dict(ratio=r, target=g, sense=s) for k, (r, g, s) in ratios.items()},
                rounds=rounds, errors=errors)


def slider_error(path: Path) -> float:
    """max |slider.x - closed form| of an `mbs run models/slider_crank.mbs` results file [m]."""
    import numpy as np

    import planar_mbs as mbs

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from exudyn_slider_crank import closed_form_x

    r = mbs.read_results(path)
    return float(np.max(np.abs(r["slider.x"] - closed_form_x(r.time))))


# ---------------------------------------------------------------- sweeps
def sweep(tmp: Path, rounds: int = 5, revolutions: int = 30) -> dict:
    """8 cases of the clearance slider-crank (speeds 4000..5000 rpm, 30 revolutions each, ~0.15 s of time
    loop; `section_process` also runs them 4× longer, where start-up weighs less), whole `mbs sweep`
    processes, -j 1 and -j 2 in turn: the ratio of the medians, the smallest and largest ratio of a round, the CPU seconds of each command's whole process tree (`cpu_bound`: the
    speed-up -j 2 would have if two cores ran its CPU seconds with no wait at all), and the load average
    before and after (two idle cores are the target's premise: with another busy process, -j 2 has one
    core and cannot be faster)."""
    base = [MBS, "sweep", str(MODELS / "slider_crank_clearance_a.mbs"), "-P", "speed=4000rpm..5000rpm:8",
            "-n", str(revolutions), "--rtol", "1e-6", "--overwrite", "-q"]
    load_before = os.getloadavg()
    for j in ("1", "2"):  # one warm-up each (kernel cache, page cache)
        wall(base + ["-j", j, "-o", str(tmp / f"sweep{j}.h5")])
    times, cpus = {"-j 1": [], "-j 2": []}, {"-j 1": [], "-j 2": []}
    for r in range(rounds):
        for j in ("1", "2"):
            dt, cpu = wall_and_cpu(base + ["-j", j, "-o", str(tmp / f"sweep{j}.h5")])
            times[f"-j {j}"].append(dt)
            cpus[f"-j {j}"].append(cpu)
    t = {k: statistics.median(v) for k, v in times.items()}
    cpu = {k: statistics.median(v) for k, v in cpus.items()}
    per_round = [a / b for a, b in zip(times["-j 1"], times["-j 2"])]
    case = {f"-j {j}": case_seconds(tmp / f"sweep{j}.h5") for j in ("1", "2")}
    return dict(times=t, speedup=t["-j 1"] / t["-j 2"], speedup_min=min(per_round), speedup_max=max(per_round),
                target=1.6, cases=8, revolutions=revolutions, rounds=rounds, case_seconds=case, cpu_seconds=cpu,
                cpu_bound=t["-j 1"] / (cpu["-j 2"] / 2), load=[load_before, os.getloadavg()])


def case_seconds(path: Path) -> float:
    """Mean wall time of one case inside its process (stored by the sweep): equal for -j 1 and -j 2
    when each worker gets a core of its own; larger in the workers when the machine cannot give two."""
    import h5py

    with h5py.File(path, "r") as f:
        return statistics.mean(float(g.attrs["case_wall_time"]) for g in f["cases"].values())


# ---------------------------------------------------------------- in-process: time loop vs scipy, output rows
def loop_vs_scipy(rounds: int = 5) -> dict:
    """Clearance slider-crank A, 5000 rpm, 5 revolutions, rtol 1e-6 (atol 1e-9), outputs every 10 µs: our
    time loop (DOPRI5, best of three per round) against `scipy_baseline.run` (RK45), alternating round by
    round; the ratio of the medians, and the smallest and largest ratio of a round (the load's spread)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import numpy as np

    import planar_mbs as mbs
    import scipy_baseline
    import slider_crank_equations as E
    from planar_mbs.mechanism.kinematics import assemble

    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    t_end, dt = 5 * REV, 10e-6
    q, qd = assemble(model)
    y0, p = np.concatenate([q, qd]), E.parameters(model)
    grid = np.arange(0.0, t_end * (1 + 1e-12), dt)
    ours, theirs = [], []
    for _ in range(rounds):
        ours.append(min(mbs.simulate(model, t_end=t_end, output_step=dt, rtol=1e-6, atol=1e-9,
                                     integrator="dopri5").attrs["wall_time"] for _ in range(3)))
        theirs.append(scipy_baseline.run(y0, p, t_end, grid, method="RK45", rtol=1e-6, atol=1e-9)[2])
    o, t = statistics.median(ours), statistics.median(theirs)
    per_round = [b / a for a, b in zip(ours, theirs)]
    return dict(ours=o, scipy=t, ratio=t / o, ratio_min=min(per_round), ratio_max=max(per_round), rounds=rounds,
                target=100.0)


def loop_stages(scipy_wall: float) -> dict:
    """Where the clearance slider-crank's time loop goes (A, 5000 rpm, 5 revolutions, DOPRI5 rtol 1e-6):
    outputs (the loop with outputs every 10 µs minus the loop with one output at the end), right-hand
    sides (their count times one rhs's cost, measured here against the hand-specialised yardstick), and
    the rest (integrator arithmetic, error control, event location, dense output).  The yardstick is what
    a per-model generated straight-line kernel would at best be, so replacing the library's rhs cost by
    the yardstick's bounds what code generation could bring to the whole loop."""
    import planar_mbs as mbs
    from rhs_cost import section_rhs

    model = mbs.load_model(MODELS / "slider_crank_clearance_a.mbs")
    t_end = 5 * REV

    def best(dt):
        runs = [mbs.simulate(model, t_end=t_end, output_step=dt, rtol=1e-6, atol=1e-9) for _ in range(3)]
        r = min(runs, key=lambda r: r.attrs["wall_time"])
        return r.attrs["wall_time"], r.attrs["n_rhs"], len(r.time), len(r.signals)

    full, n_rhs, rows, signals = best(10e-6)
    end, n_rhs_end, _, _ = best(t_end)
    rhs = section_rhs()
    lib = (rhs["free flight"]["library"] + rhs["contact"]["library"]) / 2 * 1e-6
    hand = (rhs["free flight"]["hand"] + rhs["contact"]["hand"]) / 2 * 1e-6
    stages = {f"outputs (observation of {signals} signals per row)": full - end, "right-hand sides": n_rhs_end * lib,
              "integrator, error control, events, dense output": end - n_rhs_end * lib}
    return dict(loop=full, rows=rows, n_rhs=n_rhs_end, stages=stages, rhs_us=lib * 1e6, hand_us=hand * 1e6,
                scipy=scipy_wall, ratio=scipy_wall / full, ratio_no_outputs=scipy_wall / end,
                ratio_hand_rhs=scipy_wall / (full - n_rhs_end * (lib - hand)))


def output_rows(tmp: Path, rounds: int = 5) -> dict:
    """What one output row costs: the ideal slider-crank, 5 revolutions, outputs every 1 µs (60 001 rows)
    against one row at the end; in the time loop (observation) and in total with an HDF5 file.  Two
    selections: every signal (the default: the row's `accelerations` for the q'' block, the joint
    reactions and the driver's torque), and the bodies' positions and velocities with the system
    signals (the time loop then skips that `accelerations`).  The four runs of a selection are
    interleaved round by round, each time the best of the rounds."""
    import planar_mbs as mbs

    model = mbs.load_model(MODELS / "slider_crank.mbs")
    t_end = 5 * REV
    kinematic = [f"{b}.{q}" for b in model.body_names for q in ("x", "y", "phi", "vx", "vy", "omega")] + ["system"]
    out = {}
    for name, signals in (("all signals", None), ("positions, velocities, system", kinematic)):
        runs = {"loop_few": dict(output_step=t_end), "loop_many": dict(output_step=1e-6),
                "file_few": dict(output_step=t_end, output=tmp / "rows_few.h5"),
                "file_many": dict(output_step=1e-6, output=tmp / "rows.h5")}
        best = {k: (math.inf, math.inf) for k in runs}
        for _ in range(rounds):
            for k, kw in runs.items():
                t0 = time.perf_counter()
                r = mbs.simulate(model, t_end=t_end, signals=signals, **kw)
                best[k] = min(best[k][0], r.attrs["wall_time"]), min(best[k][1], time.perf_counter() - t0)
                if k == "file_many":
                    rows, nsig = len(r.time), len(r.signals)
        out[name] = dict(rows=rows, signals=nsig,
                         loop_us=(best["loop_many"][0] - best["loop_few"][0]) / rows * 1e6,
                         total_us=(best["file_many"][1] - best["file_few"][1]) / rows * 1e6)
    return dict(out, target_us=1.0, rounds=rounds)


# ---------------------------------------------------------------- a 40-link chain as a whole process
def chain_text(n: int, length: float = 0.1, mass: float = 0.1) -> str:
    """A pendulum of n uniform bars hinged in series, released horizontal, under gravity."""
    lines = [f"# {n}-link pendulum chain (benchmark)", "gravity (0, -9.81 m/s^2)"]
    inertia = mass * length * length / 12
    for i in range(n):
        lines.append(f"body b{i} {{ mass = {mass} kg  inertia = {inertia!r} kg*m^2  "
                     f"position = ({length * (i + 0.5)!r}, 0) }}")
    lines.append(f"joint j0 = revolute(ground (0, 0), b0 ({-length / 2!r}, 0))")
    for i in range(1, n):
        lines.append(f"joint j{i} = revolute(b{i - 1} ({length / 2!r}, 0), b{i} ({-length / 2!r}, 0))")
    lines.append("simulate { t_end = 0.5 s  integrator = dopri5  rtol = 1e-6  atol = 1e-9  output_step = 1 ms }")
    return "\n".join(lines) + "\n"


CHAIN_PHASES = r"""
import json, time, sys
T0 = time.perf_counter(); laps = {}
def lap(k, t=[T0]):
    now = time.perf_counter(); laps[k] = now - t[0]; t[0] = now
import planar_mbs as mbs
from planar_mbs import simulation, results, kernel
lap("start-up (imports)")
m = mbs.load_model(sys.argv[1])
from planar_mbs.mechanism.kinematics import assemble
assemble(m)
lap("compile (parse, compile, assemble)")
r = mbs.simulate(m)
lap("first simulate (kernel cache load, loop)")
loop = r.attrs["wall_time"]
t0 = time.perf_counter(); r = mbs.simulate(m); mem = time.perf_counter() - t0
t0 = time.perf_counter(); r = mbs.simulate(m, output=sys.argv[2]); fil = time.perf_counter() - t0
laps["loop"] = r.attrs["wall_time"]
laps["writing"] = max(fil - mem, 0.0)
laps["process"] = time.perf_counter() - T0
print(json.dumps(laps))
"""


def chain40(tmp: Path, n: int = 40) -> dict:
    path = tmp / f"chain{n}.mbs"
    path.write_text(chain_text(n))
    out = subprocess.run([PY, "-c", CHAIN_PHASES, str(path), str(tmp / "chain.h5")], capture_output=True, text=True)
    if out.returncode:
        raise RuntimeError(out.stderr[-3000:])
    laps = json.loads(out.stdout.strip().splitlines()[-1])
    import h5py

    with h5py.File(tmp / "chain.h5", "r") as f:
        nobj = []
        f.visit(nobj.append)
    laps["hdf5 objects"] = len(nobj)
    laps["whole process `mbs run`"] = wall([MBS, "run", str(path), "-q", "-o", str(tmp / "chain_cli.h5")])
    return laps


def section_process(only: set[str] | None = None) -> dict:
    tmp = Path(tempfile.mkdtemp(prefix="mbs_bench_"))
    out = {}
    for name, fn in (("startup", lambda: startup(tmp)), ("sweep", lambda: dict(sweep(tmp), longer=sweep(tmp, rounds=3, revolutions=120))),
                     ("loop_vs_scipy", loop_vs_scipy),
                     ("stages", lambda: loop_stages(out["loop_vs_scipy"]["scipy"])), ("output", lambda: output_rows(tmp)),
                     ("chain40", lambda: chain40(tmp))):
        if only and name not in only:
            continue
        t0 = time.perf_counter()
        out[name] = fn()
        print(f"  {name} ({time.perf_counter() - t0:.0f} s): {json.dumps(out[name], default=str)}", flush=True)
    out["date"] = time.strftime("%Y-%m-%d %H:%M")
    out["load"] = os.getloadavg()
    return out


def main() -> None:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--no-store", action="store_true",
                    help="print only; leave docs/benchmarks_data.json and docs/benchmarks.md alone")
    ap.add_argument("--only", help="comma-separated parts to run, printed only (startup, sweep, loop_vs_scipy, "
                    "stages, output, chain40)")
    args = ap.parse_args()
    if args.only:
        res = section_process(set(args.only.split(",")))
        return
    res = section_process()
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import report

    data = json.loads(DATA.read_text()) if DATA.exists() else {}
    data["process"] = res
    print("\n".join(report.process_table(res)))
    if not args.no_store:  # the numbers and the section written from them, together
        DATA.write_text(json.dumps(data, indent=1))
        report.write_process_section(data)


if __name__ == "__main__":
    main()
