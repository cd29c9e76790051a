"""Per-stage and per-lobe profile of a warm frame (docs/benchmarks.md "Frame profile").

    python scripts/profile_frame.py [SCENE.toml | torus:N ...] [--size 512] [--repeat 5]
                                    [--env-visibility vertex|pixel]

(``torus:N`` is the frame-scaling bench scene with a torus of about N triangles,
``warp_sg.bench_scaling.scaling_scene``.)

For each scene: precompute once, then

* **stages** (wall, median of ``repeat`` frames, camera nudged every frame so that it rasterises):
  raster sub-stages (``raster.rasterize(profile=True)``), background, shading, resolve;
* **shading parts** (process CPU time of a re-shade, visibility buffer reused): the full kernel
  and the kernel variants without shadows, environment diffuse, environment specular and local
  lights; the difference divided by the number of lobes (or lights) is the cost of one lobe.

CPU time, not wall time, because these machines are shared: other processes inflate wall times.
"""
from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

import numpy as np


def _cpu_reshade(r, repeat):
    r.render()
    ts = []
    for i in range(repeat):
        r.set_environment_scale(1.0 + 1e-6 * (i % 2)) if r.env_light is not None else None
        c = time.process_time()
        r.render()
        ts.append(time.process_time() - c)
    return min(ts)


def _wall_new_view(r, repeat):
    o = np.asarray(r.scene.camera.origin, np.float64)
    r.render()
    rows = []
    for i in range(repeat):
        r.set_camera(origin=tuple(o + (0.0, 0.0, 1e-3 * (i % 2 * 2 - 1))))
        t = time.perf_counter()
        r.render()
        rows.append((time.perf_counter() - t, dict(r.timings)))
    rows.sort(key=lambda x: x[0])
    return rows[len(rows) // 2]


def profile(path, size, repeat, env_visibility=None):
    import raster
    import warp_sg as ws
    from warp_sg.render import Renderer

    if path.startswith("torus:"):
        from warp_sg.bench_scaling import scaling_scene

        scene = scaling_scene(int(path.split(":")[1]), size)
    else:
        scene = ws.load_scene(path)
    scene.camera = replace(scene.camera, width=size, height=size)
    if env_visibility:
        scene.render.env_visibility = env_visibility
    r = Renderer(scene, device="cpu")
    g = r.geometry
    f = r.features()
    n_env = r._env_arrays().count if f.env_diffuse else 0
    n_lights = len(r.shading_lights)
    print(f"\n### {path} at {size}², env_visibility {scene.render.env_visibility}: {len(g.triangles)} triangles, {len(g.vertices)} vertices; "
          f"{n_env} environment lobes, {n_lights} lights (incl. sun peaks), "
          f"{r.ssdf.pca_terms if r.ssdf else 0} PCA terms\n")
    print("| antialias | frame ms | raster ms | shade ms | resolve ms | shaded samples | raster stages (ms) |")
    print("|---|---|---|---|---|---|---|")
    for aa in (1, scene.render.antialias):
        scene.render.antialias = aa
        wall, t = _wall_new_view(r, repeat)
        vb = raster.rasterize(r.geo_arrays.positions, r.geo_arrays.tris, scene.camera, device="cpu", supersample=aa,
                              profile=True, validate=False)
        st = ", ".join(f"{k} {1e3 * v:.1f}" for k, v in vb.stats["times"].items())
        print(f"| {aa} | {1e3 * wall:.1f} | {1e3 * t['raster']:.1f} | {1e3 * t['shade']:.1f} | "
              f"{1e3 * t['resolve']:.1f} | {t.get('shaded_samples')} | {st} |")
    scene.render.antialias = 1
    full = _cpu_reshade(r, repeat)
    parts = [("shadows (SSDF lookups)", replace(f, shadows=False), None),
             ("environment diffuse", replace(f, env_diffuse=0), n_env),
             ("environment specular", replace(f, env_specular=0), None),
             ("local lights", replace(f, lights=False), n_lights)]
    print(f"\nshading CPU time, antialias 1, re-shade: full kernel {1e3 * full:.1f} ms\n")
    print("| without | CPU ms | saved ms | per lobe / light ms |")
    print("|---|---|---|---|")
    orig = r.features
    for name, ff, n in parts:
        r.features = lambda ff=ff: ff
        c = _cpu_reshade(r, repeat)
        per = f"{1e3 * (full - c) / n:.1f}" if n else ""
        print(f"| {name} | {1e3 * c:.1f} | {1e3 * (full - c):.1f} | {per} |")
    r.features = orig


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="*", default=["examples/cook_torrance.toml"])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--env-visibility", choices=("vertex", "pixel"), default=None)
    a = ap.parse_args(argv)
    for s in a.scenes:
        profile(s, a.size, a.repeat, a.env_visibility)


if __name__ == "__main__":
    main()
