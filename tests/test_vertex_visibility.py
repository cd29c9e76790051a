"""The per-vertex visibility caches (``warp_sg.shading.vertex_visibility``): each environment lobe's
visible fraction (the lobe path, Oren–Nayar) and the diffuse term's visible fraction (Lambert)
against ray-cast quadratures, each light's SSDF deficit against a ray cast to the light, the cached
frame against the per-pixel path and the Monte-Carlo reference, and which edits rebuild the
caches."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from precompute.visibility.rays import hemisphere_visibility
from precompute.visibility.ssdf_wp import texel_directions
from warp_sg.numeric.onb import frame_from_normal
from warp_sg.renderer.renderer import Renderer
from warp_sg.scene.camera import Camera
from warp_sg.scene.lights import EnvironmentLight, PointLight
from warp_sg.scene.model import Material, Scene, SceneObject
from warp_sg.scene.render_settings import RenderSettings


def _scene(mode="vertex", rotation=0.0, width=48, height=40, light=None, model="lambert"):
    cam = Camera(origin=(0.0, 1.6, 2.6), target=(0.0, 0.25, 0.0), fov=45.0, width=width, height=height)
    objects = [SceneObject(material="ball", primitive="sphere", params={"radius": 0.4, "resolution": (16, 32),
                                                                         "center": (0.0, 0.42, 0.0)}),
               SceneObject(material="floor", primitive="plane", params={"size": (3.0, 3.0), "resolution": (24, 24)})]
    extra = {"sigma": 1e-3} if model == "oren_nayar" else {}  # Oren–Nayar: the lobe path
    mats = {"ball": Material(model, {"kd": [0.6, 0.5, 0.4], **extra}),
            "floor": Material(model, {"kd": [0.5, 0.5, 0.5], **extra})}
    env = EnvironmentLight(procedural="sky", rotation=rotation, options={"width": 64, "height": 32})
    rs = RenderSettings(shadows=True, ssdf_resolution=16, pca_terms=16, visibility_budget=0, env_lobes=4,
                        env_peaks=0, antialias=1, visibility_sampling=mode)
    lights = [env] + ([] if light is None else [PointLight(position=light, radius=0.05, intensity=(3.0, 3.0, 3.0))])
    return Scene(camera=cam, objects=objects, materials=mats, lights=lights, render=rs)


def _segment_blocked(origins, targets, V, F):
    """Whether each segment origin → target crosses a triangle (Möller–Trumbore, brute force)."""
    d = targets - origins
    v0 = V[F[:, 0]]
    e1, e2 = V[F[:, 1]] - v0, V[F[:, 2]] - v0
    p = np.cross(d[:, None], e2[None])
    det = np.einsum("nmk,mk->nm", p, e1)
    ok = np.abs(det) > 1e-12
    inv = 1.0 / np.where(ok, det, 1.0)
    s = origins[:, None] - v0[None]
    u = np.einsum("nmk,nmk->nm", s, p) * inv
    q = np.cross(s, e1[None])
    v = np.einsum("nk,nmk->nm", d, q) * inv
    t = np.einsum("nmk,mk->nm", q, e2) * inv
    return (ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-3) & (t < 1 - 1e-3)).any(1)


@pytest.fixture(scope="module")
def renderer():
    r = Renderer(_scene(), device="cpu")
    r.render()
    return r


def _hemisphere(g, ids, R=48):
    """Ray-cast visibility (n, R²) of vertices ``ids`` on an R×R equal-area map, its world directions
    (n, R², 3) and the vertices' unit normals."""
    vis = hemisphere_visibility(g.vertices, g.triangles, g.normals, resolution=R, vertex_ids=ids).reshape(len(ids), -1)
    d_local = texel_directions(R).reshape(-1, 3)
    n = g.normals[ids] / np.linalg.norm(g.normals[ids], axis=1, keepdims=True)
    t, b = frame_from_normal(n)
    d_world = d_local[None, :, 0, None] * t[:, None] + d_local[None, :, 1, None] * b[:, None] \
        + d_local[None, :, 2, None] * n[:, None]
    return vis, d_world, n, d_local[:, 2]


def _test_ids(g):
    floor = np.flatnonzero((np.abs(g.vertices[:, 1]) < 1e-6) & (np.hypot(g.vertices[:, 0], g.vertices[:, 2]) < 1.0))
    ball = np.flatnonzero(g.vertices[:, 1] > 0.02)[::7]
    return np.concatenate([floor, ball])


def test_each_vertex_lobe_value_is_the_visible_fraction_of_its_cosine_weighted_lobe_by_ray_cast():
    """V[v, j] (the lobe path, read by Oren–Nayar materials) against ∫ G_j cos V dω / ∫ G_j cos dω,
    V ray-cast on a 48² equal-area map. The cache integrates the vertex's own SSDF map (16², 16 PCA
    terms here), so it follows the ray cast up to that map's resolution — where the hemisphere model
    of eq. 30 it replaced was off by ≈ −0.08 on the floor round the ball for the broad sky lobes."""
    r = Renderer(_scene(model="oren_nayar"), device="cpu")
    r.render()
    assert r.features().env_vis_vertex and not r.features().env_visible_vertex
    g = r.geometry
    es = r._env_arrays()
    vv = r.env_vis_cache.value.numpy()
    axes, lams = es.axis.numpy().astype(np.float64), es.lam.numpy().astype(np.float64)
    ids = _test_ids(g)
    vis, d_world, n, cos = _hemisphere(g, ids)
    errs, truths = [], []
    for j in range(len(lams)):
        G = np.exp(lams[j] * (d_world @ axes[j] - 1.0)) * cos[None, :]
        truth = (G * vis).sum(1) / G.sum(1)
        up = n @ axes[j] > -0.5  # lobes that reach the hemisphere
        truths.append(truth[up])
        errs.append(vv[ids, j][up] - truth[up])
    err, truth = np.abs(np.concatenate(errs)), np.concatenate(truths)
    shadowed = truth < 0.8
    assert shadowed.sum() > 100, "the test scene must have shadowed vertices"
    assert err.mean() < 0.02, err.mean()
    # where the truth is shadowed, the cache is 8× closer to it than an occluder-blind value of 1
    assert err[shadowed].mean() < 0.125 * (1.0 - truth[shadowed]).mean()


def test_each_vertex_visible_fraction_of_the_diffuse_irradiance_matches_a_ray_cast(renderer):
    """F[v] (Lambert: the diffuse term's visible fraction, weighted by the map) against
    ∫ L cos V dω / ∫ L cos dω with ray-cast V, per colour channel."""
    from warp_sg.scene.envmap import env_lookup_numpy

    r = renderer
    assert r.features().env_visible_vertex
    g = r.geometry
    F = r.env_visible_cache.value[0].numpy()
    ids = _test_ids(g)
    vis, d_world, n, cos = _hemisphere(g, ids)
    L = env_lookup_numpy(r.env_residual, d_world.reshape(-1, 3)).reshape(len(ids), -1, 3)  # rotation 0
    truth = np.einsum("nk,nkc->nc", vis * cos[None, :], L) / np.einsum("nk,nkc->nc", np.broadcast_to(cos, vis.shape), L)
    err = np.abs(F[ids] - truth)
    shadowed = truth[:, 1] < 0.8
    assert shadowed.sum() > 50
    assert err.mean() < 0.015, err.mean()
    assert err[shadowed].mean() < 0.1 * (1.0 - truth[shadowed]).mean()


def test_cached_frame_matches_the_per_pixel_frame_and_the_reference(renderer):
    from warp_sg.groundtruth.reference import reference

    img_v = renderer.render()
    img_p = Renderer(_scene(mode="pixel"), device="cpu").render()
    ref = reference(_scene(), spp=512, seed=1, device="cpu")
    hit = renderer.rasterize(1).tri_id.numpy() >= 0
    mean = img_v[hit].mean()
    assert np.abs(img_v - img_p)[hit].mean() < 0.03 * mean
    # the per-vertex quadrature is closer to the Monte-Carlo reference than the per-pixel
    # hemisphere model (object + floor pixels)
    e_v = np.abs(img_v - ref)[hit].mean() / ref[hit].mean()
    e_p = np.abs(img_p - ref)[hit].mean() / ref[hit].mean()
    assert e_v < 0.03 and e_v < e_p, (e_v, e_p)


def test_camera_material_and_scale_edits_reuse_the_cache_and_rotation_rebuilds_it(renderer):
    r = renderer
    cached, builds = r.env_visible_cache.value, r.env_visible_cache.builds
    r.set_camera(origin=(0.3, 1.5, 2.7))
    r.set_material("ball", kd=[0.2, 0.6, 0.3])
    r.set_environment_scale(1.5)
    r.render()
    assert r.env_visible_cache.value is cached and r.env_visible_cache.builds == builds
    r.set_environment_scale(1.0)
    r.set_material("ball", kd=[0.6, 0.5, 0.4])
    r.set_camera(origin=(0.0, 1.6, 2.6))
    r.set_environment_rotation(40.0)
    img = r.render()
    assert r.env_visible_cache.value is not cached and r.env_visible_cache.builds == builds + 1
    fresh = Renderer(_scene(rotation=40.0), device="cpu").render()
    np.testing.assert_allclose(img, fresh, rtol=1e-5, atol=1e-6)
    r.set_environment_rotation(0.0)
    r.render()


def test_pixel_mode_and_unshadowed_scenes_build_no_cache():
    r = Renderer(_scene(mode="pixel", width=16, height=12), device="cpu")
    r.render()
    assert r.env_vis_cache.builds == 0 and not r.features().env_vis_vertex
    assert r.env_visible_cache.builds == 0 and not r.features().env_visible_vertex


LIGHT = (0.9, 1.3, 0.4)


@pytest.mark.parametrize("budget", [0, 400])
def test_each_vertex_ssdf_towards_the_light_is_negative_exactly_where_the_ray_to_it_is_blocked(budget):
    """Vertex v's SSDF towards a small point light, θd = θh + cached deficit (θh = asin(n·l)),
    against a ray cast from v to the light: floor vertices whose ray is blocked, and whose
    neighbours' rays agree (away from the shadow edge), have θd < 0 (inside the occluded set);
    unblocked ones θd > 0 — up to the SSDF's own error. With 400 representatives (392 of 1186
    vertices) the same holds, and a vertex's deficit is read from its own, transferred map (mean
    difference 0.004 rad; the representatives' deficits blended: 0.027)."""
    sc = _scene(light=LIGHT)
    sc.render = dataclasses.replace(sc.render, visibility_budget=budget)
    r = Renderer(sc, device="cpu")
    assert (len(np.unique(r.ssdf.representative)) <= budget) if budget else len(r.ssdf.representative) == 0
    r.render()
    g = r.geometry
    from warp_sg.shading.vertex_visibility import light_vertex_deficit

    # the SSDF's deficits (the path of moving vertices; a static scene's cache holds ray-cast ones,
    # tests/test_light_rays.py)
    dd = light_vertex_deficit(r.vis, r.geo_arrays.positions, r.light_arrays, len(g.vertices), False, "cpu").numpy()[:, 0]
    floor = np.flatnonzero(np.abs(g.vertices[:, 1]) < 1e-6)
    V, F = g.vertices.astype(np.float64), g.triangles
    light = np.asarray(LIGHT, np.float64)
    blocked = _segment_blocked(V[floor], np.broadcast_to(light, (len(floor), 3)), V, F)
    # the same test from points 0.15 away (≈ 0.1 rad seen from the light, half a texel of the
    # 16² SSDF): a vertex counts only where all of them agree
    robust = np.ones(len(floor), bool)
    for off in ((0.15, 0, 0), (-0.15, 0, 0), (0, 0, 0.15), (0, 0, -0.15)):
        robust &= _segment_blocked(V[floor] + off, np.broadcast_to(light, (len(floor), 3)), V, F) == blocked
    assert blocked[robust].sum() > 10 and (~blocked[robust]).sum() > 100
    to_light = light - V[floor]
    th_h = np.arcsin(to_light[:, 1] / np.linalg.norm(to_light, axis=1))  # floor normal +y
    theta_d = th_h + dd[floor]
    # within a quarter of the 16² map's texel (0.06 rad) of the right sign: PCA (16 terms) and the
    # map's resolution blur the SSDF by about that much at the umbra's edge
    assert (theta_d[robust & blocked] < 0.06).mean() > 0.97
    assert (theta_d[robust & ~blocked] > -0.06).mean() > 0.97
    if budget:  # the other vertices' deficits: their own maps' min(θd − θh, 0) (blended: 0.027)
        from precompute.visibility.ssdf_wp import lookup_np

        nn = g.normals / np.linalg.norm(g.normals, axis=1, keepdims=True)
        o = np.setdiff1d(np.arange(len(V)), r.ssdf.representative)
        lv = light - V[o]
        lv /= np.linalg.norm(lv, axis=1, keepdims=True)
        t, b = frame_from_normal(nn[o])
        loc = np.stack([np.sum(lv * t, 1), np.sum(lv * b, 1), np.sum(lv * nn[o], 1)], -1)
        maps = r.ssdf.reconstruct(o)
        own = np.array([lookup_np(m, d) for m, d in zip(maps, loc)]) - np.arcsin(np.clip(loc[:, 2], -1, 1))
        up = loc[:, 2] > 0.2  # (below: the below-horizon rule)
        assert up.sum() > 300 and np.abs(dd[o] - np.minimum(own, 0))[up].mean() < 0.01


def test_light_edits_rebuild_the_light_cache_and_camera_edits_do_not():
    r = Renderer(_scene(light=LIGHT, width=24, height=20), device="cpu")
    r.render()
    cached, builds = r.light_vis_cache.value, r.light_vis_cache.builds
    r.set_camera(origin=(0.3, 1.5, 2.7))
    r.set_environment_scale(1.2)
    r.render()
    assert r.light_vis_cache.value is cached and r.light_vis_cache.builds == builds
    r.set_camera(origin=(0.0, 1.6, 2.6))
    r.set_environment_scale(1.0)
    r.update_light(0, position=np.array([-0.7, 1.4, 0.2]))
    img = r.render()
    assert r.light_vis_cache.builds == builds + 1
    fresh = Renderer(_scene(light=(-0.7, 1.4, 0.2), width=24, height=20), device="cpu").render()
    np.testing.assert_allclose(img, fresh, rtol=1e-5, atol=1e-6)


def test_decompressed_ssdf_maps_render_the_same_frame_as_the_pca_form(monkeypatch):
    """``WARP_SG_SSDF_DECOMPRESS_MB``: under the budget the renderer keeps each vertex's map
    decompressed (``SSDFData.device_arrays``), 0 keeps the PCA form. The decompressed form of the
    reconstruction renders the same frame as the PCA form; by default the decompressed form holds
    the uncompressed maps themselves (``SSDFData.maps``, the ray-cast SSDFs before PCA)."""
    from precompute.visibility.ssdf import compute_ssdf
    from warp_sg.core.errors import InputError

    monkeypatch.setenv("WARP_SG_SSDF_DECOMPRESS_MB", "0")
    pca = Renderer(_scene(light=(1.0, 2.0, 1.0)), device="cpu")
    assert pca.vis.basis.shape[2] > 0 and pca.ssdf.maps.size == 0  # (nothing kept beyond the budget)
    monkeypatch.setenv("WARP_SG_SSDF_DECOMPRESS_MB", "64")
    raw = Renderer(_scene(light=(1.0, 2.0, 1.0)), device="cpu")
    R, nv = raw.ssdf.resolution, len(raw.geometry.vertices)
    assert raw.vis.basis.shape[2] == 0 and raw.vis.weights.shape == (nv, R * R)
    raw.render()
    assert raw.ssdf.pca.pending  # a renderer that reads the kept maps never computes their PCA
    # the kept maps are the vertices' own SSDFs, as compute_ssdf casts them
    g = raw.geometry
    own = compute_ssdf(g.vertices, g.triangles, g.normals, resolution=R, ray_resolution=raw.ssdf.ray_resolution,
                       progress=False)
    np.testing.assert_array_equal(raw.vis.weights.numpy(), own.reshape(nv, R * R))
    rec = Renderer(_scene(light=(1.0, 2.0, 1.0)), device="cpu",
                   precomputed={**raw.precomputed(), "ssdf": dataclasses.replace(raw.ssdf, maps=np.zeros((0, 0)))})
    assert rec.vis.basis.shape[2] == 0
    a, b = pca.render(), rec.render()
    assert a.max() > 0.1
    np.testing.assert_allclose(b, a, rtol=1e-4, atol=1e-6 * a.max())
    monkeypatch.setenv("WARP_SG_SSDF_DECOMPRESS_MB", "lots")
    with pytest.raises(InputError, match="WARP_SG_SSDF_DECOMPRESS_MB"):
        Renderer(_scene(), device="cpu")
