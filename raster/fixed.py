"""Fixed-point and tile primitives shared by the stages (``@wp.func`` building blocks).

Pixel coordinates are snapped to 1/``SUBPIXEL`` px (8 sub-pixel bits); the pixel centre (x+½, y+½)
is ``x·256 + 128``. Edge functions are evaluated exactly in int64 (|coordinates| < 2²³ thanks to
the guard band, so products < 2⁴⁷). Tiles are ``TILE`` × ``TILE`` pixels.
"""
from __future__ import annotations

import warp as wp

wp.set_module_options({"enable_backward": False})

SUBPIXEL_BITS = 8
SUBPIXEL = 1 << SUBPIXEL_BITS
HALF = SUBPIXEL // 2
TILE_BITS = 4
TILE = 1 << TILE_BITS  # tile edge in pixels (fine raster unit): 16


@wp.func
def edge_topleft(a: wp.vec2i, b: wp.vec2i):
    """1 when the directed edge a→b is a top or left edge (winding: positive area, y down)."""
    dy = b[1] - a[1]
    dx = b[0] - a[0]
    if dy < 0 or (dy == 0 and dx > 0):
        return 1
    return 0


@wp.func
def edge_eval(a: wp.vec2i, b: wp.vec2i, sx: wp.int64, sy: wp.int64):
    """Edge function (b−a)×(s−a) in int64 at fixed-point sample (sx, sy)."""
    return wp.int64(b[0] - a[0]) * (sy - wp.int64(a[1])) - wp.int64(b[1] - a[1]) * (sx - wp.int64(a[0]))


@wp.func
def sample_fixed(p: int):
    """Fixed-point coordinate of pixel centre p + 0.5."""
    return wp.int64(p) * wp.int64(SUBPIXEL) + wp.int64(HALF)


@wp.func
def lower_px(v: int):
    """First pixel whose centre is ≥ fixed-point v (ceil division by an arithmetic shift)."""
    return (v - HALF + SUBPIXEL - 1) >> SUBPIXEL_BITS


@wp.func
def upper_px(v: int):
    """Last pixel whose centre is ≤ fixed-point v (floor division by an arithmetic shift)."""
    return (v - HALF) >> SUBPIXEL_BITS


@wp.func
def pixel_bbox(s0: wp.vec2i, s1: wp.vec2i, s2: wp.vec2i, width: int, height: int):
    """Pixels whose centres lie in the snapped triangle's bounding box, clamped to the screen."""
    bx0 = wp.max(lower_px(wp.min(s0[0], wp.min(s1[0], s2[0]))), 0)
    bx1 = wp.min(upper_px(wp.max(s0[0], wp.max(s1[0], s2[0]))), width - 1)
    by0 = wp.max(lower_px(wp.min(s0[1], wp.min(s1[1], s2[1]))), 0)
    by1 = wp.min(upper_px(wp.max(s0[1], wp.max(s1[1], s2[1]))), height - 1)
    return wp.vec4i(bx0, by0, bx1, by1)


@wp.func
def sample_bbox(s0: wp.vec2i, s1: wp.vec2i, s2: wp.vec2i, width: int, height: int, grid: int):
    """Pixels that may hold a sample of the snapped triangle, clamped to the screen: ``grid`` = 1
    those whose centre lies in its bounding box (:func:`pixel_bbox`); ``grid`` > 1 those whose
    area meets it (any sub-sample: the triangles a raster keeps for :mod:`raster.subsample`)."""
    if grid <= 1:
        return pixel_bbox(s0, s1, s2, width, height)
    bx0 = wp.max(wp.min(s0[0], wp.min(s1[0], s2[0])) >> SUBPIXEL_BITS, 0)
    bx1 = wp.min(wp.max(s0[0], wp.max(s1[0], s2[0])) >> SUBPIXEL_BITS, width - 1)
    by0 = wp.max(wp.min(s0[1], wp.min(s1[1], s2[1])) >> SUBPIXEL_BITS, 0)
    by1 = wp.min(wp.max(s0[1], wp.max(s1[1], s2[1])) >> SUBPIXEL_BITS, height - 1)
    return wp.vec4i(bx0, by0, bx1, by1)


@wp.func
def eval_plane_at(pl: wp.mat33, row: int, v0: wp.vec2i, px: float, py: float):
    """Plane ``row`` of a record at the pixel-space point (px, py)."""
    dx = px - float(v0[0]) * (1.0 / float(SUBPIXEL))
    dy = py - float(v0[1]) * (1.0 / float(SUBPIXEL))
    return pl[row, 0] * dx + pl[row, 1] * dy + pl[row, 2]


@wp.func
def eval_plane(pl: wp.mat33, row: int, v0: wp.vec2i, x: int, y: int):
    """Plane ``row`` of a record at the centre of pixel (x, y)."""
    return eval_plane_at(pl, row, v0, float(x) + 0.5, float(y) + 0.5)


@wp.func
def edge_max(a: wp.vec2i, b: wp.vec2i, x0: int, y0: int, x1: int, y1: int, grid: int):
    """Maximum of edge a→b's function over the pixel centres of [x0,x1]×[y0,y1] (``grid`` = 1),
    or over the whole pixels' area (``grid`` > 1: a bound for every sub-sample)."""
    lo = wp.int64(HALF)
    hi = wp.int64(HALF)
    if grid > 1:
        lo = wp.int64(0)
        hi = wp.int64(SUBPIXEL)
    sx = wp.int64(x0) * wp.int64(SUBPIXEL) + lo
    sy = wp.int64(y0) * wp.int64(SUBPIXEL) + lo
    # dE/dx = -(b.y - a.y), dE/dy = (b.x - a.x)
    if b[1] - a[1] < 0:
        sx = wp.int64(x1) * wp.int64(SUBPIXEL) + hi
    if b[0] - a[0] > 0:
        sy = wp.int64(y1) * wp.int64(SUBPIXEL) + hi
    return edge_eval(a, b, sx, sy)


@wp.func
def tile_overlaps(v0: wp.vec2i, v1: wp.vec2i, v2: wp.vec2i, bb: wp.vec4i, tx: int, ty: int, grid: int):
    """Conservative test: may the triangle cover a sample (``grid``: :func:`sample_bbox`) of
    tile (tx, ty) ∩ bbox?"""
    x0 = wp.max(tx * TILE, bb[0])
    y0 = wp.max(ty * TILE, bb[1])
    x1 = wp.min(tx * TILE + TILE - 1, bb[2])
    y1 = wp.min(ty * TILE + TILE - 1, bb[3])
    z = wp.int64(0)
    return edge_max(v0, v1, x0, y0, x1, y1, grid) >= z and edge_max(v1, v2, x0, y0, x1, y1, grid) >= z and edge_max(
        v2, v0, x0, y0, x1, y1, grid) >= z


@wp.func
def count_tiles(bb: wp.vec4i, v0: wp.vec2i, v1: wp.vec2i, v2: wp.vec2i, tiles_x: int, rows: int, row: int,
                counts: wp.array(dtype=wp.int32), grid: int):
    """Bin raster of one triangle: +1 in ``counts[tile·rows + row]`` for every tile it may touch
    (bbox tiles; exact edge test when the bbox spans several tiles both ways)."""
    tx0 = bb[0] >> TILE_BITS  # bbox is clamped to the screen: non-negative
    tx1 = bb[2] >> TILE_BITS
    ty0 = bb[1] >> TILE_BITS
    ty1 = bb[3] >> TILE_BITS
    if tx0 == tx1 and ty0 == ty1:  # the common case: one tile
        wp.atomic_add(counts, (ty0 * tiles_x + tx0) * rows + row, 1)
        return
    small = (tx1 - tx0) < 1 or (ty1 - ty0) < 1
    for ty in range(ty0, ty1 + 1):
        for tx in range(tx0, tx1 + 1):
            if small or tile_overlaps(v0, v1, v2, bb, tx, ty, grid):
                wp.atomic_add(counts, (ty * tiles_x + tx) * rows + row, 1)
