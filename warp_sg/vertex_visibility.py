r"""Per-vertex visibility of the directions that do not depend on the view, cached between frames:
the environment's SG lobes and the lights.

The diffuse environment term (eq. 39, ``warp_sg.shading``) needs, for every SG ``G_j`` of the
environment mixture, the visible fraction ``vis_ratio(p, λ)`` of the product lobe
``(p, λ) = C*(n) ⊗ G_j`` (eq. 40 places it; eq. 24, 30 give its visibility from the SSDF). The lobe
axes are fixed in world space, so this value depends on the surface point and its normal only —
not on the camera, the materials or the local lights. Evaluated per pixel it is the bulk of a
frame (one SSDF reconstruction, NV PCA terms × 4 bilinear taps, per lobe per pixel: 8 of the ≈ 11
lookups a pixel makes in the sky-lit scenes of ``docs/benchmarks.md``).

Here it is evaluated once per **vertex** (normal ``n_v``, the vertex's own SSDF, the same
``vis_ratio`` the pixel path uses)::

    V[v, j] = vis_ratio(C*(n_v) ⊗ G_j)                      (one (vertex, lobe) pair per thread)

and the shading kernel interpolates it with the barycentrics, ``Σ_k b_k V[i_k, j]`` — the paper's
own sampling rate for visibility: the SSDFs live on the vertices (§5, "per-vertex SSDFs"), and the
mesh is refined where visibility changes (``precompute.refine``). The environment lobes are broad
(product lobes of sharpness ≤ λ_j + 2.1), so the visible fraction is smooth across a triangle and
interpolating it instead of the SSDF changes little (tests/test_vertex_visibility.py measures both
against the Monte-Carlo reference). The view-dependent specular lobes stay per pixel.

The array is rebuilt only when the lobe axes or sharpnesses change (environment rotation, a new
fit) or the visibility data does; an environment scale, material, light or camera edit reuses it.

**Lights** (:func:`light_vertex_deficit`): per vertex and light the SSDF *deficit*
``min(θd_v(l_v) − θh_v(l_v), 0)`` towards the light (direction ``l_v`` from the vertex, read in the
vertex's own frame; 0 where the occluder cone is clear, ``precompute.occluder_cone``). The shading
kernel takes ``θd = θh + Σ_k b_k deficit_k`` with the pixel's own ``θh = asin(l·n)`` and the usual
``fh(θd, λ)/fh(θh, λ)``: the SSDF is interpolated as in the paper (so a sharp shadow edge falls
where the interpolated SSDF crosses zero, inside a triangle), an unoccluded point is exactly lit,
and each vertex is read towards the light as seen from that vertex. Rebuilt when a light moves or
changes size.

**The diffuse environment sum** (:func:`env_vertex_irradiance`): with ρd = kd/π the whole diffuse
environment term is ``ρd D``, ``D = Σ_j μ_j ∫G_j e(n·p_j, λ_j) V_j`` — a function of the point and
its normal only. ``D`` is evaluated per vertex and interpolated (Gouraud) on the triangles where
that is accurate: each triangle compares the interpolated value with the per-pixel sum at the
interpolated normal at its three edge midpoints and centroid, and is shaded per pixel when they
differ by more than :data:`GOURAUD_TOLERANCE` (0.5 %) of its largest value. Flat triangles pass
exactly; finely tessellated curved ones pass; a coarse sphere keeps the per-pixel sum. Rebuilt on
environment rotation or with the visibility cache; a scale edit only rescales it.
"""
from __future__ import annotations

import time

import numpy as np
import warp as wp

from precompute.ssdf_wp import ssdf_at, ssdf_point

from .fastmath import fast_asin
from .lights import LightArrays, light_irradiance
from .shading import CC_LAM, EnvSG, Visibility, env_diffuse_sum, lookup_skip, vis_ratio
from .sg_irradiance import sg_irradiance_norm_at
from .sg_wp import sg_product_lobe


@wp.kernel(enable_backward=False)
def env_vertex_visibility_kernel(base: int, fh_mode: int, vis: Visibility, env: EnvSG,
                                 out: wp.array2d(dtype=float)):
    """``out[v, j] = vis_ratio(C*(n_v) ⊗ G_j)`` for element ``base + tid = v·J + j``."""
    e = base + wp.tid()
    nj = out.shape[1]
    v = e // nj
    j = e - v * nj
    n = wp.normalize(vis.normals[v])
    q = ssdf_point(vis.normals, v, v, v, 1.0, 0.0, 0.0, n)
    pe, le = sg_product_lobe(n, CC_LAM, env.axis[j], env.lam[j])
    out[v, j] = vis_ratio(1, fh_mode, vis, q, pe, le)


@wp.kernel(enable_backward=False)
def light_vertex_deficit_kernel(base: int, fh_mode: int, vis: Visibility, positions: wp.array(dtype=wp.vec3),
                                lights: LightArrays, out: wp.array2d(dtype=float)):
    """``out[v, j] = min(θd_v(l_v) − θh_v(l_v), 0)``: vertex v's SSDF towards light j (direction
    ``l_v`` from the vertex, its own frame) less its horizon value ``asin(l_v·n_v)`` — 0 where no
    occluder is closer than the horizon (and where the occluder cone is clear: no lookup)."""
    e = base + wp.tid()
    nl = out.shape[1]
    v = e // nl
    j = e - v * nl
    n = wp.normalize(vis.normals[v])
    la, ll, E = light_irradiance(lights, j, positions[v])
    q = ssdf_point(vis.normals, v, v, v, 1.0, 0.0, 0.0, n)
    th_h = fast_asin(wp.clamp(wp.dot(la, n), -1.0, 1.0))
    s = lookup_skip(fh_mode, vis, q, la, th_h, ll)
    d = float(0.0)
    if s < 1.0:
        d = (1.0 - s) * wp.min(ssdf_at(vis.mean, vis.basis, vis.weights, q, la) - th_h, 0.0)
    out[v, j] = d


@wp.kernel(enable_backward=False)
def env_vertex_irradiance_kernel(base: int, use_vis: int, irr: wp.array2d(dtype=float), env: EnvSG,
                                 normals: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    """``out[v] = D[v]``, the diffuse environment sum at vertex v (its normal, its visibility)."""
    v = base + wp.tid()
    out[v] = env_diffuse_sum(irr, env, use_vis, wp.normalize(normals[v]), v, v, v, 1.0, 0.0, 0.0)


@wp.func
def _max3(a: wp.vec3) -> float:
    return wp.max(wp.max(a[0], a[1]), a[2])


@wp.kernel(enable_backward=False)
def env_gouraud_kernel(base: int, use_vis: int, irr: wp.array2d(dtype=float), env: EnvSG,
                       normals: wp.array(dtype=wp.vec3), tris: wp.array(dtype=wp.vec3i),
                       dv: wp.array(dtype=wp.vec3), tol: float, out: wp.array(dtype=wp.uint8)):
    """``out[t] = 1`` where ``Σ_k b_k D[i_k]`` is within ``tol`` (relative to the largest value seen
    on the triangle) of the per-pixel sum at the normal ``normalize(Σ_k b_k n_k)``, checked at the
    three edge midpoints and the centroid (the error of linear interpolation of a smooth function
    peaks there; it is exact at the vertices)."""
    t = base + wp.tid()
    tri = tris[t]
    i0 = tri[0]
    i1 = tri[1]
    i2 = tri[2]
    d0 = dv[i0]
    d1 = dv[i1]
    d2 = dv[i2]
    scale = wp.max(wp.max(_max3(d0), _max3(d1)), _max3(d2))
    err = float(0.0)
    for k in range(4):
        b0 = float(1.0) / 3.0
        b1 = float(1.0) / 3.0
        if k == 0:
            b0 = 0.5
            b1 = 0.5
        elif k == 1:
            b0 = 0.0
            b1 = 0.5
        elif k == 2:
            b0 = 0.5
            b1 = 0.0
        b2 = 1.0 - b0 - b1
        n = wp.normalize(normals[i0] * b0 + normals[i1] * b1 + normals[i2] * b2)
        ref = env_diffuse_sum(irr, env, use_vis, n, i0, i1, i2, b0, b1, b2)
        d = wp.abs(d0 * b0 + d1 * b1 + d2 * b2 - ref)
        err = wp.max(err, _max3(d))
        scale = wp.max(scale, _max3(ref))
    ok = wp.uint8(0)
    if err <= tol * scale:
        ok = wp.uint8(1)
    out[t] = ok


#: relative error of the interpolated diffuse environment sum a triangle may have (checked at its
#: edge midpoints and centroid) to be shaded from the per-vertex values
GOURAUD_TOLERANCE = 0.005


def env_vertex_irradiance(irr, env: EnvSG, normals, tris, use_vis: bool, device,
                          tol: float = GOURAUD_TOLERANCE):
    """``(D, ok)``: the diffuse environment sum per vertex (V,) vec3 and the per-triangle flag (T,)
    uint8 of where interpolating it stays within ``tol`` (:func:`env_gouraud_kernel`). ``env.vis``
    must be the per-vertex visibility when ``use_vis``."""
    from raster import parallel

    nv, nt = int(normals.shape[0]), int(tris.shape[0])
    dv = wp.zeros(max(nv, 1), dtype=wp.vec3, device=device)
    ok = wp.zeros(max(nt, 1), dtype=wp.uint8, device=device)
    flag = 1 if use_vis else 0
    parallel.launch(env_vertex_irradiance_kernel, nv, [flag, irr, env, normals, dv], device, min_chunk=1024)
    parallel.launch(env_gouraud_kernel, nt, [flag, irr, env, normals, tris, dv, float(tol), ok], device,
                    min_chunk=1024)
    return dv, ok


def _vertex_table(kernel, n_vertices: int, n_cols: int, inputs: list, device) -> wp.array2d:
    """(V, n_cols) float array of a per-(vertex, column) ``kernel`` (element ``v·n_cols + j``;
    CPU: thread pool); (1, 1) zeros when there is nothing to compute."""
    from raster import parallel

    out = wp.zeros((max(int(n_vertices), 1), max(int(n_cols), 1)), dtype=float, device=device)
    if n_cols > 0 and n_vertices > 0:
        parallel.launch(kernel, int(n_vertices) * int(n_cols), [*inputs, out], device, min_chunk=1024)
    return out


def light_vertex_deficit(vis: Visibility, positions, lights: LightArrays, n_vertices: int, fh_sigmoid: bool,
                         device) -> wp.array2d:
    """(V, lights) array of :func:`light_vertex_deficit_kernel`."""
    return _vertex_table(light_vertex_deficit_kernel, n_vertices, lights.count,
                         [1 if fh_sigmoid else 0, vis, positions, lights], device)


def env_vertex_visibility(vis: Visibility, env: EnvSG, n_vertices: int, fh_sigmoid: bool, device) -> wp.array2d:
    """(V, J) array of :func:`env_vertex_visibility_kernel`."""
    return _vertex_table(env_vertex_visibility_kernel, n_vertices, env.count, [1 if fh_sigmoid else 0, vis, env],
                         device)


def _same_key(a, b) -> bool:
    """Keys match element by element: plain values by ``==``, objects (arrays, structs) by identity."""
    if a is None or b is None or len(a) != len(b):
        return False
    return all(x is y or (isinstance(x, (tuple, str, int, float)) and type(x) is type(y) and x == y)
               for x, y in zip(a, b))


class VertexCache:
    """A per-vertex array kept between frames: ``array(key, build, device)`` calls ``build()`` only
    when ``key`` changes (:func:`_same_key`: values by ``==``, objects by identity — the key holds
    them, so a rebuilt object never matches a stale key); ``key=None`` gives ``placeholder(device)``
    (default a (1, 1) float array: the argument of the kernel variant without the cache). ``builds`` counts rebuilds; ``seconds`` is the time the
    last ``array`` call spent building (0 when it reused the array)."""

    def __init__(self, placeholder=lambda device: wp.zeros((1, 1), dtype=float, device=device)):
        self.key = None
        self.value = None
        self.builds = 0
        self.seconds = 0.0
        self.placeholder = placeholder

    def array(self, key, build, device):
        self.seconds = 0.0
        if key is None:
            if self.value is None or self.key is not None:
                self.key, self.value = None, self.placeholder(device)
        elif not _same_key(key, self.key):
            t = time.perf_counter()
            self.value = build()
            self.key = key
            self.builds += 1
            self.seconds = time.perf_counter() - t
        return self.value


def _unit_scale(es: EnvSG, mu, irr, device) -> EnvSG:
    """A copy of ``es`` with the amplitudes ``mu`` (the environment's unscaled ones) and their
    lobe constants: what the per-vertex diffuse sum is built from, so that any later scale,
    however small or large, is one multiplication (``EnvSG.irr_scale``)."""
    from .shading import lobe_constants

    u = EnvSG()
    u.count, u.axis, u.lam, u.vis, u.mu = es.count, es.axis, es.lam, es.vis, mu
    return lobe_constants(u, irr, device)


def caches() -> tuple:
    """The renderer's three caches: environment visibility, lights' deficit, diffuse environment sum."""
    return VertexCache(), VertexCache(), VertexCache(lambda d: (wp.zeros(1, dtype=wp.vec3, device=d),
                                                                wp.zeros(1, dtype=wp.uint8, device=d)))


def update_caches(r, es: EnvSG) -> EnvSG:
    """Bring a ``Renderer``'s per-vertex caches up to date and attach them to the shading arguments:

    * ``es.vis`` (``r.env_vis_cache``), each environment lobe's visible fraction: rebuilt when the
      lobe axes (rotation, fit) or the visibility data change;
    * ``r.vis.light_deficit`` (``r.light_vis_cache``), each light's SSDF deficit: rebuilt when a
      light moves or is resized (not on an intensity or environment-scale edit);
    * ``es.irr_vertex``, ``es.gouraud`` (``r.env_irr_cache``), the diffuse environment sum and where
      it interpolates: built at unit scale, rebuilt on environment rotation or a new ``es.vis``;
      ``es.irr_scale`` is the environment's scale (the sum is linear in it).

    Camera and material edits reuse all three. ``r.timings["vertex_visibility"]``: this call's
    rebuild time."""
    d, nv, fh = r.device, len(r.geometry.vertices), r.scene.render.fh
    f = r.features()  # the caches the kernel variant reads
    key = (r._env_arrays_key[:2], r.ssdf, r.vis.cones, fh) if f.env_vis_vertex else None
    es.vis = r.env_vis_cache.array(key, lambda: env_vertex_visibility(r.vis, es, nv, fh == "sigmoid", d), d)
    where = tuple((li.type, *np.ravel(getattr(li, "position", getattr(li, "direction", ()))).tolist(),
                   float(li.radius)) for li in r.shading_lights)
    key = (where, r.ssdf, r.vis.cones, fh) if f.light_vis_vertex else None
    r.vis.light_deficit = r.light_vis_cache.array(
        key, lambda: light_vertex_deficit(r.vis, r.geo_arrays.positions, r.light_arrays, nv, fh == "sigmoid", d), d)
    # D is linear in the environment's scale: built at unit scale once per rotation, scaled per pixel
    key = (r._env_arrays_key[:2], es.vis, r.geo_arrays.normals) if f.env_irradiance_vertex else None
    es.irr_vertex, es.gouraud = r.env_irr_cache.array(key, lambda: env_vertex_irradiance(
        r.irr_table, _unit_scale(es, r._env_mu_unit, r.irr_table, d), r.geo_arrays.normals, r.geo_arrays.tris,
        f.env_vis_vertex, d), d)
    es.irr_scale = float(r.env_light.scale) if r.env_light is not None else 0.0
    r.timings["vertex_visibility"] = sum(c.seconds for c in (r.env_vis_cache, r.light_vis_cache, r.env_irr_cache))
    return es


__all__ = ["VertexCache", "caches", "update_caches", "env_vertex_irradiance", "env_vertex_visibility",
           "GOURAUD_TOLERANCE", "env_vertex_visibility_kernel", "light_vertex_deficit",
           "light_vertex_deficit_kernel"]
