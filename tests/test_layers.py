"""Import layering of the library (DESIGN.md "Layers": imports go down only, no circles).

Reads every module of ``warp_sg/``, ``raster/`` and ``precompute/`` with :mod:`ast` and builds the
graph of their imports of each other: module-level and function-level ``import`` / ``from ...
import`` statements (relative ones resolved) and ``importlib.import_module("literal")`` calls.
An imported name that is itself a module (``from . import sampling``) points at that module,
otherwise at the module it comes from. The tests then require

* no import cycle between modules (strongly connected components of more than one module; the
  failure shows one cycle of each), and
* no library module importing the command line (``warp_sg.cli``): the CLI sits on top.

Cycles between the three packages (``warp_sg`` ↔ ``raster`` ↔ ``precompute``) are not checked
here: the package-level edges are listed by :func:`package_edges` (a restructure for later).
"""
from __future__ import annotations

import ast
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("warp_sg", "raster", "precompute")


@lru_cache(maxsize=1)
def modules() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the packages (``pkg/__init__.py`` -> ``pkg``)."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def _known(name: str) -> str | None:
    """``name`` or its nearest enclosing project module (None outside the project)."""
    mods = modules()
    while name:
        if name in mods:
            return name
        name = name.rpartition(".")[0]
    return None


def _targets(module: str, is_package: bool, node: ast.AST) -> list[str]:
    mods = modules()
    if isinstance(node, ast.Import):
        return [t for a in node.names if (t := _known(a.name))]
    if isinstance(node, ast.ImportFrom):
        if node.level:
            base = module.split(".") if is_package else module.split(".")[:-1]
            base = base[: len(base) - (node.level - 1)]
            src = ".".join(base + ([node.module] if node.module else []))
        else:
            src = node.module or ""
        out = []
        for a in node.names:
            sub = f"{src}.{a.name}"
            t = sub if sub in mods else _known(src)
            if t:
                out.append(t)
        return out
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "import_module"
            and node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)):
        t = _known(node.args[0].value)
        return [t] if t else []
    return []


@lru_cache(maxsize=1)
def import_graph() -> dict[str, dict[str, int]]:
    """module -> {imported project module: line of the first such import} (self-imports left out)."""
    graph = {}
    for mod, path in modules().items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        edges: dict[str, int] = {}
        for node in ast.walk(tree):
            for t in _targets(mod, path.name == "__init__.py", node):
                if t != mod:
                    edges.setdefault(t, node.lineno)
        graph[mod] = edges
    return graph


def strongly_connected(graph) -> list[list[str]]:
    """Tarjan's strongly connected components (iterative), each sorted."""
    index, low, on, stack, comps = {}, {}, set(), [], []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                comps.append(sorted(comp))
    return comps


def _cycle_in(comp: list[str], graph) -> list[str]:
    """One cycle through ``comp[0]`` inside the component (shortest, by breadth-first search)."""
    members = set(comp)
    start = comp[0]
    prev = {start: None}
    queue = [start]
    while queue:
        v = queue.pop(0)
        for w in sorted(graph[v]):
            if w == start:
                path = [v]
                while prev[path[-1]] is not None:
                    path.append(prev[path[-1]])
                return path[::-1] + [start]
            if w in members and w not in prev:
                prev[w] = v
                queue.append(w)
    return comp  # pragma: no cover - a component always has a cycle


def _describe(cycle, graph) -> str:
    steps = [f"{a} (line {graph[a][b]})" for a, b in zip(cycle, cycle[1:])]
    return " -> ".join(steps + [cycle[-1]])


def package_edges(graph=None) -> dict[tuple[str, str], list[tuple[str, str]]]:
    """(importing package, imported package) -> the module pairs behind that edge."""
    graph = graph or import_graph()
    out: dict[tuple[str, str], list[tuple[str, str]]] = {}
    for a, targets in graph.items():
        for b in targets:
            pa, pb = a.split(".")[0], b.split(".")[0]
            if pa != pb:
                out.setdefault((pa, pb), []).append((a, b))
    return out


def test_the_graph_sees_the_packages_and_function_level_imports():
    g = import_graph()
    assert {"warp_sg", "warp_sg.cli", "warp_sg.brdf.base", "raster.rasterize", "precompute.envmap"} <= set(g)
    assert "warp_sg.render" in g["warp_sg.cli"]  # imported inside render_main
    assert "warp_sg.sampling" in g["warp_sg.reference"]  # ``from . import sampling as S``
    assert "warp_sg.brdf.measured" in g["warp_sg.brdf"]  # importlib.import_module("warp_sg.brdf.measured")


def test_cycle_finder_reports_a_cycle():
    g = {"a": {"b": 1}, "b": {"c": 2}, "c": {"a": 3, "d": 4}, "d": {}}
    comps = [c for c in strongly_connected(g) if len(c) > 1]
    assert comps == [["a", "b", "c"]]
    assert _describe(_cycle_in(comps[0], g), g) == "a (line 1) -> b (line 2) -> c (line 3) -> a"


def test_no_import_cycle_between_modules():
    g = import_graph()
    cycles = [c for c in strongly_connected(g) if len(c) > 1]
    assert not cycles, "import cycles:\n" + "\n".join(
        f"  {', '.join(c)}\n    e.g. {_describe(_cycle_in(c, g), g)}" for c in cycles)


def test_no_library_module_imports_the_cli():
    g = import_graph()
    bad = sorted(f"{m} (line {t['warp_sg.cli']})" for m, t in g.items() if "warp_sg.cli" in t)
    assert not bad, f"library modules import warp_sg.cli: {', '.join(bad)}"
