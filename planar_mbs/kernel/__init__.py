"""Numba kernels: constraints, forces, contact laws, dynamics, integrators, events.

Public entry points (all compiled with `jit.kernel` except the Python helpers):

* ``advance(km, cfg, y, clock, contact, stats, ws, t_stop, out_t, out) -> (status, n_written)``
* ``observe(km, cfg, t, y, contact, ws, row) -> status``
* ``constraint_eval(km, q, qd, t, C, Cq, Ct, gamma) -> status``
* ``accelerations(km, cfg, t, q, qd, contact, ws, stats) -> status`` (ws.qdd, ws.lam)
* ``project(km, t, y, ws, stats) -> status`` (y onto the constraints, positions then velocities)
``error_model="numpy"``: a division by zero gives inf/nan (caught as
Status.NONFINITE) instead of raising inside compiled code.

* Python: ``make_workspace(km)``, ``nobs(km)``, ``kernel_model(km)`` (contiguous
  float64/int64 copy of a KernelModel), ``constraint_rows(km)``.
"""
from .constraints import constraint_eval, constraint_rows
from .dynamics import accelerations, project
from .loop import advance, observe
from .workspace import Workspace, kernel_model, make_workspace, nobs

__all__ = [
    "advance", "observe", "constraint_eval", "accelerations", "make_workspace", "nobs",
    "kernel_model", "constraint_rows", "Workspace", "project",
]
