"""Hand-made inputs for the plot and rerun tests: a 3-body slider-crank `Model` with one
clearance joint (A, crank - rod) and a synthetic, geometrically consistent run written
with `ResultsWriter`.  No compiler, no kernel: these tests stay fast and independent.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from planar_mbs.mechanism.model import (
    CP_CLEARANCE,
    CP_EXPONENT,
    CP_LENGTH,
    CP_R_BEARING,
    CP_R_JOURNAL,
    CP_RESTITUTION,
    CP_STIFFNESS,
    N_CLEARANCE_PARAM,
    N_CLEARANCE_SIGNALS,
    N_FORCE_PARAM,
    N_JOINT_PARAM,
    N_MOTION_PARAM,
    ContactLaw,
    DriverType,
    JointType,
    KernelModel,
    Model,
    MotionType,
    Settings,
    observation_size,
)
from planar_mbs.results.hdf5 import ResultsWriter
from planar_mbs.results.signals import signal_table

CRANK = 0.05  # crank length O-A [m]
ROD = 0.12  # rod length A-B [m]
CLEARANCE = 3e-4
SOURCE = "# synthetic slider-crank for the plot tests\nparam speed = {rpm} rpm\n"


def slider_crank_model(rpm: float = 2500.0) -> Model:
    omega = rpm * 2 * math.pi / 60
    f = np.float64
    cp = np.zeros((1, N_CLEARANCE_PARAM))
    cp[0, [CP_CLEARANCE, CP_R_BEARING, CP_R_JOURNAL, CP_LENGTH, CP_STIFFNESS, CP_EXPONENT, CP_RESTITUTION]] = [
        CLEARANCE, 5e-3, 5e-3 - CLEARANCE, 0.02, 1.5e10, 1.5, 0.9]
    motion = np.zeros((1, N_MOTION_PARAM))
    motion[0, 1] = omega
    mass = np.array([0.30, 0.21, 0.14])
    inertia = np.array([1e-5, 2.5e-4, 1e-4])
    km = KernelModel(
        body_mass=mass,
        body_inertia=inertia,
        minv=1.0 / np.stack([mass, mass, inertia], 1).ravel(),
        gravity=np.array([0.0, -9.81]),
        joint_type=np.array([JointType.REVOLUTE, JointType.REVOLUTE, JointType.TRANSLATIONAL], dtype=np.int64),
        joint_body=np.array([[-1, 0], [1, 2], [-1, 2]], dtype=np.int64),
        joint_point=np.array([[[0, 0], [-CRANK / 2, 0]], [[ROD / 2, 0], [0, 0]], [[0, 0], [0, 0]]], dtype=f),
        joint_axis=np.array([[0, 0], [0, 0], [1, 0]], dtype=f),
        joint_param=np.zeros((3, N_JOINT_PARAM)),
        joint_row=np.array([0, 2, 4], dtype=np.int64),
        driver_type=np.array([DriverType.ANGLE], dtype=np.int64),
        driver_body=np.array([[-1, 0]], dtype=np.int64),
        driver_point=np.zeros((1, 2, 2)),
        driver_axis=np.zeros((1, 2)),
        driver_motion=np.array([MotionType.CONSTANT_SPEED], dtype=np.int64),
        driver_motion_param=motion,
        driver_row=np.array([6], dtype=np.int64),
        clearance_body=np.array([[0, 1]], dtype=np.int64),
        clearance_point=np.array([[[CRANK / 2, 0], [-ROD / 2, 0]]], dtype=f),
        clearance_law=np.array([ContactLaw.LANKARANI_NIKRAVESH], dtype=np.int64),
        clearance_param=cp,
        force_type=np.zeros(0, dtype=np.int64),
        force_body=np.zeros((0, 2), dtype=np.int64),
        force_point=np.zeros((0, 2, 2)),
        force_param=np.zeros((0, N_FORCE_PARAM)),
    )
    return Model(
        kernel=km,
        settings=Settings(t_end=0.1, output_step=1e-4),
        q0=np.zeros(9),
        qd0=np.zeros(9),
        body_names=["crank", "rod", "slider"],
        joint_names=["O", "B", "S"],
        driver_names=["crank_speed"],
        clearance_names=["A"],
        force_names=[],
        parameters={"speed": f"{rpm:g} rpm"},
        source_text=SOURCE.format(rpm=rpm),
        source_path="synthetic.mbs",
    )


def synthetic_rows(model: Model, t: np.ndarray) -> np.ndarray:
    """Observation rows of a plausible run: ideal crank motion, a journal that wanders
    around the clearance circle (in and out of contact), made-up reactions."""
    omega = float(model.kernel.driver_motion_param[0, 1])
    nb, nj, nd, nc, nf = model.nbody, model.njoint, model.ndriver, model.nclearance, model.nforce
    rows = np.zeros((len(t), observation_size(nb, nj, nd, nc, nf)))
    th = omega * t
    A = CRANK * np.stack([np.cos(th), np.sin(th)], 1)
    e_len = CLEARANCE * (0.97 + 0.06 * np.sin(2 * np.pi * 37 * t))
    psi = th + 0.5 * np.sin(2 * np.pi * 13 * t)
    ecc = e_len[:, None] * np.stack([np.cos(psi), np.sin(psi)], 1)
    J = A + ecc
    xB = J[:, 0] + np.sqrt(ROD**2 - J[:, 1] ** 2)
    beta = np.arctan2(-J[:, 1], xB - J[:, 0])
    q = np.zeros((len(t), 3 * nb))
    q[:, 0:2] = A / 2
    q[:, 2] = th
    q[:, 3] = (J[:, 0] + xB) / 2
    q[:, 4] = J[:, 1] / 2
    q[:, 5] = beta
    q[:, 6] = xB
    qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    rows[:, : 3 * nb] = q
    rows[:, 3 * nb: 6 * nb] = qd
    rows[:, 6 * nb: 9 * nb] = qdd
    base = 9 * nb
    for j in range(nj):
        rows[:, base + 3 * j] = 50 * (j + 1) * np.cos(th + j)
        rows[:, base + 3 * j + 1] = 30 * (j + 1) * np.sin(th)
    base += 3 * nj
    rows[:, base] = 0.8 * np.sin(2 * th) + 0.1 * np.sin(2 * np.pi * 37 * t)  # torque
    rows[:, base + nd] = rows[:, base] * omega  # power
    base += 2 * nd
    pen = e_len - CLEARANCE
    fn = 1.5e10 * np.clip(pen, 0, None) ** 1.5
    n = ecc / e_len[:, None]
    c = base
    rows[:, c + 0], rows[:, c + 1], rows[:, c + 2], rows[:, c + 3] = ecc[:, 0], ecc[:, 1], e_len, pen
    rows[:, c + 4] = fn
    rows[:, c + 5], rows[:, c + 6] = -fn * n[:, 0], -fn * n[:, 1]
    rows[:, c + 7] = (pen > 0).astype(float)
    rows[:, c + 8] = 0.05
    base += N_CLEARANCE_SIGNALS * nc
    rows[:, base] = 0.5 * (qd[:, 6] ** 2) * 0.14
    return rows


def write_run(path: Path, rpm: float = 2500.0, revolutions: float = 5.0, n: int = 2000,
              model: Model | None = None) -> Model:
    """Write a synthetic run of `revolutions` crank turns in `n` samples to `path`."""
    model = model or slider_crank_model(rpm)
    t = np.linspace(0.0, revolutions * 60.0 / rpm, n)
    rows = synthetic_rows(model, t)
    attrs = {"model_source": model.source_text, "model_path": model.source_path,
             "parameters": model.parameters, "version": "test"}
    w = ResultsWriter(path, signal_table(model), attrs)
    w.append(t, rows)
    w.close({"complete": True, "status": "done", "message": "finished", "wall_time": 0.5,
             "t_reached": float(t[-1]), "n_steps": n, "n_outputs": n})
    return model


def write_sweep(path: Path, rpms=(800.0, 1200.0, 2500.0, 5000.0), revolutions: float = 5.0, n: int = 800) -> None:
    """A sweep file: one run per case under /cases/<k>/, parameters as JSON attributes."""
    import json

    import h5py

    tmp = Path(str(path) + ".case.h5")
    with h5py.File(path, "w") as out:
        for k, rpm in enumerate(rpms):
            write_run(tmp, rpm=rpm, revolutions=revolutions, n=n)
            with h5py.File(tmp, "r") as f:
                g = out.create_group(f"cases/{k}")
                for name in f:
                    f.copy(f[name], g, name=name)
                for key, value in f.attrs.items():
                    g.attrs[key] = value
        out.attrs["sweep_parameters"] = json.dumps({"speed": [f"{r:g} rpm" for r in rpms]})
    tmp.unlink()
