"""The core's import graph: no circle, and no import from a lower layer to a higher one.

Each module of ``activetrack`` belongs to one layer (``LAYERS``, lowest first; the table and
its reasons: docs/architecture.md). A module may import from its own layer and the layers
below; the graph of modules may have no circle.

The graph is read from the sources (``ast``; nothing is imported):

- every ``import`` statement is an edge: at the top of a module, inside a function, and under
  ``if TYPE_CHECKING:`` (an import for types only is still a dependency of the design);
- ``from pkg import name`` is an edge to the module that defines ``name``: the submodule
  ``pkg.name``, or, for a name that ``pkg/__init__.py`` re-exports, the module it re-exports it
  from (followed through re-exports of re-exports), else ``pkg`` itself;
- importing ``a.b.c`` runs the ``__init__.py`` of the packages ``a`` and ``a.b`` first, so it
  is an edge to those packages too, except to the packages that contain the importer (they
  have run before it);
- a package's ``__init__.py`` is a module like any other, with its own place in the table.

Names imported through ``importlib`` from strings (the lazy exports of ``activetrack`` and the
kernel loader of ``activetrack.kernels``) are not edges: those modules are above everything
they name (the package API) or load only leaves of their own package.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

CORE = Path(__file__).resolve().parents[1] / "src" / "activetrack" / "activetrack"
ROOT = "activetrack"

# Lowest first. A module's layer is that of the longest prefix of its dotted name listed here
# (a package's entry covers its modules and its __init__).
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    (
        "foundation",
        (
            "activetrack.allocator",
            "activetrack.angles",
            "activetrack.arraytypes",
            "activetrack.checks",
            "activetrack.geometry",
            "activetrack.kernels",
            "activetrack.limits",
            "activetrack.linalg",
            "activetrack.regions",
            "activetrack.stats",
        ),
    ),
    (
        "scenario data",
        (
            "activetrack.scenarios.fields",
            "activetrack.scenarios.plugins",
            "activetrack.scenarios.registry",
            "activetrack.scenarios.schema",
            "activetrack.scenarios.tracking",
        ),
    ),
    ("models", ("activetrack.models",)),
    ("data", ("activetrack.data",)),
    (
        "bounds and filters",
        (
            "activetrack.bounds",
            "activetrack.filters",
            "activetrack.metrics",
            "activetrack.observability",
        ),
    ),
    ("simulation and tracking", ("activetrack.simulation", "activetrack.tracking")),
    ("planning", ("activetrack.planning",)),
    (
        "rules and builders",
        (
            "activetrack.scenarios",
            "activetrack.scenarios.build",
            "activetrack.scenarios.load",
            "activetrack.scenarios.rules",
        ),
    ),
    ("monte carlo", ("activetrack.montecarlo",)),
    ("loops", ("activetrack.closed_loop", "activetrack.plots")),
    ("package API", ("activetrack", "activetrack.argtypes")),
]


@dataclass(frozen=True)
class Edge:
    source: str
    target: str
    line: int
    how: str  # "import" | "re-export" | "package" (the __init__ run first)

    def __str__(self) -> str:
        return f"{self.source}:{self.line} -> {self.target} ({self.how})"


def module_files(core: Path = CORE) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the core (packages by their
    ``__init__.py``)."""
    out = {}
    for path in sorted(core.rglob("*.py")):
        parts = [ROOT, *path.relative_to(core).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _is_package(name: str, files: dict[str, Path]) -> bool:
    return name in files and files[name].name == "__init__.py"


def _absolute(module: str | None, level: int, importer: str, files: dict[str, Path]) -> str:
    """The absolute name of ``from <level dots><module> import ...`` in ``importer``."""
    if level == 0:
        return module or ""
    base = importer.split(".")
    if not _is_package(importer, files):
        base = base[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join([*base, module] if module else base)


def _bindings(files: dict[str, Path]) -> dict[str, dict[str, str]]:
    """Per package: the names its ``__init__.py`` imports (name -> dotted name it came from,
    ``module`` for a module, ``module:attr`` for an attribute)."""
    out: dict[str, dict[str, str]] = {}
    for name, path in files.items():
        if not _is_package(name, files):
            continue
        bound: dict[str, str] = {}
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                source = _absolute(node.module, node.level, name, files)
                for alias in node.names:
                    bound[alias.asname or alias.name] = f"{source}:{alias.name}"
        out[name] = bound
    return out


def _defining_module(
    package: str, attr: str, files: dict[str, Path], bindings: dict[str, dict[str, str]]
) -> tuple[str, str]:
    """Where ``from package import attr`` leads: (module, "import" or "re-export")."""
    if f"{package}.{attr}" in files:
        return f"{package}.{attr}", "import"
    how = "import"
    seen = set()
    while _is_package(package, files) and attr in bindings[package] and package not in seen:
        seen.add(package)
        source, _, name = bindings[package][attr].partition(":")
        if f"{source}.{name}" in files:
            return f"{source}.{name}", "re-export"
        if source not in files:
            break
        package, attr, how = source, name, "re-export"
    return package, how


def _known(dotted: str, files: dict[str, Path]) -> str | None:
    """The longest prefix of ``dotted`` that is a module of the core."""
    parts = dotted.split(".")
    for n in range(len(parts), 0, -1):
        candidate = ".".join(parts[:n])
        if candidate in files:
            return candidate
    return None


def import_graph(core: Path = CORE) -> tuple[dict[str, Path], list[Edge]]:
    """Every module of the core and every edge between two of them (module docstring)."""
    files = module_files(core)
    bindings = _bindings(files)
    edges: set[Edge] = set()
    for importer, path in files.items():
        for node in ast.walk(ast.parse(path.read_text())):
            targets: list[tuple[str, str]] = []
            if isinstance(node, ast.Import):
                targets = [(a.name, "import") for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                source = _absolute(node.module, node.level, importer, files)
                package = _is_package(source, files)
                targets = [(source, "package" if package else "import")]
                if package:
                    targets += [
                        _defining_module(source, a.name, files, bindings) for a in node.names
                    ]
            for dotted, how in targets:
                target = _known(dotted, files)
                if target is None:  # outside the core
                    continue
                parts = target.split(".")
                for n in range(1, len(parts) + 1):
                    module = ".".join(parts[:n])
                    if importer == module or importer.startswith(module + "."):
                        continue  # a package around the importer: it ran before it
                    kind = how if n == len(parts) else "package"
                    edges.add(Edge(importer, module, node.lineno, kind))
    return files, sorted(edges, key=lambda e: (e.source, e.target, e.line))


def layer_of(module: str) -> int:
    best, index = -1, None
    for i, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, index = len(prefix), i
    if index is None:
        raise KeyError(module)
    return index


def cycles(edges: list[Edge]) -> list[list[str]]:
    """The strongly connected components of more than one module (each a circle of imports,
    or several), sorted (Tarjan's algorithm, iterative)."""
    graph: dict[str, set[str]] = defaultdict(set)
    for e in edges:
        graph[e.source].add(e.target)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    out.append(sorted(component))
    return sorted(out)


def upward_edges(edges: list[Edge]) -> list[Edge]:
    """Edges from a module to a module of a higher layer."""
    return [e for e in edges if layer_of(e.source) < layer_of(e.target)]


def _shown_cycle(component: list[str], edges: list[Edge]) -> str:
    inside = set(component)
    lines = [str(e) for e in edges if e.source in inside and e.target in inside]
    return f"{len(component)} modules {component}:\n      " + "\n      ".join(lines)


# --- what is still open ------------------------------------------------------------------------
# Each entry names work in progress elsewhere; the test fails when an entry is no longer needed,
# so the list shrinks as that work lands.

ALLOWED_CYCLES: list[set[str]] = []

# Upward edges (source, target) still allowed: none.
ALLOWED_UPWARD: set[tuple[str, str]] = set()


FILES, EDGES = import_graph()


def test_every_module_has_a_layer():
    missing = []
    for module in FILES:
        try:
            layer_of(module)
        except KeyError:
            missing.append(module)
    assert not missing, f"modules missing from LAYERS (tests/test_import_layers.py): {missing}"


def test_no_import_circle():
    found = cycles(EDGES)
    new = [c for c in found if set(c) not in ALLOWED_CYCLES]
    stale = [sorted(c) for c in ALLOWED_CYCLES if sorted(c) not in found]
    assert not new, "import circles:\n  " + "\n  ".join(_shown_cycle(c, EDGES) for c in new)
    assert not stale, f"ALLOWED_CYCLES entries that are no longer circles (remove them): {stale}"


def test_no_import_from_a_lower_layer_to_a_higher_one():
    up = upward_edges(EDGES)
    new = [e for e in up if (e.source, e.target) not in ALLOWED_UPWARD]
    stale = sorted(ALLOWED_UPWARD - {(e.source, e.target) for e in up})
    names = [name for name, _ in LAYERS]
    shown = [f"{e}  [{names[layer_of(e.source)]} -> {names[layer_of(e.target)]}]" for e in new]
    assert not new, "imports from a lower layer to a higher one:\n  " + "\n  ".join(shown)
    assert not stale, f"ALLOWED_UPWARD entries no longer needed (remove them): {stale}"


def test_the_graph_sees_every_kind_of_import(tmp_path):
    """A function-local, a TYPE_CHECKING and a re-exported import each make an edge, and a
    circle through them is found."""
    pkg = tmp_path / "activetrack"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("from activetrack.sub.low import Thing\n")
    (pkg / "sub" / "low.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from activetrack import high\n"
        "class Thing: ...\n"
    )
    (pkg / "high.py").write_text("def f():\n    from activetrack.sub import Thing\n")
    (pkg / "other.py").write_text("from . import high\n")
    _, edges = import_graph(pkg)
    pairs = {(e.source, e.target, e.how) for e in edges}
    assert ("activetrack.sub.low", "activetrack.high", "import") in pairs
    assert ("activetrack.high", "activetrack.sub.low", "re-export") in pairs
    assert ("activetrack.high", "activetrack.sub", "package") in pairs
    assert ("activetrack.other", "activetrack.high", "import") in pairs
    assert cycles(edges) == [["activetrack.high", "activetrack.sub", "activetrack.sub.low"]]
    # The rules' old place: the schema (scenario data) asking planning (a component).
    up = Edge("activetrack.scenarios.schema", "activetrack.planning.criteria", 1, "import")
    down = Edge("activetrack.scenarios.rules", "activetrack.planning.criteria", 1, "import")
    assert upward_edges([up, down]) == [up]


if __name__ == "__main__":  # a report: python tests/test_import_layers.py
    names = [name for name, _ in LAYERS]
    print(f"{len(FILES)} modules, {len(EDGES)} edges")
    found = cycles(EDGES)
    print(f"{len(found)} circles")
    for c in found:
        print("  " + _shown_cycle(c, EDGES))
    up = upward_edges(EDGES)
    print(f"{len(up)} upward edges")
    for e in up:
        print(f"  {e}  [{names[layer_of(e.source)]} -> {names[layer_of(e.target)]}]")
