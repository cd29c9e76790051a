"""Per-stage profile of a warm frame (docs/benchmarks.md "Frame profile").

    python scripts/profile_frame.py [SCENE.toml ...] [--size 512] [--repeat 5]

For each scene: precompute once, then ``repeat`` warm frames; prints the median of each stage
(raster sub-stages from ``raster.rasterize(profile=True)``, shading, resolve) for antialias 1 and
the scene's setting, and the shading cost with parts of the model switched off.
"""
from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

import numpy as np


def _median_frame(r, repeat):
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        r.render()
        ts.append((time.perf_counter() - t, dict(r.timings)))
    ts.sort(key=lambda x: x[0])
    return ts[len(ts) // 2]


def profile(path, size, repeat):
    import raster
    import warp_sg as ws
    from warp_sg.render import Renderer

    scene = ws.load_scene(path)
    scene.camera = replace(scene.camera, width=size, height=size)
    r = Renderer(scene, device="cpu")
    g = r.geometry
    print(f"\n{path}: {len(g.triangles)} triangles, {len(g.vertices)} vertices, {size}², "
          f"features {r.features()}")
    for aa in (1, scene.render.antialias):
        scene.render.antialias = aa
        r.render()
        wall, t = _median_frame(r, repeat)
        keys = ("raster", "shade", "resolve", "frame", "shaded_samples", "edge_pixels")
        print(f"  antialias {aa}: wall {wall*1e3:.1f} ms  " + "  ".join(
            f"{k} {t[k]*1e3:.1f} ms" if isinstance(t.get(k), float) else f"{k} {t.get(k)}" for k in keys if k in t))
        vb = raster.rasterize(g.vertices, g.triangles, scene.camera, device="cpu", supersample=aa, profile=True)
        st = {k: 1e3 * v for k, v in vb.stats["times"].items()}
        print("    raster stages (ms): " + ", ".join(f"{k} {v:.1f}" for k, v in st.items()))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="*", default=["examples/cook_torrance.toml"])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args(argv)
    for s in a.scenes:
        profile(s, a.size, a.repeat)


if __name__ == "__main__":
    main()
