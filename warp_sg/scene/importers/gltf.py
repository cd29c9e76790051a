r"""glTF 2.0 assets (``.glb`` / ``.gltf``) as scene objects and GGX materials (issue 15).

A scene object ``[[objects]] mesh = "asset.glb"`` stands for every mesh primitive of the file's
default scene, each placed by its node's world matrix (the product of the scene-graph transforms,
``T·R·S`` per node, glTF 2.0 §3.5.2) and then by the object's own ``translate``/``scale``/``rotate``.
:class:`warp_sg.scene.Scene` replaces such an object by one object per primitive with inline arrays
(:func:`gltf_object_parts`) and adds the file's materials to the scene as
``"<object label>/<material name>"``; a ``material`` given for the object overrides the file's.

Files are read against the specification first — the JSON's references and fields
(:mod:`~warp_sg.scene.importers.gltf_checks`, :mod:`~warp_sg.scene.importers.gltf_rules`), the buffers and
accessors decoded with numpy (:mod:`~warp_sg.scene.importers.gltf_data`) — and then by trimesh
(``trimesh.load(..., force="scene")``: the node graph, Draco, images) from the self-contained GLB
:mod:`~warp_sg.scene.importers.gltf_repack` writes (dense float attributes, triangle lists, morph
targets applied, ``TANGENT``/``COLOR_0`` renamed ``_TANGENT``/``_COLOR_0`` so that trimesh keeps them,
every material named by its index). The file's own JSON is kept for what trimesh drops: exact
float factors (trimesh stores ``baseColorFactor`` as 8-bit), ``normalTexture.scale`` and the extensions.

Materials (metallic-roughness, KHR_materials_ior / specular / clearcoat /
emissive_strength, emission, occlusion, alpha modes) are converted by :mod:`warp_sg.scene.importers.gltf_material`;
tangents come from the file or are generated from the UVs (:func:`warp_sg.scene.geometry.uv_tangents`).
Geometry: Draco-compressed primitives (KHR_draco_mesh_compression) are decoded by trimesh with
DracoPy; ``normalized`` integer attributes (KHR_mesh_quantization) are dequantised
(:func:`~warp_sg.scene.importers.gltf_data.as_float`); ``COLOR_0`` (linear RGBA) multiplies the base colour and its alpha;
KHR_texture_transform is applied to the texture coordinates.

Whatever else a file uses (extensions it does not require, second UV sets, animations, point and
line primitives, alpha blending) is reported once per file and feature as an :class:`AssetWarning`
(one line); an extension it requires and the importer does not render refuses it. An unreadable or
malformed file raises :class:`~warp_sg.core.errors.MeshError` naming it, the glTF element and the rule
(``meshes[0].primitives[0].indices: triangle 1 has a vertex index out of range``), never a Python
exception's name. A texture whose image cannot be read (a missing file, a corrupt image) raises
:class:`~warp_sg.core.errors.ImageError` naming the material, the texture and the image: an
untextured image would be a wrong answer.
"""
from __future__ import annotations

import io
import json
import logging
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from warp_sg.core.errors import MeshError
from warp_sg.core.meshcheck import check_mesh
from warp_sg.scene.geometry import validate_mesh
from warp_sg.scene.importers.gltf_checks import check_compression, check_images, check_references
from warp_sg.scene.importers.gltf_data import GltfData, glb_chunks
from warp_sg.scene.importers.gltf_material import (
    gltf_material,
    material_uv_transform,
    texture_infos,
    uv_transform,
    vertex_colour_factors,
)
from warp_sg.scene.importers.gltf_repack import repack
from warp_sg.scene.importers.gltf_rules import (
    RENDERED,
    check_asset,
    check_extensions,
    check_materials,
    check_meshes,
    check_nodes,
    extension_notes,
    present_extensions,
)

GLTF_SUFFIXES = (".glb", ".gltf")
#: glTF extensions whose meaning the importer renders (everything else is reported and ignored)
SUPPORTED_EXTENSIONS: frozenset = RENDERED
#: the texture slots trimesh reads (the others, of extensions, are read by :func:`_extension_images`)
_TRIMESH_SLOTS = ("baseColorTexture", "metallicRoughnessTexture", "normalTexture", "emissiveTexture",
                  "occlusionTexture")

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
def _number(text: str):
    """A JSON number: an integer where its value is one (``1.0`` is the integer 1 in JSON Schema, as
    glTF's indices may be written), else a float."""
    f = float(text)
    return int(f) if f.is_integer() and abs(f) < 2.0 ** 53 else f


def _read_header(path: Path) -> tuple[dict, bytes | None]:
    """The JSON header and the GLB's BIN chunk (None for a .gltf), glTF 2.0 §3.2 and §4.4."""
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise MeshError(f"cannot read glTF file ({e.strerror or e})", where=str(path)) from None
    bin_chunk = None
    try:
        if path.suffix.lower() == ".glb":
            text, bin_chunk = glb_chunks(raw)
        else:
            text = raw
        if text.startswith(b"\xef\xbb\xbf"):
            raise ValueError("the JSON starts with a byte-order mark, which glTF 2.0 forbids (§3.2: UTF-8 "
                             "without BOM)")
        header = json.loads(text.decode("utf-8"), parse_float=_number)
    except UnicodeDecodeError:
        raise MeshError("cannot read glTF file (the JSON is not UTF-8 text)", where=str(path)) from None
    except RecursionError:
        raise MeshError("cannot read glTF file (the JSON is nested too deeply)", where=str(path)) from None
    except ValueError as e:
        raise MeshError(f"cannot read glTF file ({e})", where=str(path)) from None
    if not isinstance(header, dict):
        raise MeshError("cannot read glTF file (the JSON header is not an object)", where=str(path))
    return header, bin_chunk


def _notes(path: Path, header: dict) -> list[str]:
    """One line per feature of the file that is not rendered."""
    out = extension_notes(path, header)
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
    """:func:`load_gltf`'s reading of the file: the JSON checked against the specification
    (:mod:`warp_sg.scene.importers.gltf_rules`, references by :mod:`~warp_sg.scene.importers.gltf_checks`),
    the data decoded and repacked (:mod:`~warp_sg.scene.importers.gltf_repack`), then read by trimesh."""
    import trimesh

    header, bin_chunk = _read_header(path)
    check_asset(path, header)
    check_references(path, header)
    check_extensions(path, header)
    check_compression(path, header, SUPPORTED_EXTENSIONS)
    check_meshes(path, header)
    check_nodes(path, header)
    check_materials(path, header)
    data = GltfData(path, header, bin_chunk)
    glb, missing = repack(data, images)
    if "KHR_draco_mesh_compression" in present_extensions(header):
        try:
            import DracoPy  # noqa: F401  (trimesh decodes KHR_draco_mesh_compression with it)
        except ImportError as e:
            raise MeshError(f"Draco-compressed meshes need DracoPy ({e})", where=str(path)) from None
    failed = _TrimeshFailures()
    try:
        with failed:
            # (materials always: trimesh drops the UVs with them; without images they cost nothing)
            sc = trimesh.load(io.BytesIO(glb), file_type="glb", force="scene", skip_materials=False)
    except Exception as e:  # noqa: BLE001 - the checks above leave trimesh nothing it cannot read
        raise MeshError(f"cannot read glTF file (trimesh: {e})", where=str(path)) from None
    if failed.messages:  # e.g. a Draco blob that does not decode: trimesh would go on with zeros
        raise MeshError(f"cannot read glTF file ({failed.messages[0]})", where=str(path))
    parts, imgs = [], {}
    for node in sc.graph.nodes_geometry:
        M, gname = sc.graph[node]
        g = sc.geometry[gname]
        if not isinstance(g, trimesh.Trimesh) or len(g.faces) == 0:
            continue
        part = _part(path, node, g, np.asarray(M, np.float64))
        if part is None:
            continue
        parts.append(part)
        mat = getattr(getattr(g, "visual", None), "material", None)
        idx = parts[-1].material = _material_index(mat)
        if idx is not None and idx not in imgs:
            imgs[idx] = {k: getattr(mat, k, None) for k in _TRIMESH_SLOTS}
            if images:
                check_images(path, header, idx, imgs[idx], data)
    if not parts:
        why = f" ({missing[0].split(': ', 1)[1]})" if missing else ""
        raise MeshError(f"the file's scene holds no triangles{why}: nothing to draw", where=str(path))
    notes = _notes(path, header) + missing
    if images:
        notes += _extension_images(path, header, data, imgs)
    return GltfAsset(path=path, parts=parts, header=header, images=imgs, notes=notes)


def _texture_image(data: GltfData, tex: int):
    """The PIL image of texture ``tex`` (its ``source``, or EXT_texture_webp's)."""
    from PIL import Image

    t = data.h["textures"][tex]
    src = ((t.get("extensions") or {}).get("EXT_texture_webp") or {}).get("source", t.get("source"))
    im = Image.open(io.BytesIO(data.image_bytes(src)))
    im.load()
    return im


def _extension_images(path: Path, header: dict, data: GltfData, imgs: dict) -> list[str]:
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
                slots[name] = _texture_image(data, int(info["index"]))
            except Exception:  # noqa: BLE001 - missing files, bad image data (Pillow raises many types)
                slots[name] = None
                bad.append(f"{name} of '{entry.get('name') or f'material{idx}'}'")
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


def _part(path: Path, node: str, g, M: np.ndarray) -> GltfPart | None:
    """Apply the node's world matrix: P' = M P, n' ∝ M⁻ᵀ n, t' ∝ M t (winding flipped when det M < 0);
    None for a singular one (a zero scale: the primitive collapses, nothing is drawn)."""
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
        return None  # a zero scale collapses the primitive (a way files hide a node): nothing to draw
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
