"""Import layering of the library (docs/architecture.md "Layers": imports go down only, no circles).

Reads every module of ``warp_sg/``, ``raster/`` and ``precompute/`` with :mod:`ast` and builds the
graph of their imports of each other: module-level and function-level ``import`` / ``from ...
import`` statements (relative ones resolved) and ``importlib.import_module("literal")`` calls.
An imported name that is itself a module (``from warp_sg.groundtruth import sampling``) points at
that module, otherwise at the module it comes from. A module's layer is its folder: every package
folder has a layer in :data:`FOLDER_LAYERS` (a sub-folder of a listed folder shares its layer, so
``warp_sg/scene/importers/`` is scene and a new folder of ``warp_sg/brdf/`` is math; a new
folder directly under ``warp_sg/`` must be listed). The tests then require

* every package folder in a layer,
* no import cycle between modules (strongly connected components of more than one module; the
  failure shows one cycle of each),
* no library module importing the command line (``warp_sg.tools.cli``): the CLI sits on top,
* every import going to the same or a lower layer (the failure names the importing module, the
  line, and both layers), and
* no library file longer than :data:`MAX_LINES` lines (one concept per file).

Cycles between the three packages (``warp_sg`` ↔ ``raster`` ↔ ``precompute``) are allowed: the
layers cut across the packages (base, math and scene live in ``warp_sg/``, the engines mostly in
``raster/`` and ``precompute/``, render and tools in ``warp_sg/`` again); :func:`package_edges`
lists the module pairs behind each package-level edge.
"""
from __future__ import annotations

import ast
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("warp_sg", "raster", "precompute")

#: docs/architecture.md "Layers", bottom to top: a module may import its own layer and the layers below.
LAYER_ORDER = ("base", "math", "scene", "engines", "render", "tools")

#: package folder (dotted) -> layer. A module's layer is its folder's (a package's own ``__init__``
#: included); a folder not listed takes its nearest listed parent's, except that a folder directly
#: under a package root must be listed itself. ``warp_sg`` itself (the public facade, ``ws.*``)
#: sits on top with the tools.
FOLDER_LAYERS = {
    "warp_sg.core": "base",
    "warp_sg.numeric": "math",
    "warp_sg.sg": "math",
    "warp_sg.brdf": "math",
    "warp_sg.brdf.models": "math",
    "warp_sg.brdf.kernel": "math",
    "warp_sg.brdf.fitting": "math",
    "warp_sg.scene": "scene",
    "warp_sg.scene.importers": "scene",
    "raster": "engines",
    "precompute": "engines",
    "precompute.visibility": "engines",
    "precompute.environment": "engines",
    "warp_sg.shading": "engines",
    "warp_sg.renderer": "render",
    "warp_sg.groundtruth": "render",
    "warp_sg.tools": "tools",
    "warp_sg.distributed": "tools",
    "warp_sg.inverse": "tools",
    "warp_sg": "tools",
}

#: the longest a library file may be (one concept per file)
MAX_LINES = 500
#: files still over :data:`MAX_LINES`, each to be split (the BRDF fits go with the BRDF registry)
OVER_LIMIT: set = set()


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
    """module -> {imported project module: line of its first import in the file} (self-imports left out)."""
    graph = {}
    for mod, path in modules().items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        edges: dict[str, int] = {}
        for node in ast.walk(tree):
            for t in _targets(mod, path.name == "__init__.py", node):
                if t != mod:
                    edges[t] = min(edges.get(t, node.lineno), node.lineno)
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


def folder_of(module: str) -> str:
    """The package folder of ``module``: itself for a package's ``__init__``, else its parent."""
    path = modules()[module]
    return module if path.name == "__init__.py" else module.rpartition(".")[0]


def folders() -> list[str]:
    """Every package folder of the library (dotted)."""
    return sorted({folder_of(m) for m in modules()})


def layer_of(module: str, table=FOLDER_LAYERS) -> str | None:
    """The layer of ``module``: its folder's in ``table`` (None when it has none)."""
    folder = folder_of(module) if module in modules() else module
    while folder:
        if folder in table:
            return table[folder]
        parent = folder.rpartition(".")[0]
        if parent in PACKAGES:  # a folder directly under a package root needs its own entry
            return None
        folder = parent
    return None


def upward_imports(graph, layer=layer_of, order=LAYER_ORDER) -> list[str]:
    """Every import that goes to a higher layer, as ``"a (layer, line n) imports b (layer)"``."""
    out = []
    for a in sorted(graph):
        for b, line in sorted(graph[a].items()):
            la, lb = layer(a), layer(b)
            if la is not None and lb is not None and order.index(lb) > order.index(la):
                out.append(f"{a} ({la}, line {line}) imports {b} ({lb})")
    return out


def test_the_graph_sees_the_packages_and_function_level_imports():
    g = import_graph()
    assert {"warp_sg", "warp_sg.tools.cli", "warp_sg.brdf.base", "raster.rasterize",
            "precompute.environment.prefilter"} <= set(g)
    assert "warp_sg.renderer.renderer" in g["warp_sg.tools.cli"]  # imported inside render_main
    assert "warp_sg.groundtruth.sampling" in g["warp_sg.groundtruth.reference"]  # ``from ... import sampling as S``
    call = ast.parse('importlib.import_module("warp_sg.brdf.kernel.material_wp")').body[0].value
    assert _targets("warp_sg.x", False, call) == ["warp_sg.brdf.kernel.material_wp"]  # a literal import_module
    assert "warp_sg.brdf.models.measured" in g["warp_sg.brdf"]  # from .models.measured import Measured


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
    bad = sorted(f"{m} (line {t['warp_sg.tools.cli']})" for m, t in g.items() if "warp_sg.tools.cli" in t)
    assert not bad, f"library modules import warp_sg.tools.cli: {', '.join(bad)}"


def test_layer_checker_reports_an_upward_import():
    g = {"lo": {"hi": 7, "lo2": 3}, "hi": {"lo": 2}, "lo2": {}}
    layers = {"lo": "base", "lo2": "base", "hi": "tools"}
    assert upward_imports(g, layers.get) == ["lo (base, line 7) imports hi (tools)"]
    assert layer_of("raster.fine") == "engines" and layer_of("warp_sg.tools.bench_raster") == "tools"
    assert layer_of("warp_sg.brdf.kernel.material_wp") == "math" and layer_of("warp_sg") == "tools"
    assert layer_of("warp_sg.scene.importers.gltf") == "scene"  # a sub-folder shares its parent's layer
    assert layer_of("warp_sg.newfolder", {"warp_sg": "tools"}) is None  # a new top folder must be listed


def test_every_folder_has_a_layer():
    missing = sorted(f for f in folders() if layer_of(f) is None)
    assert not missing, f"package folders without a layer (add them to FOLDER_LAYERS): {', '.join(missing)}"


def test_every_module_has_a_layer():
    missing = sorted(m for m in modules() if layer_of(m) is None)
    assert not missing, f"modules without a layer (add their folder to FOLDER_LAYERS): {', '.join(missing)}"


def test_the_package_roots_hold_only_the_facades():
    """``warp_sg/`` directly holds its ``__init__`` (the public ``ws.*``) and nothing else: every
    other module lives in the folder of its layer."""
    loose = sorted(m for m in modules() if folder_of(m) == "warp_sg" and m != "warp_sg")
    assert not loose, f"modules directly in warp_sg/ (move them into their layer's folder): {', '.join(loose)}"


def test_imports_go_down_the_layers_only():
    bad = upward_imports(import_graph())
    assert not bad, "imports that go up a layer (" + " < ".join(LAYER_ORDER) + "):\n  " + "\n  ".join(bad)


def test_no_library_file_is_longer_than_the_limit():
    long = sorted(f"{path.relative_to(ROOT)} ({n} lines)" for path in modules().values()
                  if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES
                  and path.relative_to(ROOT).as_posix() not in OVER_LIMIT)
    assert not long, f"library files over {MAX_LINES} lines (split them by concept): {', '.join(long)}"
    stale = sorted(f for f in OVER_LIMIT if not (ROOT / f).exists()
                   or len((ROOT / f).read_text(encoding="utf-8").splitlines()) <= MAX_LINES)
    assert not stale, f"OVER_LIMIT names files that are not over {MAX_LINES} lines (drop them): {', '.join(stale)}"


def _bound_names(tree: ast.Module) -> set[str]:
    """Names a module binds at its top level (definitions, assignments, imports)."""
    out = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            for t in (node.targets if isinstance(node, ast.Assign) else [node.target]):
                out |= {n.id for n in ast.walk(t) if isinstance(n, ast.Name)}
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            out |= {(a.asname or a.name).split(".")[0] for a in node.names}
    return out


def test_no_package_name_shadows_one_of_its_modules():
    """``from pkg import name`` returns the package's attribute when it has one and imports the
    submodule only otherwise: a function in ``pkg/__init__.py`` named like a module of ``pkg``
    hides that module from every such import."""
    mods = modules()
    clashes = []
    for pkg, path in mods.items():
        if path.name != "__init__.py":
            continue
        subs = {m.rpartition(".")[2] for m in mods if m.rpartition(".")[0] == pkg}
        tree = ast.parse(path.read_text(encoding="utf-8"))
        own = {a.asname or a.name for n in tree.body if isinstance(n, ast.ImportFrom) for a in n.names
               if f"{pkg}.{a.name}" in mods}  # ``from . import sub`` binds the module itself
        clashes += [f"{pkg}.{name}" for name in sorted((_bound_names(tree) - own) & subs)]
    assert not clashes, f"package names that hide a module of the package: {', '.join(clashes)}"
