"""The shading point's surface description, shared by the SG renderer (``warp_sg.shading.kernel``) and the
Monte-Carlo reference (``warp_sg.groundtruth.reference``) so both shade exactly the same surface:
per-texel material parameters (paper §7, spatially varying BRDFs) and the shading frame with
normal and tangent maps (§7: a per-point rotation applied to the lobes and to the view).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from warp_sg.brdf.kernel.material_wp import Material, texel_param0
from warp_sg.brdf.registry import texture_kernel
from warp_sg.core.errors import SceneError
from warp_sg.numeric.onb import frame_tangent, local_to_world
from warp_sg.scene.textures import TextureAtlas, tex_sample

#: texture slots per material (columns of ``MaterialTextures.slots``): the BRDF's parameters, the
#: normal and tangent maps, and the maps of the material's layers (:mod:`warp_sg.scene.material_layers`)
SLOT_KD, SLOT_KS, SLOT_P0, SLOT_P1, SLOT_NORMAL, SLOT_TANGENT = range(6)
SLOT_EMISSION, SLOT_OCCLUSION, SLOT_COAT, SLOT_COAT_NORMAL = range(6, 10)
N_SLOTS = 10


@wp.struct
class MaterialTextures:
    """``slots[m, s]``: texture index in ``atlas`` for material m and slot s (−1 = constant)."""

    slots: wp.array2d(dtype=int)
    atlas: TextureAtlas


@wp.func
def rotate_to(v: wp.vec3, a: wp.vec3, b: wp.vec3) -> wp.vec3:
    """Apply the minimal rotation taking unit a to unit b (Rodrigues) to v."""
    k = wp.cross(a, b)
    s = wp.length(k)
    c = wp.dot(a, b)
    if s < 1.0e-7:
        if c > 0.0:
            return v
        # opposite: rotate by π about any axis orthogonal to a
        t = frame_tangent(a)
        return 2.0 * wp.dot(v, t) * t - v
    k = k / s
    return v * c + wp.cross(k, v) * s + k * (wp.dot(k, v) * (1.0 - c))


@wp.func
def textured_material(mat: Material, tex: MaterialTextures, mi: int, uv: wp.vec2) -> Material:
    """Per-texel material parameters (kd, ks, model parameters 0 and 1; Oren-Nayar σ → A, B)."""
    m = mat
    s = tex.slots[mi, 0]
    if s >= 0:
        c = tex_sample(tex.atlas, s, uv)
        m.kd = wp.vec3(wp.max(c[0], 0.0), wp.max(c[1], 0.0), wp.max(c[2], 0.0))
    s = tex.slots[mi, 1]
    if s >= 0:
        c = tex_sample(tex.atlas, s, uv)
        m.ks = wp.vec3(wp.max(c[0], 0.0), wp.max(c[1], 0.0), wp.max(c[2], 0.0))
    p = m.params
    s = tex.slots[mi, 2]
    if s >= 0:
        v = tex_sample(tex.atlas, s, uv)[0]
        p = texel_param0(m, p, v)  # the model's rule (Oren–Nayar: σ -> (A, B, σ); else max(v, 1e-4))
    s = tex.slots[mi, 3]
    if s >= 0:
        v = tex_sample(tex.atlas, s, uv)[0]
        p = wp.vec4(p[0], wp.max(v, 1.0e-4), p[2], p[3])
    m.params = p
    return m


@wp.func
def tangent_in_plane(tg: wp.vec3, n: wp.vec3) -> wp.vec3:
    """The mesh tangent made orthogonal to n; the Duff frame's tangent when there is none."""
    t = tg - n * wp.dot(tg, n)
    if wp.length(t) < 1.0e-6:
        return frame_tangent(n)
    return wp.normalize(t)


@wp.func
def apply_normal_map(tex: MaterialTextures, mi: int, slot: int, uv: wp.vec2, n: wp.vec3, t: wp.vec3):
    """The normal map in ``slot`` (tangent-space RGB → normal, the tangent rotated along with it by
    the minimal rotation); (n, t) unchanged without one. Returns the (normal, tangent)."""
    ns = n
    ts = t
    s = tex.slots[mi, slot]
    if s >= 0:
        c = tex_sample(tex.atlas, s, uv)
        nt = wp.vec3(2.0 * c[0] - 1.0, 2.0 * c[1] - 1.0, 2.0 * c[2] - 1.0)
        if wp.length(nt) > 1.0e-6:
            nn = wp.normalize(local_to_world(wp.normalize(nt), ts, wp.cross(n, ts), n))
            ts = wp.normalize(rotate_to(ts, n, nn))
            ns = nn
    return ns, ts


@wp.func
def apply_shading_maps(tex: MaterialTextures, mi: int, uv: wp.vec2, n: wp.vec3, t: wp.vec3):
    """Normal map (tangent-space RGB → normal, the tangent rotated along with it) then tangent map
    (RG → in-plane tangent direction). Returns the shading (normal, tangent)."""
    ns, ts = apply_normal_map(tex, mi, SLOT_NORMAL, uv, n, t)
    s = tex.slots[mi, SLOT_TANGENT]
    if s >= 0:
        c = tex_sample(tex.atlas, s, uv)
        a = 2.0 * c[0] - 1.0
        b = 2.0 * c[1] - 1.0
        if a * a + b * b > 1.0e-10:
            ts = wp.normalize(a * ts + b * wp.cross(ns, ts))
    return ns, ts


#: the slots of the colours a texture may drive
_COLOUR_SLOTS = {"kd": SLOT_KD, "ks": SLOT_KS}


def param_slots(model: str, pname: str) -> tuple:
    """The texture slots a texture of the parameter ``pname`` of the model called ``model`` drives:
    ``kd`` and ``ks`` their own, a number those of the kernel parameters it sets (its
    ``Param.kernel``: ``alpha`` drives both roughness slots); ``()`` when no texture may drive it."""
    kernel = texture_kernel(model, pname)
    if kernel is None:
        return ()
    if pname in _COLOUR_SLOTS:
        return (_COLOUR_SLOTS[pname],)
    return tuple(SLOT_P0 + k for k in kernel)


def material_texture_slots(materials, colour_params):
    """``(slots (n_materials, N_SLOTS) int32, images [(h, w, 4)])``: the texture atlas layout of
    ``MaterialTextures`` for scene materials (textured parameters, normal and tangent maps), shared
    by the renderer and the reference. Images used twice are stored once."""
    slots = np.full((max(len(materials), 1), N_SLOTS), -1, np.int32)
    images, index = [], {}

    def add(tex, colour: bool, raw: bool) -> int:
        key = (id(tex), colour, raw)
        if key not in index:
            index[key] = len(images)
            images.append(tex.raw() if raw else tex.rgba(colour=colour))
        return index[key]

    for mi, m in enumerate(materials):
        for pname, tex in m.textures.items():
            drives = param_slots(m.model, pname)
            if not drives:
                raise SceneError(f"parameter '{pname}' cannot be a texture", where=f"[materials.{m.name}]")
            t = add(tex, pname in colour_params, False)
            for slot in drives:
                slots[mi, slot] = t
        if m.normal_map is not None:
            slots[mi, SLOT_NORMAL] = add(m.normal_map, False, True)
        if m.tangent_map is not None:
            slots[mi, SLOT_TANGENT] = add(m.tangent_map, False, True)
        lay = getattr(m, "layers", None)
        if lay is not None:  # (the alpha map lives with the cut-outs, warp_sg.shading.cutout)
            for attr, slot, raw in (("emission_map", SLOT_EMISSION, False), ("occlusion_map", SLOT_OCCLUSION, False),
                                    ("clearcoat_map", SLOT_COAT, False),
                                    ("clearcoat_normal_map", SLOT_COAT_NORMAL, True)):
                if getattr(lay, attr) is not None:
                    slots[mi, slot] = add(getattr(lay, attr), False, raw)
    return slots, images
