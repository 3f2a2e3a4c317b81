"""Numbers the pages of docs/ state about the program, checked against the program: a page whose
number drifts from what the program gives fails here."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

import planar_mbs as mbs

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "models" / "slider_crank_clearance_a.mbs"


def test_the_complete_model_of_the_language_page_is_the_shipped_one():
    """docs/language.md §11 says its model is shipped as models/slider_crank_clearance_a.mbs: the same
    settings (integrator, tolerances, output step, end time) and values of the parameters it shows."""
    text = (ROOT / "docs" / "language.md").read_text(encoding="utf-8")
    section = text[text.index("## 11. A complete model"):text.index("## 12.")]
    block = re.search(r"```mbs\n(.*?)```", section, re.S)[1]
    page, shipped = mbs.compile_text(block, "page.mbs"), mbs.load_model(SHIPPED)
    assert page.settings == shipped.settings
    assert {k: shipped.parameters.get(k) for k in page.parameters} == page.parameters


def test_the_plots_page_states_the_shipped_tolerance():
    """docs/plots.md's performance section names the tolerance the model ships with."""
    text = (ROOT / "docs" / "plots.md").read_text(encoding="utf-8")
    stated = float(re.search(r"it now ships with rtol (\S+?) --", text)[1])
    assert stated == mbs.load_model(SHIPPED).settings.rtol


def test_the_poincare_count_of_the_plots_page():
    """docs/plots.md: the shipped model run as the page runs it (`--t-end 0.36s`, 30 revolutions at
    5000 rpm) gives the number of Poincaré points the page states, and the page's revolutions are
    the run's."""
    from planar_mbs.results import views as P

    text = (ROOT / "docs" / "plots.md").read_text(encoding="utf-8")
    assert "mbs run models/slider_crank_clearance_a.mbs -o a_5000.h5 --t-end 0.36s" in text
    revolutions, points = (int(n) for n in re.search(
        r"The Poincaré map \((\d+) revolutions, the first dropped, so (\d+) points\)", text).groups())
    res = mbs.simulate(mbs.load_model(SHIPPED), t_end="0.36 s", output_step="100 us")
    assert revolutions == round(0.36 * 5000 / 60)
    assert len(P.poincare(res, "slider.vx", "slider.ax").t) == points


def test_contact_events_and_onsets_in_the_samples():
    """docs/plots.md: the run's contact events (onsets the integrator located) against the onsets
    seen in the output samples: equal at a fine output step, fewer at a coarse one, as the page says
    (its numbers are these)."""
    from planar_mbs.results import views as P

    text = (ROOT / "docs" / "plots.md").read_text(encoding="utf-8")
    events, fine, coarse = (int(n) for n in re.search(
        r"(\d+) events, and\s+(\d+) onsets in the samples at a 10 µs output step, (\d+) at 100 µs", text).groups())
    model = mbs.load_model(SHIPPED)
    for step, onsets in (("10 us", fine), ("100 us", coarse)):
        res = mbs.simulate(model, t_end="24 ms", output_step=step)  # two revolutions at 5000 rpm
        assert res.attrs["n_contact_events"] == events
        assert len(P.contact_onsets(res, "A")) == onsets


def test_the_readme_poincare_count():
    """README: the first command (60 revolutions of the shipped model) draws a Poincaré map of the
    number of points it states."""
    from planar_mbs.results import views as P

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "--revolutions 60" in text.split("```")[1]  # the first command
    points = int(re.search(r"a Poincaré map of (\d+) points", text)[1])
    res = mbs.simulate(mbs.load_model(SHIPPED), revolutions=60, per_rev=90)
    assert len(P.poincare(res, "slider.vx", "slider.ax").t) == points


def test_the_python_block_of_the_plots_page_runs(tmp_path, monkeypatch):
    """docs/plots.md "From Python": its block runs as written on a run's file, draws the figures it
    names, and matplotlib is imported only once a figure is drawn."""
    import subprocess
    import sys

    from planar_mbs.results.section import driver_period

    text = (ROOT / "docs" / "plots.md").read_text(encoding="utf-8")
    block = re.search(r"### From Python\n\n```python\n(.*?)```", text, re.S)[1]
    revolutions, points = (int(n) for n in re.search(
        r"slider-cranks with clearance\s+stop after (\d+) revolutions, which leaves (\d+) points", text).groups())
    model = mbs.load_model(SHIPPED)
    assert round(model.settings.t_end / driver_period(model)[0], 9) == revolutions
    monkeypatch.chdir(tmp_path)
    mbs.simulate(model, output="a.h5")
    probe = "import sys, planar_mbs.outputs.plot\nassert 'matplotlib' not in sys.modules\n"
    done = subprocess.run([sys.executable, "-c", probe + block + f"\nassert len(ps.t) == {points}\n"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "orbit.pdf").stat().st_size > 0 and list((tmp_path / "figs").glob("a_slider.ax*.png"))


def test_the_tolerance_table_of_numerics_is_the_scripts_data_and_the_programs():
    """docs/numerics.md "Tolerances of the shipped models": the table is the one docs/scripts/tolerances.py
    prints from docs/tolerances_data.json (its shipped rtol read from the models), and the data's row of
    `slider_crank_clearance_a.mbs` at its shipped rtol is what the program gives now (error and steps)."""
    import json
    import sys

    import numpy as np

    sys.path.insert(0, str(ROOT / "docs" / "scripts"))
    import tolerances as T

    data = json.loads((ROOT / "docs" / "tolerances_data.json").read_text(encoding="utf-8"))
    assert T.table(data) in (ROOT / "docs" / "numerics.md").read_text(encoding="utf-8")
    name = SHIPPED.name
    rtol = mbs.load_model(SHIPPED).settings.rtol
    row = next(r for r in data[name]["rows"] if r["rtol"] == rtol)
    ref, _, _ = T.one(name, "slider.vx", None, 1e-12, 1e-15, "dop853")
    v, _, steps = T.one(name, "slider.vx", None, rtol, rtol * 1e-3)
    assert steps == row["steps"]
    assert float(np.max(np.abs(v - ref)) / np.max(np.abs(ref))) == pytest.approx(row["error"], rel=1e-6)


def _laws_table(text: str) -> dict[tuple[str, str], list[float]]:
    block = text[text.index("<!-- BEGIN generated:laws -->"):text.index("<!-- END generated:laws -->")]
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in block.splitlines()[3:]]
    return {(r[0], r[1]): [float(c) for c in r[2:]] for r in rows}


def test_the_peaks_of_the_laws_on_the_replication_page_are_the_programs():
    """docs/replication.md §III.B: the peaks of clearance A for every law over revolutions 2-5 (5000 rpm,
    207 GPa, 1440 samples per revolution, as docs/scripts/replicate.py --short makes them) are what the
    program gives now, and the ratios the page's claims quote are those of its table."""
    text = (ROOT / "docs" / "replication.md").read_text(encoding="utf-8")
    table = _laws_table(text)
    titles = {"hertz": "Hertz", "dubowsky_freudenstein": "Dubowsky–Freudenstein", "esdu78035": "ESDU-78035",
              "lankarani_nikravesh": "Lankarani–Nikravesh"}
    for law, title in titles.items():
        res = mbs.simulate(mbs.load_model(SHIPPED, law=law), revolutions=5, per_rev=1440,
                           signals=["slider.ax", "A.contact_force", "crank_speed.torque"])
        late = res.time >= 60 / 5000 * (1 - 1e-9)  # from the end of the first revolution
        got = [abs(res["slider.ax"][late]).max(), res["A.contact_force"][late].max(),
               abs(res["crank_speed.torque"][late]).max()]
        assert [float(f"{g:.4g}") for g in got] == table[("A", title)], law
    span = r"([\d.]+)–([\d.]+)×"
    quoted = re.search(rf"peak ax {span} lower at A, {span} at B; peak torque {span} lower at A, {span} at B",
                       text).groups()
    ratios = []
    for column in (0, 2):
        for joint in "AB":
            ln = table[(joint, "Lankarani–Nikravesh")][column]
            r = [table[(joint, t)][column] / ln for t in ("Hertz", "Dubowsky–Freudenstein", "ESDU-78035")]
            ratios += [f"{min(r):.1f}", f"{max(r):.1f}"]
    assert list(quoted) == ratios


def test_the_long_run_tables_of_the_replication_page_are_its_data(monkeypatch):
    """docs/replication.md: the verdicts, the claims (those on the laws too) and the bifurcation table are what
    docs/scripts/replicate.py renders from docs/replication_data.json (the runs' numbers), so no number of
    those tables was typed or left behind by an edit; every Benettin exponent of a periodic case is
    negative and within a factor 2 of its Floquet exponent (the two methods of run/lyapunov.py)."""
    import json
    import sys

    monkeypatch.syspath_prepend(str(ROOT / "docs" / "scripts"))
    replicate = __import__("replicate")
    text = (ROOT / "docs" / "replication.md").read_text(encoding="utf-8")
    data = json.loads((ROOT / "docs" / "replication_data.json").read_text(encoding="utf-8"))
    blocks = {**replicate.case_tables(data), "laws_claims": replicate.laws_claims(data["laws"])}
    for name, body in blocks.items():
        block = text[text.index(f"<!-- BEGIN generated:{name} -->\n"):text.index(f"<!-- END generated:{name} -->")]
        assert block.split("\n", 1)[1].rstrip("\n") == body, name
    periodic = [c for c in data["cases"] if c["class"] == "periodic"]
    assert periodic
    for c in periodic:
        b, f = c["benettin"]["mean"], c["floquet"]["values"]["1e-06"]
        assert b < 0 and f < 0 and 0.5 < b / f < 2, (c["joint"], c["E"], c["speed"])
    sys.modules.pop("replicate", None)


def test_the_hdf5_layout_of_the_signals_page_is_the_files(tmp_path):
    """docs/signals.md "HDF5 layout of one run": the attributes it lists are those of a run's file, and
    the chain it counts has the entity datasets and signals it states."""
    import sys

    import h5py

    sys.path.insert(0, str(ROOT / "tests"))
    from chains import pendulum_chain

    text = (ROOT / "docs" / "signals.md").read_text(encoding="utf-8")
    block = text[text.index('attributes of "/":'):text.index("```", text.index('attributes of "/":'))]
    names = [line.split("  ")[1] for line in block.splitlines()[1:] if re.match(r"  [a-z]", line)]
    listed = {name for column in names for name in re.findall(r"[a-z_]+", column)}
    out = tmp_path / "a.h5"
    mbs.simulate(mbs.load_model(SHIPPED), t_end="1 ms", output=str(out))
    with h5py.File(out) as f:
        plain = set(f.attrs)
    kept = tmp_path / "kept.h5"  # the page: `allow_unphysical` only where the run was asked to keep such results
    mbs.simulate(mbs.load_model(SHIPPED), t_end="1 ms", output=str(kept), allow_unphysical=True)
    with h5py.File(kept) as f:
        assert set(f.attrs) - plain == {"allow_unphysical"} and bool(f.attrs["allow_unphysical"])
    assert listed == plain | {"allow_unphysical"}
    bars, datasets, signals = (int(n) for n in re.search(
        r"a pendulum chain of (\d+) bars has (\d+) entity datasets\n?.*?not (\d+)\.", text, re.S).groups())
    mbs.simulate(mbs.compile_text(pendulum_chain(bars)), t_end="1 ms", output=str(out))
    with h5py.File(out) as f:
        assert len(f["signals"]) == datasets
        assert sum(len(f["signals"][k].dtype.names) for k in f["signals"]) == signals


def test_the_measured_column_of_validation_is_the_programs():
    """docs/validation.md, the paper's slider-crank rows: the errors it quotes as measured (slider x, vx,
    ax and the crank torque against their closed forms, 2 revolutions, DOPRI5 rtol 1e-10) are what the
    run of tests/test_simulation.py gives now, to the two digits shown."""
    import sys

    import numpy as np

    sys.path.insert(0, str(ROOT / "tests"))
    import test_simulation as T

    text = (ROOT / "docs" / "validation.md").read_text(encoding="utf-8")
    rows = [re.search(rf"\| {re.escape(start)}.*?\| ([\d.e-]+)(?: m/s| m)? \| `?(?:test_simulation\.py`|〃)", text)[1]
            for start in ("paper's slider-crank, 2 revolutions", "… slider vx", "… slider ax", "… crank torque")]
    t_end = 2 * 2 * np.pi / T.OMEGA
    res = mbs.simulate(mbs.load_model(T.MODELS / "slider_crank.mbs"), t_end=t_end, rtol=1e-10, integrator="dopri5",
                       output_step=t_end / 400)
    ref, torque = T.slider_crank_closed_form(res.time), T.inverse_dynamics_torque(res.time)
    got = [np.max(np.abs(res["slider.x"] - ref["x"])), np.max(np.abs(res["slider.vx"] - ref["vx"])),
           np.max(np.abs(res["slider.ax"] - ref["ax"])) / np.max(np.abs(ref["ax"])),
           np.max(np.abs(res["crank_speed.torque"] - torque)) / np.max(np.abs(torque))]
    assert [f"{g:.1e}" for g in got] == [f"{float(r):.1e}" for r in rows]


def test_the_counts_of_the_ln_memory_study_are_its_data():
    """docs/contact.md, "The Lankarani–Nikravesh law has a memory": the number of stored velocities and of
    those ending on a periodic orbit (section points equal to 1e-5 m/s over the last 10 revolutions), and
    the stored values after new impacts, are those of docs/contact_ln_memory.json (docs/scripts/ln_memory.py)."""
    import json

    import numpy as np

    text = (ROOT / "docs" / "contact.md").read_text(encoding="utf-8")
    data = json.loads((ROOT / "docs" / "contact_ln_memory.json").read_text(encoding="utf-8"))["cases"]
    counts = re.search(r"Of the (\d+) stored velocities, (\d+) end on a periodic", text).groups()
    total, periodic = (int(n) for n in counts)
    settled = [c for c in data if np.ptp(c["section_vx"]) <= 1e-5]
    assert (total, periodic) == (len(data), len(settled))
    renewed = re.search(r"close the contact with a new stored value\s+\(([\d., ]+) m/s\)", text)[1]
    assert renewed.split(", ") == [f"{c['final_stored']:.3g}" for c in settled if not c["permanent"]]


def _short(x: float) -> str:
    """1.5e-8, as the pages write it (not 1.5e-08)."""
    return re.sub(r"e([-+])0*(\d)", r"e\1\2", f"{x:.1e}").replace("e+", "e")


def test_the_singular_passage_numbers_of_numerics_are_the_programs(monkeypatch):
    """docs/numerics.md, the N = 2 parallelogram chain (20 s, rtol 1e-12) as docs/scripts/singular_passages.py
    runs it: the crank-tip errors with and without the kinetic energy given back, the energy lost without it
    and the energy error with it, and the crank-tip errors at rtol 1e-13, for DOPRI5 and DOP853, are the
    page's."""
    import sys

    sys.path.insert(0, str(ROOT / "docs" / "scripts"))
    import singular_passages as S

    monkeypatch.delenv("PLANAR_MBS_SOLVER", raising=False)
    err, energy, tighter = {}, {}, {}
    for restore in (False, True):
        for integrator in ("dopri5", "dop853"):
            with monkeypatch.context() as m:
                m.setenv("PLANAR_MBS_SOLVER", "")  # restored by the context whatever S.run sets
                _, e, de, _ = S.run(integrator, restore)
                if restore:
                    tighter[True, integrator] = _short(S.run(integrator, restore, rtol=1e-13)[1].max())
            err[restore, integrator], energy[restore, integrator] = _short(e.max()), _short(abs(de[-1]))
    text = (ROOT / "docs" / "numerics.md").read_text(encoding="utf-8")
    pair = lambda d, r: f"{d[r, 'dopri5']} / {d[r, 'dop853']}"  # noqa: E731
    assert f"| the orthogonal projection alone: `ε` = 1e-8, 2 sweeps | {pair(err, False)} |" in text
    assert f"| **kinetic energy given back after the projection (shipped)** | **{pair(err, True)}** |" in text
    assert f"({energy[False, 'dopri5']} J over 20 s with DOPRI5, {energy[False, 'dop853']} J with DOP853, N = 2)" \
        in text
    assert f"| {pair(err, True)} | {pair(tighter, True)} | {pair(energy, True).replace(' /', ' J /')} J of 35.8 J |" in text



def test_the_chain_table_of_numerics_is_the_programs(monkeypatch):
    """docs/numerics.md, the table of parallelogram chains N = 1, 3, 5, 10 (N = 2: the test above), run as
    docs/scripts/singular_passages.py runs N = 2 (20 s, projection on, atol = rtol / 100, the kinetic energy
    given back): every cell the page fills, DOPRI5 / DOP853, against the exact motion of `tests/chains.py`."""
    import sys

    sys.path.insert(0, str(ROOT / "docs" / "scripts"))
    import singular_passages as S

    monkeypatch.delenv("PLANAR_MBS_SOLVER", raising=False)
    columns = (1e-10, 1e-11, 1e-12, 1e-13)
    filled = {1: (1e-12,), 3: (1e-10, 1e-11, 1e-13), 5: (1e-10, 1e-11, 1e-13), 10: (1e-12,)}
    text = (ROOT / "docs" / "numerics.md").read_text(encoding="utf-8")
    for n, rtols in filled.items():
        monkeypatch.setattr(S, "N", n)
        cells, energy = [""] * len(columns), ""
        for rtol in rtols:
            runs = [S.run(integrator, True, rtol=rtol) for integrator in ("dopri5", "dop853")]
            cells[columns.index(rtol)] = " / ".join(_short(r[1].max()) for r in runs)
            if n == 10:
                energy = " / ".join(_short(abs(r[2][-1])) + " J" for r in runs) + " of 158.9 J"
        row = "|" + "|".join(f" {cell} " if cell else " " for cell in (f"N = {n}", *cells, energy)) + "|"
        assert row in text, row

def test_the_longest_shipped_model_of_the_language_page():
    """docs/language.md §12 names the longest shipped model and its size in names, numbers and symbols
    (with its included files, as the parser counts them against its limit): the largest, to within 10 %."""
    from planar_mbs.language import parse as P

    text = (ROOT / "docs" / "language.md").read_text(encoding="utf-8")
    name, stated = re.search(r"the longest shipped model, `([\w.]+)`, about (\d+)\)", text).groups()
    sizes = {}
    for path in (ROOT / "models").glob("*.mbs"):
        left, files = [10**9], [path]
        while files:
            source = files.pop().read_text(encoding="utf-8")
            P._check_tokens(source, None, str(path), left)
            files += [path.parent / inc for inc in re.findall(r'^include "([^"]+)"', source, re.M)]
        sizes[path.name] = 10**9 - left[0]
    assert max(sizes, key=sizes.get) == name
    assert abs(sizes[name] - int(stated)) <= 0.1 * int(stated)


def test_the_readme_layout_is_the_packages_stages():
    """README "Layout": the folders of planar_mbs/ in the order of the layering tests/test_imports.py
    checks (each imports only from those before it), and every folder of the package named."""
    import sys

    sys.path.insert(0, str(ROOT / "tests"))
    from test_imports import STAGES

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = text[text.index("## Layout"):text.index("Documentation (in `docs/`)")]
    named = re.findall(r"^  (\w+)(?:/|\.py)", block, re.M)
    folders = {p.name for p in (ROOT / "planar_mbs").iterdir() if (p / "__init__.py").exists()}
    assert folders <= set(named), folders - set(named)
    assert [s for s in named if s in folders] == [s for s in STAGES if s in folders]


def test_the_integrator_orders_of_validation_are_measured():
    """docs/validation.md's table of measured convergence orders: a row for every integrator of the
    catalog, each slope the one the convergence test measures (to the two decimals shown)."""
    from test_kernel_integrators import measured_order

    from planar_mbs import catalog

    text = (ROOT / "docs" / "validation.md").read_text(encoding="utf-8")
    section = text[text.index("## Integrators"):]
    section = section[:section.index("\n## ", 5)]
    rows = {m[1]: float(m[2]) for m in re.finditer(r"^\| (\w+) \| (\d+\.\d+)", section, re.M)}
    assert sorted(rows) == sorted(s.name.upper() for s in catalog.INTEGRATORS)
    for spec in catalog.INTEGRATORS:
        assert rows[spec.name.upper()] == round(measured_order(spec)[0], 2), spec.name


def test_the_benchmarks_page_is_what_its_generator_writes(monkeypatch):
    """docs/benchmarks.md is written by benchmarks/report.py from docs/benchmarks_data.json, keeping the
    blocks written by hand (marked) and the sections other scripts measure: rendering it again from the
    data gives the page unchanged, so a hand edit outside the marked blocks, or a generator text the page
    no longer has, fails here (the page's numbers then come from the data, not from an edit)."""
    import json

    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    import report

    page = (ROOT / "docs" / "benchmarks.md").read_text(encoding="utf-8")
    data = json.loads((ROOT / "docs" / "benchmarks_data.json").read_text(encoding="utf-8"))
    assert report.render(data, page) == page
