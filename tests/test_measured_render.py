"""A scene with a ``model = "measured"`` material renders, and agrees with the Monte-Carlo
reference (which uses the exact MERL lookup) up to the SG approximation and MC noise."""
from __future__ import annotations

import numpy as np

import warp_sg as ws
from warp_sg.brdf import CookTorrance, merl

SCENE = """
[camera]
origin = [0.0, 0.0, 3.0]
target = [0.0, 0.0, 0.0]
up     = [0.0, 1.0, 0.0]
fov    = 30.0
width  = 32
height = 32

[[objects]]
primitive = "sphere"
center = [0.0, 0.0, 0.0]
radius = 0.6
material = "meas"

[materials.meas]
model = "measured"
file  = "ct.binary"
lobes = 2

[[lights]]
type = "directional"
direction = [0.5, 0.6, 0.62]
radius = 0.1
intensity = [3.0, 3.0, 3.0]

[render]
shadows = false
"""


def test_measured_material_renders_close_to_the_reference(tmp_path):
    ct = CookTorrance(kd=(0.3, 0.15, 0.05), ks=(15.0, 15.0, 15.0), m=0.2, fresnel={"eta": 1.33})
    merl.write_merl(tmp_path / "ct.binary", merl.tabulate(ct))
    (tmp_path / "scene.toml").write_text(SCENE)
    scene = ws.load_scene(tmp_path / "scene.toml")
    assert scene.materials["meas"].brdf.NAME == "measured"
    img = ws.render(scene, device="cpu")
    ref = ws.reference(scene, spp=32, device="cpu", progress=False)
    assert img.shape == (32, 32, 3) and np.all(np.isfinite(img))
    lit = ref.sum(-1) > 0
    assert lit.mean() > 0.3
    rel = np.sqrt(np.sum((img - ref) ** 2) / np.sum(ref**2))
    assert rel < 0.2
    assert 0.9 < img[lit].mean() / ref[lit].mean() < 1.1
    # the highlight peaks at about the same value (SG fit of the NDF, 2 lobes)
    peak_img, peak_ref = img.sum(-1).max(), ref.sum(-1).max()
    assert abs(peak_img - peak_ref) < 0.25 * peak_ref
