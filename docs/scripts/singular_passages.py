"""The parallelogram chain (IFToMM "N four-bar mechanism", N = 2) through its singular positions,
with and without the kinetic energy that the velocity projection gives back (docs/numerics.md).

    .venv/bin/python docs/scripts/singular_passages.py   # writes docs/images/singular_passages.png

Crank-tip error against the exact one-degree-of-freedom motion (quadrature of the energy
equation, tests/chains.py) and the total energy's departure from its start, 20 s, rtol 1e-12,
DOPRI5 and DOP853.  `PLANAR_MBS_SOLVER` switches the restoration off for the comparison.
"""
from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

N = 2
RESTORE_OFF = "1e-8,2,0,1e-3,0"  # [REG, REFINE, REFINE_TOL, TAU, RESTORE] (kernel/workspace.py)


def run(integrator: str, restore: bool, rtol: float = 1e-12):
    """(time, crank-tip error, total energy - its start) of one 20 s run."""
    import chains
    from planar_mbs import simulate
    from planar_mbs.mechanism.compile import compile_text

    if restore:
        os.environ.pop("PLANAR_MBS_SOLVER", None)
    else:
        os.environ["PLANAR_MBS_SOLVER"] = RESTORE_OFF
    text = chains.parallelogram_chain(N, integrator=integrator, rtol=rtol, atol=rtol / 100, t_end=20.0,
                                      extra="projection = on ")
    res = simulate(compile_text(text, f"parallelogram_{N}.mbs"))
    t = res.time
    phi = res["crank0.phi"]
    tip = np.stack([res["crank0.x"] + 0.5 * np.cos(phi), res["crank0.y"] + 0.5 * np.sin(phi)])
    theta, _ = chains.crank_angle_reference(N, t)
    err = np.hypot(*(tip - np.stack([np.cos(theta), np.sin(theta)])))
    energy = res["system.total_energy"]
    return t, err, energy - energy[0], theta


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_err, ax_energy) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    for integrator, color in (("dopri5", "tab:blue"), ("dop853", "tab:orange")):
        for restore, style in ((False, ":"), (True, "-")):
            t, err, de, theta = run(integrator, restore)
            label = f"{integrator.upper()}, " + ("energy given back (shipped)" if restore else "orthogonal projection only")
            ax_err.semilogy(t[1:], np.maximum(err[1:], 1e-13), style, color=color, label=label, lw=1)
            ax_energy.plot(t, de * 1e9, style, color=color, label=label, lw=1)
            print(f"{label}: largest crank-tip error {err.max():.2g} m, energy {de[-1]:.2g} J at 20 s")
    passes = (math.pi / 2 - theta) / math.pi + 0.5  # horizontal positions passed, as in the tests
    for k in range(1, int(passes[-1]) + 1):
        t_k = t[np.searchsorted(passes, k)]
        for ax in (ax_err, ax_energy):
            ax.axvline(t_k, color="0.85", lw=0.6, zorder=0)
    ax_err.axhline(1e-8, color="k", lw=0.6)
    ax_err.set_ylabel("crank-tip error [m]")
    ax_err.set_title(f"Parallelogram chain N = {N}, rtol 1e-12 (grey: singular positions)")
    ax_energy.set_ylabel("total energy − start [nJ]")
    ax_energy.set_xlabel("time [s]")
    ax_energy.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    out = ROOT / "docs" / "images" / "singular_passages.png"
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
