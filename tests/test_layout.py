"""The shape of the package, held by tests so it cannot drift: no import cycle between modules,
techniques that render for the light slot they are given (never the scene's light list), one
release path for every technique's GL objects."""
from __future__ import annotations

import ast
from pathlib import Path

import shadowlab

PACKAGE = Path(shadowlab.__file__).resolve().parent


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """The shadowlab modules ``path`` imports, anywhere in it (a late import inside a function
    is still a dependency: two modules that need each other are one module in two files)."""
    tree = ast.parse(path.read_text())
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("shadowlab")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.startswith("shadowlab"):
                out.add(target)
                out |= {f"{target}.{a.name}" for a in node.names}
    return out


def test_no_import_cycle():
    """The import graph of shadowlab/ is acyclic (a package's ``__init__`` counts as the
    package; a module importing its own package's ``__init__`` is how Python loads it)."""
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {name: {m for m in _imports(path) if m in modules and m != name} for name, path in modules.items()}
    # a module importing its own package's __init__ is how Python loads it, not a cycle
    graph = {n: {m for m in deps if not n.startswith(m + ".")} for n, deps in graph.items()}
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for dep in sorted(graph[node]):
            if state.get(dep) == 1:
                cycle = stack[stack.index(dep):] + [dep]
                raise AssertionError("import cycle: " + " -> ".join(cycle))
            if dep not in state:
                visit(dep)
        stack.pop()
        state[node] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name)


def test_techniques_use_their_light_slot_and_one_release():
    """No technique module reads the scene's light list (they render for their slot), and the
    only ``release`` method among them is the base class's, which frees what they registered."""
    releases = []
    for path in sorted((PACKAGE / "techniques").glob("*.py")):
        tree = ast.parse(path.read_text())
        reads = [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr == "lights"
                 and isinstance(n.value, ast.Attribute) and n.value.attr == "scene"]
        assert not reads, f"{path.name} reads scene.lights at lines {reads}"
        releases += [f"{path.name}:{n.lineno}" for n in ast.walk(tree)
                     if isinstance(n, ast.FunctionDef) and n.name == "release"]
    assert releases == [r for r in releases if r.startswith("base.py:")] and len(releases) == 1, releases
