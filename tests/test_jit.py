"""The compiled-code cache stamp covers every source the kernels are compiled from."""
from __future__ import annotations

import ast
from pathlib import Path

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
