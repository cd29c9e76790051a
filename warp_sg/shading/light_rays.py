r"""Per-vertex light visibility by ray casting: the shadows of point and directional lights (and of
the environment's extracted peaks, a sun, lamps) exact at the vertices.

The light cache of :mod:`warp_sg.shading.vertex_visibility` holds per vertex and light the deficit
``min(θd − θh, 0)``: how far inside the visibility boundary the light's centre lies, which the shading
kernel interpolates with the barycentrics and turns into the visible fraction of the light's disc
(``visibility_terms.light_fraction``: the area of the disc, of angular radius α, beyond a great
circle θd from its centre). Read from the SSDF, θd cannot be deeper than half the angular width of
the occluder the map resolves: an occluder a texel or two wide (a bunny's ears, a lamp post, a thin
handle) reads as θd ≈ −½ texel, less than a small light's α, and its shadow lets 20–70 % of the light
through where the truth is dark (the bunny's ear shadows under a point light: +70 % against a path
tracer). Rays are cheap where the directions are few: the light's own cone.

Per vertex v and light j (:func:`light_rays_kernel`): ``RAYS`` directions stratified uniformly over
the light's cone (``cos γ = 1 − u (1 − cos α)``, 4 rings × 8 sectors, turned by a per-vertex angle so
neighbouring vertices do not share a pattern; when the first 8, spread over every ring, are all
unblocked, the light is: most vertices near an occluder see all of a small light), each weighted by its cosine ``n_v·d`` above the
vertex's horizon, cast from the vertex (offset along its normal) where the light's cone meets the
vertex's occluder cone (``precompute.visibility.occluder_cone``; elsewhere the light is unoccluded, as
for the SSDF path) against the occluders (alpha
cut-outs let them through); ``f`` = visible weight / total weight. Then the deficit that gives this
fraction, ``θ`` with ``cap(θ) = f · cap(θh)`` (bisection; ``cap`` the disc's visible area beyond a
boundary, monotone in θ) — so interpolation, the kernel's formula and an unoccluded vertex (``f = 1``:
deficit 0) are unchanged; a vertex in the umbra (``f = 0``) keeps its SSDF value where that is deeper
than ``−α`` (the depth tells the interpolation where the boundary lies between two vertices).

The occluders are the static objects (a moving object's shadows on others come from its proxies,
its own rows from its SSDF: :mod:`warp_sg.renderer.dynamic_objects`). Cost: ``RAYS`` any-hit rays per
vertex and light, when a light moves or the geometry changes (about 0.1 s per light for 20 k
vertices on two cores).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from precompute.visibility.ssdf_wp import ssdf_eval_vertex, world_to_local
from warp_sg.numeric.fastmath import fast_asin
from warp_sg.scene.lights import LIGHT_POINT, LightArrays, light_irradiance
from warp_sg.shading.cutout import Cutouts, blocked
from warp_sg.shading.visibility_terms import (
    Visibility,
    cap_visible,
    light_sin_radius,
    lookup_skip,
    vertex_frame,
    vertex_light_pair,
    vertex_point,
)

#: rays per vertex and light: RINGS × SECTORS
RINGS = 4
SECTORS = 8
RAYS = RINGS * SECTORS
#: bisection steps of the inverse disc fraction (2⁻²⁴ of the disc's diameter)
BISECT = 24


@wp.func
def cone_direction(axis: wp.vec3, cos_a: float, k: int, turn: float) -> wp.vec3:
    """Ray ``k`` of the stratified pattern over the cone of half-angle acos(cos_a) about ``axis``: ring
    ``k mod RINGS``, sector ``(3⌊k/RINGS⌋ + 2 ring) mod SECTORS`` (every ring and sector once, and the
    first ``SECTORS`` rays spread over all rings and sectors)."""
    ring = k % RINGS
    sec = (3 * (k // RINGS) + 2 * ring) % SECTORS
    u = (float(ring) + 0.5) / float(RINGS)
    ct = 1.0 - u * (1.0 - cos_a)
    st = wp.sqrt(wp.max(1.0 - ct * ct, 0.0))
    phi = turn + 6.283185307179586 * (float(sec) + 0.5 * float(ring % 2)) / float(SECTORS)
    t = wp.vec3(1.0, 0.0, 0.0)
    if wp.abs(axis[0]) > 0.9:
        t = wp.vec3(0.0, 1.0, 0.0)
    t = wp.normalize(t - axis * wp.dot(t, axis))
    b = wp.cross(axis, t)
    return wp.normalize(axis * ct + (t * wp.cos(phi) + b * wp.sin(phi)) * st)


@wp.func
def cap_inverse(target: float, sa: float, alpha: float) -> float:
    """θ in [−α, α] with ``cap_visible(θ) = target`` (bisection; ``cap_visible`` rises with θ)."""
    lo = -alpha
    hi = alpha
    for _ in range(BISECT):
        mid = 0.5 * (lo + hi)
        if cap_visible(mid, sa, alpha) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@wp.kernel(enable_backward=False)
def light_rays_kernel(base: int, ids: wp.array(dtype=int), fh_mode: int, vis: Visibility,
                      positions: wp.array(dtype=wp.vec3), lights: LightArrays, mesh: wp.uint64, cut: Cutouts,
                      eps: float, out: wp.array2d(dtype=float)):
    """``out[v, j]``: the deficit of light j at vertex v from its ray-cast visible fraction (module
    docstring), the SSDF's value kept in the umbra where it is deeper."""
    vj = vertex_light_pair(base + wp.tid(), ids, out.shape[1])
    v = vj[0]
    j = vj[1]
    n = wp.normalize(vis.normals[v])
    x = positions[v]
    la, ll, E = light_irradiance(lights, j, x)
    th_h = fast_asin(wp.clamp(wp.dot(la, n), -1.0, 1.0))
    q = vertex_point(v, n)  # the vertex alone, for the occluder-cone test
    deficit = float(0.0)
    if lookup_skip(fh_mode, vis, q, la, th_h, ll) < 1.0:  # the light's cone meets the vertex's occluders
        sa = light_sin_radius(ll)
        alpha = wp.asin(sa)
        cos_a = wp.sqrt(wp.max(1.0 - sa * sa, 0.0))
        max_t = float(1.0e30)
        if lights.kind[j] == LIGHT_POINT:
            max_t = wp.max(wp.length(lights.vec[j] - x) - lights.radius[j], 0.0)
        turn = 6.283185307179586 * wp.randf(wp.rand_init(7919, v))
        o = x + n * eps
        tot = float(0.0)
        seen = float(0.0)
        for k in range(RAYS):
            if k == SECTORS and seen == tot:
                break  # the first rays, spread over the cone, are all unblocked
            d = cone_direction(la, cos_a, k, turn)
            c = wp.dot(d, n)
            if c > 0.0:
                tot += c
                if not blocked(mesh, cut, o, d, max_t):
                    seen += c
        if tot > 0.0 and seen < tot:
            f = seen / tot
            if f > 0.0:
                deficit = wp.min(cap_inverse(f * cap_visible(th_h, sa, alpha), sa, alpha) - th_h, 0.0)
            else:  # the umbra: the SSDF's depth where it is deeper than the disc's edge
                t, b = vertex_frame(vis, v, n)
                th = wp.min(-alpha, ssdf_eval_vertex(vis.mean, vis.basis, vis.weights, v, world_to_local(la, t, b, n)))
                deficit = wp.min(th - th_h, 0.0)
    out[v, j] = deficit


class LightOccluders:
    """The static objects' triangles as a ``wp.Mesh`` for :func:`light_rays_kernel` (built on first
    use; the renderer's cut-outs ride along)."""

    def __init__(self, geometry, positions, tris, cut, static_objects, device):
        self.device = device
        self._args = (geometry, positions, tris, cut, static_objects)
        self.mesh = None
        scale = float(np.linalg.norm(np.ptp(np.asarray(geometry.vertices, np.float64), axis=0))) or 1.0
        self.eps = 1.0e-4 * scale
        static = np.asarray(static_objects, bool)
        self._static_tris = static[np.asarray(geometry.tri_object)] if len(static) else np.ones(0, bool)
        #: the vertices of static objects (None: every vertex): a moving object's vertices keep their
        #: SSDF's deficits, which turn with it (its rows are patched per frame from them)
        self.static_vertices = None
        if not static.all():
            moving = np.zeros(len(geometry.vertices), bool)
            moving[np.asarray(geometry.triangles)[~self._static_tris].ravel()] = True
            self.static_vertices = wp.array(np.flatnonzero(~moving).astype(np.int32), dtype=int, device=device)

    def arrays(self):
        """``(mesh id, Cutouts struct)``."""
        if self.mesh is None:
            g, positions, tris, cut, static_objects = self._args
            t = np.asarray(g.triangles, np.int32)[self._static_tris]
            if len(t) == 0:
                t = np.zeros((1, 3), np.int32)
            self.mesh = wp.Mesh(points=positions, indices=wp.array(t.ravel(), dtype=wp.int32, device=self.device))
        return self.mesh.id, self._args[3].arrays


def light_vertex_rays(occluders: LightOccluders, vis: Visibility, positions, lights: LightArrays, n_vertices: int,
                      fh_sigmoid: bool, device, into=None) -> wp.array2d:
    """(V, lights) deficits of :func:`light_rays_kernel` at the static objects' vertices
    (``occluders.static_vertices``; every vertex when no object moves), written into ``into`` (the
    SSDF's deficits, which a moving object's vertices keep) or a new zero array."""
    from raster import parallel

    ids = occluders.static_vertices
    n = int(n_vertices) if ids is None else int(ids.shape[0])
    if ids is None:
        ids = wp.zeros(0, dtype=int, device=device)
    out = wp.zeros((max(int(n_vertices), 1), max(int(lights.count), 1)), dtype=float, device=device) \
        if into is None else into
    if lights.count > 0 and n > 0:
        mesh, cut = occluders.arrays()
        parallel.launch(light_rays_kernel, n * int(lights.count),
                        [ids, 1 if fh_sigmoid else 0, vis, positions, lights, mesh, cut, occluders.eps, out], device,
                        min_chunk=256, chunks=4 * parallel.cpu_workers())
    return out


__all__ = ["light_rays_kernel", "light_vertex_rays", "LightOccluders", "cone_direction", "cap_inverse", "RAYS"]
