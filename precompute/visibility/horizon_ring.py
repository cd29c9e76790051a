r"""The horizon ring of the adaptive visibility maps (:mod:`precompute.visibility.adaptive_rays`, step 2).

The map's outermost row and column (``4 (Rr − 1)`` texels, walked clockwise from texel (0, 0):
:func:`ring_texel`) are the directions just above the horizon, where a vertex on a curved surface
sees a strip one texel wide that no coarse sample meets. The ring is sampled as a 1-D map of its
own: every ``g``-th texel first (:func:`ring_kernel`, closest hit while it is refined after), then
its segments are halved where the samples around them disagree in visibility or depth
(:func:`ring_refine_kernel`, any hit for the last halving); a texel of a segment that is not halved
takes the segment's value.
"""
from __future__ import annotations

import warp as wp

from precompute.visibility.rays import NO_HIT, ray_blocked, ray_hit_distance, vertex_ray_direction, vertex_ray_origin


@wp.func
def ring_texel(m: int, Rr: int) -> int:
    """Texel of position ``m`` of the ring (the outermost row and column, 4 (Rr − 1) texels),
    walked clockwise from texel (0, 0)."""
    side = m / (Rr - 1)
    o = m - side * (Rr - 1)
    j = int(0)
    i = int(0)
    if side == 0:
        i = o
    elif side == 1:
        j = o
        i = Rr - 1
    elif side == 2:
        j = Rr - 1
        i = Rr - 1 - o
    else:
        j = Rr - 1 - o
    return j * Rr + i


@wp.func
def _ring_ray(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3), vi: int,
              dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float, k: int, m: int, tex: int, closest: int,
              vis: wp.array2d(dtype=wp.uint8), depth: wp.array2d(dtype=float), known: wp.array2d(dtype=wp.uint8),
              ring_depth: wp.array2d(dtype=float)):
    """Cast ring position ``m`` (texel ``tex``) of vertex ``vi``: with ``closest`` its hit distance
    goes to ``ring_depth`` (the ring's own depth test), else any hit. The texel's ``depth`` is
    :data:`NO_HIT` either way: a refined cell whose sample is a ring texel takes part in the grid's
    visibility test only."""
    o = vertex_ray_origin(points, normals, vi, offset)
    d = vertex_ray_direction(normals, vi, dirs[tex])
    t = float(NO_HIT)
    if closest != 0:
        t = ray_hit_distance(mesh, o, d, max_t)
    elif ray_blocked(mesh, o, d, max_t):
        t = 0.0
    vis[k, tex] = wp.where(t < NO_HIT, wp.uint8(0), wp.uint8(1))
    depth[k, tex] = NO_HIT
    known[k, tex] = wp.uint8(1)
    ring_depth[k, m] = t


@wp.kernel(enable_backward=False)
def ring_kernel(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3), first: int,
                 dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float, Rr: int, g: int,
                 vis: wp.array2d(dtype=wp.uint8), depth: wp.array2d(dtype=float), known: wp.array2d(dtype=wp.uint8),
                 ring_depth: wp.array2d(dtype=float)):
    """Every ``g``-th texel of the ring (positions ``q·g``; :func:`ring_texel`); closest hit while
    the ring is refined after (``g > 1``)."""
    k, q = wp.tid()
    m = q * g
    tex = ring_texel(m, Rr)
    if known[k, tex] == wp.uint8(0):
        _ring_ray(mesh, points, normals, first + k, dirs, offset, max_t, k, m, tex, wp.where(g > 1, 1, 0),
                  vis, depth, known, ring_depth)
    else:
        ring_depth[k, m] = NO_HIT  # (a grid sample on the ring: its visibility only)


@wp.func
def _ring_sample(vis: wp.array2d(dtype=wp.uint8), ring_depth: wp.array2d(dtype=float), k: int, m: int, Rr: int,
                 lo: int, hi: int, dmin: float, dmax: float):
    """Fold ring position ``m``'s sample into the visibility range ``lo, hi`` and the blocked hit
    distances' range ``dmin, dmax``."""
    v = int(vis[k, ring_texel(m, Rr)])
    t = ring_depth[k, m]
    if v == 0 and t > 0.0 and t < NO_HIT:
        dmin = wp.min(dmin, t)
        dmax = wp.max(dmax, t)
    return wp.min(lo, v), wp.max(hi, v), dmin, dmax


@wp.kernel(enable_backward=False)
def ring_refine_kernel(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3),
                        first: int, dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float, Rr: int, h: int,
                        log_ratio: float, vis: wp.array2d(dtype=wp.uint8), depth: wp.array2d(dtype=float),
                        known: wp.array2d(dtype=wp.uint8), ring_depth: wp.array2d(dtype=float)):
    """The midpoints ``m = q·2h + h`` of the ring's segments of length 2h: a ray when the four ring
    samples ``m ± h``, ``m ± 3h`` (the segment and its neighbours on both sides) disagree in
    visibility or their blocked hit distances differ by more than ``exp(log_ratio)`` (closest hit
    while ``h > 1``), else the segment's value, written to ``vis`` only (not ``known``: no ray
    was cast; its ``ring_depth`` is the nearer end's)."""
    k, q = wp.tid()
    M = 4 * (Rr - 1)
    m = q * 2 * h + h
    tex = ring_texel(m, Rr)
    lo = int(1)
    hi = int(0)
    dmin = float(NO_HIT)
    dmax = float(0.0)
    lo, hi, dmin, dmax = _ring_sample(vis, ring_depth, k, (m - h + M) % M, Rr, lo, hi, dmin, dmax)
    lo, hi, dmin, dmax = _ring_sample(vis, ring_depth, k, (m + h) % M, Rr, lo, hi, dmin, dmax)
    lo, hi, dmin, dmax = _ring_sample(vis, ring_depth, k, (m - 3 * h + 2 * M) % M, Rr, lo, hi, dmin, dmax)
    lo, hi, dmin, dmax = _ring_sample(vis, ring_depth, k, (m + 3 * h) % M, Rr, lo, hi, dmin, dmax)
    split = lo != hi
    if dmax > 0.0 and dmin < NO_HIT:
        if wp.log(dmax) - wp.log(dmin) > log_ratio:
            split = True
    if known[k, tex] != wp.uint8(0):
        ring_depth[k, m] = NO_HIT
    elif split:
        _ring_ray(mesh, points, normals, first + k, dirs, offset, max_t, k, m, tex, wp.where(h > 1, 1, 0),
                  vis, depth, known, ring_depth)
    else:
        vis[k, tex] = wp.uint8(lo)
        ring_depth[k, m] = wp.min(ring_depth[k, (m - h + M) % M], ring_depth[k, (m + h) % M])


__all__ = ["ring_texel", "ring_kernel", "ring_refine_kernel"]
