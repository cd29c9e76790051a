r"""What adaptive antialiasing (:mod:`warp_sg.renderer.antialias`) keeps between frames of one
renderer: the mesh's edge adjacency (once), the contour marks of the current camera
(:mod:`warp_sg.shading.silhouette`), and the sub-pixel coverage of the last frame's candidate
pixels (a re-shade whose candidates did not change reuses it).

With dynamic objects (:mod:`warp_sg.renderer.moving_raster`) the contours come in two parts. The
static objects' edges are marked once per camera, as per-pixel depths
(:func:`~warp_sg.shading.silhouette.contour_depths`: the largest 1/depth of the edges through
each pixel), and turned into marks against the static objects' own buffer. A frame then starts
from those marks, decides them again only near the pixels the moving objects cover (there the
frame's buffer differs from the static one; whether an edge is hidden at a pixel reads it and its
4 neighbours, :func:`~warp_sg.shading.silhouette.decide_contours`), and adds the moving objects'
edges marked against the frame's buffer: the marks of all edges against the frame's buffer, bit
for bit, at the cost of the moving part.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import numpy as np
import warp as wp


class AntialiasCache:
    """What antialiasing keeps between frames of one renderer: the mesh's edge adjacency (once),
    the contour mask of the current camera, and the sub-pixel coverage of the last frame's
    candidate pixels — a re-shade (a material, light or environment edit: the same visibility
    buffer) whose candidates did not change reuses it.

    ``moving`` (per triangle, a scene with dynamic objects): the contours in two parts, the static
    edges' once per camera (module docstring). ``adjacency``: ``edge_adjacency(positions, tris)``
    where it was computed already (the renderer's first-frame caches)."""

    def __init__(self, positions: wp.array, tris: wp.array, device, moving=None, adjacency=None):
        self.positions, self.tris, self.device = positions, tris, device
        self._adjacency = adjacency  # edge_adjacency(positions, tris), when computed already
        self.moving = None if moving is None else np.asarray(moving, bool)
        self.edges = None
        self._contours = (None, None, None)  # (camera, 1× buffer, marks)
        self._static = (None, None, None, None)  # (camera, static buffer, static edges' depths, their marks)
        self._joined = None  # (_all_edges)
        self._moving_faces = None  # the triangles of the moving edges (_edges)
        self._kept = None  # the static objects' sub-samples by pixel (raster.subsample.KeptSubsamples)
        self._sub = (None, None, None)  # (visibility buffer, candidate list (numpy), coverage)

    def _edges(self):
        from warp_sg.shading.silhouette import edge_adjacency

        if self.edges is None:
            ev, ef = self._adjacency or edge_adjacency(self.positions.numpy(), self.tris.numpy())
            self._adjacency = None
            arrays = lambda sel: (wp.array(ev[sel], dtype=wp.vec2i, device=self.device),  # noqa: E731
                                  wp.array(ef[sel], dtype=wp.vec2i, device=self.device))
            if self.moving is None:
                self.edges = arrays(slice(None))
            else:  # an edge of a moving triangle moves (both faces' sides decide a silhouette)
                mov = self.moving[ef[:, 0]] | ((ef[:, 1] >= 0) & self.moving[np.maximum(ef[:, 1], 0)])
                faces = np.unique(ef[mov])
                self.edges = (arrays(~mov), arrays(mov))
                self._moving_faces = wp.array(faces[faces >= 0].astype(np.int32), dtype=int, device=self.device)
        return self.edges

    def contours(self, camera, vb1) -> wp.array:
        """The contour marks of ``camera``, without the edges its 1× buffer ``vb1`` shows hidden
        (with moving objects ``vb1`` is drawn over the static objects' buffer, ``vb1._over``:
        module docstring)."""
        from warp_sg.shading.silhouette import contour_depths, decide_contours, mark_contours

        edges = self._edges()
        key = repr(camera)
        if self._contours[0] == key and self._contours[1] is vb1:
            return self._contours[2]
        if self.moving is None or vb1._over is None:
            mark = mark_contours(self.positions, self.tris, *self._all_edges(), camera, self.device,
                                 inv_depth=vb1.inv_depth)
        else:
            static = vb1._over
            if self._static[0] != key or self._static[1] is not static:
                nearest = contour_depths(self.positions, self.tris, *edges[0], camera, self.device)
                marks = decide_contours(wp.empty(nearest.shape, dtype=wp.uint8, device=self.device), nearest,
                                        static.inv_depth, self.device)
                self._static = (key, static, nearest, marks)
            _, _, nearest, marks = self._static
            mark = wp.clone(marks)
            box = vb1.queue_bounds()  # where the moving objects may cover pixels, and 1 pixel around
            if box is not None:
                x0, y0, x1, y1 = box
                decide_contours(mark, nearest, vb1.inv_depth, self.device,
                                (max(x0 - 1, 0), max(y0 - 1, 0), min(x1 + 1, vb1.width), min(y1 + 1, vb1.height)))
            mark_contours(self.positions, self.tris, *edges[1], camera, self.device, inv_depth=vb1.inv_depth, into=mark,
                          faces=self._moving_faces)
        self._contours = (key, vb1, mark)
        return mark

    def _all_edges(self):
        """Every edge of the mesh (:meth:`_edges`' two parts joined when split)."""
        edges = self._edges()
        if self.moving is None:
            return edges
        if self._joined is None:
            self._joined = tuple(wp.array(np.concatenate([a.numpy(), b.numpy()]), dtype=wp.vec2i, device=self.device)
                                 for a, b in zip(edges[0], edges[1]))
        return self._joined

    def forget_frame(self) -> None:
        """Drop the last frame's contours and coverage (the geometry moved; the edges stay)."""
        self._contours, self._sub = (None, None, None), (None, None, None)

    def subsamples(self, vb, idx: wp.array):
        """``raster.subsample.subsample(vb, idx)``, reused when ``vb`` and the list are the last
        frame's (compared where they are: :func:`same_list`)."""
        from raster.subsample import subsample

        old_vb, old_idx, sub = self._sub
        if old_vb is vb and old_idx is not None and same_list(old_idx, idx):
            return sub
        if vb._over is not None and vb._over._over is None:  # moving objects over the static ones: those kept
            from raster.subsample import KeptSubsamples

            if self._kept is None or self._kept.vb is not vb._over:
                self._kept = KeptSubsamples(vb._over)
            sub = subsample(vb, idx, kept=self._kept)
        else:
            sub = subsample(vb, idx)
        self._sub = (vb, idx, sub)
        return sub


@wp.kernel(enable_backward=False)
def _differs_kernel(a: wp.array(dtype=int), b: wp.array(dtype=int), out: wp.array(dtype=int)):
    i = wp.tid()
    if a[i] != b[i]:
        out[0] = 1  # (every writer writes the same value)


def same_list(a: wp.array, b: wp.array) -> bool:
    """Whether two int arrays on one device hold the same values: numpy views on the CPU, a
    comparison on the device elsewhere (one integer comes back, not the lists)."""
    if a.shape != b.shape:
        return False
    if str(a.device).startswith("cpu"):
        return bool(np.array_equal(a.numpy(), b.numpy()))
    out = wp.zeros(1, dtype=int, device=a.device)
    wp.launch(_differs_kernel, dim=a.shape[0], inputs=[a, b, out], device=a.device)
    return int(out.numpy()[0]) == 0




__all__ = ["AntialiasCache", "same_list"]
