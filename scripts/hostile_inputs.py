"""Generate a fresh set of hostile inputs (≥ 250), run each as a user would, and count outcomes.

Every input is written into a temporary folder by this script — scene files with bad keys, types
and values, broken meshes, glTF and USD files as tools and the web produce them, Radiance and EXR
maps in every legal layout and many illegal ones, textures, command-line flags, batch job files,
damaged and swapped cache entries, interrupted and concurrent runs, calls of the Python API — and
run in the worker of ``scripts/outcomes.py`` (time limit per case; a hang or a killed worker is
counted). Each case says what must happen:

* ``refuse`` — exit status 2 with one line ``warp-sg: error: ...`` containing the culprit's words
  (the file, the key, the option, the glTF element), no output file (Python: one ``InputError``
  line);
* ``render`` — exit status 0 and the image written (warning lines allowed, each one line);
* ``check`` — a Python snippet that renders and compares with an independent expectation (the
  same scene rendered clean, a map in the usual orientation): a wrong image raises, and is counted.

Targets: 0 tracebacks, 0 hangs, 0 kills, 0 noise (a usage dump, raw library output), 0 refusals
quoting an exception class, 0 unexpected outcomes::

    python scripts/hostile_inputs.py [--json out.json] [--list bad] [--only PREFIX]

Exit status 0 when every target is met.
"""
from __future__ import annotations

import argparse
import base64
import json
import math
import struct
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from outcomes import Runner, summary

ROOT = Path(__file__).resolve().parents[1]
SMALL = ["--width", "16", "--height", "12", "--no-progress"]

BASE = """[camera]
origin = [0.0, 1.0, 3.0]
target = [0.0, 0.3, 0.0]
fov = 40.0
width = 16
height = 12

[[objects]]
name = "ball"
primitive = "sphere"
center = [0.0, 0.4, 0.0]
radius = 0.4
resolution = [12, 24]
material = "shiny"

[[objects]]
name = "floor"
primitive = "plane"
center = [0.0, 0.0, 0.0]
size = [3.0, 3.0]
material = "floor"

[materials.shiny]
model = "cook_torrance"
kd = [0.2, 0.1, 0.1]
ks = [0.5, 0.5, 0.5]
m = 0.3

[materials.floor]
model = "lambert"
kd = [0.6, 0.6, 0.6]

[[lights]]
type = "point"
position = [1.0, 2.0, 1.0]
radius = 0.1
intensity = [5.0, 5.0, 5.0]

[render]
shadows = false
"""


SPHERE = 'primitive = "sphere"\ncenter = [0.0, 0.4, 0.0]\nradius = 0.4\nresolution = [12, 24]'
SHINY = 'model = "cook_torrance"\nkd = [0.2, 0.1, 0.1]\nks = [0.5, 0.5, 0.5]\nm = 0.3'


class Cases:
    """The case list: ``(name, case, expect, words, output)``."""

    def __init__(self, folder: Path):
        self.dir, self.items = folder, []
        self._n = 0

    def path(self, name: str) -> Path:
        self._n += 1
        d = self.dir / f"c{self._n:03d}"
        d.mkdir()
        return d / name

    def cli(self, name, argv, expect="refuse", words=(), output=None):
        self.items.append((name, {"argv": [str(a) for a in argv]}, expect, list(words), output))

    def py(self, name, code, expect="check", words=()):
        self.items.append((name, {"python": code}, expect, list(words), None))

    def scene(self, name, text, expect="refuse", words=(), extra=(), command="render", files=None):
        p = self.path("scene.toml")
        for fname, data in (files or {}).items():
            (p.parent / fname).write_bytes(data if isinstance(data, bytes) else data.encode())
        p.write_bytes(text if isinstance(text, bytes) else text.encode())
        out = p.parent / ("o.exr" if command == "reference" else "o.png")
        argv = [command, p, "-o", out] + (["--spp", "1", "--no-progress"] if command == "reference" else SMALL)
        self.cli(name, argv + list(extra), expect, words, str(out))

    def asset(self, name, fname, data, expect="refuse", words=(), files=None):
        p = self.path(fname)
        for f, d in (files or {}).items():
            (p.parent / f).write_bytes(d)
        p.write_bytes(data)
        out = p.parent / "o.png"
        self.cli(name, ["render", p, "-o", out, "--no-shadows"] + SMALL, expect, words or [fname], str(out))


def sub(old: str, new: str, text: str = BASE) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


# --------------------------------------------------------------------------------------------
# scene files
# --------------------------------------------------------------------------------------------
def scene_cases(c: Cases) -> None:
    bad_values = [  # (old, new, words)
        ("fov = 40.0", "fov = nan", ["fov"]), ("fov = 40.0", "fov = inf", ["fov"]), ("fov = 40.0", "fov = 0.0", ["fov"]),
        ("fov = 40.0", "fov = 180.0", ["fov"]), ("fov = 40.0", 'fov = "wide"', ["fov"]),
        ("width = 16", "width = 0", ["width"]), ("width = 16", "width = -4", ["width"]),
        ("width = 16", "width = 1e9", ["width"]),
        ("origin = [0.0, 1.0, 3.0]", "origin = [0.0, 1.0]", ["origin"]),
        ("origin = [0.0, 1.0, 3.0]", "origin = [nan, 1.0, 3.0]", ["origin"]),
        ("target = [0.0, 0.3, 0.0]", "target = [0.0, 1.0, 3.0]", ["target"]),
        ("radius = 0.4", "radius = -0.4", ["radius"]), ("radius = 0.4", "radius = 0.0", ["radius"]),
        ("radius = 0.4", "radius = 1e300", ["radius", "1e12"]), ("resolution = [12, 24]", "resolution = [0, 24]", ["resolution"]),
        ("resolution = [12, 24]", "resolution = [100000, 100000]", ["resolution", "too finely"]),
        ("size = [3.0, 3.0]", "size = [3.0, -1.0]", ["size"]),
        ("kd = [0.2, 0.1, 0.1]", "kd = [2.0, 0.1, 0.1]", ["kd"]), ("kd = [0.2, 0.1, 0.1]", "kd = [nan, 0.1, 0.1]", ["kd"]),
        ("kd = [0.2, 0.1, 0.1]", "kd = -0.2", ["kd"]), ("m = 0.3", "m = 0.0", ["'m'"]), ("m = 0.3", "m = inf", ["'m'"]),
        ("m = 0.3", 'm = "rough"', ["'m'"]), ("ks = [0.5, 0.5, 0.5]", "ks = [1e30, 0.5, 0.5]", ["ks"]),
        ("intensity = [5.0, 5.0, 5.0]", "intensity = [-5.0, 5.0, 5.0]", ["intensity"]),
        ("intensity = [5.0, 5.0, 5.0]", "intensity = [inf, 5.0, 5.0]", ["intensity"]),
        ("radius = 0.1", "radius = -0.1", ["radius"]), ('type = "point"', 'type = "spot"', ["spot"]),
        ("position = [1.0, 2.0, 1.0]", "position = [1.0, nan, 1.0]", ["position"]),
        ("shadows = false", "shadows = 0", ["shadows"]), ("shadows = false", "supersampling = 0", ["supersampling"]),
        ("shadows = false", "supersampling = 99", ["supersampling"]), ("shadows = false", 'device = "tpu"', ["tpu"]),
        ("shadows = false", "ssdf_resolution = 1", ["ssdf_resolution"]),
        ("shadows = false", "shadows = true\nssdf_resolution = 100000", ["ssdf_resolution"]),
        ('model = "lambert"', 'model = "lamber"', ["lamber", "did you mean"]),
        (SHINY, 'model = "measured"', ["file"]),
        (SHINY, 'model = "measured"\nfile = "nope.binary"', ["nope.binary"]),
        ("m = 0.3", "m = 0.3\nfresnel = { eta = 0.0 }", ["fresnel", "eta"]),
        ("m = 0.3", "m = 0.3\nfresnel = { schlick = 1.5 }", ["fresnel", "schlick"]),
        ("m = 0.3", "m = 0.3\nfresnel = \"unobtainium\"", ["fresnel"]),
        ('material = "floor"', 'material = "flor"', ["flor"]), ('name = "floor"', 'name = "ball"', ["ball", "unique"]),
        ("fov = 40.0", "fvo = 40.0", ["fvo", "did you mean"]), ("[render]", "[rendr]", ["rendr"]),
        ('primitive = "sphere"', 'primitive = "sphere"\nmesh = "a.obj"', ["mesh", "primitive"]),
        ('primitive = "sphere"', 'primitive = "spere"', ["spere"]),
        ("[[lights]]\ntype = \"point\"", "[[lights]]\ntype = \"environment\"\nfile = \"missing.hdr\"\n[[unused]]\ntype = \"point\"",
         ["unused"]),
    ]
    for old, new, words in bad_values:
        c.scene(f"scene value: {new.splitlines()[-1][:40]}", sub(old, new), "refuse", ["scene.toml", *words])
    structural = [
        ("empty file", "", ["scene.toml"]), ("binary garbage", bytes(range(256)) * 4, ["scene.toml"]),
        ("not UTF-8", b"[camera]\nfov = 40.0 # \xff\xfe\n", ["scene.toml"]),
        ("BOM is fine", b"\xef\xbb\xbf" + BASE.encode(), []), ("TOML syntax", "[camera\nfov = 40", ["scene.toml", "TOML"]),
        ("duplicate table", BASE + "\n[camera]\nfov = 30.0\n", ["scene.toml"]),
        ("deeply nested arrays", "a = " + "[" * 5000 + "]" * 5000, ["scene.toml", "nested too deeply"]),
        ("deeply nested tables", "[camera]\nx = " + "{a = " * 3000 + "1" + "}" * 3000, ["scene.toml", "nested"]),
        ("no objects", BASE.split("[[objects]]")[0] + "[[lights]]\ntype = \"point\"\nposition = [0.0, 2.0, 0.0]\n",
         ["scene.toml", "objects"]),
        ("no lights", BASE.split("[[lights]]")[0], ["scene.toml", "lights"]),
        ("two environments", BASE + '[[lights]]\ntype = "environment"\nprocedural = "sky"\n[[lights]]\ntype = '
                                    '"environment"\nprocedural = "sky"\n', ["scene.toml", "environment"]),
        ("a folder as mesh", sub(SPHERE, 'mesh = "."'), ["folder"]),
        ("missing mesh", sub(SPHERE, 'mesh = "missing.obj"'), ["missing.obj"]),
        ("missing texture", sub("kd = [0.6, 0.6, 0.6]", 'kd = "missing.png"'), ["missing.png"]),
        ("missing env map", BASE + '[[lights]]\ntype = "environment"\nfile = "missing.hdr"\n', ["missing.hdr"]),
    ]
    for name, text, words in structural:
        c.scene(f"scene: {name}", text, "render" if not words else "refuse", words)
    c.scene("scene: a 1e10-sample frame", sub("width = 16\nheight = 12", "width = 100000\nheight = 100000"), "refuse",
            ["scene.toml", "samples"], command="reference")
    c.scene("scene: device cuda without a GPU", sub("shadows = false", 'shadows = false\ndevice = "cuda"'), "refuse",
            ["scene.toml: [render] device", "cuda"])
    c.scene("scene: device cuda, reference", sub("shadows = false", 'shadows = false\ndevice = "cuda"'), "refuse",
            ["scene.toml: [render] device"], command="reference")


# --------------------------------------------------------------------------------------------
# meshes and textures
# --------------------------------------------------------------------------------------------
def mesh_cases(c: Cases) -> None:
    objs = {
        "nan vertex": (b"v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n", ["vertex"]),
        "index out of range": (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", ["out of range"]),
        "zero index": (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", ["index 0"]),
        "degenerate only": (b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", ["zero area"]),
        "empty": (b"", ["tri.obj"]), "only comments": (b"# nothing\n", ["tri.obj"]),
        "binary garbage": (bytes(range(256)) * 8, ["tri.obj"]),
        "huge coordinate": (b"v 0 0 0\nv 1e30 0 0\nv 0 1 0\nf 1 2 3\n", ["1e+12"]),
        "tiny object": (b"v 0 0 0\nv 1e-9 0 0\nv 0 1e-9 0\nf 1 2 3\n", ["across"]),
    }
    for name, (data, words) in objs.items():
        c.scene(f"mesh obj: {name}", sub(SPHERE, 'mesh = "tri.obj"'), "refuse", ["tri.obj", *words],
                files={"tri.obj": data})
    ply = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n" \
          b"element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"
    c.scene("mesh ply: index out of range", sub(SPHERE, 'mesh = "t.ply"'), "refuse", ["t.ply"],
            files={"t.ply": ply})
    huge = b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n" \
           b"property float z\nend_header\n"
    c.scene("mesh ply: header claims 4e9 vertices", sub(SPHERE, 'mesh = "h.ply"'), "refuse", ["h.ply"],
            files={"h.ply": huge})
    import io

    from PIL import Image

    def png(a, mode=None):
        b = io.BytesIO()
        Image.fromarray(a, mode).save(b, format="PNG")
        return b.getvalue()

    textures = {
        "corrupt png": (b"\x89PNG\r\n\x1a\n" + b"\0" * 60, "refuse", ["t.png"]),
        "truncated png": (png(np.random.default_rng(1).integers(0, 255, (32, 32, 3), np.uint8))[:300], "refuse",
                          ["t.png"]),
        "text as png": (b"hello", "refuse", ["t.png"]),
        "16-bit grey png": (png(np.full((8, 8), 30000, np.uint16)), "render", []),
        "1x1 png": (png(np.full((1, 1, 3), 200, np.uint8)), "render", []),
    }
    for name, (data, expect, words) in textures.items():
        c.scene(f"texture: {name}", sub("kd = [0.6, 0.6, 0.6]", 'kd = "t.png"'), expect, words, files={"t.png": data})
    bomb = b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + struct.pack(">IIBBBBB", 100000, 100000, 8, 2, 0, 0, 0)
    bomb += struct.pack(">I", 0) + b"\0" * 20
    c.scene("texture: 1e10-texel header", sub("kd = [0.6, 0.6, 0.6]", 'kd = "t.png"'), "refuse", ["t.png"],
            files={"t.png": bomb})


# --------------------------------------------------------------------------------------------
# environment maps
# --------------------------------------------------------------------------------------------
def rgbe(a: np.ndarray) -> bytes:
    """Flat RGBE bytes of float RGB texels (Ward's shared exponent)."""
    v = a.max(-1)
    m, e = np.frexp(v)
    f = np.where(v > 1e-32, m * 256.0 / np.maximum(v, 1e-32), 0.0)
    out = np.zeros(a.shape[:-1] + (4,), np.uint8)
    out[..., :3] = (a * f[..., None]).astype(np.uint8)
    out[..., 3] = np.where(v > 1e-32, e + 128, 0)
    return out.tobytes()


def hdr(img: np.ndarray, first="-Y", second="+X") -> bytes:
    """A flat Radiance file of ``img`` (row 0 the top) with the resolution line ``first N second M``
    (``+Y``: the first scanline is the bottom row; ``-X``: right to left; an ``X`` first: column
    scanlines), the format's definition."""
    H, W, _ = img.shape
    if first[1] == "Y":
        d = img[::-1] if first[0] == "+" else img
        d = d[:, ::-1] if second[0] == "-" else d
        line = f"{first} {H} {second} {W}"
    else:
        d = img.transpose(1, 0, 2)
        d = d[::-1] if first[0] == "-" else d
        d = d[:, ::-1] if second[0] == "+" else d
        line = f"{first} {W} {second} {H}"
    return b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + line.encode() + b"\n" + rgbe(np.ascontiguousarray(d))


def env_cases(c: Cases) -> None:
    rng = np.random.default_rng(7)
    img = rng.uniform(0.05, 2.0, (16, 32, 3)).astype(np.float32)
    img[3:5, 8:10] = 200.0
    env = BASE + '[[lights]]\ntype = "environment"\nfile = "sky.hdr"\n'
    for first, second in [("+Y", "+X"), ("-Y", "-X"), ("+Y", "-X"), ("+X", "-Y"), ("-X", "-Y"), ("+X", "+Y"),
                          ("-X", "+Y")]:
        p = c.path("usual.hdr")
        p.write_bytes(hdr(img))
        (p.parent / "other.hdr").write_bytes(hdr(img, first, second))
        c.py(f"env hdr: {first} {second} reads as -Y +X",
             "from warp_sg.scene.envmap import load_envmap\n"
             f"a = load_envmap(r'{p}'); b = load_envmap(r'{p.parent / 'other.hdr'}')\n"
             "assert a.shape == b.shape == (16, 32, 3) and (a == b).all(), 'a different image'\n")
        c.scene(f"env hdr render: {first} {second}", env, "render", files={"sky.hdr": hdr(img, first, second)})
    bad = {
        "no resolution line": b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + b"\0" * 64,
        "truncated": hdr(img)[:200], "same axis twice": hdr(img).replace(b"-Y 16 +X 32", b"-Y 16 +Y 32"),
        "empty": b"", "text": b"hello world\n", "1x1": hdr(np.ones((1, 1, 3), np.float32)),
        "aspect 10:1": hdr(np.ones((4, 40, 3), np.float32)),
        "resolution 1e9": b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 200000\n" + b"\0" * 64,
    }
    for name, data in bad.items():
        c.scene(f"env hdr: {name}", env, "refuse", ["sky.hdr"], files={"sky.hdr": data})
    try:
        import OpenEXR  # noqa: F401

        for name, val in (("NaN", np.nan), ("inf", np.inf), ("negative", -1.0), ("1e30", 1e30)):
            e = img.copy()
            e[2, 3, 1] = val
            p = c.path("sky.exr")
            _write_exr(p, e)
            c.scene(f"env exr: a {name} texel", env.replace("sky.hdr", "sky.exr"), "refuse", ["sky.exr"],
                    files={"sky.exr": p.read_bytes()})
    except ImportError:
        pass


def _write_exr(path: Path, a: np.ndarray) -> None:
    import OpenEXR

    ch = {c: np.ascontiguousarray(a[..., i].astype(np.float32)) for i, c in enumerate("RGB")}
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, ch) as f:
        f.write(str(path))


# --------------------------------------------------------------------------------------------
# glTF
# --------------------------------------------------------------------------------------------
def gltf_doc() -> tuple[dict, bytes]:
    """A valid one-quad glTF (positions, normals, uvs, indices) and its buffer."""
    P = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32)
    N = np.tile([0, 1, 0], (4, 1)).astype(np.float32)
    UV = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    idx = np.array([0, 2, 1, 0, 3, 2], np.uint16)
    data = P.tobytes() + N.tobytes() + UV.tobytes() + idx.tobytes()
    h = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
         "nodes": [{"mesh": 0, "name": "quad"}],
         "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3,
                                     "material": 0}]}],
         "materials": [{"name": "paint", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.2, 0.2, 1.0],
                                                                  "metallicFactor": 0.0, "roughnessFactor": 0.5}}],
         "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, 0, -1],
                        "max": [1, 0, 1]},
                       {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
                       {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
                       {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}],
         "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 48},
                         {"buffer": 0, "byteOffset": 96, "byteLength": 32},
                         {"buffer": 0, "byteOffset": 128, "byteLength": 12}],
         "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64,"
                      + base64.b64encode(data).decode()}]}
    return h, data


def glb(h: dict, data: bytes) -> bytes:
    h = json.loads(json.dumps(h))
    h["buffers"][0].pop("uri", None)
    text = json.dumps(h).encode()
    text += b" " * (-len(text) % 4)
    data = data + b"\0" * (-len(data) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(data), 0x004E4942) + data
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def _edit(h: dict, path: str, value) -> dict:
    h = json.loads(json.dumps(h))
    keys = [int(k) if k.isdigit() else k for k in path.split("/")]
    d = h
    for k in keys[:-1]:
        d = d[k]
    if value == "__delete__":
        del d[keys[-1]]
    else:
        d[keys[-1]] = value
    return h


def gltf_cases(c: Cases) -> None:
    h, data = gltf_doc()
    c.asset("gltf: the valid quad", "quad.gltf", json.dumps(h).encode(), "render")
    c.asset("gltf: the valid quad as GLB", "quad.glb", glb(h, data), "render")
    edits = [  # (path, value, words)
        ("meshes/0/primitives/0/indices", 9, ["meshes[0].primitives[0].indices = 9"]),
        ("meshes/0/primitives/0/attributes/POSITION", 7, ["attributes.POSITION = 7"]),
        ("meshes/0/primitives/0/attributes/POSITION", "zero", ["attributes.POSITION"]),
        ("meshes/0/primitives/0/material", 4, ["material = 4"]), ("nodes/0/mesh", 3, ["nodes[0].mesh = 3"]),
        ("scenes/0/nodes", [5], ["scenes[0].nodes[0] = 5"]), ("scene", 2, ["scene = 2"]),
        ("bufferViews/0/buffer", 4, ["bufferViews[0].buffer = 4"]), ("accessors/0/bufferView", 9, ["bufferView = 9"]),
        ("accessors/0/count", 400, ["accessors[0] reads bytes"]), ("accessors/0/count", 0, ["count"]),
        ("accessors/0/count", 10 ** 12, ["too long"]), ("accessors/0/componentType", 5130, ["componentType"]),
        ("accessors/0/type", "VEC7", ["type"]), ("accessors/0/type", "VEC2", ["POSITION"]),
        ("accessors/3/componentType", 5126, ["indices"]), ("accessors/3/count", 5, ["multiple of 3"]),
        ("accessors/0/byteOffset", -4, ["byteOffset"]), ("bufferViews/0/byteStride", 2, ["byteStride"]),
        ("bufferViews/0/byteLength", 100000, ["bufferViews[0]"]), ("bufferViews/0/byteOffset", 1000, ["bufferViews[0]"]),
        ("buffers/0/byteLength", 10 ** 9, ["buffers[0]"]), ("buffers/0/uri", "../../etc/passwd", ["outside"]),
        ("buffers/0/uri", "/etc/passwd", ["buffers[0].uri"]), ("buffers/0/uri", "http://example.com/b.bin", ["no network"]),
        ("buffers/0/uri", "missing.bin", ["not found"]), ("buffers/0/uri", "data:application/octet-stream;base64,@@",
                                                          ["base64"]),
        ("buffers/0/uri", "data:,plain", ["base64"]), ("buffers/0/uri", 7, ["uri"]),
        ("nodes/0/translation", [math.inf, 0, 0], ["nodes[0] ('quad').translation"]),
        ("nodes/0/rotation", [0, 0, 0, 0], ["rotation"]), ("nodes/0/scale", [1, "x", 1], ["scale"]),
        ("nodes/0/matrix", [1] * 16, ["matrix"]), ("nodes/0/children", [0], ["nodes[0]"]),
        ("meshes/0/primitives/0/mode", 9, ["mode"]), ("meshes/0/primitives", [], ["primitives"]),
        ("meshes/0/primitives/0/attributes", [], ["attributes"]),
        ("materials/0/pbrMetallicRoughness/baseColorFactor", [math.nan, 0, 0, 1],
         ["materials[0] ('paint').pbrMetallicRoughness.baseColorFactor"]),
        ("materials/0/pbrMetallicRoughness/roughnessFactor", -0.5, ["roughnessFactor"]),
        ("materials/0/pbrMetallicRoughness/metallicFactor", 2.0, ["metallicFactor"]),
        ("materials/0/emissiveFactor", [5, 0, 0], ["emissiveFactor"]), ("materials/0/alphaMode", "GLASS", ["alphaMode"]),
        ("materials/0/doubleSided", "yes", ["doubleSided"]),
        ("materials/0/normalTexture", {"index": 0}, ["normalTexture.index = 0"]),
        ("extensionsRequired", ["EXT_mesh_gpu_instancing"], ["EXT_mesh_gpu_instancing"]),
        ("extensionsRequired", ["KHR_materials_unlit"], ["KHR_materials_unlit"]),
        ("extensionsRequired", ["EXT_meshopt_compression"], ["EXT_meshopt_compression"]),
        ("extensionsRequired", "KHR", ["extensionsRequired"]), ("asset", {}, ["version"]),
        ("asset/version", "1.0", ["1.0"]), ("asset/minVersion", "2.1", ["minVersion"]),
        ("materials/0", "paint", ["materials[0]"]), ("nodes", {}, ["nodes"]),
    ]
    for path, value, words in edits:
        c.asset(f"gltf edit: {path} = {str(value)[:24]}", "a.gltf", json.dumps(_edit(h, path, value)).encode(),
                "refuse", ["a.gltf", *words])
    renders = [  # files that must render (what they use is read, or reported in one line)
        ("extensionsUsed", ["KHR_materials_sheen"]), ("extensionsUsed", ["EXT_texture_webp"]),
        ("materials/0/extensions", {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}}),
        ("materials/0/extensions", {"KHR_materials_transmission": {"transmissionFactor": 1.0}}),
        ("nodes/0/extensions", {"EXT_mesh_gpu_instancing": {"attributes": {}}}),
        ("meshes/0/weights", [0.0]), ("nodes/0/weights", [0.0]), ("animations", []),
        ("meshes/0/primitives/0/mode", 5), ("meshes/0/primitives/0/mode", 6), ("accessors/3/count", 3),
        ("materials/0/doubleSided", True), ("extras", {"deep": [[[[[1]]]]]}),
    ]
    for path, value in renders:
        c.asset(f"gltf render: {path} = {str(value)[:24]}", "a.gltf", json.dumps(_edit(h, path, value)).encode(),
                "render")
    c.asset("gltf: BOM", "a.gltf", b"\xef\xbb\xbf" + json.dumps(h).encode(), "refuse", ["a.gltf", "byte-order"])
    c.asset("gltf: not JSON", "a.gltf", b"{not json", "refuse", ["a.gltf"])
    c.asset("gltf: JSON array", "a.gltf", b"[]", "refuse", ["a.gltf"])
    c.asset("gltf: deep JSON", "a.gltf", b"[" * 100000 + b"]" * 100000, "refuse", ["a.gltf"])
    c.asset("gltf: empty", "a.gltf", b"", "refuse", ["a.gltf"])
    g = glb(h, data)
    c.asset("glb: truncated", "a.glb", g[:len(g) // 2], "refuse", ["a.glb"])
    c.asset("glb: bad magic", "a.glb", b"gLTF" + g[4:], "refuse", ["a.glb"])
    c.asset("glb: version 1", "a.glb", g[:4] + struct.pack("<I", 1) + g[8:], "refuse", ["a.glb"])
    c.asset("glb: length too large", "a.glb", g[:8] + struct.pack("<I", len(g) + 100) + g[12:], "refuse", ["a.glb"])
    c.asset("glb: no BIN chunk", "a.glb", glb(h, b"")[:20 + struct.unpack_from("<I", glb(h, b""), 12)[0]], "refuse",
            ["a.glb"])
    # morph targets with weights: rendered (applied), sparse accessors: rendered
    hm = _edit(h, "meshes/0/primitives/0/targets", [{"POSITION": 1}])
    c.asset("gltf: morph target with weight 0.5", "a.gltf", json.dumps(_edit(hm, "nodes/0/weights", [0.5])).encode(),
            "render")
    hs = _edit(h, "accessors/0/sparse", {"count": 1, "indices": {"bufferView": 3, "componentType": 5123},
                                         "values": {"bufferView": 1}})
    c.asset("gltf: sparse positions", "a.gltf", json.dumps(hs).encode(), "render")
    c.asset("gltf: sparse index past count", "a.gltf",
            json.dumps(_edit(hs, "accessors/0/sparse/count", 5)).encode(), "refuse", ["sparse"])


# --------------------------------------------------------------------------------------------
# USD
# --------------------------------------------------------------------------------------------
USD_QUAD = ('def Mesh "quad"\n{\n    int[] faceVertexCounts = [4]\n    int[] faceVertexIndices = [0, 1, 2, 3]\n'
            '    point3f[] points = [(0,0,0), (1,0,0), (1,0,1), (0,0,1)]\n}\n')


def usd_cases(c: Cases) -> None:
    try:
        import pxr  # noqa: F401
    except ImportError:
        return
    cases = {
        "missing sublayer": ('#usda 1.0\n(\n    subLayers = [@missing.usda@]\n)\n' + USD_QUAD, "render", []),
        "no meshes": ('#usda 1.0\ndef Xform "x"\n{\n}\n', "refuse", ["a.usda"]),
        "syntax error": ('#usda 1.0\ndef Mesh "quad" {\n', "refuse", ["a.usda"]),
        "empty": ("", "refuse", ["a.usda"]),
        "metersPerUnit 0": ('#usda 1.0\n(\n    metersPerUnit = 0\n)\n' + USD_QUAD, "refuse", ["metersPerUnit"]),
        "upAxis X": ('#usda 1.0\n(\n    upAxis = "X"\n)\n' + USD_QUAD, "refuse", ["upAxis"]),
        "index out of range": (USD_QUAD.replace("[0, 1, 2, 3]", "[0, 1, 2, 9]").join(["#usda 1.0\n", ""]), "refuse",
                               ["a.usda"]),
        "bad binding": ('#usda 1.0\n' + USD_QUAD.replace("}\n", "    rel material:binding = </Nope>\n}\n"), "render", []),
    }
    for name, (text, expect, words) in cases.items():
        c.asset(f"usd: {name}", "a.usda", text.encode(), expect, words or ["a.usda"])


# --------------------------------------------------------------------------------------------
# command line
# --------------------------------------------------------------------------------------------
def cli_cases(c: Cases) -> None:
    p = c.path("scene.toml")
    p.write_text(BASE)
    d = p.parent
    flags = [
        (["--width", "0"], ["--width"]), (["--width", "-3"], ["--width"]), (["--width", "abc"], ["--width"]),
        (["--height", "1e9"], ["--height"]), (["--spp", "0"], ["--spp"]), (["--spp", "99"], ["--spp"]),
        (["--exposure", "nan"], ["--exposure"]), (["--view", "nan", "0"], ["--view"]), (["--cluster", "tcp://"], ["--cluster"]),
        (["--cluster", "ftp://x:1"], ["--cluster"]), (["--cluster", "local:0"], ["--cluster"]),
        (["--device", "tpu"], ["tpu"]), (["--device", "cuda:7"], ["cuda"]), (["--bogus"], ["--bogus"]),
        (["--first-frame", str(d / "f.bmp")], ["f.bmp"]), (["--width", "100000", "--height", "100000"], ["width", "16384"]),
    ]
    for extra, words in flags:
        out = d / "o.png"
        c.cli(f"cli render {' '.join(extra)[:40]}", ["render", p, "-o", out, "--no-progress"] + extra, "refuse", words,
              str(out))
    outs = [("o.bmpx", ["bmpx"]), (".", ["folder"]), ("scene.toml/o.png", ["scene.toml"])]
    for o, words in outs:
        c.cli(f"cli -o {o}", ["render", p, "-o", d / o, "--no-progress"], "refuse", words)
    c.cli("cli: no command", [], "refuse", ["COMMAND"])
    c.cli("cli: misspelt command", ["rendr", p], "refuse", ["rendr"])
    c.cli("cli: scene not found", ["render", d / "nope.toml", "-o", d / "o.png"], "refuse", ["nope.toml"])
    c.cli("cli: reference --spp 0", ["reference", p, "-o", d / "r.exr", "--spp", "0"], "refuse", ["--spp"])
    c.cli("cli: reference --max-depth 0", ["reference", p, "-o", d / "r.exr", "--spp", "1", "--max-depth", "0"],
          "refuse", ["--max-depth"])
    c.cli("cli: reference --stderr = -o", ["reference", p, "-o", d / "r.exr", "--stderr", d / "r.exr", "--spp", "1"],
          "refuse", ["--stderr", "same file"], str(d / "r.exr"))
    c.cli("cli: bench --section unknown", ["bench", "--section", "nothing-like-it"], "refuse", ["--section"])
    c.cli("cli: preview --window-size 0 0", ["preview", p, "--window-size", "0", "0"], "refuse", ["--window-size"])
    c.cli("cli: reference of an asset", ["reference", ROOT / "examples" / "assets" / "blob.obj", "-o", d / "r.exr"],
          "refuse", ["blob.obj", "not a scene file"])
    c.cli("cli: render a valid scene", ["render", p, "-o", d / "ok.png"] + SMALL, "render", [], str(d / "ok.png"))


# --------------------------------------------------------------------------------------------
# batch jobs
# --------------------------------------------------------------------------------------------
def batch_cases(c: Cases) -> None:
    jobs = {  # body after scene/output, words
        "NaN field": ('[animate]\nframes = 2\n"materials.shiny.m" = [nan, 0.3]\n', ["frame 0", "[materials.shiny] m"]),
        "fov 400": ('[animate]\nframes = 2\n"camera.fov" = [40.0, 400.0]\n', ["frame 1", "fov"]),
        "scale 1e30": ('[animate]\nframes = 2\n"objects.ball.scale" = [1.0, 1e30]\n', ["frame 1", "objects.ball"]),
        "shear matrix": ('[[frames]]\nobjects = { ball = { matrix = [[1, 1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], '
                         '[0, 0, 0, 1]] } }\n', ["frame 0", "objects.ball"]),
        "negative light radius": ('[animate]\nframes = 2\n"lights.0.radius" = [0.1, -1.0]\n', ["frame 1", "radius"]),
        "unknown material": ('[animate]\nframes = 2\n"materials.gold.m" = [0.1, 0.3]\n', ["gold"]),
        "unknown section": ('[[frames]]\nsky = { rotation = 3 }\n', ["sky"]),
        "light index 9": ('[[frames]]\nlights = { 9 = { radius = 0.2 } }\n', ["#9"]),
        "frames 0": ('[animate]\nframes = 0\n"camera.fov" = [40.0, 41.0]\n', ["frames"]),
        "one value": ('[animate]\nframes = 2\n"camera.fov" = [40.0]\n', ["camera.fov"]),
        "no frames": ("", ["no frames"]),
        "unknown top key": ('colour = 1\n[animate]\nframes = 2\n"camera.fov" = [40.0, 41.0]\n', ["colour"]),
    }
    for name, (body, words) in jobs.items():
        job = c.path("job.toml")
        (job.parent / "scene.toml").write_text(sub('name = "ball"', 'name = "ball"\ndynamic = true'))
        job.write_text('scene = "scene.toml"\noutput = "f/frame_{index:03d}.png"\ncluster = "tcp://127.0.0.1:9"\n'
                       + body)
        c.cli(f"batch: {name}", ["batch", job], "refuse", ["job.toml", *words])
    patterns = {"width 99999999": "frame_{index:099999999d}.png", "no index": "frame.png", "other field": "{name}.png",
                "bad spec": "{index:q}.png", "long name": "f" * 300 + "{index}.png", "unclosed": "{index.png"}
    for name, out in patterns.items():
        job = c.path("job.toml")
        (job.parent / "scene.toml").write_text(BASE)
        job.write_text(f'scene = "scene.toml"\noutput = {json.dumps(out)}\n[animate]\nframes = 2\n'
                       f'"camera.fov" = [40.0, 41.0]\n')
        c.cli(f"batch output: {name}", ["batch", job], "refuse", ["job.toml", "output"])
    job = c.path("job.toml")
    job.write_text("a = " + "[" * 5000 + "]" * 5000)
    c.cli("batch: deeply nested", ["batch", job], "refuse", ["job.toml", "nested"])


# --------------------------------------------------------------------------------------------
# caches, interruptions, concurrency, the Python API
# --------------------------------------------------------------------------------------------
CACHE_CHECK = """
import os, shutil, numpy as np, warnings
from pathlib import Path
cache = Path(r'{cache}')
os.environ['WARP_SG_CACHE_DIR'] = str(cache)
scene = ws.load_scene(r'{scene}')
clean = ws.render(scene)
entries = sorted(p for p in cache.rglob('*.npz'))
assert entries, 'no cache entries'
{damage}
with warnings.catch_warnings(record=True) as rec:
    warnings.simplefilter('always')
    again = ws.render(ws.load_scene(r'{scene}'))
assert np.array_equal(again, clean), 'a damaged cache gave another image'
assert len(rec) <= len(entries), [str(w.message) for w in rec]
third = ws.render(ws.load_scene(r'{scene}'))
assert np.array_equal(third, clean), 'the rebuilt cache gave another image'
"""
DAMAGES = {
    "truncated": "for e in entries: e.write_bytes(e.read_bytes()[:len(e.read_bytes()) // 2])",
    "garbage": "for e in entries: e.write_bytes(b'garbage' * 99)",
    "zero length": "for e in entries: e.write_bytes(b'')",
    "folder in place": "for e in entries:\n    e.unlink(); (e / 'x').mkdir(parents=True)",
    "entries swapped": "ds = [e.read_bytes() for e in entries]\nfor e, d in zip(entries, ds[1:] + ds[:1]): e.write_bytes(d)",
    "flipped byte": "for e in entries:\n    b = bytearray(e.read_bytes()); b[len(b) * 2 // 3] ^= 0xFF; e.write_bytes(bytes(b))",
    "kind folder is a file": "k = entries[0].parent\nshutil.rmtree(k); k.write_text('x')",
    "other scene's entry": ("other = Path(str(cache) + '_other'); os.environ['WARP_SG_CACHE_DIR'] = str(other)\n"
                            "s2 = ws.load_scene(r'{scene}'); s2.lights[0].intensity = (9.0, 1.0, 1.0); ws.render(s2)\n"
                            "o = sorted(other.rglob('*.npz'))\n"
                            "os.environ['WARP_SG_CACHE_DIR'] = str(cache)\n"
                            "for e in entries:\n    m = [x for x in o if x.parent.name == e.parent.name]\n"
                            "    if m: e.write_bytes(m[0].read_bytes())"),
}


def cache_cases(c: Cases) -> None:
    env_scene = BASE.replace("shadows = false", "shadows = true\nssdf_resolution = 8\nvisibility_budget = 0") + \
        '[[lights]]\ntype = "environment"\nprocedural = "sky"\n'
    for name, damage in DAMAGES.items():
        p = c.path("scene.toml")
        p.write_text(env_scene)
        code = CACHE_CHECK.format(cache=p.parent / "cache", scene=p, damage=damage.format(scene=p))
        c.py(f"cache: {name}", code)
    # interrupted and concurrent runs
    p = c.path("scene.toml")
    p.write_text(env_scene)
    c.py("interrupted: a run killed during its precompute, then run again", f"""
import os, subprocess, sys, time, signal, numpy as np
env = dict(os.environ, WARP_SG_CACHE_DIR=r'{p.parent / 'cache'}')
cmd = [sys.executable, '-m', 'warp_sg.tools.cli', 'render', r'{p}', '-o', r'{p.parent / 'a.exr'}', '--no-progress']
proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
time.sleep(4.0); proc.send_signal(signal.SIGKILL); proc.wait()
r = subprocess.run(cmd, env=env, capture_output=True, text=True)
assert r.returncode == 0 and r.stderr.strip() == '', r.stderr
os.environ['WARP_SG_CACHE_DIR'] = r'{p.parent / 'clean'}'
want = ws.render(ws.load_scene(r'{p}'))
assert np.array_equal(ws.load_image(r'{p.parent / 'a.exr'}'), want), 'another image after the interruption'
""")
    p = c.path("scene.toml")
    p.write_text(env_scene)
    c.py("concurrent: two runs into one cache", f"""
import os, subprocess, sys, numpy as np
env = dict(os.environ, WARP_SG_CACHE_DIR=r'{p.parent / 'cache'}')
cmds = [[sys.executable, '-m', 'warp_sg.tools.cli', 'render', r'{p}', '-o', r'{p.parent}/' + n + '.exr',
         '--no-progress'] for n in ('a', 'b')]
procs = [subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for cmd in cmds]
outs = [pr.communicate() for pr in procs]
assert all(pr.returncode == 0 for pr in procs) and all(e.strip() == '' for _, e in outs), outs
a, b = ws.load_image(r'{p.parent / 'a.exr'}'), ws.load_image(r'{p.parent / 'b.exr'}')
assert np.array_equal(a, b), 'two concurrent runs disagree'
""")
    q = c.path("scene.toml")
    q.write_text(BASE.replace('name = "ball"', 'name = "ball"\ndynamic = true'))
    api = {  # (code, expect, words)
        "set_material NaN": ("r.set_material('shiny', m=float('nan'))", ["[materials.shiny]"]),
        "set_material unknown": ("r.set_material('gold', m=0.2)", ["gold"]),
        "set_object_transform 1e30": ("from warp_sg.numeric.rigid_motion import motion_matrix\n"
                                      "r.set_object_transform('ball', motion_matrix(scale=1e30))", ["ball", "1e+12"]),
        "set_object_transform shear": ("import numpy as np\nM = np.eye(4); M[0, 1] = 1\n"
                                       "r.set_object_transform('ball', M)", ["ball"]),
        "set_object_transform static": ("import numpy as np\nr.set_object_transform('floor', np.eye(4))", ["floor"]),
        "set_camera fov 0": ("r.set_camera(fov=0.0)", ["fov"]),
        "update_light 9": ("r.update_light(9, radius=0.2)", ["#9"]),
        "update_light NaN": ("r.update_light(0, position=(float('nan'), 0, 0))", ["position"]),
        "environment rotation NaN": ("r.set_environment_rotation(float('nan'))", ["environment"]),
    }
    for name, (code, words) in api.items():
        c.py(f"api: {name}", f"r = ws.Renderer(ws.load_scene(r'{q}'))\n{code}\n", "refuse", words)
    api2 = {
        "render of a non-scene": ("ws.render('scene.toml')", ["scene"]),
        "render on tpu": (f"ws.render(ws.load_scene(r'{q}'), device='tpu')", ["tpu"]),
        "load_image garbage": (f"open(r'{q.parent / 'x.png'}', 'wb').write(b'xx'); ws.load_image(r'{q.parent / 'x.png'}')",
                               ["x.png"]),
        "save_image unknown suffix": (f"import numpy as np; ws.save_image(r'{q.parent / 'x.bmpx'}', np.zeros((2, 2, 3)))",
                                      ["bmpx"]),
        "reference spp 0": (f"ws.reference(ws.load_scene(r'{q}'), spp=0, progress=False)", ["spp"]),
        "Scene NaN vertices": ("import numpy as np\nfrom warp_sg.scene.model import Scene, SceneObject\n"
                               "from warp_sg.scene.camera import Camera\nfrom warp_sg.scene.lights import PointLight\n"
                               "v = np.array([[0, 0, 0], [1, np.nan, 0], [0, 1, 0]], float)\n"
                               "s = Scene(Camera(), [SceneObject('m', vertices=v, triangles=np.array([[0, 1, 2]]), "
                               "name='tri')], {'m': ws.brdf.Lambert(kd=0.5)}, [PointLight(position=(0, 2, 0))])\n"
                               "ws.render(s)", ["tri", "vertex 1"]),
    }
    for name, (code, words) in api2.items():
        c.py(f"api: {name}", code, "refuse", words)
    c.py("api: save_image NaN to PNG (documented: NaN is black)",
         f"import numpy as np; ws.save_image(r'{q.parent / 'n.png'}', np.full((2, 2, 3), np.nan))\n"
         f"assert (ws.load_image(r'{q.parent / 'n.png'}') == 0).all()")


GROUPS = {"scene": scene_cases, "mesh": mesh_cases, "env": env_cases, "gltf": gltf_cases, "usd": usd_cases,
          "cli": cli_cases, "batch": batch_cases, "cache": cache_cases}


def judge(o, expect: str, words: list, output: str | None) -> str | None:
    """Why an outcome misses its expectation (None: as expected)."""
    if expect == "check" and o.outcome == "traceback" and o.error.startswith("AssertionError"):
        return "wrong image" if "image" in o.error.split("\n")[0] else "check failed"
    if o.outcome in ("traceback", "hang", "kill", "noise"):
        return o.outcome
    if o.internal:
        return "internal"
    if expect == "refuse":
        if o.outcome != "refused":
            return "not refused"
        if o.left_output:
            return "left output"
        missing = [w for w in words if w.lower() not in o.error.lower()]
        return f"culprit unnamed ({missing})" if missing else None
    if expect == "render":
        if o.outcome != "rendered":
            return "not rendered"
        if output and not Path(output).is_file():
            return "no image"
        return None
    return None if o.outcome == "rendered" else "check failed"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, help="write every outcome here")
    ap.add_argument("--list", default="bad", help="print these cases: bad (default), all, none")
    ap.add_argument("--only", default="", help="only the groups whose name starts with this (" + ", ".join(GROUPS) + ")")
    ap.add_argument("--timeout", type=float, default=180.0, help="seconds per case (default 180)")
    a = ap.parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix="hostile_"))
    cases = Cases(folder)
    for g, fn in GROUPS.items():
        if g.startswith(a.only) or not a.only:
            fn(cases)
    runner = Runner({"WARP_SG_CACHE_DIR": str(folder / "cache"), "OUTCOMES_CWD": str(folder)})
    results = []
    try:
        for i, (name, case, expect, words, output) in enumerate(cases.items):
            o = runner.run(name, case, timeout=a.timeout, output=output)
            why = judge(o, expect, words, output)
            results.append((o, expect, why))
            if a.list == "all" or (a.list == "bad" and why):
                print(f"[{i + 1}/{len(cases.items)}] {'OK ' if why is None else 'BAD'} {o.outcome:9s} {name}: "
                      f"{why or ''} {(o.error or '; '.join(o.warnings + o.noise))[:200]}", flush=True)
    finally:
        runner.close()
    outs = [r[0] for r in results]
    bad = [r for r in results if r[2] is not None]
    print(f"\n{len(outs)} hostile inputs in {len(GROUPS)} groups: {summary(outs)}")
    print(f"expected outcome: {len(outs) - len(bad)}; unexpected: {len(bad)}")
    by_kind = {}
    for o, _, why in bad:
        by_kind.setdefault(why.split(" (")[0], []).append(o.name)
    for k, names in by_kind.items():
        print(f"  {k}: {len(names)} ({'; '.join(names[:4])}{' ...' if len(names) > 4 else ''})")
    if a.json:
        a.json.write_text(json.dumps([dict(o.as_dict(), expect=e, why=w) for o, e, w in results], indent=1))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
