"""Back faces a raster drops: those of single-sided objects, and of the closed objects the camera sees from outside.

**Single-sided objects** (``SceneObject.double_sided`` False: a glTF material with ``doubleSided``
false, the glTF default; glTF 2.0 §3.9.5 "Double Sided": "back-face culling is enabled") never show
a back face to camera rays, whatever their closedness, their distance or the near plane: a face is a
back face when its winding is clockwise as seen from the eye, i.e. ``(eye − v0) · ((v1 − v0) ×
(v2 − v0)) ≤ 0`` — for a pinhole camera a property of the triangle, not of the pixel. An asset
that stores a surface twice as two coincident shells facing opposite ways (the shared Ferrari's
body) thus shows its outward shell only, in the raster (:meth:`BackfaceCulling.flags`) and in the
Monte-Carlo reference (:func:`camera_mesh`: its camera rays query a mesh without those faces).
Shadow rays and the precompute see both sides.

**Closed objects** are culled as an optimisation only:

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

The image of a closed object is unchanged: the tests compare a culled and an unculled raster.
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
        one = getattr(geometry, "one_sided", None)
        self.one_sided = np.zeros(n_objects, bool) if one is None else np.asarray(one, bool)[:n_objects]

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
        """(objects,) bool: single-sided, or closed and entirely at view depth ≥ the near plane of ``camera``."""
        f = np.asarray(camera.basis()[2], np.float64)
        depth = (self.corners - np.asarray(camera.origin, np.float64)) @ f  # (objects, 8)
        return self.one_sided | (self.closed & (depth.min(1) >= float(camera.near)))

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


def facing_away(vertices, triangles, eye) -> np.ndarray:
    """(T,) bool: the triangles whose back the point ``eye`` sees, ``(eye − v0) · ((v1 − v0) × (v2 −
    v0)) ≤ 0`` (edge-on ones included: they cover no pixel), in float64."""
    V = np.asarray(vertices, np.float64)
    T = np.asarray(triangles, np.int64).reshape(-1, 3)
    v0 = V[T[:, 0]]
    n = np.cross(V[T[:, 1]] - v0, V[T[:, 2]] - v0)
    return np.einsum("ij,ij->i", np.asarray(eye, np.float64) - v0, n) <= 0.0


def camera_mesh(single_sided, ray_origins, vertices, triangles, points, device: str):
    """The ``wp.Mesh`` a Monte-Carlo reference's camera rays query: the triangles flagged in
    ``single_sided`` (T,) that the eye (every ray's origin: a pinhole camera) sees from behind
    (:func:`facing_away`) collapsed to a point, so that they are never hit while the face indices
    stay those of the full mesh (``points``: its device vertex array); None when none is culled."""
    import warp as wp

    from warp_sg.core.errors import InputError

    if single_sided is None or not np.any(single_sided):
        return None
    eyes = np.asarray(ray_origins, np.float64).reshape(-1, 3)
    if len(eyes) and np.ptp(eyes, axis=0).max() > 0.0:
        raise InputError("single-sided triangles need camera rays from one eye (a pinhole camera)",
                         where="reference inputs")
    tri = np.asarray(triangles, np.int32).reshape(-1, 3)
    single = np.asarray(single_sided, bool).reshape(-1)
    if len(single) != len(tri):
        raise InputError(f"single_sided has {len(single)} flags for {len(tri)} triangles", where="reference inputs")
    culled = single & facing_away(vertices, tri, eyes[0] if len(eyes) else np.zeros(3))
    if not culled.any():
        return None
    cam = tri.copy()
    cam[culled] = tri[culled, :1]  # (i0, i0, i0): no area, never hit
    return wp.Mesh(points=points, indices=wp.array(np.ascontiguousarray(cam.reshape(-1)), dtype=int, device=device))


__all__ = ["BackfaceCulling", "box_corners", "facing_away", "camera_mesh"]
