r"""Per-vertex visibility of the directions that do not depend on the view, cached between frames:
the environment's SG lobes and the lights.

The diffuse environment term (eq. 39, ``warp_sg.shading.kernel``) needs, for every SG ``G_j`` of the
environment mixture, the visible fraction of the cosine-weighted lobe ``G_j(i) max(n·i, 0)``. The
lobe axes are fixed in world space, so this value depends on the surface point and its normal only —
not on the camera, the materials or the local lights. It is evaluated once per **vertex** and the
shading kernel interpolates it with the barycentrics, ``Σ_k b_k V[i_k, j]`` — the paper's own
sampling rate for visibility: the SSDFs live on the vertices (§5, "per-vertex SSDFs"), and the mesh
is refined where visibility changes (``precompute.visibility.refine``).

**By quadrature of the SSDF, not by the hemisphere model.** The paper's product of an SG with the
visibility (eq. 25–31) replaces the visible set around the lobe axis by a hemisphere whose boundary
passes ``θd`` away from it. That is right for a sharp lobe near an occluder's edge and wrong for the
broad lobes of a sky: a floor point beside a ball sees the ball as a small cap, but the model cuts
the broad lobe by a whole great circle — the contact shadow comes out 5–15 % too dark (per-lobe
errors up to 0.14–0.37 against ray-cast visibility, on the sphere-on-floor scene under a real HDRI).
The vertex has its whole SSDF map, so the cache integrates it instead::

    V[v, j] = 1 − Σ_t (1 − s_t) (n_v·d_t) G_j(d_t) Ω_t / ∫ G_j(i) max(n_v·i, 0) di

over the R×R equal-area texels ``d_t`` of the vertex's hemisphere (``Ω_t = 2π/R²``), with the
texel's visible share ``s_t = clamp(½ + θd_t/h, 0, 1)`` from its SSDF value (the signed angular
distance to the visibility boundary; ``h = √(2π)/R``, the texel side) and the denominator the
lobe's exact cosine-weighted mass (``warp_sg.sg.irradiance``). Only texels inside the vertex's
occluder cone are read (``precompute.visibility.occluder_cone``; a vertex with none is 1 without a read). On the
same scene the per-lobe errors drop to 0.01–0.06 (mean ≤ 0.01; ``tests/test_vertex_visibility.py``
checks against ray casts). The per-pixel path (``visibility_sampling = "pixel"``) keeps the
hemisphere model.

The array is rebuilt only when the lobe axes or sharpnesses change (environment rotation, a new
fit) or the visibility data does; an environment scale, material, light or camera edit reuses it.

**Lights** (:func:`light_vertex_deficit`): per vertex and light the SSDF *deficit*
``min(θd_v(l_v) − θh_v(l_v), 0)`` towards the light (direction ``l_v`` from the vertex, read in the
vertex's own frame; 0 where the occluder cone is clear, ``precompute.visibility.occluder_cone``). The shading
kernel takes ``θd = θh + Σ_k b_k deficit_k`` with the pixel's own ``θh = asin(l·n)`` and the usual
``fh(θd, λ)/fh(θh, λ)``: the SSDF is interpolated as in the paper (so a sharp shadow edge falls
where the interpolated SSDF crosses zero, inside a triangle), an unoccluded point is exactly lit,
and each vertex is read towards the light as seen from that vertex. Rebuilt when a light moves or
changes size.

**The diffuse environment term** (:func:`env_vertex_visible`): with ρd = kd/π it is ``ρd E(n) F``,
``E`` the exact irradiance of the residual map (``precompute.environment.irradiance``) and ``F`` (RGB) the
visible fraction of it, which needs no SG mixture at all: per vertex the same quadrature weighs the
texels' visible shares by the map's own radiance at texel scale (``L̄``, a 64 × 128 box-filtered
copy of the residual), ``F = 1 − O/(O + S + max(E − O − S, 0))`` with ``O``, ``S`` the occluded and
the visible cosine-weighted radiance of the texels in the occluder cone (those outside it are
visible: ``E − O − S``). It is 1 where nothing occludes the vertex and exactly 0 where everything
does. The shading kernel takes ``E`` per pixel at the shading normal and ``F`` interpolated from the
vertices (``Σ_k b_k F[i_k]``): no lobe loop. Rebuilt on environment rotation or with the visibility
data; an environment scale edit changes nothing (``E`` carries the scale).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import warp as wp

from precompute.environment.irradiance import irradiance_unscaled
from precompute.visibility.ssdf_wp import ssdf_eval_vertex, texel_direction_array, world_to_local
from warp_sg.numeric.fastmath import fast_asin
from warp_sg.numeric.onb import local_to_world
from warp_sg.scene.envmap import env_lookup
from warp_sg.scene.lights import LightArrays, light_irradiance
from warp_sg.scene.render_settings import uses_sigmoid
from warp_sg.sg.algebra_wp import sg_integral
from warp_sg.sg.irradiance import sg_irradiance_norm_at
from warp_sg.shading.visibility_terms import (
    EnvSG,
    Visibility,
    lookup_skip,
    vertex_frame,
    vertex_light_pair,
    vertex_point,
)

_SQRT_2PI = wp.constant(float(np.sqrt(2.0 * np.pi)))


@wp.func
def texel_ssdf(vis: Visibility, v: int, y: int, x: int) -> float:
    """Vertex v's SSDF at texel (row y, column x) of its R×R map (PCA or decompressed form)."""
    nv = vis.basis.shape[2]
    if nv == 0:  # decompressed maps (SSDFData.device_arrays)
        return vis.weights[v, y * vis.mean.shape[0] + x]
    sd = vis.mean[y, x]
    for k in range(nv):
        sd += vis.weights[v, k] * vis.basis[y, x, k]
    return sd


@wp.func
def _vertex_id(k: int, ids: wp.array(dtype=int)) -> int:
    """The vertex of thread ``k = base + tid``: k itself, or entry k of ``ids`` when given."""
    v = k
    if ids.shape[0] > 0:
        v = ids[v]
    return v


@wp.func
def cone_in_frame(cone: wp.vec4, t: wp.vec3, b: wp.vec3, n: wp.vec3, h: float):
    """The occluder cone in the vertex's frame ``(t, b, n)``: its axis there and the cosine a texel's
    local direction must reach to be read (the half-angle widened by ``h``, the texel's half
    diagonal). Every per-vertex quadrature over the cone's texels tests them so (these kernels and
    ``warp_sg.shading.sky_table.transfer_kernel``): the same texels."""
    axis = wp.vec3(cone[0], cone[1], cone[2])
    return wp.vec3(wp.dot(axis, t), wp.dot(axis, b), wp.dot(axis, n)), wp.cos(wp.min(cone[3] + h, wp.pi))


@wp.kernel(enable_backward=False)
def env_vertex_visibility_kernel(base: int, ids: wp.array(dtype=int), irr: wp.array2d(dtype=float), vis: Visibility,
                                 env: EnvSG, dirs: wp.array(dtype=wp.vec3), out: wp.array2d(dtype=float)):
    """``out[v, j]`` = the visible fraction of the cosine-weighted lobe ``G_j max(n_v·i, 0)`` at vertex
    ``v = base + tid``, by quadrature of its SSDF over the R×R equal-area texels (module
    docstring): ``1 − Σ_t (1 − s_t) (n·d_t) G_j(d_t) Ω / (∫G_j e(n·p_j, λ_j))``, ``s_t =
    clamp(½ + θd_t/h, 0, 1)`` the texel's visible share from its SSDF value (h = the texel side).
    Only texels inside the vertex's occluder cone are read; a vertex with no occluder is 1. With
    ``ids`` (non-empty) thread k computes vertex ``ids[base + k]`` only; ``dirs``: the R² texel
    directions of the maps (``ssdf_wp.texel_direction_array``)."""
    v = _vertex_id(base + wp.tid(), ids)
    nj = out.shape[1]
    n = wp.normalize(vis.normals[v])
    for j in range(nj):
        out[v, j] = 0.0
    cone = vis.cones[v]
    if cone[3] >= 0.0:  # something occludes this vertex: integrate its occluded texels
        t, b = vertex_frame(vis, v, n)
        R = vis.mean.shape[0]
        h = _SQRT_2PI / float(R)
        om = 2.0 * wp.pi / float(R * R)
        axis_l, c_min = cone_in_frame(cone, t, b, n, h)
        for y in range(R):
            for x in range(R):
                dl = dirs[y * R + x]
                if wp.dot(dl, axis_l) >= c_min:
                    occ = 1.0 - wp.clamp(0.5 + texel_ssdf(vis, v, y, x) / h, 0.0, 1.0)
                    if occ > 0.0:
                        d = local_to_world(dl, t, b, n)
                        wgt = occ * dl[2] * om
                        for j in range(nj):
                            out[v, j] += wgt * wp.exp(env.lam[j] * (wp.dot(d, env.axis[j]) - 1.0))
    for j in range(nj):
        full = sg_integral(env.lam[j]) * sg_irradiance_norm_at(irr, wp.dot(n, env.axis[j]), env.lam[j],
                                                                env.irr_row[j])
        f = float(1.0)
        if full > 0.0:
            f = wp.clamp(1.0 - out[v, j] / full, 0.0, 1.0)
        out[v, j] = f


@wp.kernel(enable_backward=False)
def light_vertex_deficit_kernel(base: int, ids: wp.array(dtype=int), fh_mode: int, vis: Visibility,
                                positions: wp.array(dtype=wp.vec3), lights: LightArrays, out: wp.array2d(dtype=float)):
    """``out[v, j] = min(θd_v(l_v) − θh_v(l_v), 0)``: vertex v's SSDF towards light j (direction
    ``l_v`` from the vertex) less its horizon value ``asin(l_v·n_v)`` — 0 where no occluder is
    closer than the horizon (and where the occluder cone is clear: no lookup). θd is read in the
    frame the vertex's map is stored in (:func:`vertex_frame`: a moving vertex's turned frame), one
    lookup of its own weights (``ssdf_eval_vertex``, with the below-horizon rule)."""
    vj = vertex_light_pair(base + wp.tid(), ids, out.shape[1])
    v = vj[0]
    j = vj[1]
    n = wp.normalize(vis.normals[v])
    la, ll, E = light_irradiance(lights, j, positions[v])
    q = vertex_point(v, n)  # the vertex alone, for the occluder-cone test
    th_h = fast_asin(wp.clamp(wp.dot(la, n), -1.0, 1.0))
    s = lookup_skip(fh_mode, vis, q, la, th_h, ll)
    d = float(0.0)
    if s < 1.0:
        t, b = vertex_frame(vis, v, n)
        th = ssdf_eval_vertex(vis.mean, vis.basis, vis.weights, v, world_to_local(la, t, b, n))
        d = (1.0 - s) * wp.min(th - th_h, 0.0)
    out[v, j] = d


@wp.func
def visible_share(occ_sum: wp.vec3, seen_sum: wp.vec3, ex: wp.vec3, cone: wp.vec4, n: wp.vec3, h: float) -> wp.vec3:
    """``F = 1 − O/(O + S + max(E − O − S, 0))`` per channel (:func:`env_vertex_visible_kernel`)
    from the cone's occluded and visible sums ``O``, ``S`` and the exact irradiance ``E``; the
    texels outside the cone count as visible unless the cone (its half-angle grown by the texel
    side ``h``) holds the whole hemisphere of ``n``."""
    axis = wp.vec3(cone[0], cone[1], cone[2])
    outside = float(1.0)
    if wp.acos(wp.clamp(wp.dot(axis, n), -1.0, 1.0)) + 0.5 * wp.pi <= cone[3] + h:
        outside = 0.0
    f = wp.vec3(1.0, 1.0, 1.0)
    for c in range(3):
        tot = occ_sum[c] + seen_sum[c] + outside * wp.max(ex[c] - occ_sum[c] - seen_sum[c], 0.0)
        if tot > 0.0:
            f[c] = wp.clamp(1.0 - occ_sum[c] / tot, 0.0, 1.0)
    return f


@wp.kernel(enable_backward=False)
def env_vertex_visible_kernel(base: int, ids: wp.array(dtype=int), vis: Visibility, env: EnvSG,
                              dirs: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3),
                              out_irr: wp.array(dtype=wp.vec3)):
    """``out[v]`` = the visible fraction (RGB) of vertex ``v = base + tid``'s diffuse irradiance:
    ``1 − O/(O + S + max(E − O − S, 0))`` with ``O``, ``S`` the occluded and the visible parts of
    ``Σ_t (n·d_t) L̄(d_t) Ω_t`` over the texels inside the vertex's occluder cone (the texel's
    visible share ``s_t = clamp(½ + θd_t/h, 0, 1)``, ``L̄`` the residual map's radiance at texel
    scale, ``env.radiance``) and ``E`` the exact irradiance (``env.exact`` at unit scale): the texels
    outside the cone are visible (none when the cone holds the whole hemisphere). 1 without a read
    where nothing occludes the vertex; exactly 0 where everything does. ``out_irr[v] = E ∘ F``, the
    visible irradiance at unit scale (what smooth triangles interpolate). ``ids``: as in
    :func:`env_vertex_visibility_kernel`; ``dirs``: the R² texel directions of the maps
    (``ssdf_wp.texel_direction_array``)."""
    v = _vertex_id(base + wp.tid(), ids)
    n = wp.normalize(vis.normals[v])
    cone = vis.cones[v]
    f = wp.vec3(1.0, 1.0, 1.0)
    ex = irradiance_unscaled(env.exact, n)
    if cone[3] >= 0.0:
        t, b = vertex_frame(vis, v, n)
        R = vis.mean.shape[0]
        h = _SQRT_2PI / float(R)
        om = 2.0 * wp.pi / float(R * R)
        # the cone test in the vertex's frame, and one matrix from it to the map's (no world direction)
        axis_l, c_min = cone_in_frame(cone, t, b, n, h)
        to_map = env.exact.to_env * wp.matrix_from_cols(t, b, n)
        occ_sum = wp.vec3(0.0, 0.0, 0.0)
        seen_sum = wp.vec3(0.0, 0.0, 0.0)
        for y in range(R):
            for x in range(R):
                dl = dirs[y * R + x]
                if wp.dot(dl, axis_l) >= c_min:
                    s = wp.clamp(0.5 + texel_ssdf(vis, v, y, x) / h, 0.0, 1.0)
                    e = env_lookup(env.radiance, to_map, dl) * (dl[2] * om)
                    occ_sum += e * (1.0 - s)
                    seen_sum += e * s
        f = visible_share(occ_sum, seen_sum, ex, cone, n, h)
    out[v] = f
    out_irr[v] = wp.cw_mul(ex, f)


@wp.kernel(enable_backward=False)
def blend_rows_kernel(base: int, index: wp.array2d(dtype=int), weight: wp.array2d(dtype=float),
                      rows: wp.array2d(dtype=float)):
    """``rows[v] = Σ_k weight[v, k] rows[index[v, k]]`` for every vertex ``v = base + tid`` that is
    not a representative (``index[v, 0] ≠ v``): the representatives' rows, blended as the vertex's
    SSDF was (``precompute.visibility.representatives``); a representative's row is kept."""
    v = base + wp.tid()
    if index[v, 0] != v:
        for j in range(rows.shape[1]):
            s = float(0.0)
            for k in range(index.shape[1]):
                s += weight[v, k] * rows[index[v, k], j]
            rows[v, j] = s


@wp.kernel(enable_backward=False)
def blend_visible_kernel(base: int, index: wp.array2d(dtype=int), weight: wp.array2d(dtype=float), vis: Visibility,
                         env: EnvSG, out: wp.array(dtype=wp.vec3), out_irr: wp.array(dtype=wp.vec3)):
    """:func:`blend_rows_kernel` for the visible fraction ``F`` of the diffuse irradiance
    (:func:`env_vertex_visible_kernel`), then ``out_irr[v] = E(n_v) ∘ F[v]`` at the vertex's own
    normal."""
    v = base + wp.tid()
    if index[v, 0] != v:
        f = wp.vec3(0.0, 0.0, 0.0)
        for k in range(index.shape[1]):
            f += weight[v, k] * out[index[v, k]]
        out[v] = f
        out_irr[v] = wp.cw_mul(irradiance_unscaled(env.exact, wp.normalize(vis.normals[v])), f)


def _blend(ssdf, n_vertices: int, device):
    """``SSDFData.blend_arrays`` when the SSDFs of these vertices were computed at representatives
    (the caches are then computed there and blended), else None."""
    b = ssdf.blend_arrays(device) if hasattr(ssdf, "blend_arrays") else None
    return b if b is not None and int(b[1].shape[0]) == int(n_vertices) else None


def _blended(bl, build, blend_kernel, inputs, n_vertices, device):
    """``build(ids)`` at the representatives, then ``blend_kernel`` over every vertex (``bl``: :func:`_blend`)."""
    from raster import parallel

    out = build(bl[0])
    parallel.launch(blend_kernel, int(n_vertices), [bl[1], bl[2], *inputs(out)], device, min_chunk=4096)
    return out


def _ids(ids, device):
    """(the id array, its length) for the kernels' ``ids`` argument (empty: every vertex)."""
    if ids is None:
        return wp.zeros(0, dtype=int, device=device), None
    return ids, int(ids.shape[0])


def env_vertex_visible(vis: Visibility, env: EnvSG, n_vertices: int, device, ids=None, into=None):
    """``(F, E ∘ F)``: the (V,) vec3 arrays of :func:`env_vertex_visible_kernel` (one thread per
    vertex). ``ids`` (a device int array) with ``into`` (an earlier ``(F, E ∘ F)``): recompute only
    those vertices' rows, in place."""
    from raster import parallel

    ida, n = _ids(ids, device)
    if into is None:
        into = (wp.zeros(max(int(n_vertices), 1), dtype=wp.vec3, device=device),
                wp.zeros(max(int(n_vertices), 1), dtype=wp.vec3, device=device))
    n = int(n_vertices) if n is None else n
    if n > 0:
        dirs = texel_direction_array(int(vis.mean.shape[0]), device)
        parallel.launch(env_vertex_visible_kernel, n, [ida, vis, env, dirs, *into], device, min_chunk=64)
    return into


#: the largest angle between the vertex normals of a triangle whose diffuse environment term is
#: interpolated from its vertices' visible irradiance (``E ∘ F``) instead of reading the exact
#: irradiance at each pixel's normal: 5°, where interpolating E errs by ≈ (5°)²/8 ≈ 0.1 % (0.4 % of
#: the brightest pixel on a torus under a sky whose sun is left in the map, tests/test_env_diffuse.py)
SMOOTH_TRIANGLE_DEG = 5.0


def smooth_triangles(normals, triangles) -> np.ndarray:
    """(T,) uint8: 1 where the triangle's vertex normals are within :data:`SMOOTH_TRIANGLE_DEG`."""
    n = np.asarray(normals, np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    if not len(t):
        return np.zeros(1, np.uint8)
    a, b, c = n[t[:, 0]], n[t[:, 1]], n[t[:, 2]]
    cmin = np.minimum(np.minimum(np.sum(a * b, 1), np.sum(b * c, 1)), np.sum(a * c, 1))
    return (cmin >= np.cos(np.radians(SMOOTH_TRIANGLE_DEG))).astype(np.uint8)


def light_vertex_deficit(vis: Visibility, positions, lights: LightArrays, n_vertices: int, fh_sigmoid: bool,
                         device, ids=None, into=None) -> wp.array2d:
    """(V, lights) array of :func:`light_vertex_deficit_kernel` (element ``v·lights + j``; CPU:
    thread pool); (1, 1) zeros when there is nothing to compute. ``ids``/``into``: as in
    :func:`env_vertex_visible`."""
    from raster import parallel

    ida, n = _ids(ids, device)
    out = wp.zeros((max(int(n_vertices), 1), max(int(lights.count), 1)), dtype=float, device=device) \
        if into is None else into
    n = int(n_vertices) if n is None else n
    if lights.count > 0 and n > 0:
        parallel.launch(light_vertex_deficit_kernel, n * int(lights.count),
                        [ida, 1 if fh_sigmoid else 0, vis, positions, lights, out], device, min_chunk=1024,
                        chunks=2 * parallel.cpu_workers())  # (each range costs a dispatch and its arguments' packing)
    return out


def env_vertex_visibility(irr, vis: Visibility, env: EnvSG, n_vertices: int, device, ids=None,
                          into=None) -> wp.array2d:
    """(V, J) array of :func:`env_vertex_visibility_kernel` (one thread per vertex); ``ids``/``into``:
    as in :func:`env_vertex_visible`."""
    from raster import parallel

    ida, n = _ids(ids, device)
    out = wp.zeros((max(int(n_vertices), 1), max(int(env.count), 1)), dtype=float, device=device) \
        if into is None else into
    n = int(n_vertices) if n is None else n
    if env.count > 0 and n > 0:
        dirs = texel_direction_array(int(vis.mean.shape[0]), device)
        parallel.launch(env_vertex_visibility_kernel, n, [ida, irr, vis, env, dirs, out], device, min_chunk=64)
    return out


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
    (default a (1, 1) float array: the argument of the kernel variant without the cache). ``builds`` counts rebuilds;
    ``seconds`` is the time the
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


def caches() -> tuple:
    """The renderer's three caches: environment lobes' visibility, lights' deficit, and the visible
    fraction of the diffuse environment irradiance."""
    return VertexCache(), VertexCache(), VertexCache(lambda d: (wp.zeros(1, dtype=wp.vec3, device=d),
                                                                wp.zeros(1, dtype=wp.vec3, device=d)))


@dataclass(frozen=True)
class CacheInputs:
    """What the per-vertex caches read of a renderer's resources, passed explicitly
    (:meth:`warp_sg.renderer.resources.ResourceSetup.cache_inputs` builds it for each frame).

    ``env_key``: the key of the environment's kernel arrays, ``(lobes, rotation, scale, geometry)``
    or None without an environment; its first two entries decide the lobe axes. ``vis``: the
    shading visibility, whose ``light_deficit`` :func:`update_caches` sets."""

    device: str
    n_vertices: int
    fh: str
    ssdf: object
    vis: Visibility
    irr_table: object
    positions: object
    shading_lights: tuple
    light_arrays: LightArrays
    env_key: tuple | None
    env_scale: float
    #: the static objects' triangles for the lights' ray-cast deficits (:mod:`warp_sg.shading.light_rays`);
    #: None: the SSDF's deficits (:func:`light_vertex_deficit`)
    occluders: object = None


def update_caches(caches: tuple, inputs: CacheInputs, f, es: EnvSG) -> tuple[EnvSG, float]:
    """Bring the per-vertex caches ``caches = (lobes, lights, visible)`` (:func:`caches`) up to
    date for the kernel variant ``f`` (its :class:`~warp_sg.shading.kernel.Features`) and attach
    them to the shading arguments:

    * ``es.vis`` (``lobes``), each environment lobe's visible fraction (the lobe path: Oren–Nayar
      materials): rebuilt when the lobe axes (rotation, fit) or the visibility data change;
    * ``inputs.vis.light_deficit`` (``lights``), each light's SSDF deficit: rebuilt when a light
      moves or is resized (not on an intensity or environment-scale edit);
    * ``es.visible``, ``es.irr_vertex`` (``visible``), the visible fraction of each vertex's diffuse
      environment irradiance and that visible irradiance at unit scale: rebuilt on environment
      rotation or with the visibility data (``es.irr_scale`` is the scale).

    SSDFs computed at representative vertices (``precompute.visibility.representatives``:
    ``SSDFData.blend_arrays``): the lobes' and the diffuse visible fractions are computed at the
    representatives only and the other vertices' rows are their blend weights' combination of
    those rows (:func:`blend_rows_kernel`, :func:`blend_visible_kernel`; the irradiance ``E`` at
    the vertex's own normal), as their maps were blended; the light deficits (one lookup per
    vertex and light) are read at every vertex from its own, transferred map: a blend of the
    representatives' deficits moves a small light's shadow edge (a glint on its edge darkened).

    Camera and material edits reuse all three. Returns ``es`` and this call's rebuild seconds."""
    env_vis, light_vis, env_visible = caches
    r = inputs
    d, nv, sigmoid = r.device, r.n_vertices, uses_sigmoid(r.fh)
    bl = _blend(r.ssdf, nv, d)  # SSDFs at representatives: the quadratures there, then blended

    def env_lobes():
        if bl is None:
            return env_vertex_visibility(r.irr_table, r.vis, es, nv, d)
        return _blended(bl, lambda ids: env_vertex_visibility(r.irr_table, r.vis, es, nv, d, ids=ids),
                        blend_rows_kernel, lambda o: [o], nv, d)

    def deficit():  # (every vertex from its own map, transferred or not: one lookup per light)
        if r.occluders is not None:  # exact at the vertices: rays over each light's cone
            from warp_sg.shading.light_rays import light_vertex_rays

            into = None if r.occluders.static_vertices is None else \
                light_vertex_deficit(r.vis, r.positions, r.light_arrays, nv, sigmoid, d)  # (moving vertices)
            return light_vertex_rays(r.occluders, r.vis, r.positions, r.light_arrays, nv, sigmoid, d, into=into)
        return light_vertex_deficit(r.vis, r.positions, r.light_arrays, nv, sigmoid, d)

    def visible():
        if bl is None:
            return env_vertex_visible(r.vis, es, nv, d)
        return _blended(bl, lambda ids: env_vertex_visible(r.vis, es, nv, d, ids=ids), blend_visible_kernel,
                        lambda o: [r.vis, es, *o], nv, d)

    key = (r.env_key[:2], r.ssdf, r.vis.cones) if f.env_vis_vertex else None
    es.vis = env_vis.array(key, env_lobes, d)
    where = tuple((li.type, *np.ravel(getattr(li, "position", getattr(li, "direction", ()))).tolist(),
                   float(li.radius)) for li in r.shading_lights)
    key = (where, r.ssdf, r.vis.cones, r.fh, r.occluders) if f.light_vis_vertex else None
    r.vis.light_deficit = light_vis.array(key, deficit, d)
    key = (r.env_key[:2], r.ssdf, r.vis.cones) if f.env_visible_vertex else None
    es.visible, es.irr_vertex = env_visible.array(key, visible, d)
    es.irr_scale = r.env_scale
    return es, sum(c.seconds for c in caches)


__all__ = ["cone_in_frame", "blend_rows_kernel", "blend_visible_kernel", "VertexCache", "CacheInputs", "caches",
           "update_caches", "env_vertex_visible", "env_vertex_visible_kernel",
           "smooth_triangles", "SMOOTH_TRIANGLE_DEG",
           "env_vertex_visibility", "env_vertex_visibility_kernel", "light_vertex_deficit",
           "light_vertex_deficit_kernel"]
