"""The shape of the package, held by tests so it cannot drift: layers that import only downwards
(docs/architecture.md#layers), technique families that do not reach into each other, no import
cycle between modules, techniques that render for the light slot they are given (never the
scene's light list), one release path for every technique's GL objects."""
from __future__ import annotations

import ast
import functools
from pathlib import Path

import shadowlab

PACKAGE = Path(shadowlab.__file__).resolve().parent


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@functools.lru_cache(maxsize=None)
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


#: The layers, lowest first (docs/architecture.md#layers): a package may import its own layer's
#: packages' modules only within itself, and any package of a lower layer; never a higher one.
#: ``cli`` is the top-level ``cli.py`` and ``__main__.py``; ``scenes`` and ``suites`` hold data.
LAYERS = [
    ["util", "scenes", "suites"],
    ["geometry"],
    ["scene"],
    ["truth"],
    ["gpu"],
    ["lighting"],
    ["techniques"],
    ["evaluation"],
    ["measurement"],
    ["analysis"],
    ["output"],
    ["tuning"],
    ["study"],
    ["docgen"],
    ["commands", "viewer"],
    ["cli"],
]
LAYER_OF = {unit: i for i, units in enumerate(LAYERS) for unit in units}


def _unit(module: str) -> str:
    """The layer unit of a dotted module name: its top package under shadowlab (``cli`` for the
    top-level modules; the root package itself is ``shadowlab``)."""
    parts = module.split(".")
    if len(parts) == 1:
        return "shadowlab"
    return parts[1] if (PACKAGE / parts[1]).is_dir() else "cli"


def _family(module: str) -> str | None:
    """The technique family folder of a module (``techniques.<family>``), None outside one."""
    parts = module.split(".")
    if len(parts) >= 3 and parts[1] == "techniques" and (PACKAGE / "techniques" / parts[2]).is_dir():
        return parts[2]  # a family folder itself counts: ``from .. import maps`` reaches into maps
    return None


@functools.lru_cache(maxsize=None)
def _package_edges() -> list[tuple[str, str]]:
    """Every (importer, imported) pair of shadowlab modules, late imports included."""
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    return [(name, dep) for name, path in sorted(modules.items()) for dep in sorted(_imports(path))
            if dep in modules and dep != name]


def test_every_package_has_a_layer():
    """A new top-level package must be given its place in :data:`LAYERS` (and the picture in
    docs/architecture.md) before it is used."""
    units = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()}
    assert units <= set(LAYER_OF), f"packages with no layer: {sorted(units - set(LAYER_OF))}"


def test_layers_import_only_downwards():
    """No module imports a package of a higher layer (the package graph has no upward edge), so
    e.g. parsing a scene never loads the metrics or the techniques, and the study's pages are
    drawn by output/ from analysis/ tables without output/ knowing the study."""
    upward = []
    for name, dep in _package_edges():
        a, b = _unit(name), _unit(dep)
        if b == "shadowlab" or a == b:
            continue
        if LAYER_OF[b] >= LAYER_OF[a]:
            upward.append(f"{name} -> {dep}  ({a} is layer {LAYER_OF[a]}, {b} layer {LAYER_OF[b]})")
    assert not upward, "upward imports:\n" + "\n".join(upward)


def test_technique_families_do_not_reach_into_each_other():
    """A technique family's modules import the technique base, the layers below and their own
    family's toolkit — never another family's modules (shared code moves down to a layer or
    into the base)."""
    sideways = [f"{name} -> {dep}" for name, dep in _package_edges()
                if _family(name) and _family(dep) and _family(name) != _family(dep)]
    assert not sideways, sideways


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
    only ``release`` method of any registered technique class or its ancestors is the base
    class's, which frees what they registered."""
    from shadowlab.techniques import REGISTRY

    for path in sorted((PACKAGE / "techniques").rglob("*.py")):
        tree = ast.parse(path.read_text())
        reads = [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr == "lights"
                 and isinstance(n.value, ast.Attribute) and n.value.attr == "scene"]
        assert not reads, f"{path.name} reads scene.lights at lines {reads}"
    owners = {f"{c.__module__}.{c.__qualname__}" for cls in REGISTRY.values() for c in cls.__mro__
              if "release" in c.__dict__}
    assert owners == {"shadowlab.techniques.base.Technique"}, owners
