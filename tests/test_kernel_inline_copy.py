"""numba's inliner with one scope copy per inlining (`kernel/inline_copy.py`): the same code, less copying."""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numba import njit
from numba.core import inline_closurecall

from planar_mbs.kernel import inline_copy, jit

MODEL = Path(__file__).resolve().parents[1] / "models" / "slider_crank_clearance_a.mbs"


def _make_caller():
    """A fresh caller (numba compiles it anew) of an inlined callee with several blocks and variables."""
    @njit(inline="always")
    def callee(x, n):
        total = 0.0
        for i in range(n):
            if x[i] > 0.5:
                total += x[i] * x[i]
            else:
                total -= x[i]
        return total / max(n, 1)

    @njit
    def caller(x):
        return callee(x, x.shape[0]) + callee(x[::-1], x.shape[0] - 1)

    return caller


@contextlib.contextmanager
def _recording():
    """The callee copies numba's inliner makes meanwhile (its unrenamed copy of each call site)."""
    seen = []
    inline_ir = inline_closurecall.InlineWorker.inline_ir

    def recording(self, *args, **kwargs):
        result = inline_ir(self, *args, **kwargs)
        seen.append(result[0])
        return result

    inline_closurecall.InlineWorker.inline_ir = recording
    try:
        yield seen
    finally:
        inline_closurecall.InlineWorker.inline_ir = inline_ir


def _scopes(seen) -> list[int]:
    return [len({id(block.scope) for block in ir.blocks.values()}) for ir in seen]


@pytest.mark.skipif(not inline_copy.applicable() and not inline_copy.is_applied(), reason="numba's inliner differs")
def test_an_inlined_callee_is_copied_with_one_scope_and_computes_the_same(monkeypatch):
    """numba's own inliner copies the callee's scope once per block (the quadratic cost the module
    removes); with `apply` the copied blocks share one scope, as the callee's own blocks do, and the
    compiled caller gives the same numbers."""
    x = np.linspace(0.0, 1.0, 11)
    was, apply = inline_copy.is_applied(), inline_copy.apply
    monkeypatch.setattr(inline_copy, "apply", lambda: False)  # `kernel.jit`'s compile event: not now
    try:
        inline_copy.undo()
        with _recording() as seen:
            plain = _make_caller()
            plain_value = plain(x)
        numba_scopes = _scopes(seen)
        assert apply()
        with _recording() as seen:
            shared = _make_caller()
            shared_value = shared(x)
        shared_scopes = _scopes(seen)
    finally:
        inline_copy.undo()
        if was:
            apply()
    assert len(numba_scopes) == len(shared_scopes) == 2  # two call sites
    assert min(numba_scopes) > 1  # numba's own: a scope per block
    assert shared_scopes == [1, 1]
    expected = plain.py_func(x)  # the caller as Python, calling the callee compiled on its own
    assert shared_value == plain_value
    assert shared_value == pytest.approx(expected, rel=1e-15)


def test_apply_and_undo_are_idempotent():
    was = inline_copy.is_applied()
    try:
        inline_copy.undo()
        inline_copy.undo()
        assert inline_closurecall.copy.__name__ == "copy"
        if inline_copy.applicable():
            assert inline_copy.apply() and inline_copy.apply()
            assert inline_copy.is_applied()
            original = inline_closurecall.InlineWorker.inline_ir.original
            assert not hasattr(original, "original")  # wrapped once, not twice
    finally:
        (inline_copy.apply if was else inline_copy.undo)()


def test_the_first_compilation_of_a_process_applies_it_where_numbas_internals_were_checked():
    """`kernel.jit` turns it on at the first compile event where it uses numba's internals anyway
    (the fast cache path), and leaves numba alone on the public path."""
    code = ("from numba import njit\nfrom planar_mbs.kernel import inline_copy, jit\n"
            "before = inline_copy.is_applied()\nnjit(lambda a: a + 1)(1)\n"
            "print(before, inline_copy.is_applied(), jit._CACHE_CLASS is not None)")
    for public in ("0", "1"):
        env = dict(os.environ, PLANAR_MBS_PUBLIC_CACHE=public)
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
        assert out.returncode == 0, out.stderr[-2000:]
        before, after, fast = out.stdout.split()
        assert before == "False"
        assert fast == ("True" if public == "0" and jit.fast_path_problem() is None else "False")
        assert after == fast


@pytest.mark.slow
def test_the_time_loop_compiled_with_numbas_own_inliner_gives_bit_identical_results(tmp_path):
    """The whole time loop compiled twice from empty caches, with and without the shared scope copy:
    every signal of a clearance run with contact events, bit for bit (about three minutes)."""
    code = f"""
import sys, numpy as np
from planar_mbs.kernel import inline_copy
if sys.argv[1] == "numba":
    inline_copy.apply = lambda: False
import planar_mbs as mbs
r = mbs.simulate(mbs.load_model({str(MODEL)!r}), t_end="0.05 s")
np.savez(sys.argv[2], time=r.time, **r.signals)
print(inline_copy.is_applied())
"""
    for which in ("numba", "shared"):
        env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / which))
        out = subprocess.run([sys.executable, "-c", code, which, str(tmp_path / f"{which}.npz")],
                             capture_output=True, text=True, env=env, timeout=1800)
        assert out.returncode == 0, out.stderr[-2000:]
        assert out.stdout.split()[-1] == ("False" if which == "numba" else str(jit._CACHE_CLASS is not None))
    a, b = np.load(tmp_path / "numba.npz"), np.load(tmp_path / "shared.npz")
    assert sorted(a.files) == sorted(b.files) and len(a.files) > 10
    for name in a.files:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
