r"""Gather rows at the current pose: the rows of the vertices whose light a moved object changes,
cast again against the whole scene where it stands now (light that bounces with objects that move).

The precomputed rows (:mod:`precompute.visibility.gather`) are per group — the static objects
together, each dynamic object alone — and hold under a group's rigid motions, but leave out the
light between groups. After a move (and at the first frame) the renderer recasts the rows of

* every vertex of a dynamic object (it sees the rest of the scene, and the rest sees it), and
* every other vertex whose hemisphere can see a dynamic object: its current bounding sphere
  ``(c, ρ)`` not wholly below the vertex's tangent plane, ``n·(c − p) > −ρ`` (a cheap cull:
  a vertex facing away from every moving object keeps its precomputed row),

with the gather's own ray casting and compression (:func:`precompute.visibility.gather.gather_rays_kernel`,
the same ``N`` cosine rays per vertex and seeds, :func:`precompute.visibility.gather.compress_rows`)
against one ``wp.Mesh`` of every triangle at the current positions (refitted before each cast).
A recast row replaces the vertex's precomputed row (:func:`replace_rows`)::

    T'[x, ·] = Σ_{r → face f ∋ s, first hit in the posed scene} b_s(y_r)/N      (x recast)
    T'[x, ·] = T[x, ·]                                                            (otherwise)

so the light between a moving object and the rest is there, with the occlusion the move brings
(a floor vertex under the ball sees the ball, not the sky behind it), and nothing of an earlier
pose survives: the rows are a function of the current transforms (an object moved away and back
gets its first rows bit for bit).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from precompute.visibility.gather import compress_rows, gather_rays_kernel
from precompute.visibility.rays import OFFSET_SCALE, bbox_diagonal, run_batches
from warp_sg.shading.cutout import no_cutouts


@wp.func
def hemisphere_sees_sphere(p: wp.vec3, n: wp.vec3, sphere: wp.vec4) -> bool:
    """Whether the hemisphere of normal ``n`` at ``p`` can see part of the sphere ``(c, ρ)``: the
    sphere not wholly below the tangent plane, ``n·(c − p) > −ρ`` (``ρ < 0``: no bound known, true)."""
    if sphere[3] < 0.0:
        return True
    return wp.dot(n, wp.vec3(sphere[0], sphere[1], sphere[2]) - p) > -sphere[3]


@wp.kernel(enable_backward=False)
def pose_receivers_kernel(points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3),
                          vertex_object: wp.array(dtype=int), dynamic: wp.array(dtype=int),
                          bounds: wp.array(dtype=wp.vec4), out: wp.array(dtype=int)):
    """``out[v]`` = 1 when vertex ``v``'s row is recast at the current pose (module docstring): it
    belongs to a dynamic object, or its hemisphere sees a dynamic object's bounding sphere."""
    v = wp.tid()
    o = vertex_object[v]
    hit = int(0)
    if o >= 0:
        if dynamic[o] != 0:
            hit = 1
    n = wp.normalize(normals[v])
    for k in range(bounds.shape[0]):
        if hit == 0 and dynamic[k] != 0 and k != o:
            if hemisphere_sees_sphere(points[v], n, bounds[k]):
                hit = 1
    out[v] = hit


def replace_rows(offsets: np.ndarray, columns: list, ids: np.ndarray, counts: np.ndarray, new: list):
    """CSR rows with the rows of vertices ``ids`` (sorted, unique) replaced: ``offsets`` (V + 1),
    ``columns`` the per-reference arrays (senders, weights, directions …) in row order; ``counts``
    and ``new`` the replacing rows' reference counts and arrays (in the order of ``ids``). Returns
    ``(offsets, columns)`` — each reference written once to its place (no sort)."""
    off = np.asarray(offsets, np.int64)
    V = len(off) - 1
    ids = np.asarray(ids, np.int64)
    counts = np.asarray(counts, np.int64)
    base = np.diff(off)
    recast = np.zeros(V, bool)
    recast[ids] = True
    cnt = np.where(recast, 0, base)
    cnt[ids] = counts
    out_off = np.zeros(V + 1, np.int64)
    np.cumsum(cnt, out=out_off[1:])
    row_b = np.repeat(np.arange(V), base)
    keep = ~recast[row_b]
    j = np.flatnonzero(keep)
    at_b = out_off[row_b[j]] + (j - off[row_b[j]])
    row_n = np.repeat(ids, counts)
    first = np.repeat(np.cumsum(counts) - counts, counts)
    at_n = out_off[row_n] + (np.arange(len(row_n)) - first)
    cols = []
    for a, b in zip(columns, new):
        c = np.empty((int(out_off[-1]),) + a.shape[1:], np.result_type(a.dtype, np.asarray(b).dtype))
        c[at_b] = a[j]
        c[at_n] = b
        cols.append(c)
    return out_off.astype(np.int32), cols


def posed_rows(data, rest_dirs: np.ndarray, turns=(), rows=None):
    """``(offsets int32, senders int32, weights float32, directions (R, 3) float32)``: the rows of
    ``data`` (:class:`precompute.visibility.gather.GatherData`; ``rest_dirs`` its decoded
    directions) with the references of each ``(vertex ids, R)`` of ``turns`` pointing along their
    rest direction turned by ``R`` (a group's rows under its rigid motion), then the rows of
    ``rows = (ids, counts, senders, weights, directions)`` (:meth:`PoseGather.rows`) in place of
    those vertices' own (:func:`replace_rows`)."""
    off = np.asarray(data.offsets, np.int64)
    d = np.array(rest_dirs, np.float32)
    for ids, R in turns:
        ids = np.asarray(ids, np.int64)
        start, cnt = off[ids], off[ids + 1] - off[ids]
        refs = np.repeat(start - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt) + np.arange(int(cnt.sum()))
        d[refs] = rest_dirs[refs] @ np.asarray(R, np.float32).T
    cols = [np.asarray(data.senders, np.int32), np.asarray(data.weights, np.float32), d]
    if rows is None:
        return (off.astype(np.int32), *cols)
    ids, counts, *new = rows
    o, cols = replace_rows(off, cols, ids, counts, new)
    return (o, *cols)


class PoseGather:
    """The rows of a mesh whose vertices move, cast at their current positions (module docstring).
    ``points``, ``normals``: the renderer's (V,) vec3 device arrays, moved in place by each move;
    ``triangles`` (F, 3); ``rest_vertices``: the pose the precompute saw (its ray offset and
    length, as :class:`precompute.visibility.rays._MeshContext` sets them)."""

    def __init__(self, points: wp.array, normals: wp.array, triangles, rest_vertices, device):
        self.device = device
        self.points, self.normals = points, normals
        self.indices = wp.array(np.asarray(triangles, np.int32).ravel(), dtype=wp.int32, device=device)
        self.mesh = wp.Mesh(points=points, indices=self.indices)
        diag = max(bbox_diagonal(rest_vertices), 1e-12)
        self.offset, self.max_t = OFFSET_SCALE * diag, 1e3 * diag
        self.cut = no_cutouts(device)

    def receivers(self, vertex_object, dynamic, bounds) -> np.ndarray:
        """The sorted vertex ids whose rows are recast (:func:`pose_receivers_kernel`; ``bounds``:
        (objects,) vec4 device array of the objects' current bounding spheres, ``dynamic`` flags)."""
        d = self.device
        nv = int(self.points.shape[0])
        out = wp.zeros(nv, dtype=int, device=d)
        wp.launch(pose_receivers_kernel, dim=nv, device=d,
                  inputs=[self.points, self.normals, wp.array(np.asarray(vertex_object, np.int32), dtype=int, device=d),
                          wp.array(np.asarray(dynamic, np.int32), dtype=int, device=d), bounds, out])
        return np.flatnonzero(out.numpy())

    def rows(self, ids: np.ndarray, rays: int, refs: int, batch: int = 512):
        """``(counts, senders, weights, directions)`` of the rows of vertices ``ids`` at the current
        positions (:func:`gather_rays_kernel` + :func:`compress_rows` against every triangle)."""
        d = self.device
        n_side = int(round(np.sqrt(int(rays))))
        N = n_side * n_side
        self.mesh.refit()  # (the points moved in place)
        ids_w = wp.array(np.asarray(ids, np.int32), dtype=int, device=d)

        def work(s, e):
            B = e - s
            snd = wp.empty((B, N, 3), dtype=int, device=d)
            wgt = wp.empty((B, N, 3), dtype=float, device=d)
            dirs = wp.empty((B, N), dtype=wp.vec3, device=d)
            wp.launch(gather_rays_kernel, dim=(B, N), device=d,
                      inputs=[self.mesh.id, self.cut, self.indices, self.points, self.normals, ids_w, s, n_side,
                              self.offset, self.max_t, snd, wgt, dirs])
            return compress_rows(snd.numpy(), wgt.numpy(), dirs.numpy(), int(refs))

        parts = run_batches(len(ids), batch, work, d) if len(ids) else []
        if not parts:
            return np.zeros(0, np.int64), np.zeros(0, np.int32), np.zeros(0, np.float32), np.zeros((0, 3), np.float32)
        return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
                np.concatenate([p[2] for p in parts]).astype(np.float32),
                np.concatenate([p[3] for p in parts]).astype(np.float32))


__all__ = ["PoseGather", "hemisphere_sees_sphere", "pose_receivers_kernel", "posed_rows", "replace_rows"]
