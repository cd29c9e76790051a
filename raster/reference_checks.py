"""Test references of the rasterizer: a ``wp.Mesh`` ray-cast visibility buffer and test meshes.

* :func:`raycast_visibility` — the visibility buffer (triangle id, barycentrics, view-axis depth)
  of the same camera by one primary ray per (sub)pixel: what ``rasterize`` must reproduce;
  :class:`RayCaster` keeps the BVH for repeated casts (``warp_sg.tools.bench_raster`` times it).
* :func:`torus_mesh`, :func:`uv_sphere` — closed test meshes of a chosen size.

Used by the tests and by ``warp_sg.tools.bench_raster``; production code does not import this module.
"""
from __future__ import annotations

import math
import time

import numpy as np
import warp as wp

wp.set_module_options({"enable_backward": False})

from warp_sg.core.device import resolve_device  # noqa: E402
from warp_sg.scene.camera import Camera  # noqa: E402

from . import parallel  # noqa: E402


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
# test meshes
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


__all__ = ["RayCaster", "raycast_kernel", "raycast_visibility", "torus_mesh", "uv_sphere"]
