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
  First compilation of all kernels: docs/benchmarks.md ("Start-up").
* ``error_model="numpy"``: a division by zero gives inf/NaN, which the time
  loop reports as a non-finite state, instead of raising inside compiled code.
* ``_nrt=False``: no numba runtime reference counting.  The kernels never
  allocate (workspaces are made once in Python), and with the runtime on,
  every call between kernels increfs and decrefs each array of `KernelModel` (36 arrays today)
  and the workspace (30) with atomic operations: measured 5.4 µs per
  right-hand side of Muvengei et al.'s slider-crank with it, 0.9 µs without.
* ``@kernel(inline=True)``: numba inlines the function into its callers.  A call that is
  not inlined passes every array of a tuple argument as separate values (the 36 arrays of
  `KernelModel`, 30 of the workspace: a few hundred words per call).  Inlining the applied
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
* A kernel that is not inlined is a library of its own, into which numba links the code of every
  kernel it calls and then optimises and emits machine code for all of it again (LLVM is about half
  of the first compilation: benchmarks/compile_profile.py).  So a kernel with one call site and no
  caller in Python is inlined there (`passage_check`, `initial_step`, `refine`, `flip_switch` and the
  event helpers `event_possible`, `locate_switch`, `_peak`, `_crossing`, `_illinois_rate`): its code
  is optimised and emitted once, in its caller, instead of also in a library of its own.  With
  `inline_copy` (below) making numba's inlining cheap, one process's first compilation took 74.3 s of
  CPU against 79.6 s (LLVM 45.8 s against 51.5 s, a pair side by side) and the README's first command
  49.8-53.4 s against 53.4-61.3 s (five and four cold runs alternating, 2 idle cores), results
  bit-identical on every shipped model with DOPRI5, RK4 and DOP853, the time loop as fast.  Before
  `inline_copy`, inlining `fixed_step`, `passage_check`, `dense_prepare` and `initial_step` had made
  it longer (101.6 s against 94.5 s).  Inlining 23 more kernels of one call site made it longer again
  (86.5 s against 78.7 s): those land in `_emit` and `project`, whose front end grew by 11 and 4.5 s.
* The steps of `loop.advance` (`_resume`, `_adaptive`, `_contact_event`, `_end_step`, ...) are
  inlined at their one call site each: the loop reads as named steps and compiles to what it was as
  one function (bit-identical results on every shipped model, same speed).  The first compilation
  got longer: 4 % of CPU in one process (115.2 s against 110.9 s, side by side, compile events per
  kernel: `advance`'s own share did not grow), 10-14 % for the README's first command with the
  compile helper (docs/benchmarks.md, "Start-up"); not explained yet.  Only the steps called once per
  call of `advance` could be left to a call at no run-time cost, and those that reach `_emit` or `rhs`
  would then be libraries that compile those again.
* `observe` is inlined at its one call site in the time loop (`loop.observe_inlined` in `loop._emit`,
  which also writes a run's first row and a last sample off the grid): one output row of the
  slider-crank with every signal 0.94 -> 0.70-0.80 us in the loop (1.27 -> 1.01-1.21 us with the
  HDF5 file), the clearance slider-crank's loop 113x -> 116-125x the scipy baseline, and first
  compilation unchanged (72 s before, 68 s after, back to back): `_emit` had been compiled twice,
  once for a literal 0 argument.  numba compiles a function once more for each literal argument
  (a constant int or bool), so the time loop passes none to the kernels that hold big inlined code.
* numba's IR inliner copies a callee's whole variable scope once per block at each inlined call site
  (numba issue #8989); `inline_copy` makes it copy the scope once per call site, applied at this
  process's first compilation where the fast path below is used: the first compilation of the time loop
  in one process 84.8 s and 81.8 s of CPU against 103.3 s and 97.9 s with numba's own inliner (two pairs
  run side by side, 2 cores), front end (typing and lowering) about a third shorter, LLVM unchanged.
* `loop.advance`'s own library (the step control; the steps' arithmetic is in the kernels it calls)
  is optimised by LLVM at O1, and so is `loop._emit`'s (the output row), every other kernel at O3
  (`loop_opt_level`, applied as `inline_copy` is): `advance`'s is the last part of the first
  compilation, which no second process can share; 1-4 s of CPU less in three pairs side by side,
  `_emit`'s 3.5 s in one; the time loop as fast, results bit-identical.
* Each kernel that is not inlined has two versions: the one Python calls, with numba's CPython and C
  wrappers (argument unboxing: for the 36 arrays of `KernelModel` and 30 of the workspace, a big
  function of its own that LLVM optimises and emits), and the `native` one that other kernels
  call, compiled without them (numba's ``no_cpython_wrapper``/``no_cfunc_wrapper`` options) and
  cached in files of its own.  A run calls only `advance` from Python, so every other kernel is
  compiled once, without wrappers; a kernel that Python calls as well (a test, `Stepper`'s
  `project`) is compiled a second time, with them, the first time Python calls it.  One process's
  first compilation of the time loop: 59.2 s of CPU against 75.3 s (a pair side by side, 2 cores),
  results bit-identical on every shipped model with DOPRI5, RK4 and DOP853.
* A cached kernel loads without numba's target-context refresh (`_FunctionCache.load_overload`):
  the refresh imports and registers every implementation numba has, among them its array functions,
  whose import-time BLAS check imports scipy.linalg; about 0.25 s of a warm `mbs run` whose kernels
  make no BLAS call and need none of it.
* A cached kernel's library loads without parsing its linking bitcode (`_unserialize`), which numba
  needs only to compile another function against it; its defined symbols are read from the object
  file's symbol table: 40-60 ms of a warm `mbs run` (the time loop's library is 0.8 MB of bitcode).
* The two loading shortcuts and the source-hash stamp use numba's private caching classes, read
  against and tested on numba `CHECKED_NUMBA` (docs/install.md).  Where numba is outside that range
  or lacks one of them (`fast_path_problem`), or `PLANAR_MBS_PUBLIC_CACHE=1`, the kernels go
  through numba's public ``cache=True`` instead, in a cache folder named after `SOURCE_HASH` (the
  stamp by another route), with one line on stderr: same results, slower start-up.
* Where no cache folder can be written (a read-only install, no writable ``~/.cache``, a read-only
  ``NUMBA_CACHE_DIR``), the kernels are cached in a folder of the temporary directory only this user
  can write (numba's cache files are pickles), else compiled in each process; one line says which.
"""
from __future__ import annotations

import hashlib
import importlib
import os
import stat
import struct
import sys
import tempfile
from functools import partial
from pathlib import Path

import llvmlite.binding as ll  # loaded by numba itself
import numba
from numba import njit
from numba.core.registry import CPUDispatcher
from numba.core import event as numba_event  # loaded by numba itself

try:  # numba's private caching module, which the fast loading builds on (`fast_path_problem` checks it)
    from numba.core import caching
except ImportError:  # a numba without it: the public cache path (`fast_path_problem` says why)
    caching = None

_HERE = Path(__file__).resolve().parent
# every file a kernel is compiled from: the kernel modules, the model's codes and layouts, and
# the catalog the kernels' constants (law count, rows per joint type, stage buffers) come from
KERNEL_SOURCES = tuple(sorted(_HERE.glob("*.py"))) + (_HERE.parent / "mechanism" / "model.py", _HERE.parent / "catalog.py")
# the numba releases whose private caching code the fast path was read against and tested on: the
# same code in every release between them (0.61 had other class names)
CHECKED_NUMBA = ((0, 62), (0, 68))
PUBLIC_CACHE_ENV = "PLANAR_MBS_PUBLIC_CACHE"  # set to 1: numba's public cache, as where its internals differ
WITHOUT_ENV = "PLANAR_MBS_WITHOUT"  # experiments: "inline_copy,loop_opt_level" compiles without those


def source_hash(paths=KERNEL_SOURCES) -> str:
    """SHA-256 over the names and contents of `paths`."""
    h = hashlib.sha256()
    for p in paths:
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()


SOURCE_HASH = source_hash()
_NOTED: set[str] = set()


def _note(text: str) -> None:
    """One line on stderr, once per process."""
    if text not in _NOTED:
        _NOTED.add(text)
        print(f"note: {text}", file=sys.stderr, flush=True)


def _writable(path: str) -> bool:
    """Whether `path` is (or can be made) a folder this process can create files in."""
    try:
        os.makedirs(path, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError:
        return False
    return True


_PRIVATE: list[str | None] = []


def private_cache_dir() -> str | None:
    """A cache folder in the temporary directory that only this user can write, or None.  Numba's
    cache index is a pickle, so a folder another user made first (in a shared /tmp), a symbolic
    link or one others can write is never used: a fresh `mkdtemp` folder instead."""
    if _PRIVATE:
        return _PRIVATE[0]
    path = None
    try:
        base = tempfile.gettempdir()
        if hasattr(os, "getuid"):
            mine = os.path.join(base, f"planar_mbs-numba-{os.getuid()}")
            try:
                os.mkdir(mine, 0o700)
            except FileExistsError:
                pass
            st = os.lstat(mine)
            if stat.S_ISDIR(st.st_mode) and st.st_uid == os.getuid() and not st.st_mode & 0o022:
                path = mine
        if path is None or not _writable(path):
            path = tempfile.mkdtemp(prefix="planar_mbs-numba-")
    except OSError:
        path = None
    _PRIVATE.append(path)
    return path


_FALLBACK = ("kernels load through numba's public cache instead (same results, slower start-up)")
_UNCACHED = ("no writable cache folder (the package's, NUMBA_CACHE_DIR, the user cache, the temporary "
             "folder): the kernels are compiled in this process, uncached (about a minute)")


def _private_note(path: str) -> None:
    _note(f"no writable cache folder (the package's, NUMBA_CACHE_DIR, the user cache): compiled kernels "
          f"are kept in {path}")


def fast_path_problem() -> str | None:
    """Why the fast loading (numba's private caching classes) cannot be used here, or None."""
    if os.environ.get(PUBLIC_CACHE_ENV, "") not in ("", "0"):
        return f"{PUBLIC_CACHE_ENV} is set"
    try:
        version = tuple(int(x) for x in numba.__version__.split(".")[:2])
    except ValueError:
        version = None
    (lo, hi), seen = CHECKED_NUMBA, numba.__version__
    if version is None or not lo <= version <= hi:
        return f"numba {seen} is outside the releases planar_mbs's fast loading was checked on " \
               f"({lo[0]}.{lo[1]} to {hi[0]}.{hi[1]})"
    needed = {"numba.core.caching": ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator",
                                     "CompileResultCacheImpl", "FunctionCache", "Cache._load_overload",
                                     "Cache._guard_against_spurious_io_errors", "CacheImpl._locator_classes",
                                     "_CacheLocator.ensure_cache_path"),
              "numba.core.codegen": ("CPUCodeLibrary._unserialize", "CPUCodeLibrary._set_compiled_object",
                                     "CPUCodeLibrary._finalize_final_module",
                                     "CPUCodeLibrary._get_module_for_linking", "JitEngine._load_defined_symbols"),
              "llvmlite.binding": ("ObjectFileRef.from_data", "parse_bitcode")}
    for module, names in needed.items():
        for name in names:
            try:
                obj = importlib.import_module(module)
                for part in name.split("."):
                    obj = getattr(obj, part)
            except (ImportError, AttributeError):
                return f"no {module}.{name} (numba {seen}), which planar_mbs's fast loading uses"
    if not hasattr(njit(lambda: 0), "_cache"):
        return f"numba {seen}'s dispatchers have no _cache, which planar_mbs's fast loading replaces"
    return None


def defined_symbols(object_code: bytes) -> set[str] | None:
    """Names of the functions and data an ELF object file defines (its symbol table), or None for
    another object format.  The same set numba takes from the library's linking bitcode."""
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
    name, kind, data = state
    symbols = defined_symbols(data[0]) if kind == "object" else None
    if symbols is None or not isinstance(getattr(getattr(codegen, "_engine", None), "_defined_symbols", None), set):
        return codegen._library_class._unserialize(codegen, state)  # numba's own
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
        library._shared_module = ll.parse_bitcode(linking_bitcode)
    return library._shared_module


def _fast_cache_class():
    """numba's `FunctionCache` with the source-hash stamp, the two loading shortcuts and, last, a
    locator for `private_cache_dir`; built here, not at import, because it subclasses numba's private
    classes, which `fast_path_problem` checks first."""
    class _Stamped:
        """A locator whose source stamp also holds SOURCE_HASH: a cached kernel whose index was written
        with other kernel sources is not loaded.  Its folder is made and tried for writing once per
        process, not once per kernel."""

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

    class _Private(_Stamped, caching.UserProvidedCacheLocator):
        """The last resort: `private_cache_dir`, where no other folder can be written."""

        def __init__(self, py_func, py_file):
            super().__init__(py_func, py_file)
            self._cache_path = os.path.join(private_cache_dir(), self.get_suitable_cache_subpath(py_file))

        @classmethod
        def from_function(cls, py_func, py_file):
            if private_cache_dir() is None:
                return None
            locator = super(caching.UserProvidedCacheLocator, cls).from_function(py_func, py_file)
            if locator is not None:
                _private_note(private_cache_dir())
            return locator

    class _Impl(caching.CompileResultCacheImpl):
        _locator_classes = [_UserProvided, _InTree, _UserWide, _Private]

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
            kernel is machine code that calls only numba's C helpers and Python's own functions,
            which the target context installs when it is created; a kernel that has to be compiled
            (a cache miss) goes through numba's compiler, which refreshes the context itself."""
            with self._guard_against_spurious_io_errors():
                return self._load_overload(sig, target_context)
            return None  # the guard swallowed an error: compile, as numba does

    return _FunctionCache


def _native_cache_class(function_cache):
    """`function_cache` in files of its own (``module.kernel-native-...``), for `native` versions:
    numba's index key holds the signature, not the wrapper options, so a shared file would hand
    Python a version without its wrapper."""
    class _NativeImpl(function_cache._impl_class):
        def get_filename_base(self, fullname, abiflags):
            return super().get_filename_base(f"{fullname}-native", abiflags)

    return type("_NativeFunctionCache", (function_cache,), {"_impl_class": _NativeImpl})


_WRITABLE: set[str] = set()  # cache folders found writable in this process


def _public_cache_dir() -> str | None:
    """The folder of numba's public cache where the fast path is off: named after SOURCE_HASH (a
    kernel compiled from other sources is never found there), in NUMBA_CACHE_DIR, else the user cache
    folder, else `private_cache_dir`; None where none can be written."""
    name = f"planar_mbs-{SOURCE_HASH[:16]}"
    if sys.platform == "win32":
        user = os.environ.get("LOCALAPPDATA", "")
    elif sys.platform == "darwin":
        user = os.path.expanduser("~/Library/Caches")
    else:
        user = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    for root in (os.environ.get("NUMBA_CACHE_DIR"), user and os.path.join(user, "numba")):
        if root and _writable(os.path.join(root, name)):
            return os.path.join(root, name)
    private = private_cache_dir()
    if private is not None and _writable(os.path.join(private, name)):
        _private_note(private)
        return os.path.join(private, name)
    return None


def _public_kernel(func, inline: bool):
    """`func` through numba's public ``cache=True`` in `_public_cache_dir`: numba's user-provided
    cache folder (``numba.config.CACHE_DIR``) set to it while the dispatcher chooses its folder."""
    folder = _public_cache_dir() if hasattr(numba.config, "CACHE_DIR") else None
    options = dict(error_model="numpy", _nrt=False, **({"inline": "always"} if inline else {}))
    if folder is None:
        _note(_UNCACHED)
        return njit(**options)(func)
    saved = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = folder
    try:
        return njit(cache=True, **options)(func)
    except RuntimeError:  # numba found no folder after all: uncached
        _note(_UNCACHED)
        return njit(**options)(func)
    finally:
        numba.config.CACHE_DIR = saved


def _choose_cache():
    """The fast path's cache class, or None (and the line saying why) for numba's public cache."""
    problem = fast_path_problem()
    if problem is None:
        try:
            return _fast_cache_class()
        except (AttributeError, TypeError) as exc:
            problem = f"numba {numba.__version__}'s caching classes differ ({exc})"
    _note(f"{problem}; {_FALLBACK}")
    return None


_PLAIN = bool(getattr(numba.config, "DISABLE_JIT", False))  # NUMBA_DISABLE_JIT=1: the Python functions
_CACHE_CLASS = None if _PLAIN else _choose_cache()
_NATIVE_CACHE_CLASS = None if _CACHE_CLASS is None else _native_cache_class(_CACHE_CLASS)


class _SharedScopeInlining(numba_event.Listener):
    """Applies `inline_copy` and `loop_opt_level` when this process starts its first compilation
    (numba's compile event fires only for code not loaded from a cache), not at import: their numba
    modules cost a warm run 25 ms for nothing."""

    def on_start(self, event):
        left_out = os.environ.get(WITHOUT_ENV, "").split(",")  # experiments only (benchmarks/machinery.py)
        for name in ("inline_copy", "loop_opt_level"):
            if name not in left_out:
                importlib.import_module("." + name, __package__).apply()

    def on_end(self, event):
        pass


if _CACHE_CLASS is not None:  # numba's internals as checked (`fast_path_problem`)
    numba_event.register("numba:compile", _SharedScopeInlining())
_OPTIONS = dict(error_model="numpy", _nrt=False)
_njit = njit(**_OPTIONS)  # cache=True would make numba's own cache, replaced at once
_njit_inline = njit(**_OPTIONS, inline="always")  # the same, inlined into callers by numba
_njit_native = njit(**_OPTIONS, no_cpython_wrapper=True, no_cfunc_wrapper=True)  # callable by kernels only
# what `_njit` gives its dispatchers, for `_Kernel` (NUMBA_DISABLE_JIT=1: no dispatchers at all)
_TARGET_OPTIONS = None if _PLAIN else _njit(lambda: None).targetoptions


class _Kernel(CPUDispatcher):
    """A kernel as Python calls it (with numba's CPython wrapper); other kernels call its `native`
    twin instead, which numba types in their place (``_numba_type_``, numba's own protocol)."""

    @property
    def _numba_type_(self):
        return numba.types.Dispatcher(native(self))


def native(dispatcher):
    """The version of `dispatcher` that other kernels call: compiled without numba's CPython and C
    wrappers (a kernel called only from other kernels never needs them), cached in files of its
    own; made at the first compilation that calls it.  `dispatcher` itself where it has none."""
    if not isinstance(dispatcher, _Kernel):
        return dispatcher
    twin = dispatcher.__dict__.get("_native")
    if twin is None:
        twin = dispatcher._native = _njit_native(dispatcher.py_func)
        _cache(twin, _NATIVE_CACHE_CLASS)
    return twin


def _cache(dispatcher, cache_class) -> None:
    try:
        dispatcher._cache = cache_class(dispatcher.py_func)
    except RuntimeError:  # numba's "cannot cache function": no folder at all can be written
        _note(_UNCACHED)


def kernel(func=None, *, inline=False):
    """``njit`` with the options above and the source-hash-stamped cache.
    ``@kernel(inline=True)``: inlined into its callers by numba (IR level)."""
    if func is None:
        return lambda f: kernel(f, inline=inline)
    if _PLAIN:
        return func
    if _CACHE_CLASS is None:
        return _public_kernel(func, inline)
    dispatcher = _njit_inline(func) if inline else _Kernel(func, targetoptions=_TARGET_OPTIONS)
    _cache(dispatcher, _CACHE_CLASS)
    return dispatcher
