"""Constraint kernel vs finite differences (a slow numpy reference).

For every joint type of the catalog and every driver type (bodies and ground on either side,
every motion type) at random states:

* Cq = dC/dq by central differences;
* Ct = dC/dt at fixed q by central differences;
* gamma: along q(s) = q + q' s + q'' s^2/2, t + s, the identity
  d/ds (Cq q' + Ct) = Cq q'' - gamma gives gamma by one central difference.
"""
from __future__ import annotations

import numpy as np
import pytest

from kernel_models import build
from planar_mbs import catalog
from planar_mbs.kernel import constraint_eval, constraint_rows
from planar_mbs.mechanism.model import DriverType, JointType, MotionType, frozen

rng = np.random.default_rng(1234)


def _pt():
    return tuple(rng.uniform(-0.5, 0.5, 2))


def _axis():
    a = rng.normal(size=2)
    return tuple(a / np.linalg.norm(a))


def _joint(spec, bodies):
    """A joint of a catalog type with a random value of each of its settings."""
    j = dict(type=JointType(spec.code), bodies=bodies, points=(_pt(), _pt()))
    for s in spec.settings:
        if s.unit == "direction":
            j["axis"] = _axis()
        else:
            j[s.column] = float(rng.uniform(0.2, 0.8))
    return j


def all_types_model():
    """Every joint type of the catalog twice (between bodies, and with ground on one side), every
    driver and motion type."""
    joints = []
    for spec in catalog.JOINTS:
        a = spec.code % 4
        joints += [_joint(spec, (a, (a + 1) % 4)), _joint(spec, (-1, a) if spec.code % 2 else (a, -1))]
    D, M = DriverType, MotionType
    drivers = [
        dict(type=D.ANGLE, bodies=(-1, 0), motion=M.CONSTANT_SPEED, params=(0.2, 3.0)),
        dict(type=D.ANGLE, bodies=(1, 2), motion=M.RAMP, params=(0.1, 2.0, 0.5)),
        dict(type=D.POSITION, bodies=(0, 3), points=(_pt(), _pt()), axis=_axis(), motion=M.HARMONIC,
             params=(0.1, 0.3, 1.7, 0.4)),
        dict(type=D.POSITION, bodies=(-1, 1), points=(_pt(), _pt()), axis=_axis(), motion=M.POLYNOMIAL,
             params=tuple(rng.uniform(-1, 1, 8))),
        dict(type=D.POSITION, bodies=(2, -1), points=(_pt(), _pt()), axis=_axis(), motion=M.RAMP,
             params=(0.0, 1.5, 0.0)),
        dict(type=D.ANGLE, bodies=(3, 0), motion=M.EXPRESSION, params=(0.0,)),
    ]
    bodies = [(1.0 + k, 0.1 + 0.05 * k) for k in range(4)]
    return frozen(build(bodies, joints=joints, drivers=drivers)._replace(**_motion_program()))


def _motion_program():
    """The program of the EXPRESSION driver: functions, a quotient and a table of t, so that the
    finite differences below check its f' and f'' (dual numbers) too."""
    from planar_mbs.language.evaluate import Evaluator
    from planar_mbs.mechanism.expressions import Context, Programs
    from planar_mbs.language.parse import parse_expression
    from planar_mbs.language.units import ANGLE

    text = ("0.3 rad * sin(2 rad/s * t + 0.4) * exp(-t / 1.5 s) + 0.2 * atan2(t, 0.7 s) + 0.1 * sqrt(1 + t^2 / 1 s^2)"
            " + 0.05 rad * (t / 1 s)^3 / (1 + t / 1 s) + table(x = t, xs = (-1 s, 0 s, 0.5 s, 2 s, 3 s), "
            "ys = (0.1 rad, 0 rad, 0.2 rad, -0.1 rad, 0 rad), interpolation = akima) + cos(3 rad/s * t) * log(2 + t / 1 s)")
    progs = Programs(Evaluator({}, {}, {}, set()), Context({}, np.zeros(0), np.zeros(0), {}, {}))
    progs.program(parse_expression(text, "test"), ANGLE, "the test motion", state=False)
    return progs.arrays()


KM = all_types_model()
N = 12
M = constraint_rows(KM)


def evaluate(q, qd, t):
    C, Ct, g = np.zeros(M), np.zeros(M), np.zeros(M)
    Cq = np.zeros((M, N))
    assert constraint_eval(KM, q, qd, t, C, Cq, Ct, g) == 0
    return C, Cq, Ct, g


@pytest.mark.parametrize("t", [0.2, 0.8])  # the ramp driver before and after its ramp time
@pytest.mark.parametrize("seed", range(3))
def test_jacobian_ct_gamma_vs_finite_differences(t, seed):
    r = np.random.default_rng(seed)
    q = r.uniform(-1, 1, N) * np.tile([0.5, 0.5, 3.0], 4)
    qd = r.uniform(-2, 2, N)
    qdd = r.uniform(-3, 3, N)
    C, Cq, Ct, g = evaluate(q, qd, t)
    eps = 1e-6
    Cq_fd = np.zeros_like(Cq)
    for k in range(N):
        dq = np.zeros(N)
        dq[k] = eps
        Cq_fd[:, k] = (evaluate(q + dq, qd, t)[0] - evaluate(q - dq, qd, t)[0]) / (2 * eps)
    np.testing.assert_allclose(Cq, Cq_fd, atol=1e-8)
    Ct_fd = (evaluate(q, qd, t + eps)[0] - evaluate(q, qd, t - eps)[0]) / (2 * eps)
    np.testing.assert_allclose(Ct, Ct_fd, atol=1e-7)

    def velocity_constraint(s):
        _, Cq_s, Ct_s, _ = evaluate(q + qd * s + 0.5 * qdd * s * s, qd + qdd * s, t + s)
        return Cq_s @ (qd + qdd * s) + Ct_s

    h = 1e-5
    dvc = (velocity_constraint(h) - velocity_constraint(-h)) / (2 * h)
    g_fd = Cq @ qdd - dvc
    np.testing.assert_allclose(g, g_fd, atol=1e-6 * (1 + np.abs(g).max()))


def test_every_type_is_covered():
    assert set(KM.joint_type.tolist()) == {int(j) for j in JointType}
    assert set(KM.driver_type.tolist()) == {int(d) for d in DriverType}
    assert set(KM.driver_motion.tolist()) == {int(m) for m in MotionType}


def test_unknown_joint_type_is_bad_input():
    jt = KM.joint_type.copy()
    jt[0] = 99
    km = frozen(KM._replace(joint_type=jt))
    C, Ct, g = np.zeros(M), np.zeros(M), np.zeros(M)
    assert constraint_eval(km, np.zeros(N), np.zeros(N), 0.0, C, np.zeros((M, N)), Ct, g) == 7
