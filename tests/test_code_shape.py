"""The package's shape: functions fit on a screen (no function or method in planar_mbs/ is longer than
80 lines from its `def` to its last line, decorators not counted, read with `ast` over the whole
package), and every folder of modules is a package that an install ships."""
from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "planar_mbs"
MAX_LINES = 80

# Known to be longer: remove each entry as its function is split.  The second test fails on an entry
# that is no longer needed, so this list only shrinks (empty since the time loop was split).
KNOWN_LONG: set[tuple[str, str]] = set()


def long_functions() -> dict[tuple[str, str], int]:
    """{(path relative to planar_mbs/, qualified name): lines} of every function over MAX_LINES."""
    found = {}
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()

        def walk(node, prefix=""):
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                    name = prefix + child.name
                    lines = child.end_lineno - child.lineno + 1
                    if not isinstance(child, ast.ClassDef) and lines > MAX_LINES:
                        found[(rel, name)] = lines
                    walk(child, name + ".")
                else:
                    walk(child, prefix)

        walk(ast.parse(path.read_text(encoding="utf-8")))
    return found


def test_the_walk_finds_a_long_function(tmp_path, monkeypatch):
    """The walk itself: an 81-line function (nested in a class) is found, an 80-line one is not."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    body = "\n".join(f"    x{i} = {i}" for i in range(79))
    (pkg / "m.py").write_text(f"class C:\n    def short(self):\n{body}\n\n    def long(self):\n{body}\n    y = 0\n"
                              .replace("\n    x", "\n        x").replace("\n    y", "\n        y"))
    monkeypatch.setattr(sys.modules[__name__], "ROOT", pkg)
    assert long_functions() == {("m.py", "C.long"): 81}


def test_no_function_is_longer_than_a_screen():
    over = {k: v for k, v in long_functions().items() if k not in KNOWN_LONG}
    assert not over, "functions over 80 lines: " + ", ".join(f"{p}:{n} ({v})" for (p, n), v in sorted(over.items()))


def test_the_list_of_known_long_functions_only_shrinks():
    stale = KNOWN_LONG - set(long_functions())
    assert not stale, f"split now, remove from KNOWN_LONG: {sorted(stale)}"


def test_every_folder_of_modules_is_installed():
    """A folder of modules without ``__init__.py`` is a namespace package, which setuptools'
    `find_packages` (pyproject.toml) leaves out of a regular install: `pip install .` would ship
    planar_mbs without it (results/ was such a folder)."""
    from setuptools import find_packages

    folders = {".".join(p.parent.relative_to(ROOT.parent).parts) for p in ROOT.rglob("*.py")
               if "__pycache__" not in p.parts}
    assert folders <= set(find_packages(str(ROOT.parent), include=["planar_mbs*"]))
