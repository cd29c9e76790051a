"""Orchestration: ``rasterize(vertices, triangles, camera) -> VisibilityBuffer``.

Pipeline (Laine & Karras 2011, sort-middle, every stage a Warp kernel):

1. validation (finite vertices, indices in range → :class:`MeshError` naming the element);
2. ``setup.vertex_kernel`` — world → clip space;
3. ``setup.setup_kernel`` count pass → ``array_scan`` → emit pass: clipped, snapped, culled
   sub-triangles with edge data and bounding boxes, plus per original triangle its 1/w and
   barycentric interpolation planes;
4. ``bin.bin_count_kernel`` → ``array_scan``: per-(tile, batch) queue layout;
5. ``coarse.coarse_scatter_kernel``: per-tile queues of sub-triangle ids;
6. ``fine.fine_tile_kernel`` (CPU, tiles on a thread pool) or ``fine.fine_pixel_kernel`` (CUDA):
   coverage with the top-left rule + depth test into (1/w, tri) buffers, no atomics;
7. ``fine.resolve_kernel``: tri_id, perspective-correct barycentrics, depth.

Steps 4–6 run in as many passes over the sub-triangles as the queue-memory budget needs
(``max_pairs``); the depth buffers persist across passes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_sg.device import resolve_device
from warp_sg.errors import InputError, MeshError

from . import parallel
from .bin import TILE, bin_count_kernel, scan_counts
from .camera import Camera
from .coarse import coarse_scatter_kernel
from .fine import fine_pixel_kernel, fine_tile_kernel, resolve_kernel
from .setup import MAX_RESOLUTION, guard_factors, setup_kernel, vertex_kernel

DEFAULT_MAX_PAIRS = 1 << 24  # triangle/tile pairs per pass: 64 MiB of int32 queue


@dataclass
class VisibilityBuffer:
    """Per-(sub)pixel visibility, all ``wp.array`` of shape (k·H, k·W) on ``device``.

    * ``tri_id`` int32: index of the visible input triangle, -1 where empty;
    * ``bary`` vec2: perspective-correct barycentric weights of the triangle's vertices 1 and 2
      (vertex 0's weight is ``1 - b1 - b2``); (0, 0) where empty;
    * ``depth`` float32: distance along the camera's view axis; +inf where empty;
    * ``coverage`` int32 (only with ``coverage_count=True``, else None): how many (sub-)triangles
      cover each pixel centre with the depth test off.
    """

    tri_id: wp.array
    bary: wp.array
    depth: wp.array
    coverage: wp.array | None
    width: int
    height: int
    supersample: int
    device: str
    stats: dict

    @property
    def shape(self) -> tuple[int, int]:
        return (self.height, self.width)


def _as_numpy_mesh(vertices, triangles):
    if isinstance(vertices, wp.array):
        vertices = vertices.numpy()
    if isinstance(triangles, wp.array):
        triangles = triangles.numpy()
    try:
        v = np.asarray(vertices, dtype=np.float32)
    except (TypeError, ValueError) as e:
        raise MeshError(f"vertices are not numeric ({e})", where="vertices") from None
    try:
        t_raw = np.asarray(triangles)
        if t_raw.size and not np.issubdtype(t_raw.dtype, np.integer):
            if not np.all(np.isfinite(t_raw)) or not np.all(t_raw == np.round(t_raw)):
                raise MeshError("triangle indices must be integers", where="triangles")
        t = t_raw.astype(np.int64, copy=False)
    except (TypeError, ValueError) as e:
        raise MeshError(f"triangle indices are not integers ({e})", where="triangles") from None
    if v.size == 0:
        v = v.reshape(0, 3)
    if t.size == 0:
        t = t.reshape(0, 3)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"vertices must have shape (N, 3), got {v.shape}", where="vertices")
    if t.ndim != 2 or t.shape[1] != 3:
        raise MeshError(f"triangles must have shape (M, 3), got {t.shape}", where="triangles")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise MeshError(f"vertex {i} is not finite: {v[i].tolist()}", where=f"vertices[{i}]")
    if t.size:
        badt = ((t < 0) | (t >= v.shape[0])).any(axis=1)
        if badt.any():
            j = int(np.argmax(badt))
            raise MeshError(f"triangle {j} has a vertex index out of range [0, {v.shape[0]}): {t[j].tolist()}",
                            where=f"triangles[{j}]")
    return np.ascontiguousarray(v), np.ascontiguousarray(t, dtype=np.int32)


def rasterize(vertices, triangles, camera: Camera, device="cpu", supersample: int = 1,
              cull_backfaces: bool = False, coverage_count: bool = False, max_pairs: int | None = None,
              schedule: str = "auto") -> VisibilityBuffer:
    """Rasterize a triangle mesh into a :class:`VisibilityBuffer` of (k·H, k·W) pixels.

    ``vertices`` (N, 3) float, ``triangles`` (M, 3) int (numpy or ``wp.array``); ``camera`` a
    :class:`Camera` (or any object with its fields); ``supersample`` k ≥ 1; ``cull_backfaces``
    drops triangles whose front (counter-clockwise) side faces away; ``coverage_count`` also
    returns per-pixel coverage counts (depth test off); ``max_pairs`` bounds the tile-queue
    memory (int32 entries per pass); ``schedule`` = "tile" | "pixel" | "auto" picks the fine
    raster kernel (auto: tiles on CPU, pixels on CUDA).
    """
    device = resolve_device(device)
    if not isinstance(camera, Camera):
        camera = Camera(**{k: getattr(camera, k) for k in ("origin", "target", "up", "fov", "width", "height",
                                                           "near", "far") if hasattr(camera, k)})
    k = int(supersample)
    if k < 1 or k != supersample:
        raise InputError(f"supersample must be a positive integer, got {supersample!r}", where="supersample")
    W, H = camera.width * k, camera.height * k
    if W > MAX_RESOLUTION or H > MAX_RESOLUTION:
        raise InputError(f"{W}x{H} exceeds the rasterizer's {MAX_RESOLUTION}px limit per axis", where="camera")
    v_np, t_np = _as_numpy_mesh(vertices, triangles)
    n_v, n_t = v_np.shape[0], t_np.shape[0]
    stats = {"triangles": n_t, "sub_triangles": 0, "pairs": 0, "passes": 0}

    best_invw = wp.zeros((H, W), dtype=wp.float32, device=device)
    best_tri = wp.full((H, W), -1, dtype=wp.int32, device=device)
    coverage = wp.zeros((H, W), dtype=wp.int32, device=device) if coverage_count else None
    cov_arg = coverage if coverage is not None else wp.zeros((1, 1), dtype=wp.int32, device=device)
    tri_planes = wp.zeros(max(n_t, 1), dtype=wp.mat33, device=device)
    tri_ref = wp.zeros(max(n_t, 1), dtype=wp.vec2, device=device)

    if n_t > 0:
        verts = wp.array(v_np, dtype=wp.vec3, device=device)
        tris = wp.array(t_np, dtype=wp.vec3i, device=device)
        clip = wp.empty(n_v, dtype=wp.vec4d, device=device)
        mvp = wp.mat44d(*camera.view_projection().reshape(-1))
        parallel.launch(vertex_kernel, n_v, [verts, mvp, clip], device, min_chunk=4096)

        # triangle setup: count, scan, emit
        gx, gy = guard_factors(W, H)
        counts = wp.zeros(n_t + 1, dtype=wp.int32, device=device)
        offsets = wp.empty(n_t + 1, dtype=wp.int32, device=device)
        dummy_v = wp.empty((1, 3), dtype=wp.vec2i, device=device)
        dummy_b = wp.empty(1, dtype=wp.vec4i, device=device)
        dummy_i = wp.empty(1, dtype=wp.int32, device=device)
        common = [clip, tris, W, H, float(camera.near), float(camera.far), gx, gy, int(bool(cull_backfaces))]
        parallel.launch(setup_kernel, n_t, [*common, 0, counts, offsets, dummy_v, dummy_b, dummy_i,
                                            tri_planes, tri_ref], device, min_chunk=2048)
        n_sub = scan_counts(counts, offsets)
        stats["sub_triangles"] = n_sub
        if n_sub > 0:
            sub_v = wp.empty((n_sub, 3), dtype=wp.vec2i, device=device)
            sub_bbox = wp.empty(n_sub, dtype=wp.vec4i, device=device)
            sub_tri = wp.empty(n_sub, dtype=wp.int32, device=device)
            parallel.launch(setup_kernel, n_t, [*common, 1, counts, offsets, sub_v, sub_bbox, sub_tri,
                                                tri_planes, tri_ref], device, min_chunk=2048)
            _bin_and_raster(sub_v, sub_bbox, sub_tri, tri_planes, tri_ref, n_sub, W, H, camera,
                            best_invw, best_tri, cov_arg, coverage is not None, device,
                            max_pairs or DEFAULT_MAX_PAIRS, schedule, stats)

    tri_id = wp.empty((H, W), dtype=wp.int32, device=device)
    bary = wp.empty((H, W), dtype=wp.vec2, device=device)
    depth = wp.empty((H, W), dtype=wp.float32, device=device)
    wp.launch(resolve_kernel, dim=(H, W), inputs=[best_invw, best_tri, tri_planes, tri_ref],
              outputs=[tri_id, bary, depth], device=device)
    return VisibilityBuffer(tri_id, bary, depth, coverage, W, H, k, device, stats)


def _bin_and_raster(sub_v, sub_bbox, sub_tri, tri_planes, tri_ref, n_sub, W, H, camera, best_invw, best_tri,
                    coverage, count_mode, device, max_pairs, schedule, stats):
    tiles_x = (W + TILE - 1) // TILE
    tiles_y = (H + TILE - 1) // TILE
    n_tiles = tiles_x * tiles_y
    max_pairs = max(int(max_pairs), n_tiles)  # one triangle alone always fits
    cpu = device.startswith("cpu")
    rows = parallel.cpu_workers() if cpu else 1
    counts = wp.zeros(n_tiles * rows + 1, dtype=wp.int32, device=device)
    offsets = wp.empty(n_tiles * rows + 1, dtype=wp.int32, device=device)
    cursor = wp.zeros(n_tiles * rows, dtype=wp.int32, device=device)
    if schedule == "auto":
        schedule = "tile" if cpu else "pixel"
    inv_far = 1.0 / float(camera.far)

    stack = [(0, n_sub)]
    while stack:
        lo, hi = stack.pop()
        n = hi - lo
        r = min(rows, n)
        batch = (n + r - 1) // r
        counts.zero_()
        parallel.launch_rows(bin_count_kernel, n, r, [lo, batch, rows, tiles_x, sub_v, sub_bbox, counts], device)
        total = scan_counts(counts, offsets)
        if total > max_pairs and n > 1:
            mid = lo + n // 2
            stack.append((mid, hi))
            stack.append((lo, mid))
            continue
        stats["pairs"] += total
        stats["passes"] += 1
        if total == 0:
            continue
        queue = wp.empty(total, dtype=wp.int32, device=device)
        cursor.zero_()
        parallel.launch_rows(coarse_scatter_kernel, n, r,
                             [lo, batch, rows, tiles_x, sub_v, sub_bbox, offsets, cursor, queue], device)
        args = [tiles_x, n_tiles, rows, W, H, inv_far, int(count_mode), offsets, queue, sub_v, sub_bbox, sub_tri,
                tri_planes, tri_ref, best_invw, best_tri, coverage]
        if schedule == "tile":
            parallel.launch(fine_tile_kernel, n_tiles, args, device, chunks=8 * parallel.cpu_workers(), min_chunk=1)
        else:
            parallel.launch(fine_pixel_kernel, n_tiles * TILE * TILE, args, device, min_chunk=TILE * TILE)


__all__ = ["VisibilityBuffer", "rasterize", "DEFAULT_MAX_PAIRS"]
