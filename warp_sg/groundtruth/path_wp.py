r"""Paths of the Monte-Carlo reference (:mod:`warp_sg.groundtruth.reference`): the surface at a ray's
hit and the pass kernel that follows a path from the camera through ``max_depth`` vertices.

The path (Kajiya 1986; the path tracer of Pharr, Jakob and Humphreys, *PBRT* 4, §13.3, and of
Mitsuba 3's ``path`` integrator, whose depth count this follows): the camera ray's hit is the first
vertex; at every vertex ``x_k`` the estimator of :func:`warp_sg.groundtruth.reference_wp._shade_sample`
adds the light the vertex reflects straight from the lights and the environment (a light sample
and a BRDF sample, MIS-weighted), times the path's throughput ``β``; the BRDF sample's ray, where
it meets the scene, is the next vertex, with ``β ← β f(o, d) cos / p(d)`` (the exact BRDF and
the pdf of the sampling mixture)::

    L = Le(x_1) + Σ_{k ≥ 1} β_k [L_direct(x_k) + Le(x_{k+1})],   β_1 = 1

``max_depth`` counts the segments as Mitsuba does: 1 = what the camera sees emit (emission and
the background), 2 = direct light only (the paper's transport; the renderer's ``[render] bounces
= 0``), ``2 + n`` = n indirect bounces, −1 = no cap (:data:`DEPTH_CAP` as a safety net).
Russian roulette from the third vertex on (``depth ≥`` :data:`RR_DEPTH`): a path goes on with
probability ``q = min(max_c β_c, 0.95)`` and its throughput is divided by ``q`` (unbiased).
Emission met along a path lights what it is seen from (no light sample picks emitting surfaces, so
their light arrives with weight 1 through the BRDF samples).

Random numbers: each (sample, pixel) has one seed; the first vertex's stream is the direct-only
reference's (so ``max_depth = 2`` gives exactly its values), each further vertex draws from a
stream of its own (a ``@wp.func`` gets a copy of its state: a shared stream would repeat numbers).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import warp as wp

from warp_sg.brdf.kernel import material_wp as M
from warp_sg.groundtruth import sampling as S
from warp_sg.groundtruth.reference_wp import Geometry, LightTable, SurfacePoint, _mix_prob, _shade_sample
from warp_sg.numeric.onb import world_to_local
from warp_sg.shading.cutout import first_opaque_hit
from warp_sg.shading.surface import MaterialTextures, apply_shading_maps, tangent_in_plane, textured_material
from warp_sg.shading.surface_layers import (
    Layers,
    coat_at,
    coat_attenuation,
    coat_frame,
    emission_at,
    occlusion_at,
    vertex_coloured,
)

#: the depth from which Russian roulette may end a path (Mitsuba's ``rr_depth`` counts the same way)
RR_DEPTH = wp.constant(4)
#: the most segments a path has when ``max_depth`` is −1 (no cap): Russian roulette ends it long before
DEPTH_CAP = wp.constant(256)
#: the default ``max_depth`` of the reference: a full path tracer (``−1`` lifts the cap; 2 is direct light only)
DEFAULT_MAX_DEPTH = 8


@wp.func
def surface_at(geo: Geometry, materials: wp.array(dtype=M.Material), tex: MaterialTextures, lay: Layers, f: int,
               qu: float, qv: float, rd: wp.vec3, p: wp.vec3, qn: wp.vec3) -> SurfacePoint:
    """The surface point where a ray along ``rd`` meets face ``f`` at ``p`` (Warp's barycentrics
    ``qu``, ``qv``; ``qn`` the face's geometric normal): the material with its textures and vertex
    colours, the shading frame of the normal and tangent maps, the coat, the occlusion and the
    emission, exactly as the renderer shades them (:mod:`warp_sg.shading.surface`)."""
    i0 = geo.indices[3 * f]
    i1 = geo.indices[3 * f + 1]
    i2 = geo.indices[3 * f + 2]
    # Warp: position = u v0 + v v1 + (1 - u - v) v2
    b0 = qu
    b1 = qv
    b2 = 1.0 - qu - qv
    ng = wp.normalize(qn)  # geometric normal (winding order)
    n = ng
    if geo.has_normals != 0:
        ns = b0 * geo.normals[i0] + b1 * geo.normals[i1] + b2 * geo.normals[i2]
        ln = wp.length(ns)
        if ln > 0.0:
            n = ns / ln
    elif wp.dot(ng, rd) > 0.0:
        n = -ng  # no shading normals: two-sided
    if wp.dot(ng, n) < 0.0:
        ng = -ng  # the geometric normal on the side of the shading normal (shadow-ray offsets)
    mi = geo.tri_material[f]
    mat = materials[mi]
    # texels and shading frame exactly as the renderer (warp_sg.shading.surface); all-(−1) slots are a no-op
    uv = b0 * geo.uvs[i0] + b1 * geo.uvs[i1] + b2 * geo.uvs[i2]
    mat = textured_material(mat, tex, mi, uv)
    mat = vertex_coloured(mat, lay, i0, i1, i2, b0, b1, b2)
    tg = wp.vec3(0.0)
    if geo.has_tangents != 0:
        tg = b0 * geo.tangents[i0] + b1 * geo.tangents[i1] + b2 * geo.tangents[i2]
    t0 = tangent_in_plane(tg, n)
    ns_, t = apply_shading_maps(tex, mi, uv, n, t0)
    sp = SurfacePoint()
    sp.p = p
    sp.ng = ng
    sp.mat = mat
    sp.n = ns_
    sp.t = t
    sp.b = wp.cross(ns_, t)
    sp.o = world_to_local(-rd, sp.t, sp.b, sp.n)
    sp.pd = _mix_prob(mat)
    has_coat, cm = coat_at(materials, lay, tex, mi, uv)
    sp.coat = cm
    sp.has_coat = 0
    sp.atten = 1.0
    sp.pc = 0.0
    sp.nc = sp.n
    sp.tc = sp.t
    sp.bc = sp.b
    sp.oc = sp.o
    if has_coat:
        nc, tc = coat_frame(tex, mi, uv, n, t0)
        sp.has_coat = 1
        sp.nc = nc
        sp.tc = tc
        sp.bc = wp.cross(nc, tc)
        sp.oc = world_to_local(-rd, sp.tc, sp.bc, sp.nc)
        sp.atten = coat_attenuation(cm.ks[0], sp.oc[2])
        sp.pc = 0.5 * wp.clamp(cm.ks[0], 0.0, 1.0)
    sp.occ = occlusion_at(tex, mi, uv)
    sp.emit = emission_at(lay, tex, mi, uv) * sp.atten
    return sp


@wp.func
def path_radiance(geo: Geometry, materials: wp.array(dtype=M.Material), tex: MaterialTextures, lay: Layers,
                  env: S.EnvSampler, lights: LightTable, first: SurfacePoint, max_depth: int, seed: int,
                  tid: int) -> wp.vec3:
    """The light a path from the surface point ``first`` brings back along its view, emission of
    ``first`` left out (module docstring): direct light at every vertex up to ``max_depth``
    segments, times the throughput; ``seed``, ``tid``: the (sample, pixel)'s streams."""
    L = wp.vec3(0.0)
    thr = wp.vec3(1.0, 1.0, 1.0)
    sp = first
    depth = int(2)
    state = wp.rand_init(seed, tid)
    while True:
        step = _shade_sample(geo, sp, env, lights, sp.p, sp.ng, state)
        L += wp.cw_mul(thr, step.L)
        if step.hit == 0 or depth >= DEPTH_CAP or (max_depth >= 0 and depth >= max_depth):
            break
        thr = wp.cw_mul(thr, step.fw)
        depth += 1
        state = wp.rand_init(seed ^ (depth * 40503), tid)  # the next vertex's own stream
        if depth >= RR_DEPTH:
            q = wp.min(wp.max(thr[0], wp.max(thr[1], thr[2])), 0.95)
            if wp.randf(state) >= q:
                break
            thr = thr / q
        sp = surface_at(geo, materials, tex, lay, step.face, step.u, step.v, step.d, step.pos, step.n)
        L += wp.cw_mul(thr, sp.emit)
    return L


@wp.kernel(enable_backward=False)  # forward only (no gradients of the reference)
def _reference_pass(
    geo: Geometry,
    materials: wp.array(dtype=M.Material),
    tex: MaterialTextures,
    lay: Layers,
    env: S.EnvSampler,
    lights: LightTable,
    origins: wp.array(dtype=wp.vec3),
    dirs: wp.array(dtype=wp.vec3),
    background: int,
    bg_image: wp.array(dtype=wp.vec3),
    spp: int,
    seed: int,
    sample_offset: int,
    max_depth: int,
    offset: int,
    out_sum: wp.array(dtype=wp.vec3),
    out_sq: wp.array(dtype=wp.vec3),
):
    """``spp`` paths per (sub)pixel ``offset + tid`` (module docstring): the sums of their radiance
    and of its squares into ``out_sum``, ``out_sq``; a camera ray that meets nothing shows the
    background (``background`` 1: the environment, 2: ``bg_image``, 0: black)."""
    tid = wp.tid() + offset
    ro = origins[tid]
    rd = dirs[tid]
    hit, qt, f, qu, qv, qn = first_opaque_hit(geo.camera, geo.cut, ro, rd, 1.0e30)  # (single-sided back faces: not seen)
    if not hit:
        bg = wp.vec3(0.0)
        if background == 1:
            bg = S.env_radiance(env, rd)
        elif background == 2:
            bg = bg_image[tid]
        out_sum[tid] = bg * float(spp)
        out_sq[tid] = wp.cw_mul(bg, bg) * float(spp)
        return
    sp = surface_at(geo, materials, tex, lay, f, qu, qv, rd, ro + rd * qt, qn)
    acc = wp.vec3(0.0)
    acc2 = wp.vec3(0.0)
    for si in range(spp):
        # one RNG stream per (sample index, pixel) and path vertex
        st0 = wp.rand_init(seed, sample_offset + si)
        L = sp.emit
        if max_depth < 0 or max_depth >= 2:
            L = L + path_radiance(geo, materials, tex, lay, env, lights, sp, max_depth, wp.randi(st0), tid)
        acc += L
        acc2 += wp.cw_mul(L, L)
    out_sum[tid] = acc
    out_sq[tid] = acc2


__all__ = ["surface_at", "path_radiance", "RR_DEPTH", "DEPTH_CAP", "DEFAULT_MAX_DEPTH"]
