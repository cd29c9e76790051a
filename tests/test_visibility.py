"""precompute.visibility.rays + the concentric map of precompute.visibility.ssdf_wp."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp
from hypothesis import given, settings
from hypothesis import strategies as st

from precompute.visibility import ssdf_wp
from precompute.visibility.rays import hemisphere_visibility, needs_visibility, ray_visibility
from precompute.visibility.reference_checks import plane_box_scene
from warp_sg.core.errors import InputError, MeshError
from warp_sg.numeric.onb import to_world


@wp.kernel
def _map_kernel(ab: wp.array(dtype=wp.vec2), dirs_out: wp.array(dtype=wp.vec3), ab_out: wp.array(dtype=wp.vec2)):
    k = wp.tid()
    d = ssdf_wp.concentric_to_dir_wp(ab[k][0], ab[k][1])
    dirs_out[k] = d
    ab_out[k] = ssdf_wp.dir_to_concentric_wp(d)


def test_concentric_map_round_trip_numpy():
    rng = np.random.default_rng(0)
    a, b = rng.uniform(-1, 1, (2, 5000))
    d = ssdf_wp.concentric_to_dir(a, b)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-12)
    assert (d[:, 2] >= 0).all()
    a2, b2 = ssdf_wp.dir_to_concentric(d)
    np.testing.assert_allclose(a2, a, atol=1e-9)
    np.testing.assert_allclose(b2, b, atol=1e-9)


def test_concentric_map_is_equal_area():
    """Uniform texels ⇒ uniform directions on the hemisphere: E[z] = 1/2, E[z²] = 1/3."""
    d = ssdf_wp.texel_directions(256).reshape(-1, 3)
    assert d[:, 2].mean() == pytest.approx(0.5, abs=1e-4)
    assert (d[:, 2] ** 2).mean() == pytest.approx(1 / 3, abs=1e-4)


def test_concentric_map_warp_matches_numpy(device):
    rng = np.random.default_rng(1)
    ab = rng.uniform(-1, 1, (2000, 2)).astype(np.float32)
    ab[:4] = [[0, 0], [1, 1], [-1, 0.3], [0.2, -1]]
    dirs = wp.zeros(len(ab), dtype=wp.vec3, device=device)
    back = wp.zeros(len(ab), dtype=wp.vec2, device=device)
    wp.launch(_map_kernel, dim=len(ab), device=device, inputs=[wp.array(ab, dtype=wp.vec2, device=device), dirs, back])
    np.testing.assert_allclose(dirs.numpy(), ssdf_wp.concentric_to_dir(ab[:, 0], ab[:, 1]), atol=2e-6)
    np.testing.assert_allclose(back.numpy(), ab, atol=2e-5)


@wp.kernel
def _to_square_kernel(d: wp.array(dtype=wp.vec3), ab_out: wp.array(dtype=wp.vec2)):
    k = wp.tid()
    ab_out[k] = ssdf_wp.dir_to_concentric_wp(d[k])


def test_direction_to_square_matches_numpy_on_the_whole_sphere(device):
    """Every direction, below the horizon too (clamped to the horizon point of its azimuth), on
    the axes and the region diagonals |x| = |y|, against the numpy map (arctan2 branches)."""
    rng = np.random.default_rng(2)
    d = rng.normal(size=(4000, 3))
    d[:12] = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
              [1, 1, 0.5], [-1, 1, 0.5], [1, -1, -0.5], [-1, -1, 2.0], [1e-9, 0, 1], [0, -1e-9, 1]]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = wp.zeros(len(d), dtype=wp.vec2, device=device)
    wp.launch(_to_square_kernel, dim=len(d), device=device, inputs=[wp.array(d, dtype=wp.vec3, device=device), out])
    a, b = ssdf_wp.dir_to_concentric(d)
    np.testing.assert_allclose(out.numpy(), np.stack([a, b], -1), atol=1e-5)


def _box_hit(o, d, lo, hi):
    """numpy slab test: does the ray o + t d (t > 0) hit the axis-aligned box [lo, hi]?"""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - o) / d
        t2 = (hi - o) / d
    tmin = np.nanmax(np.minimum(t1, t2), axis=-1)
    tmax = np.nanmin(np.maximum(t1, t2), axis=-1)
    return (tmax >= np.maximum(tmin, 0.0))


def test_visibility_matches_analytic_box_occlusion(device):
    V, F, N = plane_box_scene(n=12, size=4.0, box=1.0)
    ids = np.array([13, 40, 50, 70, 100, 130])  # floor vertices around the cube
    R = 24
    vis = hemisphere_visibility(V, F, N, R, device=device, vertex_ids=ids)
    assert vis.shape == (len(ids), R, R) and vis.dtype == np.uint8
    d_loc = ssdf_wp.texel_directions(R)
    for k, vid in enumerate(ids):
        d = to_world(d_loc, np.broadcast_to(N[vid], d_loc.shape))
        o = np.broadcast_to(V[vid], d.shape)
        expect = ~_box_hit(o, d, np.array([-0.5, 0.0, -0.5]), np.array([0.5, 1.0, 0.5]))
        mismatch = (vis[k].astype(bool) != expect).mean()
        assert mismatch < 0.005, (vid, mismatch)  # only grazing rays along cube edges may differ
    # the vertex under the cube sees nothing, a far corner vertex sees almost everything
    center = np.argmin(np.linalg.norm(V[:144], axis=1))
    corner = 0
    v2 = hemisphere_visibility(V, F, N, R, device=device, vertex_ids=[center, corner])
    assert v2[0].sum() == 0
    assert v2[1].mean() > 0.9


def test_ray_visibility_below_horizon_is_invisible(device):
    V, F, N = plane_box_scene(n=6)
    o = np.array([[1.8, 0.0, 1.8]] * 3)
    d = np.array([[0, 1.0, 0], [0, -1.0, 0], [-0.6, 0.2, -0.6]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    vis = ray_visibility(V, F, o, [0, 1.0, 0], d, device=device)
    assert vis.tolist() == [1, 0, 0]


def test_needs_visibility():
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=2)
    assert not needs_visibility(s.vertices, s.faces)
    V, F, _ = plane_box_scene(n=6)
    assert needs_visibility(V, F)
    assert not needs_visibility(V, F, shadows=False)
    two = np.concatenate([s.vertices, s.vertices + [3.0, 0, 0]])
    assert needs_visibility(two, np.concatenate([s.faces, s.faces + len(s.vertices)]))


@settings(max_examples=25, deadline=None)
@given(st.integers(min_value=0, max_value=2**31 - 1), st.integers(min_value=8, max_value=400))
def test_the_quick_convexity_test_never_calls_a_convex_hull_concave(seed, n):
    """``_clearly_not_convex`` (the early exit of ``needs_visibility``) on convex hulls of random
    points (thin slabs among them): never "not convex", and trimesh agrees they are convex."""
    import trimesh

    from precompute.visibility.rays import _clearly_not_convex

    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)) * rng.uniform(0.01, 10.0, size=3)
    hull = trimesh.convex.convex_hull(pts)
    assert not _clearly_not_convex(hull.vertices, hull.faces)
    assert not needs_visibility(hull.vertices, hull.faces)


def test_the_quick_convexity_test_agrees_with_trimesh_where_it_answers():
    """Where the early exit answers (vertices well on both sides of a triangle's plane), trimesh's
    own test says the same: not one convex body (two spheres, a torus, the plane and box). A
    sphere with one vertex dented in has no such plane among the sampled triangles: trimesh's
    test answers."""
    import trimesh

    from precompute.visibility.rays import _clearly_not_convex

    s = trimesh.creation.icosphere(subdivisions=3)
    dented = s.vertices.copy()
    dented[np.argmax(dented[:, 1])] *= 0.8  # the top vertex pushed in by a fifth of the radius
    two = np.concatenate([s.vertices, s.vertices + [3.0, 0, 0]])
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    V, F, _ = plane_box_scene(n=6)
    cases = [(two, np.concatenate([s.faces, s.faces + len(s.vertices)])), (torus.vertices, torus.faces), (V, F)]
    for v, f in cases:
        assert _clearly_not_convex(v, f)
        assert not trimesh.Trimesh(vertices=v, faces=f, process=True).is_convex
        assert needs_visibility(v, f)
    assert not _clearly_not_convex(dented, s.faces) and needs_visibility(dented, s.faces)


def test_bad_meshes_name_the_element():
    V, F, N = plane_box_scene(n=6)
    Vb = V.copy()
    Vb[17, 1] = np.nan
    with pytest.raises(MeshError, match="vertex 17 has a non-finite coordinate"):
        hemisphere_visibility(Vb, F, N, 8)
    Fb = F.copy()
    Fb[5, 2] = 900
    oob = rf"triangle 5 references vertex \[.*900\] out of range \(the mesh has {len(V)} vertices\)"
    with pytest.raises(MeshError, match=oob):
        needs_visibility(V, Fb)
    Nb = N.copy()
    Nb[3] = 0
    with pytest.raises(MeshError, match="vertex 3 has a zero-length normal"):
        hemisphere_visibility(V, F, Nb, 8)
    with pytest.raises(InputError, match="resolution"):
        hemisphere_visibility(V, F, N, 1)


def test_empty_meshes_are_mesh_errors():
    with pytest.raises(MeshError, match="no vertices"):
        needs_visibility(np.zeros((0, 3)), np.zeros((0, 3), int))
    with pytest.raises(MeshError, match="no triangles"):
        hemisphere_visibility(np.zeros((3, 3)), np.zeros((0, 3), int), np.tile([0, 0, 1.0], (3, 1)), 8)
