r"""Kernel side of a material's layers (:mod:`warp_sg.scene.material_layers`): emission, occlusion, the
clear coat and vertex colours, ``@wp.func``\ s shared by the renderer's shading kernel
(:mod:`warp_sg.shading.kernel`) and the Monte-Carlo reference (:mod:`warp_sg.groundtruth.reference_wp`), so both shade
the same surface::

    L(o) = a(o) · [Lbase(o) + Le] + Lcoat(o),   a(o) = 1 − c · (0.04 + 0.96 (1 − n_c·o)⁵)

* vertex colours: ``kd ← kd ∘ c.rgb`` and ``ks ← ks ∘ c_ks`` (interpolated; glTF COLOR_0);
* emission ``Le = emission_m ∘ emission_map(uv)``;
* occlusion ``occlusion_map(uv).r`` (1 without a map) multiplies the environment's diffuse term;
* the coat: material ``coat[m]`` of the material table (a ``ggx`` lobe, ``ks = c``, F0 = 0.04;
  :meth:`~warp_sg.scene.material_layers.MaterialLayers.coat_model`) with its map (R: c, G: α_c) in the
  coat's frame: the interpolated normal, or the coat normal map applied to it.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func / struct annotations.
import numpy as np
import warp as wp

from warp_sg.brdf.kernel.material_wp import Material, above
from warp_sg.numeric.onb import world_to_local
from warp_sg.scene.material_layers import COAT_F0
from warp_sg.scene.textures import tex_sample
from warp_sg.shading.surface import (
    SLOT_COAT,
    SLOT_COAT_NORMAL,
    SLOT_EMISSION,
    SLOT_OCCLUSION,
    MaterialTextures,
    apply_normal_map,
)

COAT_F0_WP = wp.constant(COAT_F0)


@wp.struct
class Layers:
    """Per material: ``emission`` (RGB) and ``coat`` (the index of its coat in the material table, −1:
    none); per vertex: ``colors`` (RGBA) and ``specular_colors`` (RGB; 1-entry placeholders when
    ``has_colors`` is 0); ``n_local``: lights ``[0, n_local)`` of the shading kernel are local, the
    rest are the environment's peaks (occlusion applies to those)."""

    emission: wp.array(dtype=wp.vec3)
    coat: wp.array(dtype=int)
    colors: wp.array(dtype=wp.vec4)
    specular_colors: wp.array(dtype=wp.vec3)
    has_colors: int
    n_local: int


@wp.func
def vertex_coloured(mat: Material, lay: Layers, i0: int, i1: int, i2: int, b0: float, b1: float, b2: float) -> Material:
    """The material with the interpolated vertex colour applied (kd ∘ c.rgb, ks ∘ c_ks)."""
    m = mat
    if lay.has_colors != 0:
        c = lay.colors[i0] * b0 + lay.colors[i1] * b1 + lay.colors[i2] * b2
        m.kd = wp.cw_mul(m.kd, wp.vec3(c[0], c[1], c[2]))
        m.ks = wp.cw_mul(m.ks, lay.specular_colors[i0] * b0 + lay.specular_colors[i1] * b1
                         + lay.specular_colors[i2] * b2)
    return m


@wp.func
def emission_at(lay: Layers, tex: MaterialTextures, mi: int, uv: wp.vec2) -> wp.vec3:
    """Emitted radiance ``emission_m ∘ emission_map(uv)``."""
    e = lay.emission[mi]
    s = tex.slots[mi, SLOT_EMISSION]
    if s >= 0:
        c = tex_sample(tex.atlas, s, uv)
        e = wp.cw_mul(e, wp.vec3(c[0], c[1], c[2]))
    return e


@wp.func
def occlusion_at(tex: MaterialTextures, mi: int, uv: wp.vec2) -> float:
    """The ambient occlusion factor on the environment's diffuse term (1 without a map)."""
    s = tex.slots[mi, SLOT_OCCLUSION]
    if s < 0:
        return 1.0
    return wp.clamp(tex_sample(tex.atlas, s, uv)[0], 0.0, 1.0)


@wp.func
def coat_at(mats: wp.array(dtype=Material), lay: Layers, tex: MaterialTextures, mi: int, uv: wp.vec2):
    """(whether material ``mi`` has a coat, the coat's material at ``uv``: ks = c, α = α_c from the map)."""
    ci = lay.coat[mi]
    if ci < 0:
        return False, mats[0]
    cm = mats[ci]
    s = tex.slots[mi, SLOT_COAT]
    if s >= 0:
        c = tex_sample(tex.atlas, s, uv)
        f = wp.clamp(c[0], 0.0, 1.0)
        a = wp.max(c[1], 1.0e-4)
        cm.ks = wp.vec3(f, f, f)
        cm.params = wp.vec4(a, a, cm.params[2], cm.params[3])
    return True, cm


@wp.func
def coat_frame(tex: MaterialTextures, mi: int, uv: wp.vec2, n: wp.vec3, t: wp.vec3):
    """The coat's (normal, tangent): the interpolated frame with the coat normal map applied."""
    return apply_normal_map(tex, mi, SLOT_COAT_NORMAL, uv, n, t)


@wp.func
def coat_attenuation(c: float, cos_o: float) -> float:
    """``a = 1 − c · F(cos)``, Schlick with F0 = 0.04: what the coat lets through to the layers under it."""
    x = 1.0 - wp.clamp(cos_o, 0.0, 1.0)
    x2 = x * x
    return 1.0 - c * (COAT_F0_WP + (1.0 - COAT_F0_WP) * x2 * x2 * x)


@wp.func
def coat_setup(mats: wp.array(dtype=Material), lay: Layers, tex: MaterialTextures, mi: int, uv: wp.vec2, o: wp.vec3,
               n: wp.vec3, t: wp.vec3):
    """The coat of material ``mi`` at ``uv`` seen from world direction ``o`` over the interpolated frame
    (n, t): ``(has coat, its material, its frame ns, ts, bs, the local view, a(o))``."""
    has, cm = coat_at(mats, lay, tex, mi, uv)
    ns = n
    ts = t
    if has:
        ns, ts = coat_frame(tex, mi, uv, n, t)
    bs = wp.cross(ns, ts)
    ol = above(world_to_local(o, ts, bs, ns))
    a = float(1.0)
    if has:
        a = coat_attenuation(cm.ks[0], ol[2])
    return has, cm, ns, ts, bs, ol, a


# --------------------------------------------------------------------------------------------
# host side
# --------------------------------------------------------------------------------------------
def coat_models(layers) -> tuple[list, list]:
    """(the coat models of the materials whose layers (a list of ``MaterialLayers`` or None) have
    one, per material the index of its coat among them or −1): the coats are packed after the
    materials in one table."""
    coats, index = [], []
    for lay in layers:
        if lay is not None and lay.coated:
            index.append(len(coats))
            coats.append(lay.coat_model())
        else:
            index.append(-1)
    return coats, index


def layer_arrays(layers, coat_index, n_materials: int, colors, specular_colors, n_local: int, device) -> Layers:
    """The :class:`Layers` struct of per-material ``layers`` (``MaterialLayers`` or None):
    ``coat_index`` (from :func:`coat_models`) offset by the ``n_materials`` of the table that
    precede the coats; vertex ``colors`` (V, 4) and ``specular_colors`` (V, 3), or None."""
    lay = Layers()
    em = np.zeros((max(len(layers), 1), 3), np.float32)
    for i, x in enumerate(layers):
        if x is not None:
            em[i] = x.emission
    lay.emission = wp.array(em, dtype=wp.vec3, device=device)
    ci = np.asarray([(c + n_materials) if c >= 0 else -1 for c in coat_index] or [-1], np.int32)
    lay.coat = wp.array(ci, dtype=int, device=device)
    lay.has_colors = int(colors is not None)
    if colors is None:
        lay.colors = wp.ones(1, dtype=wp.vec4, device=device)
        lay.specular_colors = wp.ones(1, dtype=wp.vec3, device=device)
    else:
        ks = np.ones((len(colors), 3), np.float32) if specular_colors is None else specular_colors
        lay.colors = wp.array(np.ascontiguousarray(colors, np.float32), dtype=wp.vec4, device=device)
        lay.specular_colors = wp.array(np.ascontiguousarray(ks, np.float32), dtype=wp.vec3, device=device)
    lay.n_local = int(n_local)
    return lay


__all__ = ["Layers", "vertex_coloured", "emission_at", "occlusion_at", "coat_at", "coat_frame", "coat_attenuation",
           "coat_setup", "coat_models", "layer_arrays"]
