"""The import contract of docs/ARCHITECTURE.md, as code the tests run (and can plant faults in).

The core ``prtbench`` is layered; a module may import its own layer and the layers below it,
never one above, and no set of modules may import one another in a cycle. Imports inside
function bodies count like any other: only the heavy backends of :data:`DEFERRABLE` may be
imported there, so that ``prtbench list`` stays light and no cycle hides in a function. The
plug-in packages sit on top: ``methods`` and ``scenes`` may reach the layers named in
:data:`PLUGIN_LAYERS`; a method family may import ``methods.common`` and itself, not another
family; the core imports no plug-in (registries load them by name).
"""

from __future__ import annotations

import ast
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

#: The core's layers, lowest first: ``prtbench.<layer>`` subpackages (and modules).
LAYERS = ("api", "io", "scene", "transport", "render", "store", "bench", "tradeoff",
          "stability", "site", "cli")
#: Third-party modules that may be imported inside a function (measured import times on the
#: 2-core machine: torch 2.3 s, sklearn 1.4 s, trimesh 0.8 s, matplotlib.pyplot 0.8 s,
#: distributed 0.7 s, pandas 0.6 s, scipy.sparse 0.35 s, mitsuba 0.2 s; moderngl, glcontext
#: and embreex load GPU / ray-tracing backends; OpenEXR, plotly and flip_evaluator pull in
#: native libraries the lightweight commands never need).
DEFERRABLE = frozenset({"torch", "moderngl", "glcontext", "mitsuba", "drjit", "embreex", "dask",
                        "distributed", "scipy", "pandas", "matplotlib", "sklearn", "trimesh",
                        "skimage", "flip_evaluator", "plotly", "OpenEXR"})
PLUGINS = ("methods", "scenes", "reproductions")
#: Core layers each plug-in package may import.
PLUGIN_LAYERS = {
    "methods": frozenset({"api", "io", "scene", "transport", "render"}),
    "scenes": frozenset({"api", "io", "scene", "transport"}),
    "reproductions": frozenset(LAYERS) - {"cli"},
}


@dataclass(frozen=True)
class Import:
    """One import statement's target, as seen in ``source``."""

    source: str      # importing module, dotted
    target: str      # imported module, dotted (``from a import b``: a.b when b is a module)
    line: int
    deferred: bool   # inside a function body

    def where(self) -> str:
        return f"{self.source}:{self.line}"


def module_name(root: Path, path: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _resolve(source: str, is_package: bool, level: int, module: str | None) -> str:
    base = source.split(".")
    if not is_package:
        base = base[:-1]
    if level > 1:
        base = base[: len(base) - (level - 1)]
    return ".".join(base + ([module] if module else []))


def scan(root: Path, packages: tuple[str, ...]) -> tuple[set[str], list[Import]]:
    """Every module of ``packages`` under ``root`` and every import statement in them."""
    modules: set[str] = set()
    files = []
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            files.append(path)
            modules.add(module_name(root, path))
    imports: list[Import] = []
    for path in files:
        source = module_name(root, path)
        tree = ast.parse(path.read_text(), filename=str(path))
        deferred_nodes = {id(n) for f in ast.walk(tree)
                          if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                          for n in ast.walk(f) if isinstance(n, (ast.Import, ast.ImportFrom))}
        # ``if TYPE_CHECKING:`` imports never run: they are annotations, not dependencies.
        typing_only = {id(n) for f in ast.walk(tree) if isinstance(f, ast.If)
                       and "TYPE_CHECKING" in ast.unparse(f.test)
                       for n in ast.walk(f) if isinstance(n, (ast.Import, ast.ImportFrom))}
        for node in ast.walk(tree):
            if id(node) in typing_only:
                continue
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = (_resolve(source, path.name == "__init__.py", node.level, node.module)
                        if node.level else node.module or "")
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                           for a in node.names]
            else:
                continue
            for target in dict.fromkeys(targets):
                imports.append(Import(source, target, node.lineno, id(node) in deferred_nodes))
    return modules, imports


def layer_of(module: str) -> str | None:
    """The core layer of ``prtbench.<layer>...``; ``prtbench`` itself (and ``__main__``) is cli."""
    parts = module.split(".")
    if parts[0] != "prtbench":
        return None
    if len(parts) == 1 or parts[1] == "__main__":
        return "cli"
    return parts[1] if parts[1] in LAYERS else None


def _owner(module: str, modules: set[str]) -> str | None:
    """The project module an import target names (a dotted attribute path is cut back)."""
    parts = module.split(".")
    while parts:
        name = ".".join(parts)
        if name in modules:
            return name
        parts.pop()
    return None


def violations(root: Path, packages: tuple[str, ...] = ("prtbench", *PLUGINS)) -> list[str]:
    """Every breach of the contract, one line each (empty: the tree keeps it)."""
    modules, imports = scan(root, packages)
    found = []
    graph: dict[str, set[str]] = defaultdict(set)
    for imp in imports:
        top = imp.target.split(".")[0]
        target = _owner(imp.target, modules)
        if imp.deferred and top not in DEFERRABLE:
            found.append(f"{imp.where()}: imports {imp.target} inside a function (only "
                         "heavy backends may be deferred)")
        if target is None:
            continue
        graph[imp.source].add(target)
        source_layer, target_layer = layer_of(imp.source), layer_of(target)
        source_pkg, target_pkg = imp.source.split(".")[0], target.split(".")[0]
        if source_pkg == "prtbench":
            if target_pkg in PLUGINS:
                found.append(f"{imp.where()}: the core imports the plug-in module {target}")
            elif source_layer is None or target_layer is None:
                found.append(f"{imp.where()}: {target} is in no layer of {LAYERS}")
            elif LAYERS.index(target_layer) > LAYERS.index(source_layer):
                found.append(f"{imp.where()}: upward import of {target} ({target_layer}) from "
                             f"the {source_layer} layer")
        elif source_pkg in PLUGIN_LAYERS and target_pkg == "prtbench":
            if target_layer not in PLUGIN_LAYERS[source_pkg]:
                found.append(f"{imp.where()}: {source_pkg} may not import {target} (layer "
                             f"{target_layer}; allowed: {sorted(PLUGIN_LAYERS[source_pkg])})")
        elif source_pkg == "methods" and target_pkg == "methods":
            family, other = imp.source.split(".")[:2], target.split(".")[:2]
            if len(family) > 1 and len(other) > 1 and other[1] not in (family[1], "common") \
                    and family[1] != "common":
                found.append(f"{imp.where()}: method family {family[1]} imports another family "
                             f"({target}); shared code belongs in methods.common or the core")
        elif source_pkg in ("methods", "scenes") and target_pkg == "reproductions":
            found.append(f"{imp.where()}: a plug-in imports the reproduction {target}")
        if target.rsplit(".", 1)[-1].startswith("_") and target.split(".")[:2] != \
                imp.source.split(".")[:2]:
            found.append(f"{imp.where()}: imports the private module {target}")
    found += [f"import cycle: {' -> '.join(c)}" for c in cycles(graph)]
    return found


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle per strongly connected component with more than one module (Tarjan)."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component) + [sorted(component)[0]])

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out
