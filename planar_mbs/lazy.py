"""Imports declared once, at the top of a module, and done on first use.

A module that needs a heavy library (numba, h5py, matplotlib, scipy, rerun, pint, dask, lark) on a
path that must stay light (`import planar_mbs`, `mbs --help`, `mbs check`), or a module of the
package that would close an import cycle, names it once beside its other imports::

    h5py = lazy("h5py")
    store = lazy(".store", __package__)     # as `from . import store`

and uses it as the module (`h5py.File(...)`, `store.gather(...)`).  The name is a stand-in; its
first attribute access imports the module with `importlib.import_module`, and every access after
that reads the real module's attribute.  Until then nothing is imported and nothing is placed in
`sys.modules` (unlike `importlib.util.LazyLoader`, whose half-loaded module sits there from the
start, so "was h5py loaded?" could no longer be asked of `sys.modules`).  Setting an attribute
sets it on the real module, so a test's monkeypatch reaches the module itself.

`tests/test_imports.py` reads these calls as import edges: the graph it checks for cycles and for
the stage layering is the whole graph, the lazy edges included.
"""
from __future__ import annotations

import importlib


class LazyModule:
    """A module imported on first attribute access (see the module docstring)."""

    __slots__ = ("_lazy_name", "_lazy_package", "_lazy_module")

    def __init__(self, name: str, package: str | None = None):
        object.__setattr__(self, "_lazy_name", name)
        object.__setattr__(self, "_lazy_package", package)
        object.__setattr__(self, "_lazy_module", None)

    def _lazy_load(self):
        module = self._lazy_module
        if module is None:
            module = importlib.import_module(self._lazy_name, self._lazy_package)
            object.__setattr__(self, "_lazy_module", module)
        return module

    def __getattr__(self, attr: str):
        return getattr(self._lazy_load(), attr)

    def __setattr__(self, attr: str, value) -> None:
        setattr(self._lazy_load(), attr, value)

    def __delattr__(self, attr: str) -> None:
        delattr(self._lazy_load(), attr)

    def __dir__(self):
        return dir(self._lazy_load())

    def __repr__(self) -> str:
        state = "loaded" if self._lazy_module is not None else "not loaded yet"
        return f"<lazy module {self._lazy_name!r} ({state})>"


def lazy(name: str, package: str | None = None) -> LazyModule:
    """A stand-in for module `name` (relative names, with a leading dot, are resolved against
    `package`, as `importlib.import_module` does) that imports it on first attribute access."""
    if name.startswith(".") and not package:
        raise ValueError(f"lazy({name!r}): a relative module name needs the package (__package__)")
    return LazyModule(name, package)
