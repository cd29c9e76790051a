"""Property tests of the input readers (issue 51, hypothesis): glTF JSON, Radiance headers and
batch job files as a careless tool or a hand writes them. Whatever the input, the reader either
answers (finite geometry, the map the header describes, a job whose every frame passes the
renderer's checks) or refuses in one line that quotes no exception class — never a traceback,
never a silently different result. Each test runs a few derandomized examples with a deadline, so
the suite stays fast; ``WARP_SG_PROPERTY_EXAMPLES=N`` searches deeper by hand."""
from __future__ import annotations

import json
import math
import re
import string
import tempfile
from pathlib import Path

import numpy as np
import pytest
from conftest import replace_once as replace
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_hostile_inputs import write_hdr

from warp_sg.core.errors import InputError

INTERNAL = re.compile(r"\b[A-Z][A-Za-z]*(Error|Exception)\b|Traceback")


def bounded(n: int):
    """``n`` derandomized examples, each within 10 s (``WARP_SG_PROPERTY_EXAMPLES=N``: N random ones)."""
    import os

    deep = int(os.environ.get("WARP_SG_PROPERTY_EXAMPLES", "0"))
    return settings(max_examples=deep or n, deadline=10_000, derandomize=not deep, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


def one_line(e: BaseException) -> str:
    msg = str(e)
    assert "\n" not in msg and not INTERNAL.search(msg) and len(msg) < 600, msg
    return msg


# --------------------------------------------------------------------------------------------
# glTF JSON
# --------------------------------------------------------------------------------------------
def quad_gltf() -> dict:
    import base64

    P = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32)
    idx = np.array([0, 2, 1, 0, 3, 2], np.uint16)
    data = P.tobytes() + idx.tobytes()
    return {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
            "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                          {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}],
            "bufferViews": [{"buffer": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
            "buffers": [{"byteLength": 60, "uri": "data:application/octet-stream;base64,"
                         + base64.b64encode(data).decode()}]}


#: JSON paths a file's fields live at (every kind of element the importer reads)
GLTF_PATHS = ["scene", "scenes/0/nodes", "scenes/0/nodes/0", "nodes/0/mesh", "nodes/0/children", "nodes/0/matrix",
              "nodes/0/translation", "nodes/0/rotation", "nodes/0/scale", "nodes/0/weights", "meshes/0/primitives",
              "meshes/0/primitives/0/mode", "meshes/0/primitives/0/indices", "meshes/0/primitives/0/attributes",
              "meshes/0/primitives/0/attributes/POSITION", "meshes/0/primitives/0/attributes/NORMAL",
              "meshes/0/primitives/0/targets", "meshes/0/weights", "meshes/0/primitives/0/material",
              "accessors/0/count", "accessors/0/type", "accessors/0/componentType", "accessors/0/byteOffset",
              "accessors/0/normalized", "accessors/0/sparse", "accessors/1/count", "accessors/1/componentType",
              "bufferViews/0/byteLength", "bufferViews/0/byteOffset", "bufferViews/0/byteStride",
              "bufferViews/0/buffer", "buffers/0/byteLength", "buffers/0/uri", "materials/0/doubleSided",
              "materials/0/alphaMode", "materials/0/alphaCutoff", "materials/0/emissiveFactor",
              "materials/0/pbrMetallicRoughness/baseColorFactor", "materials/0/pbrMetallicRoughness/roughnessFactor",
              "materials/0/extensions", "extensionsUsed", "extensionsRequired", "asset/version", "asset/minVersion"]
JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-2 ** 40, 2 ** 40) | st.sampled_from([0, 1, 2, 3, 4, 5, 6, 7, 5126, 5123])
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(string.printable, max_size=12)
    | st.sampled_from(["VEC3", "SCALAR", "MAT4", "../x.bin", "data:,", "http://h/b", "2.0", "KHR_x"]),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.sampled_from(["index", "count", "POSITION",
                                                                                  "KHR_materials_ior", "x"]),
                                                                 inner, max_size=3),
    max_leaves=8)


def _set(doc: dict, path: str, value) -> None:
    d = doc
    keys = [int(k) if k.isdigit() else k for k in path.split("/")]
    for k in keys[:-1]:
        if isinstance(d, list) and isinstance(k, int) and k < len(d):
            d = d[k]
        elif isinstance(d, dict):
            d = d.setdefault(k, {} if not isinstance(k, int) else [])
        else:
            return
    if isinstance(d, dict):
        d[keys[-1]] = value
    elif isinstance(d, list) and isinstance(keys[-1], int) and keys[-1] < len(d):
        d[keys[-1]] = value


@bounded(40)
@given(edits=st.lists(st.tuples(st.sampled_from(GLTF_PATHS), JSON_VALUES), min_size=1, max_size=3))
def test_property_a_gltf_with_any_fields_reads_or_is_refused_in_one_line(edits):
    from warp_sg.core.errors import ImageError, MeshError
    from warp_sg.scene.importers.gltf import load_gltf

    doc = quad_gltf()
    for path, value in edits:
        _set(doc, path, value)
    folder = Path(tempfile.mkdtemp())
    try:
        text = json.dumps(doc, allow_nan=True)
    except (TypeError, ValueError):
        return  # (not writable as JSON)
    (folder / "a.gltf").write_text(text)
    try:
        asset = load_gltf(folder / "a.gltf")
    except (MeshError, ImageError) as e:
        assert "a.gltf" in one_line(e)
        return
    for p in asset.parts:
        assert np.isfinite(p.vertices).all() and len(p.triangles) > 0
        assert p.triangles.min() >= 0 and p.triangles.max() < len(p.vertices)


# --------------------------------------------------------------------------------------------
# Radiance headers
# --------------------------------------------------------------------------------------------
@st.composite
def radiance_files(draw):
    """(bytes, the image when the header is well formed and the data complete, else None)."""
    h, w = draw(st.integers(1, 6)), draw(st.integers(1, 9))
    img = np.asarray(draw(st.lists(st.floats(0.0, 1e4), min_size=h * w * 3, max_size=h * w * 3)),
                     np.float32).reshape(h, w, 3)
    first = draw(st.sampled_from(["-Y", "+Y", "-X", "+X"]))
    second = draw(st.sampled_from(["+X", "-X"] if first[1] == "Y" else ["+Y", "-Y"]))
    extra = draw(st.lists(st.sampled_from(["EXPOSURE=1.0", "# made by hand", "GAMMA=1", "SOFTWARE=x", "PRIMARIES=0 0"]),
                          max_size=3))
    head = draw(st.sampled_from(["#?RADIANCE", "#?RGBE", "#?"]))
    path = Path(tempfile.mkdtemp()) / "m.hdr"
    write_hdr(path, img, first, second)
    raw = path.read_bytes()
    body = raw[raw.index(b"\n\n") + 2:]
    res, pixels = body.split(b"\n", 1)
    header = "\n".join([head, "FORMAT=32-bit_rle_rgbe", *extra]).encode() + b"\n\n"
    damage = draw(st.sampled_from(["none", "none", "truncate", "swap numbers", "same axis", "junk resolution"]))
    if damage == "truncate":
        pixels = pixels[:draw(st.integers(0, max(len(pixels) - 1, 0)))]
    elif damage == "swap numbers":
        a = res.split()
        res = b" ".join([a[0], a[3], a[2], a[1]]) if a[1] != a[3] else res
        damage = "none" if a[1] == a[3] else damage
    elif damage == "same axis":
        res = res.replace(b"X", b"Y") if b"X" in res.split()[2] else res.replace(b"Y", b"X")
    elif damage == "junk resolution":
        res = draw(st.sampled_from([b"-Y 0 +X 4", b"-Y -3 +X 4", b"-Y 2", b"Y 2 X 4", b"-Y 1e9 +X 2"]))
    return header + res + b"\n" + pixels, (img if damage == "none" else None), (h, w)


@bounded(40)
@given(case=radiance_files())
def test_property_a_radiance_file_reads_as_its_header_says_or_is_refused_in_one_line(case):
    from warp_sg.core.errors import ImageError
    from warp_sg.core.image_io import read_hdr

    data, img, (h, w) = case
    path = Path(tempfile.mkdtemp()) / "m.hdr"
    path.write_bytes(data)
    try:
        a = read_hdr(path)
    except ImageError as e:
        assert "m.hdr" in one_line(e)
        assert img is None, f"a well-formed file was refused: {e}"
        return
    assert a.ndim == 3 and a.shape[2] == 3 and np.isfinite(a).all()
    if img is not None:  # the usual layout of the same texels: the same image
        usual = Path(tempfile.mkdtemp()) / "u.hdr"
        write_hdr(usual, img, "-Y", "+X")
        np.testing.assert_array_equal(a, read_hdr(usual))
        assert a.shape[:2] == (h, w)


# --------------------------------------------------------------------------------------------
# batch job files
# --------------------------------------------------------------------------------------------
SCENE = replace('primitive = "sphere"', 'name = "ball"\ndynamic = true\nprimitive = "sphere"')
VARIANT_KEYS = ["camera.fov", "camera.origin", "camera.width", "materials.copper.m", "materials.copper.kd",
                "materials.floor.kd", "materials.nope.m", "lights.0.radius", "lights.0.position", "lights.3.radius",
                "environment.rotation", "objects.ball.scale", "objects.ball.translate", "objects.ball.rotate",
                "objects.floor.scale", "sky.rotation"]
NUMBERS = st.floats(allow_nan=True, allow_infinity=True, width=32) | st.integers(-5, 5) | st.sampled_from(
    [1e30, -1e30, 1e-30, 0.3, 40.0, 400.0])
VALUES = NUMBERS | st.lists(NUMBERS, min_size=1, max_size=4) | st.text(max_size=4)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else ("-inf" if v == -math.inf else repr(v)))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    return "[" + ", ".join(_toml_value(x) for x in v) + "]"


@st.composite
def job_files(draw):
    out = draw(st.sampled_from(["f/frame_{index:03d}.png", "f/{index}.exr", "frame.png", "{index:099999d}.png",
                                "{index}_{name}.png", "{index:q}.png", "{index", "f" * 260 + "{index}.png"]))
    lines = ['scene = "scene.toml"', f"output = {json.dumps(out)}"]
    kind = draw(st.sampled_from(["animate", "frames", "grid"]))
    keys = draw(st.lists(st.sampled_from(VARIANT_KEYS), min_size=1, max_size=3, unique=True))
    if kind == "animate":
        lines += ["[animate]", f"frames = {draw(st.integers(-1, 4))}"]
        lines += [f'"{k}" = [{_toml_value(draw(VALUES))}, {_toml_value(draw(VALUES))}]' for k in keys]
    elif kind == "grid":
        lines += ["[grid]"] + [f'"{k}" = {_toml_value(draw(st.lists(VALUES, min_size=0, max_size=2)))}' for k in keys]
    else:
        for k in keys:
            section, *rest = k.split(".")
            lines += ["[[frames]]", f"[frames.{section}" + (f".{rest[0]}" if len(rest) > 1 else "") + "]",
                      f"{rest[-1]} = {_toml_value(draw(VALUES))}"]
    return "\n".join(lines) + "\n"


@bounded(30)
@given(text=job_files())
def test_property_a_job_file_is_refused_in_one_line_or_every_frame_passes_the_checks(text):
    """What ``warp-sg batch`` checks before any Dask work: the job file, the output pattern, then
    every frame's values against the scene (``check_variants``); an accepted job's frames must
    each apply to a renderer without an error (the setters the workers call)."""
    from warp_sg.distributed.batch import load_job
    from warp_sg.distributed.rendering import apply_variant, check_variants, normalize_variants
    from warp_sg.scene.loader import load_scene

    folder = Path(tempfile.mkdtemp())
    (folder / "scene.toml").write_text(SCENE)
    (folder / "job.toml").write_text(text)
    scene = load_scene(folder / "scene.toml")
    try:
        job = load_job(folder / "job.toml")
        check_variants(scene, job.variants, where="job.toml")
        full = normalize_variants(scene, job.variants)
    except InputError as e:
        one_line(e)
        return
    r = _renderer(scene)
    for v in full:  # what a worker does with each frame: no error may be left for it to find
        apply_variant(r, v)


_RENDERERS: dict = {}


def _renderer(scene):
    """A renderer of the job scene (built once: the setters are what is checked)."""
    from warp_sg.renderer.renderer import Renderer

    if "r" not in _RENDERERS:
        _RENDERERS["r"] = Renderer(scene)
    return _RENDERERS["r"]


@pytest.fixture(autouse=True, scope="module")
def _forget_renderers():
    yield
    _RENDERERS.clear()
