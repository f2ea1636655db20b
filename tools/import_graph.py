"""The import graph of engine/: which module imports which, checked for circles.

    python tools/import_graph.py            # modules in layers: each imports only layers above it
    python tools/import_graph.py --packages # the same, one node per package

Reads the source (ast), so nothing is imported. Every import counts, at the top of a module
or inside a function: an import inside a function is how a circle hides.
"""
from __future__ import annotations

import argparse
import ast
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _module_name(path: pathlib.Path, root: pathlib.Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def module_graph(root: pathlib.Path = ROOT, package: str = "engine") -> dict[str, dict[str, bool]]:
    """{module: {imported engine module: imported inside a function or class}} for every
    module of `package` under `root` (dotted names, e.g. engine.integrators.path)."""
    paths = {_module_name(p, root): p for p in (root / package).rglob("*.py")}
    graph: dict[str, dict[str, bool]] = {}
    for name, path in paths.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        top = {id(node) for node in tree.body}
        is_package = path.name == "__init__.py"
        edges: dict[str, bool] = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = name.split(".") if is_package else name.split(".")[:-1]
                    base = base[:len(base) - (node.level - 1)]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = node.module or ""
                targets = [f"{module}.{a.name}" if f"{module}.{a.name}" in paths else module for a in node.names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            for target in targets:
                if target in paths and target != name:
                    edges[target] = edges.get(target, True) and id(node) not in top
        graph[name] = edges
    return graph


def cycles(graph: dict[str, dict]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
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
                found.append(sorted(component))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(graph) + 100))
    try:
        for v in sorted(graph):
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return found


def reaches(graph: dict[str, dict], start: str) -> set[str]:
    """Every module `start` imports, directly or through others."""
    seen, todo = set(), [start]
    while todo:
        for w in graph.get(todo.pop(), ()):
            if w not in seen:
                seen.add(w)
                todo.append(w)
    return seen


def collapse(graph: dict[str, dict], depth: int = 2) -> dict[str, dict]:
    """The graph with modules merged into their package prefix of `depth` parts."""
    out: dict[str, dict] = {}
    for v, edges in graph.items():
        key = ".".join(v.split(".")[:depth])
        node = out.setdefault(key, {})
        for w in edges:
            target = ".".join(w.split(".")[:depth])
            if target != key:
                node[target] = False
    return out


def layers(graph: dict[str, dict]) -> list[list[str]]:
    """Modules in layers: layer 0 imports nothing of the graph, layer k only layers below k."""
    level: dict[str, int] = {}

    def depth(v, path=()):
        if v not in level:
            if v in path:
                raise ValueError(f"import circle through {v}")
            level[v] = 1 + max((depth(w, path + (v,)) for w in graph.get(v, ())), default=-1)
        return level[v]

    for v in graph:
        depth(v)
    out = [[] for _ in range(max(level.values(), default=-1) + 1)]
    for v in sorted(level):
        out[level[v]].append(v)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--packages", action="store_true", help="one node per package (engine.integrators, ...)")
    args = ap.parse_args(argv)
    graph = module_graph()
    found = cycles(graph)
    if found:
        for component in found:
            print("circle:", ", ".join(component))
        return 1
    shown = collapse(graph) if args.packages else graph
    for k, layer in enumerate(layers(shown)):
        print(f"{k:2d}  " + "  ".join(layer))
    return 0


if __name__ == "__main__":
    sys.exit(main())
