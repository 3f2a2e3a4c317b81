"""`kernel.loop_opt_level`: LLVM's O1 for the own libraries of `loop.advance` and `loop._emit`, numba's O3
for every other.
What it saves and that results are bit-identical are measured (docs/benchmarks.md, "Start-up"); here,
that it picks that one library and leaves every other to numba."""
from __future__ import annotations

from types import SimpleNamespace

from planar_mbs.kernel import loop, loop_opt_level as L


def _module(*names):
    return SimpleNamespace(functions=[SimpleNamespace(name=n) for n in names])


def test_only_the_time_loops_and_emits_own_libraries_are_light():
    advance = "_ZN10planar_mbs6kernel4loop7advanceB2v1B46c8tJTIeFIjx"
    assert L.is_light(SimpleNamespace(name="advance"), _module("cfunc." + advance, advance))
    assert L.is_light(SimpleNamespace(name="_emit"), _module("_ZN10planar_mbs6kernel4loop5_emitB3v28"))
    assert not L.is_light(SimpleNamespace(name="rk_stages"),
                          _module("_ZN10planar_mbs6kernel11integrators9rk_stagesB3v12"))
    # a user's function of the same name, elsewhere, is numba's
    assert not L.is_light(SimpleNamespace(name="advance"), _module("_ZN8__main__7advanceB2v1"))
    assert not L.is_light(SimpleNamespace(name="_emit"), _module("_ZN8__main__5_emitB2v1"))


def test_the_loop_is_compiled_with_it_where_numba_is_as_checked():
    """Applied at this process's first compilation (the suite compiles or loads the loop); numba's own
    optimisation back by `undo`, and applied again."""
    assert L.applicable()
    assert L.apply() and L.is_applied()
    L.undo()
    assert not L.is_applied()
    assert L.apply() and L.is_applied()
    for name, mangled in L.LIGHT.items():
        assert getattr(loop, name).py_func.__name__ == name and mangled.endswith(f"{len(name)}{name}")
