"""pyvista preview: the headless screenshot is the renderer's frame (objects in their rendered colours)."""
from __future__ import annotations

import os

import numpy as np
from PIL import Image

from warp_sg.tools.cli import main

SCENE = """
[camera]
origin = [0.0, 0.0, 3.0]
target = [0.0, 0.0, 0.0]
fov = 35.0
width = 64
height = 64

[[objects]]
primitive = "sphere"
center = [-0.45, 0.0, 0.0]
radius = 0.4
resolution = [12, 24]
material = "red"

[[objects]]
primitive = "sphere"
center = [0.45, 0.0, 0.0]
radius = 0.4
resolution = [12, 24]
material = "green"

[materials.red]
model = "lambert"
kd = [0.8, 0.05, 0.05]

[materials.green]
model = "blinn_phong"
kd = [0.05, 0.6, 0.05]
ks = [0.02, 0.02, 0.02]
n = 10.0

[[lights]]
type = "directional"
direction = [0.0, 0.2, 1.0]
radius = 0.05
intensity = [3.0, 3.0, 3.0]

[[lights]]
type = "point"
position = [0.0, 1.5, 1.0]
radius = 0.1
intensity = [0.5, 0.5, 0.5]

[render]
shadows = false
"""


def test_preview_screenshot_shows_the_objects_in_their_rendered_colours(tmp_path, capsys):
    p = tmp_path / "scene.toml"
    p.write_text(SCENE)
    shot = tmp_path / "shot.png"
    rc = main(["preview", str(p), "--screenshot", str(shot)])
    assert rc == 0, capsys.readouterr().err
    img = np.asarray(Image.open(shot).convert("RGB")).astype(float)
    assert img.shape == (64, 64, 3)
    left = img[28:36, 12:20].mean((0, 1))  # the red sphere's centre
    right = img[28:36, 44:52].mean((0, 1))  # the green one's
    assert left[0] > 100 and left[0] > 3 * left[1] and left[0] > 3 * left[2]
    assert right[1] > 80 and right[1] > 2 * right[0]
    corner = img[:4, :4].mean((0, 1))
    assert corner.max() < 10  # no environment: black background
    # the window shows the renderer's image per pixel (the same frame `warp-sg render` makes)
    import warp_sg as ws
    from warp_sg.core.image_io import tonemap_srgb

    frame = (tonemap_srgb(ws.render(ws.load_scene(p))) * 255 + 0.5).astype(float)
    assert np.abs(img - frame).max() <= 1
    assert not [f for f in tmp_path.iterdir() if f.name.startswith(".shot")]  # no temporary left behind
    umask = os.umask(0)
    os.umask(umask)
    assert shot.stat().st_mode & 0o777 == 0o666 & ~umask  # atomic_output: umask permissions, not mkstemp's 0600


def test_vertex_colours_are_the_renderers_shading_at_the_vertices():
    import warp_sg as ws
    from warp_sg.renderer.renderer import Renderer

    sc = ws.scene.Scene(camera=ws.scene.Camera(origin=(0, 0, 3), target=(0, 0, 0), width=8, height=8),
                        objects=[ws.scene.SceneObject(material="m", primitive="sphere", params={"resolution": (6, 12)})],
                        materials={"m": ws.brdf.Lambert(kd=0.5)},
                        lights=[ws.scene.DirectionalLight(direction=(0, 0, 1), radius=0.01, intensity=1.0)],
                        render=ws.scene.RenderSettings(shadows=False))
    r = Renderer(sc)
    rad = r.shade_vertices()
    n = r.geometry.normals
    # Lambert under a distant light, shaded with the exact cosine: (kd/π) E max(n·l, 0)
    cos = n[:, 2]
    facing = cos > 0.3
    expect = 0.5 / np.pi * cos
    np.testing.assert_allclose(rad[facing, 0], expect[facing], rtol=0.01)
    assert np.all(rad[cos < -0.3] < 1e-4)


def test_preview_of_an_asset_is_the_frame_render_makes_of_it(tmp_path, capsys):
    # `warp-sg preview ASSET --env MAP --view AZ EL` shows the scene `warp-sg render ASSET` makes
    # (the same asset path: framing camera, ground, environment), here an emissive glTF ball
    from gltf_files import GltfWriter, uv_sphere

    from warp_sg.core.image_io import save_image

    w = GltfWriter()
    P, idx, N, uv = uv_sphere(0.5, (0.0, 0.5, 0.0), 12, 24)
    m = w.material({"name": "ball", "emissiveFactor": [0.3, 0.1, 0.0],
                    "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.5, 0.8, 1.0], "metallicFactor": 0.0}})
    w.mesh(P, idx, N, uv, material=m, name="ball")
    asset = w.glb(tmp_path / "ball.glb")
    sky = np.ones((16, 32, 3), np.float32) * np.linspace(0.2, 1.0, 16)[:, None, None]
    env = save_image(tmp_path / "sky.hdr", sky)
    shot, out = tmp_path / "shot.png", tmp_path / "render.png"
    args = [str(asset), "--env", str(env), "--view", "40", "25"]
    assert main(["preview", *args, "--screenshot", str(shot), "--window-size", "48", "36"]) == 0, capsys.readouterr().err
    assert main(["render", *args, "-o", str(out), "--width", "48", "--height", "36", "--no-progress"]) == 0
    a = np.asarray(Image.open(shot).convert("RGB")).astype(float)
    b = np.asarray(Image.open(out).convert("RGB")).astype(float)
    assert a.shape == (36, 48, 3) and np.abs(a - b).max() <= 1
    centre = a[14:22, 20:28].mean((0, 1))
    assert centre[0] > centre[1] > 0  # the ball's emission is red: it shows in the middle of the frame
