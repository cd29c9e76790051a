r"""Silhouette and boundary edges seen from a camera, marked on the pixel grid.

Antialiasing (:mod:`warp_sg.renderer.antialias`) needs sub-pixel coverage only where a pixel may hold an
occlusion boundary. Where one surface passes in front of another, the boundary lies on one of the
front mesh's **contour edges**:

* a *silhouette* edge, whose two triangles face opposite ways as seen from the eye
  (``sign((p1 − p0) × (p2 − p0) · (eye − p0))`` differs) — where an object passes in front of
  itself or of anything behind it;
* a *boundary* edge (one triangle: an open mesh's rim, e.g. a floor's border) or a non-manifold
  edge (three or more triangles), marked always.

Edges are found on the mesh welded by position (:func:`edge_adjacency`, once per geometry), so
seams where an exporter split vertices for normals or UVs are not boundaries. Per view,
:func:`mark_contours` projects the contour edges through the pinhole camera (clipped to the near
plane and to the image) and marks every pixel each one passes through, found row by row from the
segment's x-range in that row, grown by ``MARK_EPS`` (0.02 px): a conservative mask, also for
geometry thinner than a pixel that point sampling at pixel centres misses (a wire between two
pixel centres still has its contour edges marked). A pixel no contour edge crosses has all its
sub-pixels on one side of every occlusion boundary that lies on an edge. (Marking each pixel's 8
neighbours too, as first written, doubled the candidates on the frame-scaling scene, 3.9 k → 7.8 k
pixels, for the same image.)

With the 1× visibility buffer of the same camera (``inv_depth``), an edge is not marked at a pixel
where the surface seen at that pixel's and its 4 neighbours' centres lies in front of the edge's
nearest point (a contour behind a floor, the far side of a torus): one surface covers the pixel in
front of the edge, and its own boundaries are contours or object changes of their own. On the
frame-scaling scene this drops the torus's contour under the floor and its far rim.

Boundaries that lie on no edge: where two objects intersect, where one mesh passes through itself,
and where the near or far plane cuts the geometry. Antialiasing finds the first from the 1× buffer
(neighbouring pixels that see different objects), the others only where that test or its contrast
test flags them.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import math

import numpy as np
import warp as wp

from warp_sg.core.meshcheck import weld_ids


def edge_adjacency(vertices, triangles) -> tuple:
    """``(edge_v (E, 2) int32, edge_f (E, 2) int32)``: each edge of the position-welded mesh once,
    with an input vertex id for each end and its triangles: ``(f0, f1)`` for a manifold edge,
    ``(f0, -1)`` for a boundary or non-manifold edge (always a contour). Edges whose ends weld to
    one point are left out."""
    v = np.ascontiguousarray(np.asarray(vertices, np.float32))
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    if len(t) == 0:
        return np.zeros((0, 2), np.int32), np.zeros((0, 2), np.int32)
    weld = weld_ids(v)
    corners = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])   # input ids (3M, 2)
    faces = np.tile(np.arange(len(t)), 3)
    w = weld[corners]
    keep = w[:, 0] != w[:, 1]
    corners, faces, w = corners[keep], faces[keep], w[keep]
    lo, hi = np.minimum(w[:, 0], w[:, 1]), np.maximum(w[:, 0], w[:, 1])
    n = int(hi.max()) + 1 if len(hi) else 1
    # by (lo, hi), stably: np.lexsort((hi, lo)), as one int64 key where it fits (faster)
    order = np.argsort(lo * n + hi, kind="stable") if n < 3_000_000_000 else np.lexsort((hi, lo))
    lo, hi, corners, faces = lo[order], hi[order], corners[order], faces[order]
    start = np.flatnonzero(np.r_[True, (lo[1:] != lo[:-1]) | (hi[1:] != hi[:-1])])
    count = np.diff(np.r_[start, len(lo)])
    f1 = np.where(count == 2, faces[np.minimum(start + 1, len(faces) - 1)], -1)
    edge_f = np.stack([faces[start], f1], 1).astype(np.int32)
    return np.ascontiguousarray(corners[start], np.int32), edge_f


#: pixels a contour edge passes within this distance of are marked too (float32 projection here,
#: vertices snapped to 1/256 of a pixel by the raster)
MARK_EPS = wp.constant(0.02)
#: an edge is hidden at a pixel when the samples of the pixel and its 4 neighbours are all nearer
#: than its nearest point by more than this fraction of 1/depth (:func:`_hidden`)
OCCLUSION_MARGIN = wp.constant(1.0e-3)


@wp.struct
class ContourCamera:
    """The pinhole camera of :func:`mark_contours`: eye, unit right/up/forward, tan of the half
    field of view in x and y, the near distance and the grid size."""

    eye: wp.vec3
    right: wp.vec3
    up: wp.vec3
    fwd: wp.vec3
    tx: float
    ty: float
    near: float
    width: int
    height: int


@wp.func
def _facing(pos: wp.array(dtype=wp.vec3), tri: wp.vec3i, eye: wp.vec3) -> float:
    p0 = pos[tri[0]]
    return wp.dot(wp.cross(pos[tri[1]] - p0, pos[tri[2]] - p0), eye - p0)


@wp.func
def _to_pixel(cam: ContourCamera, p: wp.vec3) -> wp.vec2:
    """Continuous pixel coordinates (x right, y down; pixel centres at +½) of a point in front."""
    v = p - cam.eye
    z = wp.dot(v, cam.fwd)
    x = wp.dot(v, cam.right) / (z * cam.tx)
    y = wp.dot(v, cam.up) / (z * cam.ty)
    return wp.vec2((x + 1.0) * 0.5 * float(cam.width), (1.0 - y) * 0.5 * float(cam.height))


@wp.kernel(enable_backward=False)
def facing_kernel(base: int, pos: wp.array(dtype=wp.vec3), tris: wp.array(dtype=wp.vec3i), eye: wp.vec3,
                  faces: wp.array(dtype=int), side: wp.array(dtype=wp.int8)):
    """side[f] = +1 / −1 as triangle f faces the eye or away, 0 when degenerate (edge-on), for
    f = ``base + tid`` (``faces[base + tid]`` when ``faces`` is not empty)."""
    f = base + wp.tid()
    if faces.shape[0] > 0:
        f = faces[f]
    s = _facing(pos, tris[f], eye)
    v = wp.int8(0)
    if s > 0.0:
        v = wp.int8(1)
    elif s < 0.0:
        v = wp.int8(-1)
    side[f] = v


@wp.kernel(enable_backward=False)
def mark_contours_kernel(base: int, pos: wp.array(dtype=wp.vec3), side: wp.array(dtype=wp.int8),
                         edge_v: wp.array(dtype=wp.vec2i), edge_f: wp.array(dtype=wp.vec2i), cam: ContourCamera,
                         inv_depth: wp.array2d(dtype=float), occlusion: int, mark: wp.array2d(dtype=wp.uint8),
                         per_plane: int, nearest: wp.array3d(dtype=float)):
    """Mark the pixels that edge ``base + tid`` passes through (within ``MARK_EPS``) if it is a
    contour (``side``: :func:`facing_kernel`): ``occlusion`` 0 everywhere, 1 not where it is hidden
    (:func:`_hidden`), 2 instead of a mark the largest 1/depth of the nearest points of the
    contour edges that pass through the pixel, ``nearest[e / per_plane, r, c]`` (0: none; each
    range of ``per_plane`` edges owns one plane, so that CPU threads never write the same value)."""
    e = base + wp.tid()
    ef = edge_f[e]
    if ef[1] >= 0:
        s0 = side[ef[0]]
        if s0 == side[ef[1]] and s0 != wp.int8(0):
            return  # both triangles face the same way (a degenerate one counts as a contour)
    a = pos[edge_v[e][0]]
    b = pos[edge_v[e][1]]
    za = wp.dot(a - cam.eye, cam.fwd)
    zb = wp.dot(b - cam.eye, cam.fwd)
    if za < cam.near and zb < cam.near:
        return
    if za < cam.near:  # clip to the near plane
        a = a + (b - a) * ((cam.near - za) / (zb - za))
    elif zb < cam.near:
        b = b + (a - b) * ((cam.near - zb) / (za - zb))
    pa = _to_pixel(cam, a)
    pb = _to_pixel(cam, b)
    inv_near = 1.0 / wp.max(wp.min(wp.dot(a - cam.eye, cam.fwd), wp.dot(b - cam.eye, cam.fwd)), cam.near)
    # Liang–Barsky clip of the 2-D segment to the image grown by one pixel
    t0 = float(0.0)
    t1 = float(1.0)
    d = pb - pa
    lo = wp.vec2(-1.0, -1.0)
    hi = wp.vec2(float(cam.width) + 1.0, float(cam.height) + 1.0)
    for k in range(2):
        if d[k] == 0.0:
            if pa[k] < lo[k] or pa[k] > hi[k]:
                return
        else:
            u0 = (lo[k] - pa[k]) / d[k]
            u1 = (hi[k] - pa[k]) / d[k]
            t0 = wp.max(t0, wp.min(u0, u1))
            t1 = wp.min(t1, wp.max(u0, u1))
    if t0 > t1:
        return
    q0 = pa + d * t0
    q1 = pa + d * t1
    W = cam.width
    H = cam.height
    # conservative scan of the segment: in each pixel row it crosses, the columns of its x-range
    # within that row, grown by MARK_EPS (the raster snaps vertices to 1/256 of a sub-pixel)
    ya = wp.min(q0[1], q1[1])
    yb = wp.max(q0[1], q1[1])
    dy = q1[1] - q0[1]
    r0 = wp.max(int(wp.floor(ya - MARK_EPS)), 0)
    r1 = wp.min(int(wp.floor(yb + MARK_EPS)), H - 1)
    for r in range(r0, r1 + 1):
        u0 = float(0.0)
        u1 = float(1.0)
        if wp.abs(dy) > 1.0e-12:  # the segment's parameters inside rows [r − ε, r + 1 + ε]
            ua = (float(r) - MARK_EPS - q0[1]) / dy
            ub = (float(r) + 1.0 + MARK_EPS - q0[1]) / dy
            u0 = wp.max(0.0, wp.min(ua, ub))
            u1 = wp.min(1.0, wp.max(ua, ub))
        xa = q0[0] + (q1[0] - q0[0]) * u0
        xb = q0[0] + (q1[0] - q0[0]) * u1
        c0 = wp.max(int(wp.floor(wp.min(xa, xb) - MARK_EPS)), 0)
        c1 = wp.min(int(wp.floor(wp.max(xa, xb) + MARK_EPS)), W - 1)
        for c in range(c0, c1 + 1):
            if occlusion == 0:
                mark[r, c] = wp.uint8(1)
            elif occlusion == 2:
                wp.atomic_max(nearest, e / per_plane, r, c, inv_near)
            elif not _hidden(inv_depth, r, c, inv_near):
                mark[r, c] = wp.uint8(1)


@wp.func
def _hidden(inv_depth: wp.array2d(dtype=float), r: int, c: int, inv_edge: float) -> bool:
    """Whether the 1× samples of pixel (r, c) and of its 4 neighbours all see a surface nearer
    than the edge's nearest point (1/depth ``inv_edge``) by more than ``OCCLUSION_MARGIN``: one
    surface then covers the pixel in front of the edge (a boundary of that surface inside the
    pixel is a contour or an object change of its own, marked or flagged for itself)."""
    H = inv_depth.shape[0]
    W = inv_depth.shape[1]
    t = inv_edge * (1.0 + OCCLUSION_MARGIN)
    m = wp.min(inv_depth[r, c], inv_depth[wp.max(r - 1, 0), c])
    m = wp.min(m, wp.min(inv_depth[wp.min(r + 1, H - 1), c], inv_depth[r, wp.max(c - 1, 0)]))
    m = wp.min(m, inv_depth[r, wp.min(c + 1, W - 1)])
    return m > t


_CAMERAS: dict = {}  # repr(camera) -> ContourCamera, the last few


def contour_camera(camera) -> ContourCamera:
    """:class:`ContourCamera` of a ``warp_sg`` / ``raster`` camera (at its own resolution; the
    last few kept)."""
    key = repr(camera)
    if key not in _CAMERAS:
        if len(_CAMERAS) > 8:
            _CAMERAS.clear()
        _CAMERAS[key] = _contour_camera(camera)
    return _CAMERAS[key]


def _contour_camera(camera) -> ContourCamera:
    r, u, f = (np.asarray(x, np.float32) for x in camera.basis())
    c = ContourCamera()
    c.eye = wp.vec3(*np.asarray(camera.origin, np.float32))
    c.right, c.up, c.fwd = wp.vec3(*r), wp.vec3(*u), wp.vec3(*f)
    th = math.tan(math.radians(camera.fov) * 0.5)
    c.tx, c.ty = float(th * camera.width / camera.height), float(th)
    c.near = float(camera.near)
    c.width, c.height = int(camera.width), int(camera.height)
    return c


def _sides(positions: wp.array, tris: wp.array, cam: ContourCamera, device, faces=None) -> wp.array:
    """(T,) int8 of :func:`facing_kernel`: which way each triangle faces the eye (only those of
    ``faces``, a device int array, when given: the others are left undefined)."""
    from raster import parallel

    side = wp.empty(max(int(tris.shape[0]), 1), dtype=wp.int8, device=device)
    n = int(tris.shape[0]) if faces is None else int(faces.shape[0])
    ids = wp.zeros(0, dtype=int, device=device) if faces is None else faces
    parallel.launch(facing_kernel, n, [positions, tris, cam.eye, ids, side], device, min_chunk=4096,
                    chunks=parallel.cpu_workers())  # (uniform work: a range per thread)
    return side


def mark_contours(positions: wp.array, tris: wp.array, edge_v: wp.array, edge_f: wp.array, camera,
                  device, inv_depth: wp.array | None = None, into: wp.array | None = None, faces=None) -> wp.array:
    """(H, W) uint8: 1 on the pixels the mesh's contour edges pass through (see the module
    docstring); ``edge_v``, ``edge_f`` of :func:`edge_adjacency` as ``vec2i`` arrays.
    ``inv_depth``: the camera's 1× visibility buffer's 1/depth (``VisibilityBuffer.inv_depth``, 0
    where empty): then not where a nearer surface hides the edge (:func:`_hidden`). ``into``: marks
    to add these to (in place) instead of an empty mask. ``faces``: the triangles of these edges
    (a device int array; only their sides are computed)."""
    from raster import parallel

    mark = wp.zeros((int(camera.height), int(camera.width)), dtype=wp.uint8, device=device) if into is None else into
    cam = contour_camera(camera)
    side = _sides(positions, tris, cam, device, faces)
    occ = inv_depth if inv_depth is not None else wp.zeros((1, 1), dtype=float, device=device)
    parallel.launch(mark_contours_kernel, int(edge_v.shape[0]),
                    [positions, side, edge_v, edge_f, cam, occ, int(inv_depth is not None), mark, 1,
                     wp.zeros((1, 1, 1), dtype=float, device=device)], device, min_chunk=4096,
                    chunks=2 * parallel.cpu_workers())
    return mark


def contour_depths(positions: wp.array, tris: wp.array, edge_v: wp.array, edge_f: wp.array, camera,
                   device) -> wp.array:
    """(H, W) float: per pixel the largest 1/depth of the nearest points of the contour edges that
    pass through it (those :func:`mark_contours` marks without ``inv_depth``), 0 where none does.
    :func:`decide_contours` turns it into the marks of any 1× buffer of the camera: whether an edge
    is hidden at a pixel (:func:`_hidden`) is monotone in that 1/depth, so one value per pixel
    decides for all the edges through it."""
    from raster import parallel

    H, W = int(camera.height), int(camera.width)
    n = int(edge_v.shape[0])
    cpu = str(device).startswith("cpu")
    planes = max(1, min(parallel.cpu_workers(), n)) if cpu else 1
    per = max(-(-n // planes), 1)
    nearest = wp.zeros((planes, H, W), dtype=float, device=device)
    cam = contour_camera(camera)
    side = _sides(positions, tris, cam, device)
    args = [positions, side, edge_v, edge_f, cam, wp.zeros((1, 1), dtype=float, device=device), 2,
            wp.zeros((1, 1), dtype=wp.uint8, device=device), per, nearest]
    parallel.launch_rows(mark_contours_kernel, n, planes, args, device)
    if planes == 1:
        return nearest.reshape((H, W))
    out = wp.empty((H, W), dtype=float, device=device)
    parallel.launch(_plane_max_kernel, H * W, [nearest, W, out], device, min_chunk=16384)
    return out


@wp.kernel(enable_backward=False)
def _plane_max_kernel(base: int, planes: wp.array3d(dtype=float), width: int, out: wp.array2d(dtype=float)):
    i = base + wp.tid()
    r = i / width
    c = i - r * width
    m = planes[0, r, c]
    for p in range(1, planes.shape[0]):
        m = wp.max(m, planes[p, r, c])
    out[r, c] = m


@wp.kernel(enable_backward=False)
def decide_contours_kernel(base: int, x0: int, y0: int, width: int, nearest: wp.array2d(dtype=float),
                           inv_depth: wp.array2d(dtype=float), mark: wp.array2d(dtype=wp.uint8)):
    """Pixel ``base + tid`` of the ``width``-wide rectangle at (x0, y0): ``mark`` = 1 where an edge
    of ``nearest`` (:func:`contour_depths`) is not hidden by ``inv_depth``, else 0."""
    i = base + wp.tid()
    r = y0 + i / width
    c = x0 + i - (i / width) * width
    z = nearest[r, c]
    m = wp.uint8(0)
    if z > 0.0:
        if not _hidden(inv_depth, r, c, z):
            m = wp.uint8(1)
    mark[r, c] = m


def decide_contours(mark: wp.array, nearest: wp.array, inv_depth: wp.array, device, region=None) -> wp.array:
    """``mark`` (in place) = the marks of the edges behind ``nearest`` (:func:`contour_depths`)
    that ``inv_depth`` (a 1× buffer's) does not hide — :func:`mark_contours` of those edges, bit
    for bit — over ``region`` ``(x0, y0, x1, y1)`` (pixels x0 ≤ x < x1, y0 ≤ y < y1; default the
    whole grid); the rest of ``mark`` is left as it is."""
    from raster import parallel

    H, W = int(mark.shape[0]), int(mark.shape[1])
    x0, y0, x1, y1 = (0, 0, W, H) if region is None else region
    if x1 > x0 and y1 > y0:
        parallel.launch(decide_contours_kernel, (x1 - x0) * (y1 - y0), [x0, y0, x1 - x0, nearest, inv_depth, mark],
                        device, min_chunk=16384)
    return mark


__all__ = ["ContourCamera", "contour_camera", "contour_depths", "edge_adjacency", "facing_kernel", "mark_contours",
           "mark_contours_kernel", "decide_contours"]
