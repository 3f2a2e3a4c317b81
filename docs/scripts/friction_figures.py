"""The figure of docs/contact.md's friction section: the stick-slip cycle of models/belt_oscillator.mbs
against its closed form, written to docs/images/friction_belt_stick_slip.png.

    .venv/bin/python docs/scripts/friction_figures.py
"""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import planar_mbs as mbs  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
IMG = ROOT / "docs" / "images"
G = 9.81


def closed_form(m=1.0, k=100.0, v=0.05, ms=0.4, mk=0.25):
    """(stick time, x_k - A, x_k + A, x_s) of the belt oscillator's limit cycle (docs/contact.md)."""
    w = math.sqrt(k / m)
    xs, xk = ms * m * G / k, mk * m * G / k
    A = math.hypot(xs - xk, v / w)
    return 2 * (xs - xk) / v, xk - A, xk + A, xs


def belt_figure():
    r = mbs.simulate(mbs.load_model(ROOT / "models" / "belt_oscillator.mbs"))
    t_stick, lo, hi, xs = closed_form()
    fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax[0].plot(r.time, r["block.x"] * 1e3, lw=0.9, label="block position")
    ax[0].fill_between(r.time, lo * 1e3, hi * 1e3, where=r["on_belt.stick"] > 0, color="C1", alpha=0.25,
                       label="stuck to the belt")
    for y in (lo, hi):
        ax[0].axhline(y * 1e3, color="k", ls=":", lw=0.7)
    ax[0].axhline(xs * 1e3, color="C3", ls="--", lw=0.7, label="x_s = mu_s m g / k (breakaway)")
    ax[0].set_ylabel("x [mm]")
    ax[0].legend(fontsize=7, loc="lower right")
    ax[0].set_title(f"mass on a belt at 50 mm/s: stick time {t_stick:.3f} s (closed form), "
                    f"x between x_k ∓ A (dotted)", fontsize=9)
    ax[1].plot(r.time, r["on_belt.friction_force"], lw=0.9, label="friction force on the block")
    ax[1].plot(r.time, r["on_belt.contact_force"] * 0.4, "k:", lw=0.7, label="mu_s F_N")
    ax[1].plot(r.time, r["on_belt.contact_force"] * 0.25, "k--", lw=0.7, label="mu_k F_N")
    ax[1].set_ylabel("F_T [N] (along t = +x)")
    ax[1].set_xlabel("t [s]")
    ax[1].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(IMG / "friction_belt_stick_slip.png", dpi=110)


if __name__ == "__main__":
    belt_figure()
