"""Rasterizer vs wp.Mesh ray casting, watertightness and camera conventions."""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
import warp as wp

import raster
from raster.reference_checks import raycast_visibility, torus_mesh, uv_sphere


def _cam(w=96, h=72, origin=(0.0, 1.2, 3.0), target=(0.0, 0.0, 0.0), fov=40.0, **kw):
    return raster.Camera(origin=origin, target=target, up=(0.0, 1.0, 0.0), fov=fov, width=w, height=h, **kw)


def _compare(V, F, cam, device, supersample=1, min_agree=0.999, **kw):
    vb = raster.rasterize(V, F, cam, device=device, supersample=supersample, **kw)
    rt, rb, rd = vb.tri_id.numpy(), vb.bary.numpy(), vb.depth.numpy()
    ct, cb, cd = raycast_visibility(V, F, cam, device=device, supersample=supersample)
    assert rt.shape == (cam.height * supersample, cam.width * supersample)
    assert rb.shape == rt.shape + (2,)
    agree = (rt == ct).mean()
    assert agree >= min_agree, f"tri_id agreement {agree:.5f}"
    both = (rt == ct) & (rt >= 0)
    assert both.sum() > 0.2 * rt.size
    assert np.abs(rd[both] - cd[both]).max() <= 1e-4 * cd[both].max()
    assert np.abs(rb[both] - cb[both]).max() < 2e-3
    assert np.all(np.isfinite(rb)) and not np.isnan(rd).any()
    assert np.all(rd[rt < 0] == np.inf)
    return vb, (rt, rb, rd), (ct, cb, cd)


def test_sphere_matches_raycast_tri_id_depth_bary(device):
    V, F = uv_sphere(64, 32, radius=1.0)
    _compare(V, F, _cam(), device)


def test_torus_matches_raycast_with_self_occlusion(device):
    V, F = torus_mesh(96, 48)
    _compare(V, F, _cam(w=120, h=90, origin=(0.3, 1.0, 2.4)), device)


def test_trimesh_ply_icosphere_matches_raycast(tmp_path, device):
    path = tmp_path / "ico.ply"
    trimesh.creation.icosphere(subdivisions=4, radius=0.8).export(path)
    m = trimesh.load(path, process=False)
    V, F = np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int32)
    assert F.shape == (5120, 3)
    _compare(V, F, _cam(w=80, h=80, origin=(1.5, 0.7, 1.9)), device)


def test_supersampled_buffers_are_k_times_larger_and_match_raycast(device):
    V, F = uv_sphere(48, 24, radius=1.0)
    vb, *_ = _compare(V, F, _cam(w=40, h=30), device, supersample=3)
    assert vb.tri_id.shape == (90, 120) and vb.supersample == 3


def test_camera_rays_pass_through_projected_pixel_centres():
    cam = _cam(w=64, h=48, origin=(0.4, 1.1, 2.7), target=(0.1, -0.2, 0.0), fov=55.0)
    d = cam.ray_directions().astype(np.float64)
    o = cam.ray_origins()
    assert o.shape == d.shape == (48, 64, 3) and np.allclose(o, cam.origin)
    assert np.allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-6)
    pts = np.asarray(cam.origin) + 2.5 * d
    clip = np.c_[pts.reshape(-1, 3), np.ones(pts.size // 3)] @ cam.view_projection().T
    X = (clip[:, 0] / clip[:, 3] + 1) * 0.5 * cam.width
    Y = (1 - clip[:, 1] / clip[:, 3]) * 0.5 * cam.height
    yy, xx = np.mgrid[0:48, 0:64]
    assert np.abs(X - (xx.ravel() + 0.5)).max() < 2e-5
    assert np.abs(Y - (yy.ravel() + 0.5)).max() < 2e-5
    # w = distance along the view axis; row 0 is the top (+Y up)
    assert np.allclose(clip[:, 3], 2.5 * (d.reshape(-1, 3) @ cam.forward()), rtol=1e-6)
    assert d[0, 32, 1] > d[-1, 32, 1]
    # Mitsuba look_at: +x of the image is right = forward x up
    assert np.dot(d[24, -1] - d[24, 0], np.cross(cam.forward(), [0, 1, 0])) > 0


def _jittered_grid(n, half, z, seed=0, jitter=0.35):
    rng = np.random.default_rng(seed)
    xs = np.linspace(-half, half, n + 1)
    X, Y = np.meshgrid(xs, xs, indexing="xy")
    h = xs[1] - xs[0]
    J = rng.uniform(-jitter, jitter, size=X.shape + (2,)) * h
    J[0, :] = J[-1, :] = J[:, 0] = J[:, -1] = 0.0
    V = np.stack([X + J[..., 0], Y + J[..., 1], np.full_like(X, z)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = i * (n + 1) + j
    b, c, d = a + 1, a + n + 2, a + n + 1
    flip = rng.random(a.shape) < 0.5  # random diagonals
    t1 = np.where(flip[..., None], np.stack([a, b, c], -1), np.stack([a, b, d], -1))
    t2 = np.where(flip[..., None], np.stack([a, c, d], -1), np.stack([b, c, d], -1))
    return V.astype(np.float32), np.concatenate([t1.reshape(-1, 3), t2.reshape(-1, 3)]).astype(np.int32)


def test_screen_filling_jittered_grid_covers_every_pixel_exactly_once(device):
    V, F = _jittered_grid(60, 2.0, -1.0)
    cam = raster.Camera(origin=(0, 0, 1), target=(0, 0, 0), up=(0, 1, 0), fov=60, width=97, height=83)
    vb = raster.rasterize(V, F, cam, device=device, coverage_count=True)
    cov = vb.coverage.numpy()
    assert cov.shape == (83, 97)
    assert cov.min() == 1 and cov.max() == 1
    assert (vb.tri_id.numpy() >= 0).all()


def test_grid_with_vertices_on_pixel_centres_is_watertight(device):
    # vertices project exactly onto pixel centres and edges run through rows of sample points,
    # so the top-left rule decides every shared edge and vertex
    cam = raster.Camera(origin=(0, 0, 0), target=(0, 0, -1), up=(0, 1, 0), fov=90, width=64, height=64)
    n = 17
    px = np.arange(n + 1) * 4 + 0.5 - 2  # pixel-centre coordinates, beyond the image at both ends
    ndc = (px / 32.0) - 1.0
    X, Y = np.meshgrid(ndc * 2.0, -ndc * 2.0, indexing="xy")  # tan(45°)=1, plane at z=-2
    V = np.stack([X, Y, np.full_like(X, -2.0)], -1).reshape(-1, 3).astype(np.float32)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = i * (n + 1) + j
    F = np.concatenate([np.stack([a, a + n + 1, a + n + 2], -1).reshape(-1, 3),
                        np.stack([a, a + n + 2, a + 1], -1).reshape(-1, 3)]).astype(np.int32)
    vb = raster.rasterize(V, F, cam, device=device, coverage_count=True)
    cov = vb.coverage.numpy()
    assert cov.min() == 1 and cov.max() == 1


def test_floor_crossing_near_plane_is_covered_once_and_matches_raycast(device):
    V, F = _jittered_grid(40, 50.0, 0.0, seed=3, jitter=0.3)
    V = V[:, [0, 2, 1]].copy()  # floor y = 0 spanning under and behind the camera
    F = F[:, [0, 2, 1]].copy()
    cam = _cam(w=80, h=60, origin=(0.3, 0.5, 0.2), target=(0.3, 0.2, -3.0), fov=70)
    vb = raster.rasterize(V, F, cam, device=device, coverage_count=True)
    ct, _, _ = raycast_visibility(V, F, cam, device=device)
    cov = vb.coverage.numpy()
    assert cov.max() == 1
    assert ((cov == 1) == (ct >= 0)).mean() > 0.999
    _compare(V, F, cam, device)


def test_closed_mesh_seen_from_inside_has_no_holes(device):
    m = trimesh.creation.icosphere(subdivisions=3, radius=2.0)
    V, F = np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int32)
    cam = _cam(w=90, h=70, origin=(0.2, 0.3, -0.1), target=(1.0, -0.5, -2.0), fov=100)
    vb = raster.rasterize(V, F, cam, device=device, coverage_count=True)
    assert (vb.tri_id.numpy() >= 0).all()
    assert (vb.coverage.numpy() == 1).all()
    _compare(V, F, cam, device)


def test_backface_culling_keeps_outside_view_and_empties_inside_view(device):
    V, F = uv_sphere(48, 24)
    cam = _cam(w=64, h=48)
    a = raster.rasterize(V, F, cam, device=device).tri_id.numpy()
    b = raster.rasterize(V, F, cam, device=device, cull_backfaces=True).tri_id.numpy()
    assert (a >= 0).sum() > 500 and (a == b).all()
    inside = _cam(w=32, h=32, origin=(0.0, 0.1, 0.0), target=(0.0, 0.0, -1.0))
    assert (raster.rasterize(V, F, inside, device=device, cull_backfaces=True).tri_id.numpy() == -1).all()
    assert (raster.rasterize(V, F, inside, device=device).tri_id.numpy() >= 0).all()


def test_per_triangle_culling_drops_only_the_flagged_back_faces(device):
    """``cull_backfaces`` as one flag per triangle: seen from inside the sphere every face is a back
    face and each ray meets one; the pixels of flagged triangles see nothing, the others are as
    drawn without culling. A wrong count is an input error."""
    from warp_sg.core.errors import InputError

    V, F = uv_sphere(48, 24)
    inside = _cam(w=32, h=32, origin=(0.0, 0.1, 0.0), target=(0.0, 0.0, -1.0))
    full = raster.rasterize(V, F, inside, device=device).tri_id.numpy()
    flags = (np.arange(len(F)) % 2).astype(np.uint8)
    for given in (flags, wp.array(flags, dtype=wp.uint8, device=device)):
        got = raster.rasterize(V, F, inside, device=device, cull_backfaces=given).tri_id.numpy()
        kept = flags[full] == 0
        assert kept.sum() > 100 and (got[kept] == full[kept]).all()
        assert (got[~kept] == -1).all()
    with pytest.raises(InputError, match="cull_backfaces"):
        raster.rasterize(V, F, inside, device=device, cull_backfaces=flags[:-1])


def test_interpolated_positions_equal_raycast_hit_points(device):
    V, F = torus_mesh(64, 32)
    cam = _cam(w=64, h=48, origin=(0.0, 2.0, 2.0))
    vb = raster.rasterize(V, F, cam, device=device)
    P = raster.interpolate(vb, F, V).numpy()
    assert P.shape == (48, 64, 3)
    t = vb.tri_id.numpy()
    # hit points of the camera rays from an independent wp.Mesh ray cast (its own depth along the view axis)
    ct, _, cd = raycast_visibility(V, F, cam, device=device)
    d = cam.ray_directions().astype(np.float64)
    hit = np.asarray(cam.origin) + d * (cd / (d @ cam.forward()))[..., None]
    m = (t >= 0) & (t == ct)
    assert m.sum() > 300 and m.sum() >= 0.999 * (t >= 0).sum()
    assert np.abs(P[m] - hit[m]).max() < 1e-3
    assert (P[~(t >= 0)] == 0).all()
    # a scalar attribute (N,): an affine function of position interpolates to its value at the hit point
    a, c = np.array([0.7, -1.3, 2.1]), 0.25
    s = raster.interpolate(vb, F, (V @ a + c).astype(np.float32)).numpy()
    assert s.shape == (48, 64, 1)
    np.testing.assert_allclose(s[m, 0], hit[m] @ a + c, atol=3e-3)
    assert np.ptp(s[m, 0]) > 1.0  # the attribute varies over the image


def test_small_queue_budget_gives_identical_buffers_in_several_passes(device):
    V, F = torus_mesh(64, 32)
    cam = _cam(w=64, h=64)
    a = raster.rasterize(V, F, cam, device=device)
    b = raster.rasterize(V, F, cam, device=device, max_pairs=500)
    assert b.stats["passes"] > 2 and a.stats["passes"] == 1
    assert (a.tri_id.numpy() == b.tri_id.numpy()).all()
    assert np.array_equal(a.depth.numpy(), b.depth.numpy())


def _near_plane_quad():
    """A ground quad that passes under and behind the camera: clipped at the near plane."""
    V = np.array([[-6.0, -0.6, -6.0], [6.0, -0.6, -6.0], [6.0, -0.6, 8.0], [-6.0, -0.6, 8.0]], np.float32)
    return V, np.array([[0, 2, 1], [0, 3, 2]], np.int32)


@pytest.mark.parametrize("a", [2, 3, 4, 8])
def test_subsamples_of_listed_pixels_match_a_raster_of_the_finer_grid(device, a):
    """``raster.subsample`` on a 1× raster kept with ``subsamples=a`` against the full a× raster
    (itself checked against ray casting above) at a shuffled third of the pixels: a fine torus whose
    triangles mostly miss every pixel centre (kept for their sub-samples) over a ground quad clipped
    at the near plane. The vertices are snapped to 1/256 of a pixel instead of a sub-pixel, so a
    few sub-samples on shared edges may go to the neighbour; nothing else differs. The 1× buffer
    itself is bit-identical to an ordinary raster."""
    from raster.subsample import subsample

    Vt, Ft = torus_mesh(192, 96)
    Vq, Fq = _near_plane_quad()
    V = np.concatenate([Vt, Vq])
    F = np.concatenate([Ft, Fq + len(Vt)])
    cam = _cam(w=40, h=30, origin=(0.2, 0.9, 2.2), near=0.3)
    one = raster.rasterize(V, F, cam, device=device, subsamples=a)
    plain = raster.rasterize(V, F, cam, device=device)
    assert np.array_equal(one.tri_id.numpy(), plain.tri_id.numpy())
    assert np.array_equal(one.bary.numpy(), plain.bary.numpy())
    assert one.stats["passes"] == 1 and one.stats["clipped_extra"] > 0
    full = raster.rasterize(V, F, cam, device=device, supersample=a)
    H, W = cam.height, cam.width
    rng = np.random.default_rng(a)
    pix = rng.permutation(H * W)[: H * W // 3].astype(np.int32)
    tri, bary, invw, _ = subsample(one, wp.array(pix, dtype=int, device=device))
    tri, bary, invw = tri.numpy(), bary.numpy(), invw.numpy()
    y, x = pix // W, pix % W
    q = np.arange(a * a)
    rows, cols = y[:, None] * a + q[None] // a, x[:, None] * a + q[None] % a
    ref_t, ref_b = full.tri_id.numpy()[rows, cols], full.bary.numpy()[rows, cols]
    ref_w = full.inv_depth.numpy()[rows, cols]
    same = tri == ref_t
    assert (ref_t >= len(Ft)).any() and (ref_t < 0).any() and (ref_t[ref_t >= 0] < len(Ft)).mean() > 0.3
    assert (~same).mean() < 0.01, f"{(~same).sum()} of {same.size} sub-samples differ"
    d = ~same & (tri >= 0) & (ref_t >= 0)  # a sample on an edge or at a vertex the two triangles share
    shared = [len(set(F[t1]) & set(F[t2])) for t1, t2 in zip(tri[d], ref_t[d])]
    assert all(n >= 1 for n in shared) and np.mean(np.equal(shared, 2)) > 0.8, shared
    assert ((tri < 0) != (ref_t < 0)).mean() < 1e-3  # no holes from dropped sub-pixel triangles
    hit = same & (tri >= 0)
    assert np.abs(bary[hit] - ref_b[hit]).max() < 1e-4
    assert np.abs(invw[hit] - ref_w[hit]).max() <= 1e-5 * ref_w[hit].max()
    assert (invw[tri < 0] == 0).all() and (bary[tri < 0] == 0).all()


def test_subsamples_where_nothing_is_drawn_are_empty(device):
    from raster.subsample import subsample

    V, F = uv_sphere(16, 8, radius=0.5)
    cam = _cam(w=20, h=16, target=(0.0, 1.2, 9.0))  # looking away
    one = raster.rasterize(V, F, cam, device=device, subsamples=4)
    tri, bary, invw, _ = subsample(one, wp.array(np.arange(0, 320, 7, dtype=np.int32), dtype=int, device=device))
    assert tri.shape == (46, 16) and (tri.numpy() == -1).all() and (invw.numpy() == 0).all()
    with pytest.raises(ValueError, match="subsamples"):
        subsample(raster.rasterize(V, F, cam, device=device), wp.zeros(1, dtype=int, device=device))
    from warp_sg.core.errors import InputError

    for bad in (0, 17, 2.5):
        with pytest.raises(InputError, match="subsamples"):
            raster.rasterize(V, F, cam, device=device, subsamples=bad)


def test_tile_and_pixel_schedules_agree_and_are_deterministic(device):
    V, F = _jittered_grid(30, 1.0, -1.0, seed=5)
    V2, F2 = torus_mesh(48, 24)
    V = np.concatenate([V, V2])
    F = np.concatenate([F, F2 + len(_jittered_grid(30, 1.0, -1.0, seed=5)[0])])
    cam = _cam(w=70, h=50)
    a = raster.rasterize(V, F, cam, device=device, schedule="tile", coverage_count=True)
    b = raster.rasterize(V, F, cam, device=device, schedule="pixel", coverage_count=True)
    c = raster.rasterize(V, F, cam, device=device, schedule="tile", coverage_count=True)
    for x, y in ((a, b), (a, c)):
        assert (x.tri_id.numpy() == y.tri_id.numpy()).all()
        assert np.array_equal(x.bary.numpy(), y.bary.numpy())
        assert (x.coverage.numpy() == y.coverage.numpy()).all()


def test_camera_fov_and_aspect_follow_mitsuba_vertical_fov():
    cam = _cam(w=200, h=100, fov=60.0)
    d = cam.ray_directions().astype(np.float64)
    f = cam.forward()
    # top edge of the image (not pixel centre) is at fov/2 from the axis: centre row 0 slightly inside
    top = math.degrees(math.acos(np.clip(d[0, 100] @ f, -1, 1)))
    assert 29.0 < top < 30.0
    P = cam.projection_matrix()
    assert np.isclose(P[1, 1], 1 / math.tan(math.radians(30))) and np.isclose(P[0, 0], P[1, 1] / 2)


def test_quick_benchmark_runs_and_its_buffers_agree_with_ray_casting():
    # correctness only: speed claims are measured by `warp-sg bench`, not asserted in unit tests
    from warp_sg.tools.bench_raster import format_rows, run_bench

    rows = run_bench(device="cpu", quick=True)
    assert len(rows) == 1
    r = rows[0]
    assert r["triangles"] > 90_000 and (r["width"], r["height"]) == (512, 512)
    assert r["tri_id_agreement"] >= 0.999
    assert "speedup" in format_rows(rows)


def test_warp_array_inputs_and_flat_indices_give_the_same_buffer(device):
    import warp as wp

    V, F = uv_sphere(32, 16)
    cam = _cam(w=48, h=40)
    a = raster.rasterize(V, F, cam, device=device)
    b = raster.rasterize(wp.array(V, dtype=wp.vec3, device=device), wp.array(F.reshape(-1), dtype=wp.int32,
                                                                               device=device), cam, device=device)
    assert (a.tri_id.numpy() == b.tri_id.numpy()).all()
    assert np.array_equal(a.bary.numpy(), b.bary.numpy())
    n = raster.interpolate(b, F, wp.array(V, dtype=wp.vec3, device=device)).numpy()
    assert n.shape == (40, 48, 3) and np.isfinite(n).all()


@wp.kernel(enable_backward=False)
def _stamp_kernel(base: int, per: int, n: int, hits: wp.array(dtype=int)):
    for s in range(per):
        i = base + wp.tid() * per + s
        if i < n:
            hits[i] = hits[i] + 1


@pytest.mark.parametrize("n,per,chunks", [(1, 16, None), (1000, 16, None), (1001, 7, 3), (4096, 16, 8), (37, 1, 5),
                                          (5000, 64, 1)])
def test_a_launch_with_several_elements_per_thread_touches_every_element_exactly_once(n, per, chunks):
    """``parallel.launch(per_thread=...)``: the thread ranges of every chunk tile 0..n-1 exactly
    (a kernel that increments its elements finds each at 1)."""
    from raster import parallel

    hits = wp.zeros(n, dtype=int)
    parallel.launch(_stamp_kernel, n, [n, hits], "cpu", chunks=chunks, min_chunk=1, per_thread=per)
    assert (hits.numpy() == 1).all()


def test_a_launch_from_a_pool_thread_completes_and_touches_every_element_once():
    """The calling thread shares the ranges with the pool (``parallel._run_ranges``): a launch made
    from inside a pool thread (every pool thread busy) still finishes, by itself, instead of
    waiting on helpers that cannot start; plain and per-row launches cover every element once."""
    from raster import parallel

    n = 5000
    hits = wp.zeros(n, dtype=int)

    def nested():
        parallel.launch(_stamp_kernel, n, [1, n, hits], "cpu", chunks=8, min_chunk=1)

    parallel._pool().submit(nested).result(timeout=60)
    assert (hits.numpy() == 1).all()
    rows = wp.zeros(n, dtype=int)
    parallel.launch_rows(_stamp_kernel, n, 7, [1, n, rows], "cpu")
    assert (rows.numpy() == 1).all()
