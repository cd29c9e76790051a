"""Stage 1 — vertex transform and triangle setup (Laine & Karras 2011, "triangle setup").

* ``vertex_kernel`` (one thread per vertex): world → homogeneous clip space with the camera's
  view-projection matrix in float64 (huge coordinates keep their precision; ``w`` = distance along
  the view axis), the frustum outcode, and — when the vertex needs no clipping — its position
  **snapped to fixed point** (1/256 px), computed once and shared bit-identically by every triangle
  using the vertex.
* ``setup_kernel`` (one thread per input triangle, writes slot i):

  1. trivial reject when all three vertices lie outside one frustum plane (outcodes AND);
  2. fast path (no vertex behind the near plane or outside the guard band): the three snapped
     vertices; otherwise **clipping in homogeneous space** (Sutherland–Hodgman) against the near
     plane ``w = near`` and, only when needed, a guard band ``|x| ≤ g·w``, ``|y| ≤ g·w`` keeping pixel
     coordinates within ±32000 px (so int64 edge functions never overflow). The polygon (≤ 8
     vertices) is fanned into sub-triangles (two for a plain near-plane crossing). Intersections are
     computed from the inside towards the outside vertex, so an edge shared by two triangles clips
     to bit-identical points (watertight). Nothing behind the near plane survives: never inverted;
  3. int64 signed area of the snapped triangle: zero → dropped (degenerate), back-facing →
     dropped when culling; the winding is normalised so edge functions are positive inside;
  4. the bounding box of the covered pixel centres (empty → dropped, so sub-pixel triangles that
     miss every centre cost nothing more);
  5. **interpolation planes** of the *original* triangle in 2D homogeneous form (Olano & Greer
     1997): with ``M = [X·w; Y·w; w]`` (pixel-space homogeneous vertices, float64), the rows of
     ``M⁻¹`` are linear in the pixel position and give ``λ_i = b_i / w``; ``Σλ = 1/w`` is the depth
     plane and ``b_i = λ_i / Σλ`` the perspective-correct barycentrics. Stored (float32) about the
     piece's first vertex in its 64-byte :class:`SubTri` record; being planes of the original
     triangle, clipped pieces report the original ``tri_id`` and barycentrics for free;
  6. the bin raster, fused: the tiles the piece touches are counted (``fixed.count_tiles``) in
     the counter row of the pool thread that owns the triangle (see ``bin.py``).

  The first piece goes to slot i (``tri = -1`` when nothing survives); ``extra[i]`` counts further
  pieces, which ``setup_extra_kernel`` writes after a prefix sum into slots ``M + offset``.

Edge function of the directed edge a→b at sample p (fixed point): ``E = (b−a) × (p−a)``; a sample
is inside when ``E > 0`` for all edges, or ``E = 0`` on a *top-left* edge (top-left fill rule: a
sample on an edge shared by two triangles is covered exactly once).
"""
from __future__ import annotations

import warp as wp

from raster.fixed import (  # noqa: F401
    HALF,
    SUBPIXEL,
    SUBPIXEL_BITS,
    count_tiles,
    edge_eval,
    edge_topleft,
    eval_plane,
    lower_px,
    pixel_bbox,
    sample_bbox,
    sample_fixed,
    upper_px,
)

wp.set_module_options({"enable_backward": False})

GUARD_PIXELS = 32000.0  # |X|, |Y| of snapped vertices stay below this (fixed point < 2^23)
MAX_RESOLUTION = 16384  # per axis, after supersampling

vec8 = wp.types.vector(length=8, dtype=wp.float64)


@wp.struct
class SubTri:
    """One rasterizable (sub-)triangle: exactly 64 bytes, one cache line per fine-raster visit."""

    v0: wp.vec2i  # snapped fixed-point vertices, positive-area winding (y down)
    v1: wp.vec2i
    v2: wp.vec2i
    tri: wp.int32  # original triangle id; -1 marks an empty slot
    p: wp.mat33  # interpolation planes of the original triangle (rows 1/w, λ1, λ2) about v0


@wp.func
def plane_dist(x: wp.float64, y: wp.float64, w: wp.float64, plane: int, near: wp.float64, gx: wp.float64,
               gy: wp.float64):
    """Signed distance (≥ 0 inside) to clip plane 0 = near, 1..4 = guard band ±x, ±y."""
    d = w - near
    if plane == 1:
        d = gx * w - x
    elif plane == 2:
        d = gx * w + x
    elif plane == 3:
        d = gy * w - y
    elif plane == 4:
        d = gy * w + y
    return d


@wp.func
def clip_polygon(px: vec8, py: vec8, pw: vec8, n: int, plane: int, near: wp.float64, gx: wp.float64,
                 gy: wp.float64):
    """One Sutherland–Hodgman step; returns the clipped polygon (≤ n + 1 vertices)."""
    ox = vec8()
    oy = vec8()
    ow = vec8()
    m = int(0)
    for k in range(n):
        k2 = (k + 1) % n
        ax = px[k]
        ay = py[k]
        aw = pw[k]
        bx = px[k2]
        by = py[k2]
        bw = pw[k2]
        da = plane_dist(ax, ay, aw, plane, near, gx, gy)
        db = plane_dist(bx, by, bw, plane, near, gx, gy)
        zero = wp.float64(0.0)
        if da >= zero:
            if m < 8:
                ox[m] = ax
                oy[m] = ay
                ow[m] = aw
                m += 1
        if (da >= zero) != (db >= zero):
            # canonical: interpolate from the inside vertex towards the outside one
            ix = ax
            iy = ay
            iw = aw
            di = da
            ux = bx
            uy = by
            uw = bw
            du = db
            if da < zero:
                ix = bx
                iy = by
                iw = bw
                di = db
                ux = ax
                uy = ay
                uw = aw
                du = da
            t = di / (di - du)
            if m < 8:
                ox[m] = ix + t * (ux - ix)
                oy[m] = iy + t * (uy - iy)
                ow[m] = iw + t * (uw - iw)
                if plane == 0:
                    ow[m] = near  # exactly on the near plane
                m += 1
    return ox, oy, ow, m


@wp.func
def snap(x: wp.float64, w: wp.float64, size: float, flip: int):
    """Clip coordinate → fixed-point pixel coordinate (1/SUBPIXEL px)."""
    ndc = x / w
    if flip == 1:
        ndc = -ndc
    p = (ndc + wp.float64(1.0)) * wp.float64(0.5) * wp.float64(size)
    p = wp.clamp(p, wp.float64(-GUARD_PIXELS), wp.float64(GUARD_PIXELS))
    return wp.int32(wp.round(p * wp.float64(SUBPIXEL)))


# outcode bits of a clip-space vertex
OUT_XP = wp.constant(1)  # x > w
OUT_XN = wp.constant(2)  # x < -w
OUT_YP = wp.constant(4)  # y > w
OUT_YN = wp.constant(8)  # y < -w
OUT_NEAR = wp.constant(16)  # w < near
OUT_FAR = wp.constant(32)  # w > far
OUT_GUARD = wp.constant(64)  # outside the guard band
REJECT_MASK = wp.constant(63)
CLIP_MASK = wp.constant(16 + 64)


@wp.kernel
def vertex_kernel(
    base: int,
    verts: wp.array(dtype=wp.vec3),
    mvp: wp.mat44d,
    width: int,
    height: int,
    near: wp.float64,
    far: wp.float64,
    gx: wp.float64,
    gy: wp.float64,
    clip: wp.array(dtype=wp.vec4d),
    vsnap: wp.array(dtype=wp.vec2i),
    vcode: wp.array(dtype=wp.int32),
):
    """Per vertex: clip position (float64, so huge coordinates keep their precision), frustum
    outcode, and — when the vertex needs no clipping — its snapped fixed-point pixel position,
    shared by every triangle using the vertex (computed once, bit-identical for all of them)."""
    i = base + wp.tid()
    if i >= verts.shape[0]:
        return
    v = verts[i]
    c = mvp * wp.vec4d(wp.float64(v[0]), wp.float64(v[1]), wp.float64(v[2]), wp.float64(1.0))
    clip[i] = c
    x = c[0]
    y = c[1]
    w = c[3]
    code = int(0)
    if x > w:
        code = code | OUT_XP
    if x < -w:
        code = code | OUT_XN
    if y > w:
        code = code | OUT_YP
    if y < -w:
        code = code | OUT_YN
    if w < near:
        code = code | OUT_NEAR
    if w > far:
        code = code | OUT_FAR
    if wp.abs(x) > gx * w or wp.abs(y) > gy * w:
        code = code | OUT_GUARD
    vcode[i] = code
    if (code & CLIP_MASK) == 0:
        vsnap[i] = wp.vec2i(snap(x, w, float(width), 0), snap(y, w, float(height), 1))
    else:
        vsnap[i] = wp.vec2i(0, 0)


@wp.func
def covers(v0: wp.vec2i, v1: wp.vec2i, v2: wp.vec2i, x: int, y: int):
    """Top-left-rule coverage of the centre of pixel (x, y) (positive-area winding)."""
    sx = sample_fixed(x)
    sy = sample_fixed(y)
    z = wp.int64(0)
    return (edge_eval(v0, v1, sx, sy) + wp.int64(edge_topleft(v0, v1)) > z
            and edge_eval(v1, v2, sx, sy) + wp.int64(edge_topleft(v1, v2)) > z
            and edge_eval(v2, v0, sx, sy) + wp.int64(edge_topleft(v2, v0)) > z)


@wp.func
def make_piece(s0: wp.vec2i, s1: wp.vec2i, s2: wp.vec2i, width: int, height: int, cull: int, grid: int):
    """Area, cull and winding of a snapped triangle and its bbox of the pixels with a sample in it
    (``grid``: :func:`fixed.sample_bbox`); bbox[0] > bbox[2] = dropped."""
    area = wp.int64(s1[0] - s0[0]) * wp.int64(s2[1] - s0[1]) - wp.int64(s1[1] - s0[1]) * wp.int64(s2[0] - s0[0])
    bb = wp.vec4i(1, 1, 0, 0)
    a = s1
    b = s2
    keep = area != wp.int64(0)
    # front faces (counter-clockwise in world/NDC) have negative area with y down
    if cull == 1 and area > wp.int64(0):
        keep = False
    if keep:
        if area < wp.int64(0):
            a = s2
            b = s1
        pb = sample_bbox(s0, a, b, width, height, grid)
        if pb[0] <= pb[2] and pb[1] <= pb[3]:
            bb = pb
            # sub-pixel triangles: a bbox of one or two pixel centres that none of them is covered
            # by is dropped here (at 4 triangles per pixel that is a third of all tile pairs)
            nx = pb[2] - pb[0]
            ny = pb[3] - pb[1]
            if nx + ny <= 1 and grid <= 1:
                if not covers(s0, a, b, pb[0], pb[1]) and not covers(s0, a, b, pb[2], pb[3]):
                    bb = wp.vec4i(1, 1, 0, 0)
    return a, b, bb


@wp.func
def clip_triangle(c0: wp.vec4d, c1: wp.vec4d, c2: wp.vec4d, near: wp.float64, gx: wp.float64, gy: wp.float64):
    """Clip against the near plane, then (if still needed) the guard band: polygon of ≤ 8 vertices."""
    px = vec8()
    py = vec8()
    pw = vec8()
    px[0] = c0[0]
    px[1] = c1[0]
    px[2] = c2[0]
    py[0] = c0[1]
    py[1] = c1[1]
    py[2] = c2[1]
    pw[0] = c0[3]
    pw[1] = c1[3]
    pw[2] = c2[3]
    n = int(3)
    if c0[3] < near or c1[3] < near or c2[3] < near:
        px, py, pw, n = clip_polygon(px, py, pw, n, 0, near, gx, gy)
    need_guard = int(0)
    for k in range(n):
        if wp.abs(px[k]) > gx * pw[k] or wp.abs(py[k]) > gy * pw[k]:
            need_guard = 1
    if need_guard == 1:
        for plane in range(1, 5):
            if n >= 3:
                px, py, pw, n = clip_polygon(px, py, pw, n, plane, near, gx, gy)
    return px, py, pw, n


@wp.func
def polygon_snap(px: vec8, py: vec8, pw: vec8, k: int, width: int, height: int):
    return wp.vec2i(snap(px[k], pw[k], float(width), 0), snap(py[k], pw[k], float(height), 1))


@wp.func
def homogeneous_matrix(c0: wp.vec4d, c1: wp.vec4d, c2: wp.vec4d, width: int, height: int):
    """Columns: the vertices in pixel-space homogeneous coordinates (X·w, Y·w, w)."""
    fw = wp.float64(width) * wp.float64(0.5)
    fh = wp.float64(height) * wp.float64(0.5)
    return wp.mat33d(
        (c0[0] + c0[3]) * fw, (c1[0] + c1[3]) * fw, (c2[0] + c2[3]) * fw,
        (c0[3] - c0[1]) * fh, (c1[3] - c1[1]) * fh, (c2[3] - c2[1]) * fh,
        c0[3], c1[3], c2[3],
    )


@wp.func
def planes_about(m: wp.mat33d, ref: wp.vec2i):
    """Interpolation planes (rows: 1/w, λ1, λ2; columns: d/dX, d/dY, value at ``ref``) of the
    triangle with homogeneous matrix m, about fixed-point point ``ref`` (float64 → float32)."""
    inv = wp.inverse(m)
    rx = wp.float64(ref[0]) / wp.float64(SUBPIXEL)
    ry = wp.float64(ref[1]) / wp.float64(SUBPIXEL)
    l0 = inv[0, 0] * rx + inv[0, 1] * ry + inv[0, 2]
    l1 = inv[1, 0] * rx + inv[1, 1] * ry + inv[1, 2]
    l2 = inv[2, 0] * rx + inv[2, 1] * ry + inv[2, 2]
    return wp.mat33(
        float(inv[0, 0] + inv[1, 0] + inv[2, 0]), float(inv[0, 1] + inv[1, 1] + inv[2, 1]), float(l0 + l1 + l2),
        float(inv[1, 0]), float(inv[1, 1]), float(l1),
        float(inv[2, 0]), float(inv[2, 1]), float(l2),
    )


@wp.func
def invertible(m: wp.mat33d):
    """False when the triangle's plane passes through the eye (or is not finite)."""
    det = wp.determinant(m)
    return det != wp.float64(0.0) and wp.isfinite(det)


@wp.func
def _culls(cull: int, cull_tri: wp.array(dtype=wp.uint8), i: int):
    """Whether triangle i drops its back face: ``cull`` 0 none, 1 every triangle, 2 where
    ``cull_tri[i]`` is set (the closed objects the camera sees from outside)."""
    c = cull
    if cull == 2:
        c = int(cull_tri[i] != wp.uint8(0))
    return c


# ---------------------------------------------------------------------------------------------
# the setup kernels
# ---------------------------------------------------------------------------------------------
@wp.kernel
def setup_kernel(
    base: int,
    clip: wp.array(dtype=wp.vec4d),
    vsnap: wp.array(dtype=wp.vec2i),
    vcode: wp.array(dtype=wp.int32),
    tris: wp.array(dtype=wp.vec3i),
    width: int,
    height: int,
    near: wp.float64,
    gx: wp.float64,
    gy: wp.float64,
    cull: int,
    cull_tri: wp.array(dtype=wp.uint8),
    subs: wp.array(dtype=SubTri),
    extra: wp.array(dtype=wp.int32),
    bin_batch: int,
    rows: int,
    tiles_x: int,
    counts: wp.array(dtype=wp.int32),
    grid: int,
):
    """Triangle i → its first sub-triangle in slot i (an empty bbox when nothing survives) and
    ``extra[i]`` = number of further pieces (clipped triangles only), emitted by ``setup_extra_kernel``."""
    i = base + wp.tid()
    if i >= tris.shape[0]:
        return
    t = tris[i]
    c = _culls(cull, cull_tri, i)
    k0 = vcode[t[0]]
    k1 = vcode[t[1]]
    k2 = vcode[t[2]]
    n_valid = int(0)
    bb = wp.vec4i(1, 1, 0, 0)
    a = wp.vec2i(0, 0)
    b = wp.vec2i(0, 0)
    s0 = wp.vec2i(0, 0)
    if (k0 & k1 & k2 & REJECT_MASK) == 0:
        if ((k0 | k1 | k2) & CLIP_MASK) == 0:
            # fast path: no clipping, vertices already snapped
            s0 = vsnap[t[0]]
            a, b, bb = make_piece(s0, vsnap[t[1]], vsnap[t[2]], width, height, c, grid)
            if bb[0] <= bb[2]:
                n_valid = 1
        else:
            px, py, pw, n = clip_triangle(clip[t[0]], clip[t[1]], clip[t[2]], near, gx, gy)
            if n >= 3:
                q0 = polygon_snap(px, py, pw, 0, width, height)
                for k in range(n - 2):
                    qa, qb, qbb = make_piece(q0, polygon_snap(px, py, pw, k + 1, width, height),
                                             polygon_snap(px, py, pw, k + 2, width, height), width, height, c, grid)
                    if qbb[0] <= qbb[2]:
                        if n_valid == 0:
                            s0 = q0
                            a = qa
                            b = qb
                            bb = qbb
                        n_valid += 1
    rec = SubTri()
    if n_valid > 0:
        m = homogeneous_matrix(clip[t[0]], clip[t[1]], clip[t[2]], width, height)
        if invertible(m):
            rec.p = planes_about(m, s0)
        else:
            n_valid = 0
            bb = wp.vec4i(1, 1, 0, 0)
    rec.v0 = s0
    rec.v1 = a
    rec.v2 = b
    rec.tri = i
    if n_valid == 0:
        rec.tri = -1  # empty slot
    subs[i] = rec
    if bin_batch > 0 and n_valid > 0:  # bin raster fused in: count the tiles of this piece
        count_tiles(bb, s0, a, b, tiles_x, rows, i // bin_batch, counts, grid)
    extra[i] = wp.max(n_valid - 1, 0)


@wp.kernel
def setup_extra_kernel(
    base: int,
    clip: wp.array(dtype=wp.vec4d),
    tris: wp.array(dtype=wp.vec3i),
    width: int,
    height: int,
    near: wp.float64,
    gx: wp.float64,
    gy: wp.float64,
    cull: int,
    cull_tri: wp.array(dtype=wp.uint8),
    extra: wp.array(dtype=wp.int32),
    extra_off: wp.array(dtype=wp.int32),
    subs: wp.array(dtype=SubTri),
    bin_batch: int,
    rows: int,
    tiles_x: int,
    counts: wp.array(dtype=wp.int32),
    grid: int,
):
    """Second and later pieces of clipped triangles, into slots M + extra_off[i] + j."""
    i = base + wp.tid()
    if i >= tris.shape[0]:
        return
    if extra[i] == 0:
        return
    t = tris[i]
    c = _culls(cull, cull_tri, i)
    px, py, pw, n = clip_triangle(clip[t[0]], clip[t[1]], clip[t[2]], near, gx, gy)
    q0 = polygon_snap(px, py, pw, 0, width, height)
    n_valid = int(0)
    o = tris.shape[0] + extra_off[i]
    for k in range(n - 2):
        qa, qb, qbb = make_piece(q0, polygon_snap(px, py, pw, k + 1, width, height),
                                 polygon_snap(px, py, pw, k + 2, width, height), width, height, c, grid)
        if qbb[0] <= qbb[2]:
            if n_valid > 0:
                rec = subs[i]  # first piece: same triangle, same fan apex q0, hence same planes
                rec.v0 = q0
                rec.v1 = qa
                rec.v2 = qb
                subs[o] = rec
                if bin_batch > 0:
                    count_tiles(qbb, q0, qa, qb, tiles_x, rows, i // bin_batch, counts, grid)
                o += 1
            n_valid += 1


def guard_factors(width: int, height: int) -> tuple[float, float]:
    """Guard-band factors g (clip space |x| ≤ g·w) keeping pixel coordinates inside ±GUARD_PIXELS."""
    gx = 2.0 * (GUARD_PIXELS - 16.0) / width - 1.0
    gy = 2.0 * (GUARD_PIXELS - 16.0) / height - 1.0
    return gx, gy
