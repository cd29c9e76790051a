"""Stage 2 — bin raster: count triangle/tile pairs and lay out the per-tile queues.

Laine & Karras (2011) first distribute triangles to coarse bins, then bins to tiles. Here the
screen is cut directly into ``TILE`` × ``TILE`` pixel tiles and this stage does the *counting* half:

* the sub-triangles are split into ``rows`` contiguous batches (on the CPU one per worker
  thread, so a batch is owned by one thread and needs no atomics; on CUDA one batch, counted
  with atomics);
* ``bin_count_kernel`` (one thread per sub-triangle) walks the tiles of the triangle's bounding
  box and counts the tiles it really touches (``tile_overlaps``: the exact edge-function test of
  the tile's sample rectangle, so long thin triangles don't fill their whole bounding box)
  into ``counts[tile·rows + batch]``;
* an exclusive prefix sum (``wp.utils.array_scan``) of that tile-major table gives every
  (tile, batch) its start in one queue array: tile t's queue is
  ``queue[offsets[t·rows] : offsets[(t+1)·rows]]``, ordered by batch, then (CPU) by triangle.

The scatter that fills the queues is the coarse raster (``coarse.py``).
"""
from __future__ import annotations

import warp as wp

wp.set_module_options({"enable_backward": False})

from .setup import HALF, SUBPIXEL, SubTri, edge_eval

TILE = 16  # tile edge in pixels (fine raster unit)


@wp.func
def edge_max(a: wp.vec2i, b: wp.vec2i, x0: int, y0: int, x1: int, y1: int):
    """Maximum of edge a→b's function over the pixel centres of [x0,x1]×[y0,y1]."""
    sx = wp.int64(x0) * wp.int64(SUBPIXEL) + wp.int64(HALF)
    sy = wp.int64(y0) * wp.int64(SUBPIXEL) + wp.int64(HALF)
    # dE/dx = -(b.y - a.y), dE/dy = (b.x - a.x)
    if b[1] - a[1] < 0:
        sx = wp.int64(x1) * wp.int64(SUBPIXEL) + wp.int64(HALF)
    if b[0] - a[0] > 0:
        sy = wp.int64(y1) * wp.int64(SUBPIXEL) + wp.int64(HALF)
    return edge_eval(a, b, sx, sy)


@wp.func
def tile_overlaps(v0: wp.vec2i, v1: wp.vec2i, v2: wp.vec2i, bb: wp.vec4i, tx: int, ty: int):
    """Conservative test: may the triangle cover a pixel centre of tile (tx, ty) ∩ bbox?"""
    x0 = wp.max(tx * TILE, bb[0])
    y0 = wp.max(ty * TILE, bb[1])
    x1 = wp.min(tx * TILE + TILE - 1, bb[2])
    y1 = wp.min(ty * TILE + TILE - 1, bb[3])
    z = wp.int64(0)
    return edge_max(v0, v1, x0, y0, x1, y1) >= z and edge_max(v1, v2, x0, y0, x1, y1) >= z and edge_max(
        v2, v0, x0, y0, x1, y1) >= z


@wp.kernel
def bin_count_kernel(
    base: int,
    sub_lo: int,
    batch: int,
    rows: int,
    tiles_x: int,
    subs: wp.array(dtype=SubTri),
    sub_bbox: wp.array(dtype=wp.vec4i),
    counts: wp.array(dtype=wp.int32),
):
    j = base + wp.tid()
    s = sub_lo + j
    row = j // batch
    bb = sub_bbox[s]
    if bb[0] > bb[2]:
        return  # empty slot (culled / clipped away / no pixel centre covered)
    tx0 = bb[0] // TILE
    tx1 = bb[2] // TILE
    ty0 = bb[1] // TILE
    ty1 = bb[3] // TILE
    small = (tx1 - tx0) < 1 or (ty1 - ty0) < 1
    v0 = wp.vec2i(0, 0)
    v1 = wp.vec2i(0, 0)
    v2 = wp.vec2i(0, 0)
    if not small:  # the full record only for triangles spanning several tiles both ways
        rec = subs[s]
        v0 = rec.v0
        v1 = rec.v1
        v2 = rec.v2
    for ty in range(ty0, ty1 + 1):
        for tx in range(tx0, tx1 + 1):
            if small or tile_overlaps(v0, v1, v2, bb, tx, ty):
                wp.atomic_add(counts, (ty * tiles_x + tx) * rows + row, 1)


def scan_counts(counts: wp.array, offsets: wp.array) -> int:
    """Exclusive prefix sum of ``counts`` (last entry is a 0 sentinel) → total pair count."""
    wp.utils.array_scan(counts, offsets, inclusive=False)
    return int(offsets[offsets.shape[0] - 1:].numpy()[0])
