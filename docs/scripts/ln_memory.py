"""The memory of the Lankarani–Nikravesh law: one speed, a family of permanent-contact orbits.

    .venv/bin/python docs/scripts/ln_memory.py [--state build/replication/long_A_207GPa_5000rpm.npz]

Starts from a state of clearance A, 207 GPa, 5000 rpm in permanent contact (the end of a long
run: the saved state of docs/scripts/replication_runs.py, or a run until it settles), replaces
the stored impact velocity of the contact by each of a range of values, runs 60 revolutions and
records where the section lands.  Writes docs/images/contact_ln_memory.png and
docs/contact_ln_memory.json.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

STORED = [1e-4, 3e-4, 1e-3, 3e-3, 0.01, 0.02, 0.0315, 0.05, 0.1, 0.2, 0.5, 1.0]
REVOLUTIONS = 60
SETTINGS = {"rtol": 1e-8, "atol": 1e-11}


def start_state(path: Path | None):
    from planar_mbs import load_model
    from planar_mbs.run.study import long_run

    model = load_model(ROOT / "models" / "slider_crank_clearance_a.mbs")
    if path and path.exists():
        d = np.load(path)
        return model, d["y"], d["contact"], float(d["clock"][0])
    run = long_run(model, 1500, 8, until_settled=True)
    st = run.stepper
    return model, st.y, st.contact, st.t


def main(state: Path | None) -> dict:
    from planar_mbs.results.section import driver_period
    from planar_mbs.run.stepper import Stepper

    model, y, contact, t0 = start_state(state)
    T = driver_period(model)[0]
    if contact[0, 0] < 0.5:
        raise SystemExit("the start state is not in contact")
    out = {"start_impact_velocity": float(contact[0, 1]), "t0": t0, "revolutions": REVOLUTIONS, "cases": []}
    for v in STORED:
        c = contact.copy()
        c[0, 1] = v
        st = Stepper.restore(model, y, c, t0, output_step=T / 64, **SETTINGS)
        t, rows = st.run_to(t0 + REVOLUTIONS * T)
        sig = st.signals(rows)
        on = sig["A.in_contact"]
        k = (t - t0) / T
        at = np.nonzero(np.abs(k - np.round(k)) < 1e-6)[0]  # the section: output times t0 + kT
        sec = sig["slider.vx"][at]
        last = slice(len(t) - 65, len(t))
        case = {"stored": v, "final_stored": float(st.contact[0, 1]), "permanent": bool(np.all(on > 0.5)),
                "section_vx": sec[-10:].tolist(), "section_ax": sig["slider.ax"][at][-10:].tolist(),
                "ex": sig["A.ex"][last].tolist(), "ey": sig["A.ey"][last].tolist(),
                "max_penetration": float(np.max(sig["A.penetration"]))}
        out["cases"].append(case)
        print(f"stored {v:g} m/s -> final {case['final_stored']:.4g}, permanent {case['permanent']}, "
              f"section vx {sec[-1]:+.4f} m/s (spread over the last 10: {np.ptp(sec[-10:]):.1e})", flush=True)
    (ROOT / "docs" / "contact_ln_memory.json").write_text(json.dumps(out, indent=1))
    figure(out)
    return out


def figure(out: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(10.5, 4.4), constrained_layout=True)
    for c in out["cases"]:
        settled = np.ptp(c["section_vx"]) < 1e-4
        a.semilogx([c["final_stored"]], [c["section_vx"][-1]], "o" if settled else "x",
                   color="tab:blue" if c["permanent"] else ("tab:green" if settled else "tab:red"))
    a.plot([], [], "o", color="tab:blue", label="periodic, in contact throughout")
    a.plot([], [], "o", color="tab:green", label="periodic after new impacts")
    a.plot([], [], "x", color="tab:red", label="not periodic after 60 rev")
    a.axvline(out["start_impact_velocity"], color="0.6", lw=0.8, ls="--")
    a.set_xlabel("stored impact velocity δ̇⁽⁻⁾ at the end [m/s]")
    a.set_ylabel("slider.vx at the Poincaré section [m/s]")
    a.set_title("A, 207 GPa, 5000 rpm: one permanent-contact orbit per stored velocity\n"
                "(dashed: the 1000-revolution run's own)", fontsize=9)
    a.legend(fontsize=7)
    a.grid(True, lw=0.3)
    shown = [c for c in out["cases"] if np.ptp(c["section_vx"]) < 1e-4][:4]
    for c in shown:
        b.plot(np.array(c["ex"]) * 1e3, np.array(c["ey"]) * 1e3, lw=0.8,
               label=f"δ̇⁽⁻⁾ = {c['final_stored']:.3g} m/s")
    th = np.linspace(0, 2 * np.pi, 200)
    b.plot(0.3 * np.cos(th), 0.3 * np.sin(th), "k", lw=0.5)
    b.set_aspect("equal")
    b.set_xlabel("A.ex [mm]")
    b.set_ylabel("A.ey [mm]")
    b.set_title("journal centre over the last revolution of periodic cases\n(circle: the 0.3 mm clearance)",
                fontsize=9)
    b.legend(fontsize=7)
    fig.savefig(ROOT / "docs" / "images" / "contact_ln_memory.png", dpi=110)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--state", type=Path, default=ROOT / "build" / "replication" / "long_A_207GPa_5000rpm.npz")
    ap.add_argument("--draw", action="store_true", help="only redraw from docs/contact_ln_memory.json")
    args = ap.parse_args()
    if args.draw:
        figure(json.loads((ROOT / "docs" / "contact_ln_memory.json").read_text()))
    else:
        main(args.state)
