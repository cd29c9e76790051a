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

PBR metallic-roughness → ``ggx`` (glTF 2.0 Appendix B, "BRDF implementation"), per texel::

    base  = baseColorFactor · sRGB⁻¹(baseColorTexture)          (linear RGB)
    metal = metallicFactor · metallicRoughnessTexture.B
    rough = roughnessFactor · metallicRoughnessTexture.G
    kd    = base · (1 − metal)                                   (Lambert, kd/π)
    F0    = 0.04 · (1 − metal) + base · metal                    (Schlick)
    α     = max(rough², ALPHA_MIN)                              (Trowbridge–Reitz)

``fresnel = {schlick = F0}`` is a per-material constant in the renderer; when F0 varies over the
texture, the material gets ``f0 = mean F0`` and a ``ks`` texture ``F0(x) / mean F0``, which is
exact at normal incidence (the Schlick rise towards grazing is that of the mean F0).
Normal textures (tangent space, +Y = ``n × t`` for ``tangent.w = +1``) are rescaled by
``normalTexture.scale`` in x and y and stored as the material's ``normal_map``; tangents come from
the file or are generated from the UVs (:func:`warp_sg.geometry.uv_tangents`).

Extensions, occlusion and emissive textures, alpha modes, vertex colours, second UV sets and
animations are not rendered: each is reported once as an :class:`AssetWarning` (one line) and
ignored. An unreadable file raises :class:`~warp_sg.errors.MeshError` naming it; so do an index
that points past its list (``meshes[0].primitives[0].indices = 9: the file has 2 accessors``), a
node graph with a cycle, meshes compressed by an extension that cannot be decoded
(:mod:`warp_sg.gltf_checks`), and a primitive with non-finite positions or out-of-range vertex
indices (naming the node). A texture whose image cannot be read (a missing file, a corrupt image)
raises :class:`~warp_sg.errors.ImageError` naming the material, the texture and the image: an
untextured image would be a wrong answer.
"""
from __future__ import annotations

import io
import json
import struct
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ImageError, MeshError
from .geometry import validate_mesh
from .gltf_checks import check_compression, check_images, check_references
from .meshcheck import check_mesh
from .textures import Texture, sample_bilinear_np, srgb_to_linear

GLTF_SUFFIXES = (".glb", ".gltf")
#: glTF extensions whose meaning the importer renders (everything else is reported and ignored)
SUPPORTED_EXTENSIONS: frozenset = frozenset()
#: smallest GGX α the importer emits (glTF roughness 0 is a perfect mirror)
ALPHA_MIN = 1e-2
#: F0 of glTF dielectrics (index of refraction 1.5)
DIELECTRIC_F0 = 0.04

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


def _retagged(path: Path, header: dict, raw: bytes) -> bytes:
    """The file with ``TANGENT`` attributes renamed ``_TANGENT`` (trimesh keeps ``_`` attributes)
    and every material named by its index (to find the header entry behind trimesh's material)."""
    h = json.loads(json.dumps(header))
    for mesh in h.get("meshes", []):
        for prim in mesh.get("primitives", []):
            attr = prim.get("attributes", {})
            if "TANGENT" in attr:
                attr["_TANGENT"] = attr.pop("TANGENT")
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
    mats = header.get("materials", [])
    checks = (("occlusionTexture", "occlusion textures"), ("emissiveTexture", "emissive textures"))
    for key, what in checks:
        if any(key in m for m in mats):
            out.append(f"{path.name}: {what} are not rendered; ignored")
    if any(any(float(x) > 0 for x in m.get("emissiveFactor", [])) for m in mats):
        out.append(f"{path.name}: emission (emissiveFactor) is not rendered; ignored")
    if any(m.get("alphaMode", "OPAQUE") != "OPAQUE" for m in mats):
        out.append(f"{path.name}: alpha modes MASK/BLEND are not rendered; surfaces are opaque")
    texs = [t for m in mats for t in [m.get("normalTexture", {}), *m.get("pbrMetallicRoughness", {}).values()]
            if isinstance(t, dict)]
    if any(t.get("texCoord", 0) != 0 for t in texs):
        out.append(f"{path.name}: textures on a second UV set (texCoord > 0) read TEXCOORD_0")
    prims = [p for m in header.get("meshes", []) for p in m.get("primitives", [])]
    if any("COLOR_0" in p.get("attributes", {}) for p in prims):
        out.append(f"{path.name}: vertex colours (COLOR_0) are not rendered; ignored")
    if any(p.get("mode", 4) not in (4, 5) for p in prims):
        out.append(f"{path.name}: point, line and fan primitives are not rendered; skipped")
    if header.get("animations") or header.get("skins"):
        out.append(f"{path.name}: animations and skins are not rendered; the rest pose is used")
    return out


def load_gltf(path, *, images: bool = True) -> GltfAsset:
    """Read a glTF 2.0 file: every triangle primitive in world space (:class:`GltfPart`), the
    header, the texture images of each material (``images=False`` skips them) and the notes."""
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise MeshError("glTF file not found", where=str(path))
    header, raw = _read_header(path)
    check_references(path, header)
    check_compression(path, header, SUPPORTED_EXTENSIONS)
    data = _retagged(path, header, raw)
    try:
        resolver = trimesh.resolvers.FilePathResolver(str(path))
        sc = trimesh.load(io.BytesIO(data), file_type=path.suffix.lower()[1:], resolver=resolver, force="scene",
                          skip_materials=not images)
    except Exception as e:  # noqa: BLE001 - trimesh raises many types for broken files
        raise MeshError(f"cannot read glTF file ({type(e).__name__}: {e})", where=str(path)) from None
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
            imgs[idx] = {k: getattr(mat, k, None) for k in ("baseColorTexture", "metallicRoughnessTexture",
                                                               "normalTexture")}
            if images:
                check_images(path, header, idx, imgs[idx])
    if not parts:
        raise MeshError("glTF file contains no triangles", where=str(path))
    return GltfAsset(path=path, parts=parts, header=header, images=imgs, notes=_notes(path, header))


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
                    tangents=None if tan is None else tan.astype(np.float32), material=None)


# --------------------------------------------------------------------------------------------
# materials
# --------------------------------------------------------------------------------------------
def _image(img, where: str) -> np.ndarray:
    """A PIL image as float32 (H, W, 4) code values in [0, 1]."""
    from .textures import to_rgba

    try:  # Pillow decodes lazily: a truncated or corrupt image fails here
        if img.mode in ("I;16", "I;16B", "I;16L", "I"):
            a = np.asarray(img, np.float32) / 65535.0
        else:
            a = np.asarray(img.convert("RGBA") if img.mode not in ("L", "LA", "RGB", "RGBA") else img,
                           np.float32) / 255.0
    except (OSError, ValueError, SyntaxError) as e:
        raise ImageError(f"cannot decode the image ({type(e).__name__}: {e})", where=where) from None
    return to_rgba(a, where)


def _on_grid(a: np.ndarray | None, shape) -> np.ndarray | None:
    """Resample an (H, W, 4) texture bilinearly at the texel centres of an (h, w) grid."""
    if a is None or a.shape[:2] == tuple(shape):
        return a
    h, w = shape
    u = (np.arange(w) + 0.5) / w
    v = 1.0 - (np.arange(h) + 0.5) / h
    uv = np.stack(np.meshgrid(u, v), -1)
    return sample_bilinear_np(a, uv)


def pbr_to_ggx(base, metal, rough) -> dict:
    """glTF metallic-roughness → GGX values (arrays broadcast): ``kd``, ``f0``, ``alpha``
    (module docstring)."""
    base = np.asarray(base, np.float64)
    metal = np.asarray(metal, np.float64)[..., None]
    rough = np.asarray(rough, np.float64)
    return {"kd": base * (1.0 - metal), "f0": DIELECTRIC_F0 * (1.0 - metal) + base * metal,
            "alpha": np.maximum(rough * rough, ALPHA_MIN)}


def gltf_material(entry: dict | None, images: dict | None, where: str = "glTF") -> dict:
    """The ``ggx`` material of one glTF material entry as :class:`warp_sg.scene.Material` keyword
    arguments (``model``, ``params``, ``textures``, ``normal_map``); ``None``: the glTF default
    material (base colour 1, metallic 1, roughness 1)."""
    entry = entry or {}
    images = images or {}
    pbr = entry.get("pbrMetallicRoughness", {})
    bcf = np.asarray(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0]), np.float64)[:3]
    mf = float(pbr.get("metallicFactor", 1.0))
    rf = float(pbr.get("roughnessFactor", 1.0))
    bt = images.get("baseColorTexture") if "baseColorTexture" in pbr else None
    mrt = images.get("metallicRoughnessTexture") if "metallicRoughnessTexture" in pbr else None
    bt = None if bt is None else _image(bt, f"{where}: baseColorTexture")
    mrt = None if mrt is None else _image(mrt, f"{where}: metallicRoughnessTexture")
    params, textures = {}, {}
    if bt is None and mrt is None:
        g = pbr_to_ggx(bcf, mf, rf)
        params.update(kd=g["kd"].tolist(), alpha=float(g["alpha"]), fresnel={"schlick": g["f0"].tolist()})
    else:
        shape = max((a.shape[:2] for a in (bt, mrt) if a is not None), key=lambda s: s[0] * s[1])
        bt, mrt = _on_grid(bt, shape), _on_grid(mrt, shape)
        base = bcf * (srgb_to_linear(bt[..., :3]) if bt is not None else np.ones(shape + (3,)))
        metal = mf * (mrt[..., 2] if mrt is not None else np.ones(shape))
        rough = rf * (mrt[..., 1] if mrt is not None else np.ones(shape))
        g = pbr_to_ggx(base, metal, rough)
        textures["kd"] = Texture(data=g["kd"].astype(np.float32))
        if mrt is not None:
            textures["alpha"] = Texture(data=g["alpha"].astype(np.float32))
        else:
            params["alpha"] = float(pbr_to_ggx(1.0, 0.0, rf)["alpha"])
        f0 = g["f0"].reshape(-1, 3)
        f0_ref = np.clip(f0.mean(0), 1e-4, 1.0)
        params["fresnel"] = {"schlick": f0_ref.tolist()}
        if np.ptp(f0, axis=0).max() > 1e-6:
            textures["ks"] = Texture(data=(g["f0"] / f0_ref).astype(np.float32))
    nt = images.get("normalTexture") if "normalTexture" in entry else None
    normal_map = None
    if nt is not None:
        s = float(entry["normalTexture"].get("scale", 1.0))
        n = 2.0 * _image(nt, f"{where}: normalTexture")[..., :3] - 1.0
        n[..., :2] *= s
        n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
        normal_map = Texture(data=((n + 1.0) / 2.0).astype(np.float32))
    return {"model": "ggx", "params": params, "textures": textures, "normal_map": normal_map}


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
    parts = [GltfPart(name=f"{label}/{p.name}", vertices=p.vertices, triangles=p.triangles, normals=p.normals,
                      uvs=p.uvs, tangents=p.tangents, material=keys[p.material]) for p in asset.parts]
    return parts, specs


__all__ = ["AssetWarning", "GltfAsset", "GltfPart", "GLTF_SUFFIXES", "ALPHA_MIN", "DIELECTRIC_F0",
           "SUPPORTED_EXTENSIONS", "is_gltf", "load_gltf", "pbr_to_ggx", "gltf_material", "gltf_object_parts"]
