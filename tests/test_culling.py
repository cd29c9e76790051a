"""Back-face culling of closed objects seen from outside (``warp_sg.scene.culling``): the raster drops
about half of a closed mesh's (triangle, tile) pairs and the image does not change; open,
inward-wound, entered or near-clipped objects keep their back faces."""
from __future__ import annotations

import numpy as np
import trimesh

import raster
import warp_sg as ws
from warp_sg.scene.culling import BackfaceCulling
from warp_sg.scene.camera import Camera
from warp_sg.scene.lights import EnvironmentLight
from warp_sg.scene.model import Scene, SceneObject
from warp_sg.scene.render_settings import RenderSettings


def _scene(flip: bool = False, camera: Camera | None = None):
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.4)
    F = np.asarray(sphere.faces)[:, ::-1] if flip else np.asarray(sphere.faces)
    cam = camera or Camera(origin=(0.0, 0.9, 3.0), target=(0.0, 0.3, 0.0), fov=40.0, width=48, height=40)
    return Scene(camera=cam,
                 objects=[SceneObject(material="ring", primitive="torus", name="ring",
                                      params={"center": (-0.5, 0.45, 0.0), "major_radius": 0.4, "minor_radius": 0.15,
                                              "resolution": (48, 24)}),
                          SceneObject(material="ring", name="ball", vertices=np.asarray(sphere.vertices) + [0.6, 0.4, 0],
                                      triangles=F),
                          SceneObject(material="floor", primitive="plane", name="floor",
                                      params={"size": (4.0, 4.0), "resolution": (4, 4)})],
                 materials={"ring": ws.brdf.Lambert(kd=0.5), "floor": ws.brdf.Lambert(kd=0.7)},
                 lights=[EnvironmentLight(procedural="constant", options={"radiance": [1.0, 1.0, 1.0]})],
                 render=RenderSettings(shadows=False, antialias=1))


def _objects(r):
    names = r.geometry.object_names
    return {n: bool(c) for n, c in zip(names, BackfaceCulling(r.geometry).objects(r.scene.camera))}


def test_closed_objects_seen_from_outside_drop_their_back_faces_and_the_raster_is_unchanged(cache_dir):
    """Against the same raster with nothing culled (itself checked against ray casting in
    test_raster.py): the same visible triangle wherever the pixel centre is not on a silhouette
    edge (where a back face sharing the edge at the same depth could win the tie), the same
    barycentrics, and about half the (triangle, tile) pairs of the closed objects."""
    r = ws.Renderer(_scene())
    assert _objects(r) == {"ring": True, "ball": True, "floor": False}
    culled = r.rasterize(1)
    g = r.geo_arrays
    full = raster.rasterize(g.positions, g.tris, r.scene.camera, validate=False)
    a, b = culled.tri_id.numpy(), full.tri_id.numpy()
    assert (a >= 0).mean() > 0.5
    assert (a != b).mean() < 0.01
    same = (a == b) & (a >= 0)
    assert np.abs(culled.bary.numpy()[same] - full.bary.numpy()[same]).max() < 1e-6
    assert culled.stats["pairs"] < 0.75 * full.stats["pairs"]


def test_open_inward_wound_entered_and_near_clipped_objects_keep_their_back_faces(cache_dir):
    """An inward-wound closed ball is not a volume (culling it would drop every face the camera
    sees: it must still be drawn); a camera inside the ball, or a near plane that cuts it, sees
    its inside. (The scene turns an inside-out ball outwards with a warning, warp_sg.scene.geometry.
    orient_outward: the culling's own rule is checked on the ball wound back inwards.)"""
    from dataclasses import replace

    import pytest

    from warp_sg.core.errors import InputWarning

    with pytest.warns(InputWarning, match="inside out"):
        r = ws.Renderer(_scene(flip=True))
    assert _objects(r) == {"ring": True, "ball": True, "floor": False}  # outwards now: a volume
    img = r.render()
    ball = np.asarray(r.geometry.tri_object)[np.maximum(r.rasterize(1).tri_id.numpy(), 0)] == 1
    assert ball.sum() > 50 and np.isfinite(img).all()
    g = r.geometry
    inward = np.where((np.asarray(g.tri_object) == 1)[:, None], np.asarray(g.triangles)[:, ::-1], g.triangles)
    assert not BackfaceCulling(replace(g, triangles=inward)).objects(r.scene.camera)[1]
    inside = Camera(origin=(0.6, 0.4, 0.1), target=(0.6, 0.4, -1.0), fov=60.0, width=16, height=16)
    assert _objects(ws.Renderer(_scene(camera=inside)))["ball"] is False
    clipped = Camera(origin=(0.6, 0.4, 0.55), target=(0.6, 0.4, -1.0), fov=60.0, width=16, height=16, near=0.3)
    assert _objects(ws.Renderer(_scene(camera=clipped)))["ball"] is False
    away = Camera(origin=(0.6, 0.4, 0.75), target=(0.6, 0.4, -1.0), fov=60.0, width=16, height=16, near=0.3)
    assert _objects(ws.Renderer(_scene(camera=away)))["ball"] is True
