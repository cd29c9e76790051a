r"""A bounding cone of each vertex's occluders, to skip SSDF lookups that cannot see them.

The SSDF (eq. 24) of a vertex at direction ``p`` is ``θd(p) = min(θh(p), dist(p, O))``: the
angular distance to the nearest direction that is either below the horizon (``θh = asin(p·n)``)
or occluded (the set ``O``). The visibility of an SG lobe ``(p, λ)`` is the ratio
``fh(θd, λ)/fh(θh, λ)`` (``warp_sg.shading.kernel.vis_ratio``), and the tabulated ``fh`` is constant for
``θ ≥ θmax(λ) = min(π/2, 6/√λ)`` (``warp_sg.sg.fh``: an SG keeps less than e^-18 of its mass beyond). So

    dist(p, O) ≥ min(θh(p), θmax(λ))   ⇒   vis_ratio(p, λ) = 1 exactly,

and no lookup is needed. Most lookups of a typical frame are of this kind: an open floor seen by a
light or a sky lobe far from the only object on it, the outer side of a convex-ish object.

Per vertex the occluded set is bounded by a cone, axis ``c`` (world space) and half-angle ``α``:
the mean direction of the occluded texels and the largest angle from it, plus ``h`` (the half
diagonal of a texel, for the texels' extent). Then ``dist(p, O) ≥ ∠(p, c) − α``. Texels count as
occluded where the (uncompressed, :func:`precompute.visibility.ssdf.compute_ssdf`) SSDF is negative, or is
below ``h`` and more than ``0.3 h`` below its horizon value ``θh``: an occluder inside the texel
that does not cover its centre (the distance transform's own error on an open plane is up to 0.17 h). A vertex with
no such texel stores ``α = −1`` (nothing occludes
it); one whose occluders surround it gets ``α ≥ π`` (never skipped).

Kernel side, :func:`occluder_clearance` returns ``s ∈ [0, 1]``: 1 when every vertex of the shading
point's triangle (``SSDFPoint``) clears its cone by ``min(θh, θmax)``, 0 when one is within it,
with a smoothstep of width ``h`` between; ``vis_ratio`` returns ``s + (1 − s)·ratio``, so the skip
changes the image continuously. The skipped value (1) is the exact visibility of such a lobe,
which the PCA reconstruction only approximates.
"""
from __future__ import annotations

import math

import numpy as np
import warp as wp

from precompute.visibility.ssdf_wp import SSDFPoint, texel_directions
from warp_sg.numeric.fastmath import fast_asin
from warp_sg.numeric.onb import frame_from_normal

_HALF_PI = wp.constant(0.5 * math.pi)


def texel_half_diagonal(resolution: int) -> float:
    """``h``: a bound on the angular half-diagonal of a texel of an R×R equal-area concentric map
    (a texel covers 2π/R² sr; 1.5 × its side √(2π)/R covers the map's most stretched texels)."""
    return 1.5 * math.sqrt(2.0 * math.pi) / float(resolution)


def occluder_cones(ssdf_maps, normals, resolution: int, chunk: int = 4096) -> np.ndarray:
    """(V, 4) float32 cones ``(c_x, c_y, c_z, α)`` (world axis, half-angle in radians incl. the
    texel margin ``h``; ``α = −1``: no occluder) from the uncompressed SSDFs ``(V, R, R)`` or
    ``(V, R²)`` of vertices with unit normals ``(V, 3)`` (the frames of :mod:`warp_sg.numeric.onb`)."""
    R = int(resolution)
    X = np.asarray(ssdf_maps, np.float32).reshape(len(normals), R * R)
    n = np.asarray(normals, np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    t, b = frame_from_normal(n)
    D = texel_directions(R).reshape(-1, 3)
    th = np.arcsin(np.clip(D[:, 2], 0.0, 1.0)).astype(np.float32)
    h = texel_half_diagonal(R)
    out = np.empty((len(X), 4), np.float32)
    for s in range(0, len(X), chunk):
        x = X[s:s + chunk]
        occ = (x < 0.0) | ((x < h) & (x < th[None, :] - 0.3 * h))
        cnt = occ.sum(1)
        S = occ.astype(np.float64) @ D  # (c, 3) sum of occluded directions (local frame)
        L = np.linalg.norm(S, axis=1)
        a = S / np.maximum(L, 1e-30)[:, None]
        cos_min = np.where(occ, a @ D.T, 1.0).min(1)
        alpha = np.arccos(np.clip(cos_min, -1.0, 1.0)) + h
        alpha = np.where(L > 1e-6 * np.maximum(cnt, 1), alpha, 4.0)  # occluders all round: never skip
        alpha = np.where(cnt == 0, -1.0, alpha)
        nn, tt, bb = n[s:s + chunk], t[s:s + chunk], b[s:s + chunk]
        w = a[:, :1] * tt + a[:, 1:2] * bb + a[:, 2:3] * nn
        out[s:s + chunk, :3] = w
        out[s:s + chunk, 3] = alpha
    return out


def no_cones(n_vertices: int) -> np.ndarray:
    """Cones that never allow a skip (``α = 4 > π``), for SSDF data without cones."""
    c = np.zeros((max(int(n_vertices), 1), 4), np.float32)
    c[:, 2] = 1.0
    c[:, 3] = 4.0
    return c


@wp.func
def _vertex_clearance(cone: wp.vec4, n: wp.vec3, p: wp.vec3, th_h: float, tmax: float, band: float) -> float:
    """smoothstep(0, band, ∠(p, c) − α − m) for one vertex (cone ``c, α``, normal ``n``): 1 once p is
    ``m + band`` clear of the cone, ``m = min(max(θh, θh_k), θmax)`` at least 0 (the larger of the
    pixel's and the vertex's horizon angle: conservative for both the blended and the own-frame reads)."""
    if cone[3] < 0.0:
        return 1.0
    c = wp.clamp(p[0] * cone[0] + p[1] * cone[1] + p[2] * cone[2], -1.0, 1.0)
    g = _HALF_PI - fast_asin(c) - cone[3]  # ∠(p, c) − α
    if g <= 0.0:  # p inside the cone: 0 whatever m ≥ 0 (no second asin)
        return 0.0
    m = wp.clamp(wp.min(wp.max(th_h, fast_asin(wp.clamp(wp.dot(p, n), -1.0, 1.0))), tmax), 0.0, _HALF_PI)
    return wp.smoothstep(0.0, band, g - m)


@wp.func
def occluder_clearance(cones: wp.array(dtype=wp.vec4), q: SSDFPoint, p: wp.vec3, th_h: float, tmax: float,
                       band: float) -> float:
    """``s ∈ [0, 1]``: how clearly the lobe at world direction ``p`` misses the occluders of the
    vertices that carry the point ``q`` (:func:`precompute.visibility.ssdf_wp.ssdf_point`): the smallest
    :func:`_vertex_clearance` of the vertices with a weight. ``th_h``: the point's horizon angle of
    ``p``; ``tmax``: the fh saturation angle θmax(λ)."""
    s = float(1.0)
    if q.c0 + q.e0 > 0.0:
        s = wp.min(s, _vertex_clearance(cones[q.i0], q.n0, p, th_h, tmax, band))
    if s > 0.0 and q.c1 + q.e1 > 0.0:
        s = wp.min(s, _vertex_clearance(cones[q.i1], q.n1, p, th_h, tmax, band))
    if s > 0.0 and q.c2 + q.e2 > 0.0:
        s = wp.min(s, _vertex_clearance(cones[q.i2], q.n2, p, th_h, tmax, band))
    return s


__all__ = ["occluder_cones", "occluder_clearance", "no_cones", "texel_half_diagonal"]
