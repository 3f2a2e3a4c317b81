"""The compiled-code cache stamp covers every source the kernels are compiled from."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from planar_mbs import catalog
from planar_mbs.kernel.jit import KERNEL_SOURCES

KERNEL = Path(__file__).resolve().parents[1] / "planar_mbs" / "kernel"


def test_every_module_a_kernel_imports_is_hashed_into_the_cache_stamp():
    """A kernel's constants may come from a module outside kernel/ (`..model`, `..catalog`):
    editing that module must recompile the kernels, so it must be among KERNEL_SOURCES."""
    hashed = {p.resolve() for p in KERNEL_SOURCES}
    for src in KERNEL.glob("*.py"):
        assert src.resolve() in hashed, src.name
        for node in ast.walk(ast.parse(src.read_text())):
            if not (isinstance(node, ast.ImportFrom) and node.level == 2):
                continue  # `from ..x import y` and `from .. import x` reach outside kernel/
            names = [node.module] if node.module else [a.name for a in node.names]
            for name in names:
                dep = (KERNEL.parent / (name.replace(".", "/") + ".py")).resolve()
                assert dep in hashed, f"{src.name} imports {name}, not in KERNEL_SOURCES"


@pytest.mark.slow
def test_a_run_compiles_each_row_writing_kernel_once(tmp_path):
    """The time loop and `_emit` (the one place the observation row is compiled, `observe` inlined) have
    one signature after runs of every integrator, with and without a file and through `Simulation`:
    a literal argument (a constant 0 count, a True/False flag) would make numba compile `_emit` once
    more per literal, each copy holding the whole observation.  In a fresh process with an empty
    cache (a dispatcher loaded from the cache lists no overloads of the kernels it calls): about
    a minute of compilation."""
    import os
    import subprocess
    import sys

    code = f"""
import planar_mbs as mbs
from planar_mbs.kernel import loop
m = mbs.load_model({str(KERNEL.parents[1] / 'models' / 'slider_crank_clearance_a.mbs')!r})
for integ in {[s.name for s in catalog.INTEGRATORS if s.dense != "none"]!r}:
    mbs.simulate(m, t_end=2e-3, integrator=integ, step=1e-6)
mbs.simulate(m, t_end=2e-3, output={str(tmp_path / 'a.h5')!r}, signals=["A"])
with mbs.Simulation(m, t_end=2e-3) as sim:
    sim.step("1 ms")
    sim.run()
from planar_mbs.kernel.jit import native
print(len(loop.advance.overloads), len(native(loop._emit).overloads), len(loop._emit.overloads),
      len(loop.observe.overloads))
"""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1800, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    # `_emit` once, the version kernels call; the versions Python calls (wrappers) of `_emit` and the
    # public `observe` are compiled only when Python calls them
    assert out.stdout.split() == ["1", "1", "0", "0"]


CACHED_LOAD = """
import llvmlite.binding as ll
import numpy as np
parsed = []
parse_bitcode = ll.parse_bitcode
ll.parse_bitcode = lambda data: parsed.append(len(data)) or parse_bitcode(data)
from numba import njit
import planar_mbs.kernel.jit as jit
from planar_mbs.kernel.dynamics import kinetic_energy2
loads = []
unserialize = jit._unserialize
jit._unserialize = lambda codegen, state: loads.append(state) or unserialize(codegen, state)
minv, qd = np.array([0.5, 2.0, 4.0]), np.array([1.0, 2.0, -3.0])
print(kinetic_energy2(minv, qd), len(parsed))
@njit
def twice(m, v):
    return 2.0 * kinetic_energy2(m, v)
print(twice(minv, qd), len(parsed))
library = kinetic_energy2.overloads[kinetic_energy2.signatures[0]].library
module = library._get_module_for_linking()
linked = {f.name for f in module.functions if not f.is_declaration}
linked |= {g.name for g in module.global_variables if not g.is_declaration}
print(jit.defined_symbols(loads[0][2][0]) == linked if loads else "compiled")  # object code of the cache
"""


def test_a_cached_kernel_loads_without_parsing_its_bitcode_and_still_links(tmp_path):
    """A kernel loaded from the cache does not parse its linking bitcode (`jit._unserialize`), gives the
    same answer, and a new function compiled against it still links (the bitcode parsed then); the
    symbols read from the object file are the ones numba takes from that bitcode."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    expected = 1.0 / 0.5 + 4.0 / 2.0 + 9.0 / 4.0  # q'^T M q', M = 1 / minv
    runs = [subprocess.run([sys.executable, "-c", CACHED_LOAD], capture_output=True, text=True, timeout=600, env=env)
            for _ in range(2)]
    for run in runs:
        assert run.returncode == 0, run.stderr
    value, parsed_before = runs[1].stdout.split("\n")[0].split()
    assert float(value) == expected and parsed_before == "0"  # loaded from the cache, nothing parsed
    value, parsed_after = runs[1].stdout.split("\n")[1].split()
    assert float(value) == 2 * expected and int(parsed_after) >= 1  # linking parsed the bitcode
    assert runs[1].stdout.split("\n")[2] == "True"


TWINS = """
from planar_mbs.kernel.jit import kernel


@kernel
def inner(a, x):
    return a[0] * x


@kernel
def outer(a):
    return inner(a, 2.0) + 1.0
"""
TWIN_RUN = """
import sys
import numpy as np
import twins
from planar_mbs.kernel.jit import native
a = np.array([3.0])
value = twins.outer(a) if sys.argv[1] == "outer" else twins.inner(a, 2.0)
def kinds(dispatcher):  # the functions of twins.py a compiled version defines: itself and wrappers
    names = {f.name for o in dispatcher.overloads.values() for f in o.library._final_module.functions
             if not f.is_declaration and "5twins" in f.name}
    return "+".join(sorted({"cfunc" if n.startswith("cfunc.") else "cpython" if "7cpython" in n else "native"
                            for n in names})) or "none"
print(value, kinds(twins.inner), kinds(native(twins.inner)), kinds(twins.outer))
"""


def test_a_kernel_called_only_by_kernels_is_compiled_without_wrappers_and_cached_apart(tmp_path):
    """`jit.native`: a kernel that another kernel calls is compiled there without numba's CPython and
    C wrappers; Python calling it later (another process, the same cache) gets its own version with
    them, not the cached one without, which would crash the interpreter (numba's cache index is
    keyed by the signature alone).  Values against the kernels' arithmetic, 3 * 2 (+ 1)."""
    import os
    import subprocess
    import sys

    (tmp_path / "twins.py").write_text(TWINS)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(tmp_path))
    outs = [subprocess.run([sys.executable, "-c", TWIN_RUN, which], capture_output=True, text=True, timeout=600,
                           env=env, cwd=tmp_path) for which in ("outer", "inner", "inner")]
    for out in outs:
        assert out.returncode == 0, out.stderr[-2000:]
    first, second, third = (out.stdout.split() for out in outs)
    # first process: `outer` with its wrappers, `inner` only without (called by `outer`)
    assert float(first[0]) == 7.0 and first[1:] == ["none", "native", "cfunc+cpython+native"]
    # a later process calls `inner` from Python: compiled with its wrappers, the native one not touched
    assert float(second[0]) == 6.0 and second[1:] == ["cfunc+cpython+native", "none", "none"]
    assert float(third[0]) == 6.0  # and loaded from the cache
    index = sorted(p.name.split("-")[0] + ("-native" if "-native-" in p.name else "")
                   for p in (tmp_path / "cache").rglob("*.nbi"))
    assert index == ["twins.inner", "twins.inner-native", "twins.outer"]
