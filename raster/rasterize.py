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
7. ``fine.resolve_kernel``: depth from 1/w, on the first access to ``VisibilityBuffer.depth``.

Steps 4–6 run in as many passes over the sub-triangles as the queue-memory budget needs
(``max_pairs``); the depth buffers persist across passes.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_sg.core.device import resolve_device
from warp_sg.core.errors import InputError
from warp_sg.core.meshcheck import check_mesh
from warp_sg.scene.camera import Camera

from . import parallel
from .bin import TILE, bin_count_kernel, scan_counts
from .coarse import coarse_scatter_kernel, relabel_kernel
from .fine import fine_pixel_kernel, fine_tile_kernel, resolve_kernel, resolve_pixel_kernel
from .triangle_setup import MAX_RESOLUTION, SubTri, guard_factors, setup_extra_kernel, setup_kernel, vertex_kernel

#: largest ``subsamples``: raster.subsample's edge functions take vertices in units of
#: 1/(2a·256) px as int32 (|coordinates| ≤ 2a·32000·256 < 2³¹)
MAX_SUBSAMPLES = 16
DEFAULT_MAX_PAIRS = 1 << 21  # triangle/tile pairs per pass: 128 MiB of 64-byte queue records
#: fewer triangles than this are set up and binned in one range on the CPU (no thread pool)
SMALL_MESH = 4096


class _Workspace:
    """Scratch arrays reused between calls (per device and calling thread): allocating and freeing
    hundreds of MB per frame costs more than some stages. Outputs are never taken from here."""

    def __init__(self, device):
        self.device = device
        self.bufs = {}

    def get(self, name, n, dtype):
        n = int(n)
        a = self.bufs.get(name)
        if a is None or a.shape[0] < n or a.dtype != dtype:
            a = wp.empty(max(n + n // 4, 1), dtype=dtype, device=self.device)
            self.bufs[name] = a
        return a[:n]

    def get2d(self, name, shape, dtype):
        a = self.bufs.get(name)
        if a is None or a.shape != tuple(shape) or a.dtype != dtype:
            a = wp.empty(tuple(shape), dtype=dtype, device=self.device)
            self.bufs[name] = a
        return a


_WORKSPACES: dict = {}


class _Clock:
    """Per-stage wall times when profiling (synchronises the device at each lap)."""

    def __init__(self, device, enabled):
        self.device, self.enabled, self.times = device, enabled, {}
        self.t = time.perf_counter()

    def lap(self, name):
        if self.enabled:
            wp.synchronize_device(self.device)
            t = time.perf_counter()
            self.times[name] = self.times.get(name, 0.0) + t - self.t
            self.t = t


def _workspace(device) -> _Workspace:
    key = (device, threading.get_ident())
    ws = _WORKSPACES.get(key)
    if ws is None:
        ws = _WORKSPACES[key] = _Workspace(device)
    return ws


def clear_workspace() -> None:
    """Free the cached scratch arrays (they hold the largest frame's working set)."""
    _WORKSPACES.clear()


@dataclass
class VisibilityBuffer:
    """Per-(sub)pixel visibility, all ``wp.array`` of shape (k·H, k·W) on ``device``.

    * ``tri_id`` int32: index of the visible input triangle, -1 where empty;
    * ``bary`` vec2: perspective-correct barycentric weights of the triangle's vertices 1 and 2
      (vertex 0's weight is ``1 - b1 - b2``); (0, 0) where empty;
    * ``inv_depth`` float32: 1 / the distance along the camera's view axis (the interpolated 1/w
      the depth test compares); 0 where empty;
    * ``depth`` float32 (a property, computed on first access): distance along the camera's view
      axis, +inf where empty;
    * ``coverage`` int32 (only with ``coverage_count=True``, else None): how many (sub-)triangles
      cover each pixel centre with the depth test off.
    """

    tri_id: wp.array
    bary: wp.array
    inv_depth: wp.array
    coverage: wp.array | None
    width: int
    height: int
    supersample: int
    device: str
    stats: dict
    _schedule: str = "tile"
    _depth_buf: wp.array | None = None  # reused storage for depth (a previous buffer's)
    _depth: wp.array | None = None
    #: with ``rasterize(subsamples=a)``: a and the tile queues (``raster.subsample``); offsets None:
    #: nothing was binned
    _subsamples: int = 1
    _queue: wp.array | None = None
    _offsets: wp.array | None = None
    _rows: int = 1
    _inv_far: float = 0.0
    #: ``rasterize(over=...)``: the buffer this one was drawn over (its queues hold the rest of
    #: the triangles, which ``raster.subsample`` walks too)
    _over: "VisibilityBuffer | None" = None
    #: drawn over ``_over`` with kept queues: the rows (y0, y1) outside which it equals ``_over``
    #: (a later draw over the same buffer that reuses this one's arrays copies only those back)
    _drawn_rows: tuple | None = None
    _bounds: tuple | None = None  # (queue_bounds, computed once)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.height, self.width)

    def queue_bounds(self):
        """``(x0, y0, x1, y1)``: the pixels (x0 ≤ x < x1, y0 ≤ y < y1) of the tiles that hold queued
        triangles, kept with ``subsamples`` > 1 — every pixel these triangles cover lies inside —
        or None when nothing was queued."""
        if self._offsets is None:
            return None
        if self._bounds is None:
            self._bounds = (self._queue_bounds(),)
        return self._bounds[0]

    def _queue_bounds(self):
        o = self._offsets.numpy()
        n_tiles = (len(o) - 1) // self._rows
        full = np.flatnonzero(o[self._rows::self._rows][:n_tiles] > o[:-1:self._rows][:n_tiles])
        if not len(full):
            return None
        tx, _ = tile_grid(self.width, self.height)
        cols, rows = full % tx, full // tx
        return (int(cols.min()) * TILE, int(rows.min()) * TILE, min(int(cols.max() + 1) * TILE, self.width),
                min(int(rows.max() + 1) * TILE, self.height))

    @property
    def depth(self) -> wp.array:
        if self._depth is None:
            H, W = self.height, self.width
            d = self._depth_buf if self._depth_buf is not None else wp.empty((H, W), dtype=wp.float32,
                                                                              device=self.device)
            if self._schedule == "tile":  # CPU: a row per thread
                parallel.launch(resolve_kernel, H, [self.inv_depth, self.tri_id, d], self.device, min_chunk=16)
            else:
                parallel.launch(resolve_pixel_kernel, H * W, [self.inv_depth, self.tri_id, d], self.device)
            self._depth, self._depth_buf = d, None
        return self._depth


def _as_numpy_mesh(vertices, triangles):
    """Validated contiguous (N,3) float32 / (M,3) int32 numpy copies (no copy when already so);
    a flat index buffer (as ``wp.Mesh`` takes it) is accepted. Checks: :func:`warp_sg.core.meshcheck.check_mesh`."""
    if isinstance(vertices, wp.array):
        vertices = vertices.numpy()
    if isinstance(triangles, wp.array):
        triangles = triangles.numpy()
    t = np.asarray(triangles)
    if t.ndim == 1 and t.size % 3 == 0:  # flat index buffer
        t = t.reshape(-1, 3)
    v, t, _ = check_mesh(vertices, t, dtype=np.float32, index_dtype=np.int32)
    return np.ascontiguousarray(v), np.ascontiguousarray(t)


def rasterize(vertices, triangles, camera: Camera, device="cpu", supersample: int = 1,
              cull_backfaces=False, coverage_count: bool = False, max_pairs: int | None = None,
              schedule: str = "auto", profile: bool = False, validate: bool = True,
              reuse: VisibilityBuffer | None = None, subsamples: int = 1, over: VisibilityBuffer | None = None,
              tri_ids: wp.array | None = None) -> VisibilityBuffer:
    """Rasterize a triangle mesh into a :class:`VisibilityBuffer` of (k·H, k·W) pixels.

    ``vertices`` (N, 3) float, ``triangles`` (M, 3) int (numpy or ``wp.array``); ``camera`` a
    :class:`Camera` (or any object with its fields); ``supersample`` k ≥ 1; ``cull_backfaces``
    drops triangles whose front (counter-clockwise) side faces away — all of them (True), or
    those with a set flag (one per triangle: a renderer culls the closed objects it sees from
    outside); ``coverage_count`` also
    returns per-pixel coverage counts (depth test off); ``max_pairs`` bounds the tile-queue
    memory (64-byte (triangle, tile) entries per pass; more passes when exceeded); ``schedule`` =
    "tile" | "pixel" | "auto" picks the fine raster kernel (auto: tiles on CPU, pixels on CUDA); ``profile`` records per-stage wall
    times (device-synchronised) in ``vb.stats["times"]``. ``validate=False`` with ``wp.array``
    inputs already on ``device`` (``vec3`` vertices, ``vec3i`` triangles, checked once by the
    caller, e.g. the ``Renderer``'s static geometry) uses them as they are: no per-frame
    validation and no host↔device copies. ``reuse``: a buffer the caller is done with; when its size
    and device match, its arrays are overwritten instead of allocating new ones (no page faults on
    the first touch of 16 bytes per sub-pixel every frame); ``reuse`` is invalid afterwards.
    ``subsamples`` a > 1: also bin the triangles that cover only sub-samples of an a×a grid per
    pixel (not just the centres) and keep the tile queues with the buffer, so that
    :func:`raster.subsample.subsample` finds the a×a coverage of any listed pixels later without
    another raster (adaptive antialiasing). One pass then (``max_pairs`` does not split it): the
    queue holds 64 bytes per (triangle, tile) pair, ~10 MB for 100 k triangles at 512².

    ``over``: a buffer of the same camera, size and ``subsamples`` holding other triangles of the
    same mesh; the result starts from its contents instead of an empty buffer, so it is the
    buffer of both sets of triangles — bit for bit a raster of their union, since each
    triangle's coverage, 1/w and barycentrics depend on it and the camera alone and the depth test
    keeps the maximum of a total order (larger 1/w, ties to the lower triangle id). ``tri_ids``
    ((M,) int ``wp.array``): the mesh's id of each row of ``triangles`` (a subset of a mesh, in
    ascending order), written to the buffer and compared in ties instead of the row index. A
    renderer whose dynamic objects move draws them over its static objects' buffer this way
    (``warp_sg.renderer.moving_raster``).
    """
    device = resolve_device(device)
    if not isinstance(camera, Camera):
        camera = Camera(**{k: getattr(camera, k) for k in ("origin", "target", "up", "fov", "width", "height",
                                                           "near", "far") if hasattr(camera, k)})
    try:
        k = int(supersample)
    except (TypeError, ValueError):
        k = 0
    if k < 1 or k != supersample:
        raise InputError(f"supersample must be a positive integer, got {supersample!r}", where="supersample")
    if not (isinstance(subsamples, (int, np.integer)) and 1 <= subsamples <= MAX_SUBSAMPLES):
        raise InputError(f"subsamples must be an integer in 1..{MAX_SUBSAMPLES}, got {subsamples!r}",
                         where="subsamples")
    W, H = camera.width * k, camera.height * k
    if W > MAX_RESOLUTION or H > MAX_RESOLUTION:
        raise InputError(f"{W}x{H} exceeds the rasterizer's {MAX_RESOLUTION}px limit per axis", where="camera")
    if schedule == "auto":
        schedule = "tile" if device.startswith("cpu") else "pixel"
    if schedule not in ("tile", "pixel"):
        raise InputError(f"schedule must be 'tile', 'pixel' or 'auto', got {schedule!r}", where="schedule")
    clock = _Clock(device, profile)
    trusted = (not validate and isinstance(vertices, wp.array) and isinstance(triangles, wp.array)
               and vertices.dtype == wp.vec3 and triangles.dtype == wp.vec3i
               and str(vertices.device) == device and str(triangles.device) == device)
    if trusted:
        n_v, n_t = vertices.shape[0], triangles.shape[0]
    else:
        v_np, t_np = _as_numpy_mesh(vertices, triangles)
        n_v, n_t = v_np.shape[0], t_np.shape[0]
    stats = {"triangles": n_t, "sub_triangles": 0, "pairs": 0, "passes": 0, "times": clock.times}
    clock.lap("validate")

    ws = _workspace(device)
    # the fine raster writes 1/w, tri_id and bary of the winners straight into the outputs
    depth_buf = None
    if reuse is not None and reuse.width == W and reuse.height == H and str(reuse.device) == device:
        tri_id, bary, best_invw = reuse.tri_id, reuse.bary, reuse.inv_depth
        depth_buf = reuse._depth if reuse._depth is not None else reuse._depth_buf
    else:
        tri_id = wp.empty((H, W), dtype=wp.int32, device=device)
        bary = wp.empty((H, W), dtype=wp.vec2, device=device)
        best_invw = wp.empty((H, W), dtype=wp.float32, device=device)
    if over is not None:  # draw over the other triangles' buffer
        if (over.width, over.height, over.supersample, over._subsamples, str(over.device)) != (W, H, k,
                                                                                            int(subsamples), device):
            raise InputError("over= needs a buffer of the same size, supersampling, subsamples and device",
                             where="over")
        rows = (0, H)  # the rows to copy: all, or those the buffer's last draw over `over` changed
        if reuse is not None and reuse._over is over and reuse.tri_id is tri_id and reuse._drawn_rows is not None:
            rows = reuse._drawn_rows
        if rows[1] > rows[0]:
            o, c = rows[0] * W, (rows[1] - rows[0]) * W
            for dst, src in ((best_invw, over.inv_depth), (tri_id, over.tri_id), (bary, over.bary)):
                wp.copy(dst, src, dest_offset=o, src_offset=o, count=c)
    else:
        best_invw.zero_()  # (memsets: on the CPU faster than clearing in the fine kernel's tiles)
        tri_id.fill_(-1)
        bary.zero_()
    clock.lap("clear")
    coverage = wp.zeros((H, W), dtype=wp.int32, device=device) if coverage_count else None
    cov_arg = coverage if coverage is not None else wp.zeros((1, 1), dtype=wp.int32, device=device)

    if n_t > 0:
        if trusted:
            verts, tris = vertices, triangles
        else:
            host = device.startswith("cpu")  # CPU: reference the numpy memory, no copy
            verts = wp.array(v_np, dtype=wp.vec3, device=device, copy=not host)
            tris = wp.array(t_np, dtype=wp.vec3i, device=device, copy=not host)
        gx, gy = guard_factors(W, H)
        near, far = float(camera.near), float(camera.far)
        clip = ws.get("clip", n_v, wp.vec4d)
        vsnap = ws.get("vsnap", n_v, wp.vec2i)
        vcode = ws.get("vcode", n_v, wp.int32)
        mvp = wp.mat44d(*camera.view_projection().reshape(-1))
        parallel.launch(vertex_kernel, n_v, [verts, mvp, W, H, near, far, gx, gy, clip, vsnap, vcode], device,
                        min_chunk=4096, chunks=parallel.cpu_workers())  # (uniform work: a range per thread)
        clock.lap("vertex")

        # triangle setup: slot i = first piece of triangle i; clipped triangles' further pieces after M
        cull, cull_tri = _cull_args(cull_backfaces, n_t, device, ws)
        extra = ws.get("extra", n_t + 1, wp.int32)
        extra[n_t:].zero_()
        subs = ws.get("subs", n_t, SubTri)
        bins = _Bins(W, H, device, ws, n_t)
        grid = max(int(subsamples), 1)
        bin_args = [bins.batch, bins.rows, bins.tiles_x, bins.counts, grid]
        parallel.launch_rows(setup_kernel, n_t, min(bins.rows, n_t),
                             [clip, vsnap, vcode, tris, W, H, near, gx, gy, cull, cull_tri, subs, extra, *bin_args], device)
        extra_off = ws.get("extra_off", n_t + 1, wp.int32)
        n_extra = scan_counts(extra, extra_off)
        if n_extra > 0:
            grown = ws.get("subs_grown", n_t + n_extra, SubTri)
            wp.copy(grown, subs, count=n_t)
            subs = grown
            parallel.launch_rows(setup_extra_kernel, n_t, min(bins.rows, n_t),
                                 [clip, tris, W, H, near, gx, gy, cull, cull_tri, extra, extra_off, subs, *bin_args],
                                 device)
        clock.lap("setup")
        n_sub = n_t + n_extra
        stats["sub_triangles"] = n_sub
        stats["clipped_extra"] = n_extra
        keep = None
        if grid > 1:  # the queues stay with the buffer (reusing a previous buffer's storage)
            keep = {"queue": getattr(reuse, "_queue", None) if reuse is not None else None, "offsets": None,
                    "rows": bins.rows}
        _bin_and_raster(subs, n_t, n_extra, bins, W, H, camera, best_invw, tri_id, bary, cov_arg,
                        coverage is not None, device, max_pairs or DEFAULT_MAX_PAIRS, schedule, stats, ws, clock,
                        grid, keep, tri_ids)
    else:
        keep = {"queue": None, "offsets": None, "rows": 1} if int(subsamples) > 1 else None
    vb = VisibilityBuffer(tri_id, bary, best_invw, coverage, W, H, k, device, stats, _schedule=schedule,
                          _depth_buf=depth_buf)
    if keep is not None:
        vb._subsamples, vb._queue, vb._offsets, vb._rows = int(subsamples), keep["queue"], keep["offsets"], keep["rows"]
        vb._inv_far = 1.0 / float(camera.far)
    vb._over = over
    if over is not None and keep is not None:  # (the tiles its queue holds: every pixel it drew lies in them)
        box = vb.queue_bounds()
        vb._drawn_rows = (0, 0) if box is None else (box[1], box[3])
    if profile:
        _ = vb.depth  # (resolved now, for its time)
        clock.lap("resolve")
    return vb


def _cull_args(cull_backfaces, n_t: int, device: str, ws) -> tuple:
    """(mode, per-triangle flags) of ``rasterize(cull_backfaces=...)``: a bool (0 / 1, flags
    unused) or one flag per triangle (mode 2; a ``wp.array(uint8)`` on the device or array-like)."""
    if isinstance(cull_backfaces, (bool, int, np.bool_)) or cull_backfaces is None:
        return int(bool(cull_backfaces)), ws.get("no_cull", 1, wp.uint8)
    if isinstance(cull_backfaces, wp.array) and cull_backfaces.dtype == wp.uint8 and str(cull_backfaces.device) == device:
        flags = cull_backfaces
    else:
        flags = wp.array(np.ascontiguousarray(np.asarray(cull_backfaces).astype(np.uint8).reshape(-1)), dtype=wp.uint8,
                         device=device)
    if flags.shape[0] != n_t:
        raise InputError(f"cull_backfaces has {flags.shape[0]} flags for {n_t} triangles", where="cull_backfaces")
    return 2, flags


class _Bins:
    """Tile grid + per-(tile, batch) counters shared by the fused setup/bin pass and the passes."""

    def __init__(self, W, H, device, ws, n_t):
        self.tiles_x = (W + TILE - 1) // TILE
        self.n_tiles = self.tiles_x * ((H + TILE - 1) // TILE)
        self.cpu = device.startswith("cpu")
        # one counter row per pool thread (CPU); a few triangles in one range: a dispatch costs more
        self.rows = parallel.cpu_workers() if self.cpu and n_t >= SMALL_MESH else 1
        self.counts = ws.get("counts", self.n_tiles * self.rows + 1, wp.int32)
        self.offsets = ws.get("offsets", self.n_tiles * self.rows + 1, wp.int32)
        self.cursor = ws.get("cursor", self.n_tiles * self.rows, wp.int32)
        self.counts.zero_()
        # fused counting in setup: triangle i is counted in row i // batch by the pool thread owning it
        self.batch = max(1, (n_t + self.rows - 1) // self.rows)


def tile_grid(width: int, height: int) -> tuple[int, int]:
    """(tiles_x, tiles_y): the fine raster's ``TILE``×``TILE`` tiles over a width × height grid."""
    return (width + TILE - 1) // TILE, (height + TILE - 1) // TILE


def _bin_and_raster(subs, n_t, n_extra, bins, W, H, camera, best_invw, best_tri, best_bary,
                    coverage, count_mode, device, max_pairs, schedule, stats, ws, clock, grid, keep, tri_ids=None):
    """Bin, scatter and draw in as many passes as the queue budget needs. ``keep`` (a dict, with
    ``subsamples``): one pass, whose queue (``keep["queue"]``: storage to reuse when large enough)
    and offsets are returned in it. ``tri_ids``: the queued records' triangle ids are mapped
    through it before the fine raster (``rasterize(tri_ids=...)``)."""
    n_sub = n_t + n_extra
    tiles_x, n_tiles, rows = bins.tiles_x, bins.n_tiles, bins.rows
    counts, offsets, cursor = bins.counts, bins.offsets, bins.cursor
    max_pairs = max(int(max_pairs), n_tiles)  # one triangle alone always fits
    if keep is not None:
        max_pairs = 1 << 62  # the kept queue must hold every pair
    inv_far = 1.0 / float(camera.far)

    stack = [(0, n_sub)]
    first = True
    while stack:
        lo, hi = stack.pop()
        n = hi - lo
        r = min(rows, n)
        batch = (n + r - 1) // r
        if not first:  # a split pass: count its slot range (rows = contiguous slot batches)
            counts.zero_()
            parallel.launch_rows(bin_count_kernel, n, r, [lo, batch, rows, tiles_x, W, H, subs, counts, grid], device)
        total = scan_counts(counts, offsets)
        clock.lap("bin")
        if total > max_pairs and n > 1:
            mid = lo + n // 2
            stack.append((mid, hi))
            stack.append((lo, mid))
            first = False
            continue
        stats["pairs"] += total
        stats["passes"] += 1
        if total == 0:
            first = False
            continue
        if keep is None:
            queue = ws.get("queue", total, SubTri)
        else:
            queue = keep["queue"]
            if queue is None or queue.shape[0] < total or str(queue.device) != device:
                queue = wp.empty(max(total, 1) + total // 4, dtype=SubTri, device=device)  # room to grow
            keep["queue"] = queue
            keep["offsets"] = wp.clone(offsets)
        cursor.zero_()
        if first:
            # counted by setup: primaries per pool thread, then the clipped extra pieces (few) serially
            parallel.launch_rows(coarse_scatter_kernel, n_t, min(rows, n_t),
                                 [0, bins.batch, rows, tiles_x, W, H, subs, offsets, cursor, queue, 0, grid], device)
            if n_extra > 0:
                wp.launch(coarse_scatter_kernel, dim=n_extra,
                          inputs=[0, n_t, bins.batch, rows, tiles_x, W, H, subs, offsets, cursor, queue, 1, grid],
                          device=device)
        else:
            parallel.launch_rows(coarse_scatter_kernel, n, r,
                                 [lo, batch, rows, tiles_x, W, H, subs, offsets, cursor, queue, 0, grid], device)
        first = False
        if tri_ids is not None:
            parallel.launch(relabel_kernel, total, [queue, tri_ids], device, min_chunk=16384)
        clock.lap("coarse")
        args = [tiles_x, n_tiles, rows, W, H, inv_far, int(count_mode), offsets, queue, best_invw, best_tri,
                best_bary, coverage]
        if schedule == "tile":  # (a short queue: fewer ranges, each costs a dispatch)
            workers = parallel.cpu_workers()
            parallel.launch(fine_tile_kernel, n_tiles, args, device,
                            chunks=8 * workers if total >= 16384 else max(1, total // 2048), min_chunk=1)
        else:
            parallel.launch(fine_pixel_kernel, n_tiles * TILE * TILE, args, device, min_chunk=TILE * TILE)
        clock.lap("fine")


__all__ = ["VisibilityBuffer", "rasterize", "tile_grid", "clear_workspace", "DEFAULT_MAX_PAIRS"]
