r"""UsdPreviewSurface materials of a USD file as GGX materials (:mod:`warp_sg.scene.importers.usd`).

A material bound to a mesh (``UsdShade.MaterialBindingAPI.ComputeBoundMaterial``, per face
subset too) whose surface is a ``UsdPreviewSurface`` shader is read as its constant inputs (the
UsdPreviewSurface specification, openusd.org, "UsdPreviewSurface Specification" v2.5) and written
as the equivalent glTF metallic-roughness entry, which :func:`warp_sg.scene.importers.gltf_material.gltf_material`
turns into a ``ggx`` material (one conversion for both formats):

* ``diffuseColor`` → base colour, ``metallic`` and ``roughness`` as such (``kd = base·(1 − m)``,
  ``α = max(roughness², 0.01)``, ``F0 = (1 − m)·((ior − 1)/(ior + 1))² + m·base``);
* ``useSpecularWorkflow = 1``: ``specularColor`` is F0 (metallic is ignored, F90 = 1): written as
  ``KHR_materials_specular.specularColorFactor = specularColor / ((ior − 1)/(ior + 1))²``;
* ``ior`` (``KHR_materials_ior``), ``emissiveColor`` (emission), ``clearcoat`` /
  ``clearcoatRoughness`` (``KHR_materials_clearcoat``), ``opacity`` with ``opacityThreshold > 0``
  (a cut-out: ``alphaMode = MASK``, ``alphaCutoff = opacityThreshold``).

Inputs connected to a material's interface inputs are followed to their value. What is not
rendered — an input driven by a texture or another shader (the specification's default is used),
``opacity < 1`` without a threshold (translucency: rendered opaque), a surface that is not a
UsdPreviewSurface (the default material) — is said once per material and input as a one-line note
(:class:`~warp_sg.scene.importers.gltf.AssetWarning`).
"""
from __future__ import annotations

import numpy as np

#: UsdPreviewSurface inputs read and their specification defaults
PREVIEW_DEFAULTS = {
    "diffuseColor": (0.18, 0.18, 0.18), "emissiveColor": (0.0, 0.0, 0.0), "useSpecularWorkflow": 0,
    "specularColor": (0.0, 0.0, 0.0), "metallic": 0.0, "roughness": 0.5, "clearcoat": 0.0,
    "clearcoatRoughness": 0.01, "opacity": 1.0, "opacityThreshold": 0.0, "ior": 1.5,
}
#: inputs that only a texture can drive (a constant value changes nothing)
_TEXTURE_ONLY = ("normal", "occlusion", "displacement")


def preview_entry(values: dict, name: str) -> tuple[dict, list[str]]:
    """The glTF material entry of UsdPreviewSurface input values (missing ones: the defaults) and
    the notes on what it does not render."""
    v = {**PREVIEW_DEFAULTS, **values}
    diffuse = [float(x) for x in v["diffuseColor"]]
    opacity, threshold = float(v["opacity"]), float(v["opacityThreshold"])
    ior = float(v["ior"])
    notes = []
    entry = {"name": name, "pbrMetallicRoughness": {"baseColorFactor": diffuse + [1.0], "metallicFactor": 0.0,
                                                    "roughnessFactor": float(v["roughness"])}, "extensions": {}}
    ext = entry["extensions"]
    if ior != 1.5 and ior > 0:
        ext["KHR_materials_ior"] = {"ior": ior}
    if int(v["useSpecularWorkflow"]):
        f0c = ((ior - 1.0) / (ior + 1.0)) ** 2 if ior > 0 and ior != 1.5 else 0.04
        ext["KHR_materials_specular"] = {"specularColorFactor": [float(x) / f0c for x in v["specularColor"]]}
    else:
        entry["pbrMetallicRoughness"]["metallicFactor"] = float(v["metallic"])
    e = np.asarray(v["emissiveColor"], np.float64)
    if np.any(e > 0):
        top = float(e.max())
        entry["emissiveFactor"] = (e / max(top, 1.0)).tolist()
        if top > 1.0:
            ext["KHR_materials_emissive_strength"] = {"emissiveStrength": top}
    if float(v["clearcoat"]) > 0:
        ext["KHR_materials_clearcoat"] = {"clearcoatFactor": float(v["clearcoat"]),
                                          "clearcoatRoughnessFactor": float(v["clearcoatRoughness"])}
    if opacity < 1.0:
        if threshold > 0:
            entry["alphaMode"], entry["alphaCutoff"] = "MASK", threshold
            entry["pbrMetallicRoughness"]["baseColorFactor"][3] = opacity
        else:
            notes.append(f"material '{name}': opacity {opacity:g} without an opacityThreshold (translucency) is "
                         f"not rendered: the surface is opaque")
    return entry, notes


def _input_value(inp, time, UsdShade):
    """(value or None, True when a shader output drives the input): connections through the
    material's interface inputs are followed."""
    if not inp.HasConnectedSource():
        return inp.Get(time), False
    for attr in inp.GetValueProducingAttributes():
        if UsdShade.Output.IsOutput(attr):
            return None, True
        return attr.Get(time), False
    return None, False


def bound_surface_entry(material, time, UsdShade) -> tuple[dict, list[str]]:
    """The glTF entry of a bound ``UsdShade.Material`` (its UsdPreviewSurface, else the default
    material) and the notes on what is not rendered."""
    name = material.GetPrim().GetName()
    shader = material.ComputeSurfaceSource()[0]
    sid = shader.GetIdAttr().Get() if shader and shader.GetPrim().IsValid() else None
    if sid != "UsdPreviewSurface":
        entry, notes = preview_entry({}, name)
        what = f"a '{sid}' shader" if sid else "no UsdPreviewSurface"
        return entry, notes + [f"material '{name}' has {what} as its surface: the UsdPreviewSurface defaults are "
                               f"used"]
    values, notes = {}, []
    for key in (*PREVIEW_DEFAULTS, *_TEXTURE_ONLY):
        inp = shader.GetInput(key)
        if not inp:
            continue
        val, textured = _input_value(inp, time, UsdShade)
        if textured:
            notes.append(f"material '{name}': input '{key}' is driven by a texture or another shader, which is not "
                         f"read (its {'default' if key in PREVIEW_DEFAULTS else 'absence'} is used)")
        elif val is not None and key in PREVIEW_DEFAULTS:
            values[key] = tuple(val) if hasattr(val, "__len__") else val
    entry, more = preview_entry(values, name)
    return entry, notes + more


__all__ = ["PREVIEW_DEFAULTS", "preview_entry", "bound_surface_entry"]
