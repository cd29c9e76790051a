"""Back faces a raster may drop: those of the closed objects the camera sees from outside.

A closed, consistently wound, outward-facing mesh (every directed edge of the position-welded
mesh once and its reverse once, ``warp_sg.core.meshcheck.closed_parts``, and a positive volume:
trimesh's ``is_volume``) seen from outside never shows a back face: along every ray the first surface
it meets faces the eye. Its back faces only cost raster work — about half the (triangle, tile)
pairs of a torus, and half the queue the antialiasing's sub-pixel coverage walks. Three cases
where a back face can be seen keep every triangle of the object:

* an open surface (a floor, a leaf, a mesh with holes or T-junctions, where one sees its other
  side) or one wound inwards (negative volume): not a volume;
* the eye inside the object, or the near plane cutting it (one looks into it through the cut):
  the object's bounding box must lie entirely at view depth ≥ ``near`` — a conservative test per
  frame (an object partly behind the camera keeps its back faces).

The image is unchanged: the tests compare a culled and an unculled raster.
"""
from __future__ import annotations

import numpy as np


def box_corners(lo, hi) -> np.ndarray:
    """(8, 3): the corners of the axis-aligned box ``lo``–``hi`` (corner i takes bit 2, 1, 0 of i
    for x, y, z: 0 the low side, 1 the high one)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    bits = (np.arange(8)[:, None] >> np.array([2, 1, 0])) & 1
    return np.where(bits == 1, hi, lo)


class BackfaceCulling:
    """Per-object culling decisions for a flattened scene mesh (``warp_sg.scene.geometry.Geometry``):
    which objects are closed (once), and per camera which triangles may drop their back face
    (:meth:`flags`)."""

    def __init__(self, geometry, device: str = "cpu"):
        from warp_sg.core.meshcheck import closed_parts, part_volumes, weld_ids

        n_objects = len(geometry.object_names)
        self.device, self._cached = device, (None, False)
        self._used = {}  # object -> its vertex ids (moved)
        self.tri_object = np.asarray(geometry.tri_object, np.int64)
        V = np.asarray(geometry.vertices, np.float64)
        T = np.asarray(geometry.triangles, np.int64).reshape(-1, 3)
        counts = np.bincount(self.tri_object, minlength=n_objects)[:n_objects]
        self.corners = np.zeros((n_objects, 8, 3))
        has = np.flatnonzero(counts)
        if len(has):  # each object's box: of its triangles' corners, grouped by object
            order = np.argsort(self.tri_object, kind="stable")
            P = V[T[order]].reshape(-1, 3)
            start = 3 * np.concatenate([[0], np.cumsum(counts)[:-1]])[has]
            lo, hi = np.minimum.reduceat(P, start, axis=0), np.maximum.reduceat(P, start, axis=0)
            self.corners[has] = [box_corners(a, b) for a, b in zip(lo, hi)]  # (per object, not per vertex)
        # closed and consistently wound (the directed edges of the position-welded mesh), with a
        # positive volume (outward): trimesh's ``is_volume`` on merged vertices, every object at once
        volume = part_volumes(V, T, self.tri_object, n_objects, self.corners.mean(axis=1))
        self.closed = (counts >= 4) & (volume > 0.0) & closed_parts(T, weld_ids(V), self.tri_object, n_objects)

    def moved(self, geometry, objects=None) -> None:
        """Objects moved rigidly (``objects``: their indices, default all): new bounding boxes from
        the vertices of ``geometry``; closedness stays."""
        V, T = np.asarray(geometry.vertices, np.float64), np.asarray(geometry.triangles)
        for k in np.flatnonzero(self.closed):
            if objects is not None and k not in objects:
                continue
            if k not in self._used:
                self._used[k] = np.unique(T[self.tri_object == k])
            used = V[self._used[k]]
            self.corners[k] = box_corners(used.min(0), used.max(0))

    def place(self, k: int, corners: np.ndarray) -> None:
        """Object k lies inside the convex hull of ``corners`` (8, 3) — e.g. its rest-pose box
        carried by a rigid motion (``warp_sg.renderer.dynamic_objects``): the depth test of
        :meth:`objects` reads their nearest, a bound of the object's. (The flags depend only on
        which objects cull, compared in :meth:`flags`: nothing else to invalidate.)"""
        self.corners[k] = corners

    def objects(self, camera) -> np.ndarray:
        """(objects,) bool: closed and entirely at view depth ≥ the near plane of ``camera``."""
        f = np.asarray(camera.basis()[2], np.float64)
        depth = (self.corners - np.asarray(camera.origin, np.float64)) @ f  # (objects, 8)
        return self.closed & (depth.min(1) >= float(camera.near))

    def flags(self, camera):
        """``cull_backfaces`` for ``raster.rasterize``: False when no object may cull, else one
        uint8 flag per triangle, a ``wp.array`` on the device (rebuilt only when the set of culled
        objects changes)."""
        import warp as wp

        obj = self.objects(camera)
        key, flags = self._cached
        if key is None or not np.array_equal(obj, key):
            flags = wp.array(obj[self.tri_object].astype(np.uint8), dtype=wp.uint8, device=self.device) \
                if obj.any() else False
            self._cached = (obj, flags)
        return flags


__all__ = ["BackfaceCulling", "box_corners"]
