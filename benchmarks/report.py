"""docs/benchmarks.md from docs/benchmarks_data.json (written by benchmarks/run.py)."""
from __future__ import annotations

import statistics
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _g(x, fmt=".3g"):
    return "—" if x is None else format(x, fmt)


def wp_table(sec):
    lines = ["| run | error | time loop [s] | steps | rejected | rhs |", "| --- | ---: | ---: | ---: | ---: | ---: |"]
    for r in sec["rows"]:
        if "error" not in r:
            lines.append(f"| {r['label']} | failed: {r['failed']} | | | | |")
            continue
        ref = " (the reference itself)" if r["error"] < 1e-15 and "floor" in sec else ""
        lines.append(f"| {r['label']}{ref} | {r['error']:.2e} | {r['wall']:.4f} | {r.get('steps', '')} | "
                     f"{r.get('rejected', '')} | {r.get('rhs', '')} |")
    return "\n".join(lines)


def process_table(pr) -> list[str]:
    """The whole-process section: ratios measured in one run (benchmarks/process.py)."""
    st, sw, lv, o, ch = pr["startup"], pr["sweep"], pr["loop_vs_scipy"], pr["output"], pr["chain40"]
    t = st["times"]

    def verdict(r, target, sense):
        if target is None:
            return ""
        ok = r <= target if sense == "≤" else r >= target
        return f"{sense} {target:g}: **{'met' if ok else 'missed'}**"

    out = [f"Medians of {st['rounds']} interleaved rounds for the start-up rows, of {sw['rounds']} for the sweep"
           + (f" ({sw['longer']['rounds']} for its longer cases)" if "longer" in sw else "")
           + f", of {lv['rounds']} for the time loop, best of {o['rounds']} for the output rows.\n",
           "| what | time [s] | against | its time [s] | ratio | target |",
           "| --- | ---: | --- | ---: | ---: | --- |"]
    rows = [("`mbs check models/slider_crank_clearance_a.mbs`", "mbs check", "`python -c \"import numpy\"`",
             "import numpy", "mbs check / import numpy"),
            ("`mbs --help`", "mbs --help", "`python -c \"import numpy\"`", "import numpy", "mbs --help / import numpy"),
            ("warm `mbs run models/slider_crank.mbs`", "mbs run slider_crank", "`python -c \"import numba\"`",
             "import numba", "mbs run slider_crank / import numba")]
    for what, k, against, k2, rk in rows:
        r = st["ratios"][rk]
        out.append(f"| {what} | {t[k]:.3f} | {against} | {t[k2]:.3f} | {r['ratio']:.2f}× | "
                   f"{verdict(r['ratio'], r['target'], r['sense'])} |")
    if "exudyn slider_crank" in t:
        e = st.get("errors", {})
        r = st["ratios"]["exudyn / mbs run (slider_crank, whole process)"]["ratio"]
        out.append(f"| warm `mbs run models/slider_crank.mbs` (slider error {e.get('mbs run slider_crank', 0):.1e} m) | "
                   f"{t['mbs run slider_crank']:.3f} | Exudyn, same mechanism, whole process "
                   f"(error {e.get('exudyn slider_crank', 0):.1e} m) | {t['exudyn slider_crank']:.3f} | "
                   f"Exudyn takes {r:.2f}× | |")
    r = st["ratios"]["scipy baseline / mbs run (clearance A, 5 rev, whole process)"]["ratio"]
    out.append(f"| `mbs run models/slider_crank_clearance_a.mbs` (5 rev, its own rtol 1e-8, HDF5 file) | "
               f"{t['mbs run clearance A 5 rev']:.3f} | scipy baseline, same case at rtol 1e-6, whole process | "
               f"{t['scipy baseline clearance A 5 rev']:.3f} | scipy takes {r:.1f}× | |")
    spread_sw = f" (rounds: {sw['speedup_min']:.2f}–{sw['speedup_max']:.2f}×)" if "speedup_min" in sw else ""
    out.append(f"| `mbs sweep` of {sw['cases']} cases, `-j 2` | {sw['times']['-j 2']:.2f} | `-j 1` | "
               f"{sw['times']['-j 1']:.2f} | {sw['speedup']:.2f}× faster{spread_sw} | "
               f"{verdict(sw['speedup'], sw['target'], '≥')} |")
    if "longer" in sw:
        lg = sw["longer"]
        out.append(f"| … the same cases, {lg['revolutions']} revolutions each, `-j 2` | {lg['times']['-j 2']:.2f} | "
                   f"`-j 1` | {lg['times']['-j 1']:.2f} | {lg['speedup']:.2f}× faster "
                   f"(rounds: {lg['speedup_min']:.2f}–{lg['speedup_max']:.2f}×) | |")
    if "case_seconds" in sw:
        c = sw["case_seconds"]
        out.append(f"| … one case inside a worker of `-j 2` | {c['-j 2']:.2f} | one case in the `-j 1` process | "
                   f"{c['-j 1']:.2f} | {c['-j 2'] / c['-j 1']:.2f}× slower | 1× on two free cores |")
    spread = f" (rounds: {lv['ratio_min']:.0f}–{lv['ratio_max']:.0f}×)" if "ratio_min" in lv else ""
    out.append(f"| time loop, clearance slider-crank (A, 5000 rpm, 5 rev, rtol 1e-6) | {lv['ours']:.4f} | "
               f"scipy baseline's time loop, same settings | {lv['scipy']:.3f} | {lv['ratio']:.0f}× faster{spread} | "
               f"{verdict(lv['ratio'], lv['target'], '≥')}"
               f"{' on the median, not in every round' if lv.get('ratio_min', lv['ratio']) < lv['target'] <= lv['ratio'] else ''}"
               " |")
    for name, sel in o.items():
        if not isinstance(sel, dict):
            continue  # target_us, rounds
        out.append(f"| one output row of `slider_crank.mbs`, {name} ({sel['signals']} signals), in the time loop | "
                   f"{sel['loop_us']:.2f} µs | | | | |")
        out.append(f"| one output row, {name}, in total with the HDF5 file | {sel['total_us']:.2f} µs | | | | "
                   f"≤ {o['target_us']:g} µs: **{'met' if sel['total_us'] <= o['target_us'] else 'missed'}** |")
    if "stages" in pr:
        sg = pr["stages"]
        out.append(f"\nWhere the clearance slider-crank's time loop goes ({sg['loop']:.4f} s, {sg['rows']} output rows, "
                   f"{sg['n_rhs']} rhs; one rhs {sg['rhs_us']:.2f} µs, the hand-specialised yardstick "
                   f"{sg['hand_us']:.2f} µs):\n")
        out.append("| stage | seconds | share |\n| --- | ---: | ---: |")
        for k, v in sg["stages"].items():
            out.append(f"| {k} | {v:.4f} | {v / sg['loop']:.0%} |")
        outputs = next(v for k, v in sg["stages"].items() if k.startswith("outputs"))
        out.append(f"\nAgainst the scipy baseline's time loop: **{sg['ratio']:.0f}×** as measured here (this loop's "
                   "best of three; the table's ratio is a median of rounds); "
                   f"{sg['ratio_no_outputs']:.0f}× with outputs only at the end (scipy's `t_eval` interpolates the state "
                   f"and computes no signals); {sg['ratio_hand_rhs']:.0f}× if every rhs cost what the yardstick costs. "
                   f"The yardstick is what per-model generated straight-line code would at best be: it would take "
                   f"{sg['stages']['right-hand sides'] * (1 - sg['hand_us'] / sg['rhs_us']) / sg['loop']:.0%} off this "
                   f"loop, where the outputs take {outputs / sg['loop']:.0%}. Per-model code generation (one compilation per model, "
                   "cached by a hash of it) was measured through this bound only, not built: the 100× goal rests as "
                   "much on the outputs and the integrator as on the rhs.\n")
    out.append("\n40-link chain (0.5 s, DOPRI5 rtol 1e-6, outputs every 1 ms), one process:\n")
    out.append("| phase | seconds |\n| --- | ---: |")
    for k, v in ch.items():
        out.append(f"| {k} | {v:.3f} |" if isinstance(v, float) else f"| {k} | {v} |")
    return out + process_notes(pr)


PROCESS_HEADING = "## The whole process: start-up, sweeps, output (`benchmarks/process.py`)"


def process_section(data) -> list[str]:
    """The whole-process section of docs/benchmarks.md, heading included, from data["process"]."""
    return [PROCESS_HEADING + "\n", PROCESS_TEXT, *process_table(data["process"]), ""]


def _section_span(text: str, heading: str) -> tuple[int, int] | None:
    """Where the section under ``heading`` lies in ``text`` (from its heading to the next one), or None."""
    start = text.find(heading)
    if start < 0:
        return None
    end = text.find("\n## ", start + len(heading))
    return start, len(text) if end < 0 else end + 1


def write_process_section(data) -> None:
    """Rewrite only the whole-process section of docs/benchmarks.md (from its heading to the next one) from
    ``data``: `benchmarks/process.py` does after each full run, leaving the other sections as they are."""
    path = ROOT / "docs" / "benchmarks.md"
    text = path.read_text()
    start, end = _section_span(text, PROCESS_HEADING)
    path.write_text(text[:start] + "\n".join(process_section(data)) + "\n" + text[end:])


EXPRESSIONS_HEADING = "## Expression loads against built-in elements (`benchmarks/expressions.py`)"
ORDER_HEADING = "## Order of the model text and size (`benchmarks/order_scaling.py`)"
SCAN_HEADING = "## Scans at scale (`benchmarks/scan_scaling.py`)"  # written by hand from that script's output


def _kept_section(heading: str, page: str) -> list[str]:
    """A section this run did not measure, as `page` has it now (its numbers come from a run with its
    own options, e.g. `order_scaling.py --before`), so that regenerating the page never drops it."""
    span = _section_span(page, heading)
    return [page[span[0]:span[1]].rstrip("\n") + "\n"] if span else []


HAND_BEGIN, HAND_END = "<!-- BEGIN hand:{} -->", "<!-- END hand:{} -->"


def _hand(page: str, name: str) -> list[str]:
    """The block of `page` between the markers ``hand:name`` (markers included): prose written by hand
    from a script's output at a date it names, which regenerating the page keeps as it is."""
    begin, end = HAND_BEGIN.format(name), HAND_END.format(name)
    if begin not in page:
        return []
    return [page[page.index(begin):page.index(end) + len(end)] + "\n"]


def write(data) -> None:
    path = ROOT / "docs" / "benchmarks.md"
    path.write_text(render(data, path.read_text() if path.exists() else ""))


def _target_facts(data) -> dict:
    """Verdicts of the targets list that come from the rhs and start-up tables."""
    ratios = [v["ratio"] for v in data["rhs"].values()]
    st = data["startup"]
    return dict(rhs_min=min(ratios), rhs_max=max(ratios), rhs_verdict="met" if max(ratios) <= 2 else "missed",
                help=st["help"], help_verdict="met" if st["help"] < 0.3 else "missed",
                warm=st["run_warm_overhead"], warm_verdict="met" if st["run_warm_overhead"] < 1 else "missed")


def _scipy_ratios(data) -> list[float]:
    return [r["ratio"] for r in data["ratios"]["rows"] if r["baseline"].startswith("scipy") and r.get("ratio")]


def _ratio_facts(data, scipy_ratios) -> dict:
    """The numbers the ratio section's prose states, from the runs: the scipy verdict, RK4 at 1 µs
    against DOP853 at rtol 1e-9, the signals stored and what fewer outputs save (the skip section)."""
    rows = {r["label"]: r for r in data["wp_clearance"]["rows"]}
    rk4, dop = rows["RK4 h=1e-06"], rows["DOP853 rtol=1e-09"]
    met = sum(1 for r in scipy_ratios if r >= 100)
    verdict = "met" if met == len(scipy_ratios) else f"missed on {len(scipy_ratios) - met} of {len(scipy_ratios)} rows"
    skip = data["skip"]
    counts = [rows[r["baseline"]]["rhs"] / rows[r["ours"]]["rhs"] for r in data["ratios"]["rows"]
              if r["baseline"].startswith("scipy") and r.get("ours") and "rhs" in rows.get(r["baseline"], {})]
    cost = [v["numpy"] / v["library"] for v in data["rhs"].values()]
    return dict(scipy_verdict=verdict, count_lo=min(counts), count_hi=max(counts), cost_lo=min(cost),
                cost_hi=max(cost), signals=skip["all signals"]["signals"],
                faster=100 * (1 - skip["outputs every 1 ms"]["loop"] / skip["outputs every 10 us"]["loop"]),
                rk4_error=rk4["error"], gap=rk4["rhs"] / dop["rhs"], dop_rhs=dop["rhs"], rk4_rhs=rk4["rhs"],
                need=rk4["rhs"] / 50, impacts=data["wp_clearance"]["impacts"])


def render(data, page: str = "") -> str:
    """docs/benchmarks.md from the measurements in `data`, keeping `page`'s hand-written blocks and the
    sections other scripts measure."""
    m = data["machine"]
    out = [TEXT_HEAD.format(**m)]
    if "process" in data:
        out.extend(process_section(data))
    if "rhs" in data:
        rhs = data["rhs"]
        out.append("## One right-hand side against the hand-specialised yardstick\n")
        out.append(RHS_TEXT)
        out.append("| state | library [µs] | hand-specialised numba [µs] | ratio | numpy (scipy baseline) [µs] |")
        out.append("| --- | ---: | ---: | ---: | ---: |")
        for k, v in rhs.items():
            out.append(f"| {k} | {v['library']:.3f} | {v['hand']:.3f} | **{v['ratio']:.2f}×** | {v['numpy']:.1f} |")
        out.append(RHS_AFTER)
    if "wp_clearance" in data and "ratios" in data:
        sec = data["wp_clearance"]
        out.append("## Clearance slider-crank (joint A, 5000 rpm): ratios at equal or better error\n")
        out.append(HORIZON_TEXT.format(h_ms=sec["horizon"] * 1e3, h_rev=sec["horizon_rev"], floor=sec["floor"],
                                       tol=sec["agree_tol"], impacts=sec["impacts"]))
        out.append("![divergence](images/bench_clearance_divergence.png)\n")
        out.append("| baseline | its error [m] | its time loop [s] | our fastest run with error ≤ it | error [m] | "
                   "time loop [s] | **ratio** |")
        out.append("| --- | ---: | ---: | --- | ---: | ---: | ---: |")
        for r in data["ratios"]["rows"]:
            if r["ours"] is None:
                out.append(f"| {r['baseline']} | {r['error']:.2e} | {r['wall']:.3f} | none reaches it | | | |")
            else:
                out.append(f"| {r['baseline']} | {r['error']:.2e} | {r['wall']:.3f} | {r['ours']} | "
                           f"{r['ours_error']:.2e} | {r['ours_wall']:.4f} | **{r['ratio']:.0f}×** |")
        sc = _scipy_ratios(data)
        rk = [r["ratio"] for r in data["ratios"]["rows"] if r["baseline"].startswith("RK4") and r.get("ratio")]
        data["_verdict"] = dict(scipy_min=min(sc) if sc else None, scipy_max=max(sc) if sc else None,
                                scipy_median=statistics.median(sc) if sc else None, rk4=rk[0] if rk else None)
        out.append(RATIO_TEXT.format(**data["_verdict"], **_ratio_facts(data, sc)))
        out.append("![clearance work-precision](images/bench_clearance_slider_crank.png)\n")
        out.append("<details><summary>all runs</summary>\n\n" + wp_table(sec) + "\n\n</details>\n")
    out.extend(_hand(page, "friction"))  # benchmarks/friction_cost.py, written by hand from its output
    if "wp_ideal" in data:
        sec = data["wp_ideal"]
        out.append("## Ideal slider-crank against its closed form\n")
        out.append(f"Error: {sec['measure']}.\n")
        out.append("![ideal slider-crank](images/bench_ideal_slider_crank.png)\n")
        out.append("<details><summary>all runs</summary>\n\n" + wp_table(sec) + "\n\n</details>\n")
    if "wp_pendulum" in data:
        sec = data["wp_pendulum"]
        out.append("## Undriven double pendulum against energy conservation\n")
        out.append(f"Error: {sec['measure']}. RK4 below 1 µs is left out (10⁸ steps).\n")
        out.append("![double pendulum](images/bench_double_pendulum.png)\n")
        out.append("<details><summary>all runs</summary>\n\n" + wp_table(sec) + "\n\n</details>\n")
    if "startup" in data:
        s = data["startup"]
        out.append("## Start-up\n")
        out.append("| measurement | seconds |\n| --- | ---: |")
        out.append(f"| `mbs --help` (median of 7) | {s['help']:.3f} |")
        out.append(f"| `mbs run models/slider_crank_clearance_a.mbs` warm cache, everything but the time loop "
                   f"(median of 5) | {s['run_warm_overhead']:.3f} |")
        out.append(f"| … its time loop | {s['run_warm_loop']:.3f} |")
        out.append(f"| first run, empty numba cache (`NUMBA_CACHE_DIR` = new directory): total | "
                   f"{s['run_cold_total']:.1f} |")
        out.append(f"| second run with that `NUMBA_CACHE_DIR`, everything but the time loop | "
                   f"{s['run_cache_dir_second']:.3f} |\n")
        out.extend(_hand(page, "startup"))
        out.append("\nPhases inside one warm process (`mbs run` does the same plus reading its command line and the summary):\n")
        out.append("| phase | seconds |\n| --- | ---: |")
        for k, v in s["phases"].items():
            out.append(f"| {k} | {v:.3f} |")
        out.append(STARTUP_TEXT)
        out.extend(_hand(page, "cache-loading"))
        out.extend(_hand(page, "machinery"))
    if "skip" in data:
        s = data["skip"]
        out.append("## Skipping what a scene does not need\n")
        out.append(SKIP_TEXT)
        out.append("| run (5 revolutions, HDF5 file) | simulate() total [s] | time loop [s] | signals | in memory [MB] | "
                   "file [MB] |\n| --- | ---: | ---: | ---: | ---: | ---: |")
        for k in ("all signals", "slider and A only"):
            v = s[k]
            out.append(f"| {k} | {v['total']:.3f} | {v['loop']:.4f} | {v['signals']} | {v['mbytes']:.1f} | "
                       f"{v['file_mbytes']:.1f} |")
        out.append("\n| outputs | time loop [s] | rows | steps |\n| --- | ---: | ---: | ---: |")
        for k in ("outputs every 10 us", "outputs every 1 ms", "only the end"):
            v = s[k]
            out.append(f"| {k} | {v['loop']:.4f} | {v['rows']} | {v['steps']} |")
        out.append("")
        out.extend(_hand(page, "skip"))
        heavy = list(next(iter(s["imports"].values())).keys())
        out.append("\nModules loaded by each entry point (checked in a fresh subprocess, `sys.modules`; "
                   "also a test, `tests/test_kernel_imports.py`):\n")
        out.append("| entry point | " + " | ".join(heavy) + " |\n| --- |" + " :-: |" * len(heavy))
        for k, v in s["imports"].items():
            out.append(f"| {k} | " + " | ".join("yes" if v[h] else "·" for h in heavy) + " |")
        out.append("")
    if "memory" in data:
        import memory

        out.append("## Memory: peak RSS against the simulated time\n")
        out.append(MEMORY_TEXT)
        out.extend(memory.table(data["memory"]))
        out.append("")
    if "scaling" in data:
        out.append("## Scale: N-link pendulum chains\n")
        out.append(SCALING_TEXT)
        out.append("| N | rows m | rhs, envelope [µs] | rhs, dense [µs] | DOPRI5 step [µs] |\n| ---: | ---: | ---: | ---: | ---: |")
        for r in data["scaling"]["rows"]:
            out.append(f"| {r['N']} | {r['m']} | {r['envelope']:.2f} | {r['dense']:.2f} | {r['per_step']:.1f} |")
        out.append("\n![scaling](images/bench_scaling.png)\n")
    if "order_scaling" in data:
        import order_scaling

        out.append(ORDER_HEADING + "\n")
        out.append(ORDER_TEXT)
        out.append(order_scaling.markdown(data["order_scaling"]) + "\n")
    else:
        out.extend(_kept_section(ORDER_HEADING, page))
    out.extend(_kept_section(SCAN_HEADING, page))
    if "stress" in data:
        s = data["stress"]
        out.append("## Stress tests (`pytest -m slow tests/test_stress.py`)\n")
        out.append("Each case is one crank revolution of `slider_crank_clearance_a.mbs` at its shipped settings "
                   "(DOPRI5, rtol 1e-8) with one parameter changed, except the four-bar.\n")
        out.append("| case | outcome | time [s] | steps | impacts | max penetration / c | max constraint error | "
                   "message |\n| --- | --- | ---: | ---: | ---: | ---: | ---: | --- |")
        for r in s["rows"]:
            pen = r.get("max_penetration_over_c")
            out.append(f"| {r['name']} | {r['outcome']} | {r['wall']:.2f} | {r['steps']} | {r['events']} | "
                       f"{_g(pen)} | {r['max_position_error']:.1e} | {r['message'] if r['outcome'] != 'finished' else ''} |")
        L = s["long"]
        out.append(LONG_TEXT.format(**L))
        out.extend(_hand(page, "stress"))
    out.extend(_kept_section(EXPRESSIONS_HEADING, page))  # benchmarks/expressions.py --write measures it
    out.append(MISSED_TEXT.format(**data.get("_verdict", {}), **_ratio_facts(data, _scipy_ratios(data)),
                                  **_target_facts(data)))
    return "\n".join(out) + "\n"


MEMORY_TEXT = """`benchmarks/memory.py`: `mbs run models/slider_crank_clearance_a.mbs --t-end T` at the model's own
output step (10 µs, 54 columns in these runs; the model has 56 now), each run its own process, its peak resident set size from the kernel
(`os.wait4`). A run streams its rows to the HDF5 file and the `Results` it returns reads them back
lazily, so the peak does not grow with T: target, the 100-s run within 1.2× the 1-s run.

Target **met: the 100-s run peaks at 1.04× the 1-s run** (on two idle cores, below).  The summary
printed after a run asks `"system.position_error" in res.signals`; the lazily read `Results` answers
that from the names, where Python's default `Mapping.__contains__` would read the whole signal (80 MB
for 10^7 rows; `tests/adversarial/test_memory.py` shows it needs no file at all).
""" + "\n"


PROCESS_TEXT = """Users feel the whole process, not the time loop. Each row is a ratio of two times measured in the
same run of `benchmarks/process.py` (separate processes, interleaved round by round, medians), because the
machine is shared and only ratios taken together mean something.  Exudyn (`pip install -e '.[bench]'`) runs the
same ideal slider-crank as `benchmarks/exudyn_slider_crank.py` (its row is in the table only when Exudyn was
installed for the run); the scipy baseline runs as a script of its own
(`benchmarks/scipy_baseline.py`, numpy and scipy only).  The table below is written from that run's numbers in
`docs/benchmarks_data.json` ("process"), measured on the machine named at the top.

What keeps the start-up short: `mbs check` loads neither numba (the
initial pose is assembled by the constraint kernels' source run as plain Python, `planar_mbs.pykernel`), nor
pint (units from a table of our own, each entry tested against pint; pint only for other unit names), nor typer
(a plain `mbs check MODEL [--set ...]` bypasses it: typer's argument handling imports pydantic); a plain
`mbs run MODEL [OPTIONS]` bypasses typer too (its options are read by `planar_mbs/cli/run_options.py` from the same table the typer command is generated from; any other command line still goes to typer).
A cached kernel loads without numba's target-context refresh, which imported every implementation numba has
(scipy.linalg among them) and compiled its reference-counting runtime, none of which the kernels' machine code
calls (`kernel/jit.py`), and without parsing its linking bitcode (0.8 MB for the time loop, 40–60 ms), which numba
needs only to compile another function against it: the symbols come from the object file's symbol table.  The modules defining typer commands do not postpone their annotations; a command that
only prints ends without the interpreter's teardown, as `run` does; a run prints its summary and warnings as
plain lines and loads rich (about 20 ms) only for a progress bar or an error; the CLI keeps BLAS on one thread.
`benchmarks/process.py` writes the package's byte-code before its rounds, as pip does at install (an editable
install under `PYTHONDONTWRITEBYTECODE=1` compiles every module in every process: `mbs check`
1.57× instead of 1.29×).  Results files keep one compound dataset per entity instead of one per signal (a 40-link
chain: 83 HDF5 objects instead of 568 groups and datasets).

Sweeps: `mbs sweep` on several cores starts multiprocessing's fork server at its first line, preloaded with
numba and the kernels (`planar_mbs.sweep.server`, `planar_mbs.sweep.worker`), so they load on the other core
while the command line is read and the cases are checked; the pool's workers are forks of that server, and the
sweep's own process never loads numba (from Python, `run_sweep` loads them itself and forks its workers from
itself).  Each worker writes its case in a file of its own beside the sweep file, into disk
space reserved first (the sweep's journal), and hands back only the table row; the parent gathers the journal
into the scan file with HDF5's object copy (about 6 ms for a 19 MB case) instead of receiving cases through a pipe.  Cases are stored uncompressed (gzip saved
~20 % of float64 outputs for ~20× the write time).  The model text of a sweep is parsed once per process
(`parse.PARSED_CACHE`), not once for the parent's check of each case and again in each case.

Output rows: the time loop computes only the groups of the observation row that the kept signals read
(`simulate(..., signals=[...])`, `signals.skip_bits`): without the bodies' accelerations, the joint reactions and
the driver efforts, an output row makes no `accelerations` call of its own.  The results writer gathers each
entity's records straight into buffers kept between writes, so HDF5 writes them without a conversion (a strided
view had cost about 0.1 µs per row and entity), and `simulate` lets the time loop write its rows into the ~8 MB
block that goes to the file next, in whole HDF5 chunks, which go to the file straight (`H5Dwrite_chunk`: HDF5's
ordinary write copies each chunk into its chunk buffer first).
"""


def _longer(sw) -> str:
    """The sentence part on the same sweep with longer cases, when this run measured it."""
    lg = sw.get("longer")
    if not lg:
        return ""
    return (f" (the same 8 cases at {lg['revolutions']} revolutions each, where the start weighs a quarter as much: "
            f"`-j 2` {lg['speedup']:.2f}× faster than `-j 1`)")


def process_notes(pr) -> list[str]:
    """What remains, with this run's numbers (`process_table` prints the table itself)."""
    out = ["", "What remains:\n"]
    help_ratio = pr.get("startup", {}).get("ratios", {}).get("mbs --help / import numpy", {})
    if help_ratio and help_ratio["ratio"] > help_ratio["target"] - 0.3:  # met or not, it sits near the line
        t = pr["startup"]["times"]
        out.append(f"* `mbs --help` takes {help_ratio['ratio']:.2f}× a bare `import numpy` here ({t['mbs --help']:.3f} s "
                   f"against {t['import numpy']:.3f} s; target ≤ {help_ratio['target']:g}×).  It sits on the "
                   "line: runs of this script have given 1.23–1.60× as numpy's own import took 0.083–0.124 s.  "
                   "typer renders "
                   "its help with rich: `typer.rich_utils` imports `rich.markdown` (with markdown_it and pygments) "
                   "and `rich.traceback` (with attrs), which help text in typer's \"rich\" markup never uses: "
                   "about 0.05 of the 0.13 s (`python -X importtime`).  Loading `Markdown` lazily was asked of "
                   "typer upstream (a comment on fastapi/typer pull request 1128, 2025-09); typer 0.29.2 still "
                   "imports it.  Help without them here would mean replacing typer's renderer with our own copy "
                   "of it, or plain click help; neither was done.")
    run_ratio = pr.get("startup", {}).get("ratios", {}).get("mbs run slider_crank / import numba", {})
    if run_ratio and run_ratio["ratio"] > run_ratio["target"]:
        t = pr["startup"]["times"]
        out.append(f"* A warm `mbs run models/slider_crank.mbs` takes {run_ratio['ratio']:.2f}× a bare `import numba` "
                   f"here ({t['mbs run slider_crank']:.3f} s against {t['import numba']:.3f} s; target ≤ "
                   f"{run_ratio['target']:g}×): what the run adds to numba's import (h5py, lark, loading the time loop's "
                   "machine code: about 0.17 s) weighs more the quicker numba's own import is on the machine.")
    o = pr.get("output", {})
    sel = {k: v for k, v in o.items() if isinstance(v, dict)}
    if "all signals" in sel and sel["all signals"]["total_us"] >= o.get("target_us", 1.0):
        a = sel["all signals"]
        cheap = [f"{k} ({v['signals']} signals) {v['total_us']:.2f} µs" for k, v in sel.items() if k != "all signals"]
        out.append(f"* An output row of every signal ({a['signals']}) costs {a['total_us']:.2f} µs with the HDF5 "
                   f"file, {a['loop_us']:.2f} µs of it in the time loop: a row lies on the dense output between "
                   "steps, where no integrator stage was evaluated, so its accelerations, reactions and driver "
                   "efforts need one `accelerations` call (a Schur factorisation and solve) of their own, and "
                   f"packing and writing its columns to the file {a['total_us'] - a['loop_us']:.2f} µs more.  Rows "
                   "under 1 µs hold for signals that need no accelerations: " + ", ".join(cheap) + ".")
    sw = pr.get("sweep", {})
    if "cpu_seconds" in sw:
        cpu1, cpu2 = sw["cpu_seconds"]["-j 1"], sw["cpu_seconds"]["-j 2"]
        out.append(f"* `mbs sweep -j 2` is {sw['speedup']:.2f}× faster than `-j 1` on {sw['cases']} cases of about "
                   f"{sw['case_seconds']['-j 1']:.2f} s each" + _longer(sw) + ".  The bound is the work, not the "
                   f"scheduling: the whole process tree of `-j 2` used {cpu2:.2f} CPU seconds against {cpu1:.2f} "
                   f"for `-j 1` (counted in every process, the fork server and the workers included), and two "
                   f"cores cannot run {cpu2:.2f} CPU seconds in less than {cpu2 / 2:.2f} s, so `-j 2` could be at "
                   f"most {sw['cpu_bound']:.2f}× faster here even with no wait at all.  The extra "
                   f"{cpu2 - cpu1:.2f} CPU seconds are the pool's own: a second interpreter that imports numpy, "
                   "h5py, the compiler and numba again (the sweep's process needs the first three too), "
                   "multiprocessing's resource tracker, and each case written to its own file by its worker and "
                   "copied into the sweep file by the parent (17 MB a case; about 30 ms of CPU in all per case).  "
                   "Reaching 1.6× on cases this short needs a cheaper way for a case's signals into the file, not "
                   "a better pool.  Traced (timestamps in every process, idle cores): the fork "
                   "server has the kernels 0.38–0.39 s after the command starts (0.09 s for the command's "
                   "interpreter to start the server's, 0.29 s of imports and cache loads), the sweep's process is "
                   "ready to hand out cases at 0.29–0.31 s, the 8 cases then take 0.72 s on the two workers, and "
                   "the sweep ends 0.04 s after its last case.  Each worker keeps the memory of its finished cases "
                   "(`planar_mbs.sweep.worker.keep_freed_memory`): with glibc's defaults the freed arrays go back to "
                   "the kernel after every case and the next case maps and zeroes them afresh (9,000–10,000 page "
                   "faults and 15 ms in each 0.15-s case, 31,000–38,000 in each 0.6-s case of 120 revolutions); 10 "
                   "interleaved pairs of `-j 2` on the 8 short cases took 1.29 s against 1.33 s with glibc's "
                   "defaults.  These sweep rows were measured with every signal of each case stored (as `--keep all` "
                   "stores them); cases stored small, the default (section, verdict, summary), were not measured here.")
    return out + [""]


TEXT_HEAD = """# Benchmarks: speed against accuracy, start-up, scale, stress

Everything on this page but three sections is regenerated by one command (10–15 minutes); the
sections on the order of the model text, on scans at scale and on expression loads, and the blocks
written by hand, come from the scripts they name and are kept as they are:

    .venv/bin/python benchmarks/run.py                  # all sections
    .venv/bin/python benchmarks/run.py --only rhs,startup   # some; the others keep their last numbers

Its numbers are in `docs/benchmarks_data.json`, figures in `docs/images/bench_*.png`.
Machine: {cpu}, {cores} cores, {system}; Python {python}, numpy {numpy}, numba {numba}, scipy {scipy}.
All times are wall-clock seconds of the **time loop** (`simulate`'s `wall_time`: the compiled `advance` calls, including
the outputs it writes), best of three (one run for RK4 below 1 µs, and at 1 µs for the 10-s pendulum; the scipy runs once each).  Tolerances: `atol = 1e-3 rtol`.
"""

RHS_TEXT = """The yardstick `benchmarks/slider_crank_equations.py::rhs_hand` hard-codes the slider-crank with the
clearance at A: the same Baumgarte-stabilised equations and Lankarani–Nikravesh law, every Jacobian and Schur
entry written out from the known sparsity, a 7×7 Cholesky on scratch arrays. Both are called 200 000 times from
a numba loop on the same state; the library's and the numpy version's results agree with it to 1e-12.
"""

RHS_AFTER = """
**Target (≤ 2×): missed.** Where the library's time goes (measured piece by piece, contact state, ns,
when the right-hand side took 0.555 µs): the
cosines/sines of the three bodies ~90 (the yardstick needs two bodies: the slider's angle is constrained to 0),
the generic constraint rows ~185 (per-joint branches on type codes, zeroing the row-sparse Jacobian, the
driver's motion law), forming and factoring the 7×7 Schur complement from the row-sparse Jacobian ~105, the
two triangular solves ~60, forces and contact ~100. The yardstick does the same arithmetic in straight-line
code with everything in registers. The library already computes the trigonometry of each body once per rhs,
not once per joint point (6 calls instead of 22), keeps a row-sparse Jacobian `J (m, 2, 3)` instead of a
dense `m × n` one (no 63-entry zeroing and dense products), and factors the Schur complement in its envelope
(below). What would
close the rest: code generation per model (emit and compile the yardstick's straight-line code from the
`Model`), at the price of one compilation per model instead of one cached kernel for all models.
"""

HORIZON_TEXT = """Reference: DOP853 at rtol 1e-12. Two tighter references (DOP853 1e-13 and 1e-14) are run with it over
five revolutions; the **horizon is the time up to which all three agree within {tol:g} m** (journal
eccentricity): **{h_ms:.2f} ms = {h_rev:.2f} revolutions**, with {impacts} impacts. After that the references
themselves separate: every impact multiplies a difference in the state (the next impact's time and velocity depend
on where the journal was), so a rounding-level difference grows by orders of magnitude per revolution — the
figure shows it. Errors below the reference floor ({floor:.1e} m, the largest disagreement of the references
inside the horizon) are not resolved. Error measure: the largest distance between the computed and the reference
journal eccentricity vector of joint A over the horizon, outputs every 20 µs.
"""

RATIO_TEXT = """
Baselines, measured in the same run: Muvengei et al.'s way (fixed-step RK4 at 1 µs, our compiled kernel, with our event
location) and `benchmarks/scipy_baseline.py`: `scipy.integrate.solve_ivp` (RK45 and DOP853) with the right-hand
side written in numpy and the contact handled the way solve_ivp allows — terminal events on the penetration,
restarted with the other mode, impact velocity from the event state, and `max_step = 10 µs` (without it
solve_ivp's steps jump over whole free flights and the journal leaves the bearing unseen; with 50 µs it still
missed re-contacts after short bounces).

**Targets.** *≥100× faster than scipy at equal or better error: {scipy_verdict}* — measured
{scipy_min:.0f}× to {scipy_max:.0f}× (median {scipy_median:.0f}×). The ratio is the cost of one rhs (numpy and
Python against compiled code: {cost_lo:.0f}–{cost_hi:.0f}× in the rhs table above) times the ratio of rhs counts at
equal error, here {count_lo:.2g}× to {count_hi:.2g}× as many for scipy (its `max_step` and its restart at every event), less
what our loop spends beside the rhs.  In this chaotic regime a run's error is decided by how well it resolves every
impact, so both codes need many evaluations for any error.
Errors here are also noisy (one impact more or less resolved changes a run's error by 10×, so "equal error"
pairs are partly luck, e.g. scipy RK45 at rtol 1e-5 happens to land at 4e-5). Our time loop also computes all {signals}
output signals (accelerations, reactions, energies) at every output, which scipy's `t_eval` does not: with
outputs every 1 ms instead of 10 µs our loop takes {faster:.0f} % less time (section "Skipping" below).
*≥50× faster than RK4 at 1 µs: missed* — measured {rk4:.1f}×. Why: RK4 at 1 µs is not
cheap-and-inaccurate here, it is accurate to {rk4_error:.1e} m over the horizon, and to match that error an adaptive
method must resolve all the impacts in the horizon as well as 1 µs steps do. During an impact the contact force
`K δ^1.5` has an unbounded second derivative at δ = 0 and lasts tens of µs, so adaptive steps there are µs-sized
anyway (most rejected steps are at these onsets/separations, not at the restart after an event: restarting with
Hairer's initial-step estimate changed nothing). The adaptive methods save only in free flight. The gap in rhs
evaluations is {gap:.1f}× (DOP853 at rtol 1e-9: {dop_rhs:,} rhs vs {rk4_rhs:,} for RK4 1 µs), and both use the same compiled
rhs, so a faster rhs does not change the ratio. A 50× ratio would need about {need:,.0f} rhs for {impacts} impacts at
{rk4_error:.0e} m accuracy.
"""

STARTUP_TEXT = """
`mbs --help` imports typer and the CLI only; `mbs check` neither typer (a plain `check MODEL [--set ...]` command
line bypasses it: typer's argument handling imports pydantic) nor numba (assembly runs the constraint kernels'
source as plain Python, `planar_mbs.pykernel`) nor pint (units come from our own table, checked against pint
entry by entry; pint is imported only for a unit outside it).  The warm `mbs run` overhead is mostly numba:
importing it, and on the first compiled call loading the kernels from its cache, without numba's target-context
refresh (so no `scipy.linalg`: `kernel/jit.py`).
"""

SKIP_TEXT = """* **No clearance joint → no contact code**: `accelerations` skips the contact loop when `nclearance = 0`, the
  time loop skips event location.
* **Journals in free flight → no contact force work**: a joint in free-flight mode costs one comparison per rhs
  (see the rhs table: free flight vs contact). DOP853's 7th-order dense output needs three extra stages; they are
  computed only for steps that hold an output time or where a cheap cubic-Hermite screening of the penetration
  (no extra stage) sees a possible mode change.
* **Nothing stored that no one asked for**: `simulate(..., signals=[...])` keeps only the named signals or
  entities in memory and in the file, and the (compiled) observation computes only the groups they read:
  without the bodies' accelerations, joint reactions and driver efforts, no `accelerations` per output row
  (`signals.skip_bits`); the output step decides how often the observation runs.
* **No heavy import in a command that does not use it**: see the table at the end of this section.
"""

SCALING_TEXT = """Each constraint row touches at most two bodies, so the Schur complement `S = Cq M⁻¹ Cqᵀ` couples two
rows only when they share a body: for a chain it is block-tridiagonal. The library stores the Jacobian row-sparse
(`J (m, 2, 3)`) and factors `S` in its *envelope* (profile Cholesky: no fill outside it), which is exact for any
topology and O(N) for chains. "dense" is the same code with the envelope set to the full matrix, i.e. a dense
Cholesky (O(N³)).
"""

ORDER_TEXT = """The IFToMM "N four-bar" chain (`tests/chains.py`: 2N + 1 bars, 3N + 1 revolute joints, closed loops)
with the same joints written along the chain, reversed, grouped by kind (all ground pins first) and shuffled.
The constraint rows are placed at compile time by reverse Cuthill-McKee on the body-joint graph
(`planar_mbs/mechanism/ordering.py`), so the four texts compile to the same row order and the same envelope: at N = 40
the slowest text costs 1.01 times the fastest (target ≤ 1.3), and the cost per right-hand side grows linearly
from 41 to 321 bodies, closed loops included (target: within 1.5 times linear).  Measured on two idle
cores; `.venv/bin/python benchmarks/order_scaling.py` prints these tables and writes
`docs/order_scaling_data.json`.  Cost per accepted DOPRI5 step [µs] (0.2 s from the top,
rtol 1e-8), then cost per right-hand side from 41 to 321 bodies (linear would be 321/41 = 7.83 times).
"""

LONG_TEXT = """
**1000 crank revolutions** (5000 rpm, 12 s, clearance at A, projection on, DOPRI5 at the model's rtol 1e-8): {steps} steps,
{events} impacts, time loop {wall:.1f} s; largest constraint error **{max_position_error:.1e}** (bound 1e-8),
largest velocity-constraint error {max_velocity_error:.1e}; energy balance: the driver's work minus the change of
the mechanism's energy is the energy the contacts dissipated, {dissipated:.1f} J at the end, never below
{min_dissipated:.1e} J (quadrature of the driver power on the 20 µs output grid) — no energy is created.
"""

MISSED_TEXT = """## Targets: met and missed

* scipy baseline ≥100× at equal error: **{scipy_verdict}** (ratio table: {scipy_min:.0f}× to {scipy_max:.0f}×): the
  rhs-cost ratio times the ratio of rhs counts, explained above.
* RK4 at 1 µs ≥50×: **missed** (ratio table) — bound by impact resolution, explained above.
* one rhs ≤2× the hand-specialised rhs: **{rhs_verdict}** ({rhs_min:.1f}–{rhs_max:.1f}×, rhs table) — generic code vs
  straight-line code.
* `mbs --help` < 0.3 s: **{help_verdict}** ({help:.3f} s). Warm `mbs run` overhead < 1 s: **{warm_verdict}** ({warm:.3f} s,
  start-up table); numba's import, the kernel modules and their cache load are about half of it (phases table).
* Whole-process ratios (check, --help, warm run, sweeps, output rows, time loop vs scipy): see the first section's
  table, with its verdicts, measured in one run.
* Scale: per-rhs cost linear in N with the envelope factorisation (dense: cubic) — **met**.
* Translational clearance at the slider within 2× the revolute clearance slider-crank at the same tolerance:
  **met** (`benchmarks/translational_clearance.py`, 20 revolutions at 2500 rpm, rtol 1e-8: 0.64 s against
  0.79 s, 0.81×; at 5000 rpm 0.42 s against 0.41 s, 1.03×; one rhs with four corner pairs costs 1.35–1.48×
  one with a journal, but the run needs 0.60–0.70× the rhs).
* Stress: every case finishes or stops with a message; 1000 revolutions with projection keep the constraint error
  below 1e-8 and create no energy — **met**.
"""
