"""Figures of docs/contact.md's imperfect joints and the table of docs/replication.md's translational
clearance study: runs the shipped models and writes docs/images/ij_*.png and docs/translational_study.json.

    .venv/bin/python docs/scripts/imperfect_joints.py
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import planar_mbs as mbs  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
IMG = ROOT / "docs" / "images"
CORNERS = ("rear_bottom", "rear_top", "front_bottom", "front_top")


def run(name, **kw):
    settings = {k: kw.pop(k) for k in ("revolutions", "per_rev", "t_end") if k in kw}
    return mbs.simulate(mbs.load_model(ROOT / "models" / f"{name}.mbs", **kw), **settings)


def slider_crank_figures():
    ideal = run("slider_crank", speed="2500rpm", revolutions=5, per_rev=720)
    fig, ax = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for name, label in (("slider_crank_clearance_s", "clearance at the slider"),
                        ("slider_crank_clearance_as", "clearance at the slider and at A")):
        r = run(name, revolutions=5, per_rev=720)
        turns = r["crank.phi"] / (2 * math.pi)
        ax[0].plot(turns, r["slider.ax"], lw=0.6, label=label)
        ax[1].plot(turns, np.degrees(r["slider.phi"]) * 60, lw=0.6, label=label)
        if name.endswith("_s"):
            for c in CORNERS:
                ax[2].plot(turns, r[f"S_{c}.contact_force"], lw=0.6, label=c)
    ax[0].plot(ideal["crank.phi"] / (2 * math.pi), ideal["slider.ax"], "k", lw=0.8, label="ideal joints")
    ax[0].set_ylabel("slider acceleration [m/s²]")
    ax[1].set_ylabel("slider tilt [arcmin]")
    ax[2].set_ylabel("corner force [N]\n(slider clearance only)")
    ax[2].set_xlabel("crank revolutions")
    for a in ax:
        a.legend(fontsize=7, loc="upper right")
    fig.suptitle("slider-crank, 2500 rpm, 0.3 mm gap at the slider")
    fig.tight_layout()
    fig.savefig(IMG / "ij_slider_crank_translational.png", dpi=110)


def lubricated_figure():
    r = run("slider_crank_lubricated_a", revolutions=5, per_rev=720)
    dry = run("slider_crank_clearance_a", revolutions=5, per_rev=720)
    c = 0.3e-3
    fig, ax = plt.subplots(1, 2, figsize=(10, 4.5))
    th = np.linspace(0, 2 * math.pi, 200)
    ax[0].plot(np.cos(th), np.sin(th), "k", lw=0.8)
    ax[0].plot(0.95 * np.cos(th), 0.95 * np.sin(th), "k:", lw=0.6)
    ax[0].plot(dry["A.ex"] / c, dry["A.ey"] / c, lw=0.5, label="dry (Lankarani-Nikravesh)")
    ax[0].plot(r["A.ex"] / c, r["A.ey"] / c, lw=0.8, label="lubricated, 0.04 Pa s")
    ax[0].set_aspect("equal")
    ax[0].set_title("journal orbit in joint A (e / c)")
    ax[0].legend(fontsize=7)
    turns = r["crank.phi"] / (2 * math.pi)
    ax[1].plot(turns, r["A.film_pressure"] / 1e6, lw=0.7)
    ax[1].set_xlabel("crank revolutions")
    ax[1].set_ylabel("peak film pressure [MPa]")
    fig.suptitle("slider-crank with a lubricated joint A, 5000 rpm")
    fig.tight_layout()
    fig.savefig(IMG / "ij_lubricated_a.png", dpi=110)


def cam_figure():
    fig, ax = plt.subplots(figsize=(8, 4))
    for speed in ("1000rpm", "1300rpm"):
        r = run("cam_follower", speed=speed)
        th = r["cam.phi"] / (2 * math.pi)
        ax.plot(th, 1e3 * r["follower.y"], lw=0.8, label=f"follower, {speed}")
    th = np.linspace(0, 4, 800)
    ax.plot(th, 1e3 * (0.03 + 0.01 * np.sin(2 * math.pi * th)), "k:", lw=0.8, label="cam lift")
    ax.set_xlabel("cam revolutions")
    ax.set_ylabel("follower face height [mm]")
    ax.legend(fontsize=8)
    ax.set_title("disc cam and flat follower: contact holds below w* = 1170 rpm, jumps above")
    fig.tight_layout()
    fig.savefig(IMG / "ij_cam_follower.png", dpi=110)


def disc_figure():
    r = run("bouncing_disc")
    fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    ax[0].plot(r.time, r["disc.y"] - 0.05)
    ax[0].set_ylabel("height of the disc's bottom [m]")
    ax[1].plot(r.time, r["disc.vx"], label="vx [m/s]")
    ax[1].plot(r.time, 0.05 * r["disc.omega"], label="r omega [m/s]")
    ax[1].set_xlabel("time [s]")
    ax[1].legend(fontsize=8)
    ax[0].set_title("a spinning steel disc bouncing on a steel floor (e = 0.8, mu = 0.3)")
    fig.tight_layout()
    fig.savefig(IMG / "ij_bouncing_disc.png", dpi=110)


def study():
    """Slider tilt, corner forces and slider acceleration against the ideal joint, by gap and speed."""
    out = []
    for speed in ("1000rpm", "2500rpm", "5000rpm"):
        ideal = run("slider_crank", speed=speed, revolutions=10, per_rev=720)
        settle = ideal.time > ideal.time[-1] / 2
        for gap in ("0.1mm", "0.3mm", "0.5mm"):
            for mu in ("0", "0.1"):
                r = run("slider_crank_clearance_s", speed=speed, clearance=gap, friction=mu, revolutions=10, per_rev=720)
                k = r.time > r.time[-1] / 2  # the last five revolutions
                f = np.max([r[f"S_{c}.contact_force"][k] for c in CORNERS])
                out.append(dict(speed=speed, gap=gap, friction=float(mu),
                                tilt_arcmin=float(np.max(np.abs(np.degrees(r["slider.phi"][k]) * 60))),
                                peak_corner_force=float(f),
                                peak_ax=float(np.max(np.abs(r["slider.ax"][k]))),
                                peak_ax_ideal=float(np.max(np.abs(ideal["slider.ax"][settle]))),
                                impacts_per_rev=float(r.attrs["n_contact_events"]) / 10,
                                flight_fraction=float(np.mean(np.sum([r[f"S_{c}.in_contact"][k] for c in CORNERS],
                                                                     axis=0) == 0))))
                print(out[-1])
    (ROOT / "docs" / "translational_study.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    slider_crank_figures()
    lubricated_figure()
    cam_figure()
    disc_figure()
    study()
