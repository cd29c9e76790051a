"""Benchmark: tile rasterizer vs a ``wp.Mesh`` ray-cast visibility buffer of the same scene.

``run_bench(device="cpu", quick=False) -> list[dict]``; ``python -m raster.bench [--quick]``
prints the table. Scenes: a torus with a sphere in front (occlusion, silhouettes, sub-pixel
and multi-pixel triangles) at ~100 k and ~1 M triangles; resolutions 512², 1024², 1920×1080.
Time per frame = median of ``repeats`` runs after a warm-up run; the ray cast excludes its BVH
build (reported separately, and folded into ``speedup_with_bvh_build``: a static scene pays it
once, a dynamic (deforming) scene every frame, the rasterizer never). Ray casting is
timed both as one launch (how Warp runs it: one CPU core) and spread over the same thread
pool as the rasterizer (same cores), so ``speedup_pool`` is the like-for-like ratio.

``raycast_visibility`` is also the reference the tests compare against.
"""
from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
import warp as wp

wp.set_module_options({"enable_backward": False})

from warp_sg.device import resolve_device

from . import parallel
from .camera import Camera
from .rasterize import rasterize


@wp.kernel
def raycast_kernel(
    base: int,
    mesh: wp.uint64,
    width: int,
    origin: wp.vec3,
    dirs: wp.array(dtype=wp.vec3),
    forward: wp.vec3,
    tmax: float,
    tri_id: wp.array(dtype=wp.int32),
    bary: wp.array(dtype=wp.vec2),
    depth: wp.array(dtype=wp.float32),
):
    """Primary ray per pixel: closest hit → tri id, barycentrics (of vertices 1, 2), view-axis depth."""
    i = base + wp.tid()
    if i >= dirs.shape[0]:
        return
    d = dirs[i]
    q = wp.mesh_query_ray(mesh, origin, d, tmax)
    if q.result:
        tri_id[i] = q.face
        bary[i] = wp.vec2(q.v, 1.0 - q.u - q.v)
        depth[i] = q.t * wp.dot(d, forward)
    else:
        tri_id[i] = -1
        bary[i] = wp.vec2(0.0, 0.0)
        depth[i] = wp.inf


class RayCaster:
    """``wp.Mesh`` BVH of a triangle mesh + the primary-ray kernel for a camera."""

    def __init__(self, vertices, triangles, device="cpu"):
        self.device = resolve_device(device)
        t0 = time.perf_counter()
        self.points = wp.array(np.asarray(vertices, np.float32), dtype=wp.vec3, device=self.device)
        self.indices = wp.array(np.asarray(triangles, np.int32).reshape(-1), dtype=wp.int32, device=self.device)
        self.mesh = wp.Mesh(points=self.points, indices=self.indices)
        wp.synchronize_device(self.device)
        self.build_s = time.perf_counter() - t0

    def prepare(self, camera: Camera, supersample: int = 1):
        dirs = camera.ray_directions(supersample)
        h, w = dirs.shape[:2]
        d = self.device
        return dict(h=h, w=w, dirs=wp.array(dirs.reshape(-1, 3), dtype=wp.vec3, device=d),
                    tri=wp.empty(h * w, dtype=wp.int32, device=d), bary=wp.empty(h * w, dtype=wp.vec2, device=d),
                    depth=wp.empty(h * w, dtype=wp.float32, device=d),
                    origin=wp.vec3(*camera.origin), fwd=wp.vec3(*camera.forward()), far=float(camera.far))

    def cast(self, p, pooled: bool = True):
        n = p["h"] * p["w"]
        inputs = [self.mesh.id, p["w"], p["origin"], p["dirs"], p["fwd"], p["far"] * 10.0, p["tri"], p["bary"],
                  p["depth"]]
        if pooled:
            parallel.launch(raycast_kernel, n, inputs, self.device, min_chunk=1024)
        else:
            wp.launch(raycast_kernel, dim=n, inputs=[0, *inputs], device=self.device)
        wp.synchronize_device(self.device)
        return p


def raycast_visibility(vertices, triangles, camera: Camera, device="cpu", supersample: int = 1):
    """Ray-cast visibility buffer as numpy: (tri_id (H,W) int32, bary (H,W,2), depth (H,W))."""
    rc = RayCaster(vertices, triangles, device)
    p = rc.cast(rc.prepare(camera, supersample))
    h, w = p["h"], p["w"]
    return p["tri"].numpy().reshape(h, w), p["bary"].numpy().reshape(h, w, 2), p["depth"].numpy().reshape(h, w)


# ---------------------------------------------------------------------------------------------
# scenes
# ---------------------------------------------------------------------------------------------
def torus_mesh(nu: int, nv: int, R: float = 1.0, r: float = 0.35):
    """Parametric torus around +Y, 2·nu·nv triangles, counter-clockwise seen from outside."""
    u = np.arange(nu) * (2 * math.pi / nu)
    v = np.arange(nv) * (2 * math.pi / nv)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    x = (R + r * np.cos(vv)) * np.cos(uu)
    z = (R + r * np.cos(vv)) * np.sin(uu)
    y = r * np.sin(vv)
    verts = np.stack([x, y, z], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    tris = np.concatenate([np.stack([a, d, c], -1).reshape(-1, 3), np.stack([a, c, b], -1).reshape(-1, 3)])
    return verts.astype(np.float32), tris.astype(np.int32)


def uv_sphere(nu: int, nv: int, center=(0.0, 0.0, 0.0), radius: float = 1.0):
    """UV sphere (poles duplicated per column: degenerate-free quads split in two), 2·nu·nv triangles."""
    th = np.linspace(0, math.pi, nv + 1)
    ph = np.arange(nu) * (2 * math.pi / nu)
    tt, pp = np.meshgrid(th, ph, indexing="ij")
    verts = np.stack([np.sin(tt) * np.cos(pp), np.cos(tt), -np.sin(tt) * np.sin(pp)], -1).reshape(-1, 3)
    verts = verts * radius + np.asarray(center)
    i, j = np.meshgrid(np.arange(nv), np.arange(nu), indexing="ij")
    a = i * nu + j
    b = i * nu + (j + 1) % nu
    c = (i + 1) * nu + (j + 1) % nu
    d = (i + 1) * nu + j
    tris = np.concatenate([np.stack([a, d, c], -1).reshape(-1, 3), np.stack([a, c, b], -1).reshape(-1, 3)])
    return verts.astype(np.float32), tris.astype(np.int32)


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
