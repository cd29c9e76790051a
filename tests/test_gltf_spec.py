"""glTF read against the specification before anything is decoded (issue 51): JSON references,
required fields, ranges, accessor bounds, buffer URIs, extensions, morph targets, strips and fans.

Two independent sources of truth: the Khronos glTF-Validator's own test files and reports
(``tests/data/gltf_validator``, Apache-2.0) — each invalid file is refused in one line naming the
element the validator points at, each valid one renders once a quad is added — and the glTF 2.0
specification's formulas (sparse substitution, morph targets, strip and fan order), computed here
with numpy on small files the tests write."""
from __future__ import annotations

import importlib.util
import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from gltf_files import FLOAT, U16, GltfWriter, png, quad

from warp_sg.core.errors import MeshError
from warp_sg.scene.importers.gltf import AssetWarning, gltf_object_parts, load_gltf
from warp_sg.tools.cli import main

ROOT = Path(__file__).resolve().parents[1]
VALIDATOR = Path(__file__).parent / "data" / "gltf_validator"
FILES = sorted(p.name for p in VALIDATOR.iterdir() if p.suffix in (".gltf", ".glb"))
#: an exception class quoted instead of the user's words
INTERNAL = re.compile(r"\b[A-Z][A-Za-z]*(Error|Exception)\b|Traceback")


def _corpus_script():
    spec = importlib.util.spec_from_file_location("gltf_corpus", ROOT / "scripts" / "gltf_corpus.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _report(name: str) -> dict:
    return json.loads((VALIDATOR / f"{name}.report.json").read_text())["issues"]


def _element_paths(pointer: str) -> list[str]:
    """The glTF paths a JSON pointer ``/nodes/0/translation/1`` names, shortest first from the
    entry on: ``nodes[0]``, ``nodes[0].translation``, ``nodes[0].translation[1]`` (a top-level
    key alone: ``scene``)."""
    out, path = [], ""
    for part in pointer.strip("/").split("/"):
        path += f"[{part}]" if part.isdigit() else (("." if path else "") + part)
        out.append(path)
    return out[1:] if len(out) > 1 else out


@pytest.mark.parametrize("name", FILES)
def test_validator_files_are_refused_in_one_line_naming_what_the_validator_points_at(name):
    issues = _report(name)
    with pytest.raises(MeshError) as err:
        load_gltf(VALIDATOR / name)
    msg = str(err.value)
    assert name in msg and "\n" not in msg and not INTERNAL.search(msg), msg
    if issues["numErrors"] == 0:  # valid, but none of these files holds drawable data
        assert "nothing to draw" in msg
        return
    pointers = [m.get("pointer") for m in issues["messages"] if m["severity"] == 0]
    if any(pointers):
        assert any(p in msg for ptr in pointers if ptr for p in _element_paths(ptr)), (msg, pointers)
    else:  # the container itself
        assert ("GLB" in msg) if name.endswith(".glb") else ("JSON" in msg), msg


def test_validator_files_found_valid_render_once_a_quad_is_added(tmp_path):
    corpus = _corpus_script()
    valid = [n for n in FILES if _report(n)["numErrors"] == 0]
    assert len(valid) >= 4
    for name in valid:
        path = tmp_path / name
        path.write_text(json.dumps(corpus.with_quad(json.loads((VALIDATOR / name).read_text()))))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", AssetWarning)
            asset = load_gltf(path)
        (part,) = asset.parts
        np.testing.assert_array_equal(np.sort(part.vertices, 0), np.sort(corpus.QUAD.astype(np.float64), 0))
        assert len(part.triangles) == 2


# --------------------------------------------------------------------------------------------
# materials, nodes, extensions: one line naming file, element and rule
# --------------------------------------------------------------------------------------------
def quad_file(path, material: dict | None = None, *, used=(), required=(), node: dict | None = None, gltf=False):
    w = GltfWriter()
    P, idx, N, uv = quad(1.0, 0.0, 1)
    m = None if material is None else w.material(material)
    w.mesh(P, idx, N, uv, material=m, name="thing")
    if node is not None:
        w.h["nodes"][0].update(node)
    w.used.update(used)
    if required:
        w.h["extensionsRequired"] = list(required)
    return w.gltf(path) if gltf else w.glb(path)


def run(argv, capsys):
    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    return rc, [x for x in out.err.splitlines() if x.strip()]


def refused(path, capsys, *words):
    out = path.with_name("o.png")
    rc, err = run(["render", path, "-o", out, "--width", 16, "--height", 12, "--no-shadows", "--no-progress"], capsys)
    assert rc == 2 and len(err) == 1 and err[0].startswith("warp-sg: error:"), err
    assert path.name in err[0] and not INTERNAL.search(err[0]), err
    for w in words:
        assert w in err[0], (w, err[0])
    assert not out.exists()
    return err[0]


@pytest.mark.parametrize("field,value", [("baseColorFactor", [float("nan"), 0.1, 0.1, 1.0]), ("roughnessFactor", -0.5),
                                         ("metallicFactor", 2.0)])
def test_a_bad_material_factor_names_the_file_the_material_and_the_glTF_field(tmp_path, capsys, field, value):
    # before: "kd: must be finite" / "kd: must be >= 0", a derived value, the material and field unnamed
    mat = {"name": "paint", "pbrMetallicRoughness": {"metallicFactor": 0.0, field: value}}
    msg = refused(quad_file(tmp_path / "car.glb", mat), capsys, "materials[0] ('paint')",
                  f"pbrMetallicRoughness.{field}", "[0, 1]")
    assert "kd" not in msg


def test_a_required_extension_that_is_not_rendered_is_refused_and_a_used_one_warned_once(tmp_path, capsys):
    inst = {"extensions": {"EXT_mesh_gpu_instancing": {"attributes": {}}}}
    refused(quad_file(tmp_path / "req.glb", used=["EXT_mesh_gpu_instancing"], required=["EXT_mesh_gpu_instancing"],
                      node=inst), capsys, "EXT_mesh_gpu_instancing", "extensionsRequired")
    out = tmp_path / "o.png"
    rc, err = run(["render", quad_file(tmp_path / "used.glb", used=["EXT_mesh_gpu_instancing"], node=inst), "-o", out,
                   "--width", 16, "--height", 12, "--no-shadows", "--no-progress"], capsys)
    assert rc == 0 and out.is_file()
    assert len(err) == 1 and "warning" in err[0] and "EXT_mesh_gpu_instancing" in err[0], err


def test_a_webp_texture_is_decoded_and_not_reported(tmp_path):
    # EXT_texture_webp: the texture's image comes from the extension's source (lossless WebP here)
    import io

    from PIL import Image

    from warp_sg.scene.textures import srgb_to_linear

    w = GltfWriter()
    buf = io.BytesIO()
    Image.fromarray(np.full((4, 4, 3), (200, 100, 50), np.uint8)).save(buf, format="WEBP", lossless=True)
    w.h["images"] = [{"bufferView": w.view(buf.getvalue()), "mimeType": "image/webp"}]
    w.h["textures"] = [{"extensions": {"EXT_texture_webp": {"source": 0}}}]
    m = w.material({"name": "w", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}})
    w.used.add("EXT_texture_webp")
    P, idx, N, uv = quad(1.0, 0.0, 1)
    w.mesh(P, idx, N, uv, material=m)
    path = w.glb(tmp_path / "webp.glb")
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssetWarning)
        _, specs = gltf_object_parts(path, "a")
    (spec,) = specs.values()
    want = srgb_to_linear(np.array([200, 100, 50]) / 255.0)
    np.testing.assert_allclose(spec["textures"]["kd"].data[..., :3].reshape(-1, 3).mean(0), want, rtol=1e-5)


def test_an_infinite_translation_on_a_parent_node_is_refused_naming_it(tmp_path, capsys):
    w = GltfWriter()
    P, idx, N, uv = quad(1.0, 0.0, 1)
    child = w.mesh(P, idx, N, uv)
    w.h["nodes"].append({"name": "root", "translation": [float("inf"), 0.0, 0.0], "children": [child]})
    w.h["scenes"][0]["nodes"] = [len(w.h["nodes"]) - 1]
    refused(w.glb(tmp_path / "far.glb"), capsys, "nodes[1] ('root').translation", "finite")


def test_material_extensions_present_but_undeclared_are_rendered_or_reported(tmp_path):
    # KHR_materials_emissive_strength is rendered whether declared or not; KHR_materials_sheen is
    # not rendered, and said so even though extensionsUsed does not list it
    mat = {"name": "m", "emissiveFactor": [0.5, 0.25, 1.0],
           "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0},
                          "KHR_materials_sheen": {"sheenColorFactor": [1, 0, 0]}}}
    w = GltfWriter()
    m = w.h["materials"].append(mat) or 0
    P, idx, N, uv = quad(1.0, 0.0, 1)
    w.mesh(P, idx, N, uv, material=m)
    with pytest.warns(AssetWarning) as rec:
        _, specs = gltf_object_parts(w.glb(tmp_path / "undeclared.glb"), "a")
    assert [str(r.message) for r in rec] == ["undeclared.glb: glTF extension 'KHR_materials_sheen' is not supported; "
                                             "ignored"]
    assert specs["a/m"]["layers"].emission == pytest.approx((2.0, 1.0, 4.0))


def test_morph_targets_move_the_vertices_by_their_weights(tmp_path):
    # glTF 2.0 §3.7.2.2: P = P0 + Σ w_k T_k, the node's weights overriding the mesh's
    w = GltfWriter()
    P, idx, N, uv = quad(1.0, 0.0, 1)
    w.mesh(P, idx, N, uv)
    prim = w.h["meshes"][0]["primitives"][0]
    up = np.tile([0.0, 1.0, 0.0], (len(P), 1))
    side = np.c_[np.arange(len(P), dtype=np.float64), np.zeros((len(P), 2))]
    prim["targets"] = [{"POSITION": w.accessor(up)}, {"POSITION": w.accessor(side)}]
    w.h["meshes"][0]["weights"] = [1.0, 1.0]
    w.h["nodes"][0]["weights"] = [0.5, -0.25]
    (part,) = load_gltf(w.glb(tmp_path / "morph.glb")).parts
    np.testing.assert_allclose(part.vertices, P + 0.5 * up - 0.25 * side, atol=1e-6)


# --------------------------------------------------------------------------------------------
# buffers and accessors
# --------------------------------------------------------------------------------------------
def test_data_uri_and_relative_buffers_are_read(tmp_path):
    a = load_gltf(quad_file(tmp_path / "inline.gltf", gltf=True))
    w = GltfWriter()
    P, idx, N, uv = quad(1.0, 0.0, 1)
    w.mesh(P, idx, N, uv)
    (tmp_path / "sub").mkdir()
    b = load_gltf(w.gltf(tmp_path / "sub" / "beside.gltf", uri="beside%20data.bin"))
    for asset in (a, b):
        np.testing.assert_allclose(asset.parts[0].vertices, P)


@pytest.mark.parametrize("uri,words", [
    ("../outside.bin", ["buffers[0].uri '../outside.bin'", "outside the asset's folder"]),
    ("/etc/passwd", ["buffers[0].uri", "relative path"]),
    ("http://example.com/a.bin", ["buffers[0].uri 'http://example.com/a.bin'", "no network"]),
    ("missing.bin", ["buffers[0].uri 'missing.bin'", "not found"]),
    ("data:application/octet-stream;base64,@@@", ["buffers[0].uri", "not valid base64"]),
    ("short.bin", ["buffers[0] holds 4 bytes", "byteLength"]),
])
def test_a_buffer_uri_that_cannot_be_read_is_refused_naming_it(tmp_path, capsys, uri, words):
    (tmp_path / "outside.bin").write_bytes(b"\0" * 200)
    (tmp_path / "short.bin").write_bytes(b"\0" * 4)
    folder = tmp_path / "asset"
    folder.mkdir()
    path = quad_file(folder / "a.gltf", gltf=True)
    h = json.loads(path.read_text())
    h["buffers"][0]["uri"] = uri
    if uri == "short.bin":
        (folder / "short.bin").write_bytes(b"\0" * 4)
    path.write_text(json.dumps(h))
    refused(path, capsys, *words)


def test_an_accessor_past_its_buffer_view_is_refused_naming_its_use(tmp_path, capsys):
    path = quad_file(tmp_path / "a.gltf", gltf=True)
    h = json.loads(path.read_text())
    h["accessors"][0]["count"] = 400
    path.write_text(json.dumps(h))
    refused(path, capsys, "meshes[0].primitives[0].attributes.POSITION: accessors[0] reads bytes", "bufferViews[0]")


def test_sparse_positions_replace_the_base_values(tmp_path):
    # glTF 2.0 §3.6.2.3: out[indices[k]] = values[k]; without a bufferView the base is zeros
    w = GltfWriter()
    P, idx, N, uv = quad(1.0, 0.0, 1)
    w.mesh(P, idx, N, uv)
    pos = w.h["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
    moved = np.array([[0.7, 0.2, -0.1], [0.0, 0.5, 0.0]])
    w.h["accessors"][pos]["sparse"] = {
        "count": 2, "indices": {"bufferView": w.view(np.array([1, 3], np.uint16).tobytes()), "componentType": U16},
        "values": {"bufferView": w.view(moved.astype(np.float32).tobytes())}}
    want = P.copy()
    want[[1, 3]] = moved
    (part,) = load_gltf(w.glb(tmp_path / "sparse.glb")).parts
    np.testing.assert_allclose(part.vertices, want, atol=1e-7)


@pytest.mark.parametrize("mode", [5, 6])
def test_strips_and_fans_become_the_specified_triangles(tmp_path, mode):
    # glTF 2.0 §3.7.2.1: strip triangle i = (v_i, v_{i+1+i%2}, v_{i+2-i%2}); fan i = (v_{i+1}, v_{i+2}, v_0)
    ring = np.array([[0, 0, 0], [1, 0, 0], [1.5, 0, 1], [1, 0, 2], [0, 0, 2.2]], np.float64)
    w = GltfWriter()
    w.mesh(ring, np.arange(5), None, None)
    w.h["meshes"][0]["primitives"][0]["mode"] = mode
    (part,) = load_gltf(w.glb(tmp_path / "m.glb")).parts
    i = np.arange(3)
    want = np.stack([i, i + 1 + i % 2, i + 2 - i % 2], 1) if mode == 5 else np.stack([i + 1, i + 2, 0 * i], 1)
    got = {tuple(np.roll(t, -int(np.argmin(t)))) for t in part.triangles}
    assert got == {tuple(np.roll(t, -int(np.argmin(t)))) for t in want}


def test_indices_that_do_not_make_whole_triangles_are_refused(tmp_path, capsys):
    w = GltfWriter()
    P, idx, N, uv = quad(1.0, 0.0, 1)
    w.mesh(P, np.r_[idx.reshape(-1), 0], N, uv)
    refused(w.glb(tmp_path / "t.glb"), capsys, "meshes[0].primitives[0].indices", "multiple of 3")


def test_a_large_accessor_without_data_is_refused_by_its_size_not_by_memory(tmp_path, capsys):
    path = quad_file(tmp_path / "a.gltf", gltf=True)
    h = json.loads(path.read_text())
    h["accessors"].append({"componentType": FLOAT, "count": 10 ** 12, "type": "VEC3"})
    h["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = len(h["accessors"]) - 1
    path.write_text(json.dumps(h))
    refused(path, capsys, "attributes.NORMAL", "too long", "1,000,000,000,000")


def test_a_texture_image_outside_the_folder_is_not_read(tmp_path, capsys):
    (tmp_path / "secret.png").write_bytes(png(np.zeros((2, 2, 3), np.uint8)))
    folder = tmp_path / "asset"
    folder.mkdir()
    w = GltfWriter()
    w.h["images"] = [{"uri": "../secret.png"}]
    w.h["textures"] = [{"source": 0}]
    m = w.material({"name": "paint", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})
    P, idx, N, uv = quad(1.0, 0.0, 1)
    w.mesh(P, idx, N, uv, material=m)
    refused(w.gltf(folder / "a.gltf"), capsys, "material 'paint' baseColorTexture", "outside the asset's folder")
