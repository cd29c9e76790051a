"""The layers of warp-sg and the imports that still go up (docs/architecture.md "Layers").

    python scripts/layers_figure.py [--out docs/figures/layers.png] [--root .] [--list]

Reads every import of ``warp_sg/``, ``raster/`` and ``precompute/`` with :mod:`ast` (imports
inside functions count), puts each module in its layer (``LAYERS``), draws the six layers as
stacked boxes (imports may only go down) and every upward import as a red arrow, labelled with the
modules. ``--list`` prints the upward imports instead of drawing.
"""
from __future__ import annotations

import argparse
import ast
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: bottom to top: (layer, modules: exact names or "pkg.*" prefixes); the first match wins.
LAYERS = [
    ("base", ["warp_sg.errors", "warp_sg.device", "warp_sg.atomic", "warp_sg.workers", "warp_sg.meshcheck",
              "warp_sg.image_io", "warp_sg.lazy", "warp_sg.cache"]),
    ("math", ["warp_sg.sg", "warp_sg.sg_wp", "warp_sg.frames", "warp_sg.clamped_cosine", "warp_sg.fh",
              "warp_sg.sg_irradiance", "warp_sg.ssdf_product", "warp_sg.anisotropy", "warp_sg.pca", "warp_sg.brdf",
              "warp_sg.brdf.*"]),
    ("scene", ["warp_sg.scene", "warp_sg.scene_model", "warp_sg.scene_toml", "warp_sg.scene_schema",
               "warp_sg.scene_values", "warp_sg.geometry", "warp_sg.camera", "warp_sg.envmap", "warp_sg.primitives",
               "warp_sg.textures", "warp_sg.lights", "warp_sg.plain_scenes"]),
    ("tools", ["warp_sg.cli", "warp_sg.report", "warp_sg.bench", "warp_sg.preview", "raster.bench",
               "precompute.bench"]),
    ("engines", ["raster", "raster.*", "precompute", "precompute.*", "warp_sg.surface", "warp_sg.shading"]),
    ("render, reference", ["warp_sg.render", "warp_sg.antialias", "warp_sg.reference", "warp_sg.reference_wp",
                           "warp_sg.sampling", "warp_sg.regions"]),
]
ORDER = ["base", "math", "scene", "engines", "render, reference", "tools"]
HOLDS = {
    "base": "errors, device, atomic writes, workers, mesh check, image I/O, lazy exports, disk cache",
    "math": "SG algebra (numpy + wp.func), frames, clamped cosine, fh, SG irradiance, PCA, BRDFs",
    "scene": "data model, TOML loading, geometry, camera, env maps, primitives, textures, lights",
    "engines": "raster/, precompute/ (refine, env_peaks, ...), surface + shading kernels",
    "render, reference": "Renderer (+ antialiasing), MC reference + sampling, regions",
    "tools": "CLI, report, bench (+ raster/precompute bench), preview",
}
FACADES = {"warp_sg"}  # the package __init__ only re-exports (lazily); it is not a layer member


def layer_of(mod: str) -> str:
    for name, pats in LAYERS:
        for p in pats:
            if mod == p or (p.endswith(".*") and mod.startswith(p[:-1])):
                return name
    raise KeyError(f"{mod}: no layer (add it to LAYERS)")


def modules(root: Path) -> dict[str, Path]:
    out = {}
    for pkg in ("warp_sg", "raster", "precompute"):
        for p in sorted((root / pkg).rglob("*.py")):
            name = ".".join(p.relative_to(root).with_suffix("").parts)
            out[name.removesuffix(".__init__")] = p
    return out


def imports(root: Path) -> set[tuple[str, str]]:
    """(importer, imported module) for every project import, lazy ones included."""
    mods = modules(root)
    edges = set()
    for m, path in mods.items():
        pkg = m if path.name == "__init__.py" else m.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                    base = ".".join(parts + ([node.module] if node.module else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
            else:
                continue
            for t in targets:
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t and t != m:
                    edges.add((m, t))
    return edges


def upward(root: Path) -> dict[tuple[str, str], list[str]]:
    """{(from layer, to layer): ["a -> b", ...]} for imports that go up."""
    ups = defaultdict(list)
    for a, b in sorted(imports(root)):
        if a in FACADES or b in FACADES:
            continue
        la, lb = layer_of(a), layer_of(b)
        if ORDER.index(lb) > ORDER.index(la):
            ups[(la, lb)].append(f"{a} -> {b}")
    return dict(ups)


def package_circles(root: Path) -> list[tuple[str, str]]:
    """Pairs of packages that import each other."""
    pairs = {(a.split(".")[0], b.split(".")[0]) for a, b in imports(root)}
    return sorted((p, q) for p, q in pairs if p < q and (q, p) in pairs)


def draw(ups, circles, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyBboxPatch

    fig, ax = plt.subplots(figsize=(13.5, 6.4), dpi=100)
    ax.set_xlim(0, 14)
    ax.set_ylim(-0.1, 6.3)
    ax.axis("off")
    y = {name: i for i, name in enumerate(ORDER)}
    for name, i in y.items():
        ax.add_patch(FancyBboxPatch((0.2, i + 0.12), 7.0, 0.76, boxstyle="round,pad=0.02",
                                    fc="#e8eef7", ec="#4a6a9a"))
        ax.text(0.35, i + 0.62, name, fontsize=11, weight="bold", va="center")
        ax.text(0.35, i + 0.32, HOLDS[name], fontsize=8, va="center")
        if i:
            ax.annotate("", (3.5, i + 0.1), (3.5, i - 0.1), arrowprops=dict(arrowstyle="<-", color="#4a6a9a"))
    ax.text(8.7, 6.1, "imports go down only (tests/test_layers.py); upward imports (red):",
            fontsize=8.5, color="#a02020")
    items = sorted(ups.items(), key=lambda kv: (y[kv[0][0]], y[kv[0][1]]))
    lines = []
    for k, ((la, lb), mods) in enumerate(items, 1):
        xa = 7.2 + 0.3 * k
        ax.annotate("", (xa, y[lb] + 0.35), (xa, y[la] + 0.65),
                    arrowprops=dict(arrowstyle="->", color="#c03030", lw=1.2))
        ax.text(xa, y[la] + 0.58, str(k), fontsize=7, color="#c03030", ha="center", va="top",
                bbox=dict(fc="white", ec="none", pad=0.3))
        lines.append(_wrap(f"{k}. {la} \u2192 {lb}: " + ", ".join(m.replace(" -> ", " \u2192 ") for m in mods), 64))
    if circles:
        lines.append(_wrap(("none between modules; " if not items else "") + "packages: "
                           + ", ".join(f"{p} \u2194 {q}" for p, q in circles)
                           + " import each other by design (the layers cut across the packages)", 64))
    ax.text(8.85, 5.85, "\n".join(lines) or "none", fontsize=7.2, va="top", color="#802020", family="monospace")
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, bbox_inches="tight")
    plt.close(fig)


def _wrap(s: str, width: int) -> str:
    words, lines, cur = s.split(" "), [], ""
    for w in words:
        if cur and len(cur) + 1 + len(w) > width:
            lines.append(cur)
            cur = "   " + w
        else:
            cur = f"{cur} {w}" if cur else w
    return "\n".join(lines + [cur])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures" / "layers.png"))
    ap.add_argument("--root", default=str(ROOT))
    ap.add_argument("--list", action="store_true", help="print the upward imports, draw nothing")
    a = ap.parse_args(argv)
    ups, circles = upward(Path(a.root)), package_circles(Path(a.root))
    if a.list:
        for (la, lb), items in ups.items():
            print(f"{la} -> {lb}:")
            for s in items:
                print(f"    {s}")
        for p, q in circles:
            print(f"packages {p} <-> {q}")
        return 0
    draw(ups, circles, Path(a.out))
    print(a.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
