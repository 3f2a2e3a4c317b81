"""The fork server of a local sweep's workers, started before anything else is loaded.

Every worker of a local sweep needs numba and the compiled kernels (`sweep_worker`), about
0.4 s of loading.  Loaded in the sweep's own process, they wait for the command line, the model
and the check of every case (another 0.3 s), and both come before the first case: on a sweep of
short cases that serial start is a third of the whole run with two workers.

`start` launches multiprocessing's fork server at the first line of ``mbs sweep``, with
`sweep_worker` as its preload: a fresh interpreter loads the kernels on another core while this
process reads its command line, parses the model and checks the cases.  The pool's workers are
then forks of that server (`sweep.default_executor`) and start their first case at once.  A fresh
interpreter takes about as long to load them as this process takes to reach its pool, so the gain
is small (8 short cases on two cores, 9 interleaved pairs: 1.30 s against 1.34 s), but this
process never loads numba and the workers start as soon as the kernels are there.  The
server ends with this process: at once while it is still loading (`die_with_the_sweep`: a first
sweep with a cold numba cache compiles for a minute), else when the pipe that only this process
holds open closes.
"""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

from ..lazy import lazy
from ..run.children import PACKAGE_ENV, die_with_parent, package_env

# multiprocessing only where a server starts (a sweep on several cores)
mp = lazy("multiprocessing")
forkserver = lazy("multiprocessing.forkserver")
process = lazy("multiprocessing.process")
resource_tracker = lazy("multiprocessing.resource_tracker")

_STARTED: list[bool] = []
SERVER_ENV = "PLANAR_MBS_SWEEP_SERVER"  # set for the server only: the pid of the sweep that started it


def start() -> bool:
    """Start the fork server with the sweep's worker preloaded, once; False where there is none
    (Windows) or it cannot start (the sweep then loads the kernels itself)."""
    if _STARTED:
        return True
    if "forkserver" not in mp.get_all_start_methods():
        return False
    # the server imports this very package (`children.package_env`): the workers are its forks
    saved = {k: os.environ.get(k) for k in (SERVER_ENV, *PACKAGE_ENV)}
    os.environ.update({SERVER_ENV: str(os.getpid()), **package_env()})
    try:
        own_temp_folder()
        mp.get_context("forkserver").set_forkserver_preload(["planar_mbs.sweep.worker"])
        _start_quiet_resource_tracker()
        forkserver.ensure_running()
    except (OSError, ValueError) as exc:  # no fork, no socket, a read-only temp folder: load them here
        print(f"note: the sweep's worker server did not start ({exc}); loading the kernels here",
              file=sys.stderr)
        return False
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    _STARTED.append(True)
    return True


TEMP_PREFIX = "mbs-sweep-"  # the fork server's socket folder: mbs-sweep-<pid>-XXXX in the temp folder


def own_temp_folder() -> None:
    """Give multiprocessing a temporary folder of ours (``mbs-sweep-<pid>-*``) instead of its own
    ``pymp-*``: its finalizer never runs, as the command ends with ``os._exit``, and the folder of the
    fork server's socket stayed behind after every sweep.  `remove_temp_folder` removes it at the end
    of the sweep; folders of sweeps that were killed (their process is gone) are removed here."""
    for old in Path(tempfile.gettempdir()).glob(f"{TEMP_PREFIX}*"):
        pid = old.name[len(TEMP_PREFIX):].split("-")[0]
        if pid.isdigit() and not _alive(int(pid)) and old.stat().st_uid == os.getuid():
            shutil.rmtree(old, ignore_errors=True)
    config = process.current_process()._config
    if config.get("tempdir") is None:
        config["tempdir"] = tempfile.mkdtemp(prefix=f"{TEMP_PREFIX}{os.getpid()}-")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_temp_folder() -> None:
    """Remove the folder `own_temp_folder` made (the server keeps running without its socket file)."""
    folder = process.current_process()._config.get("tempdir")
    if folder and Path(folder).name.startswith(f"{TEMP_PREFIX}{os.getpid()}-"):
        shutil.rmtree(folder, ignore_errors=True)


def die_with_the_sweep() -> None:
    """Called first by the server's preload (`sweep_worker`): the kernel kills the server when the
    sweep's process ends (prctl PR_SET_PDEATHSIG), so a server still loading does not outlive a
    sweep that stopped at a usage error, an interrupt or SIGKILL.  Elsewhere it does nothing."""
    owner = os.environ.pop(SERVER_ENV, None)
    if owner is None or not die_with_parent():  # not Linux: the server ends when its preload is done
        return
    if os.getppid() != int(owner):  # the sweep ended before the signal was armed
        os._exit(0)


def _start_quiet_resource_tracker() -> None:
    """Start multiprocessing's resource tracker with its stderr on /dev/null.  It unlinks the
    pool's named semaphores when this process ends without releasing them, which an interrupted
    sweep does (it ends at once, `cli.entry.leave`), and then prints a warning about "leaked
    semaphore objects" after the user's Ctrl-C: it did its job, the warning is noise."""
    saved, devnull = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        resource_tracker.ensure_running()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def started() -> bool:
    """True once `start` has launched the server in this process."""
    return bool(_STARTED)


def kernels_loaded() -> bool:
    """True in a process where the time loop's compiled code is already in memory (a pool forks
    such a process; see `sweep.default_executor`)."""
    kernel = sys.modules.get("planar_mbs.kernel")
    return kernel is not None and bool(kernel.advance.overloads)


def wanted(argv: list[str], cores: int | None) -> bool:
    """Whether the ``mbs sweep`` arguments ``argv`` (after ``sweep``) ask for a local pool: no
    ``--help``, no dask ``--scheduler``, and ``--jobs`` above 1 (its default is the number of
    ``cores``).  A guess from the raw arguments, before typer reads them: when it is wrong, the
    only cost is a server started for nothing (or a sweep that loads its kernels itself)."""
    jobs = None
    if argv[:1] in (["replay"], ["merge"]) and not os.path.exists(argv[0]):  # `mbs sweep replay/merge`
        return False
    for i, a in enumerate(argv):
        if a in ("--help", "--scheduler") or a.startswith("--scheduler="):
            return False
        if a in ("-j", "--jobs") and i + 1 < len(argv):
            jobs = argv[i + 1]
        elif a.startswith("--jobs="):
            jobs = a[len("--jobs="):]
        elif a.startswith("-j") and len(a) > 2:
            jobs = a[2:]
    if jobs is None:
        return (cores or 1) > 1
    try:
        return int(jobs) > 1
    except ValueError:
        return False
