r"""Which of the moving vertices' per-vertex cache rows a frame reads, and which of those are stale.

A moved frame recomputes the moving vertices' rows of the per-vertex caches (the lights' SSDF
deficits, the environment's visible fraction, its lobes' visibility:
:meth:`warp_sg.renderer.dynamic_objects.DynamicObjects.patch_caches`). The shading kernel reads a
vertex's rows only where a sample sees one of its triangles, and every sample of a frame — the
pixel centres and antialiasing's sub-pixels (``raster.subsample`` walks the same queues) — sees a
triangle that the raster queued. The moving part of the visibility buffer
(:mod:`warp_sg.renderer.moving_raster`, rasterised with ``subsamples`` > 1) keeps its tile queues,
so the rows a frame reads are those of the vertices of the moving triangles in that queue: for a
closed object seen from outside, its front faces in view (the turning bunny: 39 % of its
vertices). Only those are computed, each for the current transforms; a row is stamped with the
transform version it was computed for, so that a row the frame reads is never one of an older
pose (the camera turned to the side that was hidden: those rows are computed then). The rows a
frame does not read are left as they were; the image is a function of the transforms and the
camera, as before (each row a pure function of its vertex's pose).

Without a kept queue (supersampling, ``Renderer.incremental_raster = False``, the preview's
per-vertex shading) every moving vertex's row is computed.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import numpy as np
import warp as wp

from raster.triangle_setup import SubTri


@wp.kernel(enable_backward=False)
def mark_queued_kernel(base: int, queue: wp.array(dtype=SubTri), tris: wp.array(dtype=wp.vec3i),
                       slot_of: wp.array(dtype=int), needed: wp.array(dtype=int)):
    """Queue record ``base + tid`` (its triangle a mesh id): ``needed[slot_of[v]] = 1`` for its
    three vertices (plain stores of one value from any thread: no race)."""
    t = queue[base + wp.tid()].tri
    if t >= 0:
        tr = tris[t]
        for c in range(3):
            s = slot_of[tr[c]]
            if s >= 0:
                needed[s] = 1


class FrameRows:
    """The moving vertices' rows a frame reads (module docstring). ``ids``: the moving vertices'
    mesh ids (numpy, in the order of their slots, ``DynamicObjects.all_ids``); ``n_vertices``: the
    mesh's vertex count."""

    def __init__(self, ids: np.ndarray, n_vertices: int, device):
        self.ids = np.asarray(ids, np.int32)
        self.device = device
        slot_of = np.full(max(int(n_vertices), 1), -1, np.int32)
        slot_of[self.ids] = np.arange(len(self.ids), dtype=np.int32)
        self.slot_of = wp.array(slot_of, dtype=int, device=device)
        self._needed = wp.zeros(max(len(self.ids), 1), dtype=int, device=device)
        self._memo = (None, None)  # (the moving part's buffer, its mask)
        self._stamps = {}  # cache name -> (the cache array's identity, per slot the version its row holds)
        self._ids_memo = None  # (slots, their mesh ids on the device): mesh_ids
        #: rows computed (all caches together), for tests and the bench
        self.computed = 0

    def needed(self, vb, tris: wp.array):
        """(slots,) bool: the moving vertices of the triangles queued in ``vb`` (the moving part's
        buffer of this frame, kept queues), or None (no queue kept: every row)."""
        if vb is None or vb._subsamples < 2:
            return None
        if self._memo[0] is vb:
            return self._memo[1]
        from raster import parallel

        total = 0 if vb._offsets is None else _last(vb._offsets)
        self._needed.zero_()
        if total > 0:
            parallel.launch(mark_queued_kernel, total, [vb._queue, tris, self.slot_of, self._needed], self.device,
                            min_chunk=4096, chunks=parallel.cpu_workers())
        mask = self._needed.numpy()[:len(self.ids)] != 0  # (a view on the CPU)
        self._memo = (vb, mask)
        return mask

    def stale(self, name: str, ident: int, fresh_when_rebuilt: bool, version: int, needed) -> np.ndarray:
        """The slots (ascending) of cache ``name`` whose row the frame reads (``needed``; None: all)
        and does not hold for ``version``; a cache array of a new identity was just rebuilt for the
        current pose (every row fresh, unless ``fresh_when_rebuilt`` is False: the moving rows come
        from elsewhere). :meth:`done` stamps them once computed."""
        st = self._stamps.get(name)
        if st is None or st[0] != ident:
            st = (ident, np.full(len(self.ids), version if fresh_when_rebuilt else -1, np.int64), None)
            self._stamps[name] = st
        # (the needed mask of a frame is one array, memoised per buffer: compared by identity)
        if st[2] is not None and st[2][0] == version and st[2][1] is needed:
            return _NONE  # every row it reads was found fresh, or computed, since
        todo = st[1] != version
        if needed is not None:
            todo &= needed
        slots = np.flatnonzero(todo)
        if not len(slots):
            self._stamps[name] = (st[0], st[1], (version, needed))
        return slots

    def done(self, name: str, slots: np.ndarray, version: int, needed) -> None:
        """Stamp cache ``name``'s rows ``slots`` as computed for ``version`` (every row of
        ``needed`` now is)."""
        ident, stamp, _ = self._stamps[name]
        stamp[slots] = version
        self._stamps[name] = (ident, stamp, (version, needed))
        self.computed += len(slots)

    def mesh_ids(self, slots: np.ndarray) -> wp.array:
        """The mesh ids of ``slots`` as a device int array (the last list's kept: the caches of a
        frame usually ask for the same)."""
        last = self._ids_memo
        if last is None or not np.array_equal(last[0], slots):
            self._ids_memo = last = (slots.copy(), wp.array(self.ids[slots], dtype=int, device=self.device))
        return last[1]


_NONE = np.zeros(0, np.int64)


def _last(a: wp.array) -> int:
    """The last entry of an int array (a view on the CPU, one value copied elsewhere)."""
    n = int(a.shape[0])
    return int(a.numpy()[n - 1]) if a.device.is_cpu else int(a[n - 1:].numpy()[0])


__all__ = ["FrameRows", "mark_queued_kernel"]
