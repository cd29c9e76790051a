"""Import layering of the library (docs/architecture.md "Layers": imports go down only, no circles).

Reads every module of ``warp_sg/``, ``raster/`` and ``precompute/`` with :mod:`ast` and builds the
graph of their imports of each other: module-level and function-level ``import`` / ``from ...
import`` statements (relative ones resolved) and ``importlib.import_module("literal")`` calls.
An imported name that is itself a module (``from . import sampling``) points at that module,
otherwise at the module it comes from. The tests then require

* no import cycle between modules (strongly connected components of more than one module; the
  failure shows one cycle of each),
* no library module importing the command line (``warp_sg.cli``): the CLI sits on top,
* every module in a layer (:data:`LAYERS`, the table of docs/architecture.md "Layers": base → math → scene → engines →
  render → tools) and every import going to the same or a lower layer (the failure names the
  importing module, the line, and both layers), and
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

#: (layer, modules): exact dotted names, or ``"pkg.*"`` for every module below ``pkg``; the first
#: match wins (so the bench modules of ``raster``/``precompute`` are tools, the rest engines).
LAYERS = (
    ("base", ("warp_sg.errors", "warp_sg.device", "warp_sg.atomic", "warp_sg.workers", "warp_sg.meshcheck",
              "warp_sg.lazy", "warp_sg.image_io", "warp_sg.cache", "warp_sg.stage_clock", "warp_sg.watchdog")),
    ("math", ("warp_sg.fastmath", "warp_sg.sg", "warp_sg.sg_wp", "warp_sg.frames", "warp_sg.clamped_cosine", "warp_sg.fh",
              "warp_sg.sg_irradiance", "warp_sg.ssdf_product", "warp_sg.anisotropy", "warp_sg.pca",
              "warp_sg.rigid_motion",
              "warp_sg.brdf", "warp_sg.brdf.*")),
    ("scene", ("warp_sg.scene", "warp_sg.scene_model", "warp_sg.scene_toml", "warp_sg.scene_schema",
               "warp_sg.scene_values", "warp_sg.geometry", "warp_sg.camera", "warp_sg.culling",
               "warp_sg.envmap", "warp_sg.primitives", "warp_sg.textures", "warp_sg.lights",
               "warp_sg.plain_scenes", "warp_sg.gltf", "warp_sg.gltf_checks", "warp_sg.gltf_material",
               "warp_sg.material_layers", "warp_sg.asset_scene", "warp_sg.lobe_extent")),
    # the public facade ``warp_sg`` (``ws.render``, ``ws.reference``: lazy) sits on top with the tools
    ("tools", ("warp_sg", "warp_sg.cli", "warp_sg.report",
               "warp_sg.bench",
               "warp_sg.peer_mitsuba",
               "warp_sg.bench_scaling",
               "warp_sg.bench_motion",
               "warp_sg.bench_assets",
               "warp_sg.bench_first_image",
               "warp_sg.spp_curve",
               "warp_sg.preview",
               "warp_sg.viewer",
               "warp_sg.viewer_widgets",
               "warp_sg.viewer_objects",
               "raster.bench",
               "precompute.bench",
               "warp_sg.cluster",
               "warp_sg.distributed",
               "warp_sg.distributed_precompute",
               "warp_sg.batch",
               )),
    # surface: the shading point's textured material and frame, @wp.funcs shared by the shading
    # kernels and the reference kernel (it reads the scene's textures, so it cannot sit lower)
    # surface_layers and cutout: a material's layers and alpha cut-outs, likewise shared (and the
    # cut-outs by the precompute's visibility rays)
    ("engines", ("raster", "raster.*", "precompute", "precompute.*", "warp_sg.surface", "warp_sg.surface_layers",
                 "warp_sg.cutout", "warp_sg.shading",
                 "warp_sg.vertex_visibility", "warp_sg.silhouette", "warp_sg.background", "warp_sg.motion_wp")),
    ("render", ("warp_sg.render", "warp_sg.render_environment", "warp_sg.costs", "warp_sg.progressive",
                "warp_sg.dynamic_objects",
                "warp_sg.visibility_setup", "warp_sg.antialias", "warp_sg.reference", "warp_sg.reference_wp",
                "warp_sg.sampling", "warp_sg.regions")),
)

#: the longest a library file may be (one concept per file; the aim is about 600)
MAX_LINES = 650


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


def layer_of(module: str, layers=LAYERS) -> str | None:
    """The layer of ``module`` by :data:`LAYERS` (None when it has none)."""
    for layer, patterns in layers:
        for p in patterns:
            if module == p or (p.endswith(".*") and module.startswith(p[:-1])):
                return layer
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
    assert {"warp_sg", "warp_sg.cli", "warp_sg.brdf.base", "raster.rasterize", "precompute.envmap"} <= set(g)
    assert "warp_sg.render" in g["warp_sg.cli"]  # imported inside render_main
    assert "warp_sg.sampling" in g["warp_sg.reference"]  # ``from . import sampling as S``
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
    bad = sorted(f"{m} (line {t['warp_sg.cli']})" for m, t in g.items() if "warp_sg.cli" in t)
    assert not bad, f"library modules import warp_sg.cli: {', '.join(bad)}"


def test_layer_checker_reports_an_upward_import():
    g = {"lo": {"hi": 7, "lo2": 3}, "hi": {"lo": 2}, "lo2": {}}
    layers = (("base", ("lo", "lo2")), ("tools", ("hi",)))
    assert upward_imports(g, lambda m: layer_of(m, layers)) == ["lo (base, line 7) imports hi (tools)"]
    assert layer_of("raster.fine") == "engines" and layer_of("raster.bench") == "tools"
    assert layer_of("warp_sg.brdf.material_wp") == "math" and layer_of("warp_sg") == "tools"


def test_every_module_has_a_layer():
    missing = sorted(m for m in modules() if layer_of(m) is None)
    assert not missing, f"modules without a layer (add them to LAYERS): {', '.join(missing)}"


def test_imports_go_down_the_layers_only():
    bad = upward_imports(import_graph())
    assert not bad, "imports that go up a layer (" + " < ".join(LAYER_ORDER) + "):\n  " + "\n  ".join(bad)


def test_no_library_file_is_longer_than_the_limit():
    long = sorted(f"{path.relative_to(ROOT)} ({n} lines)" for path in modules().values()
                  if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES)
    assert not long, f"library files over {MAX_LINES} lines (split them by concept): {', '.join(long)}"
