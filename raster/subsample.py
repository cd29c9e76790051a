"""Sub-sample coverage of listed pixels, from the tile queues of a kept 1× raster.

``rasterize(..., subsamples=a)`` bins every (sub-)triangle that may cover any of a pixel's a×a
sub-samples — not only those that cover a pixel centre — and keeps the per-tile queues with the
buffer. :func:`subsample` then finds what each sub-sample of a few listed pixels sees (adaptive
antialiasing: the pixels on contours and shadow edges), without a second raster of the a×-sized
grid: one thread per tile that holds listed pixels walks that tile's queue once and tests, for
each record, the a×a sub-samples of the listed pixels in its bounding box.

The tests are the fine raster's (``fine.py``), at the sub-sample positions
``(x + (2i+1)/(2a), y + (2j+1)/(2a))`` instead of the centre: coverage by the exact int64 edge
functions of the same snapped vertices with the top-left rule (evaluated in units of
1/(2a·SUBPIXEL) px, where every sub-sample position is an integer: watertight, each sub-sample on
a shared edge covered once), the depth test on the record's 1/w plane (nearest wins, ties to the
lower triangle id, nothing beyond the far plane), and perspective-correct barycentrics from its
planes. Sub-samples are therefore those of a raster of the a×-sized grid whose vertices are
snapped to 1/SUBPIXEL of a *pixel* (not of a sub-pixel): the same image up to ≤ 1/512 px of vertex
position.
"""
from __future__ import annotations

import warp as wp

from . import parallel
from .fine import barycentrics_at, closer
from .fixed import SUBPIXEL, TILE, TILE_BITS, edge_eval, edge_topleft, eval_plane_at, sample_bbox
from .triangle_setup import SubTri

wp.set_module_options({"enable_backward": False})


@wp.func
def _grid_max(e: wp.int64, dx: wp.int64, dy: wp.int64, span: wp.int64):
    """Largest value of an edge function over an a×a sample grid: e at sample (0, 0), steps dx, dy,
    span = a − 1."""
    m = e
    if dx > wp.int64(0):
        m += dx * span
    if dy > wp.int64(0):
        m += dy * span
    return m


vec16i = wp.types.vector(length=16, dtype=wp.int32)  # one bit row per tile row (TILE = 16)
assert TILE == 16, "subsample_tiles_kernel keeps one 16-bit row mask per tile row"


@wp.kernel
def subsample_tiles_kernel(base: int, tiles: wp.array(dtype=int), tiles_x: int, rows: int, width: int, height: int,
                           a: int, inv_far: float, slot: wp.array2d(dtype=int), offsets: wp.array(dtype=wp.int32),
                           queue: wp.array(dtype=SubTri), mask: wp.array(dtype=int), sub_tri: wp.array2d(dtype=int),
                           sub_bary: wp.array2d(dtype=wp.vec2), sub_invw: wp.array2d(dtype=float)):
    """Tile ``tiles[base + tid]``: the a×a sub-samples of its listed pixels (``slot[y, x]`` ≥ 0:
    row of the outputs; sub-sample q = j·a + i; with ``mask`` not empty only the rows it flags) —
    the winning triangle (-1: none), its barycentrics (b1, b2) and 1/w (0: none), against what the
    outputs hold (cleared before the first queue, :func:`subsample`)."""
    t = tiles[base + wp.tid()]
    tx = t % tiles_x
    ty = t / tiles_x
    X0 = tx * TILE
    Y0 = ty * TILE
    X1 = wp.min(X0 + TILE, width) - 1
    Y1 = wp.min(Y0 + TILE, height) - 1
    rowbits = vec16i()  # listed pixels of the tile, a bit per column: records that miss them are skipped
    for y in range(Y0, Y1 + 1):
        for x in range(X0, X1 + 1):
            s = slot[y, x]
            if s >= 0:
                if mask.shape[0] == 0 or mask[s] != 0:
                    rowbits[y - Y0] = rowbits[y - Y0] | (1 << (x - X0))
    g = 2 * a  # sub-sample coordinates in units of 1/(2a·SUBPIXEL) px
    o = wp.int64(SUBPIXEL)  # half a sub-pixel
    d = wp.int64(g) * o  # one pixel
    z = wp.int64(0)
    inv_a = 1.0 / float(a)
    for qi in range(offsets[t * rows], offsets[(t + 1) * rows]):
        rec = queue[qi]
        bb = sample_bbox(rec.v0, rec.v1, rec.v2, width, height, a)
        x0 = wp.max(bb[0], X0)
        y0 = wp.max(bb[1], Y0)
        x1 = wp.min(bb[2], X1)
        y1 = wp.min(bb[3], Y1)
        if x0 > x1 or y0 > y1:
            continue
        cols = ((1 << (x1 - X0 + 1)) - 1) & ~((1 << (x0 - X0)) - 1)
        hit = int(0)
        for y in range(y0, y1 + 1):
            hit = hit | (rowbits[y - Y0] & cols)
        if hit == 0:
            continue
        # the vertices in those units (|coordinates| < 2·16·32000·256 < 2³¹ for a ≤ 16)
        p0 = wp.vec2i(rec.v0[0] * g, rec.v0[1] * g)
        p1 = wp.vec2i(rec.v1[0] * g, rec.v1[1] * g)
        p2 = wp.vec2i(rec.v2[0] * g, rec.v2[1] * g)
        t0 = wp.int64(edge_topleft(rec.v0, rec.v1))
        t1 = wp.int64(edge_topleft(rec.v1, rec.v2))
        t2 = wp.int64(edge_topleft(rec.v2, rec.v0))
        # edge functions at sub-sample (0, 0) of a pixel, and their steps to the next sub-sample
        # along x and y (the fine raster's incremental form, exact in int64)
        dx0 = -wp.int64(p1[1] - p0[1]) * (o + o)
        dx1 = -wp.int64(p2[1] - p1[1]) * (o + o)
        dx2 = -wp.int64(p0[1] - p2[1]) * (o + o)
        dy0 = wp.int64(p1[0] - p0[0]) * (o + o)
        dy1 = wp.int64(p2[0] - p1[0]) * (o + o)
        dy2 = wp.int64(p0[0] - p2[0]) * (o + o)
        span = wp.int64(a - 1)
        for y in range(y0, y1 + 1):
            for x in range(x0, x1 + 1):
                if (rowbits[y - Y0] & (1 << (x - X0))) == 0:
                    continue
                sx = wp.int64(x) * d + o
                sy = wp.int64(y) * d + o
                r0 = edge_eval(p0, p1, sx, sy) + t0
                r1 = edge_eval(p1, p2, sx, sy) + t1
                r2 = edge_eval(p2, p0, sx, sy) + t2
                # the pixel's sub-samples all outside one edge: nothing to test
                if (_grid_max(r0, dx0, dy0, span) <= z or _grid_max(r1, dx1, dy1, span) <= z
                        or _grid_max(r2, dx2, dy2, span) <= z):
                    continue
                s = slot[y, x]
                for j in range(a):
                    e0 = r0
                    e1 = r1
                    e2 = r2
                    for i in range(a):
                        if e0 > z and e1 > z and e2 > z:
                            fx = float(x) + (float(i) + 0.5) * inv_a
                            fy = float(y) + (float(j) + 0.5) * inv_a
                            invw = eval_plane_at(rec.p, 0, rec.v0, fx, fy)
                            q = j * a + i
                            if invw >= inv_far and closer(invw, rec.tri, sub_invw[s, q], sub_tri[s, q]):
                                sub_invw[s, q] = invw
                                sub_tri[s, q] = rec.tri
                                sub_bary[s, q] = barycentrics_at(rec.p, rec.v0, fx, fy, invw)
                        e0 += dx0
                        e1 += dx1
                        e2 += dx2
                    r0 += dy0
                    r1 += dy1
                    r2 += dy2


@wp.kernel
def _slots_kernel(base: int, pixels: wp.array(dtype=int), width: int, tiles_x: int, slot: wp.array2d(dtype=int),
                  tile_flag: wp.array(dtype=int)):
    """slot[pixel] = its row i; flag the pixel's tile (plain stores of one value: no race)."""
    i = base + wp.tid()
    k = pixels[i]
    y = k / width
    x = k - y * width
    slot[y, x] = i
    tile_flag[(y >> TILE_BITS) * tiles_x + (x >> TILE_BITS)] = 1


def subsample(vb, pixels: wp.array, kept=None):
    """What the a×a sub-samples of the listed pixels see, for a buffer of
    ``rasterize(..., subsamples=a)``: ``(tri, bary, inv_depth, tiles)`` — ``wp.array2d`` of shape
    (n, a²) (int, vec2, float; sub-sample q = j·a + i of pixel ``pixels[r]`` (row-major index
    y·W + x, distinct) in row r; tri -1 and inv_depth 0 where it sees nothing) and the number of
    tiles visited. A buffer drawn over another (``rasterize(over=...)``) walks both's queues;
    ``kept``: a :class:`KeptSubsamples` of the buffer it was drawn over, which gives the pixels it
    has seen before and computes (and keeps) the others."""
    a = int(getattr(vb, "_subsamples", 1))
    if a < 2:
        raise ValueError("subsample() needs a buffer rasterised with subsamples > 1")
    device = vb.device
    n = int(pixels.shape[0])
    W, H = vb.width, vb.height
    if kept is not None:
        tri, bary, invw, unknown = kept.begin(pixels)
    else:
        tri = wp.full((max(n, 1), a * a), -1, dtype=int, device=device)
        bary = wp.zeros((max(n, 1), a * a), dtype=wp.vec2, device=device)
        invw = wp.zeros((max(n, 1), a * a), dtype=float, device=device)
    if n == 0:
        return tri[:0], bary[:0], invw[:0], 0
    tiles_x = (W + TILE - 1) // TILE
    n_tiles = tiles_x * ((H + TILE - 1) // TILE)
    slot = wp.full((H, W), -1, dtype=int, device=device)
    flag = wp.zeros(n_tiles, dtype=int, device=device)
    parallel.launch(_slots_kernel, n, [pixels, W, tiles_x, slot, flag], device, min_chunk=16384)  # trivial: one range
    tiles = parallel.compact(flag, device)
    workers, n_t = parallel.cpu_workers(), int(tiles.shape[0])
    none = wp.zeros(0, dtype=int, device=device)

    def walk(layer, mask, tl):  # one buffer's queues over tiles tl (offsets None: nothing was binned)
        m = int(tl.shape[0])
        if layer._offsets is not None and m:  # ranges: 8 per thread, fewer for a short queue or a few tiles
            chunks = min(8 * workers, max(1, int(layer.stats.get("pairs", 1 << 20)) // 4096), max(1, m // 16))
            parallel.launch(subsample_tiles_kernel, m, [tl, tiles_x, layer._rows, W, H, a, float(layer._inv_far),
                                                        slot, layer._offsets, layer._queue, mask, tri, bary, invw],
                            device, chunks=chunks, min_chunk=1)

    if kept is not None:
        new_tiles = wp.zeros(n_tiles, dtype=int, device=device)  # the tiles of the pixels it has not seen
        parallel.launch(_unknown_tiles_kernel, n, [pixels, unknown, W, tiles_x, new_tiles], device, min_chunk=16384)
        walk(kept.vb, unknown, parallel.compact(new_tiles, device))
        kept.finish(pixels, unknown, (tri, bary, invw))
        walk(vb, none, tiles)
    else:
        layer = vb
        while layer is not None:  # this buffer's queues and those of the buffers it was drawn over
            walk(layer, none, tiles)
            layer = layer._over
    return tri[:n], bary[:n], invw[:n], n_t


@wp.kernel
def _unknown_tiles_kernel(base: int, pixels: wp.array(dtype=int), unknown: wp.array(dtype=int), width: int,
                          tiles_x: int, tile_flag: wp.array(dtype=int)):
    i = base + wp.tid()
    if unknown[i] != 0:
        k = pixels[i]
        y = k / width
        tile_flag[(y >> TILE_BITS) * tiles_x + ((k - y * width) >> TILE_BITS)] = 1


@wp.kernel
def _begin_kernel(base: int, pixels: wp.array(dtype=int), width: int, row: wp.array2d(dtype=int),
                  tri: wp.array2d(dtype=int), bary: wp.array2d(dtype=wp.vec2), invw: wp.array2d(dtype=float),
                  out_tri: wp.array2d(dtype=int), out_bary: wp.array2d(dtype=wp.vec2),
                  out_invw: wp.array2d(dtype=float), unknown: wp.array(dtype=int)):
    """Listed pixel i: its kept row's sub-samples, or empty ones and ``unknown[i] = 1``."""
    i = base + wp.tid()
    k = pixels[i]
    y = k / width
    r = row[y, k - y * width]
    unknown[i] = int(r < 0)
    for q in range(out_tri.shape[1]):
        if r >= 0:
            out_tri[i, q] = tri[r, q]
            out_bary[i, q] = bary[r, q]
            out_invw[i, q] = invw[r, q]
        else:
            out_tri[i, q] = -1
            out_bary[i, q] = wp.vec2(0.0, 0.0)
            out_invw[i, q] = 0.0


@wp.kernel
def _keep_kernel(base: int, pixels: wp.array(dtype=int), pos: wp.array(dtype=int), first: int, width: int,
                 tri: wp.array2d(dtype=int), bary: wp.array2d(dtype=wp.vec2), invw: wp.array2d(dtype=float),
                 row: wp.array2d(dtype=int), kept_tri: wp.array2d(dtype=int), kept_bary: wp.array2d(dtype=wp.vec2),
                 kept_invw: wp.array2d(dtype=float)):
    """New pixel j (row ``pos[base + tid]`` of the outputs) kept in row ``first + j``."""
    j = base + wp.tid()
    i = pos[j]
    k = pixels[i]
    y = k / width
    row[y, k - y * width] = first + j
    for q in range(tri.shape[1]):
        kept_tri[first + j, q] = tri[i, q]
        kept_bary[first + j, q] = bary[i, q]
        kept_invw[first + j, q] = invw[i, q]


class KeptSubsamples:
    """:func:`subsample` of one buffer, kept by pixel between calls: a pixel's sub-samples are
    computed the first time it is listed and copied afterwards. A renderer whose moving objects
    are drawn over its static objects' buffer (``rasterize(over=...)``) asks every frame for the
    sub-samples of a candidate list that changes a little (around the moving objects, their
    shadows); ``subsample(moving, pixels, kept=KeptSubsamples(static))`` walks the static queues
    for the new pixels only — the same values. At most ``max(4 n, 16384)`` pixels are kept (n:
    the list's length); beyond, the store starts again. ``computed`` counts the pixels computed."""

    def __init__(self, vb):
        a = int(vb._subsamples)
        self.vb, self.a, self.n, self.computed = vb, a, 0, 0
        self.row = wp.full((vb.height, vb.width), -1, dtype=int, device=vb.device)
        self.store = self._alloc(1)

    def _alloc(self, rows: int) -> tuple:
        d, a2 = self.vb.device, self.a * self.a
        return (wp.empty((rows, a2), dtype=int, device=d), wp.empty((rows, a2), dtype=wp.vec2, device=d),
                wp.empty((rows, a2), dtype=float, device=d))

    def begin(self, pixels: wp.array) -> tuple:
        """``(tri, bary, inv_depth, unknown)`` of ``pixels``: the kept ones' sub-samples, empty
        rows flagged in ``unknown`` for the others (:func:`subsample` walks the kept buffer's queues
        for those, then calls :meth:`finish`)."""
        n = int(pixels.shape[0])
        out = self._alloc(max(n, 1))
        unknown = wp.empty(max(n, 1), dtype=int, device=self.vb.device)
        if n:
            parallel.launch(_begin_kernel, n, [pixels, self.vb.width, self.row, *self.store, *out, unknown],
                            self.vb.device, min_chunk=1024, chunks=parallel.cpu_workers())
        return (*out, unknown)

    def finish(self, pixels: wp.array, unknown: wp.array, out: tuple) -> None:
        """Keep the rows of ``out`` that ``unknown`` flags (computed now)."""
        n = int(pixels.shape[0])
        pos = parallel.compact(unknown[:n], self.vb.device)
        m = int(pos.shape[0])
        if not m:
            return
        if self.n + m > max(4 * n, 16384):  # start again
            self.row.fill_(-1)
            self.n = 0
        if self.store[0].shape[0] < self.n + m:
            new = self._alloc(max(2 * (self.n + m), 1024))
            for dst, src in zip(new, self.store):
                if self.n:
                    wp.copy(dst, src, count=self.n * self.a * self.a)
            self.store = new
        parallel.launch(_keep_kernel, m, [pixels, pos, self.n, self.vb.width, *out, self.row, *self.store],
                        self.vb.device, min_chunk=4096)
        self.n += m
        self.computed += m


__all__ = ["KeptSubsamples", "subsample", "subsample_tiles_kernel"]
