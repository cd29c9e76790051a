r"""glTF 2.0 assets (``.glb`` / ``.gltf``) as scene objects and GGX materials (issue 15).

A scene object ``[[objects]] mesh = "asset.glb"`` stands for every mesh primitive of the file's
default scene, each placed by its node's world matrix (the product of the scene-graph transforms,
``T·R·S`` per node, glTF 2.0 §3.5.2) and then by the object's own ``translate``/``scale``/``rotate``.
:class:`warp_sg.scene.Scene` replaces such an object by one object per primitive with inline arrays
(:func:`gltf_object_parts`) and adds the file's materials to the scene as
``"<object label>/<material name>"``; a ``material`` given for the object overrides the file's.

Files are read by trimesh (``trimesh.load(..., force="scene")``: accessors, images, the node
graph). The JSON header is read first, for what trimesh drops: exact float factors (trimesh stores
``baseColorFactor`` as 8-bit), ``normalTexture.scale``, ``TANGENT`` attributes (renamed
``_TANGENT`` so that trimesh keeps them as a vertex attribute) and the extension lists.

Materials (metallic-roughness, KHR_materials_ior / specular / clearcoat /
emissive_strength, emission, occlusion, alpha modes) are converted by :mod:`warp_sg.scene.importers.gltf_material`;
tangents come from the file or are generated from the UVs (:func:`warp_sg.scene.geometry.uv_tangents`).
Geometry: Draco-compressed primitives (KHR_draco_mesh_compression) are decoded by trimesh with
DracoPy; ``normalized`` integer attributes (KHR_mesh_quantization) are dequantised
(:func:`_dequantize`); ``COLOR_0`` (linear RGBA) multiplies the base colour and its alpha;
KHR_texture_transform is applied to the texture coordinates.

Whatever else a file uses (other extensions, second UV sets, animations, point and line
primitives, alpha blending) is reported once per file and feature as an :class:`AssetWarning`
(one line). An unreadable file raises :class:`~warp_sg.core.errors.MeshError` naming it; so do an index
that points past its list (``meshes[0].primitives[0].indices = 9: the file has 2 accessors``), a
node graph with a cycle, meshes compressed by an extension that cannot be decoded
(:mod:`warp_sg.scene.importers.gltf_checks`), and a primitive with non-finite positions or out-of-range vertex
indices (naming the node). A texture whose image cannot be read (a missing file, a corrupt image)
raises :class:`~warp_sg.core.errors.ImageError` naming the material, the texture and the image: an
untextured image would be a wrong answer.
"""
from __future__ import annotations

import io
import json
import logging
import struct
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from warp_sg.core.errors import MeshError
from warp_sg.scene.geometry import validate_mesh
from warp_sg.scene.importers.gltf_checks import check_compression, check_images, check_references
from warp_sg.scene.importers.gltf_material import (gltf_material, material_uv_transform, texture_infos, uv_transform,
                                                   vertex_colour_factors)
from warp_sg.core.meshcheck import check_mesh

GLTF_SUFFIXES = (".glb", ".gltf")
#: glTF extensions whose meaning the importer renders (everything else is reported and ignored)
SUPPORTED_EXTENSIONS: frozenset = frozenset({
    "KHR_draco_mesh_compression", "KHR_mesh_quantization", "KHR_texture_transform", "KHR_materials_emissive_strength",
    "KHR_materials_ior", "KHR_materials_specular", "KHR_materials_clearcoat"})
#: the texture slots trimesh reads (the others, of extensions, are read by :func:`_extension_images`)
_TRIMESH_SLOTS = ("baseColorTexture", "metallicRoughnessTexture", "normalTexture", "emissiveTexture",
                  "occlusionTexture")

_GLB_MAGIC, _JSON_CHUNK = 0x46546C67, 0x4E4F534A
_TAG = "warp_sg_material_"


class AssetWarning(UserWarning):
    """A feature of an asset file that is not rendered (reported once, one line)."""


@dataclass
class GltfPart:
    """One mesh primitive in the file's world frame (node matrix applied)."""

    name: str
    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None
    uvs: np.ndarray | None
    tangents: np.ndarray | None
    material: int | str | None  # file material index (None: glTF default), or the scene's key
    colors: np.ndarray | None = None  # COLOR_0 (V, 4) linear RGBA
    specular_colors: np.ndarray | None = None  # (V, 3) the ks factor of COLOR_0 (gltf_material)
    #: the material's ``doubleSided`` (glTF 2.0 §3.9.5; default false: back faces culled)
    double_sided: bool = True


@dataclass
class GltfAsset:
    path: Path
    parts: list
    header: dict
    images: dict = field(default_factory=dict)  # material index -> {texture key: PIL image}
    notes: list = field(default_factory=list)  # one-line AssetWarning messages

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        v = np.concatenate([p.vertices for p in self.parts])
        return v.min(0), v.max(0)


def is_gltf(path) -> bool:
    return Path(str(path)).suffix.lower() in GLTF_SUFFIXES


# --------------------------------------------------------------------------------------------
# file
# --------------------------------------------------------------------------------------------
def _read_header(path: Path) -> tuple[dict, bytes]:
    """The JSON header and the raw file bytes (GLB: 12-byte header, JSON chunk first)."""
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise MeshError(f"cannot read glTF file ({e.strerror or e})", where=str(path)) from None
    try:
        if path.suffix.lower() == ".glb":
            if len(raw) < 20:
                raise ValueError(f"not a binary glTF ({len(raw)} bytes; GLB has a 20-byte header)")
            magic, version, _length = struct.unpack_from("<III", raw, 0)
            if magic != _GLB_MAGIC:
                raise ValueError("not a binary glTF (GLB magic missing)")
            if version != 2:
                raise ValueError(f"GLB version {version}; only glTF 2.0 is supported")
            n, kind = struct.unpack_from("<II", raw, 12)
            if kind != _JSON_CHUNK:
                raise ValueError("the first GLB chunk is not JSON")
            header = json.loads(raw[20:20 + n].decode("utf-8"))
        else:
            header = json.loads(raw.decode("utf-8"))
    except (ValueError, struct.error, UnicodeDecodeError) as e:
        raise MeshError(f"cannot read glTF file ({e})", where=str(path)) from None
    if not isinstance(header, dict):
        raise MeshError("cannot read glTF file (the JSON header is not an object)", where=str(path))
    version = str(header.get("asset", {}).get("version", "2.0"))
    if not version.startswith("2"):
        raise MeshError(f"glTF version {version}; only glTF 2.0 is supported", where=str(path))
    return header, raw


#: glTF 2.0 §3.6.2.1 (``normalized`` accessors, KHR_mesh_quantization): integer code c → float,
#: ``max(c / (2^(b−1) − 1), −1)`` for signed and ``c / (2^b − 1)`` for unsigned b-bit components
_NORMALIZED = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0, 5125: 4294967295.0}
#: the private primitive extension that carries the dequantisation plan to :func:`_dequantize`
_DEQUANTIZE = "WARP_SG_dequantize"


def _dequantize(context) -> None:
    """trimesh ``primitive_preprocess`` handler: the primitive's ``normalized`` integer accessors
    (listed by :func:`_retagged`, each in one primitive only) become floats in place."""
    acc = context["accessors"]
    for idx, div in context["data"].items():
        a = acc[int(idx)]
        acc[int(idx)] = np.maximum(np.asarray(a, np.float64) / float(div), -1.0).astype(np.float32)


def _register_dequantize() -> None:
    from trimesh.exchange.gltf.extensions import register_handler

    register_handler(_DEQUANTIZE, scope="primitive_preprocess")(_dequantize)


def _retagged(path: Path, header: dict, raw: bytes) -> bytes:
    """The file with ``TANGENT`` and ``COLOR_0`` attributes renamed ``_TANGENT`` and ``_COLOR_0``
    (trimesh keeps ``_`` attributes, aligned with the vertices), every material named by its index
    (to find the header entry behind trimesh's material) and the ``normalized`` integer accessors of
    the primitives' attributes (KHR_mesh_quantization) listed for :func:`_dequantize` in the first
    primitive that reads each (Draco primitives decode to floats: none of theirs)."""
    h = json.loads(json.dumps(header))
    accessors = h.get("accessors", [])
    planned = set()
    for mesh in h.get("meshes", []):
        for prim in mesh.get("primitives", []):
            attr = prim.get("attributes", {})
            for name in ("TANGENT", "COLOR_0"):
                if name in attr:
                    attr["_" + name] = attr.pop(name)
            if "KHR_draco_mesh_compression" in prim.get("extensions", {}):
                continue
            plan = {}
            for idx in attr.values():
                a = accessors[idx] if isinstance(idx, int) and 0 <= idx < len(accessors) else {}
                if a.get("normalized") and a.get("componentType") in _NORMALIZED and idx not in planned:
                    plan[str(idx)] = _NORMALIZED[a["componentType"]]
                    planned.add(idx)
            if plan:
                prim.setdefault("extensions", {})[_DEQUANTIZE] = plan
    for i, mat in enumerate(h.get("materials", [])):
        mat["name"] = f"{_TAG}{i}"
    text = json.dumps(h).encode("utf-8")
    if path.suffix.lower() != ".glb":
        return text
    text += b" " * (-len(text) % 4)  # chunks are 4-byte aligned, JSON padded with spaces
    n_old = struct.unpack_from("<I", raw, 12)[0]
    rest = raw[20 + n_old:]
    body = struct.pack("<II", len(text), _JSON_CHUNK) + text + rest
    return struct.pack("<III", _GLB_MAGIC, 2, 12 + len(body)) + body


def _notes(path: Path, header: dict) -> list[str]:
    """One line per feature of the file that is not rendered."""
    out = []
    used = list(dict.fromkeys(list(header.get("extensionsUsed", [])) + list(header.get("extensionsRequired", []))))
    for ext in used:
        if ext not in SUPPORTED_EXTENSIONS:
            out.append(f"{path.name}: glTF extension '{ext}' is not supported; ignored")
    mats = [m for m in header.get("materials", []) if isinstance(m, dict)]
    blend = [m.get("name") or f"material{i}" for i, m in enumerate(mats) if m.get("alphaMode") == "BLEND"
             and (float(m.get("pbrMetallicRoughness", {}).get("baseColorFactor", [1, 1, 1, 1])[3]) < 1.0
                  or "baseColorTexture" in m.get("pbrMetallicRoughness", {}))]
    if blend:
        out.append(f"{path.name}: alphaMode BLEND is rendered as MASK with alphaCutoff 0.5 (no blending): "
                   f"{_names(blend)}")
    mixed = [m.get("name") or f"material{i}" for i, m in enumerate(mats) if material_uv_transform(m)[1]]
    if mixed:
        out.append(f"{path.name}: textures of one material with different KHR_texture_transforms all use the "
                   f"first one's: {_names(mixed)}")
    infos = [i for m in mats for i in texture_infos(m).values()]
    if any(i.get("extensions", {}).get("KHR_texture_transform", {}).get("texCoord", i.get("texCoord", 0)) != 0
           for i in infos):
        out.append(f"{path.name}: textures on a second UV set (texCoord > 0) read TEXCOORD_0")
    prims = [p for m in header.get("meshes", []) for p in m.get("primitives", [])]
    if any(p.get("mode", 4) not in (4, 5) for p in prims):
        out.append(f"{path.name}: point, line and fan primitives are not rendered; skipped")
    if header.get("animations") or header.get("skins"):
        out.append(f"{path.name}: animations and skins are not rendered; the rest pose is used")
    return out


def _names(names: list, n: int = 3) -> str:
    """The first ``n`` names, quoted, and how many more."""
    shown = ", ".join(f"'{x}'" for x in names[:n])
    return shown + (f" and {len(names) - n} more" if len(names) > n else "")


#: the one asset read with ``keep=True`` and not taken yet: ``{(path, mtime, size, images): GltfAsset}``
_KEPT: dict = {}


def _file_key(path: Path, images: bool) -> tuple:
    st = path.stat()
    return str(path.resolve()), st.st_mtime_ns, st.st_size, bool(images)


def load_gltf(path, *, images: bool = True, keep: bool = False) -> GltfAsset:
    """Read a glTF 2.0 file: every triangle primitive in world space (:class:`GltfPart`), the
    header, the texture images of each material (``images=False`` skips them) and the notes.

    ``keep``: also keep the result for the next read of the same file (unchanged: path, size and
    modification time), which takes it instead of reading the file again — the asset scene reads
    its bounds first and then its objects (``warp_sg.scene.importers.asset``; a 359 k-triangle Draco
    file decodes in 0.4 s). One asset is kept at most."""
    path = Path(path)
    if not path.is_file():
        raise MeshError("glTF file not found", where=str(path))
    key = _file_key(path, images)
    asset = _KEPT.pop(key, None)
    if asset is None:
        asset = _read_gltf(path, images)
    if keep:
        _KEPT.clear()
        _KEPT[key] = asset
    return asset


def _read_gltf(path: Path, images: bool) -> GltfAsset:
    """:func:`load_gltf`'s reading of the file."""
    import trimesh

    header, raw = _read_header(path)
    check_references(path, header)
    check_compression(path, header, SUPPORTED_EXTENSIONS)
    data = _retagged(path, header, raw)
    _register_dequantize()
    if "KHR_draco_mesh_compression" in header.get("extensionsUsed", []):
        try:
            import DracoPy  # noqa: F401  (trimesh decodes KHR_draco_mesh_compression with it)
        except ImportError as e:
            raise MeshError(f"Draco-compressed meshes need DracoPy ({e})", where=str(path)) from None
    failed = _TrimeshFailures()
    try:
        resolver = trimesh.resolvers.FilePathResolver(str(path))
        with failed:
            sc = trimesh.load(io.BytesIO(data), file_type=path.suffix.lower()[1:], resolver=resolver,
                              force="scene", skip_materials=not images)
    except Exception as e:  # noqa: BLE001 - trimesh raises many types for broken files
        raise MeshError(f"cannot read glTF file ({type(e).__name__}: {e})", where=str(path)) from None
    if failed.messages:  # e.g. a Draco blob that does not decode: trimesh would go on with zeros
        raise MeshError(f"cannot read glTF file ({failed.messages[0]})", where=str(path))
    parts, imgs = [], {}
    for node in sc.graph.nodes_geometry:
        M, gname = sc.graph[node]
        g = sc.geometry[gname]
        if not isinstance(g, trimesh.Trimesh) or len(g.faces) == 0:
            continue
        parts.append(_part(path, node, g, np.asarray(M, np.float64)))
        mat = getattr(getattr(g, "visual", None), "material", None)
        idx = parts[-1].material = _material_index(mat)
        if idx is not None and idx not in imgs:
            imgs[idx] = {k: getattr(mat, k, None) for k in _TRIMESH_SLOTS}
            if images:
                check_images(path, header, idx, imgs[idx])
    if not parts:
        raise MeshError("glTF file contains no triangles", where=str(path))
    notes = _notes(path, header)
    if images:
        notes += _extension_images(path, header, raw, imgs)
    return GltfAsset(path=path, parts=parts, header=header, images=imgs, notes=notes)


def _buffer_bytes(path: Path, header: dict, raw: bytes, i: int) -> bytes:
    """Buffer ``i``: the GLB's BIN chunk (no ``uri``), a base64 ``data:`` URI or a file next to ``path``."""
    import base64
    from urllib.parse import unquote

    uri = header["buffers"][i].get("uri")
    if uri is None:
        n = struct.unpack_from("<I", raw, 12)[0]
        off = 20 + n + (-n % 4)
        length = struct.unpack_from("<I", raw, off)[0]
        return raw[off + 8:off + 8 + length]
    if uri.startswith("data:"):
        return base64.b64decode(uri.split(",", 1)[1])
    return (path.parent / unquote(uri)).read_bytes()


def _texture_image(path: Path, header: dict, raw: bytes, tex: int):
    """The PIL image of texture ``tex`` (its ``source`` image: a buffer view or a URI)."""
    import base64
    from urllib.parse import unquote

    from PIL import Image

    img = header["images"][header["textures"][tex]["source"]]
    if "bufferView" in img:
        bv = header["bufferViews"][img["bufferView"]]
        buf = _buffer_bytes(path, header, raw, bv.get("buffer", 0))
        data = buf[bv.get("byteOffset", 0):bv.get("byteOffset", 0) + bv["byteLength"]]
    elif img["uri"].startswith("data:"):
        data = base64.b64decode(img["uri"].split(",", 1)[1])
    else:
        data = (path.parent / unquote(img["uri"])).read_bytes()
    im = Image.open(io.BytesIO(data))
    im.load()
    return im


def _extension_images(path: Path, header: dict, raw: bytes, imgs: dict) -> list[str]:
    """Add the images of the extension texture slots (which trimesh does not read) to ``imgs``
    ({material index: {slot: PIL image}}); one note per file for those that cannot be read."""
    mats = header.get("materials", [])
    bad = []
    for idx, slots in imgs.items():
        entry = mats[idx] if 0 <= idx < len(mats) else {}
        for name, info in texture_infos(entry).items():
            if name in _TRIMESH_SLOTS:
                continue
            try:
                slots[name] = _texture_image(path, header, raw, int(info["index"]))
            except Exception as e:  # noqa: BLE001 - missing keys, files, bad image data
                slots[name] = None
                bad.append(f"{name} of '{entry.get('name') or f'material{idx}'}' ({type(e).__name__})")
    return [f"{path.name}: textures that cannot be read are not rendered: {_names(bad)}"] if bad else []


class _TrimeshFailures(logging.Handler):
    """Collects trimesh's "failed to process extension" log records while it loads a file (its
    handlers log and go on with placeholder zeros, which would render as an empty mesh)."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages = []

    def emit(self, record):
        msg = record.getMessage()
        if "failed to process extension" in msg:
            self.messages.append(msg)

    def __enter__(self):
        logging.getLogger("trimesh").addHandler(self)
        return self

    def __exit__(self, *exc):
        logging.getLogger("trimesh").removeHandler(self)
        return False


def _material_index(mat) -> int | None:
    name = getattr(mat, "name", None)
    if isinstance(name, str) and name.startswith(_TAG):
        return int(name[len(_TAG):])
    return None


def _part(path: Path, node: str, g, M: np.ndarray) -> GltfPart:
    """Apply the node's world matrix: P' = M P, n' ∝ M⁻ᵀ n, t' ∝ M t (winding flipped when det M < 0)."""
    A, t = M[:3, :3], M[:3, 3]
    try:  # before trimesh touches the triangles (its normals index the vertices by them)
        v, f, _ = check_mesh(g.vertices, g.faces)
        validate_mesh(v, f, where=None)  # and not all of zero area (an accessor without data reads as zeros)
    except MeshError as e:
        raise MeshError(f"node '{node}': {e}", where=str(path)) from None
    if not np.isfinite(M).all():
        raise MeshError(f"node '{node}' has a non-finite transform", where=str(path))
    with np.errstate(invalid="ignore", divide="ignore"):  # zero-area faces: normals fixed below
        n = np.nan_to_num(np.asarray(g.vertex_normals, np.float64))
    uv = getattr(g.visual, "uv", None)
    uv = None if uv is None or len(uv) != len(v) else np.asarray(uv, np.float32)
    tan = g.vertex_attributes.get("_TANGENT") if hasattr(g, "vertex_attributes") else None
    tan = None if tan is None or len(tan) != len(v) else np.asarray(tan, np.float64)[:, :3]
    col = g.vertex_attributes.get("_COLOR_0") if hasattr(g, "vertex_attributes") else None
    if col is not None and len(col) == len(v):  # COLOR_0: linear RGB(A), alpha 1 for RGB
        col = np.asarray(col, np.float64).reshape(len(v), -1)
        col = np.c_[col[:, :3], col[:, 3] if col.shape[1] > 3 else np.ones(len(v))].astype(np.float32)
    else:
        col = None
    det = np.linalg.det(A)
    if abs(det) < 1e-30:
        raise MeshError(f"node '{node}' has a singular transform", where=str(path))
    vw = v @ A.T + t
    nw = n @ np.linalg.inv(A)  # (A⁻ᵀ n)ᵀ = nᵀ A⁻¹
    nw /= np.maximum(np.linalg.norm(nw, axis=1, keepdims=True), 1e-30)
    if tan is not None:
        tan = tan @ A.T
        tan /= np.maximum(np.linalg.norm(tan, axis=1, keepdims=True), 1e-30)
    if det < 0:
        f = f[:, [0, 2, 1]]
    return GltfPart(name=str(node), vertices=vw, triangles=f, normals=nw.astype(np.float32), uvs=uv,
                    tangents=None if tan is None else tan.astype(np.float32), material=None, colors=col)


# --------------------------------------------------------------------------------------------
# scene objects
# --------------------------------------------------------------------------------------------
def gltf_object_parts(path, label: str, *, materials: bool = True) -> tuple[list, dict]:
    """A glTF scene object's pieces: its parts (:class:`GltfPart`, ``name`` = ``label/node``,
    ``material`` = the key of its material) and ``{"label/material name": Material kwargs}``
    (empty with ``materials=False``, when the scene names the object's material). Issues one
    :class:`AssetWarning` per feature of the file that is not rendered."""
    asset = load_gltf(path, images=materials)
    for msg in asset.notes:
        warnings.warn(msg, AssetWarning, stacklevel=3)
    entries = asset.header.get("materials", [])
    specs, keys = {}, {}
    for idx in sorted({p.material for p in asset.parts}, key=lambda i: (i is None, i or 0)):
        entry = entries[idx] if idx is not None and idx < len(entries) else None
        key = f"{label}/{(entry or {}).get('name') or ('default' if idx is None else f'material{idx}')}"
        while key in specs:
            key = f"{key}#{idx}"
        keys[idx] = key
        if materials:
            specs[key] = gltf_material(entry, asset.images.get(idx), where=str(asset.path))
    parts = []
    for p in asset.parts:
        entry = entries[p.material] if p.material is not None and p.material < len(entries) else None
        uvs, tangents, colors, spec = p.uvs, p.tangents, None, None
        if materials:
            M, _ = material_uv_transform(entry or {})
            if M is not None and uvs is not None:  # KHR_texture_transform (affine: exact per vertex)
                uvs = uv_transform(uvs, M)
                if not np.allclose(M[:2, :2] / np.linalg.norm(M[:2, 0]), np.eye(2), atol=1e-6):
                    tangents = None  # a rotated UV frame: tangents come from the transformed UVs
            if p.colors is not None:
                colors, spec = vertex_colour_factors(entry, p.colors)
        parts.append(GltfPart(name=f"{label}/{p.name}", vertices=p.vertices, triangles=p.triangles,
                              normals=p.normals, uvs=uvs, tangents=tangents, material=keys[p.material],
                              colors=colors, specular_colors=spec,
                              double_sided=(entry or {}).get("doubleSided", False) is True))
    for key, spec in specs.items():  # a cut-out with no alpha below its cutoff anywhere is opaque
        lay = spec.get("layers")
        if lay is not None and lay.cut_out and lay.alpha_map is None:
            low = [float(p.colors[:, 3].min()) for p in parts if p.material == key and p.colors is not None]
            if lay.alpha * min(low + [1.0]) >= lay.alpha_cutoff:
                lay.alpha_cutoff = None
                if not (lay.emissive or lay.occlusion_map is not None or lay.coated):
                    spec["layers"] = None
    return parts, specs


__all__ = ["AssetWarning", "GltfAsset", "GltfPart", "GLTF_SUFFIXES", "SUPPORTED_EXTENSIONS", "is_gltf",
           "load_gltf", "gltf_material", "gltf_object_parts"]
