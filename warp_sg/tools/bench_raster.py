"""Benchmark: tile rasterizer vs a ``wp.Mesh`` ray-cast visibility buffer of the same scene.

``run_bench(device="cpu", quick=False) -> list[dict]``; ``python -m warp_sg.tools.bench_raster [--quick]``
prints the table. Scenes: a torus with a sphere in front (occlusion, silhouettes, sub-pixel
and multi-pixel triangles) at ~100 k and ~1 M triangles; resolutions 512², 1024², 1920×1080.
Time per frame = median of ``repeats`` runs after a warm-up run; the ray cast excludes its BVH
build (reported separately, and folded into ``speedup_with_bvh_build``: a static scene pays it
once, a dynamic (deforming) scene every frame, the rasterizer never). Ray casting is
timed both as one launch (how Warp runs it: one CPU core) and spread over the same thread
pool as the rasterizer (same cores), so ``speedup_pool`` is the like-for-like ratio.

The ray caster and the test meshes are :mod:`raster.reference_checks` (what the tests compare
against); they are imported here under their old names.
"""
from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
import warp as wp

from raster import parallel
from raster.rasterize import rasterize
from raster.reference_checks import RayCaster, torus_mesh, uv_sphere
from warp_sg.core.device import resolve_device
from warp_sg.scene.camera import Camera


def bench_scene(n_triangles: int):
    """Torus + sphere in front of it, about ``n_triangles`` triangles in total."""
    n_torus = int(n_triangles * 0.7)
    nv = max(8, int(math.sqrt(n_torus / 2 / 3)))
    nu = max(8, n_torus // (2 * nv))
    tv, tt = torus_mesh(nu, nv)
    n_sph = n_triangles - tt.shape[0]
    snv = max(4, int(math.sqrt(n_sph / 4)))
    snu = max(8, n_sph // (2 * snv))
    sv, st = uv_sphere(snu, snv, center=(0.0, 0.1, 0.9), radius=0.45)
    verts = np.concatenate([tv, sv])
    tris = np.concatenate([tt, st + tv.shape[0]])
    return verts, tris


def bench_camera(width: int, height: int) -> Camera:
    return Camera(origin=(0.0, 1.4, 3.2), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=40.0, width=width,
                  height=height)


def _median_time(fn, repeats: int) -> float:
    fn()  # warm-up
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def run_bench(device="cpu", quick=False) -> list[dict]:
    """Rasterizer vs ray cast per frame; one dict per (triangles, resolution)."""
    device = resolve_device(device)
    sizes = [100_000] if quick else [100_000, 1_000_000]
    resolutions = [(512, 512)] if quick else [(512, 512), (1024, 1024), (1920, 1080)]
    repeats = 2 if quick else 5
    rows = []
    for n in sizes:
        verts, tris = bench_scene(n)
        rc = RayCaster(verts, tris, device)
        for w, h in resolutions:
            cam = bench_camera(w, h)

            def raster_frame():
                vb = rasterize(verts, tris, cam, device=device)
                wp.synchronize_device(device)
                return vb

            t_r = _median_time(raster_frame, repeats)
            p = rc.prepare(cam)
            t_pool = _median_time(lambda: rc.cast(p, pooled=True), repeats)
            t_one = _median_time(lambda: rc.cast(p, pooled=False), max(1, repeats // 2))
            vb = raster_frame()
            agree = float((vb.tri_id.numpy().reshape(-1) == p["tri"].numpy()).mean())
            rows.append({
                "case": f"{tris.shape[0] / 1e6:.2f}M tris {w}x{h}",
                "triangles": int(tris.shape[0]), "width": w, "height": h, "device": device,
                "threads": parallel.cpu_workers() if device == "cpu" else 0,
                "raster_s": t_r, "raycast_pool_s": t_pool, "raycast_1launch_s": t_one,
                "bvh_build_s": rc.build_s,
                "speedup_pool": t_pool / t_r, "speedup_1launch": t_one / t_r,
                "speedup_with_bvh_build": (rc.build_s + t_pool) / t_r,
                "tri_id_agreement": agree,
            })
    return rows


def format_rows(rows: list[dict]) -> str:
    lines = ["| case | raster ms | ray cast ms (pool) | ray cast ms (1 launch) | speedup vs pool | speedup vs 1 launch "
             "| BVH build ms | speedup incl. build | tri_id agree |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['case']} | {1e3 * r['raster_s']:.1f} | {1e3 * r['raycast_pool_s']:.1f} | "
                     f"{1e3 * r['raycast_1launch_s']:.1f} | {r['speedup_pool']:.1f}x | {r['speedup_1launch']:.1f}x | "
                     f"{1e3 * r['bvh_build_s']:.0f} | {r['speedup_with_bvh_build']:.1f}x | "
                     f"{100 * r['tri_id_agreement']:.2f}% |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description="rasterizer vs wp.Mesh ray casting (time per frame)")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    rows = run_bench(device=a.device, quick=a.quick)
    print(format_rows(rows))


if __name__ == "__main__":
    main()
