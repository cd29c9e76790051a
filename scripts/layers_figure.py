"""The layers of warp-sg drawn from the real imports (docs/architecture.md "Layers").

    python scripts/layers_figure.py [--out docs/figures/layers.png] [--list]

The import graph and the layer of each module come from ``tests/test_layers.py`` (every import of
``warp_sg/``, ``raster/`` and ``precompute/`` read with :mod:`ast`, imports inside functions
included; a module's layer is its folder), so the figure and the test cannot disagree. Each layer
is a row, each package folder a box in its layer's row labelled with its module count; an arrow
from folder A to folder B means some module of A imports a module of B (its width grows with the
number of such imports), grey when it goes down or stays in the layer, red when it goes up (the
test fails on those). ``--list`` prints the folder-level imports and every upward import instead.
"""
from __future__ import annotations

import argparse
import importlib.util
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _layers_test():
    spec = importlib.util.spec_from_file_location("_test_layers", ROOT / "tests" / "test_layers.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


T = _layers_test()


def folder_graph() -> Counter:
    """(folder, imported folder) -> number of module imports between them (self-edges left out)."""
    edges = Counter()
    for a, targets in T.import_graph().items():
        for b in targets:
            fa, fb = T.folder_of(a), T.folder_of(b)
            if fa != fb:
                edges[(fa, fb)] += 1
    return edges


def upward() -> list[str]:
    return T.upward_imports(T.import_graph())


def draw(out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyBboxPatch

    order = T.LAYER_ORDER
    counts = Counter(T.folder_of(m) for m in T.modules())
    rows = {layer: sorted(f for f in T.folders() if T.layer_of(f) == layer) for layer in order}
    width = 15.0
    pos, box_w = {}, {}
    for i, layer in enumerate(order):
        fs = rows[layer]
        step = (width - 2.2) / max(len(fs), 1)
        for k, f in enumerate(fs):
            pos[f] = (2.2 + step * (k + 0.5), i * 1.6 + 0.55)
            box_w[f] = min(step * 0.9, 3.2)
    fig, ax = plt.subplots(figsize=(15, 10), dpi=100)
    ax.set_xlim(0, width)
    ax.set_ylim(-0.2, len(order) * 1.6)
    ax.axis("off")
    for i, layer in enumerate(order):
        ax.add_patch(FancyBboxPatch((0.1, i * 1.6 + 0.05), width - 0.2, 1.0, boxstyle="round,pad=0.02",
                                    fc="#f2f5fa", ec="#9fb0c8", zorder=0))
        ax.text(0.25, i * 1.6 + 0.55, layer, fontsize=12, weight="bold", va="center")
    edges = folder_graph()
    up = 0
    for (fa, fb), n in sorted(edges.items()):
        (xa, ya), (xb, yb) = pos[fa], pos[fb]
        going_up = order.index(T.layer_of(fb)) > order.index(T.layer_of(fa))
        up += going_up
        same = ya == yb
        ax.annotate("", (xb, yb + (0.0 if same else 0.22)), (xa, ya - (0.0 if same else 0.22)),
                    arrowprops=dict(arrowstyle="->", lw=0.4 + 0.25 * min(n, 12) ** 0.5,
                                    color="#c03030" if going_up else "#7a8aa0", alpha=0.9 if going_up else 0.35,
                                    connectionstyle="arc3,rad=0.25" if same else "arc3,rad=0.05",
                                    shrinkA=14, shrinkB=14), zorder=1)
    for f, (x, y) in pos.items():
        w = box_w[f]
        ax.add_patch(FancyBboxPatch((x - w / 2, y - 0.2), w, 0.4, boxstyle="round,pad=0.03",
                                    fc="white", ec="#4a6a9a", zorder=2))
        label = f.replace("warp_sg.", "").replace(".", "/") + "/"
        label = "warp_sg (ws.*)" if f == "warp_sg" else label
        ax.text(x, y, f"{label}  {counts[f]}", fontsize=8.5, ha="center", va="center", zorder=3)
    ax.set_title(f"warp-sg layers: {len(T.modules())} modules in {len(pos)} folders; "
                 f"{sum(edges.values())} imports between folders, {up} going up "
                 "(grey: down or within a layer, red: up)", fontsize=11)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, bbox_inches="tight")
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures" / "layers.png"))
    ap.add_argument("--list", action="store_true", help="print the folder imports and upward imports, draw nothing")
    a = ap.parse_args(argv)
    if a.list:
        for (fa, fb), n in sorted(folder_graph().items()):
            print(f"{fa} ({T.layer_of(fa)}) -> {fb} ({T.layer_of(fb)}): {n}")
        ups = upward()
        print(f"upward imports: {len(ups)}")
        for s in ups:
            print(f"    {s}")
        return 0
    draw(Path(a.out))
    print(a.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
