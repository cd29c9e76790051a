r"""glTF 2.0 binary data read by the importer itself, against the specification, before trimesh
sees the file (issue 51).

:class:`GltfData` reads the buffers — the GLB's BIN chunk, ``data:`` URIs (base64, any media
type) and files *inside the asset's folder* (a relative path, no scheme, no way out through ``..``
or a link: never the network, never the rest of the disk) — and decodes accessors with numpy
(glTF 2.0 §3.6: component types, ``byteOffset``, ``byteStride``, ``normalized`` integers, sparse
substitution, accessors without a buffer view read as zeros). Every refusal is a
:class:`~warp_sg.core.errors.MeshError` naming the glTF element and the rule, e.g.
``meshes[0].primitives[1].attributes.POSITION: accessors[3] reads bytes 0–48 of bufferViews[1],
which holds 36 (an accessor must fit its buffer view, glTF 2.0 §3.6.2.4)``.

:func:`repack` then writes the file trimesh reads: one GLB whose accessors are the decoded,
dense float32 attributes (``TANGENT`` and ``COLOR_0`` renamed ``_TANGENT``/``_COLOR_0`` so trimesh
keeps them) and uint32 triangle indices (strips and fans turned into triangle lists, §3.7.2.1), the
images embedded, every material reduced to its name tag and the texture slots trimesh reads, the
nodes of the scene to draw and nothing else (no skins, cameras, animations, morph targets, unused
accessors). What trimesh would stumble on (a missing ``bufferViews`` list, sparse accessors read as
zeros, an image path outside the folder) never reaches it.
"""
from __future__ import annotations

import base64
import re
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from warp_sg.core.errors import MeshError
from warp_sg.core.watchdog import MAX_TRIANGLES, check_size

#: componentType → numpy dtype (little-endian), glTF 2.0 §3.6.2.2
COMPONENTS = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
#: accessor type → components
TYPES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
#: normalized integer c → float: max(c / (2^(b−1) − 1), −1) signed, c / (2^b − 1) unsigned (§3.6.2.1)
NORMALIZED = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0, 5125: 4294967295.0}
#: the attributes the importer reads: name → (accepted types, accepted componentTypes) — the core
#: specification's (§3.7.2.1) with KHR_mesh_quantization's integer forms
ATTRIBUTES = {
    "POSITION": (("VEC3",), (5126, 5120, 5121, 5122, 5123)),
    "NORMAL": (("VEC3",), (5126, 5120, 5122)),
    "TANGENT": (("VEC4",), (5126, 5120, 5122)),
    "TEXCOORD_0": (("VEC2",), (5126, 5120, 5121, 5122, 5123)),
    "COLOR_0": (("VEC3", "VEC4"), (5126, 5121, 5123)),
    "TARGET": (("VEC3",), (5126, 5120, 5121, 5122, 5123)),  # a morph target's displacement (§3.7.2.2)
}
#: primitive modes: 4 triangles, 5 strip, 6 fan (drawn); 0–3 points and lines (not drawn)
TRIANGLE_MODES = (4, 5, 6)
_DRACO = "KHR_draco_mesh_compression"
_TAG = "warp_sg_material_"
_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942
#: ``data:[<media type>][;base64],<data>`` (RFC 2397)
_DATA_URI = re.compile(r"^data:([^,;]*)((?:;[^,;]*)*),(.*)$", re.S)


class MissingData(MeshError):
    """A buffer whose bytes are not in the file (no ``uri`` and no GLB BIN chunk): what reads it is
    not drawn (valid glTF JSON, the data left out)."""


def glb_chunks(raw: bytes) -> tuple[bytes, bytes | None]:
    """(JSON bytes, BIN chunk or None) of a GLB (glTF 2.0 §4.4: 12-byte header, then chunks of
    ``length, type, data``; JSON first, at most one BIN after it); ValueError naming what is wrong."""
    if len(raw) < 20:
        raise ValueError(f"not a binary glTF ({len(raw)} bytes; a GLB has a 12-byte header and a JSON chunk)")
    magic, version, length = struct.unpack_from("<III", raw, 0)
    if magic != _GLB_MAGIC:
        raise ValueError("not a binary glTF (the GLB magic 'glTF' is missing)")
    if version != 2:
        raise ValueError(f"GLB version {version}; only glTF 2.0 is read")
    if length > len(raw):
        raise ValueError(f"the GLB header declares {length} bytes, the file holds {len(raw)}")
    chunks, off = [], 12
    while off + 8 <= length:
        n, kind = struct.unpack_from("<II", raw, off)
        if off + 8 + n > length:
            raise ValueError(f"GLB chunk {len(chunks)} declares {n} bytes past the end of the file")
        chunks.append((kind, raw[off + 8:off + 8 + n]))
        off += 8 + n + (-n % 4)
    if not chunks:
        raise ValueError(f"the GLB header declares {length} bytes, too few for its JSON chunk")
    if chunks[0][0] != _JSON_CHUNK:
        raise ValueError("the first GLB chunk is not JSON")
    bins = [c for k, c in chunks[1:] if k == _BIN_CHUNK]
    if len(bins) > 1 or (len(chunks) > 1 and chunks[1][0] != _BIN_CHUNK and bins):
        raise ValueError("a GLB holds at most one BIN chunk, right after the JSON chunk")
    return chunks[0][1], (bins[0] if bins else None)


class GltfData:
    """The buffers, buffer views, images and accessors of one glTF file, read on demand."""

    def __init__(self, path: Path, header: dict, bin_chunk: bytes | None):
        self.path, self.h, self.bin = Path(path), header, bin_chunk
        self.folder = self.path.resolve().parent
        self._buffers: dict = {}

    # sources ------------------------------------------------------------------------------
    def uri_bytes(self, uri, where: str) -> bytes:
        """The bytes a ``uri`` names: a ``data:`` URI (base64) or a file inside the asset's folder."""
        if not isinstance(uri, str):
            raise MeshError(f"{where}.uri must be a string", where=str(self.path))
        m = _DATA_URI.match(uri)
        if m:
            if ";base64" not in m.group(2):
                raise MeshError(f"{where}.uri: a data: URI must be base64-encoded (glTF 2.0 §3.6.1)",
                                where=str(self.path))
            try:
                return base64.b64decode(m.group(3), validate=True)
            except ValueError:
                raise MeshError(f"{where}.uri: the data: URI is not valid base64", where=str(self.path)) from None
        if uri.startswith("data:"):
            raise MeshError(f"{where}.uri: malformed data: URI (expected data:<type>;base64,<data>)",
                            where=str(self.path))
        short = uri if len(uri) <= 60 else uri[:57] + "..."
        if re.match(r"^[A-Za-z][A-Za-z0-9+.-]*:", uri) and not re.match(r"^[A-Za-z]:[\\/]", uri):
            raise MeshError(f"{where}.uri '{short}': only data: URIs and files beside the asset are read "
                            f"(no network)", where=str(self.path))
        rel = unquote(uri)
        if not rel or rel.startswith(("/", "\\")) or re.match(r"^[A-Za-z]:", rel) or "\0" in rel:
            raise MeshError(f"{where}.uri '{short}': must be a relative path inside the asset's folder",
                            where=str(self.path))
        try:
            file = (self.folder / rel).resolve()
        except (OSError, RuntimeError, ValueError):
            raise MeshError(f"{where}.uri '{short}': not a readable path", where=str(self.path)) from None
        if not file.is_relative_to(self.folder):
            raise MeshError(f"{where}.uri '{short}': leads outside the asset's folder (files are read from "
                            f"{self.folder} only)", where=str(self.path))
        if not file.is_file():
            raise MeshError(f"{where}.uri '{short}': file not found", where=str(self.path))
        try:
            return file.read_bytes()
        except OSError as e:
            raise MeshError(f"{where}.uri '{short}': cannot be read ({e.strerror or e})", where=str(self.path)) from None

    def buffer(self, i: int) -> bytes:
        """Buffer ``i``, at least its ``byteLength`` long (glTF 2.0 §3.6.1)."""
        if i in self._buffers:
            return self._buffers[i]
        b, where = self.h["buffers"][i], f"buffers[{i}]"
        n = _integer(b.get("byteLength"), f"{where}.byteLength", self.path, minimum=1)
        if "uri" in b:
            data = self.uri_bytes(b["uri"], where)
        elif i == 0 and self.bin is not None:
            data = self.bin
        else:
            holder = "is not the first buffer of a GLB" if self.bin is not None else "the file has no GLB BIN chunk"
            raise MissingData(f"{where} has no uri and {holder}: its data is not in the file (glTF 2.0 §4.4)",
                              where=str(self.path))
        if len(data) < n:
            raise MeshError(f"{where} holds {len(data)} bytes, its byteLength is {n}", where=str(self.path))
        self._buffers[i] = data
        return data

    def view(self, i: int) -> tuple[bytes, int | None]:
        """(bytes, byteStride or None) of buffer view ``i``, inside its buffer."""
        v, where = self.h["bufferViews"][i], f"bufferViews[{i}]"
        off = _integer(v.get("byteOffset", 0), f"{where}.byteOffset", self.path)
        n = _integer(v.get("byteLength"), f"{where}.byteLength", self.path, minimum=1)
        stride = v.get("byteStride")
        if stride is not None:
            stride = _integer(stride, f"{where}.byteStride", self.path, minimum=4)
            if stride > 252 or stride % 4:
                raise MeshError(f"{where}.byteStride = {stride}: must be a multiple of 4 in 4–252 (glTF 2.0 "
                                f"§3.6.2.4)", where=str(self.path))
        buf = self.buffer(v["buffer"])
        if off + n > len(buf):
            raise MeshError(f"{where} spans bytes {off}–{off + n} of buffers[{v['buffer']}], which holds {len(buf)}",
                            where=str(self.path))
        return buf[off:off + n], stride

    def image_bytes(self, i: int) -> bytes:
        """The encoded bytes of image ``i`` (a buffer view or a URI)."""
        img, where = self.h["images"][i], f"images[{i}]"
        if "bufferView" in img:
            return self.view(img["bufferView"])[0]
        if "uri" in img:
            return self.uri_bytes(img["uri"], where)
        raise MeshError(f"{where} has neither uri nor bufferView (glTF 2.0 §5.18)", where=str(self.path))

    # accessors ----------------------------------------------------------------------------
    def accessor(self, j: int, where: str) -> np.ndarray:
        """Accessor ``j`` as an (count, components) array of its component type (sparse values
        substituted); ``where`` names its use (``meshes[0].primitives[0].attributes.POSITION``)."""
        a = self.h["accessors"][j]
        at = f"{where}: accessors[{j}]"
        ctype, kind = a.get("componentType"), a.get("type")
        if ctype not in COMPONENTS:
            raise MeshError(f"{at}.componentType = {ctype!r}: must be one of {sorted(COMPONENTS)} (glTF 2.0 §3.6.2.2)",
                            where=str(self.path))
        if kind not in TYPES:
            raise MeshError(f"{at}.type = {kind!r}: must be one of {', '.join(TYPES)}", where=str(self.path))
        count = _integer(a.get("count"), f"{at}.count", self.path, minimum=1)
        check_size(at, count, 3 * MAX_TRIANGLES, "too long", "elements", where=str(self.path), error=MeshError)
        dt, n = np.dtype(COMPONENTS[ctype]), TYPES[kind]
        elem = dt.itemsize * n
        if "bufferView" in a:
            off = _integer(a.get("byteOffset", 0), f"{at}.byteOffset", self.path)
            data, stride = self.view(a["bufferView"])
            stride = stride or elem
            if stride < elem:
                raise MeshError(f"{at}: bufferViews[{a['bufferView']}].byteStride = {stride} is smaller than one "
                                f"element ({elem} bytes)", where=str(self.path))
            end = off + stride * (count - 1) + elem
            if end > len(data):
                raise MeshError(f"{at} reads bytes {off}–{end} of bufferViews[{a['bufferView']}], which holds "
                                f"{len(data)} (an accessor must fit its buffer view, glTF 2.0 §3.6.2.4)",
                                where=str(self.path))
            raw = np.frombuffer(data, np.uint8, count=end - off, offset=off)
            out = np.lib.stride_tricks.as_strided(raw, (count, elem), (stride, 1)).copy().view(dt).reshape(count, n)
        else:
            out = np.zeros((count, n), dt)
        if "sparse" in a:
            out = self._sparse(a["sparse"], out, at, dt, n)
        return out

    def _sparse(self, s, out: np.ndarray, at: str, dt, n: int) -> np.ndarray:
        """Sparse substitution (glTF 2.0 §3.6.2.3): ``out[indices[k]] = values[k]``."""
        where = f"{at}.sparse"
        if not isinstance(s, dict) or not isinstance(s.get("indices"), dict) or not isinstance(s.get("values"), dict):
            raise MeshError(f"{where} must have count, indices and values objects", where=str(self.path))
        k = _integer(s.get("count"), f"{where}.count", self.path, minimum=1)
        if k > len(out):
            raise MeshError(f"{where}.count = {k} exceeds the accessor's count {len(out)}", where=str(self.path))
        ic = s["indices"].get("componentType")
        if ic not in (5121, 5123, 5125):
            raise MeshError(f"{where}.indices.componentType = {ic!r}: must be 5121, 5123 or 5125", where=str(self.path))
        idx = self._block(s["indices"], f"{where}.indices", np.dtype(COMPONENTS[ic]), 1, k).reshape(-1)
        vals = self._block(s["values"], f"{where}.values", dt, n, k)
        if np.any(idx >= len(out)) or np.any(np.diff(idx.astype(np.int64)) <= 0):
            raise MeshError(f"{where}.indices must increase strictly and stay below the accessor's count "
                            f"{len(out)}", where=str(self.path))
        out = out.copy()
        out[idx.astype(np.int64)] = vals
        return out

    def _block(self, ref: dict, where: str, dt, n: int, count: int) -> np.ndarray:
        """A tightly packed block of ``count`` elements (sparse indices or values)."""
        if not isinstance(ref.get("bufferView"), int):
            raise MeshError(f"{where}.bufferView is required", where=str(self.path))
        data, _ = self.view(ref["bufferView"])
        off = _integer(ref.get("byteOffset", 0), f"{where}.byteOffset", self.path)
        end = off + count * n * dt.itemsize
        if end > len(data):
            raise MeshError(f"{where} reads bytes {off}–{end} of bufferViews[{ref['bufferView']}], which holds "
                            f"{len(data)}", where=str(self.path))
        return np.frombuffer(data, dt, count=count * n, offset=off).reshape(count, n)


def _integer(v, where: str, path, minimum: int = 0) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
        raise MeshError(f"{where} = {v!r}: must be an integer ≥ {minimum}", where=str(path))
    return v


def as_float(a: np.ndarray, ctype: int, normalized: bool) -> np.ndarray:
    """float32 values of decoded components (``normalized`` integers scaled, §3.6.2.1)."""
    if ctype == 5126:
        return a.astype(np.float32)
    x = a.astype(np.float64)
    if normalized:
        x = np.maximum(x / NORMALIZED[ctype], -1.0)
    return x.astype(np.float32)


def triangle_list(idx: np.ndarray, mode: int) -> np.ndarray:
    """(T, 3) triangles of an index list in ``mode`` 4 (list), 5 (strip) or 6 (fan), glTF 2.0
    §3.7.2.1: strip triangle i = (v_i, v_{i+1+i%2}, v_{i+2−i%2}); fan triangle i = (v_{i+1}, v_{i+2}, v_0)."""
    idx = np.asarray(idx, np.int64).reshape(-1)
    if mode == 4:
        return idx.reshape(-1, 3)
    m = max(len(idx) - 2, 0)
    i = np.arange(m)
    if mode == 5:
        return np.stack([idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2]], 1)
    return np.stack([idx[i + 1], idx[i + 2], np.full(m, idx[0] if len(idx) else 0)], 1)
