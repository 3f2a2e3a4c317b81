"""The own libraries of the time loop and of its output row optimised by LLVM at O1; every other
kernel keeps numba's O3.

`loop.advance` is the kernel Python calls.  Its own code is the step control (trial steps, checks,
events, outputs, each once per step); the arithmetic of a step is in the kernels it calls, libraries of
their own optimised at O3 before `advance` links them.  `advance`'s own library is the last part of the
first compilation, after everything it calls, so no helper process can share it (`run.first_compile`);
`loop._emit` (the output row) is the same kind of code.  At O1 the first compilation takes 0.97x the CPU
time (`benchmarks/machinery.py`); the time loop is as fast and the results bit-identical.

It replaces two private methods of numba's ``CPUCodeLibrary`` and calls its codegen's pass-manager
factories with an ``opt`` level, so `kernel.jit` applies it only where its other reliance on numba's
internals was checked (``CHECKED_NUMBA``), at the process's first compilation; elsewhere, and for
every other library, numba optimises as it always does.
"""
from __future__ import annotations

from numba.core import codegen

LEVEL = 1  # LLVM's optimisation level for the libraries of `LIGHT`
# library name -> what the mangled names of that kernel and its wrappers hold
LIGHT = {"advance": "planar_mbs6kernel4loop7advance", "_emit": "planar_mbs6kernel4loop5_emit"}


def is_light(library, module) -> bool:
    """Whether `library` (with its LLVM `module`) is the own library of a kernel of `LIGHT`."""
    mangled = LIGHT.get(library.name)
    return mangled is not None and any(mangled in f.name for f in module.functions)


def _light_functions(optimize_functions):
    def optimize_light_functions(self, ll_module):
        if not is_light(self, ll_module):
            return optimize_functions(self, ll_module)
        self._planar_mbs_light = True  # its final module too (`_light_final_module`)
        ll_module.data_layout = self._codegen._data_layout
        for func in ll_module.functions:
            fpm, pb = self._codegen._function_pass_manager(opt=LEVEL)
            fpm.run(func, pb)

    optimize_light_functions.original = optimize_functions
    return optimize_light_functions


def _light_final_module(optimize_final_module):
    def optimize_light_final_module(self):
        if not getattr(self, "_planar_mbs_light", False):
            return optimize_final_module(self)
        mpm, mpb = self._codegen._module_pass_manager(opt=LEVEL, loop_vectorize=False, slp_vectorize=False)
        mpm.run(self._final_module, mpb)

    optimize_light_final_module.original = optimize_final_module
    return optimize_light_final_module


def applicable() -> bool:
    """Whether numba's code library and codegen have the names `apply` uses."""
    lib = getattr(codegen, "CPUCodeLibrary", None)
    gen = getattr(codegen, "CPUCodegen", None)
    return all(callable(getattr(lib, n, None)) for n in ("_optimize_functions", "_optimize_final_module")) and \
        all(callable(getattr(gen, n, None)) for n in ("_function_pass_manager", "_module_pass_manager"))


def apply() -> bool:
    """Optimise `loop.advance`'s own library at `LEVEL` (once per process); False where it cannot."""
    if is_applied():
        return True
    if not applicable():
        return False
    lib = codegen.CPUCodeLibrary
    lib._optimize_functions = _light_functions(lib._optimize_functions)
    lib._optimize_final_module = _light_final_module(lib._optimize_final_module)
    return True


def is_applied() -> bool:
    return hasattr(codegen.CPUCodeLibrary._optimize_functions, "original")


def undo() -> None:
    """numba's own optimisation for every library again (tests)."""
    if is_applied():
        lib = codegen.CPUCodeLibrary
        lib._optimize_functions = lib._optimize_functions.original
        lib._optimize_final_module = lib._optimize_final_module.original
