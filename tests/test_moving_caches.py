"""The per-vertex caches of objects that move (:mod:`warp_sg.shading.sky_table`): the visible
fraction of a moving vertex's diffuse environment irradiance from its cone texels listed once and
the sky turned into the object's frame, against the map-read quadrature of every texel
(:func:`warp_sg.shading.vertex_visibility.env_vertex_visible`) at the same pose; nothing stale
when a self-shadowed object moves away and back; and the grouped SSDFs read back from the cache."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import warp_sg as ws
from warp_sg.scene.plain_scenes import write_plain_scene
from warp_sg.numeric.rigid_motion import motion_about, motion_matrix, rotation_about


def _torus_scene(tmp_path):
    """A torus (its inner side shadows itself deeply) on a floor under the sky EXR."""
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import EnvironmentLight
    from warp_sg.scene.model import Material, RenderSettings, Scene, SceneObject
    from warp_sg.scene.plain_scenes import write_sky_exr

    tmp_path.mkdir(parents=True, exist_ok=True)
    sky = write_sky_exr(tmp_path / "sky.exr")
    ring = SceneObject(material="m", primitive="torus", name="ring", dynamic=True,
                       params={"center": (0, 0.5, 0), "major_radius": 0.45, "minor_radius": 0.2,
                               "resolution": (40, 20)})
    floor = SceneObject(material="m", primitive="plane", name="floor", params={"size": (6.0, 6.0), "resolution": (2, 2)})
    return Scene(camera=Camera(origin=(0, 2, 3.5), target=(0, 0.4, 0), up=(0, 1, 0), fov=40, width=24, height=24),
                 objects=[ring, floor], materials={"m": Material("lambert", {"kd": [0.6, 0.6, 0.6]})},
                 lights=[EnvironmentLight(file=str(sky))],
                 render=RenderSettings(ssdf_resolution=16, pca_terms=16, visibility_budget=0, antialias=1))


def _blob_scene(tmp_path):
    rs = {"ssdf_resolution": 16, "pca_terms": 16, "visibility_budget": 3000, "antialias": 1}
    return ws.load_scene(write_plain_scene(tmp_path, obj="blob", size=24, render=rs, dynamic=True))


def _reference_rows(r):
    """The moving vertices' ``(F, E ∘ F)`` by the map-read quadrature of every texel, at the
    renderer's current pose."""
    from warp_sg.shading.vertex_visibility import env_vertex_visible

    ids = r.dynamic.all_ids
    nv = len(r.geometry.vertices)
    out = env_vertex_visible(r.vis, r._env_arrays(), nv, r.device, ids=ids,
                             into=tuple(wp.clone(a) for a in r.env_visible_cache.value))
    return tuple(a.numpy()[ids.numpy()] for a in out)


@pytest.mark.parametrize("make, pivot, name", [(_torus_scene, (0.0, 0.5, 0.0), "ring"),
                                               (_blob_scene, (0.0, 0.5, 0.0), "object")])
def test_the_turned_sky_gives_the_map_quadratures_visible_fraction(tmp_path, make, pivot, name):
    r = ws.Renderer(make(tmp_path))
    deepest = 1.0
    for axis, deg in (([0, 1, 0], 0.0), ([0, 1, 0], 70.0), ([1, 0.3, 0], 135.0), ([0.2, 1, 0.7], 250.0)):
        r.set_object_transform(name, motion_about(rotation_about(axis, deg), pivot))
        r.render()
        ids = r.dynamic.all_ids.numpy()
        got = tuple(a.numpy()[ids] for a in r.env_visible_cache.value)
        want = _reference_rows(r)
        shadowed = want[0].min(1) < 1.0
        assert shadowed.sum() > 20
        err = np.abs(got[0] - want[0])
        assert err.max() < 3e-3 and err.mean() < 4e-4, (axis, deg, err.max(), err.mean())
        E = np.maximum(want[1] / np.maximum(want[0], 1e-6), 1e-6)
        assert (np.abs(got[1] - want[1]) / E).max() < 3e-3
        deepest = min(deepest, float(want[0].min()))
    if make is _torus_scene:
        assert deepest < 0.7  # (a deep self-shadow was checked)


def test_a_self_shadowed_object_moved_away_and_back_is_bit_identical(tmp_path):
    r = ws.Renderer(_torus_scene(tmp_path))
    first = r.render().copy()
    r.set_object_transform("ring", motion_about(rotation_about([1, 0, 0], 60.0), [0.0, 0.5, 0.0]))
    moved = r.render().copy()
    r.set_environment_rotation(30.0)
    r.render()
    r.set_environment_rotation(0.0)
    r.set_object_transform("ring", np.eye(4))
    assert not np.array_equal(moved, first)
    assert np.array_equal(r.render(), first)


def test_a_second_renderer_reads_the_grouped_ssdfs_from_the_cache(tmp_path, cache_dir):
    """The per-group SSDFs of a scene with a dynamic object are a cache entry (kind
    ``ssdf_groups``): a second renderer of the scene casts no ray; the maps are the same."""
    from warp_sg.core.cache import entry_path, record_builds

    with record_builds() as first:
        a = ws.Renderer(_blob_scene(tmp_path / "a"))
    with record_builds() as second:
        b = ws.Renderer(_blob_scene(tmp_path / "b"))
    built = lambda ledger: [k for k, _, fresh in ledger.events if fresh]  # noqa: E731
    assert "ssdf_groups" in built(first)
    assert "ssdf_groups" not in built(second)
    assert ("ssdf_groups", a.ssdf.key, False) in second.events
    assert "ssdf" not in built(second)
    assert np.array_equal(a.ssdf.weights, b.ssdf.weights) and np.array_equal(a.ssdf.cones, b.ssdf.cones)
    assert entry_path("ssdf_groups", a.ssdf.key).is_file() and str(cache_dir) in str(entry_path("ssdf_groups", "k"))


def test_texel_lists_over_their_budget_leave_the_map_quadrature(tmp_path, monkeypatch):
    """``WARP_SG_SKY_TABLE_MB`` too small for the lists: the moving vertices are integrated against
    the map itself (the reference quadrature, exactly); a budget that is not a number is refused."""
    from warp_sg.core.errors import InputError

    monkeypatch.setenv("WARP_SG_SKY_TABLE_MB", "0.001")
    r = ws.Renderer(_torus_scene(tmp_path))
    r.set_object_transform("ring", motion_about(rotation_about([1, 0, 0], 60.0), [0.0, 0.5, 0.0]))
    r.render()
    assert not r.dynamic._sky.fits
    ids = r.dynamic.all_ids.numpy()
    assert np.array_equal(r.env_visible_cache.value[0].numpy()[ids], _reference_rows(r)[0])
    monkeypatch.setenv("WARP_SG_SKY_TABLE_MB", "lots")
    r2 = ws.Renderer(_torus_scene(tmp_path / "again"))
    r2.set_object_transform("ring", np.eye(4))
    with pytest.raises(InputError, match="WARP_SG_SKY_TABLE_MB"):
        r2.render()
