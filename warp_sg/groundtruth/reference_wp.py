r"""Kernel side of the Monte-Carlo reference (:mod:`warp_sg.groundtruth.reference`, which documents the light
transport and re-exports these names): the :class:`LightTable` and :class:`Geometry` structs and
the estimator of one path vertex, ``_shade_sample`` (light sampling + BRDF sampling, power
heuristic, exact ``wp.Mesh`` shadow rays; the BRDF sample's hit is where the path goes on, a
:class:`PathStep`). The surface at a hit and the pass kernel that follows paths are
:mod:`warp_sg.groundtruth.path_wp`'s.

A surface point (:class:`SurfacePoint`) carries the material's layers as the renderer shades them
(:mod:`warp_sg.shading.surface_layers`): with a clear coat the reflectance times cosine towards a world
direction ``d`` is ``a(o) · f_base(o, i_b) (n·d) + f_coat(o_c, i_c) (n_c·d)`` (each in its own
frame), the environment's share of the diffuse part times the occlusion; the BRDF sample picks
the coat lobe with probability ``c/2``. Camera and shadow rays pass through alpha cut-outs
(:mod:`warp_sg.shading.cutout`); emission is added to every sample of a pixel (it lights nothing else).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import warp as wp

from warp_sg.brdf.kernel import material_wp as M  # contract: Material, brdf_eval, brdf_sample, brdf_pdf
from warp_sg.brdf.models.ggx import GGX
from warp_sg.groundtruth import sampling as S
from warp_sg.numeric.onb import local_to_world, world_to_local
from warp_sg.scene.lights import LIGHT_DIRECTIONAL, LIGHT_POINT
from warp_sg.shading.cutout import Cutouts, blocked, first_opaque_hit

#: the coat is a GGX lobe (warp_sg.scene.material_layers): its functions specialised to that model
_COAT = M.material_funcs({GGX.CODE})
coat_eval = _COAT.brdf_eval


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
    camera: wp.uint64  # what camera rays query: ``mesh`` without the back faces of single-sided objects
    indices: wp.array(dtype=int)  # 3T
    normals: wp.array(dtype=wp.vec3)  # V (shading normals, per vertex)
    has_normals: int
    uvs: wp.array(dtype=wp.vec2)  # V
    tangents: wp.array(dtype=wp.vec3)  # V
    has_tangents: int
    tri_material: wp.array(dtype=int)  # T
    eps: float  # shadow-ray offset (world units)
    cut: Cutouts  # alpha cut-outs (disabled: every hit is opaque)


@wp.struct
class SurfacePoint:
    """A shading point: the base material in its frame (t, b, n) with the local view ``o``, and the
    coat (``has_coat``; material ``coat``, frame (tc, bc, nc), view ``oc``) with the attenuation
    ``atten`` = a(o); ``occ``: the occlusion of the environment's diffuse term; ``pd``: the
    probability of a cosine sample among the base's; ``pc``: of a coat sample; ``p``: the point,
    ``ng``: its geometric normal on the shading normal's side (ray offsets); ``emit``: the
    radiance it emits towards the view (times a(o))."""

    mat: M.Material
    coat: M.Material
    has_coat: int
    t: wp.vec3
    b: wp.vec3
    n: wp.vec3
    o: wp.vec3
    tc: wp.vec3
    bc: wp.vec3
    nc: wp.vec3
    oc: wp.vec3
    atten: float
    occ: float
    pd: float
    pc: float
    p: wp.vec3
    ng: wp.vec3
    emit: wp.vec3


@wp.struct
class PathStep:
    """What one vertex of a path adds (``L``, its light sample and its BRDF sample's light, MIS
    weighted) and where the path goes on: the BRDF sample's direction ``d``, its weight ``fw =
    f cos/pdf`` and its nearest opaque hit (``hit``; ``face``, ``u``, ``v`` Warp's barycentrics,
    ``pos`` the point, ``n`` the triangle's geometric normal)."""

    L: wp.vec3
    d: wp.vec3
    fw: wp.vec3
    hit: int
    face: int
    u: float
    v: float
    pos: wp.vec3
    n: wp.vec3


@wp.func
def _occluded(geo: Geometry, p: wp.vec3, ng: wp.vec3, d: wp.vec3, max_t: float) -> bool:
    """True when the segment from ``p`` along ``d`` (length ``max_t``) hits the mesh (holes of
    alpha cut-outs let it through).

    A direction below the geometric surface is blocked by the surface itself.
    """
    s = wp.dot(d, ng)
    if s <= 0.0:
        return True
    return blocked(geo.mesh, geo.cut, p + ng * geo.eps, d, max_t)


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


#: ``brdf_sample`` / ``brdf_pdf`` of a GGX material (Heitz 2018 visible normals), as the generic ones
_coat_sample = _COAT.brdf_sample
_coat_pdf = _COAT.brdf_pdf


@wp.func
def _pdf(sp: SurfacePoint, d: wp.vec3) -> float:
    """Solid-angle density of the BRDF sample (:func:`_sample`) at world direction ``d``."""
    p = (1.0 - sp.pc) * _brdf_pdf(sp.mat, sp.pd, sp.o, world_to_local(d, sp.t, sp.b, sp.n))
    if sp.has_coat != 0:
        ic = world_to_local(d, sp.tc, sp.bc, sp.nc)
        if ic[2] > 0.0:
            p = p + sp.pc * _coat_pdf(sp.coat, sp.oc, ic)
    return p


@wp.func
def _fcos(sp: SurfacePoint, d: wp.vec3, occ: float):
    """Reflectance and cosine towards world direction ``d`` (module docstring), per layer:
    ``(f_base, a(o) (n·d), f_coat, n_c·d)`` (zero where ``d`` is below a layer's horizon), the base's
    diffuse part times ``occ`` (the occlusion for the environment's light, 1 for local lights)."""
    i = world_to_local(d, sp.t, sp.b, sp.n)
    fb = wp.vec3(0.0)
    cb = float(0.0)
    if i[2] > 0.0:
        fb = M.brdf_eval(sp.mat, sp.o, i)
        if occ < 1.0:
            fb = fb - M.brdf_diffuse(sp.mat, sp.o, i) * (1.0 - occ)
        cb = i[2] * sp.atten
    fc = wp.vec3(0.0)
    cc = float(0.0)
    if sp.has_coat != 0:
        ic = world_to_local(d, sp.tc, sp.bc, sp.nc)
        if ic[2] > 0.0:
            fc = coat_eval(sp.coat, sp.oc, ic)
            cc = ic[2]
    return fb, cb, fc, cc


@wp.func
def _sample(sp: SurfacePoint, us: float, u1: float, u2: float) -> wp.vec3:
    """A world direction from the BRDF mixture: cosine, the base's lobe or the coat's."""
    if us < (1.0 - sp.pc) * sp.pd:
        return wp.normalize(local_to_world(S.cosine_sample_local(u1, u2), sp.t, sp.b, sp.n))
    if us < 1.0 - sp.pc:
        return wp.normalize(local_to_world(M.brdf_sample(sp.mat, sp.o, wp.vec2(u1, u2)), sp.t, sp.b, sp.n))
    return wp.normalize(local_to_world(_coat_sample(sp.coat, sp.oc, wp.vec2(u1, u2)), sp.tc, sp.bc, sp.nc))


@wp.func
def _positive(f: wp.vec3) -> bool:
    return f[0] + f[1] + f[2] > 0.0


@wp.func
def _shade_sample(
    geo: Geometry,
    sp: SurfacePoint,
    env: S.EnvSampler,
    lights: LightTable,
    p: wp.vec3,
    ng: wp.vec3,
    state: wp.uint32,
) -> PathStep:
    """One MIS sample of the light reflected at ``p`` towards the view of ``sp`` from the lights
    and the environment (direct light), and the BRDF sample a path continues with
    (:class:`PathStep`; ``hit`` 0 where the sample leaves the scene or has no weight)."""
    L = wp.vec3(0.0)
    step = PathStep()
    step.hit = 0
    step.face = -1
    step.fw = wp.vec3(0.0)

    # ---- light sampling -------------------------------------------------------------------
    if env.present != 0:
        d = S.env_sample(env, wp.randf(state), wp.randf(state), wp.randf(state), wp.randf(state))
        fb, cb, fk, ck = _fcos(sp, d, sp.occ)
        if _positive(fb) or _positive(fk):
            if not _occluded(geo, p, ng, d, 1.0e30):
                pl = S.env_pdf(env, d)
                w = S.power_heuristic(pl, _pdf(sp, d))
                le = S.env_radiance(env, d)
                L += wp.cw_mul(le, fb) * (cb * w / pl) + wp.cw_mul(le, fk) * (ck * w / pl)
    for k in range(lights.count):
        kind = lights.kind[k]
        r = lights.radius[k]
        u1 = wp.randf(state)
        u2 = wp.randf(state)
        le = lights.radiance[k]
        if kind == LIGHT_POINT:
            rel = lights.pos[k] - p
            dist2 = wp.dot(rel, rel)
            dist = wp.sqrt(dist2)
            if r <= 0.0:
                if dist2 < 1.0e-30:
                    continue  # a delta light on the surface: undefined, contributes nothing
                d = rel / dist
                fb, cb, fk, ck = _fcos(sp, d, 1.0)
                if _positive(fb) or _positive(fk):
                    if not _occluded(geo, p, ng, d, dist * (1.0 - 1.0e-5)):
                        L += wp.cw_mul(le, fb) * (cb / dist2) + wp.cw_mul(le, fk) * (ck / dist2)
            else:
                omc = float(2.0)
                if dist2 > r * r:
                    omc = S.cone_omc(r * r / dist2)
                axis = sp.n
                if dist2 > 1.0e-30:
                    axis = rel / dist
                d = S.cone_sample(axis, omc, u1, u2)
                fb, cb, fk, ck = _fcos(sp, d, 1.0)
                if _positive(fb) or _positive(fk):
                    th = S.sphere_hit_distance(rel, r, d)
                    if th < 0.0:
                        th = dist  # grazing the silhouette in float32
                    if not _occluded(geo, p, ng, d, th * (1.0 - 1.0e-5)):
                        pl = S.cone_pdf(omc)
                        w = S.power_heuristic(pl, _pdf(sp, d))
                        L += wp.cw_mul(le, fb) * (cb * w / pl) + wp.cw_mul(le, fk) * (ck * w / pl)
        else:
            axis = lights.pos[k]
            if r <= 0.0:
                fb, cb, fk, ck = _fcos(sp, axis, 1.0)
                if _positive(fb) or _positive(fk):
                    if not _occluded(geo, p, ng, axis, 1.0e30):
                        L += wp.cw_mul(le, fb) * cb + wp.cw_mul(le, fk) * ck
            else:
                omc = lights.omc[k]
                d = S.cone_sample(axis, omc, u1, u2)
                fb, cb, fk, ck = _fcos(sp, d, 1.0)
                if _positive(fb) or _positive(fk):
                    if not _occluded(geo, p, ng, d, 1.0e30):
                        pl = S.cone_pdf(omc)
                        w = S.power_heuristic(pl, _pdf(sp, d))
                        L += wp.cw_mul(le, fb) * (cb * w / pl) + wp.cw_mul(le, fk) * (ck * w / pl)

    # ---- BRDF sampling --------------------------------------------------------------------
    us = wp.randf(state)
    u1 = wp.randf(state)
    u2 = wp.randf(state)
    d = _sample(sp, us, u1, u2)
    step.d = d
    pb = _pdf(sp, d)
    if pb > 0.0:
        fb, cb, fk, ck = _fcos(sp, d, 1.0)
        if _positive(fb) or _positive(fk):
            fw = fb * (cb / pb) + fk * (ck / pb)
            tm = float(0.0)  # (below the geometric surface: blocked by the surface itself)
            if wp.dot(d, ng) > 0.0:
                hit, th, face, hu, hv, hn = first_opaque_hit(geo.mesh, geo.cut, p + ng * geo.eps, d, 1.0e30)
                tm = 1.0e30
                if hit:
                    tm = th
                    step.hit = 1
                    step.face = face
                    step.u = hu
                    step.v = hv
                    step.fw = fw
                    step.pos = p + ng * geo.eps + d * th
                    step.n = hn
            if tm > 0.0:
                if env.present != 0 and tm >= 1.0e30:
                    w = S.power_heuristic(pb, S.env_pdf(env, d))
                    fe = fw
                    if sp.occ < 1.0:
                        eb, ecb, ek, eck = _fcos(sp, d, sp.occ)
                        fe = eb * (ecb / pb) + ek * (eck / pb)
                    L += wp.cw_mul(S.env_radiance(env, d), fe) * w
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
    step.L = L
    return step


__all__ = ["LightTable", "Geometry", "SurfacePoint", "PathStep", "LIGHT_POINT", "LIGHT_DIRECTIONAL"]
