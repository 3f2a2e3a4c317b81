"""No import cycle inside the package: every module of planar_mbs/ and planar_mbs/cli/ (the CLI is installed
as planar_mbs.cli), with the imports inside functions and the lazily declared ones
(``name = lazy(".module", __package__)``, `planar_mbs/lazy.py`) counted too, read with `ast`.

The package's own ``__init__`` (the public facade, which declares its modules lazily) is not a node; no
module of the package imports it (the version a file is stamped with comes from ``planar_mbs.version``)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"planar_mbs": ROOT / "planar_mbs"}


def modules() -> dict[str, Path]:
    out = {}
    for pkg, folder in PACKAGES.items():
        for path in folder.rglob("*.py"):
            rel = path.relative_to(folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            out[".".join([pkg, *parts])] = path
    return out


def lazy_target(node) -> str | None:
    """The module named by a ``lazy("...", ...)`` call (as written: relative names keep their dots), else None."""
    if not isinstance(node, ast.Call) or not node.args:
        return None
    func = node.func.id if isinstance(node.func, ast.Name) else node.func.attr if isinstance(node.func, ast.Attribute) else ""
    first = node.args[0]
    if func == "lazy" and isinstance(first, ast.Constant) and isinstance(first.value, str):
        return first.value
    return None


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    is_pkg = path.name == "__init__.py"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        lazy_name = lazy_target(node)
        if lazy_name is not None:  # as `from <dots><module> import ...`
            level = len(lazy_name) - len(lazy_name.lstrip("."))
            node = ast.ImportFrom(module=lazy_name[level:] or None, names=[], level=level)
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                root = base[: len(base) - node.level + 1]
                mod = ".".join(root + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [f"{mod}.{a.name}" for a in node.names] + [mod]
        else:
            continue
        for t in targets:
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


def graph() -> dict[str, set[str]]:
    mods = modules()
    nodes = set(mods) - {"planar_mbs"}
    return {m: imports_of(m, p, nodes) & nodes for m, p in mods.items() if m in nodes}


def find_cycle(g: dict[str, set[str]]) -> list[str] | None:
    state, stack = {}, []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for m in sorted(g.get(n, ())):
            if state.get(m) == 1:
                return stack[stack.index(m):] + [m]
            if m not in state:
                found = visit(m)
                if found:
                    return found
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(g):
        if n not in state:
            found = visit(n)
            if found:
                return found
    return None


def test_the_graph_is_read():
    g = graph()
    assert "planar_mbs.sweep.scan" in g and "planar_mbs.kernel.loop" in g and "planar_mbs.cli.app" in g
    assert "planar_mbs.results.hdf5" in g["planar_mbs.sweep.scan"]  # a top-level relative import
    assert "planar_mbs.run.driver" in g["planar_mbs.run.simulation"]  # a top-level relative import
    assert "planar_mbs.kernel" in g["planar_mbs.run.lyapunov"]  # lazy("..kernel", __package__)
    assert "planar_mbs.mechanism.compile" in g["planar_mbs.sweep.scan"]  # lazy("..mechanism.compile", ...)
    assert "planar_mbs.sweep.worker" in g["planar_mbs.sweep.scan"]  # lazy(".worker", ...)


def test_a_lazy_declaration_is_an_edge(tmp_path):
    """Read from a package written here: relative (one and two dots) and absolute lazy names are edges,
    a lazy third-party module and any other call are not."""
    pkg = tmp_path / "p"
    (pkg / "a").mkdir(parents=True)
    for f in ("__init__.py", "b.py", "a/__init__.py", "a/c.py", "a/d.py"):
        (pkg / f).write_text("")
    (pkg / "a" / "c.py").write_text('from ..lazy import lazy\nd = lazy(".d", __package__)\nb = lazy("..b", __package__)\n'
                                    'h = lazy("h5py")\nx = print("p.b")\n')
    (pkg / "a" / "d.py").write_text('import p.lazy\nc = p.lazy.lazy("p.a.c")\n')
    known = {"p.b", "p.a", "p.a.c", "p.a.d", "p.lazy"}
    assert imports_of("p.a.c", pkg / "a" / "c.py", known) == {"p.a.d", "p.b", "p.lazy"}
    assert imports_of("p.a.d", pkg / "a" / "d.py", known) == {"p.a.c", "p.lazy"}
    assert find_cycle({m: imports_of(m, pkg / (m[2:].replace(".", "/") + ".py"), known) & known
                       for m in ("p.a.c", "p.a.d")}) == ["p.a.c", "p.a.d", "p.a.c"]


def test_the_cycle_finder_finds_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_no_import_cycle():
    cycle = find_cycle(graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


# The package's folders in the order of the data flow, lowest first (docs/architecture.md):
# a module imports from its own folder and the folders before it, never from one after it.
STAGES = ["lazy", "version", "catalog", "errors", "files", "pykernel", "language", "mechanism", "kernel", "results", "run", "sweep",
          "outputs", "cli"]


def upward_imports(g: dict[str, set[str]]) -> list[str]:
    def stage(m):
        parts = m.split(".")
        return STAGES.index(parts[1]) if len(parts) > 1 and parts[1] in STAGES else None

    return sorted(f"{a} -> {b}" for a, targets in g.items() for b in targets
                  if stage(a) is not None and stage(b) is not None and stage(b) > stage(a))


def test_every_module_lives_in_a_stage_folder():
    folders = {m.split(".")[1] for m in modules() if m.count(".") >= 1}
    assert folders <= set(STAGES), folders - set(STAGES)


def test_the_stage_folders_import_only_back_up_the_data_flow():
    assert upward_imports({"planar_mbs.language.parse": {"planar_mbs.run.simulation"}}) == [
        "planar_mbs.language.parse -> planar_mbs.run.simulation"]  # the check can fail
    assert upward_imports(graph()) == []


# ---------------------------------------------------------------- imports declared once, at the top
# The rule (docs/architecture.md, "Imports"): a module's imports sit at its top; one that must load
# late (a heavy library on a path that must stay light, or a module that would close a cycle) is
# declared there too, through `planar_mbs.lazy.lazy`, never inside a function body.


def function_body_imports(source: str) -> list[int]:
    """Line numbers of the import statements inside a function (or lambda) body of `source`."""
    found = []

    def walk(node, inside: bool):
        for child in ast.iter_child_nodes(node):
            if inside and isinstance(child, (ast.Import, ast.ImportFrom)):
                found.append(child.lineno)
            walk(child, inside or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

    walk(ast.parse(source), False)
    return found


def test_the_function_body_import_finder_finds_them():
    src = ("import os\nif os:\n    import re\ntry:\n    import json\nexcept ImportError:\n    pass\n"
           "def f():\n    import sys\n    class C:\n        def g(self):\n            from . import x\n"
           "class D:\n    import math\n    def h(self):\n        if 1:\n            import io\n")
    assert function_body_imports(src) == [9, 12, 17]


def test_no_import_inside_a_function():
    found = [f"{path.relative_to(ROOT)}:{line}" for path in sorted(PACKAGES["planar_mbs"].rglob("*.py"))
             for line in function_body_imports(path.read_text())]
    assert found == [], "imports inside functions (declare them at the top, lazily if they must load late):\n" + \
        "\n".join(found)


def _is_type_checking(node) -> bool:
    """`if TYPE_CHECKING:` at a module's top: its imports are the lazy modules themselves, for type checkers."""
    return isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"


def test_every_lazy_module_of_the_package_is_visible_to_standard_tools():
    """Each `lazy(".module", __package__)` of the package sits in the `else` of a top-level `if TYPE_CHECKING`
    whose body imports that very module under the same name, so type checkers and import-graph tools see
    the module and the edge, while the run loads it on first use."""
    missing = []
    for path in sorted(PACKAGES["planar_mbs"].rglob("*.py")):
        if path.name == "lazy.py":
            continue
        tree = ast.parse(path.read_text())
        seen = {alias.asname or alias.name for branch in tree.body if _is_type_checking(branch)
                for node in branch.body if isinstance(node, ast.ImportFrom) for alias in node.names}
        for node in ast.walk(tree):
            if isinstance(node, ast.Assign) and (lazy_target(node.value) or "x")[0] == ".":
                if node.targets[0].id not in seen:
                    missing.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert missing == []


def test_lazy_modules_are_declared_at_the_top_of_a_module():
    """Every `lazy(...)` call is a module-level assignment of a name: declared once, where a reader
    of the module's imports sees it."""
    stray = []
    for path in sorted(PACKAGES["planar_mbs"].rglob("*.py")):
        tree = ast.parse(path.read_text())
        body = list(tree.body) + [node for branch in tree.body if _is_type_checking(branch) for node in branch.orelse]
        top = {id(node.value) for node in body if isinstance(node, ast.Assign)}
        stray += [f"{path.relative_to(ROOT)}:{node.lineno}" for node in ast.walk(tree)
                  if lazy_target(node) is not None and id(node) not in top]
    assert stray == []


LAZY_USE = """import sys
from planar_mbs.lazy import lazy
h5py, numba, hdf5 = lazy("h5py"), lazy("numba"), lazy(".results.hdf5", "planar_mbs")
print(sorted(m for m in ("h5py", "numba", "planar_mbs.results.hdf5") if m in sys.modules))
f = h5py.File(sys.argv[1], "w")
f["x"] = [1.0, 2.0]
f.close()
print(float(h5py.File(sys.argv[1], "r")["x"][1]), isinstance(h5py.File(sys.argv[1], "r"), h5py.File))
print(numba.njit(lambda x: 2 * x + 1)(20), hdf5.read_results is sys.modules["planar_mbs.results.hdf5"].read_results)
hdf5.MARK = 7
print(sys.modules["planar_mbs.results.hdf5"].MARK, "loaded" in repr(hdf5))
"""


def test_a_lazy_module_loads_on_first_use_and_is_then_the_module(tmp_path):
    """Nothing in sys.modules until the first attribute access; then h5py, numba and a module of the
    package work through the stand-in as themselves (a jitted function compiles and runs, an
    isinstance check holds), and an attribute set on the stand-in is set on the module."""
    import subprocess
    import sys

    res = subprocess.run([sys.executable, "-c", LAZY_USE, str(tmp_path / "x.h5")], capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines() == ["[]", "2.0 True", "41 True", "7 True"]


def test_a_relative_lazy_name_needs_its_package():
    import pytest

    from planar_mbs.lazy import lazy

    with pytest.raises(ValueError, match="needs the package"):
        lazy(".store")
    assert "not loaded yet" in repr(lazy("no_such_module_anywhere"))


def test_no_module_of_the_package_imports_its_facade():
    """The facade (`planar_mbs/__init__.py`) stands above every stage: a module that took a name from it
    (not a submodule through it, as `from .. import catalog`) would be an arrow back up; the version
    comes from `planar_mbs.version`.  The command line, the one layer above the facade, may use it."""
    mods = modules()
    found = []
    for name, path in mods.items():
        if name == "planar_mbs" or name.startswith("planar_mbs.cli"):
            continue
        base = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                mod = ".".join(base[: len(base) - node.level + 1] + ([node.module] if node.module else [])) \
                    if node.level else node.module
                if mod == "planar_mbs":
                    found += [f"{name}: {a.name}" for a in node.names if f"planar_mbs.{a.name}" not in mods]
    assert found == []
