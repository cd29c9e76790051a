"""The per-vertex caches of objects that move (:mod:`warp_sg.shading.sky_table`): the visible
fraction of a moving vertex's diffuse environment irradiance from its transfer vectors (its cone
texels' weights projected onto spherical harmonics once) and the sky turned into the object's
frame, against the map-read quadrature of every texel
(:func:`warp_sg.shading.vertex_visibility.env_vertex_visible`) at the same pose; the per-vertex
bound on the truncation against the texel lists; the texel lists kept where the sky is sharp;
the harmonics against a Gauss–Legendre quadrature and their closed forms; nothing stale when a
self-shadowed object moves away and back; and the grouped SSDFs read back from the cache."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import warp_sg as ws
from warp_sg.numeric.rigid_motion import motion_about, rotation_about
from warp_sg.scene.plain_scenes import write_plain_scene


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


POSES = (([0, 1, 0], 0.0), ([0, 1, 0], 70.0), ([1, 0.3, 0], 135.0), ([0.2, 1, 0.7], 250.0))


# (measured at ORDER 8: torus max 1.3e-2, mean 1.6e-3; blob 1.0e-3, 3.7e-5 — docs/benchmarks.md)
@pytest.mark.parametrize("make, pivot, name, worst, mean", [(_torus_scene, (0.0, 0.5, 0.0), "ring", 2e-2, 2.5e-3),
                                                            (_blob_scene, (0.0, 0.5, 0.0), "object", 2e-3, 1e-4)])
def test_the_turned_sky_gives_the_map_quadratures_visible_fraction(tmp_path, make, pivot, name, worst, mean):
    r = ws.Renderer(make(tmp_path))
    deepest = 1.0
    for axis, deg in POSES:
        r.set_object_transform(name, motion_about(rotation_about(axis, deg), pivot))
        r.render()
        assert r.dynamic._sky.exact_count == 0  # (the smooth residual sky)
        ids = r.dynamic.all_ids.numpy()
        got = tuple(a.numpy()[ids] for a in r.env_visible_cache.value)
        want = _reference_rows(r)
        shadowed = want[0].min(1) < 1.0
        assert shadowed.sum() > 20
        err = np.abs(got[0] - want[0])
        assert err.max() < worst and err.mean() < mean, (axis, deg, err.max(), err.mean())
        E = np.maximum(want[1] / np.maximum(want[0], 1e-6), 1e-6)
        assert (np.abs(got[1] - want[1]) / E).max() < worst
        deepest = min(deepest, float(want[0].min()))
    if make is _torus_scene:
        assert deepest < 0.7  # (a deep self-shadow was checked)


def test_the_truncation_stays_within_each_vertexs_bound(tmp_path):
    """Each vertex's visible fraction from its transfer vectors errs against the map quadrature by
    less than its bound ``(‖ρ^O − ρ^O_n‖ + ‖ρ^S − ρ^S_n‖)·‖L' − L'_n‖ / E_min`` (the truncation,
    against the exact sums over the turned cube) plus the cube's own resampling error (those exact
    sums against the map: within 2.0e-3 on this torus, docs/benchmarks.md) — and by more than
    nothing."""
    r = ws.Renderer(_torus_scene(tmp_path))
    for axis, deg in POSES:
        r.set_object_transform("ring", motion_about(rotation_about(axis, deg), (0.0, 0.5, 0.0)))
        r.render()
        ids = r.dynamic.all_ids.numpy()
        err = np.abs(r.env_visible_cache.value[0].numpy()[ids] - _reference_rows(r)[0]).max(1)
        bound = r.dynamic._sky.bound
        assert err.max() > 1e-3 and bound.max() < 0.25
        assert np.all(err <= bound + 2e-3), (err - bound).max()


def test_a_sharp_sky_is_left_to_the_map_quadrature(tmp_path):
    """The sun left in the map (``env_peaks = 0``): its energy outside the harmonics makes every
    shadowed vertex's bound large, so those vertices are integrated against the map itself — the
    reference quadrature, bit for bit."""
    sc = _torus_scene(tmp_path)
    sc.render.env_peaks = 0
    r = ws.Renderer(sc)
    r.set_object_transform("ring", motion_about(rotation_about([1, 0.3, 0], 135.0), (0.0, 0.5, 0.0)))
    r.render()
    sky = r.dynamic._sky
    ids = r.dynamic.all_ids.numpy()
    want = _reference_rows(r)
    shadowed = want[0].min(1) < 1.0
    assert sky.sky_residual.max() > 10.0  # (the smooth residual sky's: 0.2)
    assert sky.bound[shadowed].min() > 1.0 and sky.exact_count >= shadowed.sum()
    assert np.array_equal(r.env_visible_cache.value[0].numpy()[ids], want[0])


def test_the_harmonics_are_orthonormal_and_match_their_closed_forms():
    """:func:`sh_values` against a Gauss–Legendre × uniform-φ quadrature (exact for these
    polynomials): Gram matrix the identity; orders 0–2 against their closed forms."""
    from warp_sg.shading.sky_table import sh_values

    x, w = np.polynomial.legendre.leggauss(24)
    phi = (np.arange(48) + 0.5) * 2.0 * np.pi / 48
    z, p = np.meshgrid(x, phi, indexing="ij")
    s = np.sqrt(1.0 - z * z)
    d = np.stack([s * np.cos(p), s * np.sin(p), z], -1).reshape(-1, 3)
    wt = np.repeat(w, 48) * 2.0 * np.pi / 48
    Y = sh_values(d, 10)
    assert Y.shape == (len(d), 121)
    assert np.abs((Y * wt[:, None]).T @ Y - np.eye(121)).max() < 2e-5
    X, Yy, Z = d.T
    c0, c1, c2 = 0.5 / np.sqrt(np.pi), np.sqrt(3 / (4 * np.pi)), np.sqrt(15 / (4 * np.pi))
    closed = np.stack([np.full(len(d), c0), c1 * Yy, c1 * Z, c1 * X, c2 * X * Yy, c2 * Yy * Z,
                       np.sqrt(5 / (16 * np.pi)) * (3 * Z * Z - 1), c2 * X * Z, 0.5 * c2 * (X * X - Yy * Yy)], 1)
    assert np.abs(Y[:, :9] - closed).max() < 1e-5


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
