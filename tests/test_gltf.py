"""glTF 2.0 import (issue 15, warp_sg.scene.importers.gltf): files written here with trimesh (and their JSON edited
where trimesh cannot write a feature), loaded as scene objects; the expectations are the glTF 2.0
specification's (node matrices, metallic-roughness → GGX, texture orientation), not the code's.
"""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import trimesh
from PIL import Image
from trimesh.visual import TextureVisuals
from trimesh.visual.material import PBRMaterial

from warp_sg.core.errors import MeshError
from warp_sg.scene.camera import Camera
from warp_sg.scene.importers.gltf import AssetWarning, load_gltf
from warp_sg.scene.importers.gltf_material import ALPHA_MIN
from warp_sg.scene.lights import EnvironmentLight
from warp_sg.scene.loader import load_scene
from warp_sg.scene.model import Scene, SceneObject, Transform
from warp_sg.scene.textures import sample_bilinear_np
from warp_sg.tools.cli import main

SKY = [EnvironmentLight(procedural="constant")]
QUAD_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
QUAD_F = np.array([[0, 1, 2], [0, 2, 3]])


def quad(material=None, uv=None, **attrs):
    uv = QUAD_V[:, :2].copy() if uv is None else uv
    vis = TextureVisuals(uv=uv, material=material) if material is not None else None
    return trimesh.Trimesh(QUAD_V.copy(), QUAD_F.copy(), visual=vis, process=False, vertex_attributes=attrs or None)


def write_gltf(path, scene: trimesh.Scene, edit=None):
    """Write ``scene`` as .gltf (+ .bin/.png files) next to ``path``; ``edit(header)`` changes the JSON."""
    files = scene.export(file_type="gltf")
    header = json.loads(files.pop("model.gltf"))
    if edit is not None:
        edit(header)
    for name, data in files.items():
        (path.parent / name).write_bytes(data)
    path.write_text(json.dumps(header))
    return path


def asset_scene(path, **ob):
    return Scene(camera=Camera(), objects=[SceneObject(material=ob.pop("material", None), mesh=path, **ob)],
                 materials=ob.pop("materials", {}), lights=SKY)


def test_textured_quad_texels_land_where_the_image_puts_them(tmp_path):
    # 2x2 base colour image, rows top first: red, green / blue, white. glTF UV (0, 0) is the image's
    # top-left corner; the texel centres are at u, v_glTF = 0.25, 0.75.
    px = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)
    mat = PBRMaterial(name="paint", baseColorTexture=Image.fromarray(px), metallicFactor=0.0, roughnessFactor=0.5)
    uv = np.array([[0.25, 0.25], [0.75, 0.25], [0.75, 0.75], [0.25, 0.75]])  # trimesh UVs: origin bottom-left
    s = trimesh.Scene()
    s.add_geometry(quad(mat, uv=uv), node_name="q")
    path = tmp_path / "quad.glb"
    path.write_bytes(s.export(file_type="glb"))
    sc = asset_scene(path)
    (key,) = sc.material_names
    m = sc.materials[key]
    assert key == "quad.glb/paint" and m.model == "ggx"
    g = sc.geometry()
    kd = sample_bilinear_np(m.textures["kd"].rgba(colour=True), g.uvs)[:, :3]
    # bottom-left, bottom-right, top-right, top-left of the image: blue, white, green, red
    expect = np.array([[0, 0, 1], [1, 1, 1], [0, 1, 0], [1, 0, 0]], float)
    order = np.lexsort((g.vertices[:, 0], g.vertices[:, 1]))  # (0,0), (1,0), (0,1), (1,1)
    np.testing.assert_allclose(kd[order], expect[[0, 1, 3, 2]], atol=1e-6)
    assert m.params["alpha"] == pytest.approx(0.25) and m.params["fresnel"] == {"schlick": [0.04] * 3}


def test_srgb_base_colour_is_decoded_and_metal_and_roughness_come_from_b_and_g(tmp_path):
    # sRGB code 128 is linear 0.2158605 (IEC 61966-2-1); metallicRoughness texel (R, G, B) = (9, 128, 255)
    base = Image.fromarray(np.full((2, 2, 3), 128, np.uint8))
    mr = Image.fromarray(np.array([[[9, 128, 255], [9, 128, 0]]] * 2, np.uint8))
    mat = PBRMaterial(name="m", baseColorTexture=base, metallicRoughnessTexture=mr, metallicFactor=1.0,
                      roughnessFactor=1.0)
    s = trimesh.Scene()
    s.add_geometry(quad(mat), node_name="q")
    path = write_gltf(tmp_path / "m.gltf", s)
    m = asset_scene(path).materials["m.gltf/m"]
    kd = m.textures["kd"].data
    alpha = m.textures["alpha"].data
    lin = 0.2158605
    np.testing.assert_allclose(kd[:, 0], 0.0, atol=1e-6)  # left column: metal (B = 255) has no diffuse
    np.testing.assert_allclose(kd[:, 1], lin, rtol=1e-5)  # right column: dielectric (B = 0)
    np.testing.assert_allclose(alpha, (128 / 255) ** 2, rtol=1e-5)
    # F0 = lin (metal) and 0.04 (dielectric): mean f0 in fresnel, the ratio in ks
    f0 = np.array(m.params["fresnel"]["schlick"])
    np.testing.assert_allclose(f0, (lin + 0.04) / 2, rtol=1e-5)
    np.testing.assert_allclose(m.textures["ks"].data[:, 0] * f0, lin, rtol=1e-5)
    np.testing.assert_allclose(m.textures["ks"].data[:, 1] * f0, 0.04, rtol=1e-5)


def test_metal_and_dielectric_factors_map_to_ggx(tmp_path):
    def edit(h):  # exact factors (trimesh stores baseColorFactor as 8 bits)
        h["materials"] = [
            {"name": "gold", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.766, 0.336, 1.0],
                                                      "metallicFactor": 1.0, "roughnessFactor": 0.3}},
            {"name": "plastic", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.05, 1.0],
                                                         "metallicFactor": 0.0, "roughnessFactor": 0.6}},
            {"name": "half", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0],
                                                      "metallicFactor": 0.5, "roughnessFactor": 0.05}}]
        for i, mesh in enumerate(h["meshes"]):
            mesh["primitives"][0]["material"] = i

    s = trimesh.Scene()
    for i in range(3):
        s.add_geometry(quad(PBRMaterial(name=f"x{i}")), node_name=f"n{i}", geom_name=f"g{i}",
                       transform=trimesh.transformations.translation_matrix([2.0 * i, 0, 0]))
    sc = asset_scene(write_gltf(tmp_path / "a.gltf", s, edit))
    gold, plastic, half = (sc.materials[f"a.gltf/{n}"].params for n in ("gold", "plastic", "half"))
    assert gold["kd"] == pytest.approx([0, 0, 0]) and gold["fresnel"]["schlick"] == pytest.approx([1.0, 0.766, 0.336])
    assert gold["alpha"] == pytest.approx(0.09)
    assert plastic["kd"] == pytest.approx([0.8, 0.1, 0.05]) and plastic["fresnel"]["schlick"] == pytest.approx([0.04] * 3)
    assert plastic["alpha"] == pytest.approx(0.36)
    assert half["kd"] == pytest.approx([0.25] * 3) and half["fresnel"]["schlick"] == pytest.approx([0.27] * 3)
    assert half["alpha"] == pytest.approx(max(0.05 ** 2, ALPHA_MIN))
    g = sc.geometry()
    for i, name in enumerate(("gold", "plastic", "half")):  # each quad carries its own material
        tri = g.tri_material[np.isclose(g.vertices[g.triangles[:, 0], 0], 2.0 * i)]
        assert len(tri) == 2 and {g.material_names[t] for t in tri} == {f"a.gltf/{name}"}


def test_node_hierarchy_places_two_meshes_at_their_world_transforms(tmp_path):
    tf = trimesh.transformations
    parent = tf.translation_matrix([1, 2, 3]) @ tf.rotation_matrix(np.pi / 2, [0, 1, 0])
    child = tf.translation_matrix([0, 0, 5]) @ np.diag([2.0, 3.0, 1.0, 1.0])
    other = tf.rotation_matrix(np.pi / 3, [1, 0, 0])
    s = trimesh.Scene()
    s.graph.update(frame_from=s.graph.base_frame, frame_to="parent", matrix=parent)
    s.add_geometry(quad(), node_name="child", geom_name="a", parent_node_name="parent", transform=child)
    s.add_geometry(quad(), node_name="other", geom_name="b", transform=other)
    path = tmp_path / "two.glb"
    path.write_bytes(s.export(file_type="glb"))
    shift = np.array([10.0, 0.0, 0.0])
    sc = asset_scene(path, transform=Transform(translate=tuple(shift), rotate=(0.0, 0.0, 0.0)))
    g = sc.geometry()
    hom = np.c_[QUAD_V, np.ones(4)]
    for name, M in (("child", parent @ child), ("other", other)):
        i = g.object_names.index(f"two.glb/{name}")
        got = g.vertices[g.vertex_object == i]
        want = (hom @ M.T)[:, :3] + shift
        np.testing.assert_allclose(np.sort(got, 0), np.sort(want, 0), atol=1e-5)
        # shading normals follow the transform: the quad's +Z normal, by the inverse transpose
        n = np.linalg.inv(M[:3, :3]).T @ [0, 0, 1.0]
        np.testing.assert_allclose(g.normals[g.vertex_object == i], np.tile(n / np.linalg.norm(n), (4, 1)),
                                   atol=1e-5)


def test_mirroring_node_flips_the_winding_so_faces_agree_with_normals(tmp_path):
    s = trimesh.Scene()
    s.add_geometry(quad(), node_name="m", transform=np.diag([-1.0, 1.0, 1.0, 1.0]))
    path = tmp_path / "mirror.glb"
    path.write_bytes(s.export(file_type="glb"))
    g = asset_scene(path).geometry()
    v = g.vertices[g.triangles]
    face_n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    assert np.all(np.sum(face_n * g.normals[g.triangles[:, 0]], 1) > 0)


def test_tangents_come_from_the_file_or_from_the_uvs(tmp_path):
    tangent = np.tile([0.0, 1.0, 0.0, 1.0], (4, 1)).astype(np.float32)  # not ∂P/∂u = +X
    s = trimesh.Scene()
    s.add_geometry(quad(PBRMaterial(name="p"), _TANGENT=tangent), node_name="q")

    def rename(h):
        a = h["meshes"][0]["primitives"][0]["attributes"]
        a["TANGENT"] = a.pop("_TANGENT")

    g = asset_scene(write_gltf(tmp_path / "t.gltf", s, rename)).geometry()
    np.testing.assert_allclose(g.tangents, np.tile([0, 1, 0], (4, 1)), atol=1e-6)
    s2 = trimesh.Scene()
    s2.add_geometry(quad(PBRMaterial(name="p")), node_name="q")
    (tmp_path / "u").mkdir()
    g2 = asset_scene(write_gltf(tmp_path / "u" / "t.gltf", s2)).geometry()
    np.testing.assert_allclose(g2.tangents, np.tile([1, 0, 0], (4, 1)), atol=1e-6)


def test_normal_texture_scale_tilts_x_and_y(tmp_path):
    n = np.array([0.6, 0.0, 0.8])
    px = np.round((n + 1) / 2 * 255).astype(np.uint8)
    img = Image.fromarray(np.tile(px, (2, 2, 1)))
    s = trimesh.Scene()
    s.add_geometry(quad(PBRMaterial(name="p", normalTexture=img)), node_name="q")

    def scale(h):
        h["materials"][0]["normalTexture"]["scale"] = 0.5

    m = asset_scene(write_gltf(tmp_path / "n.gltf", s, scale)).materials["n.gltf/p"]
    got = 2 * m.normal_map.raw()[0, 0, :3] - 1
    texel = 2 * px.astype(float) / 255 - 1
    want = texel * [0.5, 0.5, 1] / np.linalg.norm(texel * [0.5, 0.5, 1])
    np.testing.assert_allclose(got, want, atol=1e-6)


TOML = """
[camera]
origin = [0.0, 1.0, 4.0]
[[objects]]
mesh = "{mesh}"
{material}
[materials.red]
model = "lambert"
kd = [0.8, 0.1, 0.1]
[[lights]]
type = "environment"
procedural = "constant"
"""


@pytest.fixture
def two_material_glb(tmp_path):
    s = trimesh.Scene()
    s.add_geometry(quad(PBRMaterial(name="a", metallicFactor=1.0)), node_name="a", geom_name="a")
    s.add_geometry(quad(PBRMaterial(name="b", metallicFactor=0.0)), node_name="b", geom_name="b",
                   transform=trimesh.transformations.translation_matrix([0, 0, 1]))
    path = tmp_path / "asset.glb"
    path.write_bytes(s.export(file_type="glb"))
    return path


def test_toml_material_overrides_the_files(tmp_path, two_material_glb):
    p = tmp_path / "s.toml"
    p.write_text(TOML.format(mesh=two_material_glb.name, material='material = "red"'))
    sc = load_scene(p)
    assert sc.material_names == ["red"]
    g = sc.geometry()
    assert len(g.triangles) == 4 and set(g.tri_material.tolist()) == {0}
    p.write_text(TOML.format(mesh=two_material_glb.name, material=""))
    sc = load_scene(p)
    assert sc.material_names == ["red", "asset.glb/a", "asset.glb/b"]
    assert sc.materials["asset.glb/a"].params["kd"] == pytest.approx([0, 0, 0])


def test_unsupported_extension_is_one_line_warning_and_ignored(tmp_path, capsys):
    s = trimesh.Scene()
    s.add_geometry(quad(PBRMaterial(name="p")), node_name="q")

    def ext(h):
        h["extensionsUsed"] = ["KHR_materials_sheen", "EXT_made_up"]
        h["materials"][0]["extensions"] = {"KHR_materials_sheen": {"sheenColorFactor": [1, 0, 0]}}

    path = write_gltf(tmp_path / "e.gltf", s, ext)
    with pytest.warns(AssetWarning) as rec:
        sc = asset_scene(path)
    msgs = [str(w.message) for w in rec]
    assert msgs == ["e.gltf: glTF extension 'KHR_materials_sheen' is not supported; ignored",
                    "e.gltf: glTF extension 'EXT_made_up' is not supported; ignored"]
    assert len(sc.geometry().triangles) == 2
    rc = main(["render", str(path), "--print-scene"])
    err = capsys.readouterr().err
    assert rc == 0
    assert err.splitlines() == ["warp-sg: warning: " + m for m in msgs]


@pytest.mark.parametrize("content", [b"", b"glTF\x02\x00\x00\x00garbage-garbage-garbage", b"{not json"])
def test_bad_file_exits_2_naming_it_and_writes_nothing(tmp_path, capsys, content):
    bad = tmp_path / ("bad.gltf" if content.startswith(b"{") else "bad.glb")
    bad.write_bytes(content)
    with pytest.raises(MeshError, match="bad.gl"):
        load_gltf(bad)
    out = tmp_path / "o.png"
    rc = main(["render", str(bad), "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and bad.name in err[0] and not out.exists()
    p = tmp_path / "s.toml"
    p.write_text(TOML.format(mesh=bad.name, material=""))
    with pytest.raises(MeshError, match="bad.gl"):
        load_scene(p)


def test_no_warning_for_a_plain_file(two_material_glb):
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssetWarning)
        asset_scene(two_material_glb)
