"""Edge- and contrast-adaptive antialiasing (``warp_sg.antialias``) against brute force: shading
every one of the a×a sub-pixels (``supersampling = a``) and box-filtering."""
from __future__ import annotations

import numpy as np

import warp_sg as ws
from warp_sg.lights import DirectionalLight, EnvironmentLight
from warp_sg.scene import Camera, RenderSettings, Scene, SceneObject


def _scene(**render):
    cam = Camera(origin=(0.0, 0.9, 3.0), target=(0.0, 0.3, 0.0), fov=40.0, width=40, height=32)
    return Scene(camera=cam,
                 objects=[SceneObject(material="ring", primitive="torus", name="ring",
                                      params={"center": (0.0, 0.45, 0.0), "major_radius": 0.5, "minor_radius": 0.18,
                                              "resolution": (48, 24)}),
                          SceneObject(material="floor", primitive="plane", name="floor",
                                      params={"size": (4.0, 4.0), "resolution": (8, 8)})],
                 materials={"ring": ws.brdf.BlinnPhong(kd=0.3, ks=0.5, n=80.0), "floor": ws.brdf.Lambert(kd=0.7)},
                 lights=[DirectionalLight(direction=(0.4, 0.8, 0.5), radius=0.03, intensity=2.5),
                         EnvironmentLight(procedural="constant", options={"radiance": [0.2, 0.25, 0.3]})],
                 render=RenderSettings(shadows=False, **render))


def test_adaptive_antialiasing_matches_shading_every_subpixel(cache_dir):
    r = ws.Renderer(_scene(antialias=4))
    adaptive = r.render()
    t = dict(r.timings)
    full = ws.render(_scene(supersampling=4))
    point = ws.render(_scene(antialias=1))
    err = np.abs(adaptive - full).sum(-1)
    err_point = np.abs(point - full).sum(-1)
    # where it matters (edges) adaptive ≈ full supersampling; point sampling is far off there
    assert err.mean() < 0.15 * err_point.mean(), (err.mean(), err_point.mean())
    assert np.quantile(err, 0.99) < 0.05 * full.sum(-1).max()
    # and it shades far fewer samples than full supersampling (16 per pixel)
    assert t["shaded_samples"] < 0.5 * 16 * 40 * 32
    assert t["edge_pixels"] > 0


def test_a_flat_floor_at_grazing_view_is_not_an_edge_except_at_its_border(cache_dir):
    cam = Camera(origin=(0.0, 0.15, 3.0), target=(0.0, 0.0, -2.0), fov=40.0, width=48, height=32)
    sc = Scene(camera=cam, objects=[SceneObject(material="floor", primitive="plane",
                                                params={"size": (20.0, 20.0), "resolution": (2, 2)})],
               materials={"floor": ws.brdf.Lambert(kd=0.7)},
               lights=[EnvironmentLight(procedural="constant", options={"radiance": [1.0, 1.0, 1.0]})],
               render=RenderSettings(shadows=False, antialias=4))
    r = ws.Renderer(sc)
    img = r.render()
    # the floor's far edge meets the background along one row or two: only those pixels are edges
    # (1/depth is affine across a flat triangle, so the grazing floor itself is no edge)
    assert r.timings["edge_pixels"] <= 3 * cam.width
    assert np.all(np.isfinite(img))
