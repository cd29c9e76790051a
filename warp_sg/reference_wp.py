r"""Kernel side of the Monte-Carlo reference (:mod:`warp_sg.reference`, which documents the light
transport and re-exports these names): the :class:`LightTable` and :class:`Geometry` structs, the
per-sample MIS estimator ``_shade_sample`` (light sampling + BRDF sampling, power heuristic, exact
``wp.Mesh`` shadow rays) and the ``_reference_pass`` kernel (primary ray, surface, ``spp``
samples per pixel).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import warp as wp

from . import sampling as S
from .brdf import material_wp as M  # contract: Material, brdf_eval, brdf_sample, brdf_pdf
from .frames import local_to_world, world_to_local
from .surface import MaterialTextures, apply_shading_maps, tangent_in_plane, textured_material

LIGHT_POINT = 0
LIGHT_DIRECTIONAL = 1


# --------------------------------------------------------------------------------------------
# Kernel
# --------------------------------------------------------------------------------------------
@wp.struct
class LightTable:
    count: int
    kind: wp.array(dtype=int)  # LIGHT_POINT | LIGHT_DIRECTIONAL
    pos: wp.array(dtype=wp.vec3)  # point: position; directional: unit direction *towards* the light
    radius: wp.array(dtype=float)  # point: sphere radius; directional: angular radius (rad)
    radiance: wp.array(dtype=wp.vec3)  # r > 0: emitted radiance Le; r = 0: s (point) or E (directional)
    omc: wp.array(dtype=float)  # directional: 1 - cos r (points: computed per shading point)


@wp.struct
class Geometry:
    mesh: wp.uint64
    indices: wp.array(dtype=int)  # 3T
    normals: wp.array(dtype=wp.vec3)  # V (shading normals, per vertex)
    has_normals: int
    uvs: wp.array(dtype=wp.vec2)  # V
    tangents: wp.array(dtype=wp.vec3)  # V
    has_tangents: int
    tri_material: wp.array(dtype=int)  # T
    eps: float  # shadow-ray offset (world units)


@wp.func
def _occluded(geo: Geometry, p: wp.vec3, ng: wp.vec3, d: wp.vec3, max_t: float) -> bool:
    """True when the segment from ``p`` along ``d`` (length ``max_t``) hits the mesh.

    A direction below the geometric surface is blocked by the surface itself.
    """
    s = wp.dot(d, ng)
    if s <= 0.0:
        return True
    q = wp.mesh_query_ray(geo.mesh, p + ng * geo.eps, d, max_t)
    return q.result


@wp.func
def _trace(geo: Geometry, p: wp.vec3, ng: wp.vec3, d: wp.vec3) -> float:
    """Distance to the first mesh hit along ``d`` (1e30 if none; 0 if below the surface)."""
    if wp.dot(d, ng) <= 0.0:
        return 0.0
    q = wp.mesh_query_ray(geo.mesh, p + ng * geo.eps, d, 1.0e30)
    if q.result:
        return q.t
    return 1.0e30


@wp.func
def _mix_prob(mat: M.Material) -> float:
    """Probability of choosing the cosine (diffuse) strategy for the BRDF sample."""
    ld = M.lum(mat.kd)
    ls = M.lum(mat.ks)
    if ls <= 0.0:
        return 1.0
    if ld <= 0.0:
        return 0.0
    return wp.clamp(ld / (ld + ls), 0.1, 0.9)


@wp.func
def _brdf_pdf(mat: M.Material, pd: float, o: wp.vec3, i: wp.vec3) -> float:
    if i[2] <= 0.0:
        return 0.0
    p = float(0.0)
    if pd > 0.0:
        p = pd * i[2] * S.INV_PI
    if pd < 1.0:
        p = p + (1.0 - pd) * M.brdf_pdf(mat, o, i)
    return p


@wp.func
def _shade_sample(
    geo: Geometry,
    mat: M.Material,
    env: S.EnvSampler,
    lights: LightTable,
    p: wp.vec3,
    ng: wp.vec3,
    n: wp.vec3,
    t: wp.vec3,
    b: wp.vec3,
    o: wp.vec3,
    state: wp.uint32,
) -> wp.vec3:
    """One MIS sample of the reflected radiance at ``p`` towards local view ``o``."""
    L = wp.vec3(0.0)
    pd = _mix_prob(mat)

    # ---- light sampling -------------------------------------------------------------------
    if env.present != 0:
        d = S.env_sample(env, wp.randf(state), wp.randf(state), wp.randf(state), wp.randf(state))
        il = world_to_local(d, t, b, n)
        if il[2] > 0.0:
            f = M.brdf_eval(mat, o, il)
            if f[0] + f[1] + f[2] > 0.0:
                if not _occluded(geo, p, ng, d, 1.0e30):
                    pl = S.env_pdf(env, d)
                    w = S.power_heuristic(pl, _brdf_pdf(mat, pd, o, il))
                    L += wp.cw_mul(S.env_radiance(env, d), f) * (il[2] * w / pl)
    for k in range(lights.count):
        kind = lights.kind[k]
        r = lights.radius[k]
        u1 = wp.randf(state)
        u2 = wp.randf(state)
        if kind == LIGHT_POINT:
            rel = lights.pos[k] - p
            dist2 = wp.dot(rel, rel)
            dist = wp.sqrt(dist2)
            if r <= 0.0:
                if dist2 < 1.0e-30:
                    continue  # a delta light on the surface: undefined, contributes nothing
                d = rel / dist
                il = world_to_local(d, t, b, n)
                if il[2] > 0.0:
                    if not _occluded(geo, p, ng, d, dist * (1.0 - 1.0e-5)):
                        L += wp.cw_mul(lights.radiance[k], M.brdf_eval(mat, o, il)) * (il[2] / dist2)
            else:
                omc = float(2.0)
                if dist2 > r * r:
                    omc = S.cone_omc(r * r / dist2)
                axis = n
                if dist2 > 1.0e-30:
                    axis = rel / dist
                d = S.cone_sample(axis, omc, u1, u2)
                il = world_to_local(d, t, b, n)
                if il[2] > 0.0:
                    f = M.brdf_eval(mat, o, il)
                    if f[0] + f[1] + f[2] > 0.0:
                        th = S.sphere_hit_distance(rel, r, d)
                        if th < 0.0:
                            th = dist  # grazing the silhouette in float32
                        if not _occluded(geo, p, ng, d, th * (1.0 - 1.0e-5)):
                            pl = S.cone_pdf(omc)
                            w = S.power_heuristic(pl, _brdf_pdf(mat, pd, o, il))
                            L += wp.cw_mul(lights.radiance[k], f) * (il[2] * w / pl)
        else:
            axis = lights.pos[k]
            if r <= 0.0:
                il = world_to_local(axis, t, b, n)
                if il[2] > 0.0:
                    if not _occluded(geo, p, ng, axis, 1.0e30):
                        L += wp.cw_mul(lights.radiance[k], M.brdf_eval(mat, o, il)) * il[2]
            else:
                omc = lights.omc[k]
                d = S.cone_sample(axis, omc, u1, u2)
                il = world_to_local(d, t, b, n)
                if il[2] > 0.0:
                    f = M.brdf_eval(mat, o, il)
                    if f[0] + f[1] + f[2] > 0.0:
                        if not _occluded(geo, p, ng, d, 1.0e30):
                            pl = S.cone_pdf(omc)
                            w = S.power_heuristic(pl, _brdf_pdf(mat, pd, o, il))
                            L += wp.cw_mul(lights.radiance[k], f) * (il[2] * w / pl)

    # ---- BRDF sampling --------------------------------------------------------------------
    us = wp.randf(state)
    u1 = wp.randf(state)
    u2 = wp.randf(state)
    ib = wp.vec3(0.0, 0.0, 1.0)
    if us < pd:
        ib = S.cosine_sample_local(u1, u2)
    else:
        ib = M.brdf_sample(mat, o, wp.vec2(u1, u2))
    if ib[2] > 0.0:
        pb = _brdf_pdf(mat, pd, o, ib)
        if pb > 0.0:
            f = M.brdf_eval(mat, o, ib)
            if f[0] + f[1] + f[2] > 0.0:
                fw = f * (ib[2] / pb)
                d = wp.normalize(local_to_world(ib, t, b, n))
                tm = _trace(geo, p, ng, d)
                if tm > 0.0:
                    if env.present != 0 and tm >= 1.0e30:
                        w = S.power_heuristic(pb, S.env_pdf(env, d))
                        L += wp.cw_mul(S.env_radiance(env, d), fw) * w
                    for k in range(lights.count):
                        r = lights.radius[k]
                        if r > 0.0:
                            if lights.kind[k] == LIGHT_POINT:
                                rel = lights.pos[k] - p
                                th = S.sphere_hit_distance(rel, r, d)
                                if th >= 0.0 and th < tm:
                                    dist2 = wp.dot(rel, rel)
                                    omc = float(2.0)
                                    if dist2 > r * r:
                                        omc = S.cone_omc(r * r / dist2)
                                    w = S.power_heuristic(pb, S.cone_pdf(omc))
                                    L += wp.cw_mul(lights.radiance[k], fw) * w
                            else:
                                omc = lights.omc[k]
                                if tm >= 1.0e30 and S.in_cone(lights.pos[k], omc, d):
                                    w = S.power_heuristic(pb, S.cone_pdf(omc))
                                    L += wp.cw_mul(lights.radiance[k], fw) * w
    return L


@wp.kernel
def _reference_pass(
    geo: Geometry,
    materials: wp.array(dtype=M.Material),
    tex: MaterialTextures,
    env: S.EnvSampler,
    lights: LightTable,
    origins: wp.array(dtype=wp.vec3),
    dirs: wp.array(dtype=wp.vec3),
    background: int,
    bg_image: wp.array(dtype=wp.vec3),
    spp: int,
    seed: int,
    sample_offset: int,
    offset: int,
    out_sum: wp.array(dtype=wp.vec3),
    out_sq: wp.array(dtype=wp.vec3),
):
    tid = wp.tid() + offset
    ro = origins[tid]
    rd = dirs[tid]
    q = wp.mesh_query_ray(geo.mesh, ro, rd, 1.0e30)
    if not q.result:
        bg = wp.vec3(0.0)
        if background == 1:
            bg = S.env_radiance(env, rd)
        elif background == 2:
            bg = bg_image[tid]
        out_sum[tid] = bg * float(spp)
        out_sq[tid] = wp.cw_mul(bg, bg) * float(spp)
        return
    f = q.face
    i0 = geo.indices[3 * f]
    i1 = geo.indices[3 * f + 1]
    i2 = geo.indices[3 * f + 2]
    # Warp: position = u v0 + v v1 + (1 - u - v) v2
    b0 = q.u
    b1 = q.v
    b2 = 1.0 - q.u - q.v
    p = ro + rd * q.t
    ng = wp.normalize(q.normal)  # geometric normal (winding order)
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
    # texels and shading frame exactly as the renderer (warp_sg.surface); all-(−1) slots are a no-op
    uv = b0 * geo.uvs[i0] + b1 * geo.uvs[i1] + b2 * geo.uvs[i2]
    mat = textured_material(mat, tex, mi, uv)
    tg = wp.vec3(0.0)
    if geo.has_tangents != 0:
        tg = b0 * geo.tangents[i0] + b1 * geo.tangents[i1] + b2 * geo.tangents[i2]
    n, t = apply_shading_maps(tex, mi, uv, n, tangent_in_plane(tg, n))
    b = wp.cross(n, t)
    o = world_to_local(-rd, t, b, n)
    acc = wp.vec3(0.0)
    acc2 = wp.vec3(0.0)
    for si in range(spp):
        # one RNG stream per (sample index, pixel); wp.funcs get their own copy of the state
        st0 = wp.rand_init(seed, sample_offset + si)
        state = wp.rand_init(wp.randi(st0), tid)
        L = _shade_sample(geo, mat, env, lights, p, ng, n, t, b, o, state)
        acc += L
        acc2 += wp.cw_mul(L, L)
    out_sum[tid] = acc
    out_sq[tid] = acc2


__all__ = ["LightTable", "Geometry", "LIGHT_POINT", "LIGHT_DIRECTIONAL"]
