"""Light that bounces with objects that move (issue 48, item 3): after a move the rows the move
changes are cast again at the current pose (precompute.visibility.gather_pose). Checked against
independent paths: the gather of the posed mesh computed from scratch, the full path tracer at the
moved pose, and a renderer with the ball placed there as a static object; a move back gives the
first frame bit for bit, and bounces = 0 casts nothing."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import warp_sg as ws
from precompute.visibility import gather as G
from precompute.visibility.gather_pose import PoseGather, posed_rows, replace_rows
from warp_sg.numeric.rigid_motion import rolling
from warp_sg.scene.plain_scenes import write_plain_scene

ROLL = rolling(0.8, direction=[1.0, 0.0, 0.4])  # the notebook's pose (notebooks/01_tour.ipynb)


def _disc_over_point(radius=1.0, height=1.0, segments=64):
    a = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    rim = np.stack([radius * np.cos(a), np.full(segments, height), radius * np.sin(a)], 1)
    v = np.concatenate([[[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0], [0.0, 0.0, 1e-3]], [[0.0, height, 0.0]], rim])
    k = np.arange(segments)
    t = np.concatenate([[[0, 2, 1]], np.stack([np.full(segments, 3), 4 + k, 4 + (k + 1) % segments], 1)])
    n = np.concatenate([np.tile([0.0, 1.0, 0.0], (3, 1)), np.tile([0.0, -1.0, 0.0], (segments + 1, 1))])
    return v, t, n


def test_rows_cast_at_the_pose_are_the_gather_of_the_posed_mesh_from_scratch():
    v, t, n = _disc_over_point()
    pts = wp.array(v.astype(np.float32), dtype=wp.vec3, device="cpu")
    nor = wp.array(n.astype(np.float32), dtype=wp.vec3, device="cpu")
    pg = PoseGather(pts, nor, t, v, "cpu")
    ids = np.array([0, 1, 2])
    want = G.compute_gather(v, t, n, rays=64, refs=100, receivers=ids)
    cnt, snd, w, _ = pg.rows(ids, 64, 100)
    np.testing.assert_array_equal(cnt, np.diff(want.offsets)[ids])
    np.testing.assert_array_equal(snd, want.senders)
    np.testing.assert_allclose(w, want.weights.astype(np.float32), rtol=1e-3, atol=1e-6)
    # the disc lifted in place (the points array moved, as a move writes it): the rows follow it, and
    # equal the gather of the lifted mesh computed from scratch (its view factor R²/(R² + h²) drops)
    lifted = v.copy()
    lifted[3:, 1] += 1.0
    pts.assign(lifted.astype(np.float32))
    cnt2, snd2, w2, _ = pg.rows(ids, 64, 100)
    again = G.compute_gather(lifted, t, n, rays=64, refs=100, receivers=ids)
    np.testing.assert_allclose(w2.sum(), again.weights.astype(np.float64).sum(), rtol=2e-3)
    assert abs(w2[:cnt2[0]].sum() - 1.0 / 5.0) < 0.03 and abs(w[:cnt[0]].sum() - 0.5) < 0.03


def test_replaced_rows_are_the_rows_given_and_the_others_untouched():
    rng = np.random.default_rng(1)
    counts = rng.integers(0, 5, 7)
    off = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    snd = rng.integers(0, 7, off[-1]).astype(np.int32)
    w = rng.random(off[-1]).astype(np.float32)
    ids, new_cnt = np.array([1, 4, 6]), np.array([3, 0, 2])
    new_snd, new_w = np.arange(5, dtype=np.int32) + 100, np.arange(5, dtype=np.float32)
    o, (s2, w2) = replace_rows(off, [snd, w], ids, new_cnt, [new_snd, new_w])
    at = {1: slice(0, 3), 4: slice(3, 3), 6: slice(3, 5)}
    for v in range(7):
        got = s2[o[v]:o[v + 1]], w2[o[v]:o[v + 1]]
        ref = (new_snd[at[v]], new_w[at[v]]) if v in at else (snd[off[v]:off[v + 1]], w[off[v]:off[v + 1]])
        np.testing.assert_array_equal(got[0], ref[0])
        np.testing.assert_array_equal(got[1], ref[1])


def test_posed_rows_turn_the_kept_rows_directions():
    d = np.tile(np.array([[1.0, 0.0, 0.0]], np.float32), (4, 1))
    data = G.GatherData(np.array([0, 2, 4], np.int32), np.array([1, 1, 0, 0], np.int32),
                        np.full(4, 0.25, np.float16), G.octahedral_encode(d), 4, 4)
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    off, snd, w, dirs = posed_rows(data, d, [(np.array([1]), R)])
    np.testing.assert_allclose(dirs[:2], d[:2])
    np.testing.assert_allclose(dirs[2:], [[0.0, 1.0, 0.0]] * 2, atol=1e-6)
    off, snd, w, dirs = posed_rows(data, d, [(np.array([1]), R)],
                                   (np.array([0]), np.array([1]), np.array([1], np.int32),
                                    np.array([0.5], np.float32), np.array([[0.0, 0.0, 1.0]], np.float32)))
    np.testing.assert_array_equal(off, [0, 1, 3])
    np.testing.assert_allclose(w, [0.5, 0.25, 0.25])
    np.testing.assert_allclose(dirs[0], [0.0, 0.0, 1.0])


# ----------------------------------------------------------------------------- the renderer
@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("rolled")


@pytest.fixture(scope="module")
def rolled(folder):
    """The tour's ball (dynamic, 48², the scene's defaults: bounces = 4) rolled to x = 0.8, its
    first frame at rest, and the frame there."""
    r = ws.Renderer(ws.load_scene(write_plain_scene(folder / "dyn", obj="sphere", light="sky", size=48,
                                                    dynamic=True)))
    first = r.render().copy()
    first_irr = r.indirect_irradiance().copy()
    r.set_object_transform("object", ROLL)
    return r, first, first_irr, r.render().copy()


def test_a_rolled_ball_gets_the_light_between_it_and_the_floor_as_the_path_tracer_does(folder, rolled):
    from warp_sg.groundtruth.region_error import box_reference, region_errors, scene_regions

    r, _, _, img = rolled
    ref, se = box_reference(r.scene, spp=256, supersample=4, device="cpu", return_stderr=True, seed=5)  # full depth
    regions = scene_regions(r.scene)
    e = region_errors(img, ref, regions, stderr=se)
    # without the light between the ball and the floor (issue 48): object −13.5 %, lit floor −4.1 %,
    # shadow −15 %; with the rows cast at the pose: +0.1 %, −0.3 %, −2.4 %
    assert abs(e["object"]["bias"]) < 0.03 and abs(e["lit_floor"]["bias"]) < 0.02, e
    assert abs(e["shadow"]["bias"]) < 0.10 and e["shadow"]["pixels"] > 5, e
    # the ball placed there as a static object (one group: every row gathered from the whole scene
    # by the precompute, nothing cast per move) — an independent path to the same light
    sc = ws.load_scene(write_plain_scene(folder / "static", obj="sphere", light="sky", size=48))
    sc.objects[0].motion = ROLL
    sc.invalidate_geometry()
    es = region_errors(ws.Renderer(sc).render(), ref, regions, stderr=se)
    assert abs(e["object"]["bias"] - es["object"]["bias"]) < 0.01, (e, es)
    assert abs(e["lit_floor"]["bias"] - es["lit_floor"]["bias"]) < 0.01, (e, es)
    assert r.timings["pose_rows"] > 0.0


def test_rows_are_cast_again_at_each_pose_and_back_at_rest_give_the_first_frame_bit_for_bit(rolled):
    r, first, first_irr, img = rolled
    nv = len(r.geometry.vertices)
    recast = np.diff(r._transfer.offsets.numpy())
    # the precomputed rows are empty (a convex ball and a flat floor see nothing of their own group);
    # cast at the pose, the floor's rows see the ball and the ball's lower half the floor
    assert (np.diff(r.gather.offsets) > 0).sum() == 0 < 0.5 * nv < (recast > 0).sum()
    ball = r.dynamic.ids[0]
    assert r.indirect_irradiance()[ball].mean() > 0.05 * first_irr.mean()
    r.set_object_transform("object", rolling(0.3, direction=[1.0, 0.0, 0.4]))
    mid = r.render().copy()
    assert not np.array_equal(mid, img)
    r.set_object_transform("object", ROLL)
    np.testing.assert_array_equal(r.render(), img)  # (a function of the pose: no state of the last one)
    r.set_object_transform("object", np.eye(4))
    np.testing.assert_array_equal(r.render(), first)
    np.testing.assert_array_equal(r.indirect_irradiance(), first_irr)


def test_bounces_zero_casts_no_rows_and_is_the_direct_light_bit_for_bit(folder):
    rs = {"bounces": 0}
    a = ws.Renderer(ws.load_scene(write_plain_scene(folder / "b0", obj="sphere", light="sky", size=32, render=rs,
                                                    dynamic=True)))
    b = ws.Renderer(ws.load_scene(write_plain_scene(folder / "b4", obj="sphere", light="sky", size=32,
                                                    dynamic=True)))
    b.set_terms(bounces=False)
    for m in (np.eye(4), ROLL):
        a.set_object_transform("object", m)
        b.set_object_transform("object", m)
        np.testing.assert_array_equal(a.render(), b.render())
    assert getattr(a, "_pose_gather", None) is None and getattr(b, "_pose_gather", None) is None
