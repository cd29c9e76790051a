"""Small glTF 2.0 files written by the tests themselves (JSON + numpy buffers, glTF 2.0 §3, §4):
the features exporters write — emission, cut-outs, texture transforms, vertex colours, clear coat,
ior/specular, quantised attributes (KHR_mesh_quantization) and Draco (DracoPy) — each where a test
sets it, so the expectations come from the specification, not from the importer's code."""
from __future__ import annotations

import io
import json
import struct

import numpy as np

FLOAT, U8, U16, U32, I16 = 5126, 5121, 5123, 5125, 5122
_NP = {FLOAT: np.float32, U8: np.uint8, U16: np.uint16, U32: np.uint32, I16: np.int16}
_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}


def png(rgba: np.ndarray) -> bytes:
    """PNG bytes of an (H, W, 3|4) uint8 image (row 0 at the top, as glTF images are)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgba, np.uint8)).save(buf, format="PNG")
    return buf.getvalue()


class GltfWriter:
    """Accumulates buffer views, accessors, meshes, nodes, materials and images; :meth:`glb` writes."""

    def __init__(self):
        self.bin = bytearray()
        self.h = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": []}], "nodes": [], "meshes": [],
                  "accessors": [], "bufferViews": [], "buffers": [{"byteLength": 0}], "materials": []}
        self.used = set()

    def view(self, data: bytes) -> int:
        self.bin += b"\0" * (-len(self.bin) % 4)
        self.h["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)})
        self.bin += data
        return len(self.h["bufferViews"]) - 1

    def accessor(self, a: np.ndarray, ctype: int = FLOAT, normalized: bool = False) -> int:
        a = np.asarray(a)
        a2 = a.reshape(len(a), -1)
        acc = {"bufferView": self.view(np.ascontiguousarray(a2.astype(_NP[ctype])).tobytes()), "componentType": ctype,
               "count": len(a), "type": _TYPES[a2.shape[1]]}
        if normalized:
            acc["normalized"] = True
        if a2.shape[1] == 3 and ctype == FLOAT:
            acc["min"], acc["max"] = a2.min(0).tolist(), a2.max(0).tolist()
        self.h["accessors"].append(acc)
        return len(self.h["accessors"]) - 1

    def image(self, rgba: np.ndarray) -> int:
        """A texture (PNG in the buffer) of an (H, W, 3|4) uint8 image; returns the texture index."""
        self.h.setdefault("images", []).append({"bufferView": self.view(png(rgba)), "mimeType": "image/png"})
        self.h.setdefault("textures", []).append({"source": len(self.h["images"]) - 1})
        return len(self.h["textures"]) - 1

    def material(self, entry: dict) -> int:
        self.h["materials"].append(entry)
        for ext in entry.get("extensions", {}):
            self.used.add(ext)
        return len(self.h["materials"]) - 1

    def mesh(self, positions, indices, normals=None, uvs=None, colors=None, material=None, matrix=None,
             name="mesh", quantize=False, draco=False) -> int:
        """A one-primitive mesh under its own node (``matrix``: its 4×4 transform). ``uvs`` in glTF's
        convention (origin top-left). ``quantize``: positions as normalized int16 and uvs as
        normalized uint16 (KHR_mesh_quantization); ``draco``: the primitive Draco-compressed."""
        positions = np.asarray(positions, np.float64)
        prim = {"attributes": {}, "mode": 4}
        if draco:
            import DracoPy

            blob = DracoPy.encode(positions.astype(np.float32), np.asarray(indices, np.uint32).reshape(-1, 3),
                                  quantization_bits=16, preserve_order=True,
                                  normals=None if normals is None else np.asarray(normals, np.float64),
                                  tex_coord=None if uvs is None else np.asarray(uvs, np.float64))
            # the extension maps each glTF attribute to its Draco unique id (Draco attribute types:
            # 0 position, 1 normal, 3 texture coordinate)
            kinds = {0: "POSITION", 1: "NORMAL", 3: "TEXCOORD_0"}
            ids = {kinds[a["attribute_type"]]: a["unique_id"] for a in DracoPy.decode(blob).attributes}
            for name_, n in (("POSITION", 3), ("NORMAL", 3), ("TEXCOORD_0", 2)):
                if name_ in ids:
                    self.h["accessors"].append({"componentType": FLOAT, "count": len(positions), "type": _TYPES[n]})
                    prim["attributes"][name_] = len(self.h["accessors"]) - 1
            self.h["accessors"].append({"componentType": U32, "count": int(np.size(indices)), "type": "SCALAR"})
            prim["indices"] = len(self.h["accessors"]) - 1
            prim["extensions"] = {"KHR_draco_mesh_compression": {"bufferView": self.view(blob), "attributes": ids}}
            self.used.add("KHR_draco_mesh_compression")
            self.h.setdefault("extensionsRequired", []).append("KHR_draco_mesh_compression")
        else:
            if quantize:
                prim["attributes"]["POSITION"] = self.accessor(np.round(positions * 32767.0), I16, normalized=True)
                self.used.add("KHR_mesh_quantization")
                self.h.setdefault("extensionsRequired", []).append("KHR_mesh_quantization")
            else:
                prim["attributes"]["POSITION"] = self.accessor(positions)
            if normals is not None:
                prim["attributes"]["NORMAL"] = self.accessor(normals)
            if uvs is not None:
                if quantize:
                    prim["attributes"]["TEXCOORD_0"] = self.accessor(np.round(np.asarray(uvs) * 65535.0), U16,
                                                                     normalized=True)
                else:
                    prim["attributes"]["TEXCOORD_0"] = self.accessor(uvs)
            if colors is not None:
                prim["attributes"]["COLOR_0"] = self.accessor(colors)
            prim["indices"] = self.accessor(np.asarray(indices, np.uint32).reshape(-1), U32)
        if material is not None:
            prim["material"] = material
        self.h["meshes"].append({"name": name, "primitives": [prim]})
        node = {"name": name, "mesh": len(self.h["meshes"]) - 1}
        if matrix is not None:
            node["matrix"] = np.asarray(matrix, np.float64).T.reshape(-1).tolist()  # column-major
        self.h["nodes"].append(node)
        self.h["scenes"][0]["nodes"].append(len(self.h["nodes"]) - 1)
        return len(self.h["nodes"]) - 1

    def gltf(self, path, uri: str | None = None):
        """A ``.gltf`` (JSON) whose buffer is a base64 ``data:`` URI, or the file ``uri`` (a URI:
        ``%20`` for a space) beside it."""
        import base64

        h = dict(self.h)
        data = bytes(self.bin)
        if uri is None:
            buf = {"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}
        else:
            from urllib.parse import unquote

            (path.parent / unquote(uri)).write_bytes(data)
            buf = {"byteLength": len(data), "uri": uri}
        h["buffers"] = [buf]
        if self.used:
            h["extensionsUsed"] = sorted(self.used)
        if "extensionsRequired" in h:
            h["extensionsRequired"] = sorted(set(h["extensionsRequired"]))
        path.write_text(json.dumps(h))
        return path

    def glb(self, path):
        h = dict(self.h)
        h["buffers"] = [{"byteLength": len(self.bin)}]
        if self.used:
            h["extensionsUsed"] = sorted(self.used)
        if "extensionsRequired" in h:
            h["extensionsRequired"] = sorted(set(h["extensionsRequired"]))
        js = json.dumps(h).encode()
        js += b" " * (-len(js) % 4)
        b = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(b), 0x004E4942) + b
        path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)
        return path


def quad(size=1.0, y=0.0, n=1):
    """A horizontal square (facing +Y) of side ``size`` at height ``y``, ``n × n`` cells: (positions,
    indices, normals, glTF uvs with u along +X and v along +Z)."""
    s = np.linspace(-size / 2, size / 2, n + 1)
    X, Z = np.meshgrid(s, s)
    P = np.stack([X.ravel(), np.full(X.size, y), Z.ravel()], 1)
    uv = np.stack([(X.ravel() + size / 2) / size, (Z.ravel() + size / 2) / size], 1)
    idx = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            idx += [[a, a + n + 1, a + 1], [a + 1, a + n + 1, a + n + 2]]
    return P, np.asarray(idx), np.tile([0.0, 1.0, 0.0], (len(P), 1)), uv


def uv_sphere(radius=0.5, centre=(0.0, 0.5, 0.0), n_theta=24, n_phi=48):
    """A UV sphere: (positions, indices, normals, uvs)."""
    th = np.linspace(0, np.pi, n_theta + 1)
    ph = np.linspace(0, 2 * np.pi, n_phi + 1)
    T, Ph = np.meshgrid(th, ph, indexing="ij")
    N = np.stack([np.sin(T) * np.cos(Ph), np.cos(T), np.sin(T) * np.sin(Ph)], -1).reshape(-1, 3)
    uv = np.stack([Ph / (2 * np.pi), T / np.pi], -1).reshape(-1, 2)
    idx = []
    w = n_phi + 1
    for i in range(n_theta):
        for j in range(n_phi):
            a, b = i * w + j, (i + 1) * w + j
            if i > 0:
                idx.append([a, a + 1, b])
            if i < n_theta - 1:
                idx.append([a + 1, b + 1, b])
    return N * radius + np.asarray(centre), np.asarray(idx), N, uv
