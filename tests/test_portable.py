"""mechanism/portable.py: the assembly's linear algebra, checked against numpy's LAPACK path (an
independent method) and for the one thing it is for: the same bits whatever BLAS kernel or numpy SIMD
code the processor selects."""
from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planar_mbs.mechanism.portable import matvec, min_norm_step, rotate

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("m, n", [(1, 3), (6, 9), (30, 45), (12, 12)])
def test_the_step_of_a_full_rank_system_is_the_pseudo_inverse_one(m, n):
    rng = np.random.default_rng(m * n)
    A, b = rng.standard_normal((m, n)), rng.standard_normal(m)
    x = min_norm_step(A, b, 1e-9)
    expected = A.T @ np.linalg.solve(A @ A.T, b)  # normal equations of the smallest solution
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-11 * np.abs(expected).max())


def test_a_repeated_and_a_combined_row_add_no_rank_and_the_step_still_meets_them():
    """A redundant joint's rows are combinations of others (consistent right-hand side): the step is
    the smallest that meets all rows, which is lstsq's minimum-norm solution."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((5, 9))
    A = np.vstack([A, A[1], 2 * A[0] - A[3]])
    b = A @ rng.standard_normal(9)
    x = min_norm_step(A, b, 1e-9)
    np.testing.assert_allclose(A @ x, b, atol=1e-12)
    np.testing.assert_allclose(x, np.linalg.lstsq(A, b, rcond=None)[0], atol=1e-12)


def chain_jacobian(bodies: int, rng) -> np.ndarray:
    """A random Jacobian shaped as a chain's: two rows per joint, each on the three coordinates of one or
    two neighbouring bodies, rows shuffled (full row rank)."""
    rows = []
    for b in range(bodies):
        for _ in range(2):
            r = np.zeros(3 * bodies)
            r[3 * b:3 * b + 3] = rng.standard_normal(3)
            if b > 0:
                r[3 * b - 3:3 * b] = rng.standard_normal(3)
            rows.append(r)
    return np.array(rows)[rng.permutation(2 * bodies)]


def test_the_envelope_step_of_a_large_sparse_system_is_the_qr_one():
    """`envelope_step` (A Aᵀ's envelope Cholesky in reverse Cuthill-McKee order) against the QR of
    `min_norm_step` on a shuffled 600-row chain Jacobian: the same smallest solution to rounding; a
    repeated row makes it decline (None), and `min_norm_step` then gives the QR's step, bit for bit."""
    from planar_mbs.mechanism import portable

    rng = np.random.default_rng(3)
    A = chain_jacobian(300, rng)
    b = rng.standard_normal(A.shape[0])
    x = portable.envelope_step(A, b)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(portable, "LARGE_ROWS", 10 ** 9)
        qr = portable.min_norm_step(A, b, 1e-9)
        redundant = np.vstack([A, A[:1]])
        qr_redundant = portable.min_norm_step(redundant, np.r_[b, b[:1]], 1e-9)
    assert np.abs(x - qr).max() <= 1e-12 * np.abs(qr).max()
    assert np.abs(A @ x - b).max() <= 1e-12
    assert portable.envelope_step(redundant, np.r_[b, b[:1]]) is None
    assert np.array_equal(portable.min_norm_step(redundant, np.r_[b, b[:1]], 1e-9), qr_redundant)


def test_a_zero_matrix_gives_a_zero_step():
    assert np.all(min_norm_step(np.zeros((3, 4)), np.ones(3), 1e-9) == 0)


def test_products_and_rotations():
    rng = np.random.default_rng(5)
    A, x = rng.standard_normal((7, 4)), rng.standard_normal(4)
    np.testing.assert_allclose(matvec(A, x), A @ x, rtol=1e-14)
    phi, s = 0.7, np.array([0.3, -1.2])
    R = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
    np.testing.assert_allclose(rotate(phi, s), R @ s, rtol=1e-15)


_ASSEMBLE = """
import hashlib, numpy as np, planar_mbs as mbs
from planar_mbs.mechanism.kinematics import assemble
from planar_mbs.mechanism.portable import min_norm_step
for name in ("slider_crank_clearance_a", "parallelogram_chain", "redundant_rails"):
    q, qd = assemble(mbs.load_model("models/%s.mbs" % name))
    print(hashlib.sha1(q.tobytes() + qd.tobytes()).hexdigest())
import sys; sys.path.insert(0, "tests")
from chains import parallelogram_chain  # 601 rows: the envelope step
q, qd = assemble(mbs.compile_text(parallelogram_chain(150, "shuffled", t_end=0.01)))
print(hashlib.sha1(q.tobytes() + qd.tobytes()).hexdigest())
beam = mbs.load_model("models/slider_crank_flexible_rod_clearance.mbs")  # the beam's M^-1 and band factor
q, qd = assemble(beam)
km = beam.kernel
print(hashlib.sha1(km.beam_minv.tobytes() + km.beam_band.tobytes() + q.tobytes() + qd.tobytes()).hexdigest())
A = np.random.default_rng(0).standard_normal((30, 45))
print(hashlib.sha1(min_norm_step(A, A[:, 0], 1e-9).tobytes()).hexdigest())
print(hashlib.sha1(np.linalg.lstsq(A, A[:, 0], rcond=None)[0].tobytes()).hexdigest())
"""


def _cpu_flags() -> set[str]:
    """The instruction sets this processor has (/proc/cpuinfo's flags; "sse3" is `pni` there)."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    line = next((ln for ln in text.splitlines() if ln.startswith("flags")), "")
    flags = set(line.split(":", 1)[-1].split())
    return flags | ({"sse3"} if "pni" in flags else set())


def test_the_assembled_state_has_the_same_bits_whatever_kernels_the_processor_selects():
    """OpenBLAS picks its kernels by core type and numpy its SIMD loops by instruction set; forcing
    other choices (as another processor would make them) leaves the assembled state of the shipped
    models, a beam's inverse mass and band factor, and the step of a random system bit for bit the same.  The last line, LAPACK's lstsq, is
    the control: it does change with the BLAS kernel, so the forcing takes effect.  Only kernels this
    processor can run are forced (SkylakeX's AVX-512 on a processor without it stops with SIGILL)."""
    if platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip("the forced kernels are x86 names")
    flags = _cpu_flags()
    cores = [("Prescott", "sse3"), ("Haswell", "avx2"), ("SkylakeX", "avx512f")]  # each needs its instructions
    choices = [{}, *({"OPENBLAS_CORETYPE": core} for core, needs in cores if needs in flags),
               {"NPY_DISABLE_CPU_FEATURES": "X86_V3,X86_V4,AVX512_ICL"}]
    prints = []
    for extra in choices:
        env = {**os.environ, **extra}
        out = subprocess.run([sys.executable, "-c", _ASSEMBLE], cwd=ROOT, env=env, capture_output=True,
                             text=True, check=True, timeout=120)
        prints.append(out.stdout.split())
    assert all(p[:6] == prints[0][:6] for p in prints), prints
    assert len({p[6] for p in prints}) > 1, "no forced kernel changed LAPACK's result: the check has no teeth here"
