"""Import-layer checker: every import of a package goes to a lower layer (or within its own
subpackage), and no module imports itself back through a circle.

Pure (AST, nothing imported), so it can be tested on a synthetic package. The one sanctioned
exception is python-control's pattern: a result object's ``plot`` method may import the
plotting layer lazily (compute -> result -> separate plot; matplotlib only loaded on demand).
"""

from __future__ import annotations

import ast
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Edge:
    """``src`` (module) imports ``dst`` (module or package) at ``line``; ``lazy_plot``: inside a
    method named ``plot``."""

    src: str
    dst: str
    line: int
    lazy_plot: bool


def module_name(root: Path, path: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(mod: str, is_pkg: bool, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = mod.split(".")
    if not is_pkg:
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _is_module(root: Path, dotted: str) -> bool:
    base = root.parent / Path(*dotted.split("."))
    return base.with_suffix(".py").exists() or (base / "__init__.py").exists()


def _visit(
    node: ast.AST, in_plot: bool, root: Path, mod: str, is_pkg: bool, edges: list[Edge]
) -> None:
    top = root.name
    for child in ast.iter_child_nodes(node):
        plot = in_plot or (
            isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef) and child.name == "plot"
        )
        if isinstance(child, ast.Import):
            for a in child.names:
                if a.name.split(".")[0] == top:
                    edges.append(Edge(mod, a.name, child.lineno, plot))
        elif isinstance(child, ast.ImportFrom):
            base = _resolve(mod, is_pkg, child)
            if base.split(".")[0] == top:
                for a in child.names:  # `from pkg import sub` imports a module
                    sub = f"{base}.{a.name}"
                    edges.append(
                        Edge(mod, sub if _is_module(root, sub) else base, child.lineno, plot)
                    )
        _visit(child, plot, root, mod, is_pkg, edges)


def import_edges(root: Path) -> list[Edge]:
    """Every import (module level, function-local and TYPE_CHECKING) of the package at ``root``
    that targets the package itself."""
    edges: list[Edge] = []
    for path in sorted(root.rglob("*.py")):
        mod = module_name(root, path)
        tree = ast.parse(path.read_text(), filename=str(path))
        is_pkg = path.name == "__init__.py"

        _visit(tree, False, root, mod, is_pkg, edges)
    return edges


def layer_of(module: str, layers: Mapping[str, int]) -> tuple[str, int]:
    """(layer name, rank) of ``module``: its first sub-package under the top package."""
    parts = module.split(".")
    name = parts[1] if len(parts) > 1 else ""
    if name not in layers:
        raise KeyError(f"{module}: in no layer; known: {sorted(layers)}")
    return name, layers[name]


def violations(root: Path, layers: Mapping[str, int], *, plot_layer: str) -> list[str]:
    """Upward or sideways imports between layers, and import circles between modules.

    ``layers``: sub-package (or top-level module) name -> rank; ``""`` is the package's own
    ``__init__``. A module may import its own layer's modules and any layer of lower rank; a
    ``plot`` method may also import ``plot_layer``."""
    out: list[str] = []
    edges = import_edges(root)
    graph: dict[str, set[str]] = {}
    for e in edges:
        (ls, rs), (ld, rd) = layer_of(e.src, layers), layer_of(e.dst, layers)
        if e.lazy_plot and ld == plot_layer:
            continue
        if ls != ld and rd >= rs:
            out.append(f"{e.src}:{e.line} imports {e.dst} ({ls} may not import {ld})")
        if e.dst != e.src and not e.src.startswith(e.dst + "."):
            graph.setdefault(e.src, set()).add(e.dst)
    out.extend(f"import circle: {' -> '.join(c)}" for c in _cycles(graph))
    return out


def _cycles(graph: Mapping[str, set[str]]) -> list[list[str]]:
    """One circle per strongly connected component with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp) + [sorted(comp)[0]])

    for v in sorted(graph):
        if v not in index:
            strong(v)
    return found
