r"""The rules of glTF 2.0 a file's JSON must follow before anything is decoded (issue 51): the
fields the importer reads, their types and ranges, and the extensions a file uses.

Every refusal is one :class:`~warp_sg.core.errors.MeshError` line naming the element by its glTF
path and the rule, e.g. ``materials[1] ('Paint').pbrMetallicRoughness.roughnessFactor = -0.5:
must be a number in [0, 1] (glTF 2.0 material)`` or ``nodes[0].translation = [inf, 0, 0]: must be
3 finite numbers``. Covered:

* the ``version`` of the ``asset`` object (a 2.x file; ``minVersion`` at most 2.0);
* meshes: ``primitives`` a non-empty list of objects with an ``attributes`` object, ``mode`` 0–6;
* nodes: ``matrix`` (16 finite numbers) or ``translation``/``rotation``/``scale`` (finite; a
  rotation of non-zero length), not both; ``weights`` finite (morph targets are applied by
  :mod:`~warp_sg.scene.importers.gltf_repack`);
* materials: every factor in its range (``baseColorFactor`` 4 numbers in [0, 1], ``metallicFactor``
  and ``roughnessFactor`` in [0, 1], ``emissiveFactor`` in [0, 1], ``alphaCutoff`` ≥ 0,
  ``alphaMode``, ``doubleSided`` a boolean, texture ``scale``/``strength``/``texCoord``, the factors
  of KHR_materials_emissive_strength, _ior, _specular, _clearcoat and KHR_texture_transform);
* **extensions** (glTF 2.0 §3.12): one that ``extensionsRequired`` lists and the importer does not
  render (:data:`RENDERED`, :data:`NEUTRAL`) refuses the file, as the specification asks of a
  loader; one that is merely present — listed in ``extensionsUsed`` or found on any object, declared
  or not — is reported once (:func:`extension_notes`); those it renders are never reported.

Accessors, buffer views and buffers are checked where they are decoded
(:mod:`warp_sg.scene.importers.gltf_data`); references by :func:`~warp_sg.scene.importers.gltf_checks.check_references`.
"""
from __future__ import annotations

import math
from pathlib import Path

from warp_sg.core.errors import MeshError

#: extensions whose meaning the importer renders
RENDERED = frozenset({
    "KHR_draco_mesh_compression", "KHR_mesh_quantization", "KHR_texture_transform", "KHR_materials_emissive_strength",
    "KHR_materials_ior", "KHR_materials_specular", "KHR_materials_clearcoat", "EXT_texture_webp"})
#: extensions that do not change the still image of the default scene: variants (the default
#: material is drawn, as the extension defines) and metadata
NEUTRAL = frozenset({"KHR_materials_variants", "KHR_xmp", "KHR_xmp_json_ld"})

_MAT = "glTF 2.0 material"
#: (path in a material entry, rule, low, high, length) — ``length`` None: one number
_MATERIAL_RULES = (
    (("pbrMetallicRoughness", "baseColorFactor"), 0.0, 1.0, 4),
    (("pbrMetallicRoughness", "metallicFactor"), 0.0, 1.0, None),
    (("pbrMetallicRoughness", "roughnessFactor"), 0.0, 1.0, None),
    (("emissiveFactor",), 0.0, 1.0, 3),
    (("alphaCutoff",), 0.0, math.inf, None),
    (("normalTexture", "scale"), -math.inf, math.inf, None),
    (("occlusionTexture", "strength"), 0.0, 1.0, None),
    (("extensions", "KHR_materials_emissive_strength", "emissiveStrength"), 0.0, math.inf, None),
    (("extensions", "KHR_materials_specular", "specularFactor"), 0.0, 1.0, None),
    (("extensions", "KHR_materials_specular", "specularColorFactor"), 0.0, math.inf, 3),
    (("extensions", "KHR_materials_clearcoat", "clearcoatFactor"), 0.0, 1.0, None),
    (("extensions", "KHR_materials_clearcoat", "clearcoatRoughnessFactor"), 0.0, 1.0, None),
    (("extensions", "KHR_materials_clearcoat", "clearcoatNormalTexture", "scale"), -math.inf, math.inf, None),
)
_TEXTURE_INFOS = (("pbrMetallicRoughness", "baseColorTexture"), ("pbrMetallicRoughness", "metallicRoughnessTexture"),
                  ("normalTexture",), ("occlusionTexture",), ("emissiveTexture",),
                  ("extensions", "KHR_materials_clearcoat", "clearcoatTexture"),
                  ("extensions", "KHR_materials_clearcoat", "clearcoatRoughnessTexture"),
                  ("extensions", "KHR_materials_clearcoat", "clearcoatNormalTexture"),
                  ("extensions", "KHR_materials_specular", "specularTexture"),
                  ("extensions", "KHR_materials_specular", "specularColorTexture"))


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _fmt(v) -> str:
    s = repr(v)
    return s if len(s) <= 80 else s[:77] + "..."


def _lookup(entry: dict, keys: tuple, at: str, path: Path):
    """(present, value) of ``entry[k0][k1]...``; an intermediate that is not an object is refused."""
    d = entry
    for i, k in enumerate(keys):
        if not isinstance(d, dict):
            raise MeshError(f"{at}.{'.'.join(keys[:i])} must be an object", where=str(path))
        if k not in d:
            return False, None
        d = d[k]
    return True, d


def check_asset(path: Path, header: dict) -> None:
    """The ``asset`` object's ``version`` is required and must be 2.x (glTF 2.0 §5.2); ``minVersion`` at most 2.0."""
    asset = header.get("asset")
    if not isinstance(asset, dict) or not isinstance(asset.get("version"), str):
        raise MeshError("asset.version is required (a string such as \"2.0\", glTF 2.0 §5.2)", where=str(path))
    version = asset["version"]
    major = version.split(".")[0]
    if major != "2" or not version.replace(".", "").isdigit():
        raise MeshError(f"asset.version = '{_fmt(version)[1:-1]}': only glTF 2.0 is supported", where=str(path))
    mv = asset.get("minVersion")
    if mv is not None and (not isinstance(mv, str) or mv.split(".")[0] != "2" or mv not in ("2.0", "2")):
        raise MeshError(f"asset.minVersion = {_fmt(mv)}: this importer reads glTF 2.0", where=str(path))


def check_materials(path: Path, header: dict) -> None:
    for i, m in enumerate(header.get("materials", [])):
        name = m.get("name")
        at = f"materials[{i}]" + (f" ('{name}')" if isinstance(name, str) and name else "")
        for keys, lo, hi, n in _MATERIAL_RULES:
            present, v = _lookup(m, keys, at, path)
            if not present:
                continue
            vals = v if n is not None else [v]
            ok = isinstance(vals, list) and len(vals) == (n or 1) and all(
                _number(x) and math.isfinite(x) and lo <= x <= hi for x in vals)
            if not ok:
                rng = "" if lo == -math.inf else (f" in [{lo:g}, {hi:g}]" if hi < math.inf else f" ≥ {lo:g}")
                what = (f"{n} finite numbers" if n else "a finite number") + rng
                raise MeshError(f"{at}.{'.'.join(keys)} = {_fmt(v)}: must be {what} ({_MAT})", where=str(path))
        present, ior = _lookup(m, ("extensions", "KHR_materials_ior", "ior"), at, path)
        if present and not (_number(ior) and math.isfinite(ior) and (ior == 0 or ior >= 1)):
            raise MeshError(f"{at}.extensions.KHR_materials_ior.ior = {_fmt(ior)}: must be 0 or a number ≥ 1",
                            where=str(path))
        if m.get("alphaMode", "OPAQUE") not in ("OPAQUE", "MASK", "BLEND"):
            raise MeshError(f"{at}.alphaMode = {_fmt(m['alphaMode'])}: must be OPAQUE, MASK or BLEND ({_MAT})",
                            where=str(path))
        if not isinstance(m.get("doubleSided", False), bool):
            raise MeshError(f"{at}.doubleSided = {_fmt(m['doubleSided'])}: must be true or false ({_MAT})",
                            where=str(path))
        for keys in _TEXTURE_INFOS:
            present, info = _lookup(m, keys, at, path)
            if present:
                _texture_info(info, f"{at}.{'.'.join(keys)}", path)


def _texture_info(info, at: str, path: Path) -> None:
    if not isinstance(info, dict) or "index" not in info:
        raise MeshError(f"{at} must be an object with an index (glTF 2.0 textureInfo)", where=str(path))
    tc = info.get("texCoord", 0)
    if isinstance(tc, bool) or not isinstance(tc, int) or tc < 0:
        raise MeshError(f"{at}.texCoord = {_fmt(tc)}: must be an integer ≥ 0", where=str(path))
    present, t = _lookup(info, ("extensions", "KHR_texture_transform"), at, path)
    if not present:
        return
    if not isinstance(t, dict):
        raise MeshError(f"{at}.extensions.KHR_texture_transform must be an object", where=str(path))
    for key, n in (("offset", 2), ("scale", 2), ("rotation", None)):
        if key in t:
            vals = t[key] if n else [t[key]]
            if not (isinstance(vals, list) and len(vals) == (n or 1) and all(_number(x) and math.isfinite(x)
                                                                            for x in vals)):
                raise MeshError(f"{at}.extensions.KHR_texture_transform.{key} = {_fmt(t[key])}: must be "
                                f"{f'{n} finite numbers' if n else 'a finite number'}", where=str(path))


def check_meshes(path: Path, header: dict) -> None:
    for i, mesh in enumerate(header.get("meshes", [])):
        prims = mesh.get("primitives")
        if not isinstance(prims, list) or not prims:
            raise MeshError(f"meshes[{i}].primitives is required: a non-empty list (glTF 2.0 mesh)", where=str(path))
        for j, p in enumerate(prims):
            at = f"meshes[{i}].primitives[{j}]"
            if not isinstance(p, dict) or not isinstance(p.get("attributes"), dict):
                raise MeshError(f"{at} must be an object with an attributes object (glTF 2.0 mesh.primitive)",
                                where=str(path))
            mode = p.get("mode", 4)
            if isinstance(mode, bool) or mode not in range(7):
                raise MeshError(f"{at}.mode = {_fmt(mode)}: must be an integer 0–6 (glTF 2.0 §3.7.2.1)", where=str(path))
            targets = p.get("targets", [])
            if not isinstance(targets, list) or not all(isinstance(t, dict) for t in targets):
                raise MeshError(f"{at}.targets must be a list of objects", where=str(path))
        w = mesh.get("weights")
        if w is not None and not (isinstance(w, list) and all(_number(x) and math.isfinite(x) for x in w)):
            raise MeshError(f"meshes[{i}].weights = {_fmt(w)}: must be a list of finite numbers", where=str(path))


def check_nodes(path: Path, header: dict) -> None:
    """Every node's transform and morph weights."""
    nodes = header.get("nodes", [])
    for i, n in enumerate(nodes):
        name = n.get("name")
        at = f"nodes[{i}]" + (f" ('{name}')" if isinstance(name, str) and name else "")
        for key, size in (("matrix", 16), ("translation", 3), ("rotation", 4), ("scale", 3)):
            if key in n:
                v = n[key]
                if not (isinstance(v, list) and len(v) == size and all(_number(x) and math.isfinite(x) for x in v)):
                    raise MeshError(f"{at}.{key} = {_fmt(v)}: must be {size} finite numbers (glTF 2.0 node)",
                                    where=str(path))
        if "rotation" in n and math.hypot(*n["rotation"]) < 1e-12:
            raise MeshError(f"{at}.rotation = {n['rotation']}: not a rotation (a unit quaternion x, y, z, w)",
                            where=str(path))
        if "matrix" in n and n["matrix"][3::4] != [0, 0, 0, 1]:
            raise MeshError(f"{at}.matrix: its last row is {n['matrix'][3::4]}, not [0, 0, 0, 1] (a glTF matrix is an "
                            f"affine transform, §3.5.3)", where=str(path))
        if "matrix" in n and any(k in n for k in ("translation", "rotation", "scale")):
            raise MeshError(f"{at} has both matrix and translation/rotation/scale: one or the other (glTF 2.0 "
                            f"§3.5.3)", where=str(path))
        w = n.get("weights")
        if w is not None and not (isinstance(w, list) and all(_number(x) and math.isfinite(x) for x in w)):
            raise MeshError(f"{at}.weights = {_fmt(w)}: must be a list of finite numbers", where=str(path))


def present_extensions(header: dict) -> list[str]:
    """Every extension the file names: ``extensionsUsed``, ``extensionsRequired`` and the keys of
    every ``extensions`` object anywhere in the JSON (declared or not), in order of appearance."""
    seen = {}
    for key in ("extensionsUsed", "extensionsRequired"):
        for e in header.get(key) or []:
            if isinstance(e, str):
                seen.setdefault(e, None)
    stack = [header]
    while stack:
        v = stack.pop()
        if isinstance(v, dict):
            ext = v.get("extensions")
            if isinstance(ext, dict):
                for e in ext:
                    seen.setdefault(str(e), None)
            stack.extend(x for k, x in v.items() if k != "extras" and isinstance(x, (dict, list)))
        elif isinstance(v, list):
            stack.extend(x for x in v if isinstance(x, (dict, list)))
    return list(seen)


def check_extensions(path: Path, header: dict) -> None:
    """A required extension the importer does not render refuses the file (glTF 2.0 §3.12)."""
    for key in ("extensionsUsed", "extensionsRequired"):
        v = header.get(key, [])
        if not isinstance(v, list) or not all(isinstance(e, str) for e in v):
            raise MeshError(f"{key} = {_fmt(v)}: must be a list of extension names", where=str(path))
    for ext in header.get("extensionsRequired", []):
        if ext not in RENDERED and ext not in NEUTRAL:
            raise MeshError(f"the file requires glTF extension '{ext}' (extensionsRequired), which this renderer "
                            f"cannot decode or draw; a loader must refuse such a file (glTF 2.0 §3.12)",
                            where=str(path))


def extension_notes(path: Path, header: dict) -> list[str]:
    """One line per extension the file names that is not rendered (once each)."""
    return [f"{path.name}: glTF extension '{e}' is not supported; ignored" for e in present_extensions(header)
            if e not in RENDERED and e not in NEUTRAL]


__all__ = ["RENDERED", "NEUTRAL", "check_asset", "check_materials", "check_meshes", "check_nodes", "check_extensions",
           "extension_notes", "present_extensions"]
