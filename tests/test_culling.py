"""Back-face culling of closed objects seen from outside (``warp_sg.scene.culling``): the raster drops
about half of a closed mesh's (triangle, tile) pairs and the image does not change; open,
inward-wound, entered or near-clipped objects keep their back faces."""
from __future__ import annotations

import numpy as np
import trimesh

import raster
import warp_sg as ws
from warp_sg.scene.camera import Camera
from warp_sg.scene.culling import BackfaceCulling
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


def test_closedness_of_all_objects_at_once_matches_trimesh_per_object():
    """``closed_parts`` (one pass over every object's directed edges) against trimesh's
    ``is_volume``-style checks object by object (watertight and winding-consistent on merged
    vertices): closed spheres and a box, one with a face removed (open), one with a flipped face,
    one with a face twice, and two objects that share vertex positions."""
    from warp_sg.core.meshcheck import closed_parts, weld_ids

    parts = []
    ico = trimesh.creation.icosphere(subdivisions=2)
    box = trimesh.creation.box()
    parts.append((np.asarray(ico.vertices), np.asarray(ico.faces)))                       # closed
    parts.append((np.asarray(box.vertices) + 3.0, np.asarray(box.faces)))                 # closed
    parts.append((np.asarray(ico.vertices) + 6.0, np.asarray(ico.faces)[1:]))             # a hole
    flipped = np.asarray(ico.faces).copy()
    flipped[5] = flipped[5, ::-1]
    parts.append((np.asarray(ico.vertices) - 6.0, flipped))                              # a flipped face
    parts.append((np.asarray(box.vertices) - 3.0, np.r_[np.asarray(box.faces), np.asarray(box.faces)[:1]]))
    parts.append((np.asarray(box.vertices) + 3.0, np.asarray(box.faces)))                 # the 2nd box's positions
    V, T, part, base = [], [], [], 0
    for k, (v, f) in enumerate(parts):
        # split every vertex per face (as exporters do for normals/UVs): closedness must weld them
        V.append(v[f].reshape(-1, 3))
        T.append(base + np.arange(3 * len(f)).reshape(-1, 3))
        part.append(np.full(len(f), k))
        base += 3 * len(f)
    V, T, part = np.concatenate(V), np.concatenate(T), np.concatenate(part)
    got = closed_parts(T, weld_ids(V), part, len(parts))
    want = [bool(trimesh.Trimesh(V, T[part == k], process=True).is_watertight
                 and trimesh.Trimesh(V, T[part == k], process=True).is_winding_consistent) for k in range(len(parts))]
    assert want == [True, True, False, False, False, True]
    assert got.tolist() == want


def test_weld_ids_number_positions_as_numpy_unique_does():
    from warp_sg.core.meshcheck import weld_ids

    rng = np.random.default_rng(3)
    v = rng.integers(-2, 3, (5000, 3)).astype(np.float32) * 0.25
    v[::7] *= -1.0  # −0.0 and 0.0 are one position
    assert np.array_equal(weld_ids(v), np.unique(v + 0.0, axis=0, return_inverse=True)[1].reshape(-1))


def test_part_volumes_are_each_closed_parts_own_volume():
    """Boxes of 1 × 2 × 3 and 2 × 2 × 2 (volumes 6 and 8, closed form), the second turned inside
    out (−8), and a box with a face removed, each about its own box centre, in one call."""
    from warp_sg.core.meshcheck import part_volumes

    parts = [(trimesh.creation.box(extents=(1.0, 2.0, 3.0)), 5.0), (trimesh.creation.box(extents=(2, 2, 2)), -4.0)]
    V, T, part = [], [], []
    for k, (b, shift) in enumerate(parts):
        V.append(np.asarray(b.vertices) + shift)
        T.append(np.asarray(b.faces) + sum(len(v) for v in V[:-1]))
        part.append(np.full(len(b.faces), k))
    T[1] = T[1][:, ::-1]  # inside out
    V, T, part = np.concatenate(V), np.concatenate(T), np.concatenate(part)
    origin = np.stack([V[np.unique(T[part == k])].mean(0) for k in range(2)])
    assert np.allclose(part_volumes(V, T, part, 2, origin), [6.0, -8.0])
    assert np.allclose(part_volumes(V, T, part, 3, origin=np.r_[origin, [[0.0, 0.0, 0.0]]]), [6.0, -8.0, 0.0])
