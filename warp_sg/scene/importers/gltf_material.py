r"""glTF 2.0 materials → the renderer's ``ggx`` materials and their layers (issues 15, 27).

PBR metallic-roughness → ``ggx`` (glTF 2.0 Appendix B, "BRDF implementation"), per texel::

    base  = baseColorFactor · sRGB⁻¹(baseColorTexture.rgb)        (linear RGB; × COLOR_0)
    metal = metallicFactor · metallicRoughnessTexture.B
    rough = roughnessFactor · metallicRoughnessTexture.G
    kd    = base · (1 − metal)                                   (Lambert, kd/π)
    α     = max(rough², ALPHA_MIN)                              (Trowbridge–Reitz)

Specular reflectance (KHR_materials_ior, KHR_materials_specular)::

    F0c   = ((ior − 1)/(ior + 1))²                               (ior 1.5: 0.04)
    s     = specularFactor · specularTexture.A
    f0d   = min(F0c · specularColorFactor · sRGB⁻¹(specularColorTexture.rgb), 1) · s
    F0    = (1 − metal) · f0d + metal · base,   F90 = (1 − metal) · s + metal

Schlick with F0 and F90 is ``F90 · Schlick(F0/F90)``, so the material gets ``ks = F90`` and
``fresnel = {schlick = F0/F90}``: exact. When F0/F90 varies over the texture, the material gets
``f0 = mean(F0/F90)`` and a ``ks`` texture ``F90 · (F0/F90)/mean``, exact at normal incidence
(the Schlick rise towards grazing is that of the mean).
Normal textures (tangent space, +Y = ``n × t`` for ``tangent.w = +1``) are rescaled by
``normalTexture.scale`` in x and y and stored as the material's ``normal_map``.

Layers (:class:`warp_sg.scene.material_layers.MaterialLayers`): ``emissiveFactor`` ×
``KHR_materials_emissive_strength`` × sRGB⁻¹(``emissiveTexture``); ``occlusionTexture.R`` with its
strength, ``1 + strength·(R − 1)``; ``alphaMode`` MASK: ``alphaCutoff`` (default 0.5) on
``baseColorFactor.a · baseColorTexture.a`` (BLEND is rendered as MASK at 0.5 and reported);
KHR_materials_clearcoat: ``clearcoatFactor · clearcoatTexture.R``, α_c =
``max((clearcoatRoughnessFactor · clearcoatRoughnessTexture.G)², ALPHA_MIN)``, the
``clearcoatNormalTexture`` like a normal texture.

Textures of one material are resampled (bilinearly, at texel centres) onto the grid of the largest
of those that combine (base, metallic-roughness, specular, specular colour; clear coat and its
roughness), so each derived map is one texture. KHR_texture_transform (offset, rotation, scale)
is applied to the primitive's texture coordinates (:func:`uv_transform`, exact: it is affine), the
one transform of the material's textures.
"""
from __future__ import annotations

import math

import numpy as np

from warp_sg.core.errors import ImageError, reason
from warp_sg.scene.material_layers import MaterialLayers
from warp_sg.scene.textures import Texture, sample_bilinear_np, srgb_to_linear

#: smallest GGX α the importer emits (glTF roughness 0 is a perfect mirror)
ALPHA_MIN = 1e-2
#: F0 of glTF dielectrics (index of refraction 1.5)
DIELECTRIC_F0 = 0.04
#: the texture references of a material entry: (path in the entry, name)
TEXTURE_SLOTS = (
    (("pbrMetallicRoughness", "baseColorTexture"), "baseColorTexture"),
    (("pbrMetallicRoughness", "metallicRoughnessTexture"), "metallicRoughnessTexture"),
    (("normalTexture",), "normalTexture"),
    (("occlusionTexture",), "occlusionTexture"),
    (("emissiveTexture",), "emissiveTexture"),
    (("extensions", "KHR_materials_clearcoat", "clearcoatTexture"), "clearcoatTexture"),
    (("extensions", "KHR_materials_clearcoat", "clearcoatRoughnessTexture"), "clearcoatRoughnessTexture"),
    (("extensions", "KHR_materials_clearcoat", "clearcoatNormalTexture"), "clearcoatNormalTexture"),
    (("extensions", "KHR_materials_specular", "specularTexture"), "specularTexture"),
    (("extensions", "KHR_materials_specular", "specularColorTexture"), "specularColorTexture"),
)


def texture_infos(entry: dict) -> dict:
    """{slot name: textureInfo dict} of the textures a material entry references."""
    out = {}
    for keys, name in TEXTURE_SLOTS:
        d = entry
        for k in keys:
            d = d.get(k, {}) if isinstance(d, dict) else {}
        if isinstance(d, dict) and "index" in d:
            out[name] = d
    return out


# --------------------------------------------------------------------------------------------
# KHR_texture_transform
# --------------------------------------------------------------------------------------------
def texture_transform(info: dict) -> np.ndarray:
    """The 3×3 matrix of a textureInfo's KHR_texture_transform in glTF UV space (origin top-left):
    ``T(offset) · R(rotation) · S(scale)`` with ``R = [[cos, sin], [−sin, cos]]`` (the extension's
    definition); the identity without one."""
    t = info.get("extensions", {}).get("KHR_texture_transform", {}) if isinstance(info, dict) else {}
    ox, oy = (float(v) for v in t.get("offset", [0.0, 0.0]))
    r = float(t.get("rotation", 0.0))
    sx, sy = (float(v) for v in t.get("scale", [1.0, 1.0]))
    c, s = math.cos(r), math.sin(r)
    T = np.array([[1, 0, ox], [0, 1, oy], [0, 0, 1]], np.float64)
    R = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]], np.float64)
    S = np.diag([sx, sy, 1.0])
    return T @ R @ S


def material_uv_transform(entry: dict) -> tuple[np.ndarray | None, bool]:
    """(the KHR_texture_transform of the material's textures, or None for the identity;
    whether its textures disagree — the first textured slot's transform is then used)."""
    mats = [texture_transform(i) for i in texture_infos(entry or {}).values()]
    if not mats:
        return None, False
    mixed = any(not np.allclose(m, mats[0]) for m in mats[1:])
    return (None if np.allclose(mats[0], np.eye(3)) else mats[0]), mixed


def uv_transform(uv: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Apply a glTF UV-space transform to UVs with the bottom-left origin (``v = 1 − v_glTF``)."""
    g = np.c_[uv[:, 0], 1.0 - uv[:, 1], np.ones(len(uv))] @ M.T
    return np.c_[g[:, 0], 1.0 - g[:, 1]].astype(np.float32)


# --------------------------------------------------------------------------------------------
# images
# --------------------------------------------------------------------------------------------
def image_array(img, where: str) -> np.ndarray:
    """A PIL image as float32 (H, W, 4) code values in [0, 1]."""
    from warp_sg.scene.textures import to_rgba

    try:  # Pillow decodes lazily: a truncated or corrupt image fails here
        if img.mode in ("I;16", "I;16B", "I;16L", "I"):
            a = np.asarray(img, np.float32) / 65535.0
        else:
            a = np.asarray(img.convert("RGBA") if img.mode not in ("L", "LA", "RGB", "RGBA") else img,
                           np.float32) / 255.0
    except (OSError, ValueError, SyntaxError) as e:
        raise ImageError(f"cannot decode the image ({reason(e)})", where=where) from None
    return to_rgba(a, where)


def on_grid(a: np.ndarray | None, shape) -> np.ndarray | None:
    """Resample an (H, W, 4) texture bilinearly at the texel centres of an (h, w) grid."""
    if a is None or a.shape[:2] == tuple(shape):
        return a
    h, w = shape
    u = (np.arange(w) + 0.5) / w
    v = 1.0 - (np.arange(h) + 0.5) / h
    uv = np.stack(np.meshgrid(u, v), -1)
    return sample_bilinear_np(a, uv)


def _common_grid(*arrays):
    """The arrays resampled onto the grid of the largest (None stays None); the grid's shape."""
    present = [a for a in arrays if a is not None]
    if not present:
        return arrays, None
    shape = max((a.shape[:2] for a in present), key=lambda s: s[0] * s[1])
    return tuple(on_grid(a, shape) for a in arrays), shape


def _normal_texture(img, scale: float, where: str) -> Texture:
    n = 2.0 * image_array(img, where)[..., :3] - 1.0
    n[..., :2] *= scale
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    return Texture(data=((n + 1.0) / 2.0).astype(np.float32))


# --------------------------------------------------------------------------------------------
# materials
# --------------------------------------------------------------------------------------------
def pbr_to_ggx(base, metal, rough, f0_dielectric=DIELECTRIC_F0, f90_dielectric=1.0) -> dict:
    """glTF metallic-roughness (and KHR_materials_specular/ior) → GGX values (arrays broadcast):
    ``kd``, ``f0`` (= F0/F90, the Schlick F0), ``f90`` (the ``ks`` scale) and ``alpha``
    (module docstring)."""
    base = np.asarray(base, np.float64)
    metal = np.asarray(metal, np.float64)[..., None]
    rough = np.asarray(rough, np.float64)
    f0 = (1.0 - metal) * np.asarray(f0_dielectric, np.float64) + base * metal
    f90 = (1.0 - metal) * np.asarray(f90_dielectric, np.float64) + metal
    f90 = np.broadcast_to(f90, f0.shape)
    return {"kd": base * (1.0 - metal), "f0": np.where(f90 > 0, f0 / np.where(f90 > 0, f90, 1.0), 0.0),
            "f90": f90, "alpha": np.maximum(rough * rough, ALPHA_MIN)}


def dielectric_specular(entry: dict) -> tuple[np.ndarray, float]:
    """(F0 colour before the specular weight, the weight s) of the factors: KHR_materials_ior's
    ``((ior − 1)/(ior + 1))²`` × KHR_materials_specular's ``specularColorFactor`` (clamped to 1)."""
    ext = entry.get("extensions", {})
    ior = float(ext.get("KHR_materials_ior", {}).get("ior", 1.5))
    spec = ext.get("KHR_materials_specular", {})
    f0c = ((ior - 1.0) / (ior + 1.0)) ** 2 if ior > 0 and ior != 1.5 else DIELECTRIC_F0
    colour = np.asarray(spec.get("specularColorFactor", [1.0, 1.0, 1.0]), np.float64)
    return np.minimum(f0c * colour, 1.0), float(spec.get("specularFactor", 1.0))


def gltf_material(entry: dict | None, images: dict | None, where: str = "glTF") -> dict:
    """The ``ggx`` material of one glTF material entry as :class:`warp_sg.scene.Material` keyword
    arguments (``model``, ``params``, ``textures``, ``normal_map``, ``layers``); ``None``: the glTF
    default material (base colour 1, metallic 1, roughness 1). ``images``: {slot name (the keys of
    :data:`TEXTURE_SLOTS`): PIL image} of the textures that could be read."""
    entry = entry or {}
    images = images or {}
    pbr = entry.get("pbrMetallicRoughness", {})
    infos = texture_infos(entry)
    img = {k: images.get(k) for k in infos}

    def arr(name):
        return None if img.get(name) is None else image_array(img[name], f"{where}: {name}")

    bcf = np.asarray(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0]), np.float64)
    mf = float(pbr.get("metallicFactor", 1.0))
    rf = float(pbr.get("roughnessFactor", 1.0))
    f0c, sf = dielectric_specular(entry)
    (bt, mrt, st, sct), shape = _common_grid(arr("baseColorTexture"), arr("metallicRoughnessTexture"),
                                             arr("specularTexture"), arr("specularColorTexture"))
    params, textures = {}, {}
    f0d = f0c * sf if sct is None else np.minimum(f0c * srgb_to_linear(sct[..., :3]), 1.0) * sf
    s = sf if st is None else sf * st[..., 3:4]
    if st is not None:
        f0d = f0d * st[..., 3:4]
    if shape is None:
        g = pbr_to_ggx(bcf[:3], mf, rf, f0d, s)
        params.update(kd=g["kd"].tolist(), alpha=float(g["alpha"]), fresnel={"schlick": g["f0"].tolist()})
        if not np.allclose(g["f90"], 1.0):
            params["ks"] = g["f90"].tolist()
    else:
        base = bcf[:3] * (srgb_to_linear(bt[..., :3]) if bt is not None else np.ones(shape + (3,)))
        metal = mf * (mrt[..., 2] if mrt is not None else np.ones(shape))
        rough = rf * (mrt[..., 1] if mrt is not None else np.ones(shape))
        g = pbr_to_ggx(base, metal, rough, f0d, s)
        textures["kd"] = Texture(data=g["kd"].astype(np.float32))
        if mrt is not None:
            textures["alpha"] = Texture(data=g["alpha"].astype(np.float32))
        else:
            params["alpha"] = float(pbr_to_ggx(1.0, 0.0, rf)["alpha"])
        f0 = g["f0"].reshape(-1, 3)
        f0_ref = np.clip(f0.mean(0), 1e-4, 1.0)
        params["fresnel"] = {"schlick": f0_ref.tolist()}
        ks = g["f90"] * g["f0"] / f0_ref
        if not np.allclose(ks, 1.0, rtol=0.0, atol=1e-6):
            textures["ks"] = Texture(data=ks.astype(np.float32))
    nt = img.get("normalTexture")
    normal_map = None if nt is None else _normal_texture(nt, float(entry["normalTexture"].get("scale", 1.0)),
                                                         f"{where}: normalTexture")
    return {"model": "ggx", "params": params, "textures": textures, "normal_map": normal_map,
            "layers": material_layers(entry, img, bt, where)}


def material_layers(entry: dict, img: dict, base_texture, where: str) -> MaterialLayers | None:
    """The :class:`MaterialLayers` of a material entry (None when it has none of them)."""
    lay = MaterialLayers()
    ext = entry.get("extensions", {})
    strength = float(ext.get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0))
    lay.emission = tuple(float(x) * strength for x in (list(entry.get("emissiveFactor", [0.0, 0.0, 0.0])) + [0.0] * 3)[:3])
    if img.get("emissiveTexture") is not None and lay.emissive:
        e = image_array(img["emissiveTexture"], f"{where}: emissiveTexture")
        lay.emission_map = Texture(data=srgb_to_linear(e[..., :3]))
    if img.get("occlusionTexture") is not None:
        s = float(entry["occlusionTexture"].get("strength", 1.0))
        o = image_array(img["occlusionTexture"], f"{where}: occlusionTexture")[..., 0]
        lay.occlusion_map = Texture(data=(1.0 + s * (o - 1.0)).astype(np.float32))
    mode = entry.get("alphaMode", "OPAQUE")
    if mode in ("MASK", "BLEND"):
        lay.alpha = float(entry.get("pbrMetallicRoughness", {}).get("baseColorFactor", [1, 1, 1, 1])[3])
        lay.alpha_cutoff = float(entry.get("alphaCutoff", 0.5)) if mode == "MASK" else 0.5
        if base_texture is not None and np.any(base_texture[..., 3] < 1.0):
            lay.alpha_map = Texture(data=base_texture[..., 3].astype(np.float32))
    cc = ext.get("KHR_materials_clearcoat", {})
    if float(cc.get("clearcoatFactor", 0.0)) > 0:
        cf, crf = float(cc.get("clearcoatFactor", 0.0)), float(cc.get("clearcoatRoughnessFactor", 0.0))
        (ct, crt), shape = _common_grid(
            *(None if img.get(k) is None else image_array(img[k], f"{where}: {k}")
              for k in ("clearcoatTexture", "clearcoatRoughnessTexture")))
        lay.clearcoat, lay.clearcoat_alpha = cf, max(crf * crf, ALPHA_MIN)
        if shape is not None:
            c = cf * (ct[..., 0] if ct is not None else np.ones(shape))
            a = np.maximum((crf * (crt[..., 1] if crt is not None else np.ones(shape))) ** 2, ALPHA_MIN)
            lay.clearcoat_map = Texture(data=np.stack([c, a, np.zeros(shape)], -1).astype(np.float32))
            lay.clearcoat, lay.clearcoat_alpha = float(c.mean()), float(a.mean())
        if img.get("clearcoatNormalTexture") is not None:
            lay.clearcoat_normal_map = _normal_texture(img["clearcoatNormalTexture"],
                                                       float(cc["clearcoatNormalTexture"].get("scale", 1.0)),
                                                       f"{where}: clearcoatNormalTexture")
    if not (lay.emissive or lay.occlusion_map is not None or lay.cut_out or lay.coated):
        return None
    return lay


def vertex_colour_factors(entry: dict | None, colors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """COLOR_0 (V, 4) linear RGBA → (kd and alpha factor (V, 4), ks factor (V, 3)) of a material:
    the vertex colour multiplies the base colour, so ``kd`` by ``c`` and the Schlick F0 of the
    metallic part, ``ks`` by ``((1 − m) f0d + m c b̄)/((1 − m) f0d + m b̄)`` with the material's
    metallic and base colour factors m, b̄ (exact for untextured metals; 1 for dielectrics)."""
    entry = entry or {}
    pbr = entry.get("pbrMetallicRoughness", {})
    b = np.asarray(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0]), np.float64)[:3]
    m = float(pbr.get("metallicFactor", 1.0))
    f0c, s = dielectric_specular(entry)
    c = np.asarray(colors, np.float64)
    den = (1.0 - m) * f0c * s + m * b
    ks = np.where(den > 0, ((1.0 - m) * f0c * s + m * c[:, :3] * b) / np.where(den > 0, den, 1.0), 1.0)
    return c.astype(np.float32), ks.astype(np.float32)


__all__ = ["ALPHA_MIN", "DIELECTRIC_F0", "TEXTURE_SLOTS", "texture_infos", "texture_transform",
           "material_uv_transform", "uv_transform", "image_array", "on_grid", "pbr_to_ggx", "dielectric_specular",
           "gltf_material", "material_layers", "vertex_colour_factors"]
