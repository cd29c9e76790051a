r"""The file trimesh reads: a glTF decoded and checked by :mod:`warp_sg.scene.importers.gltf_data`,
written back as one self-contained GLB (issue 51).

:func:`repack` keeps what the importer draws and nothing else: the nodes of the scene to draw
(:func:`drawn_nodes`: the default ``scene``, else the first, else every root node) with their
finite transforms (quaternions normalised), the triangle primitives of their meshes (strips and
fans as triangle lists) whose attributes are dense float32 accessors and indices uint32, the
Draco blobs as they are (trimesh decodes them), the images embedded in the BIN chunk, and each
material as its name tag (``warp_sg_material_<index>``, to find the entry behind trimesh's
material) with the texture slots trimesh reads. The header the materials are converted from stays
the file's own.
"""
from __future__ import annotations

import json
import struct

import numpy as np

from warp_sg.core.errors import MeshError
from warp_sg.scene.importers.gltf_data import ATTRIBUTES, TRIANGLE_MODES, GltfData, MissingData, as_float, triangle_list

_DRACO = "KHR_draco_mesh_compression"
_TAG = "warp_sg_material_"
_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942
#: the texture slots trimesh reads: (path in the material entry)
_SLOTS = (("pbrMetallicRoughness", "baseColorTexture"), ("pbrMetallicRoughness", "metallicRoughnessTexture"),
          ("normalTexture",), ("emissiveTexture",), ("occlusionTexture",))
#: attribute names trimesh keeps as vertex attributes (a leading ``_``)
_RENAMED = {"TANGENT": "_TANGENT", "COLOR_0": "_COLOR_0"}


def scene_roots(h: dict) -> list[int]:
    """The root nodes of the scene to draw: ``scenes[scene]`` (default 0), or, in a file without
    scenes, every node that is nobody's child."""
    nodes = h.get("nodes", [])
    scenes = h.get("scenes", [])
    if scenes:
        return list(dict.fromkeys(scenes[h.get("scene", 0)].get("nodes", [])))
    children = {c for n in nodes for c in n.get("children", [])}
    return [i for i in range(len(nodes)) if i not in children]


def drawn_nodes(h: dict) -> list[int]:
    """The nodes of the scene to draw (:func:`scene_roots` and their descendants), parents first."""
    nodes = h.get("nodes", [])
    out, stack = [], list(reversed(scene_roots(h)))
    seen = set()
    while stack:
        i = stack.pop()
        if i in seen:
            continue
        seen.add(i)
        out.append(i)
        stack.extend(reversed(nodes[i].get("children", [])))
    return out


class _Bin:
    """The BIN chunk being written and its buffer views."""

    def __init__(self):
        self.data, self.views = bytearray(), []

    def add(self, blob: bytes) -> int:
        self.data += b"\0" * (-len(self.data) % 4)
        self.views.append({"buffer": 0, "byteOffset": len(self.data), "byteLength": len(blob)})
        self.data += blob
        return len(self.views) - 1


def morph_weights(h: dict, i: int) -> tuple:
    """The morph weights node ``i`` draws its mesh with (glTF 2.0 §3.7.2.2: the node's ``weights``,
    else the mesh's), () when its mesh has no targets or every weight is 0."""
    n = h["nodes"][i]
    mesh = h["meshes"][n["mesh"]]
    if not any(p.get("targets") for p in mesh.get("primitives", [])):
        return ()
    w = tuple(float(x) for x in n.get("weights", mesh.get("weights", [])))
    return w if any(x != 0.0 for x in w) else ()


def repack(data: GltfData, images: bool = True) -> tuple[bytes, list[str]]:
    """(the GLB trimesh reads, notes): see the module docstring; MeshError naming the element at
    fault. A primitive whose data is not in the file (:class:`~warp_sg.scene.importers.gltf_data.MissingData`)
    is left out with one note line for the file."""
    h = data.h
    out, accessors, missing = _Bin(), [], []
    nodes = [_node(n) for n in h.get("nodes", [])]
    users, variants = {}, {}  # mesh -> a node's name; (mesh, weights) -> index in the new meshes
    for i in drawn_nodes(h):
        if "mesh" in nodes[i]:
            m = nodes[i]["mesh"]
            users.setdefault(m, h["nodes"][i].get("name") or f"nodes[{i}]")
            w = morph_weights(h, i)
            if w:
                nodes[i]["mesh"] = variants.setdefault((m, w), len(h.get("meshes", [])) + len(variants))

    def accessor(arr: np.ndarray, ctype: int, kind: str) -> int:
        accessors.append({"bufferView": out.add(np.ascontiguousarray(arr).tobytes()), "componentType": ctype,
                          "count": int(len(arr)), "type": kind})
        return len(accessors) - 1

    def mesh_entry(mi: int, weights: tuple) -> dict:
        mesh, prims = h["meshes"][mi], []
        for pi, p in enumerate(mesh.get("primitives", []) if mi in users else []):
            try:
                q = _primitive(data, out, accessors, accessor, f"meshes[{mi}].primitives[{pi}]", p, users[mi], weights)
            except MissingData as e:
                missing.append(f"meshes[{mi}].primitives[{pi}] ({str(e).split(': ', 1)[-1].split(' has no uri')[0]} "
                               f"has no data)")
                continue
            if q is not None:
                prims.append(q)
        return {"name": str(mesh.get("name") or f"mesh{mi}"), "primitives": prims}

    meshes = [mesh_entry(mi, ()) for mi in range(len(h.get("meshes", [])))]
    meshes += [mesh_entry(mi, w) for (mi, w) in variants]
    new = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": scene_roots(h)}],
           "nodes": nodes, "meshes": meshes, "accessors": accessors}
    if images:
        new["images"] = [_image(data, out, i) for i in range(len(h.get("images", [])))]
        new["textures"] = [_texture(t) for t in h.get("textures", [])]
    new["materials"] = [_material(i, m, images) for i, m in enumerate(h.get("materials", []))]
    if not out.views:  # trimesh reads the accessors only when the file has buffer views
        out.add(b"\0" * 4)
    out.data += b"\0" * (max(4 - len(out.data), 0) + (-len(out.data) % 4))
    new["bufferViews"] = out.views
    new["buffers"] = [{"byteLength": len(out.data)}]
    if _DRACO in (h.get("extensionsUsed") or []):
        new["extensionsUsed"] = [_DRACO]
    notes = [f"{data.path.name}: primitives whose data is not in the file are not drawn: {', '.join(missing[:3])}"
             + (f" and {len(missing) - 3} more" if len(missing) > 3 else "")] if missing else []
    return _glb(new, bytes(out.data)), notes


def _node(n: dict) -> dict:
    """A node's name, children, mesh and transform (quaternion normalised); nothing else."""
    out = {k: n[k] for k in ("name", "children", "mesh", "matrix", "translation", "scale") if k in n}
    if "name" in out:
        out["name"] = str(out["name"])
    if "rotation" in n:
        q = np.asarray(n["rotation"], np.float64)
        out["rotation"] = (q / np.linalg.norm(q)).tolist()
    return out


def _primitive(data: GltfData, out: _Bin, accessors: list, accessor, where: str, p: dict, node: str,
               weights: tuple = ()):
    """The repacked primitive (triangles, dense attributes, morph ``weights`` applied), or None when
    it draws nothing (no triangles, or only triangles of zero area: an accessor without data)."""
    mode = p.get("mode", 4)
    attr = p.get("attributes", {})
    if mode not in TRIANGLE_MODES or "POSITION" not in attr:
        return None  # points and lines (reported by the notes); no positions: nothing to draw (§3.7.2.1)
    q = {"mode": 4}
    if "material" in p:
        q["material"] = p["material"]
    ext = p.get("extensions") or {}
    if _DRACO in ext:
        if weights:
            raise MeshError(f"{where}: morph targets of a Draco-compressed primitive are not rendered (its weights "
                            f"are {list(weights)})", where=str(data.path))
        return _draco(data, out, accessors, where, p, q, ext[_DRACO])
    h = data.h
    pos = _attribute(data, "POSITION", attr["POSITION"], f"{where}.attributes.POSITION")
    bad = np.flatnonzero(~np.isfinite(pos).all(1))
    if len(bad):
        raise MeshError(f"{where}.attributes.POSITION: vertex {bad[0]} is non-finite ({pos[bad[0]].tolist()}) "
                        f"(node '{node}')", where=str(data.path))
    n = len(pos)
    arrays = {"POSITION": pos}
    for name in ("NORMAL", "TANGENT", "TEXCOORD_0", "COLOR_0"):
        if name not in attr:
            continue
        at = f"{where}.attributes.{name}"
        a = _attribute(data, name, attr[name], at)
        if len(a) != n:
            raise MeshError(f"{at}: {len(a)} elements, POSITION has {n} (every attribute of a primitive has the "
                            f"same count, glTF 2.0 §3.7.2.1)", where=str(data.path))
        arrays[name] = a
    if weights:
        _morph(data, where, p, weights, arrays)
    q["attributes"] = {_RENAMED.get(k, k): accessor(a, 5126, f"VEC{a.shape[1]}") for k, a in arrays.items()}
    if "indices" in p:
        at = f"{where}.indices"
        a = h["accessors"][p["indices"]]
        idx = data.accessor(p["indices"], at)
        if a.get("type") != "SCALAR" or a.get("componentType") not in (5121, 5123, 5125):
            raise MeshError(f"{at}: accessors[{p['indices']}] must be SCALAR of an unsigned integer type (5121, "
                            f"5123 or 5125), got {a.get('type')} of {a.get('componentType')} (glTF 2.0 §3.7.2.1)",
                            where=str(data.path))
        idx = idx.reshape(-1).astype(np.int64)
    else:
        at, idx = f"{where} (no indices)", np.arange(n)
    if mode == 4 and len(idx) % 3:
        raise MeshError(f"{at}: {len(idx)} indices do not make whole triangles (a multiple of 3, glTF 2.0 §3.7.2.1)",
                        where=str(data.path))
    tris = triangle_list(idx, mode)
    over = np.flatnonzero((tris >= n).any(1))
    if len(over):
        t = int(over[0])
        raise MeshError(f"{at}: triangle {t} has a vertex index out of range ({int(tris[t].max())} ≥ {n} vertices "
                        f"of POSITION; node '{node}')", where=str(data.path))
    if not len(tris):
        return None
    v = arrays["POSITION"].astype(np.float64)
    area = np.linalg.norm(np.cross(v[tris[:, 1]] - v[tris[:, 0]], v[tris[:, 2]] - v[tris[:, 0]]), axis=1)
    if not np.any(area > 0.0):
        return None  # (zeros: an accessor without a buffer view, as the specification allows)
    q["indices"] = accessor(tris.astype(np.uint32).reshape(-1), 5125, "SCALAR")
    return q


def _morph(data: GltfData, where: str, p: dict, weights: tuple, arrays: dict) -> None:
    """``arrays`` + Σ_k weights[k] · targets[k] for POSITION, NORMAL and TANGENT (xyz), glTF 2.0
    §3.7.2.2 (normals and tangents renormalised); in place."""
    n = len(arrays["POSITION"])
    for k, target in enumerate(p.get("targets", [])[:len(weights)]):
        if weights[k] == 0.0:
            continue
        for name in ("POSITION", "NORMAL", "TANGENT"):
            if name not in target or name not in arrays:
                continue
            at = f"{where}.targets[{k}].{name}"
            d = _attribute(data, "TARGET", target[name], at)
            if len(d) != n:
                raise MeshError(f"{at}: {len(d)} elements, POSITION has {n}", where=str(data.path))
            arrays[name] = arrays[name].copy()
            arrays[name][:, :3] += np.float32(weights[k]) * d
    for name in ("NORMAL", "TANGENT"):
        if name in arrays and weights:
            xyz = arrays[name][:, :3]
            xyz /= np.maximum(np.linalg.norm(xyz, axis=1, keepdims=True), 1e-30)


def _attribute(data: GltfData, name: str, j: int, where: str) -> np.ndarray:
    """Attribute ``name`` of accessor ``j`` as float32, its type and component type checked."""
    a = data.h["accessors"][j]
    kinds, ctypes = ATTRIBUTES[name]
    arr = data.accessor(j, where)
    if a.get("type") not in kinds or a.get("componentType") not in ctypes:
        raise MeshError(f"{where}: accessors[{j}] is {a.get('type')} of componentType {a.get('componentType')}; "
                        f"{name} must be {' or '.join(kinds)} of {', '.join(map(str, ctypes))} (glTF 2.0 §3.7.2.1, "
                        f"KHR_mesh_quantization)", where=str(data.path))
    return as_float(arr, a["componentType"], bool(a.get("normalized", False)))


def _draco(data: GltfData, out: _Bin, accessors: list, where: str, p: dict, q: dict, ext) -> dict:
    """A Draco primitive as the file has it: header-only accessors trimesh's decoder fills, the blob."""
    if not isinstance(ext, dict) or not isinstance(ext.get("bufferView"), int) or not isinstance(ext.get("attributes"),
                                                                                                  dict):
        raise MeshError(f"{where}.extensions.{_DRACO} must have a bufferView and an attributes object",
                        where=str(data.path))
    blob, _ = data.view(ext["bufferView"])
    mapping = {}
    q["attributes"] = {}
    for name in ("POSITION", "NORMAL", "TANGENT", "TEXCOORD_0", "COLOR_0"):
        if name not in p["attributes"]:
            continue
        a = data.h["accessors"][p["attributes"][name]]
        accessors.append({k: a[k] for k in ("componentType", "count", "type") if k in a})
        q["attributes"][_RENAMED.get(name, name)] = len(accessors) - 1
        if name in ext["attributes"]:
            mapping[_RENAMED.get(name, name)] = ext["attributes"][name]
    if "indices" in p:
        a = data.h["accessors"][p["indices"]]
        accessors.append({k: a[k] for k in ("componentType", "count", "type") if k in a})
        q["indices"] = len(accessors) - 1
    q["extensions"] = {_DRACO: {"bufferView": out.add(blob), "attributes": mapping}}
    return q


def _image(data: GltfData, out: _Bin, i: int) -> dict:
    """Image ``i`` embedded (an unreadable one as an empty view: trimesh then has no image, and
    ``gltf_checks.check_images`` names why)."""
    try:
        blob = data.image_bytes(i)
    except MeshError:
        blob = b""
    img = data.h["images"][i]
    return {"bufferView": out.add(blob), "mimeType": str(img.get("mimeType") or "image/png")}


def _texture(t: dict) -> dict:
    out = {k: t[k] for k in ("source",) if k in t}
    webp = (t.get("extensions") or {}).get("EXT_texture_webp")
    if isinstance(webp, dict) and "source" in webp:
        out["source"] = webp["source"]  # (decoded by Pillow like any other image)
    return out


def _material(i: int, m: dict, images: bool) -> dict:
    out = {"name": f"{_TAG}{i}"}
    if not images:
        return out
    for keys in _SLOTS:
        d = m
        for k in keys:
            d = d.get(k) if isinstance(d, dict) else None
        if isinstance(d, dict) and "index" in d:
            tgt = out
            for k in keys[:-1]:
                tgt = tgt.setdefault(k, {})
            tgt[keys[-1]] = {"index": d["index"]}
    return out


def _glb(header: dict, bin_data: bytes) -> bytes:
    text = json.dumps(header).encode("utf-8")
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), _JSON_CHUNK) + text
    if bin_data:
        bin_data += b"\0" * (-len(bin_data) % 4)
        body += struct.pack("<II", len(bin_data), _BIN_CHUNK) + bin_data
    return struct.pack("<III", _GLB_MAGIC, 2, 12 + len(body)) + body


__all__ = ["scene_roots", "drawn_nodes", "repack"]
