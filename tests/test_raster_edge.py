"""Rasterizer edge cases: clipping, degenerate and huge input, bad input errors."""
from __future__ import annotations

import numpy as np
import pytest

import raster
from raster.reference_checks import raycast_visibility
from warp_sg.core.errors import InputError, MeshError

CAM = dict(origin=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0), fov=60.0, width=48, height=40)


def _cam(**kw):
    return raster.Camera(**{**CAM, **kw})


def _agree(V, F, cam, device, min_agree=0.999):
    vb = raster.rasterize(np.asarray(V, np.float32), np.asarray(F, np.int32), cam, device=device)
    rt, rb, rd = vb.tri_id.numpy(), vb.bary.numpy(), vb.depth.numpy()
    ct, cb, cd = raycast_visibility(np.asarray(V, np.float32), np.asarray(F, np.int32), cam, device=device)
    assert (rt == ct).mean() >= min_agree
    m = (rt == ct) & (rt >= 0)
    assert np.all(np.isfinite(rb)) and not np.isnan(rd).any()
    return vb, m, (rt, rb, rd), (ct, cb, cd)


def test_triangles_behind_the_camera_draw_nothing(device):
    V = [[-1, -1, 2], [1, -1, 2], [0, 1, 2], [-1, -1, 0.001], [1, -1, 0.001], [0, 1, 0.0]]
    vb = raster.rasterize(V, [[0, 1, 2], [3, 4, 5]], _cam(), device=device)
    assert (vb.tri_id.numpy() == -1).all() and vb.stats["pairs"] == 0
    assert (vb.depth.numpy() == np.inf).all() and (vb.bary.numpy() == 0).all()


def test_triangle_crossing_near_plane_reports_original_id_and_barycentrics(device):
    # one vertex 1 unit behind the camera, two in front: clipped into 2 sub-triangles
    V = [[-3.0, -1.0, -2.0], [3.0, -1.0, -2.0], [0.0, -0.2, 1.0], [-0.2, -0.3, -5.0], [0.2, -0.3, -5.0], [0, 0.4, -5]]
    F = [[0, 1, 2], [3, 4, 5]]
    vb, m, (rt, rb, rd), (ct, cb, cd) = _agree(V, F, _cam(), device)
    assert vb.stats["sub_triangles"] == 3  # 2 pieces of triangle 0 + triangle 1
    assert (rt == 0).sum() > 100 and (rt == 1).sum() >= 5
    assert np.abs(rb[m] - cb[m]).max() < 1e-3
    assert np.abs(rd[m] - cd[m]).max() < 1e-4 * cd[m].max()
    # interpolated positions lie on the original triangle (weights w.r.t. its own vertices)
    P = raster.interpolate(vb, F, np.asarray(V, np.float32)).numpy()
    assert np.abs(P[rt == 0][:, 1] - (-1.0 + 0.8 * (P[rt == 0][:, 2] + 2.0) / 3.0)).max() < 1e-3


def test_vertex_exactly_on_camera_plane_and_guard_band_clipping(device):
    # a vertex at w = 0 beside the camera and one far off-screen (guard band) near the eye
    V = [[0.0, -0.5, 0.0], [-50.0, -0.5, -0.02], [50.0, -0.6, -8.0], [1e3, 0.2, -0.05], [-2, 0.5, -3], [2, 0.4, -3]]
    F = [[0, 1, 2], [3, 4, 5]]
    vb, m, (rt, rb, rd), (ct, cb, cd) = _agree(V, F, _cam(), device)
    assert (rt == 0).sum() > 300 and (rt == 1).sum() > 20
    assert np.abs(rb[m] - cb[m]).max() < 2e-3


def test_triangle_larger_than_screen_covers_every_pixel(device):
    V = [[-1e3, -1e3, -4.0], [1e3, -1e3, -4.0], [0.0, 1e3, -4.0]]
    vb = raster.rasterize(V, [[0, 1, 2]], _cam(), device=device)
    assert (vb.tri_id.numpy() == 0).all()
    assert np.allclose(vb.depth.numpy(), 4.0, rtol=1e-5)


def test_degenerate_triangles_are_skipped_without_affecting_others(device):
    V = np.array([[-1, -1, -3], [1, -1, -3], [0, 1, -3], [2, 2, -3], [-1, 0, -2], [1, 0, -2]], np.float32)
    good = [[0, 1, 2]]
    degen = [[0, 0, 1], [3, 3, 3], [4, 5, 4], [0, 1, 1], [4, 5, 0 + 4]]
    collinear_v = np.array([[-1, 0, -2.5], [0, 0, -2.5], [1, 0, -2.5]], np.float32)
    V2 = np.concatenate([V, collinear_v])
    F = np.array(degen + good + [[6, 7, 8]], np.int32)
    a = raster.rasterize(V, good, _cam(), device=device).tri_id.numpy()
    b = raster.rasterize(V2, F, _cam(), device=device, coverage_count=True)
    t = b.tri_id.numpy()
    assert set(np.unique(t)) == {-1, 5}
    assert ((a == 0) == (t == 5)).all() and (a == 0).sum() > 100
    assert b.coverage.numpy().max() == 1


def test_huge_coordinates_floor_matches_raycast(device):
    V = [[-1e6, -1.0, 1e6], [1e6, -1.0, 1e6], [1e6, -1.0, -1e6], [-1e6, -1.0, -1e6],
         [-0.5, -0.5, -3.0], [0.5, -0.5, -3.0], [0.0, 0.5, -3.0]]
    F = [[0, 1, 2], [0, 2, 3], [4, 5, 6]]
    cam = _cam(target=(0.0, -0.3, -1.0))
    vb, m, (rt, rb, rd), (ct, cb, cd) = _agree(V, F, cam, device)
    assert (rt >= 0).sum() > 0.5 * rt.size and (rt == 2).sum() > 50
    # the floor's exact depth (the float32 ray cast is the noisier one against 1e6-sized triangles)
    d = cam.ray_directions().astype(np.float64)
    exact = (-1.0 / d[..., 1]) * (d @ cam.forward())
    fl = (rt >= 0) & (rt < 2)
    assert fl.sum() > 500
    assert np.abs(rd[fl] / exact[fl] - 1).max() < 5e-4  # float32 planes about a vertex 1e4 px away


def test_subpixel_triangles_match_raycast(device):
    rng = np.random.default_rng(1)
    n = 4000
    c = np.c_[rng.uniform(-1.6, 1.6, n), rng.uniform(-1.2, 1.2, n), rng.uniform(-3.5, -2.5, n)]
    V = (c[:, None, :] + rng.normal(0, 0.02, (n, 3, 3))).reshape(-1, 3)
    F = np.arange(3 * n).reshape(n, 3)
    vb, m, (rt, *_), (ct, *_) = _agree(V, F, _cam(width=64, height=48), device, min_agree=0.998)
    assert (rt >= 0).sum() > 150


def test_beyond_far_plane_is_empty(device):
    V = [[-1, -1, -20.0], [1, -1, -20.0], [0, 1, -20.0]]
    assert (raster.rasterize(V, [[0, 1, 2]], _cam(far=10.0), device=device).tri_id.numpy() == -1).all()
    assert (raster.rasterize(V, [[0, 1, 2]], _cam(far=30.0), device=device).tri_id.numpy() == 0).any()


@pytest.mark.parametrize("V,F", [(np.zeros((0, 3)), np.zeros((0, 3), np.int32)),
                                 (np.ones((4, 3)), np.zeros((0, 3), np.int32))])
def test_empty_mesh_gives_empty_buffer(V, F, device):
    vb = raster.rasterize(V, F, _cam(), device=device, coverage_count=True)
    assert vb.tri_id.shape == (40, 48) and (vb.tri_id.numpy() == -1).all()
    assert (vb.coverage.numpy() == 0).all()
    assert raster.interpolate(vb, F, np.ones((V.shape[0], 2))).numpy().shape == (40, 48, 2)


def test_nan_vertex_is_a_mesh_error_naming_the_vertex():
    V = np.zeros((8, 3), np.float32)
    V[5, 1] = np.nan
    with pytest.raises(MeshError, match=r"vertex 5"):
        raster.rasterize(V, [[0, 1, 2]], _cam())
    V[5, 1] = np.inf
    with pytest.raises(MeshError, match=r"vertex 5"):
        raster.rasterize(V, [[0, 1, 2]], _cam())


def test_out_of_range_index_is_a_mesh_error_naming_the_triangle():
    V = np.zeros((4, 3), np.float32)
    with pytest.raises(MeshError, match=r"triangle 2"):
        raster.rasterize(V, [[0, 1, 2], [1, 2, 3], [0, 4, 1]], _cam())
    with pytest.raises(MeshError, match=r"triangle 1"):
        raster.rasterize(V, [[0, 1, 2], [-1, 2, 3]], _cam())
    with pytest.raises(MeshError, match=r"shape"):
        raster.rasterize(V, [[0, 1]], _cam())


def test_bad_camera_and_supersample_are_input_errors():
    for kw in (dict(fov=0.0), dict(width=0), dict(target=(0, 0, 0)), dict(up=(0, 0, 2)), dict(near=0.0)):
        with pytest.raises(InputError):
            _cam(**kw)
    with pytest.raises(InputError, match="supersample"):
        raster.rasterize(np.zeros((3, 3)), [[0, 1, 2]], _cam(), supersample=0)
