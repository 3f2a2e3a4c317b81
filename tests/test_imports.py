"""No import cycle inside the package: every module of planar_mbs/ and planar_mbs/cli/ (the CLI is installed
as planar_mbs.cli), with the imports inside functions counted too, read with `ast`.

The package's own ``__init__`` (the public facade, which imports its modules only inside its
functions) is not a node: ``from . import __version__`` in a module is not a dependency cycle."""
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


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    is_pkg = path.name == "__init__.py"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
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
    assert "planar_mbs.kernel" in g["planar_mbs.run.simulation"]  # one inside a function


def test_the_cycle_finder_finds_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_no_import_cycle():
    cycle = find_cycle(graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


# The package's folders in the order of the data flow, lowest first (docs/architecture.md):
# a module imports from its own folder and the folders before it, never from one after it.
STAGES = ["catalog", "errors", "pykernel", "language", "mechanism", "kernel", "results", "run", "sweep",
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
