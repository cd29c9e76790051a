"""Stage 2 — bin raster: count (triangle, tile) pairs and lay out the per-tile queues.

Laine & Karras (2011) first distribute triangles to coarse bins, then bins to tiles. Here the
screen is cut directly into ``TILE`` × ``TILE`` (16×16) pixel tiles and this stage does the
*counting* half:

* the triangles are split into ``rows`` contiguous batches (on the CPU one per pool thread, so a
  counter row has a single writer and needs no atomics; on CUDA one batch, counted with atomics);
* for every piece, ``fixed.count_tiles`` walks the tiles of its bounding box and counts those it
  may touch (exact edge-function test of the tile's sample rectangle when the bbox spans several
  tiles both ways, so long thin triangles don't fill their whole bbox) into
  ``counts[tile·rows + batch]``. In the first pass this is fused into the triangle setup kernel;
  ``bin_count_kernel`` recounts a range of slots when the queue budget forces several passes;
* an exclusive prefix sum (``wp.utils.array_scan``) of that tile-major table gives every
  (tile, batch) its start in one queue array: tile t's queue is
  ``queue[offsets[t·rows] : offsets[(t+1)·rows]]``, ordered by batch, then (CPU) by triangle.

The scatter that fills the queues is the coarse raster (``coarse.py``).
"""
from __future__ import annotations

import warp as wp

from .fixed import TILE, count_tiles, pixel_bbox, sample_bbox, tile_overlaps  # noqa: F401
from .triangle_setup import SubTri

wp.set_module_options({"enable_backward": False})


@wp.kernel
def bin_count_kernel(
    base: int,
    sub_lo: int,
    batch: int,
    rows: int,
    tiles_x: int,
    width: int,
    height: int,
    subs: wp.array(dtype=SubTri),
    counts: wp.array(dtype=wp.int32),
    grid: int,
):
    j = base + wp.tid()
    s = sub_lo + j
    row = j // batch
    rec = subs[s]
    if rec.tri < 0:
        return  # empty slot (culled / clipped away / no pixel centre covered)
    bb = sample_bbox(rec.v0, rec.v1, rec.v2, width, height, grid)
    count_tiles(bb, rec.v0, rec.v1, rec.v2, tiles_x, rows, row, counts, grid)


def scan_counts(counts: wp.array, offsets: wp.array) -> int:
    """Exclusive prefix sum of ``counts`` (last entry is a 0 sentinel) → total pair count."""
    wp.utils.array_scan(counts, offsets, inclusive=False)
    if offsets.device.is_cpu:  # (a view of the array's memory: no copy)
        return int(offsets.numpy()[-1])
    return int(offsets[offsets.shape[0] - 1:].numpy()[0])
