"""Scene files and Scene objects: loading, validation messages, geometry flattening, primitives."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import replace_once, write_scene  # (the shared scene: BALL_ON_FLOOR)

import warp_sg as ws
from warp_sg.core.errors import MeshError, SceneError
from warp_sg.scene.loader import load_scene
from warp_sg.scene.model import Material, Scene, SceneObject, Transform
from warp_sg.scene.primitives import plane, sphere, torus
from warp_sg.scene.render_settings import RENDER_CHOICES, RenderSettings, uses_sigmoid

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


# ---------------------------------------------------------------------------------------------
# loading
# ---------------------------------------------------------------------------------------------
def test_scene_file_loads_camera_objects_materials_lights_and_render_settings(tmp_path):
    sc = load_scene(write_scene(tmp_path))
    assert (sc.camera.width, sc.camera.height, sc.camera.fov) == (16, 12, 40.0)
    assert np.allclose(sc.camera.origin, [0, 1, 4])
    assert [o.primitive for o in sc.objects] == ["sphere", "plane"]
    assert sc.material_names == ["copper", "floor"]
    assert sc.materials["copper"].brdf.NAME == "cook_torrance"
    assert sc.materials["copper"].brdf.m == pytest.approx(0.2)
    (light,) = sc.lights
    assert light.type == "point" and light.radius == pytest.approx(0.1)
    assert np.allclose(light.intensity, 20.0)
    assert sc.render.shadows is False and sc.render.supersampling == 1 and sc.render.antialias == 4
    assert sc.environment is None and sc.local_lights == [light]


def test_geometry_merges_objects_with_material_and_object_ids(tmp_path):
    g = load_scene(write_scene(tmp_path)).geometry()
    n_sphere = 9 * 17  # (n_theta + 1) × (n_phi + 1) vertices, seams duplicated
    n_plane = 3 * 3
    assert g.vertices.shape == (n_sphere + n_plane, 3) and g.vertices.dtype == np.float32
    assert g.normals.shape == g.vertices.shape and g.tangents.shape == g.vertices.shape
    assert g.uvs.shape == (len(g.vertices), 2)
    sphere_tris = 8 * 16 * 2 - 2 * 16  # one triangle per pole segment
    assert g.triangles.shape == (sphere_tris + 2 * 2 * 2, 3) and g.triangles.dtype == np.int32
    assert np.all(g.tri_material[:sphere_tris] == 0) and np.all(g.tri_material[sphere_tris:] == 1)
    assert np.all(g.tri_object[sphere_tris:] == 1) and np.all(g.vertex_object[n_sphere:] == 1)
    assert g.triangles[sphere_tris:].min() == n_sphere  # plane indices are offset
    np.testing.assert_allclose(np.linalg.norm(g.normals, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(np.sum(g.normals * g.tangents, axis=1), 0.0, atol=1e-5)


def test_python_scene_equals_the_toml_scene(tmp_path):
    toml = load_scene(write_scene(tmp_path))
    py = Scene(
        camera=toml.camera,
        objects=[SceneObject(material="copper", primitive="sphere",
                             params={"center": (0, 0.5, 0), "radius": 0.5, "resolution": (8, 16)}),
                 SceneObject(material="floor", primitive="plane", params={"size": (4, 4), "resolution": (2, 2)})],
        materials={"copper": ws.brdf.CookTorrance(ks=1.0, m=0.2, fresnel="copper"), "floor": Material("lambert", {"kd": 0.8})},
        lights=[ws.scene.PointLight(position=(2, 3, 2), radius=0.1, intensity=20.0)],
        render=RenderSettings(shadows=False),
    )
    a, b = toml.geometry(), py.geometry()
    np.testing.assert_array_equal(a.triangles, b.triangles)
    np.testing.assert_allclose(a.vertices, b.vertices)
    np.testing.assert_allclose(py.materials["floor"].brdf.kd, 0.8)


def test_example_scenes_load(tmp_path):
    for f in ["cook_torrance", "ward", "ashikhmin_shirley", "textured", "shadows"]:
        sc = load_scene(EXAMPLES / f"{f}.toml")
        g = sc.geometry()
        assert len(g.triangles) > 1000 and g.dropped_triangles == 0
    tex = load_scene(EXAMPLES / "textured.toml").materials["tiles"]
    assert set(tex.textures) == {"kd", "m"} and tex.normal_map is not None
    m = tex.textures["m"].rgba()[..., 0]
    assert 0.05 <= m.min() and m.max() <= 0.55 + 1e-6  # offset + scale · texel
    assert load_scene(EXAMPLES / "ashikhmin_shirley.toml").materials["brushed"].brdf.lobes == 7


def test_mesh_objects_are_read_with_trimesh_relative_to_the_scene_file(tmp_path):
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    sc = load_scene(write_scene(tmp_path, replace_once('primitive = "plane"\nsize = [4.0, 4.0]\nresolution = [2, 2]',
                                        'mesh = "m/tri.obj"\ntranslate = [1.0, 0.0, 0.0]\nscale = 2.0')))
    g = sc.geometry()
    v = g.vertices[g.vertex_object == 1]
    np.testing.assert_allclose(sorted(v[:, 0]), [1, 1, 3, 3])
    np.testing.assert_allclose(g.normals[g.vertex_object == 1], [[0, 0, 1]] * 4, atol=1e-6)


def test_transform_rotates_vertices_normals_and_tangents():
    tr = Transform(translate=(1, 2, 3), scale=(2, 2, 2), rotate=(0, 90, 0))
    m = tr.apply(plane(size=2.0, resolution=(1, 1)))
    # rotation by 90° about +Y maps +X to −Z; the plane's normal +Y is unchanged
    np.testing.assert_allclose(m.normals, [[0, 1, 0]] * 4, atol=1e-6)
    np.testing.assert_allclose(m.tangents, [[0, 0, -1]] * 4, atol=1e-6)
    np.testing.assert_allclose(m.vertices[:, 1], 2.0)
    np.testing.assert_allclose(np.sort(m.vertices[:, 0]), [-1, -1, 3, 3], atol=1e-6)


# ---------------------------------------------------------------------------------------------
# primitives
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mesh", [sphere(radius=2.0, resolution=(8, 12)), plane(resolution=(3, 2)),
                                  torus(resolution=(12, 8))], ids=["sphere", "plane", "torus"])
def test_primitives_wind_counterclockwise_about_unit_normals_with_orthogonal_tangents(mesh):
    v, t = mesh.vertices, mesh.triangles
    e = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    assert np.all(np.linalg.norm(e, axis=1) > 0)  # no zero-area triangles
    assert np.all(np.sum(e * mesh.normals[t].mean(1), axis=1) > 0)
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1, atol=1e-6)
    np.testing.assert_allclose(np.sum(mesh.normals * mesh.tangents, axis=1), 0, atol=1e-6)
    assert mesh.uvs.min() >= 0 and mesh.uvs.max() <= 1


def test_sphere_vertices_lie_on_the_sphere_and_tangents_follow_u():
    m = sphere(center=(1, 2, 3), radius=0.5, resolution=(6, 8))
    np.testing.assert_allclose(np.linalg.norm(m.vertices - [1, 2, 3], axis=1), 0.5, atol=1e-6)
    # ∂P/∂u along the equator at u = 0 (φ = 0, point +Z) is +X
    k = np.argmin(np.linalg.norm(m.vertices - [1, 2, 3.5], axis=1))
    np.testing.assert_allclose(m.tangents[k], [1, 0, 0], atol=1e-6)


# ---------------------------------------------------------------------------------------------
# validation messages
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("old,new,message", [
    ("m = 0.2", "rougness = 0.2", "scene.toml: [materials.copper] key 'rougness' unknown"),
    ("fov = 40.0", "fvo = 40.0", "[camera] key 'fvo' unknown — did you mean 'fov'?"),
    ("[render]", "[rendr]", "key 'rendr' unknown — did you mean 'render'?"),
    ("shadows = false", "shadow = false", "[render] key 'shadow' unknown — did you mean 'shadows'?"),
    ("fov = 40.0", 'fov = "wide"', "[camera] key 'fov' must be a number"),
    ("width = 16", "width = 0", "[camera] key 'width' must be >= 1"),
    ("radius = 0.1", "radius = -0.1", "[[lights]] #1 key 'radius' must be >= 0"),
    ('type = "point"', 'type = "spot"', "[[lights]] #1 key 'type': unknown light type 'spot'"),
    ('material = "copper"', 'material = "coper"', "[[objects]] #1 material 'coper' is not defined — did you mean 'copper'?"),
    ('primitive = "sphere"', 'primitive = "sphre"', "did you mean 'sphere'?"),
    ('model = "lambert"', 'model = "lamber"', "[materials.floor] key 'model': unknown model 'lamber' — did you mean 'lambert'?"),
    ("radius = 0.5\n", "radius = 0.5\nheight = 2.0\n", "[[objects]] #1 key 'height' unknown"),
    ("kd = [0.8, 0.8, 0.8]", 'kd = "nothere.png"', "[materials.floor] key 'kd': file not found: nothere.png"),
    ("m = 0.2", "m = -0.2", "[materials.copper] key 'm'"),
    ("shadows = false", "supersampling = 0", "[render] key 'supersampling' must be in [1, 16]"),
    ("[render]", 'mesh = "x"\n[render]', "[[lights]] #1 key 'mesh' unknown"),
])
def test_bad_scene_file_raises_scene_error_naming_file_table_and_key(tmp_path, old, new, message):
    with pytest.raises(SceneError) as ei:
        load_scene(write_scene(tmp_path, replace_once(old, new)))
    assert message in str(ei.value)
    assert str(ei.value).startswith("scene.toml: ")


@pytest.mark.parametrize("key,toml,value,message", [
    ("supersampling", "0", 0, "[render] key 'supersampling' must be in [1, 16], got 0"),
    ("antialias", "9", 9, "[render] key 'antialias' must be in [1, 8], got 9"),
    ("lobes", "2.5", 2.5, "[render] key 'lobes' must be an integer, got 2.5"),
    ("shadows", "1", 1, "[render] key 'shadows' must be true or false, got 1"),
    ("fh", '"spline"', "spline", "[render] key 'fh' must be 'table' or 'sigmoid', got 'spline'"),
    ("visibility_sampling", '"texel"', "texel", "[render] key 'visibility_sampling' must be 'vertex' or 'pixel', "
                                                "got 'texel'"),
    ("device", "3", 3, "[render] key 'device' must be a string, got 3"),
])
def test_python_render_settings_are_refused_in_the_scene_files_words(tmp_path, key, toml, value, message):
    """One rule for [render]: the same bad value in a scene file and in a Scene built in Python
    gives the same line (the file's prefixed with its name)."""
    with pytest.raises(SceneError) as from_file:
        load_scene(write_scene(tmp_path, replace_once("shadows = false", f"{key} = {toml}")))
    assert str(from_file.value) == f"scene.toml: {message}"
    with pytest.raises(SceneError) as from_python:
        Scene(camera=ws.scene.Camera(), objects=[SceneObject(material="a", primitive="sphere")],
              materials={"a": Material("lambert")}, lights=[ws.scene.DirectionalLight((0, 1, 0))],
              render=RenderSettings(**{key: value}))
    assert str(from_python.value) == message


def test_the_fh_choice_is_read_in_one_place():
    """``[render] fh``: the kernels' sigmoid or the table, decided by ``uses_sigmoid`` alone (the kernel
    variant, the per-vertex light caches and the moving objects' ask it)."""
    assert [uses_sigmoid(c) for c in RENDER_CHOICES["fh"]] == [False, True]
    with pytest.raises(ValueError, match="fh must be one of table, sigmoid"):
        uses_sigmoid("spline")


def test_render_settings_edited_after_the_scene_was_built_are_checked_by_the_renderer():
    sc = Scene(camera=ws.scene.Camera(width=4, height=4), objects=[SceneObject(material="a", primitive="sphere")],
               materials={"a": Material("lambert")}, lights=[ws.scene.DirectionalLight((0, 1, 0))],
               render=RenderSettings(shadows=False, supersampling=np.int64(2)))  # a numpy integer is an integer
    sc.render.supersampling = 17
    with pytest.raises(SceneError, match=r"^\[render\] key 'supersampling' must be in \[1, 16\], got 17$"):
        ws.Renderer(sc)


def test_missing_mesh_file_and_missing_scene_file_are_scene_errors(tmp_path):
    with pytest.raises(SceneError, match="file not found: gone.ply"):
        load_scene(write_scene(tmp_path, replace_once('primitive = "plane"\nsize = [4.0, 4.0]\nresolution = [2, 2]', 'mesh = "gone.ply"')))
    with pytest.raises(SceneError, match="nope.toml"):
        load_scene(tmp_path / "nope.toml")


def _inline(v, t):
    return Scene(camera=ws.scene.Camera(width=4, height=4), objects=[SceneObject(material="a", vertices=v, triangles=t,
                                                                                 name="blob")],
                 materials={"a": Material("lambert")}, lights=[ws.scene.DirectionalLight((0, 1, 0))])


def test_nan_vertex_and_out_of_range_index_raise_mesh_error_naming_the_element():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [np.nan, 0, 0]], float)
    with pytest.raises(MeshError, match=r"blob.*vertex 3 has a non-finite coordinate"):
        _inline(v, [[0, 1, 2]]).geometry()
    with pytest.raises(MeshError, match=r"triangle 1 references vertex \[0, 1, 7\] out of range .*3 vertices"):
        _inline(v[:3], [[0, 1, 2], [0, 1, 7]]).geometry()


def test_zero_area_triangles_are_dropped_and_counted():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], float)
    g = _inline(v, [[0, 1, 2], [0, 1, 3], [1, 1, 2]]).geometry()  # collinear + repeated index
    assert g.dropped_triangles == 2
    np.testing.assert_array_equal(g.triangles, [[0, 1, 2]])


def test_undefined_material_and_missing_lights_in_python_scene():
    with pytest.raises(SceneError, match="material 'b' is not defined"):
        Scene(camera=ws.scene.Camera(), objects=[SceneObject(material="b", primitive="sphere")],
              materials={"a": Material("lambert")}, lights=[ws.scene.DirectionalLight((0, 1, 0))])
    with pytest.raises(SceneError, match="no lights"):
        Scene(camera=ws.scene.Camera(), objects=[SceneObject(material="a", primitive="sphere")],
              materials={"a": Material("lambert")}, lights=[])
