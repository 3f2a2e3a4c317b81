"""The one decorator of every kernel: ``@kernel``.

* ``cache=True``: compiled code is kept and reused by later processes: next to the sources, else in
  the user's cache folder (``~/.cache/numba``, ``$XDG_CACHE_HOME/numba``), or ``NUMBA_CACHE_DIR``.
  Every kernel's cache stamp holds a hash of all the sources the kernels are compiled from
  (`KERNEL_SOURCES`): numba alone checks only a kernel's own file, so an edit of `contact.py` would
  leave the cached time loop running the old physics.  Where no folder can be written, a folder of
  the temporary directory only this user can write (numba's cache files are pickles), else none.
* ``error_model="numpy"``: a division by zero gives inf/NaN, which the time loop reports as a
  non-finite state, instead of raising inside compiled code.
* ``_nrt=False``: no reference counting.  The kernels never allocate (workspaces are made once in
  Python); with it, every call between kernels would incref and decref each array of the model and
  the workspace.
* ``@kernel(inline=True)``: inlined into its callers by numba.  A call that is not inlined passes every
  array of a tuple argument separately, and a kernel that is not inlined is a library of its own that
  LLVM optimises again; the hot path (applied forces, constraint rows, the Schur solve) and kernels of
  one call site are inlined.  Which ones is measured, not assumed (docs/benchmarks.md).

Four pieces rely on numba's internals, read against and tested on numba `CHECKED_NUMBA`
(docs/install.md); each earns its place in `benchmarks/machinery.py`, which measures them in one run
against numba's public path (`PLANAR_MBS_PUBLIC_CACHE=1`, where none of them is used: the same results,
a slower start).  Where numba is outside that range or lacks a class (`fast_path_problem`), the public
path is taken with one line on stderr.

* `inline_copy`: numba's inliner copies a callee's whole variable scope once per block (numba issue
  #8989); copied once per inlining, the first compilation takes 0.8x the CPU time.
* `loop_opt_level`: the own libraries of `loop.advance` (the step control, the last part of the first
  compilation, which no helper process can share) and `loop._emit` optimised by LLVM at O1, every other
  kernel at O3: the first compilation takes 0.97x the CPU time, the time loop as fast.
* Two versions of each kernel that is not inlined: the one Python calls, with numba's CPython and C
  wrappers, and the `native` one other kernels call, compiled without them; a run calls only `advance`
  from Python, so every other kernel is compiled once, without wrappers.
* A cached kernel loads without numba's target-context refresh (`_FunctionCache.load_overload`, which
  imports every implementation numba has, scipy.linalg among them) and without parsing its linking
  bitcode (`_unserialize`; its symbols are read from the object file).  With the wrapper-less twins,
  the public path's first compilation takes 1.7x the CPU time and a warm run 5x the wall time.
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
WITHOUT_ENV = "PLANAR_MBS_WITHOUT"  # experiments: "inline_copy,loop_opt_level" (benchmarks/machinery.py)


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
