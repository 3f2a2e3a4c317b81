"""The figure of docs/beams.md "A flexible rod in a clearance joint": the slider-crank with a clearance at
the crank pin A, once with the steel beam rod (models/slider_crank_flexible_rod_clearance.mbs) and once
with the rigid rod (models/slider_crank_clearance_a.mbs), over their first two crank revolutions.

    .venv/bin/python docs/scripts/flexible_clearance.py            # draws docs/images/beams_flexible_clearance.png
    .venv/bin/python docs/scripts/flexible_clearance.py OUTDIR     # draws it into OUTDIR (tests/test_doc_figures.py)

Panels: the rod's midpoint deflection from the chord between its end nodes (from the node signals
`rod_node<k>.x/.y`), and the contact force of joint A, flexible and rigid, on one scale.  Prints the
numbers docs/beams.md quotes (`summary`, `prose`).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import planar_mbs as mbs  # noqa: E402

IMAGES = ROOT / "docs" / "images"
NAME = "beams_flexible_clearance.png"
FLEXIBLE = "slider_crank_flexible_rod_clearance"
RIGID = "slider_crank_clearance_a"
REVOLUTIONS = 2
PER_REV = 7200  # 1.7 us at 5000 rpm: a beam node's shortest impacts last a few us, so their peaks are sampled


def node_count(res) -> int:
    """How many nodes the beam `rod` of these results has (its `rod_node<k>.x` signals)."""
    k = 0
    while f"rod_node{k}.x" in res:
        k += 1
    return k


def midpoint_deflection(res) -> np.ndarray:
    """The middle node's distance from the chord between the end nodes (m), positive to the chord's left
    (an even element count puts a node in the middle)."""
    n = node_count(res) - 1
    if n < 2 or n % 2:
        raise ValueError(f"the rod has {n} elements: the midpoint is a node only for an even count")
    p = [np.stack([np.asarray(res[f"rod_node{k}.x"]), np.asarray(res[f"rod_node{k}.y"])]) for k in (0, n // 2, n)]
    chord, mid = p[2] - p[0], p[1] - p[0]
    return (chord[0] * mid[1] - chord[1] * mid[0]) / np.hypot(chord[0], chord[1])


def run(name: str):
    """The shipped model `name` over REVOLUTIONS crank revolutions, PER_REV samples each: the crank's
    angle, joint A's contact force and, of a beam rod, its nodes."""
    model = mbs.load_model(ROOT / "models" / f"{name}.mbs")
    elements = model.kernel.beam_info[:, 1]
    nodes = [f"rod_node{k}" for k in range(int(elements[0]) + 1)] if len(elements) else []
    return mbs.simulate(model, revolutions=REVOLUTIONS, per_rev=PER_REV,
                        signals=["crank.phi", "A.contact_force", *nodes])


def summary(flexible, rigid) -> dict:
    """The numbers of the page: the midpoint's largest deflection (mm) and the peak contact forces (kN)."""
    return {"deflection_mm": float(np.abs(midpoint_deflection(flexible)).max() * 1e3),
            "peak_flexible_kN": float(np.max(flexible["A.contact_force"]) / 1e3),
            "peak_rigid_kN": float(np.max(rigid["A.contact_force"]) / 1e3)}


def prose(s: dict) -> str:
    """The sentence of docs/beams.md made of `summary`'s numbers (tests/test_flexible_clearance.py)."""
    return (f"Over these two revolutions the midpoint deflects up to {s['deflection_mm']:.2f} mm, and the "
            f"largest contact force at A is {s['peak_flexible_kN']:.0f} kN with the flexible rod against "
            f"{s['peak_rigid_kN']:.0f} kN with the rigid one.")


def figure(flexible, rigid, out: Path) -> Path:
    """Deflection above, the two contact forces below on one scale, against the crank angle."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(3, 1, figsize=(8, 7.5), sharex=True)
    deg = {id(r): np.degrees(np.asarray(r["crank.phi"])) for r in (flexible, rigid)}
    ax[0].plot(deg[id(flexible)], midpoint_deflection(flexible) * 1e3, lw=0.6, color="tab:blue")
    ax[0].axhline(0.0, lw=0.8, color="0.4", ls="--", label="rigid rod")
    ax[0].set_ylabel("midpoint deflection [mm]")
    ax[0].legend(loc="upper right", fontsize=8)
    top = 1.05 * max(np.max(r["A.contact_force"]) for r in (flexible, rigid)) / 1e3
    for a, r, label, color in ((ax[1], flexible, "flexible rod (steel beam, 4 elements)", "tab:blue"),
                               (ax[2], rigid, "rigid rod", "k")):
        a.plot(deg[id(r)], np.asarray(r["A.contact_force"]) / 1e3, lw=0.6, color=color, label=label)
        a.set_ylim(0.0, top)
        a.set_ylabel("contact force at A [kN]")
        a.legend(loc="upper right", fontsize=8)
    ax[2].set_xlabel("crank angle [deg]")
    ax[2].set_xlim(0.0, 360.0 * REVOLUTIONS)
    ax[2].set_xticks(np.arange(0, 360 * REVOLUTIONS + 1, 90))
    fig.suptitle("slider-crank, 0.3 mm clearance at A, 5000 rpm: flexible and rigid connecting rod", fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def runs():
    """(flexible, rigid): the two runs of the figure."""
    return run(FLEXIBLE), run(RIGID)


def draw(outdir: Path) -> list[Path]:
    """The figure into `outdir` under its docs/images name (docs/scripts/page_figures.py calls this)."""
    flexible, rigid = runs()
    return [figure(flexible, rigid, Path(outdir) / NAME)]


if __name__ == "__main__":
    flexible, rigid = runs()
    print(figure(flexible, rigid, (Path(sys.argv[1]) if len(sys.argv) > 1 else IMAGES) / NAME))
    print(prose(summary(flexible, rigid)))
