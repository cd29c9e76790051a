r"""The visibility buffer of a scene with dynamic objects, in two parts: static and moving.

A frame after :meth:`Renderer.set_object_transform` with the camera where it was has the same
static geometry in view as the last frame. Its triangles are rasterised once per camera (and
antialiasing's sub-pixel grid) into a buffer of their own, with their tile queues; each frame then
rasterises only the dynamic objects' triangles, drawn over a copy of it (``raster.rasterize(over=,
tri_ids=)``: the depth test against the static winners, ties by the mesh's triangle ids) — bit for
bit the raster of the whole mesh, at the cost of the moving triangles and a copy of the buffer.
The antialiasing's sub-pixel coverage walks both parts' queues (``raster.subsample``), and its
contours split likewise (:class:`warp_sg.renderer.antialias.AntialiasCache`).

The moving part is rasterised from a compact copy of its vertices (gathered each frame), so its
vertex stage costs its own vertices only. Back-face culling (``warp_sg.scene.culling``) takes each
part's share of the renderer's flags; the static part is rasterised again only when the camera,
the grid or its own flags change.
"""
from __future__ import annotations

import numpy as np
import warp as wp


@wp.kernel(enable_backward=False)
def gather_kernel(ids: wp.array(dtype=int), src: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = src[ids[i]]


class _Part:
    """One part's triangles (ascending mesh ids) and their id map; ``compact``: the part's own
    vertex buffer (its vertices gathered, its triangles renumbered) instead of the mesh's."""

    def __init__(self, ids: np.ndarray, triangles: np.ndarray, device, compact: bool = False):
        self.ids_np = ids.astype(np.int32)
        T = triangles[ids]
        self.vertex_ids = None
        if compact:
            vids = np.unique(T)
            T = np.searchsorted(vids, T)
            self.vertex_ids = wp.array(vids.astype(np.int32), dtype=int, device=device)
            self.positions = wp.empty(max(len(vids), 1), dtype=wp.vec3, device=device)
        self.tris = wp.array(np.ascontiguousarray(T, np.int32).reshape(-1, 3), dtype=wp.vec3i, device=device)
        self.ids = wp.array(self.ids_np if len(ids) else np.zeros(1, np.int32), dtype=int, device=device)
        self.key = None
        self.vb = None
        self._flags = (None, None)  # (the renderer's flags, this part's)

    def flags(self, cull):
        """This part's ``cull_backfaces`` from the whole mesh's (False, or one flag per triangle)."""
        if isinstance(cull, (bool, np.bool_)) or cull is None:
            return bool(cull)
        if self._flags[0] is not cull:
            sub = cull.numpy()[self.ids_np]
            self._flags = (cull, wp.array(sub, dtype=wp.uint8, device=cull.device) if sub.any() else False)
        return self._flags[1]

    def raster(self, positions, camera, k, subsamples, cull, device, key, over=None):
        """This part's buffer for ``key`` (rasterised when the key changed; ``over``: drawn over
        that buffer)."""
        import raster

        flags = self.flags(cull)
        full = (key, flags if isinstance(flags, bool) else id(flags), None if over is None else id(over))
        if self.key != full:
            if self.vertex_ids is not None:
                n = int(self.vertex_ids.shape[0])
                wp.launch(gather_kernel, dim=n, inputs=[self.vertex_ids, positions, self.positions], device=device)
                positions = self.positions
            old, self.vb = self.vb, None
            self.vb = raster.rasterize(positions, self.tris, camera, device=device, supersample=k, validate=False,
                                       reuse=old, subsamples=subsamples, cull_backfaces=flags, over=over,
                                       tri_ids=self.ids)
            self.key = full
        return self.vb


class MovingRaster:
    """The two-part raster of one installed geometry (module docstring): ``static`` the triangles
    of the objects that never move, ``moving`` those of the dynamic ones (``dynamic`` per object)."""

    def __init__(self, geometry, dynamic: np.ndarray, device):
        T = np.asarray(geometry.triangles, np.int64).reshape(-1, 3)
        moving = np.asarray(dynamic, bool)[np.asarray(geometry.tri_object, np.int64)]
        self.device = device
        self.static = _Part(np.flatnonzero(~moving), T, device)
        self.moving = _Part(np.flatnonzero(moving), T, device, compact=True)
        self.tri_moving = moving
        #: rasterisations of each part (the static one: once per camera)
        self.counts = {"static": 0, "moving": 0}

    def rasterize(self, positions, camera, k: int, subsamples: int, cull, version: int):
        """The buffer of the whole mesh for ``camera`` (k× supersampled, ``subsamples`` a: as
        ``raster.rasterize``), with the moving objects at transform ``version``."""
        key = (repr(camera), int(k), int(subsamples))
        s_key, m_key = self.static.key, self.moving.key
        a = self.static.raster(positions, camera, k, subsamples, cull, self.device, key)
        b = self.moving.raster(positions, camera, k, subsamples, cull, self.device, (key, version), over=a)
        self.counts["static"] += self.static.key != s_key
        self.counts["moving"] += self.moving.key != m_key
        return b


__all__ = ["MovingRaster"]
