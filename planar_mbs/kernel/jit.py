"""The one decorator of every kernel: ``@kernel``.

* ``cache=True``: compiled code is stored next to the sources and reused by
  later processes.  When the package directory is not writable (a read-only or
  system install) numba falls back to the user's cache directory
  (``~/.cache/numba`` or ``$XDG_CACHE_HOME/numba``); ``NUMBA_CACHE_DIR`` chooses
  one explicitly.  Numba alone checks only each kernel's own source file, so
  editing `contact.py` would leave the cached time loop (in `loop.py`) running
  the old contact physics; here every kernel's cache stamp also holds a hash of
  all the sources the kernels are compiled from (`KERNEL_SOURCES`), so a change
  to any of them recompiles every kernel.
  First compilation of all kernels: about 30 s (docs/benchmarks.md).
* ``error_model="numpy"``: a division by zero gives inf/NaN, which the time
  loop reports as a non-finite state, instead of raising inside compiled code.
* ``_nrt=False``: no numba runtime reference counting.  The kernels never
  allocate (workspaces are made once in Python), and with the runtime on,
  every call between kernels increfs and decrefs each array of the ~25-array
  `KernelModel` and the workspace with atomic operations: measured 5.4 µs per
  right-hand side of Muvengei et al.'s slider-crank with it, 0.9 µs without.
* ``@kernel(inline=True)``: numba inlines the function into its callers.  A call that is
  not inlined passes every array of a tuple argument as separate values (the ~25 arrays of
  `KernelModel`, ~30 of the workspace: a few hundred words per call).  Inlining the applied
  forces, the constraint rows, the Schur factorisation and the multiplier solve into
  `accelerations` took one right-hand side of the clearance slider-crank from 4.1x to 2.9x
  the hand-specialised yardstick (`benchmarks/run.py --only rhs`), and `accelerations` into
  `rhs` its time loop from 25.6 to 23 ms; `rhs` inlined at DOPRI5's one stage call site
  (`dynamics.rhs_inlined`) took it to 20.4 ms for 8 s more of first compilation (50 to 58 s).
  Inlining `rhs` at every call site doubled that compilation (94 s); at DOP853's stage call
  site as well it took DOP853's loop on the same model from 39.6 to 34.5 ms (rtol 1e-8, medians
  of 3 x 11, interleaved) for 7 s more of first compilation, which every model pays (`advance`
  compiles all methods): not taken.  Inlining small helpers
  (`jac_dot`) made it slower: each use is measured, not assumed.
* `observe` is inlined at its one call site in the time loop (`loop.observe_inlined` in `loop._emit`,
  which also writes a run's first row and a last sample off the grid): one output row of the
  slider-crank with every signal 0.94 -> 0.70-0.80 us in the loop (1.27 -> 1.01-1.21 us with the
  HDF5 file), the clearance slider-crank's loop 113x -> 116-125x the scipy baseline, and first
  compilation unchanged (72 s before, 68 s after, back to back): `_emit` had been compiled twice,
  once for a literal 0 argument.  numba compiles a function once more for each literal argument
  (a constant int or bool), so the time loop passes none to the kernels that hold big inlined code.
* A cached kernel loads without numba's target-context refresh (`_FunctionCache.load_overload`):
  the refresh imports and registers every implementation numba has, among them its array functions,
  whose import-time BLAS check imports scipy.linalg; about 0.25 s of a warm `mbs run` whose kernels
  make no BLAS call and need none of it.
* A cached kernel's library loads without parsing its linking bitcode (`_unserialize`), which numba
  needs only to compile another function against it; its defined symbols are read from the object
  file's symbol table: 40-60 ms of a warm `mbs run` (the time loop's library is 0.8 MB of bitcode).
"""
from __future__ import annotations

import hashlib
from pathlib import Path

from numba import njit
from numba.core import caching

_HERE = Path(__file__).resolve().parent
# every file a kernel is compiled from: the kernel modules, the model's codes and layouts, and
# the catalog the kernels' constants (law count, rows per joint type, stage buffers) come from
KERNEL_SOURCES = tuple(sorted(_HERE.glob("*.py"))) + (_HERE.parent / "model.py", _HERE.parent / "catalog.py")


def source_hash(paths=KERNEL_SOURCES) -> str:
    """SHA-256 over the names and contents of `paths`."""
    h = hashlib.sha256()
    for p in paths:
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()


SOURCE_HASH = source_hash()


_WRITABLE: set[str] = set()  # cache folders found writable in this process


class _Stamped:
    """A numba cache locator whose source stamp also holds SOURCE_HASH: a cached
    kernel whose index was written with other kernel sources is not loaded.  Its folder
    is made and tried for writing once per process, not once per kernel."""

    def get_source_stamp(self):
        return (super().get_source_stamp(), SOURCE_HASH)

    def ensure_cache_path(self):
        path = self.get_cache_path()
        if path not in _WRITABLE:
            super().ensure_cache_path()
            _WRITABLE.add(path)


class _UserProvided(_Stamped, caching.UserProvidedCacheLocator):
    pass


class _InTree(_Stamped, caching.InTreeCacheLocator):
    pass


class _UserWide(_Stamped, caching.UserWideCacheLocator):
    pass


def defined_symbols(object_code: bytes) -> set[str] | None:
    """Names of the functions and data an ELF object file defines (its symbol table), or None for
    another object format.  The same set numba takes from the library's linking bitcode."""
    import struct

    import llvmlite.binding as ll

    if object_code[:4] != b"\x7fELF" or object_code[4] != 2 or object_code[5] != 1:
        return None  # not 64-bit little-endian ELF
    sections = {s.name(): s.data() for s in ll.ObjectFileRef.from_data(object_code).sections()}
    symtab, strtab = sections.get(b".symtab"), sections.get(b".strtab")
    if symtab is None or strtab is None:
        return None
    names = set()
    for offset in range(0, len(symtab), 24):  # Elf64_Sym: name, info, other, section index, value, size
        name, info, _, section, _, _ = struct.unpack_from("<IBBHQQ", symtab, offset)
        if name and section != 0 and (info & 0xF) not in (3, 4):  # defined; not a section or file symbol
            names.add(strtab[name:strtab.index(b"\0", name)].decode())
    return names


def _unserialize(codegen, state):
    """numba's loading of a cached library (`CPUCodeLibrary._unserialize`), without parsing the
    library's linking bitcode unless another function is compiled against it: that parse was 40-60 ms
    of a warm `mbs run` (the time loop's library is 0.8 MB of bitcode), and a run compiles nothing.
    The defined symbols come from the object file's symbol table instead."""
    from functools import partial

    name, kind, data = state
    symbols = defined_symbols(data[0]) if kind == "object" else None
    if symbols is None:
        return codegen._library_class._unserialize(codegen, state)
    object_code, linking_bitcode = data
    library = codegen.create_library(name)
    library.enable_object_caching()
    library._set_compiled_object(object_code)
    library._finalize_final_module()
    codegen._engine._defined_symbols |= symbols
    library._get_module_for_linking = partial(_module_for_linking, library, linking_bitcode)
    return library


def _module_for_linking(library, linking_bitcode):
    """The bitcode parsed when a new function links to a cached library (numba's
    ``_get_module_for_linking`` of a loaded library returns exactly this module)."""
    if library._shared_module is None:
        import llvmlite.binding as ll

        library._shared_module = ll.parse_bitcode(linking_bitcode)
    return library._shared_module


class _Impl(caching.CompileResultCacheImpl):
    _locator_classes = [_UserProvided, _InTree, _UserWide]

    def rebuild(self, target_context, payload):
        """numba's rebuild with `_unserialize` for the library."""
        codegen = target_context.codegen()
        codegen.unserialize_library = lambda state: _unserialize(codegen, state)
        try:
            return super().rebuild(target_context, payload)
        finally:
            del codegen.unserialize_library


class _FunctionCache(caching.FunctionCache):
    _impl_class = _Impl

    def load_overload(self, sig, target_context):
        """numba's ``load_overload`` without its first step, ``target_context.refresh()``, which
        imports and registers every implementation numba has (arrays, strings, lists, random, ...)
        and compiles its reference-counting runtime: about 0.25 s of a warm `mbs run`.  A cached
        kernel is machine code that calls only numba's C helpers and Python's own functions, which
        the target context installs when it is created; a kernel that has to be compiled (a cache
        miss) goes through numba's compiler, which refreshes the context itself."""
        guard = getattr(self, "_guard_against_spurious_io_errors", None)
        if guard is None or not hasattr(self, "_load_overload"):
            return super().load_overload(sig, target_context)
        with guard():
            return self._load_overload(sig, target_context)
        return None  # the guard swallowed an error: compile, as numba does


_njit = njit(error_model="numpy", _nrt=False)  # cache=True would make numba's own cache, replaced at once


_njit_inline = njit(error_model="numpy", _nrt=False, inline="always")  # the same, inlined into callers by numba


def kernel(func=None, *, inline=False):
    """``njit`` with the options above and the source-hash-stamped cache.
    ``@kernel(inline=True)``: inlined into its callers by numba (IR level)."""
    if func is None:
        return lambda f: kernel(f, inline=inline)
    dispatcher = (_njit_inline if inline else _njit)(func)
    dispatcher._cache = _FunctionCache(func)
    return dispatcher
