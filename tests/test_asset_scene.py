"""``warp-sg render ASSET`` (issue 15, warp_sg.scene.importers.asset): the scene made for an asset frames its
bounding box, puts a ground plane under it, lights it with the default sky or ``--env``, and
``--print-scene`` prints TOML that loads back into the same scene."""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from warp_sg.scene.importers.asset import asset_scene
from warp_sg.scene.loader import load_scene
from warp_sg.tools.cli import main


@pytest.fixture
def glb(tmp_path):
    """Two boxes under a translated, rotated and scaled root: bbox off the origin."""
    tf = trimesh.transformations
    s = trimesh.Scene()
    root = tf.translation_matrix([3.0, 1.0, -2.0]) @ tf.rotation_matrix(0.4, [0, 1, 0]) @ np.diag([2, 2, 2, 1.0])
    s.graph.update(frame_from=s.graph.base_frame, frame_to="root", matrix=root)
    s.add_geometry(trimesh.creation.box(extents=[1, 0.5, 0.3]), node_name="a", geom_name="a",
                   parent_node_name="root")
    s.add_geometry(trimesh.creation.icosphere(subdivisions=1, radius=0.3), node_name="b", geom_name="b",
                   parent_node_name="root", transform=tf.translation_matrix([0, 0.6, 0]))
    p = tmp_path / "thing.glb"
    p.write_bytes(s.export(file_type="glb"))
    return p, s.bounds


def corners(lo, hi):
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


@pytest.mark.parametrize("view", [(30.0, 20.0), (-120.0, 60.0), (200.0, -10.0)])
def test_camera_frames_every_bbox_corner_from_the_asked_direction(glb, view):
    path, (lo, hi) = glb
    scene, _ = asset_scene(path, view=view, width=320, height=200)
    cam = scene.camera
    o, t = np.array(cam.origin), np.array(cam.target)
    np.testing.assert_allclose(t, (lo + hi) / 2, atol=1e-5)
    d = (o - t) / np.linalg.norm(o - t)
    az, el = map(math.radians, view)
    np.testing.assert_allclose(d, [math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)], atol=1e-6)
    # pinhole projection of the corners (independent of warp_sg.scene.camera): inside the image
    f = (t - o) / np.linalg.norm(t - o)
    r = np.cross(f, [0, 1, 0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    rel = corners(lo, hi) - o
    z = rel @ f
    th = math.tan(math.radians(cam.fov) / 2)
    assert np.all(z > cam.near)
    assert np.all(np.abs(rel @ u / z) < th) and np.all(np.abs(rel @ r / z) < th * cam.width / cam.height)


def test_ground_plane_lies_under_the_bbox_and_extends_past_it(glb):
    path, (lo, hi) = glb
    scene, _ = asset_scene(path)
    g = scene.geometry()
    ground = g.vertices[g.vertex_object == g.object_names.index("ground")]
    np.testing.assert_allclose(ground[:, 1], lo[1], atol=1e-5)
    assert np.all(ground.min(0)[[0, 2]] < lo[[0, 2]]) and np.all(ground.max(0)[[0, 2]] > hi[[0, 2]])
    asset = g.vertices[g.vertex_object != g.object_names.index("ground")]
    np.testing.assert_allclose(asset.min(0), lo, atol=1e-5)
    np.testing.assert_allclose(asset.max(0), hi, atol=1e-5)
    (env,) = scene.lights
    assert env.procedural == "sky"


def test_printed_scene_loads_back_into_the_same_scene(glb, tmp_path, capsys):
    path, _ = glb
    sky = tmp_path / "sky.exr"
    from warp_sg.core.image_io import save_image

    save_image(sky, np.full((8, 16, 3), 0.5, np.float32))
    rc = main(["render", str(path), "--env", str(sky), "--view", "45", "30", "--width", "96", "--height", "64",
               "--print-scene"])
    text = capsys.readouterr().out
    assert rc == 0
    (tmp_path / "elsewhere").mkdir()
    saved = tmp_path / "elsewhere" / "scene.toml"  # absolute paths: loads from any folder
    saved.write_text(text)
    loaded = load_scene(saved)
    made, _ = asset_scene(path, env=sky, view=(45.0, 30.0), width=96, height=64)
    assert loaded.camera == made.camera
    assert loaded.material_names == made.material_names
    for k in made.materials:
        assert loaded.materials[k].params == made.materials[k].params
    a, b = loaded.geometry(), made.geometry()
    for name in ("vertices", "normals", "triangles", "tri_material", "tangents", "uvs"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.object_names == b.object_names
    (la,), (lb,) = loaded.lights, made.lights
    assert (la.file, la.rotation, la.scale) == (lb.file, lb.rotation, lb.scale)
    np.testing.assert_array_equal(la.base_radiance(), lb.base_radiance())


def test_a_plain_mesh_gets_the_default_material_and_toml_scenes_refuse_env(tmp_path, capsys):
    p = tmp_path / "box.ply"
    trimesh.creation.box().export(p)
    scene, text = asset_scene(p)
    assert "[materials.asset]" in text and scene.materials["asset"].model == "ggx"
    toml = tmp_path / "s.toml"
    toml.write_text(text)
    assert main(["render", str(toml), "--env", "x.hdr", "-o", str(tmp_path / "o.png")]) == 2
    assert "--env" in capsys.readouterr().err
    assert main(["render", str(p)]) == 2
    assert "-o/--output" in capsys.readouterr().err


def test_the_asset_file_is_read_once_and_again_when_it_changes(glb, monkeypatch):
    """The scene of an asset reads its bounds and then its objects from one read of the file
    (``load_gltf(keep=True)``); a file changed since is read again, and its new bounds are the
    ones the scene frames."""
    import os

    from warp_sg.scene.importers import gltf

    path, (lo, hi) = glb
    reads = []
    real = gltf._read_gltf
    monkeypatch.setattr(gltf, "_read_gltf", lambda p, images: reads.append(p) or real(p, images))
    scene, _ = asset_scene(path, width=64, height=48)
    g = scene.geometry()
    assert len(reads) == 1
    asset = g.vertices[g.vertex_object != g.object_names.index("ground")]
    assert np.allclose(asset.min(0), lo, atol=1e-5) and np.allclose(asset.max(0), hi, atol=1e-5)
    s = trimesh.Scene()
    s.add_geometry(trimesh.creation.box(extents=[4.0, 1.0, 1.0]), node_name="c", geom_name="c")
    path.write_bytes(s.export(file_type="glb"))
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    scene2, _ = asset_scene(path, width=64, height=48)
    scene2.geometry()
    assert len(reads) == 2
    ground = next(o for o in scene2.objects if o.name == "ground")
    assert np.isclose(ground.params["center"][1], -0.5, atol=1e-6)  # under the new box, not the old boxes
