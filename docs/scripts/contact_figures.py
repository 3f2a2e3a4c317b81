"""Regenerate the figures and the single-impact table of docs/contact.md.

    .venv/bin/python docs/scripts/contact_figures.py            # figures + table (markdown on stdout)

A journal (0.2 kg) flies at 0.5 m/s into Muvengei et al.'s bearing (R_B = 5 mm, c = 0.3 mm,
L = 20 mm, steel 207 GPa, stiffness of Muvengei et al. eq. 18), fixed to ground; no gravity.  The same
.mbs text runs every law at restitution 0.9 and 0.5 (the text goes through the compiler and
the compiled time loop, as `mbs run` does).  Writes docs/images/contact_hysteresis.png and
prints the effective-restitution table (rebound / impact speed) with the exact value of the
Hunt-Crossley family, chi (1 + e) = ln((1 + chi) / (1 - chi e)).
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from planar_mbs import catalog  # noqa: E402
from planar_mbs.mechanism.compile import compile_text  # noqa: E402
from planar_mbs.kernel.contact import damping_factor  # noqa: E402
from planar_mbs.mechanism.model import CONTACT_LAW_NAMES, ContactLaw  # noqa: E402

V0 = 0.5
MODEL = """
# one radial impact of a free journal in a ground bearing (docs/contact.md)
param law = hertz
param restitution = 0.9
material steel {{ E = 207 GPa  nu = 0.3 }}
body journal {{ mass = 0.2 kg  inertia = 1e-5 kg*m^2  position = (0, 0)  velocity = ({v0} m/s, 0) }}
joint J = clearance_revolute(ground (0, 0), journal (0, 0)) {{
    clearance = 0.3 mm  bearing_radius = 5 mm  length = 20 mm  material = steel
    law = law  restitution = restitution
}}
simulate {{ t_end = {t_end} s  integrator = dopri5  rtol = 1e-10  atol = 1e-14  output_step = {dt} s }}
"""
LABELS = {ContactLaw(spec.code): spec.title for spec in catalog.LAWS}
# the laws of one stiffness from the materials (eq. 18); Kelvin-Voigt's K is linear and given (its impact:
# docs/contact.md, "The Kelvin-Voigt law")
LAWS = [law for law in ContactLaw if catalog.LAWS[int(law)].group is not catalog.LINEAR]
STYLE = {
    ContactLaw.HERTZ: ("k", "-"), ContactLaw.DUBOWSKY_FREUDENSTEIN: ("0.45", "--"), ContactLaw.ESDU_78035: ("0.65", ":"),
    ContactLaw.LANKARANI_NIKRAVESH: ("tab:blue", "-"), ContactLaw.HUNT_CROSSLEY: ("tab:orange", "-"),
    ContactLaw.FLORES: ("tab:green", "-"), ContactLaw.GONTHIER: ("tab:red", "-"),
}


def one_impact(law: ContactLaw, ce: float, t_end=1.2e-3, dt=2e-7):
    text = MODEL.format(v0=V0, t_end=t_end, dt=dt)
    model = compile_text(text, str(ROOT / "models" / "impact.mbs"),
                         {"law": CONTACT_LAW_NAMES[law], "restitution": str(ce)})
    res = run_free(model)
    assert res.attrs["complete"] and res.attrs["n_contact_events"] == 1, res.attrs
    inside = res["J.contact_force"] > 0
    i0 = np.argmax(inside)
    i1 = i0 + np.argmin(inside[i0:])
    # pad one sample on each side (zero force) so the loop closes on the axis
    sl = slice(max(i0 - 1, 0), i1 + 1)
    e = -res["journal.vx"][-1] / V0
    return res["J.penetration"][sl], res["J.contact_force"][sl], e


class _Run:
    def __init__(self, signals, attrs):
        self.signals, self.attrs = signals, attrs

    def __getitem__(self, name):
        return self.signals[name]


def run_free(model):
    """Run the compiled time loop from the model's own initial state.  (`simulate` would first
    assemble the initial state with every clearance joint closed, as Muvengei et al. starts its
    mechanisms, which stops a free journal; here the journal must fly into the wall.)"""
    from planar_mbs.kernel import advance, make_workspace, nobs
    from planar_mbs.mechanism.model import N_STATS, ST_CONTACT_EVENTS, Status
    from planar_mbs.results.signals import signal_table

    km, s = model.kernel, model.settings
    cfg = s.cfg()
    y = np.concatenate([model.q0, model.qd0]).astype(float)
    clock = np.zeros(3)
    contact = np.zeros((model.nclearance, 3))
    stats = np.zeros(N_STATS, np.int64)
    cap = int(s.t_end / s.output_step) + 3
    out_t, out = np.zeros(cap), np.zeros((cap, nobs(km)))
    st, n = advance(km, cfg, y, clock, contact, stats, make_workspace(km), s.t_end, out_t, out)
    rows = out[:n]
    signals = {sig.name: sig.extract(rows) for sig in signal_table(model)}
    return _Run(signals, {"complete": st == Status.DONE, "n_contact_events": int(stats[ST_CONTACT_EVENTS])})


def restitution_exact(chi: float) -> float:
    from scipy.optimize import brentq

    if chi == 0:
        return 1.0
    return brentq(lambda e: chi * (1 + e) - math.log((1 + chi) / (1 - chi * e)), 1e-15,
                  min(1.0, (1 - 1e-15) / chi), xtol=1e-16, rtol=1e-15)


def main():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for ax, ce in zip(axes, (0.9, 0.5)):
        for law in LAWS:
            d, F, e = one_impact(law, ce)
            color, ls = STYLE.get(law, (f"C{int(law) % 10}", "-."))  # a law added later: a default style
            ax.plot(d * 1e6, F * 1e-3, color=color, ls=ls, lw=1.4, label=f"{LABELS[law]} (e = {e:.3f})")
        ax.set_title(f"one impact, restitution $c_e$ = {ce}")
        ax.set_xlabel("penetration δ [µm]")
        ax.grid(alpha=0.3)
        ax.set_xlim(left=0)
        ax.set_ylim(bottom=0)
        ax.legend(fontsize=8, loc="upper left")
    axes[0].set_ylabel("normal force F [kN]")
    fig.suptitle("Force against penetration over one impact: journal 0.2 kg at 0.5 m/s, Muvengei et al.'s bearing "
                 "(R = 5 mm, c = 0.3 mm, L = 20 mm, steel)", fontsize=9)
    fig.tight_layout()
    out = ROOT / "docs" / "images" / "contact_hysteresis.png"
    fig.savefig(out, dpi=110)
    print(f"wrote {out.relative_to(ROOT)}")

    ces = (0.3, 0.5, 0.7, 0.9, 1.0)
    print("\n| law | " + " | ".join(f"c_e = {c}" for c in ces) + " |")
    print("| --- |" + " --- |" * len(ces))
    for law in LAWS:
        cells = []
        for ce in ces:
            d, F, e = one_impact(law, ce, t_end=1.0e-3 if ce > 0.35 else 1.2e-3, dt=1e-6)
            exact = restitution_exact(damping_factor(int(law), ce))
            cells.append(f"{e:.6f} ({exact:.6f})")
        print(f"| {LABELS[law]} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
