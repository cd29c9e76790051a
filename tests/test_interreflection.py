"""Light that bounces (issue 48): the gather rows (precompute.visibility.gather) against closed-form
view factors, the renderer's indirect light (warp_sg.shading.bounce, warp_sg.renderer.interreflection)
against the Monte-Carlo path tracer at full depth, and how it follows edits and motion."""
from __future__ import annotations

import numpy as np
import pytest

import warp_sg as ws
from precompute.visibility import gather as G


def _disc_over_point(radius: float, height: float, segments: int = 256):
    """A receiver triangle at the origin facing +y and a disc of ``radius`` at ``height`` facing it
    (a fan of ``segments`` triangles): vertices, triangles, normals."""
    a = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    rim = np.stack([radius * np.cos(a), np.full(segments, height), radius * np.sin(a)], 1)
    v = np.concatenate([[[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0], [0.0, 0.0, 1e-3]], [[0.0, height, 0.0]], rim])
    k = np.arange(segments)
    fan = np.stack([np.full(segments, 3), 4 + k, 4 + (k + 1) % segments], 1)  # winding: normal −y
    t = np.concatenate([[[0, 2, 1]], fan])
    n = np.concatenate([np.tile([0.0, 1.0, 0.0], (3, 1)), np.tile([0.0, -1.0, 0.0], (segments + 1, 1))])
    return v, t, n


@pytest.mark.parametrize("radius,height,tol", [(1.0, 1.0, 0.005), (0.5, 2.0, 0.025)])
def test_gather_row_weight_is_the_view_factor_of_a_parallel_disc(radius, height, tol):
    # a point under a coaxial disc sees it with the view factor F = R²/(R² + h²) (differential
    # area to a parallel disc): the share of the cosine-weighted hemisphere its rays hit (4096
    # stratified rays: the ~100 strata the disc's rim crosses leave a few rays' worth of noise)
    v, t, n = _disc_over_point(radius, height)
    g = G.compute_gather(v, t, n, rays=4096, refs=4000)
    F = radius ** 2 / (radius ** 2 + height ** 2)
    assert g.row_weight()[0] == pytest.approx(F, rel=tol)
    # every reference of the row is a disc vertex, each seen from below
    s = g.senders[g.offsets[0]:g.offsets[1]]
    assert np.all(s >= 3)


def test_compressed_rows_keep_their_weight_and_at_most_refs_references():
    v, t, n = _disc_over_point(1.0, 1.0, segments=512)
    full = G.compute_gather(v, t, n, rays=256, refs=10_000)
    few = G.compute_gather(v, t, n, rays=256, refs=8)
    assert np.diff(full.offsets)[0] > 8 and np.all(np.diff(few.offsets) <= 8)
    np.testing.assert_allclose(few.row_weight(), full.row_weight(), rtol=2e-3, atol=1e-6)  # (float16 weights)
    assert (few.nbytes - few.offsets.nbytes) / len(few.senders) == 8  # sender, float16 weight, direction


def test_octahedral_directions_round_trip_within_a_degree():
    d = np.random.default_rng(0).normal(size=(5000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    back = G.octahedral_decode(G.octahedral_encode(d))
    assert np.degrees(np.arccos(np.clip(np.sum(back * d, 1), -1, 1))).max() < 1.0


def test_groups_gather_from_their_own_triangles_only():
    v, t, n = _disc_over_point(1.0, 1.0)
    groups = np.concatenate([[0], np.ones(len(t) - 1, int)])  # the receiver alone in group 0
    g = G.compute_gather(v, t, n, rays=64, refs=100, groups=groups)
    assert g.row_weight()[0] == 0.0  # its group has nothing above it
    assert g.n_vertices == len(v)


# ----------------------------------------------------------------------------- the renderer
SIZE = 40
RENDER = {"ssdf_resolution": 16, "pca_terms": 16, "visibility_budget": 5000}


@pytest.fixture(scope="module")
def lambert_scene(tmp_path_factory):
    from warp_sg.scene.plain_scenes import write_plain_scene

    return write_plain_scene(tmp_path_factory.mktemp("bounce"), obj="sphere", light="sky", material="lambert",
                             size=SIZE, render=RENDER)


@pytest.fixture(scope="module")
def lambert(lambert_scene):
    r = ws.Renderer(ws.load_scene(lambert_scene))
    return r, r.render()


@pytest.fixture(scope="module")
def full_reference(lambert_scene):
    from warp_sg.groundtruth.region_error import box_reference

    return box_reference(ws.load_scene(lambert_scene), spp=256, supersample=4, seed=3, return_stderr=True)


def test_bounces_match_the_full_path_tracer_per_region(lambert_scene, lambert, full_reference):
    from warp_sg.groundtruth.region_error import region_errors, scene_regions

    r, img = lambert
    ref, se = full_reference
    regions = scene_regions(ws.load_scene(lambert_scene))
    e = region_errors(img, ref, regions, stderr=se)
    r.set_terms(bounces=False)
    try:
        direct = region_errors(r.render(), ref, regions, stderr=se)
    finally:
        r.set_terms(bounces=True)
    # the sphere gets a tenth of its light from the floor, the floor some from the sphere
    assert direct["object"]["bias"] < -0.08 and direct["lit_floor"]["bias"] < -0.02
    assert abs(e["object"]["bias"]) < 0.02 and abs(e["lit_floor"]["bias"]) < 0.015
    assert abs(e["shadow"]["bias"]) < 0.08 and abs(e["silhouette"]["bias"]) < 0.03
    assert r.timings["bounces"] >= 2


def test_bounces_zero_is_the_direct_light_and_more_bounces_add_less_and_less(lambert_scene, lambert):
    r, img = lambert
    sc = ws.load_scene(lambert_scene)
    imgs = {}
    for b in (0, 1, 2):
        sc.render.bounces = b
        imgs[b] = ws.Renderer(sc).render()
    r.set_terms(bounces=False)
    try:
        np.testing.assert_array_equal(r.render(), imgs[0])  # the toggle is bounces = 0, bit for bit
    finally:
        r.set_terms(bounces=True)
    added = [float((imgs[1] - imgs[0]).sum()), float((imgs[2] - imgs[1]).sum()), float((img - imgs[2]).sum())]
    assert added[0] > 0 and 0 <= added[1] < 0.5 * added[0] and 0 <= added[2] < 0.5 * added[1]


def test_material_and_light_edits_reuse_the_gather_and_equal_a_fresh_renderer(lambert_scene):
    from warp_sg.core.cache import record_builds

    sc = ws.load_scene(lambert_scene)
    r = ws.Renderer(sc)
    r.render()
    rows = r._transfer
    with record_builds() as ledger:
        r.set_material("floor", kd=[0.8, 0.3, 0.2])
        r.set_environment_scale(0.7)
        img = r.render()
        before = r.indirect_irradiance().copy()
        r.set_environment_rotation(120.0)  # (a fresh renderer fits the turned map's peaks anew: not compared)
        r.render()
    assert not ledger.events and r._transfer is rows  # edits need no new precompute, not even a cache read
    assert np.abs(r.indirect_irradiance() - before).max() > 0.05 * before.max()  # the bounce light follows
    r.set_environment_rotation(0.0)
    np.testing.assert_array_equal(r.render(), img)
    fresh = ws.Renderer(r.scene).render()
    np.testing.assert_array_equal(img, fresh)  # the edited renderer's frame is a fresh one's, bit for bit
    # the red floor bounces red light onto the sphere: its underside turns red
    assert r.indirect_irradiance()[:, 0].sum() > 1.5 * r.indirect_irradiance()[:, 2].sum()


def test_glossy_receiver_reflects_the_floor_as_the_path_tracer_does(tmp_path):
    from warp_sg.groundtruth.region_error import box_reference, region_errors, scene_regions
    from warp_sg.scene.plain_scenes import write_plain_scene

    p = write_plain_scene(tmp_path, obj="sphere", light="sky", material={"model": "ggx", "alpha": 0.2, "fresnel": "gold"},
                          size=SIZE, render=RENDER)
    sc = ws.load_scene(p)
    r = ws.Renderer(sc)
    img = r.render()
    r.set_terms(bounces=False)
    direct = r.render()
    ref = box_reference(sc, spp=256, supersample=4, seed=4)
    regions = scene_regions(sc)
    e, e0 = region_errors(img, ref, regions)["object"], region_errors(direct, ref, regions)["object"]
    # a quarter of the gold sphere's light is the floor it reflects
    assert e0["bias"] < -0.15 and abs(e["bias"]) < 0.04 and e["rel_mse"] < 0.25 * e0["rel_mse"]


def test_a_moving_object_leaves_no_stale_light_and_its_own_turns_with_it(tmp_path):
    from warp_sg.scene.plain_scenes import write_plain_scene

    p = write_plain_scene(tmp_path, obj="blob", light="sky", material="lambert", size=SIZE, render=RENDER, dynamic=True)
    r = ws.Renderer(ws.load_scene(p))
    first = r.render()
    nv = len(r.geometry.vertices)
    dyn = r.dynamic.ids[0]
    static = np.setdiff1d(np.arange(nv), dyn)
    e0 = r.indirect_irradiance().copy()
    assert e0[dyn].sum() > 0  # the blob's own concavities light each other
    c, s_ = np.cos(1.1), np.sin(1.1)
    m = np.array([[c, 0, s_, 0.9], [0, 1, 0, 0], [-s_, 0, c, -0.4], [0, 0, 0, 1.0]])
    r.set_object_transform(0, m)
    r.render()
    e1 = r.indirect_irradiance()
    # the floor gathers from the static objects only: the object's move changes none of its rows' light
    # beyond the direct light the move takes away or gives (its shadow): no light where it stood
    assert np.isfinite(e1).all()
    # the object's self-light is a function of its own pose only: turned about the vertical under a
    # sky whose light is not uniform it changes, but its total stays of the same size
    assert 0.5 < e1[dyn].sum() / e0[dyn].sum() < 2.0
    r.set_object_transform(0, np.eye(4))
    np.testing.assert_array_equal(r.render(), first)  # back where it was: the first frame, bit for bit
    np.testing.assert_array_equal(r.indirect_irradiance()[static], e0[static])


def test_bad_bounces_is_a_scene_error_naming_the_key():
    from warp_sg.core.errors import SceneError
    from warp_sg.scene.render_settings import RenderSettings

    with pytest.raises(SceneError, match="bounces"):
        RenderSettings(bounces=-1).validate()


def test_a_mesh_over_the_visibility_budget_gathers_at_its_representatives(lambert_scene, full_reference):
    # its SSDFs are computed at 400 representative vertices and blended: so are the gather rows, and
    # the sphere's light from the floor is still the path tracer's
    from warp_sg.groundtruth.region_error import region_errors, scene_regions

    sc = ws.load_scene(lambert_scene)
    sc.render.visibility_budget = 400
    r = ws.Renderer(sc)
    img = r.render()
    rows = np.diff(r.gather.offsets)
    assert 0 < (rows > 0).sum() <= 400 < len(rows)
    ref, se = full_reference
    e = region_errors(img, ref, scene_regions(sc), stderr=se)
    assert abs(e["object"]["bias"]) < 0.03  # (the floor, 4 vertices unrefined within this budget, is the SSDFs' own error)
