"""Stage 4 — fine raster: per tile, coverage + depth test into the visibility buffer.

Each tile owns its pixels, so no atomics are needed (Laine & Karras: one CTA per tile, the
tile's queue processed in order). Two schedules of the same work, both plain Warp kernels that
run on either device:

* ``fine_tile_kernel`` — one thread per tile (used on the CPU, tiles spread over the thread
  pool). For each queued sub-triangle it walks only the pixels of bbox ∩ tile, stepping the three
  int64 edge functions incrementally; sub-pixel triangles cost one or two samples.
* ``fine_pixel_kernel`` — one thread per pixel, looping over its tile's queue (used on CUDA:
  a tile is a block of ``TILE²`` threads reading the same queue, coalesced).

Coverage: sample (x+½, y+½) in fixed point is inside when every edge function is > 0, or = 0 on a
top-left edge. Depth: the 1/w plane of the original triangle (larger = nearer), kept only in
[1/far, 1/near]; ties go to the lower triangle id so the result does not depend on queue order.
The winner's perspective-correct barycentrics (λ1/Σλ, λ2/Σλ from the record's planes) are written
with it, straight into the output buffers (cleared before the first pass); ``resolve_kernel`` turns
1/w into depth, only when a caller asks for it.
``count_mode`` additionally counts every covering sub-triangle per pixel (depth test off) — the
watertightness diagnostic.
"""
from __future__ import annotations

import warp as wp

from .fixed import SUBPIXEL, TILE, edge_eval, edge_topleft, eval_plane, eval_plane_at, pixel_bbox, sample_fixed
from .triangle_setup import SubTri

wp.set_module_options({"enable_backward": False})


@wp.func
def closer(invw: float, tri: int, best_invw: float, best_tri: int):
    return invw > best_invw or (invw == best_invw and tri < best_tri)


@wp.func
def barycentrics_at(pl: wp.mat33, v0: wp.vec2i, px: float, py: float, invw: float):
    """Perspective-correct (b1, b2) = (λ1, λ2) / (1/w) at pixel-space point (px, py), clamped into
    the triangle."""
    b1 = wp.clamp(eval_plane_at(pl, 1, v0, px, py) / invw, 0.0, 1.0)
    b2 = wp.clamp(eval_plane_at(pl, 2, v0, px, py) / invw, 0.0, 1.0)
    tot = b1 + b2
    if tot > 1.0:
        b1 = b1 / tot
        b2 = b2 / tot
    return wp.vec2(b1, b2)


@wp.func
def barycentrics(pl: wp.mat33, v0: wp.vec2i, x: int, y: int, invw: float):
    """:func:`barycentrics_at` the centre of pixel (x, y)."""
    return barycentrics_at(pl, v0, float(x) + 0.5, float(y) + 0.5, invw)


@wp.kernel
def fine_tile_kernel(
    base: int,
    tiles_x: int,
    n_tiles: int,
    rows: int,
    width: int,
    height: int,
    inv_far: float,
    count_mode: int,
    offsets: wp.array(dtype=wp.int32),
    queue: wp.array(dtype=SubTri),
    best_invw: wp.array2d(dtype=wp.float32),
    best_tri: wp.array2d(dtype=wp.int32),
    best_bary: wp.array2d(dtype=wp.vec2),
    coverage: wp.array2d(dtype=wp.int32),
):
    t = base + wp.tid()
    if t >= n_tiles:
        return
    tx = t % tiles_x
    ty = t // tiles_x
    X0 = tx * TILE
    Y0 = ty * TILE
    X1 = wp.min(X0 + TILE, width) - 1
    Y1 = wp.min(Y0 + TILE, height) - 1
    start = offsets[t * rows]
    end = offsets[(t + 1) * rows]
    step = wp.int64(SUBPIXEL)
    for q in range(start, end):
        rec = queue[q]
        v0 = rec.v0
        v1 = rec.v1
        v2 = rec.v2
        bb = pixel_bbox(v0, v1, v2, width, height)
        x0 = wp.max(bb[0], X0)
        y0 = wp.max(bb[1], Y0)
        x1 = wp.min(bb[2], X1)
        y1 = wp.min(bb[3], Y1)
        if x0 > x1 or y0 > y1:
            continue
        # inside <=> E + bias > 0 (bias 1 on top-left edges: E >= 0)
        sx = sample_fixed(x0)
        sy = sample_fixed(y0)
        r0 = edge_eval(v0, v1, sx, sy) + wp.int64(edge_topleft(v0, v1))
        r1 = edge_eval(v1, v2, sx, sy) + wp.int64(edge_topleft(v1, v2))
        r2 = edge_eval(v2, v0, sx, sy) + wp.int64(edge_topleft(v2, v0))
        dx0 = -wp.int64(v1[1] - v0[1]) * step
        dx1 = -wp.int64(v2[1] - v1[1]) * step
        dx2 = -wp.int64(v0[1] - v2[1]) * step
        dy0 = wp.int64(v1[0] - v0[0]) * step
        dy1 = wp.int64(v2[0] - v1[0]) * step
        dy2 = wp.int64(v0[0] - v2[0]) * step
        tri = rec.tri
        pl = rec.p
        z = wp.int64(0)
        y = y0
        while y <= y1:  # (while loops compile tighter than range() here: -14 % measured)
            e0 = r0
            e1 = r1
            e2 = r2
            x = x0
            while x <= x1:
                if e0 > z and e1 > z and e2 > z:
                    invw = eval_plane(pl, 0, v0, x, y)
                    if invw >= inv_far:
                        if count_mode == 1:
                            coverage[y, x] = coverage[y, x] + 1
                        if closer(invw, tri, best_invw[y, x], best_tri[y, x]):
                            best_invw[y, x] = invw
                            best_tri[y, x] = tri
                            best_bary[y, x] = barycentrics(pl, v0, x, y, invw)
                e0 += dx0
                e1 += dx1
                e2 += dx2
                x += 1
            y += 1
            r0 += dy0
            r1 += dy1
            r2 += dy2


@wp.kernel
def fine_pixel_kernel(
    base: int,
    tiles_x: int,
    n_tiles: int,
    rows: int,
    width: int,
    height: int,
    inv_far: float,
    count_mode: int,
    offsets: wp.array(dtype=wp.int32),
    queue: wp.array(dtype=SubTri),
    best_invw: wp.array2d(dtype=wp.float32),
    best_tri: wp.array2d(dtype=wp.int32),
    best_bary: wp.array2d(dtype=wp.vec2),
    coverage: wp.array2d(dtype=wp.int32),
):
    g = base + wp.tid()
    t = g // (TILE * TILE)
    local = g - t * (TILE * TILE)
    if t >= n_tiles:
        return
    x = (t % tiles_x) * TILE + local % TILE
    y = (t // tiles_x) * TILE + local // TILE
    if x >= width or y >= height:
        return
    bi = best_invw[y, x]
    bt = best_tri[y, x]
    bq = int(-1)
    cnt = int(0)
    sx = sample_fixed(x)
    sy = sample_fixed(y)
    z = wp.int64(0)
    for q in range(offsets[t * rows], offsets[(t + 1) * rows]):
        rec = queue[q]
        v0 = rec.v0
        v1 = rec.v1
        v2 = rec.v2
        if edge_eval(v0, v1, sx, sy) + wp.int64(edge_topleft(v0, v1)) > z:
            if edge_eval(v1, v2, sx, sy) + wp.int64(edge_topleft(v1, v2)) > z:
                if edge_eval(v2, v0, sx, sy) + wp.int64(edge_topleft(v2, v0)) > z:
                    invw = eval_plane(rec.p, 0, v0, x, y)
                    if invw >= inv_far:
                        cnt += 1
                        if closer(invw, rec.tri, bi, bt):
                            bi = invw
                            bt = rec.tri
                            bq = q
    if bq >= 0:
        rec = queue[bq]
        best_invw[y, x] = bi
        best_tri[y, x] = bt
        best_bary[y, x] = barycentrics(rec.p, rec.v0, x, y, bi)
    if count_mode == 1:
        coverage[y, x] = coverage[y, x] + cnt


@wp.kernel
def resolve_pixel_kernel(
    base: int,
    best_invw: wp.array2d(dtype=wp.float32),
    tri_id: wp.array2d(dtype=wp.int32),
    depth: wp.array2d(dtype=wp.float32),
):
    """One thread per pixel (CUDA): as ``resolve_kernel``."""
    g = base + wp.tid()
    W = tri_id.shape[1]
    y = g // W
    x = g - y * W
    if y >= tri_id.shape[0]:
        return
    if tri_id[y, x] < 0:
        depth[y, x] = wp.inf
    else:
        depth[y, x] = 1.0 / best_invw[y, x]


@wp.kernel
def resolve_kernel(
    base: int,
    best_invw: wp.array2d(dtype=wp.float32),
    tri_id: wp.array2d(dtype=wp.int32),
    depth: wp.array2d(dtype=wp.float32),
):
    """One thread per image row: depth = 1/(1/w) of the winner, +inf where empty (only when a
    caller asks for ``VisibilityBuffer.depth``: the renderer needs tri_id and bary alone, and
    antialiasing reads 1/w itself)."""
    y = base + wp.tid()
    if y >= tri_id.shape[0]:
        return
    x = int(0)
    while x < tri_id.shape[1]:
        if tri_id[y, x] < 0:
            depth[y, x] = wp.inf
        else:
            depth[y, x] = 1.0 / best_invw[y, x]
        x += 1
