r"""Checks of a glTF 2.0 file's JSON and images around :func:`warp_sg.scene.importers.gltf.load_gltf`, so that a broken
file is one line naming the bad element instead of a trimesh traceback or a silently wrong image:

* :func:`check_references` — every index points into its list (``meshes[0].primitives[0].indices =
  9: the file has 2 accessors``; the references of glTF 2.0 §5) and the nodes form a forest (no
  node with two parents, no cycle: §3.5.1);
* :func:`check_compression` — meshes compressed by an extension the importer does not decode
  (:data:`COMPRESSION_EXTENSIONS`) are refused (trimesh reads them as placeholder zeros);
* :func:`check_images` — a texture the importer reads whose image trimesh could not load (a missing
  file, a corrupt PNG, KTX2) is an :class:`~warp_sg.core.errors.ImageError` naming the material, the
  texture slot, the image and why.
"""
from __future__ import annotations

import io
from pathlib import Path

from warp_sg.core.errors import ImageError, MeshError

#: extensions that compress the geometry: without a decoder the file has no usable triangles
COMPRESSION_EXTENSIONS = ("KHR_draco_mesh_compression", "EXT_meshopt_compression")

#: (list holding the references, field path inside one entry, list referred to) of glTF 2.0 (§5)
_REFERENCES = (
    ("scenes", "nodes[]", "nodes"), ("nodes", "children[]", "nodes"), ("nodes", "mesh", "meshes"),
    ("nodes", "skin", "skins"), ("nodes", "camera", "cameras"),
    ("meshes", "primitives[].attributes.*", "accessors"), ("meshes", "primitives[].indices", "accessors"),
    ("meshes", "primitives[].material", "materials"), ("meshes", "primitives[].targets[].*", "accessors"),
    ("accessors", "bufferView", "bufferViews"), ("accessors", "sparse.indices.bufferView", "bufferViews"),
    ("accessors", "sparse.values.bufferView", "bufferViews"), ("bufferViews", "buffer", "buffers"),
    ("materials", "pbrMetallicRoughness.baseColorTexture.index", "textures"),
    ("materials", "pbrMetallicRoughness.metallicRoughnessTexture.index", "textures"),
    ("materials", "normalTexture.index", "textures"), ("materials", "occlusionTexture.index", "textures"),
    ("materials", "emissiveTexture.index", "textures"), ("textures", "source", "images"),
    ("textures", "sampler", "samplers"), ("images", "bufferView", "bufferViews"),
    ("skins", "joints[]", "nodes"), ("skins", "inverseBindMatrices", "accessors"),
    ("meshes", "primitives[].extensions.KHR_draco_mesh_compression.bufferView", "bufferViews"),
    ("textures", "extensions.EXT_texture_webp.source", "images"),
    ("materials", "extensions.KHR_materials_clearcoat.clearcoatTexture.index", "textures"),
    ("materials", "extensions.KHR_materials_clearcoat.clearcoatRoughnessTexture.index", "textures"),
    ("materials", "extensions.KHR_materials_clearcoat.clearcoatNormalTexture.index", "textures"),
    ("materials", "extensions.KHR_materials_specular.specularTexture.index", "textures"),
    ("materials", "extensions.KHR_materials_specular.specularColorTexture.index", "textures"),
)


class _Shape(Exception):
    """A JSON value of the wrong kind (a number where the format has an object or a list)."""


def _kind(v) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean", type(None): "null"}.get(
        type(v), "a number")


def _walk(value, steps: list[str], at: str):
    """(location, value) of every value at the field path ``steps`` below ``value``; a container of
    the wrong kind on the way raises :class:`_Shape` naming its location."""
    if not steps:
        yield at, value
        return
    if not isinstance(value, dict):
        raise _Shape(f"{at} must be an object, got {_kind(value)}")
    step, rest = steps[0], steps[1:]
    if step == "*":
        for k, v in value.items():
            yield from _walk(v, rest, f"{at}.{k}")
        return
    key, many = (step[:-2], True) if step.endswith("[]") else (step, False)
    if key not in value:
        return
    v = value[key]
    if many:
        if not isinstance(v, list):
            raise _Shape(f"{at}.{key} must be a list, got {_kind(v)}")
        for i, x in enumerate(v):
            yield from _walk(x, rest, f"{at}.{key}[{i}]")
    else:
        yield from _walk(v, rest, f"{at}.{key}")


#: the top-level lists of glTF 2.0 (every entry an object)
_LISTS = ("scenes", "nodes", "meshes", "accessors", "bufferViews", "buffers", "materials", "textures", "images",
          "samplers", "skins", "cameras", "animations")


def check_references(path: Path, header: dict) -> None:
    """Every index of the JSON points into its list, and the node graph has no cycle (glTF 2.0
    §5.25: nodes form disjoint trees); else :class:`MeshError` naming the first bad reference."""
    def entries(name):
        v = header.get(name, [])
        if not isinstance(v, list):
            raise MeshError(f"'{name}' must be a list, got {type(v).__name__}", where=str(path))
        return v

    if "scene" in header:
        ref = header["scene"]
        if isinstance(ref, bool) or not isinstance(ref, int) or not 0 <= ref < len(entries("scenes")):
            raise MeshError(f"scene = {ref!r}: the file has {len(entries('scenes'))} scenes", where=str(path))
    for name in _LISTS:
        for i, entry in enumerate(entries(name)):
            if not isinstance(entry, dict):
                raise MeshError(f"{name}[{i}] must be an object, got {_kind(entry)}", where=str(path))
    try:
        for holder, field_path, target in _REFERENCES:
            n = len(entries(target))
            for i, entry in enumerate(entries(holder)):
                for at, ref in _walk(entry, field_path.split("."), f"{holder}[{i}]"):
                    if isinstance(ref, bool) or not isinstance(ref, int) or not 0 <= ref < n:
                        raise MeshError(f"{at} = {ref!r}: the file has {n} {target}", where=str(path))
    except _Shape as e:
        raise MeshError(str(e), where=str(path)) from None
    nodes = entries("nodes")
    parent = {}
    for i, node in enumerate(nodes):
        for c in (node.get("children", []) if isinstance(node, dict) else []):
            if c == i or c in parent:
                raise MeshError(f"nodes[{c}] has two parents or is its own child (nodes[{i}].children lists node "
                                f"{c}); the node graph must be a forest (glTF 2.0 §3.5.1)", where=str(path))
            parent[c] = i
    for i in range(len(nodes)):  # with one parent each, a cycle shows as a walk up that never ends
        j, seen = i, 0
        while j in parent and seen <= len(nodes):
            j, seen = parent[j], seen + 1
        if seen > len(nodes):
            raise MeshError(f"nodes[{i}]: the node graph has a cycle through node {i} (nodes form trees, glTF 2.0 "
                            f"§3.5.1)", where=str(path))


def check_compression(path: Path, header: dict, supported=frozenset()) -> None:
    """A geometry-compression extension that is required and not in ``supported`` (decoded by the
    importer): refuse, since the meshes would be placeholders."""
    for ext in COMPRESSION_EXTENSIONS:
        if ext in header.get("extensionsRequired", []) and ext not in supported:
            raise MeshError(f"meshes are compressed with {ext}, which this installation cannot decode",
                            where=str(path))


def _image_problem(path: Path, header: dict, ref: dict, data) -> str:
    """Why the image of texture reference ``ref`` (``{"index": t}``) could not be read (``data``:
    the file's :class:`~warp_sg.scene.importers.gltf_data.GltfData`)."""
    t = ref.get("index")
    tex = header["textures"][t]
    webp = (tex.get("extensions") or {}).get("EXT_texture_webp") or {}
    src = webp.get("source", tex.get("source"))
    if src is None:
        exts = ", ".join(tex.get("extensions", {})) or "none"
        return f"texture {t} has no image source this importer reads (its extensions: {exts})"
    img = header["images"][src]
    what = f"texture {t}, image {src}"
    if img.get("mimeType") == "image/ktx2":
        return f"{what} is KTX2, which cannot be decoded"
    uri = img.get("uri")
    try:
        blob = data.image_bytes(src)
    except MeshError as e:
        return f"{what}: {str(e).split(': ', 1)[-1]}"
    from PIL import Image

    try:
        with Image.open(io.BytesIO(blob)) as im:
            im.load()
    except Exception:  # noqa: BLE001 - Pillow raises many types for broken files
        source = f"image file '{uri}'" if isinstance(uri, str) and not uri.startswith("data:") else \
            ("the embedded data URI" if uri is not None else f"buffer view {img.get('bufferView')}")
        return f"{what}: {source} cannot be read as a PNG, JPEG or WebP image"
    return f"{what} could not be read"


def check_images(path: Path, header: dict, idx: int, found: dict, data) -> None:
    """Every texture that material ``idx`` uses and the importer reads has its image; else
    :class:`ImageError` naming the material, the texture and the image."""
    entry = header.get("materials", [])[idx]
    pbr = entry.get("pbrMetallicRoughness", {})
    for key in ("baseColorTexture", "metallicRoughnessTexture", "normalTexture", "emissiveTexture",
                "occlusionTexture"):
        ref = (pbr if key in ("baseColorTexture", "metallicRoughnessTexture") else entry).get(key)
        if isinstance(ref, dict) and "index" in ref and found.get(key) is None:
            name = entry.get("name") or f"material{idx}"
            raise ImageError(f"material '{name}' {key}: {_image_problem(path, header, ref, data)}", where=str(path))


__all__ = ["COMPRESSION_EXTENSIONS", "check_references", "check_compression", "check_images"]
