"""Adaptive visibility rays (``precompute.visibility.adaptive_rays``): the maps and SSDFs they give against a
ray per texel (the reference: ``compute_ssdf(rays="full")``) and against a 256²-ray truth."""
from __future__ import annotations

import numpy as np
import pytest

from precompute.visibility import ssdf as S
from precompute.visibility.adaptive_rays import levels
from precompute.visibility.reference_checks import plane_box_scene
from warp_sg.core.stage_clock import StageClock
from warp_sg.tools.bench_precompute import ssdf_error


def _plates_scene(gap: float, near: float = 1.0, far: float = 4.0):
    """A floor vertex at the origin (normal +y) under two large plates: one at height ``near``
    over x < 0, one at height ``far`` over x > ``gap · far``: seen from the vertex, a slit of angular
    width ≈ atan(gap) between them, with a depth jump of ``far/near``. Returns (V, F, N)."""
    import trimesh

    parts = []
    a = trimesh.creation.box(extents=[400.0, 0.02, 400.0])
    a.apply_translation([-200.0, near, 0.0])
    b = trimesh.creation.box(extents=[400.0, 0.02, 400.0])
    b.apply_translation([200.0 + gap * far, far, 0.0])
    parts += [a, b]
    floor = trimesh.creation.box(extents=[0.4, 0.02, 0.4])
    floor.apply_translation([0.0, -0.01, 0.0])
    V = np.concatenate([np.zeros((1, 3))] + [p.vertices for p in parts + [floor]])
    F, off = [], 1
    for p in parts + [floor]:
        F.append(p.faces + off)
        off += len(p.vertices)
    N = np.tile([0.0, 1.0, 0.0], (len(V), 1))
    return V, np.concatenate(F), N


def _ball_over_floor():
    """An icosphere (radius 0.5, 642 vertices) resting on a 41×41-vertex floor 6 wide, normals up on
    the floor and outward on the ball. Returns (V, F, N)."""
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    ball.apply_translation([0.0, 0.5, 0.0])
    n = 41
    g = np.linspace(-3.0, 3.0, n)
    X, Z = np.meshgrid(g, g, indexing="ij")
    fv = np.stack([X.ravel(), np.zeros(n * n), Z.ravel()], axis=1)
    q = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    ff = np.concatenate([np.stack([q, q + 1, q + n], 1), np.stack([q + 1, q + n + 1, q + n], 1)])
    V = np.concatenate([fv, ball.vertices])
    F = np.concatenate([ff, ball.faces + len(fv)])
    N = np.concatenate([np.tile([0.0, 1.0, 0.0], (len(fv), 1)), np.asarray(ball.vertex_normals)])
    return V, F, N


def _maps(V, F, N, ids, rays, **kw):
    clock = StageClock()
    sd, vis = S.compute_ssdf(V, F, N, resolution=32, ray_resolution=64, vertex_ids=ids, progress=False,
                             return_visibility=True, rays=rays, clock=clock, **kw)
    return sd, vis, clock.counts["rays_cast"]


def test_levels_halve_the_cell_size_down_to_single_texels():
    assert levels(64) == [16, 32, 64]
    assert levels(32, 4) == [8, 16, 32]
    assert levels(48) == [12, 24, 48]
    assert levels(6) == [6]  # no coarse grid of ≥ 2 cells: plain ray casting


def test_adaptive_maps_match_full_ray_maps_on_the_floor_and_box_with_a_third_of_the_rays():
    V, F, N = plane_box_scene(20)
    ids = np.arange(len(V))
    sd_a, vis_a, rays_a = _maps(V, F, N, ids, "adaptive")
    sd_f, vis_f, rays_f = _maps(V, F, N, ids, "full")
    assert rays_f == len(ids) * 64 * 64
    assert rays_a < 0.45 * rays_f
    assert np.count_nonzero(vis_a != vis_f) <= 1e-4 * vis_f.size
    # the SSDF differs from the full-ray one far less than the full-ray one's own error (0.0068 rad)
    assert ssdf_error(V, F, N, ids, sd_a, sd_f) < 5e-4


def test_a_slit_narrower_than_a_coarse_cell_is_found_by_its_depth_jump():
    V, F, N = _plates_scene(gap=0.06)  # ≈ 1.2 ray texels wide, a quarter of a coarse cell
    _, vis_f, _ = _maps(V, F, N, [0], "full")
    assert 0 < vis_f.sum() < 0.1 * vis_f.size  # the slit (and the horizon band) is all the vertex sees
    _, vis_a, _ = _maps(V, F, N, [0], "adaptive")
    assert np.array_equal(vis_a, vis_f)
    # without the depth criterion the coarse samples straddle the slit and it is lost
    _, vis_n, _ = _maps(V, F, N, [0], "adaptive", adaptive={"depth_ratio": 0})
    assert np.count_nonzero(vis_n != vis_f) > 0


def test_the_last_level_can_cast_only_between_samples_that_disagree():
    """``last="bracket"``: the last level's texels lie between two or four samples of the 2×2-texel
    cells; where those agree the texel takes their value. A slit ≈ 5 texels wide (straight edges, a
    depth jump) is found exactly with fewer rays than the default, which casts every texel of the
    marked cells; on the floor and box the maps stay within 1e-4 of the texels of a ray per texel,
    the default's within fewer. On a ball over a floor the concentric map's diagonals, where a
    boundary bends at texel scale, are cast: the bracketed maps miss no texel there."""
    V, F, N = _plates_scene(gap=0.25)
    _, vis_f, _ = _maps(V, F, N, [0], "full")
    _, vis_a, rays_a = _maps(V, F, N, [0], "adaptive", adaptive={"last": "bracket"})
    _, vis_b, rays_b = _maps(V, F, N, [0], "adaptive")
    assert 0 < vis_f.sum() < 0.3 * vis_f.size
    assert np.array_equal(vis_a, vis_f) and np.array_equal(vis_b, vis_f)
    assert rays_a < 0.85 * rays_b
    V, F, N = plane_box_scene(20)
    ids = np.arange(len(V))
    _, vis_f, _ = _maps(V, F, N, ids, "full")
    _, vis_a, rays_a = _maps(V, F, N, ids, "adaptive", adaptive={"last": "bracket"})
    _, vis_b, rays_b = _maps(V, F, N, ids, "adaptive")
    assert rays_a < 0.85 * rays_b
    assert np.count_nonzero(vis_b != vis_f) <= np.count_nonzero(vis_a != vis_f) <= 1e-4 * vis_f.size
    V, F, N = _ball_over_floor()
    ids = np.flatnonzero(np.abs(V[:, 1]) < 1e-9)
    _, vis_f, _ = _maps(V, F, N, ids, "full")
    _, vis_a, _ = _maps(V, F, N, ids, "adaptive", adaptive={"last": "bracket"})
    _, vis_b, _ = _maps(V, F, N, ids, "adaptive")
    y, x = np.mgrid[0:64, 0:64]
    diagonal = (x == y) | (x + y == 63)
    assert (vis_f[:, diagonal] == 0).any()  # the ball's outline crosses the diagonals
    assert np.count_nonzero(vis_a[:, diagonal] != vis_f[:, diagonal]) <= np.count_nonzero(vis_b != vis_f)
    assert np.count_nonzero(vis_a != vis_f) <= 1e-4 * vis_f.size
    with pytest.raises(ValueError, match="last"):
        _maps(V, F, N, ids[:1], "adaptive", adaptive={"last": "sometimes"})


def test_the_horizon_ring_keeps_a_one_texel_band_just_above_the_horizon():
    """A vertex under a wide, low plate sees out only at grazing elevations: a band one texel
    high along the map's edge, which no coarse sample meets."""
    import trimesh

    plate = trimesh.creation.box(extents=[12.0, 0.02, 12.0])
    plate.apply_translation([0.0, 0.37, 0.0])  # seen at 2.5–3.5° elevation: only the edge texels (1.8°) see under
    V = np.concatenate([np.zeros((1, 3)), plate.vertices])
    F = plate.faces + 1
    N = np.tile([0.0, 1.0, 0.0], (len(V), 1))
    _, vis_f, _ = _maps(V, F, N, [0], "full")
    edge = np.zeros((64, 64), bool)
    edge[0] = edge[-1] = True
    edge[:, 0] = edge[:, -1] = True
    assert vis_f[0][edge].mean() > 0.5 and vis_f[0][~edge].sum() == 0
    _, vis_a, _ = _maps(V, F, N, [0], "adaptive")
    assert np.array_equal(vis_a, vis_f)


def test_the_sparse_ring_finds_where_the_horizon_band_is_cut_with_fewer_ring_rays():
    """The low plate of the test above and a wall standing on the floor that hides part of the
    band: the ring, sampled every RING_STEP-th texel and halved where its samples disagree, gives
    the full-ray map exactly (band, wall edges) with fewer rays than a ray per ring texel."""
    import trimesh

    from precompute.visibility.adaptive_rays import RING_STEP

    plate = trimesh.creation.box(extents=[12.0, 0.02, 12.0])
    plate.apply_translation([0.0, 0.37, 0.0])
    wall = trimesh.creation.box(extents=[0.2, 0.3, 9.0])  # x = 3 ± 0.1, under the plate: hides ≈ 110° of azimuth
    wall.apply_translation([3.0, 0.15, 1.5])
    V = np.concatenate([np.zeros((1, 3)), plate.vertices, wall.vertices])
    F = np.concatenate([plate.faces + 1, wall.faces + 1 + len(plate.vertices)])
    N = np.tile([0.0, 1.0, 0.0], (len(V), 1))
    _, vis_f, _ = _maps(V, F, N, [0], "full")
    edge = np.zeros((64, 64), bool)
    edge[0] = edge[-1] = True
    edge[:, 0] = edge[:, -1] = True
    band = vis_f[0][edge]
    assert 0.3 < band.mean() < 0.9 and vis_f[0][~edge].sum() == 0  # the band, cut by the wall
    _, vis_a, rays_a = _maps(V, F, N, [0], "adaptive")
    _, vis_d, rays_d = _maps(V, F, N, [0], "adaptive", adaptive={"ring_step": 1})
    assert RING_STEP > 1
    assert np.array_equal(vis_a, vis_f) and np.array_equal(vis_d, vis_f)
    assert rays_a < rays_d
    with pytest.raises(ValueError, match="ring step"):
        _maps(V, F, N, [0], "adaptive", adaptive={"ring_step": 3})


@pytest.mark.slow
def test_adaptive_ssdf_error_against_a_256_ray_truth_is_that_of_full_rays():
    V, F, N = plane_box_scene(30)
    ring = np.maximum(np.abs(V[:, 0]), np.abs(V[:, 2]))
    ids = np.flatnonzero((np.abs(V[:, 1]) < 1e-9) & (ring > 0.55) & (ring < 1.4))[::3]
    truth = S.compute_ssdf(V, F, N, resolution=256, ray_resolution=256, vertex_ids=ids, progress=False, rays="full")
    sd_a, _, _ = _maps(V, F, N, ids, "adaptive")
    sd_f, _, _ = _maps(V, F, N, ids, "full")
    idx = np.arange(len(ids))
    e_full = ssdf_error(V, F, N, idx, sd_f, truth)
    e_adapt = ssdf_error(V, F, N, idx, sd_a, truth)
    assert e_adapt <= 1.02 * e_full + 1e-5, (e_adapt, e_full)


def test_ssdf_cache_key_names_the_ray_schedule():
    V, F, N = plane_box_scene(6)
    assert S.ssdf_key(V, F, N, rays="adaptive") != S.ssdf_key(V, F, N, rays="full")
    assert S.ssdf_key(V, F, N) == S.ssdf_key(V, F, N, rays=S.DEFAULT_RAYS)
    from warp_sg.core.errors import InputError

    with pytest.raises(InputError, match="rays"):
        S.ssdf_key(V, F, N, rays="sparse")
