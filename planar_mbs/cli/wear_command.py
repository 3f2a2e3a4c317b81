"""`mbs run` of a model whose revolute clearance joint declares `wear`: the wear run (`run.wear.WearRun`,
the file saved whole after each update), one line per update and a summary.  The options are checked
here and the files by `run.wear_job`; `run_command.run_model` hands such a model over."""
from __future__ import annotations

import math
import shlex
import time

from planar_mbs.errors import ModelError, SimulationError
from planar_mbs.lazy import lazy

from .common import ExitCode, check_output
from .common import console as _console

hdf5 = lazy("planar_mbs.results.hdf5")
output_names = lazy("planar_mbs.run.output_names")
section = lazy("planar_mbs.results.section")
wear_job = lazy("planar_mbs.run.wear_job")

LENGTH = "a wear run's length is its updates x `update` (the model's `wear = archard(...)`): give a new total " \
         "with `--updates N`"
REFUSED = (("t_end", "--t-end", LENGTH), ("revolutions", "--revolutions", LENGTH),
           ("until_settled", "--until-settled", "the bearing changes at every update: a wear run never settles"),
           ("keep", "--keep", "a wear run keeps the worn profile of each update, not the signals"),
           ("rerun", "--rerun", "record the wear file afterwards: `mbs view FILE.h5`"),
           ("view_", "--open", "record the wear file afterwards: `mbs view FILE.h5 --open`"))


def refuse_options(o) -> None:
    """The options that make no sense for a wear run, refused (exit 2) with what to do instead."""
    for param, flag, hint in REFUSED:
        if getattr(o, param) not in (None, False):
            raise ModelError(f"{flag} does not apply to a wear run (`{o.m.source_path}` declares `wear`)", flag,
                             hint=hint)
    if o.resume and o.from_static:
        raise ModelError("--from-static does not apply to a resumed wear run", "--from-static",
                         hint="a resumed run goes on from the state saved in its file: drop --from-static")


def refuse_without_wear(o) -> None:
    """--resume and --updates on a model that declares no `wear`: refused (exit 2)."""
    flag = "--resume" if o.resume else "--updates" if o.updates is not None else None
    if flag:
        raise ModelError(f"{flag} is an option of a wear run, and `{o.model}` declares no `wear`", flag,
                         hint="add `wear = archard(...)` to a revolute clearance joint (docs/wear.md)")


def check_files(o, inputs: list) -> None:
    """The wear file: to continue (`--resume`: it must hold this model's wear run) or to write (a file a
    new run may replace); sets ``o.joint`` and ``o.total`` (None: the model's updates)."""
    o.joint = wear_job.wearing_joint(o.m)
    if o.resume:
        o.joint, o.total = wear_job.check_resume(o.m, o.out, o.updates)
        check_output(o.out, "--output", inputs)
        return
    o.total = o.updates
    make_folder = o.output is None and not o.out.parent.exists()
    if make_folder:
        output_names.make_results_folder(o.out.parent)
    check_output(o.out, "--output", inputs)
    if not wear_job.check_fresh(o.out, o.m, o.overwrite):
        hdf5.refuse_replacing(o.out, overwrite=o.overwrite, inputs=o.m.source_files)


def run_wear(o, exit_now) -> int:
    """The wear run of the checked options ``o``; the exit code (`exit_now` ends an interrupted run)."""
    settings = {k: v for k, v in o.changes.items() if k not in ("t_end", "revolutions")}
    o.saved, o.started = 0, time.perf_counter()
    found = section.driver_period(o.m)
    o.period = found[0] if found else None
    try:
        with wear_job.stoppable():
            run = wear_job.start(o.m, o.joint, o.out, o.resume, o.total, allow_unphysical=o.allow_unphysical,
                                 **settings)
            _print_start(run, o)
            run.run(callback=lambda r: _print_update(r, o), output=o.out)
    except SimulationError as err:
        _stopped(o, f"simulation failed: {err.message}")
        return int(ExitCode.SIMULATION_FAILED)
    except KeyboardInterrupt as err:  # simulation.RunInterrupted: SIGINT or SIGTERM
        _stopped(o, "interrupted")
        return exit_now(128 + getattr(err, "signum", ExitCode.INTERRUPTED - 128))
    _print_summary(run.history, o)
    return 0


def _worn(o, worn_time: float) -> str:
    if o.period:
        return f"{worn_time / o.period:,.0f} cycles ({worn_time:.4g} s)".replace(",", " ")
    return f"{worn_time:.4g} s"


def _print_start(run, o) -> None:
    h = run.history
    what = f"resuming {o.out} at update {len(h.depths) - 1}" if o.resume else f"wear run of `{h.joint}`"
    _console().print(f"{what}: {run.wear.updates} updates of {run.wear.interval:.4g} s of motion, Archard "
                     f"k/H = {run.wear.coefficient:.3g} 1/Pa, {run.wear.nodes} nodes", markup=False, soft_wrap=True)


def _print_update(run, o) -> None:
    o.saved += 1
    if o.quiet:
        return
    h, i = run.history, len(run.history.depths) - 1
    _console().print(f"update {i:>3}/{run.wear.updates}  worn {_worn(o, h.worn_times[-1])}  volume "
                     f"{h.volume() * 1e6:.4g} mm²  deepest {h.max_depth() * 1e6:.4g} µm at "
                     f"{math.degrees(h.max_angle()):.0f}°  peak force {h.peak_forces[-1]:.4g} N", markup=False, soft_wrap=True)


def _print_summary(h, o) -> None:
    con = _console()
    n = len(h.depths) - 1
    con.print("finished", style="bold", end=" ")
    con.print(f"{n} updates, worn {_worn(o, h.worn_times[-1])} → {o.out}", markup=False, soft_wrap=True)
    con.print(f"  deepest {h.max_depth() * 1e6:.4g} µm at {math.degrees(h.max_angle()):.0f}° (bearing frame), "
              f"worn volume {h.volume() * 1e6:.4g} mm² per unit width", markup=False, soft_wrap=True)
    con.print(f"  peak contact force {h.peak_forces[1]:.4g} N at the first update, {h.peak_forces[-1]:.4g} N at "
              f"the last; wall time {time.perf_counter() - o.started:.2f} s", markup=False, soft_wrap=True)
    con.print(f"  `mbs plot {o.out}` draws the worn profile; `{_resume_command(o)} --updates {2 * n}` goes on",
              markup=False, soft_wrap=True)


def _resume_command(o) -> str:
    words = ["mbs", "run", str(o.model), *(w for s in o.set_ or [] for w in ("--set", s)), "--resume"]
    if o.output is not None:
        words += ["-o", str(o.output)]
    return " ".join(shlex.quote(w) for w in words)


def _stopped(o, why: str) -> None:
    """A run stopped before its last update: what the file holds, and how to go on."""
    wear_job.left_behind(o.out)
    err = _console(stderr=True)
    if o.saved == 0 and not o.resume:
        err.print(f"{why}\nno update finished: nothing was written", markup=False, soft_wrap=True)
        return
    h = wear_job.load_history(o.out)
    err.print(f"{why}\n{o.out} holds the wear after update {len(h.depths) - 1} of {h.wear.updates} (worn "
              f"{_worn(o, h.worn_times[-1])}); go on with: {_resume_command(o)}", markup=False, soft_wrap=True)
