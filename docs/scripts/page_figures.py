"""The figures of docs/plots.md, docs/signals.md, the README, docs/tutorial.md and docs/beams.md, drawn by the commands
those pages show or by the scripts they name.

    .venv/bin/python docs/scripts/page_figures.py            # redraws them into docs/images
    .venv/bin/python docs/scripts/page_figures.py OUTDIR     # draws them into OUTDIR (tests/test_doc_figures.py)

Each entry of PAGES is the page's own commands, run in a scratch folder through the `mbs` command line, and
the figures it keeps: the file the command wrote and the name it has in docs/images.  A page whose figure
no longer matches what these commands draw fails tests/test_doc_figures.py; this script redraws it.  Each entry
of SCRIPTS is a script of docs/scripts that a page names, whose `draw(outdir)` draws the figures listed.
"""
from __future__ import annotations

import importlib
import shlex
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
IMAGES = ROOT / "docs" / "images"

PLOTS_RUN = "mbs run models/slider_crank_clearance_a.mbs -o a_5000.h5 --t-end 0.36s"
PLOTS_DEFAULT = "mbs plot a_5000.h5 -o docs/images"
PLOTS_AGAINST = "mbs plot a_5000.h5 slider.ax A.contact_force crank_speed.torque --against crank.phi"
SWEEP_RUN = ("mbs sweep models/slider_crank_clearance_a.mbs -P speed=800rpm,1200rpm,2500rpm,5000rpm -n 30 "
             "--keep slider,crank -o sweep_a.h5")
SWEEP_PLOT = "mbs plot sweep_a.h5 -o docs/images"
SWEEP = ["sweep_a_grid_slider.ax.png", "sweep_a_poincare_grid_slider.vx_slider.ax.png",
         "sweep_a_bifurcation_slider.vx.png"]
BALANCE_RUN = "mbs run models/slider_crank_motor.mbs -o motor.h5"
BALANCE_PLOT = ("mbs plot motor.h5 motor.torque motor.power system.input_work A.dissipated "
                "system.energy_balance")
BALANCE = "motor_motor.torque_motor.power_system.input_work_A.dissipated_system.energy_balance.png"
TUTORIAL_RUN = "mbs run four_bar.mbs"
TUTORIAL_PLOT = "mbs plot results/four_bar.h5 rocker_link.phi motor.torque --against crank_link.phi"

MODES_PLOT = "mbs modes docs/studies/resting_journal.mbs --set law=hertz --plot resting_journal_modes.png"
SPEEDS_RUN = ("mbs sweep models/slider_crank_clearance_a.mbs -P speed=800rpm,1200rpm,2500rpm,5000rpm -n 4 "
              "--keep slider.ax,crank --no-section -q -o speeds.h5")
SPEEDS_PLOT = "mbs plot speeds.h5 --spectrum slider.ax --kind order -o docs/images"
SPEEDS = "speeds_order_grid_slider.ax.png"
TOLERANCE_RUN = ("mbs sweep docs/studies/tolerance_slider_crank.mbs --sample \"clearance=uniform(0.1mm, 0.3mm)\" "
                 "--sample \"crank_length=normal(50mm, 0.05mm)\" --cases 24 --set speed=2500rpm -n 2 "
                 "--keep slider.ax --no-section -q -o tolerance.h5")
TOLERANCE_PLOT = "mbs sweep stats tolerance.h5 slider.ax:rms A.contact_force:max --plot tolerance.png --band slider.ax"

A_5000 = ["a_5000_slider_velocity.png", "a_5000_slider_acceleration.png", "a_5000_contact_force.png",
          "a_5000_driver_torque.png", "a_5000_orbit_A.png", "a_5000_poincare_slider.vx_slider.ax.png"]
AGAINST = "a_5000_slider.ax_A.contact_force_crank_speed.torque_vs_crank.phi.png"

# page: (commands as the page shows them, {file the commands write: its name in docs/images})
PAGES = {
    "docs/plots.md": ([PLOTS_RUN, PLOTS_DEFAULT, PLOTS_AGAINST],
                      {**{f"docs/images/{n}": n for n in A_5000}, f"a_5000_plots/{AGAINST}": AGAINST}),
    "docs/plots.md#sweeps": ([SWEEP_RUN, SWEEP_PLOT], {f"docs/images/{n}": n for n in SWEEP}),
    "docs/signals.md": ([BALANCE_RUN, BALANCE_PLOT], {f"motor_plots/{BALANCE}": "signals_energy_balance.png"}),
    "docs/tutorial.md": ([TUTORIAL_RUN, TUTORIAL_PLOT],
                         {"results/four_bar_plots/four_bar_rocker_link.phi_motor.torque_vs_crank_link.phi.png":
                          "tutorial_four_bar.png"}),
    "docs/studies.md": ([MODES_PLOT], {"resting_journal_modes.png": "studies_resting_journal_modes.png"}),
    "docs/studies.md#spectra": ([SPEEDS_RUN, SPEEDS_PLOT], {f"docs/images/{SPEEDS}": "studies_speeds_order_slider.ax.png"}),
    "docs/studies.md#tolerances": ([TOLERANCE_RUN, TOLERANCE_PLOT], {"tolerance.png": "studies_tolerance.png"}),
}

# page: (a script of docs/scripts, the names in docs/images of the figures its draw(outdir) writes)
SCRIPTS = {
    "docs/beams.md": ("flexible_clearance", ["beams_flexible_clearance.png"]),
}


def mbs(command: str, cwd: Path) -> None:
    """One `mbs ...` command line of a page, run in `cwd` (the CLI in this process)."""
    import os

    from typer.testing import CliRunner

    from planar_mbs.cli.app import app
    from planar_mbs.cli.sweep_commands import route

    here = os.getcwd()
    os.chdir(cwd)
    argv = shlex.split(command)
    route(argv)  # `mbs sweep stats` is the command sweep-stats
    try:
        r = CliRunner().invoke(app, argv[1:], env={"COLUMNS": "200"})
    finally:
        os.chdir(here)
    if r.exit_code != 0:
        raise RuntimeError(f"`{command}` exited {r.exit_code}: {r.output}")


def draw(outdir: Path) -> list[Path]:
    """Every page's figures, drawn by its commands, into `outdir` under their docs/images names."""
    outdir.mkdir(parents=True, exist_ok=True)
    written = []
    for commands, keep in PAGES.values():
        with tempfile.TemporaryDirectory() as scratch:
            work = Path(scratch)
            shutil.copytree(ROOT / "models", work / "models")
            shutil.copy(ROOT / "docs" / "tutorial" / "four_bar.mbs", work / "four_bar.mbs")
            shutil.copytree(ROOT / "docs" / "studies", work / "docs" / "studies")
            (work / "docs" / "images").mkdir(parents=True)
            for command in commands:
                mbs(command, work)
            for made, name in keep.items():
                written.append(Path(shutil.copy(work / made, outdir / name)))
    for script, _ in SCRIPTS.values():
        written += importlib.import_module(script).draw(outdir)
    return written


if __name__ == "__main__":
    for path in draw(Path(sys.argv[1]) if len(sys.argv) > 1 else IMAGES):
        print(path)
