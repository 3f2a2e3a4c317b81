"""`mbs check`: compile a model, assemble its initial pose and print what it is made of.

Imports neither typer nor numba: `entry.main` runs a plain `mbs check MODEL [--set NAME=VALUE]...`
through `check_model` directly (typer's argument handling loads pydantic, which alone costs more than
compiling a model), and the typer command `check` calls the same function.
"""
from __future__ import annotations

import numpy as np
from rich.markup import escape
from rich.table import Table

from planar_mbs import catalog
from planar_mbs.errors import MbsError
from planar_mbs.mechanism.compile import load_model  # errors worded for --set
from planar_mbs.mechanism.kinematics import (assemble, assembly_changes, assembly_warnings, constraint_report,
                                             start_gaps)
from planar_mbs.mechanism.model import CP_CLEARANCE, CP_STIFFNESS
from planar_mbs.mechanism.start_stiffness import DEEP_FRACTION, start_contacts, step_count_message
from planar_mbs.run.output_size import MAX_ROWS, estimate

from .common import console, fail_code, parse_sets, print_assembly, print_model_warnings


def check_model(model, sets: list[str]) -> int:
    """Check one model; print its summary or its errors (with file:line:col).  Returns the exit code."""
    try:
        m = load_model(model, parse_sets(sets))
        q, qd = assemble(m)
    except MbsError as err:
        return fail_code(err)
    print_model_warnings(m)
    _print_model(m, {**constraint_report(m, q), "gaps": start_gaps(m, q)})
    _print_output_size(m)
    _print_start_contacts(m, q, qd)
    print_assembly(assembly_changes(m, q, qd))
    for warning in assembly_warnings(m, q):
        console(stderr=True).print(f"warning: {warning}", markup=False, style="yellow")
    return 0


def _print_start_contacts(m, q, qd) -> None:
    """Contacts that start deep inside (beyond DEEP_FRACTION of their size), and a start so stiff that
    `mbs run` refuses it (more than max_steps steps: `start_stiffness.check_step_count`)."""
    contacts = start_contacts(m, q, qd)
    err = console(stderr=True)
    for c in contacts:
        if c.deep:
            err.print(f"warning: {c.describe()}: deeper than {DEEP_FRACTION:g} of its {c.size_name}, beyond the small "
                      "deformations its law describes (start the body outside, or touching; or check the stiffness)",
                      markup=False, style="yellow")
    message = step_count_message(m, m.settings, contacts)
    if message:
        err.print(f"warning: {message}: `mbs run` refuses this", markup=False, style="yellow")


def _print_output_size(m) -> None:
    """The rows and file size a run with the model's own settings writes (and whether `run` would refuse it)."""
    est = estimate(m, m.settings)
    console().print(f"output: {est.describe()}", markup=False)
    if est.rows > MAX_ROWS:
        console(stderr=True).print(f"warning: more than {MAX_ROWS:,} output rows: `mbs run` refuses this without "
                                   "--force (check output_step and t_end)", markup=False, style="yellow")


def _print_model(m, report: dict) -> None:
    con = console()
    k = m.kernel
    dof = report["dof"]
    nodes = int(np.sum(np.asarray(k.body_beam) >= 0))
    beams = f"{len(m.beam_names)} beam{'s' if len(m.beam_names) != 1 else ''} ({nodes // 2} nodes), " if m.beam_names else ""
    con.print(f"[bold]{m.source_path}[/]: {m.nbody - nodes} bodies, {beams}{m.ncoord} coordinates, "
              f"{m.nconstraint} constraint{'s' if m.nconstraint != 1 else ''}"
              f"{'' if report['rank'] == m.nconstraint else ' (rank ' + str(report['rank']) + ')'}, "
              f"{dof} degree{'s' if dof != 1 else ''} of freedom "
              f"({m.nclearance} clearance joint{'s' if m.nclearance != 1 else ''})")
    if report.get("singular"):
        con.print(f"the initial pose is a singular position: the constraints lose rank there (rank "
                  f"{report['rank']}, {report['rank_nearby']} at the poses next to it; a parallelogram with its bars "
                  "in line, a toggle); no joint is redundant, and the run passes it (projection = auto)")
    if report["redundant"]:
        names = ", ".join(f"`{escape(n)}`" for n in report["redundant"])
        con.print(f"redundant at the initial pose: {names} (rows that repeat what the other joints impose; "
                  "the run splits their reactions by least squares, docs/signals.md)")

    def table(title, *columns):
        t = Table(title=title, title_justify="left")
        for c in columns:
            t.add_column(escape(c), overflow="fold", min_width=len(c))  # "[kg]" is not markup
        return t

    bodies = table("bodies", "body", "mass [kg]", "inertia [kg m²]") if m.nbody > nodes else None
    for b, name in enumerate(m.body_names[:m.nbody - nodes]):
        bodies.add_row(name, f"{k.body_mass[b]:g}", f"{k.body_inertia[b]:g}")
    if bodies is not None:
        con.print(bodies)
    if m.beam_names:
        con.print(_beam_table(m, table("beams", "beam", "elements", "coordinates", "length [m]", "mass [kg]",
                                       "EA [N]", "EI [N m²]")))
    joints = table("ideal joints and drivers", "joint", "type", "bodies", "rows")
    for j, name in enumerate(m.joint_names):
        i1, i2 = k.joint_body[j]
        spec = catalog.JOINTS[int(k.joint_type[j])]
        joints.add_row(name, spec.name, f"{_body(m, i1)} – {_body(m, i2)}", str(spec.rows))
    for d, name in enumerate(m.driver_names):
        i1, i2 = k.driver_body[d]
        joints.add_row(name, "driver", f"{_body(m, i1)} – {_body(m, i2)}", "1")
    con.print(joints)
    if m.nclearance:
        cl = table("clearance joints and contacts", "clearance joint", "bearing – journal", "clearance [mm]", "law",
                   "K [N/m^n]", "at the start")
        for c, name in enumerate(m.clearance_names):
            i1, i2 = k.clearance_body[c]
            law = catalog.LAWS[int(k.clearance_law[c])]
            cl.add_row(name, f"{_body(m, i1)} – {_body(m, i2)}",
                       f"{k.clearance_param[c, CP_CLEARANCE] * 1e3:g}",
                       law.name, "—" if law.group.compliance == "materials"  # no K of F = K d^n
                       else f"{k.clearance_param[c, CP_STIFFNESS]:.4g}", _gap(report, c))
        con.print(cl)


def _beam_table(m, t):
    """One row per beam: its elements, coordinates (4 per node), length, mass and stiffnesses."""
    k = m.kernel
    for bm, name in enumerate(m.beam_names):
        nel = int(k.beam_info[bm, 1])
        Le, ea, ei, _, rho_a = k.beam_param[bm]
        t.add_row(name, str(nel), str(4 * (nel + 1)), f"{Le * nel:g}", f"{rho_a * Le * nel:g}", f"{ea:.4g}",
                  f"{ei:.4g}")
    return t


def _gap(report: dict, c: int) -> str:
    """What element c does at the start: its gap, or that it touches (and how deep)."""
    gaps = report.get("gaps")
    if gaps is None:
        return "—"
    g = float(gaps[c])
    return f"touching ({-g * 1e6:.3g} µm deep)" if g < 0 else ("touching" if g == 0 else f"gap {g * 1e3:.4g} mm")


def _body(m, i: int) -> str:
    return "ground" if i < 0 else m.body_names[i]
