"""Hand-built KernelModel fixtures (arrays only, no compiler) for the kernel tests.

Each builder returns ``(km, q0, qd0)`` with consistent initial conditions.
"""
from __future__ import annotations

import math

import numpy as np

from planar_mbs.kernel import kernel_model
from planar_mbs.mechanism.model import (
    CP_CLEARANCE, CP_EXPONENT, CP_R_BEARING, CP_R_JOURNAL, CP_RESTITUTION, CP_SIGMA_SUM, CP_STIFFNESS,
    CP_LENGTH, JOINT_ROWS, JP, N_CLEARANCE_PARAM, N_CONTACT_STATE, N_FORCE_PARAM, N_JOINT_PARAM, N_MOTION_PARAM,
    ContactLaw, DriverType, ForceType, JointType, KernelModel, MotionType, Settings, Integrator,
)


def build(bodies, joints=(), drivers=(), clearances=(), forces=(), gravity=(0.0, 0.0)) -> KernelModel:
    """bodies: [(mass, inertia)]; joints: [dict(type, bodies=(i, j), points=((sx, sy), (sx, sy)),
    axis=(ux, uy), and a value per joint_param column: phi0=0, length=0, ...)]; drivers: [dict(type, bodies, points, axis, motion, params)];
    clearances: [dict(bodies, points, law, params={CP_*: value})];
    forces: [dict(type, bodies, points, params)]."""
    nb = len(bodies)
    mass = np.array([b[0] for b in bodies], float)
    inertia = np.array([b[1] for b in bodies], float)
    minv = np.empty(3 * nb)
    minv[0::3] = 1.0 / mass
    minv[1::3] = 1.0 / mass
    minv[2::3] = 1.0 / inertia
    nj = len(joints)
    jt = np.array([int(j["type"]) for j in joints], np.int64)
    jb = np.array([j["bodies"] for j in joints], np.int64).reshape(nj, 2)
    jp = np.array([j.get("points", ((0, 0), (0, 0))) for j in joints], float).reshape(nj, 2, 2)
    ja = np.array([j.get("axis", (1.0, 0.0)) for j in joints], float).reshape(nj, 2)
    jpar = np.zeros((nj, N_JOINT_PARAM))
    for k, j in enumerate(joints):
        for column, c in JP.items():  # phi0, length, ...: the catalog's setting columns
            jpar[k, c] = j.get(column, 0.0)
    rows = JOINT_ROWS[jt] if nj else np.zeros(0, np.int64)
    jrow = np.concatenate([[0], np.cumsum(rows)[:-1]]).astype(np.int64) if nj else np.zeros(0, np.int64)
    m0 = int(rows.sum()) if nj else 0
    nd = len(drivers)
    dt = np.array([int(d["type"]) for d in drivers], np.int64)
    db = np.array([d["bodies"] for d in drivers], np.int64).reshape(nd, 2)
    dp = np.array([d.get("points", ((0, 0), (0, 0))) for d in drivers], float).reshape(nd, 2, 2)
    da = np.array([d.get("axis", (1.0, 0.0)) for d in drivers], float).reshape(nd, 2)
    dm = np.array([int(d.get("motion", MotionType.CONSTANT_SPEED)) for d in drivers], np.int64)
    dmp = np.zeros((nd, N_MOTION_PARAM))
    for k, d in enumerate(drivers):
        p = d.get("params", ())
        dmp[k, : len(p)] = p
    drow = np.arange(m0, m0 + nd, dtype=np.int64)
    nc = len(clearances)
    cb = np.array([c["bodies"] for c in clearances], np.int64).reshape(nc, 2)
    cpt = np.array([c.get("points", ((0, 0), (0, 0))) for c in clearances], float).reshape(nc, 2, 2)
    cl = np.array([int(c["law"]) for c in clearances], np.int64)
    cpar = np.zeros((nc, N_CLEARANCE_PARAM))
    for k, c in enumerate(clearances):
        for key, v in c["params"].items():
            cpar[k, key] = v
    nf = len(forces)
    ft = np.array([int(f["type"]) for f in forces], np.int64)
    fb = np.array([f.get("bodies", (-1, -1)) for f in forces], np.int64).reshape(nf, 2)
    fp = np.array([f.get("points", ((0, 0), (0, 0))) for f in forces], float).reshape(nf, 2, 2)
    fpar = np.zeros((nf, N_FORCE_PARAM))
    for k, f in enumerate(forces):
        p = f.get("params", ())
        fpar[k, : len(p)] = p
    return kernel_model(KernelModel(
        body_mass=mass, body_inertia=inertia, minv=minv, gravity=np.array(gravity, float),
        joint_type=jt, joint_body=jb, joint_point=jp, joint_axis=ja, joint_param=jpar, joint_row=jrow,
        driver_type=dt, driver_body=db, driver_point=dp, driver_axis=da, driver_motion=dm,
        driver_motion_param=dmp, driver_row=drow,
        clearance_body=cb, clearance_point=cpt, clearance_law=cl, clearance_param=cpar,
        force_type=ft, force_body=fb, force_point=fp, force_param=fpar,
    ))


def cfg(integrator=Integrator.DOPRI5, rtol=1e-8, atol=1e-10, step=0.0, output_step=1e-2, alpha=5.0,
        beta=5.0, h_max=0.0, projection=False, h_min=1e-14, max_steps=10_000_000):
    s = Settings(integrator=integrator, rtol=rtol, atol=atol, step=step, output_step=output_step,
                 alpha=alpha, beta=beta, projection=projection, h_min=h_min, max_steps=max_steps)
    c = s.cfg()
    c[5] = h_max  # CFG_HMAX: 0 = no limit inside the kernel
    return c


G = 9.81


def pendulum(L=1.0, m=1.0, I=0.0, theta0=0.5, omega0=0.0, g=G):
    """Rod of length L (CoM at its tip, inertia I about the CoM) hinged at the origin;
    theta measured from the downward vertical; body frame x axis along the rod."""
    km = build([(m, I if I > 0 else 1e-3)],
               joints=[dict(type=JointType.REVOLUTE, bodies=(-1, 0), points=((0, 0), (-L, 0)))],
               gravity=(0.0, -g))
    phi = theta0 - math.pi / 2
    q0 = np.array([L * math.sin(theta0), -L * math.cos(theta0), phi])
    qd0 = np.array([L * math.cos(theta0) * omega0, L * math.sin(theta0) * omega0, omega0])
    return km, q0, qd0


def double_pendulum(L1=1.0, L2=0.8, m1=1.0, m2=0.7, th1=1.2, th2=-0.4, w1=0.0, w2=0.5):
    """Two uniform bars hinged in series at the origin; angles from the downward vertical."""
    I1 = m1 * L1 ** 2 / 12
    I2 = m2 * L2 ** 2 / 12
    km = build([(m1, I1), (m2, I2)], joints=[
        dict(type=JointType.REVOLUTE, bodies=(-1, 0), points=((0, 0), (-L1 / 2, 0))),
        dict(type=JointType.REVOLUTE, bodies=(0, 1), points=((L1 / 2, 0), (-L2 / 2, 0))),
    ], gravity=(0.0, -G))
    e1 = np.array([math.sin(th1), -math.cos(th1)])
    e2 = np.array([math.sin(th2), -math.cos(th2)])
    p1 = 0.5 * L1 * e1
    p2 = L1 * e1 + 0.5 * L2 * e2
    d1 = np.array([math.cos(th1), math.sin(th1)])
    d2 = np.array([math.cos(th2), math.sin(th2)])
    v1 = 0.5 * L1 * w1 * d1
    v2 = L1 * w1 * d1 + 0.5 * L2 * w2 * d2
    q0 = np.array([*p1, th1 - math.pi / 2, *p2, th2 - math.pi / 2])
    qd0 = np.array([*v1, w1, *v2, w2])
    return km, q0, qd0


# Muvengei et al.'s slider-crank (Muvengei et al. §III.A)
L_OA, L_AB = 0.05, 0.12
M_CRANK, I_CRANK = 0.30, 1e-5
M_ROD, I_ROD = 0.21, 2.5e-4
M_SLIDER, I_SLIDER = 0.14, 1e-4
STEEL_SIGMA = (1 - 0.3 ** 2) / 207e9


def _slider_crank(omega, clearance_at_A, law, restitution, clearance, E=207e9):
    joints = [dict(type=JointType.REVOLUTE, bodies=(-1, 0), points=((0, 0), (-L_OA / 2, 0)))]
    clearances = []
    if clearance_at_A:
        RB = 5e-3
        RJ = RB - clearance
        sigma = 2 * (1 - 0.3 ** 2) / E
        K = 4.0 / (3.0 * sigma) * math.sqrt(RB * RJ / (RB - RJ))  # Muvengei et al. eq. 18, concave bearing
        clearances.append(dict(bodies=(0, 1), points=((L_OA / 2, 0), (-L_AB / 2, 0)), law=law, params={
            CP_CLEARANCE: clearance, CP_R_BEARING: RB, CP_R_JOURNAL: RJ, CP_LENGTH: 0.02,
            CP_STIFFNESS: K, CP_EXPONENT: 1.5, CP_RESTITUTION: restitution, CP_SIGMA_SUM: sigma}))
    else:
        joints.append(dict(type=JointType.REVOLUTE, bodies=(0, 1), points=((L_OA / 2, 0), (-L_AB / 2, 0))))
    joints += [
        dict(type=JointType.REVOLUTE, bodies=(1, 2), points=((L_AB / 2, 0), (0, 0))),
        dict(type=JointType.TRANSLATIONAL, bodies=(-1, 2), points=((0, 0), (0, 0)), axis=(1.0, 0.0)),
    ]
    drivers = [dict(type=DriverType.ANGLE, bodies=(-1, 0), motion=MotionType.CONSTANT_SPEED, params=(0.0, omega))]
    km = build([(M_CRANK, I_CRANK), (M_ROD, I_ROD), (M_SLIDER, I_SLIDER)], joints=joints, drivers=drivers,
               clearances=clearances, gravity=(0.0, 0.0))
    # crank and rod collinear along +x, journal centred (Muvengei et al. §III.A)
    q0 = np.array([L_OA / 2, 0, 0, L_OA + L_AB / 2, 0, 0, L_OA + L_AB, 0, 0])
    w_rod = -omega * L_OA / L_AB
    qd0 = np.array([0, omega * L_OA / 2, omega, 0, omega * L_OA + w_rod * L_AB / 2, w_rod, 0, 0, 0])
    return km, q0, qd0


def slider_crank(omega=5000 * 2 * math.pi / 60):
    """Muvengei et al.'s slider-crank with ideal joints, crank driven at constant speed."""
    return _slider_crank(omega, False, None, 0.0, 0.0)


def slider_crank_clearance(omega=5000 * 2 * math.pi / 60, law=ContactLaw.LANKARANI_NIKRAVESH,
                           restitution=0.9, clearance=0.3e-3, E=207e9):
    """Muvengei et al.'s slider-crank with a revolute clearance joint at A (bearing on the crank)."""
    return _slider_crank(omega, True, law, restitution, clearance, E)


def free_journal(m=1.0, I=1e-3, clearance=1e-4, RB=5e-3, K=1e9, n=1.5, law=ContactLaw.HERTZ,
                 restitution=0.9, v0=(0.5, 0.0), offset=(0.0, 0.0)):
    """A free journal body in a bearing fixed to ground at the origin, no gravity."""
    km = build([(m, I)], clearances=[dict(bodies=(-1, 0), points=((0, 0), (0, 0)), law=law, params={
        CP_CLEARANCE: clearance, CP_R_BEARING: RB, CP_R_JOURNAL: RB - clearance, CP_STIFFNESS: K,
        CP_EXPONENT: n, CP_RESTITUTION: restitution, CP_LENGTH: 0.02})])
    q0 = np.array([offset[0], offset[1], 0.0])
    qd0 = np.array([v0[0], v0[1], 0.0])
    return km, q0, qd0


def run(km, q0, qd0, c, t_end, cap=100_000, t0=0.0, contact=None):
    """Run `advance` to t_end in buffer-sized chunks; returns (status, times, rows, y, stats, contact)."""
    from planar_mbs.kernel import advance, make_workspace, nobs
    from planar_mbs.mechanism.model import N_STATS, Status

    ws = make_workspace(km)
    y = np.concatenate([q0, qd0]).astype(float)
    clock = np.array([t0, 0.0, t0])
    if contact is None:
        contact = np.zeros((len(km.clearance_law), N_CONTACT_STATE))
    stats = np.zeros(N_STATS, np.int64)
    out_t = np.zeros(cap)
    out = np.zeros((cap, nobs(km)))
    times, rows = [], []
    while True:
        st, nw = advance(km, c, y, clock, contact, stats, ws, t_end, out_t, out)
        times.append(out_t[:nw].copy())
        rows.append(out[:nw].copy())
        if st != Status.BUFFER_FULL:
            break
    return st, np.concatenate(times), np.concatenate(rows), y, stats, contact
