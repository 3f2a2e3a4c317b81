"""The long runs behind docs/replication.md (run by docs/scripts/replicate.py, cached in --work).

Each job is one case of the paper's study (joint, Young's modulus, speed) run for a number of
crank revolutions; its section signals and final kernel state go to ``<work>/<job>.npz``, so the
Lyapunov exponents can start from the settled state.  Jobs that are done are skipped.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

MODELS = {"A": ROOT / "models" / "slider_crank_clearance_a.mbs", "B": ROOT / "models" / "slider_crank_clearance_b.mbs"}
PER_REV = 8
LONG_SETTINGS = {"rtol": 1e-6, "atol": 1e-9}  # the long runs; a tighter rtol is checked on the main cases


def kept(joint: str) -> list[str]:
    return ["slider.vx", "slider.ax", "crank.phi", f"{joint}.ex", f"{joint}.ey", f"{joint}.contact_force",
            f"{joint}.in_contact", f"{joint}.impact_velocity"]


def job_name(kind: str, joint: str, modulus: str, speed: str, law: str = "lankarani_nikravesh") -> str:
    tail = "" if law == "lankarani_nikravesh" else f"_{law}"
    return f"{kind}_{joint}_{modulus}_{speed}{tail}"


def git_commit() -> str:
    try:
        return subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return "unknown"


def run_long(work: Path, kind: str, joint: str, modulus: str, speed: str, revolutions: int,
             settings: dict | None = None, law: str = "lankarani_nikravesh") -> str:
    """One long run; writes <work>/<name>.npz.  ``kind`` "long" (`LONG_SETTINGS`) or
    "tight" (``settings``, e.g. a tighter rtol)."""
    from planar_mbs import load_model
    from planar_mbs.errors import SimulationError
    from planar_mbs.run.study import long_run

    work.mkdir(parents=True, exist_ok=True)
    name = job_name(kind, joint, modulus, speed, law)
    out = work / f"{name}.npz"
    if out.exists():
        return f"{name}: cached"
    model = load_model(MODELS[joint], speed=speed, youngs_modulus=modulus, law=law)
    start, cpu = time.perf_counter(), time.process_time()
    status = "finished"
    try:
        run = long_run(model, revolutions, PER_REV, kept(joint), **(settings or LONG_SETTINGS))
        res, st, settled = run.results, run.stepper, run.settled_at
    except SimulationError as err:
        return f"{name}: FAILED {err}"
    meta = {"joint": joint, "modulus": modulus, "speed": speed, "law": law, "revolutions": run.revolutions,
            "period": run.period, "settings": {k: str(v) for k, v in (settings or {}).items()},
            "rtol": float(st.settings.rtol), "atol": float(st.settings.atol), "integrator": st.settings.integrator.name,
            "wall": time.perf_counter() - start, "cpu": time.process_time() - cpu, "commit": git_commit(),
            "status": status, "settled_at": settled, "n_steps": int(st.stats[0])}
    np.savez_compressed(out.with_suffix(".tmp.npz"), time=res.time, **{k: v for k, v in res.signals.items()},
                        y=st.y, contact=st.contact, clock=st.clock, stats=st.stats, meta=json.dumps(meta))
    os.replace(out.with_suffix(".tmp.npz"), out)
    return f"{name}: {run.revolutions} rev, settled at {settled}, {meta['cpu']:.0f} s cpu"


def main(jobs: list[tuple], work: Path, processes: int = 2) -> None:
    from concurrent.futures import ProcessPoolExecutor, as_completed

    work.mkdir(parents=True, exist_ok=True)
    with ProcessPoolExecutor(processes) as ex:
        futs = {ex.submit(run_long, work, *job): job for job in jobs}
        for f in as_completed(futs):
            try:
                print(time.strftime("%H:%M:%S"), f.result(), flush=True)
            except Exception as err:  # noqa: BLE001  (report and go on with the others)
                print(time.strftime("%H:%M:%S"), futs[f], "ERROR", repr(err), flush=True)


LYAP_SETTINGS = {"integrator": "dop853", "rtol": 1e-10, "atol": 1e-13}
LYAP_REVOLUTIONS, LYAP_PER_REV, LYAP_SEEDS, LYAP_D0 = 60, 16, 5, 1e-6


def _from_long_run(work: Path, kind: str, joint: str, modulus: str, speed: str, law: str):
    """(job name, its output path, the long run's saved arrays, their meta, the model) for a job that starts
    from the final state of a long run; a message instead when the job is done or the long run is not."""
    from planar_mbs import load_model

    name = job_name(kind, joint, modulus, speed, law)
    out = work / f"{name}.json"
    src = work / f"{job_name('long', joint, modulus, speed, law)}.npz"
    if out.exists():
        return f"{name}: cached"
    if not src.exists():
        return f"{name}: no long run yet"
    d = np.load(src)
    model = load_model(MODELS[joint], speed=speed, youngs_modulus=modulus, law=law)
    return name, out, d, json.loads(str(d["meta"])), model


def run_lyapunov(work: Path, joint: str, modulus: str, speed: str, law: str = "lankarani_nikravesh") -> str:
    """Benettin exponents from the final state of the long run: LYAP_SEEDS perturbed companions
    (d0 = LYAP_D0), one more at d0/100 to show whether the estimate depends on d0."""
    from planar_mbs.errors import SimulationError
    from planar_mbs.run.lyapunov import mechanism_exponent
    from planar_mbs.run.stepper import Stepper

    start = _from_long_run(work, "lyap", joint, modulus, speed, law)
    if isinstance(start, str):
        return start
    name, out, d, meta, model = start
    T = meta["period"]
    cpu = time.process_time()
    runs = []
    for seed, d0 in [(s, LYAP_D0) for s in range(LYAP_SEEDS)] + [(0, LYAP_D0 / 100)]:
        st = Stepper.restore(model, d["y"], d["contact"], float(d["clock"][0]), output_step=T / LYAP_PER_REV,
                             **LYAP_SETTINGS)
        try:
            e = mechanism_exponent(st, T, LYAP_REVOLUTIONS, d0=d0, seed=seed, per_rev=LYAP_PER_REV)
            runs.append({"seed": seed, "d0": d0, "value": e.value, "logs": e.logs.tolist(), "discard": e.discard})
        except SimulationError as err:
            runs.append({"seed": seed, "d0": d0, "value": None, "error": str(err)})
    res = {"runs": runs, "settings": LYAP_SETTINGS, "revolutions": LYAP_REVOLUTIONS, "per_rev": LYAP_PER_REV,
           "from_revolution": meta["revolutions"], "cpu": time.process_time() - cpu, "commit": git_commit()}
    out.write_text(json.dumps(res))
    vals = [r["value"] for r in runs[:LYAP_SEEDS] if r["value"] is not None]
    return f"{name}: {np.mean(vals):.3g} ± {np.std(vals):.2g} per period, {res['cpu']:.0f} s cpu"


FLOQUET_PERIODS, FLOQUET_EPS, FLOQUET_SETTLE = (1, 2, 3, 4), (1e-6, 1e-5), 10


def run_floquet(work: Path, joint: str, modulus: str, speed: str, law: str = "lankarani_nikravesh") -> str:
    """Floquet exponents (`planar_mbs.run.lyapunov.floquet_exponent`) of the orbit the long run ended
    on, after FLOQUET_SETTLE more periods at the Lyapunov settings, over each of FLOQUET_PERIODS periods
    and with each difference step of FLOQUET_EPS: replicate.py shows the one of the verdict's period
    (a chaotic case's closure shows that it has none)."""
    from planar_mbs.errors import SimulationError
    from planar_mbs.run.lyapunov import floquet_exponent
    from planar_mbs.run.stepper import Stepper

    start = _from_long_run(work, "floquet", joint, modulus, speed, law)
    if isinstance(start, str):
        return start
    name, out, d, meta, model = start
    T = meta["period"]
    cpu = time.process_time()
    st = Stepper.restore(model, d["y"], d["contact"], float(d["clock"][0]), output_step=T / LYAP_PER_REV,
                         **LYAP_SETTINGS)
    runs = []
    try:
        st.run_to(st.t + FLOQUET_SETTLE * T)
        for periods in FLOQUET_PERIODS:
            for eps in FLOQUET_EPS:
                f = floquet_exponent(st, T, periods, eps=eps)
                runs.append({"periods": periods, "eps": eps, "value": f.value, "closure": f.closure,
                             "moduli": np.abs(f.multipliers).tolist()})
    except SimulationError as err:
        runs.append({"error": str(err)})
    res = {"runs": runs, "settings": LYAP_SETTINGS, "settle": FLOQUET_SETTLE, "cpu": time.process_time() - cpu,
           "commit": git_commit()}
    out.write_text(json.dumps(res))
    return f"{name}: {len(runs)} maps, {res['cpu']:.0f} s cpu"


def main_lyapunov(cases: list[tuple], work: Path) -> None:
    for case in cases:
        for attempt in range(240):  # wait for the long run of the case
            msg = run_lyapunov(work, *case)
            if not msg.endswith("no long run yet"):
                break
            time.sleep(30)
        print(time.strftime("%H:%M:%S"), msg, flush=True)
        print(time.strftime("%H:%M:%S"), run_floquet(work, *case), flush=True)


def continue_run(work: Path, kind: str, joint: str, modulus: str, speed: str, more: int,
                 law: str = "lankarani_nikravesh") -> str:
    """Continue a finished long run from its saved state by ``more`` revolutions, with the same
    settings; writes <name>_cont.npz (read back after the run by replicate.load_run)."""
    from planar_mbs import load_model
    from planar_mbs.run.stepper import Stepper

    name = job_name(kind, joint, modulus, speed, law)
    src, out = work / f"{name}.npz", work / f"{name}_cont.npz"
    if out.exists() or not src.exists():
        return f"{name}: continuation cached or no run"
    d = np.load(src)
    meta = json.loads(str(d["meta"]))
    model = load_model(MODELS[joint], speed=speed, youngs_modulus=modulus, law=law)
    T = meta["period"]
    st = Stepper.restore(model, d["y"], d["contact"], float(d["clock"][0]), output_step=T / PER_REV,
                         rtol=meta["rtol"], atol=meta["atol"], t_end=(meta["revolutions"] + more) * T)
    cpu = time.process_time()
    times, rows = [], []
    for k in range(meta["revolutions"] + 10, meta["revolutions"] + more + 1, 10):
        t, r = st.run_to(k * T)
        times.append(t)
        rows.append(r)
    sig = st.signals(np.concatenate(rows))
    meta.update(revolutions=meta["revolutions"] + more, cpu=meta["cpu"] + time.process_time() - cpu,
                continued_from=meta["revolutions"])
    np.savez_compressed(out, time=np.concatenate(times), **{k: sig[k] for k in kept(joint)}, y=st.y,
                        contact=st.contact, clock=st.clock, stats=st.stats, meta=json.dumps(meta))
    return f"{name}: continued to {meta['revolutions']} revolutions"
