"""SSDFs at representative vertices (precompute.visibility.representatives).

Checked against independent references: pairwise angles and distances of the clusters' members
(brute force), the centroid's nearest vertex (brute force), a closed-form SSDF (a half-space of
occluded directions) transferred between frames, and each vertex's own 256² ray-cast map on a
scene with a sharp shadow boundary.
"""
import math

import numpy as np
import pytest

from precompute.visibility import representatives as RP
from precompute.visibility import ssdf as S
from precompute.visibility.reference_checks import plane_box_scene
from precompute.visibility.ssdf_wp import texel_directions
from warp_sg.numeric.onb import frame_from_normal


def _members(cluster):
    """All pairs (i, j), i < j, of vertices of the same cluster (brute force over sorted groups)."""
    order = np.argsort(cluster, kind="stable")
    c = cluster[order]
    starts = np.r_[0, np.flatnonzero(np.diff(c)) + 1]
    sizes = np.diff(np.r_[starts, len(c)])
    gi = np.repeat(np.arange(len(starts)), sizes * sizes)
    off = np.concatenate([np.arange(s * s) for s in sizes])
    sz = sizes[gi]
    i = order[starts[gi] + off // sz]
    j = order[starts[gi] + off % sz]
    keep = i < j
    return i[keep], j[keep]


def _cloud(n=6000, seed=0):
    """A sphere with noisy normals plus a thin plate whose two sides are 1e-3 apart."""
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    nrm = p + 0.3 * rng.normal(size=p.shape)
    q = rng.random((n // 2, 2)) * 2 - 1
    top = np.c_[q[:, 0], np.full(len(q), 1.5), q[:, 1]]
    bot = top - [0, 1e-3, 0]
    pts = np.concatenate([p, top, bot])
    nn = np.concatenate([nrm, np.tile([0, 1.0, 0], (len(q), 1)), np.tile([0, -1.0, 0], (len(q), 1))])
    return pts, nn / np.linalg.norm(nn, axis=1, keepdims=True)


@pytest.mark.parametrize("angle", [20.0, 35.0])
def test_clusters_respect_normal_angle_and_cell(angle):
    pts, nn = _cloud()
    budget = 800
    cl = RP.cluster_vertices(pts, nn, budget, angle)
    assert 0.5 * budget < cl.count <= budget
    i, j = _members(cl.cluster)
    assert len(i) > 10 * len(pts)  # clusters do merge
    cos = np.sum(nn[i] * nn[j], 1)
    assert np.degrees(np.arccos(np.clip(cos.min(), -1, 1))) <= angle + 1e-9
    assert np.linalg.norm(pts[i] - pts[j], axis=1).max() <= math.sqrt(3) * cl.cell + 1e-12
    # the thin plate's two sides never share a cluster
    assert not np.any((nn[i, 1] > 0.99) & (nn[j, 1] < -0.99))
    # representative: a member, the one nearest its cluster's centroid (brute force on a few)
    assert np.array_equal(cl.cluster[cl.reps], np.arange(cl.count))
    for k in range(0, cl.count, max(cl.count // 25, 1)):
        m = np.flatnonzero(cl.cluster == k)
        d = np.linalg.norm(pts[m] - pts[m].mean(0), axis=1)
        assert d[m == cl.reps[k]][0] <= d.min() + 1e-12
    again = RP.cluster_vertices(pts, nn, budget, angle)
    assert np.array_equal(again.cluster, cl.cluster) and np.array_equal(again.reps, cl.reps)


def _cap_sample(axis, radius_deg, n, rng):
    """``n`` unit vectors uniform in the cap of angular radius ``radius_deg`` about ``axis``."""
    from warp_sg.numeric.onb import frame_from_normal

    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    z = 1.0 - rng.random(n) * (1.0 - math.cos(math.radians(radius_deg)))
    phi = rng.random(n) * 2 * math.pi
    r = np.sqrt(1 - z * z)
    t, b = frame_from_normal(a[None])
    return (r * np.cos(phi))[:, None] * t + (r * np.sin(phi))[:, None] * b + z[:, None] * a[None]


def test_normal_caps_of_a_full_sphere_in_one_cell():
    """20 000 normals over the whole sphere in one cell: every pair of a cluster within 20° (brute
    force), and the clusters fewer than 0.7× the 6·8² = 384 bins of a 20° cube map, yet at least
    the sphere's area over a 10°-radius cap's (each cluster lies in one)."""
    rng = np.random.default_rng(1)
    n = rng.normal(size=(20000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    cl, k = RP.normal_caps(np.zeros(len(n), np.int64), n, 20.0)
    assert np.array_equal(np.unique(cl), np.arange(k))
    i, j = _members(cl)
    assert np.degrees(np.arccos(np.clip(np.sum(n[i] * n[j], 1).min(), -1, 1))) <= 20.0 + 1e-9
    cap = 2 * math.pi * (1 - math.cos(math.radians(10.0)))
    assert 4 * math.pi / cap <= k < 0.7 * 384, k


def test_a_narrow_cone_of_normals_is_one_cluster_in_any_orientation():
    """A cell's normals within 7° of one direction — about a cube-map face's centre, an edge's
    middle or a corner, where fixed bins split them — are one cluster; two such groups 60° apart
    in one cell are two; the same normals in two cells are two clusters each."""
    rng = np.random.default_rng(2)
    for axis in ([0, 0, 1.0], [1, 1, 0.1], [1, 1, 1.0], [-1, 0.02, -1]):
        n = _cap_sample(axis, 7.0, 500, rng)
        cl, k = RP.normal_caps(np.zeros(len(n), np.int64), n, 20.0)
        assert k == 1, (axis, k)
    a = _cap_sample([0, 0, 1.0], 7.0, 400, rng)
    b = _cap_sample([math.sin(math.radians(60)), 0, math.cos(math.radians(60))], 7.0, 400, rng)
    n = np.concatenate([a, b])
    mix = rng.permutation(len(n))
    cl, k = RP.normal_caps(np.zeros(len(n), np.int64), n[mix], 20.0)
    assert k == 2 and len(np.unique(cl[np.argsort(mix)][:400])) == 1
    cl, k = RP.normal_caps(np.tile([9, 5], 400), n, 20.0)  # (each cell: half of each group)
    assert k == 4 and len(np.unique(cl[:400])) == 2 and not set(cl[:400]) & set(cl[400:])


def test_transfer_of_a_half_space_matches_closed_form():
    """Occluded: the world directions with d·w < 0 (a plane through the vertex). The SSDF of
    such a set is ``min(asin(d·w), asin(d·n))`` at visible directions, ``asin(d·w)`` (< 0) at
    occluded ones; transferred from a normal 12° away it must match the closed form in the new
    frame except in the band between the two horizons."""
    R = 32
    w = np.array([0.6, 0.0, 0.8])
    nr = np.array([0.0, 0.0, 1.0])
    rot = math.radians(12.0)
    nv = np.array([math.sin(rot), 0.3 * math.sin(rot), math.cos(rot)])
    nv /= np.linalg.norm(nv)
    D = texel_directions(R).reshape(-1, 3)

    def closed(n):
        t, b = frame_from_normal(n[None])
        d = D[:, :1] * t + D[:, 1:2] * b + D[:, 2:3] * n[None]
        sw = np.arcsin(np.clip(d @ w, -1, 1))
        return np.where(sw >= 0, np.minimum(sw, np.arcsin(D[:, 2])), sw)

    out = RP.transfer_maps(closed(nr)[None].astype(np.float32), nr[None], [0], nv[None], R)[0]
    want = closed(nv)
    t, b = frame_from_normal(nv[None])
    dw = D[:, :1] * t + D[:, 1:2] * b + D[:, 2:3] * nv[None]
    h = math.sqrt(2 * math.pi) / R  # a texel side: the bilinear read's error scale
    e_r = np.arcsin(np.clip(dw @ nr, -1, 1))
    # away from the representative's horizon, and from where its horizon and the plane are equally near
    away = (e_r > math.radians(6.0)) & (np.abs(np.arcsin(np.clip(dw @ w, -1, 1)) - e_r) > 2.5 * h)
    assert away.sum() > 0.6 * len(D)
    err = np.abs(out - want)[away]
    assert err.max() < 0.25 * h and err.mean() < 0.02 * h, (err.max() / h, err.mean() / h)
    # the same normal: the map itself (bilinear reads at the texel centres)
    same = RP.transfer_maps(closed(nr)[None].astype(np.float32), nr[None], [0], nr[None], R)[0]
    assert np.abs(same - closed(nr)).max() < 1e-5


def test_mesh_within_budget_is_unchanged():
    V, F, N = plane_box_scene(20)  # 408 vertices
    a = S.ssdf_for_mesh(V, F, N, use_cache=False, progress=False, representatives=0)
    b = S.ssdf_for_mesh(V, F, N, use_cache=False, progress=False, representatives=len(V))
    assert a.key == b.key == S.ssdf_key(V, F, N) and len(b.representative) == 0
    for k in ("mean", "basis", "weights", "cones", "pca_rms_error"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    c = S.ssdf_for_mesh(V, F, N, use_cache=False, progress=False, representatives=len(V) - 1)
    assert c.key != a.key and len(c.representative) == len(V)


def test_representatives_error_at_other_vertices_is_bounded():
    """Plane and box (a sharp shadow boundary on the floor around the box): the SSDFs of vertices
    that are not representatives (6.4 k vertices, at most 1000 representatives) against their own
    256² ray-cast maps, next to the error of their own 64²-ray maps (both PCA-compressed). Measured
    2026-12-02 with the probe: own 0.0159 / representatives 0.0174 rad near the box, 0.0170 / 0.0206
    at random vertices (the vertex nearest the centroid, distance weights: 0.0173 and 0.0191)."""
    from warp_sg.tools.bench_precompute import _near_box_floor_ids, ssdf_error

    V, F, N = plane_box_scene(80)
    own = S.ssdf_for_mesh(V, F, N, use_cache=False, progress=False, representatives=0)
    rep = S.ssdf_for_mesh(V, F, N, use_cache=False, progress=False, representatives=1000)
    reps = np.unique(rep.representative)
    assert len(reps) <= 1000 and rep.stats["representatives"] == len(reps)
    isrep = np.zeros(len(V), bool)
    isrep[reps] = True
    ring = _near_box_floor_ids(V, count=300)
    ring = ring[~isrep[ring]][:32]
    rnd = np.sort(np.random.default_rng(3).choice(np.flatnonzero(~isrep), 32, replace=False))
    for ids, bound in ((ring, 0.022), (rnd, 0.022)):
        truth = S.compute_ssdf(V, F, N, resolution=256, ray_resolution=256, vertex_ids=ids, progress=False,
                               rays="full")
        k = np.arange(len(ids))
        e_own = ssdf_error(V, F, N, k, own.reconstruct(ids), truth)
        e_rep = ssdf_error(V, F, N, k, rep.reconstruct(ids), truth)
        assert e_rep < bound and e_rep < 1.25 * e_own, (e_rep, e_own)


def test_blend_rows_kernel_matches_numpy():
    import warp as wp

    from raster import parallel
    from warp_sg.shading.vertex_visibility import blend_rows_kernel

    rng = np.random.default_rng(5)
    V, k, J = 500, 6, 7
    reps = np.sort(rng.choice(V, 60, replace=False))
    isrep = np.zeros(V, bool)
    isrep[reps] = True
    idx = np.repeat(np.arange(V)[:, None], k, 1).astype(np.int32)
    w = np.zeros((V, k), np.float32)
    w[:, 0] = 1
    o = np.flatnonzero(~isrep)
    idx[o] = rng.choice(reps, (len(o), k))
    w[o] = rng.random((len(o), k))
    w[o] /= w[o].sum(1, keepdims=True)
    rows = np.zeros((V, J), np.float32)
    rows[reps] = rng.random((len(reps), J))
    want = rows.copy()
    want[o] = np.einsum("ik,ikj->ij", w[o], rows[idx[o]])
    a = wp.array(rows, dtype=float, device="cpu")
    parallel.launch(blend_rows_kernel, V, [wp.array(idx, dtype=int, device="cpu"), wp.array(w, dtype=float, device="cpu"),
                                           a], "cpu", min_chunk=64)
    np.testing.assert_allclose(a.numpy(), want, rtol=1e-5, atol=1e-6)


def _budget_scene(budget):
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import EnvironmentLight
    from warp_sg.scene.model import Material, Scene, SceneObject
    from warp_sg.scene.render_settings import RenderSettings

    cam = Camera(origin=(0.0, 1.6, 2.6), target=(0.0, 0.25, 0.0), fov=45.0, width=24, height=20)
    objects = [SceneObject(material="m", primitive="sphere", params={"radius": 0.4, "resolution": (12, 24),
                                                                      "center": (0.0, 0.42, 0.0)}),
               SceneObject(material="m", primitive="plane", params={"size": (3.0, 3.0), "resolution": (20, 20)})]
    rs = RenderSettings(shadows=True, ssdf_resolution=16, pca_terms=8, visibility_budget=budget, env_lobes=2,
                        env_peaks=0, antialias=1)
    env = EnvironmentLight(procedural="sky", options={"width": 32, "height": 16})
    return Scene(camera=cam, objects=objects, materials={"m": Material("lambert", {"kd": [0.5, 0.5, 0.5]})},
                 lights=[env], render=rs)


def test_visibility_budget_is_the_representatives_budget():
    """``[render] visibility_budget`` of a mesh with more vertices (no refinement) is the number of
    representatives; a mesh within it keeps the key and the maps of every vertex's own (bit for
    bit); the renderer's ``precomputed`` check follows the budget."""
    from warp_sg.core.errors import InputError
    from warp_sg.renderer.renderer import Renderer

    own = Renderer(_budget_scene(0), device="cpu")
    g = own.geometry
    n = len(g.vertices)
    assert len(own.ssdf.representative) == 0
    within = Renderer(_budget_scene(n), device="cpu")
    assert within.ssdf.key == own.ssdf.key == S.ssdf_key(g.vertices, g.triangles, g.normals, resolution=16,
                                                          pca_terms=8, representatives=0)
    for k in ("mean", "basis", "weights", "cones", "pca_rms_error"):
        assert np.array_equal(getattr(within.ssdf, k), getattr(own.ssdf, k)), k
    budget = n // 3
    over = Renderer(_budget_scene(budget), device="cpu")
    reps = np.unique(over.ssdf.representative)
    assert len(over.ssdf.representative) == n and budget // 2 < len(reps) <= budget
    assert over.ssdf.key == S.ssdf_key(g.vertices, g.triangles, g.normals, resolution=16, pca_terms=8,
                                       representatives=budget) != own.ssdf.key
    again = Renderer(_budget_scene(budget), device="cpu", precomputed=over.precomputed())
    assert again.ssdf is over.ssdf or again.ssdf.key == over.ssdf.key
    with pytest.raises(InputError):
        Renderer(_budget_scene(n), device="cpu", precomputed=over.precomputed())


def _grid(n, half, y):
    """An ``n × n`` grid over ``[−half, half]²`` at height ``y``, normals +y."""
    g = np.linspace(-half, half, n)
    X, Z = np.meshgrid(g, g, indexing="ij")
    V = np.stack([X.ravel(), np.full(X.size, y), Z.ravel()], -1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return V, np.concatenate([np.stack([a, d, c], -1), np.stack([a, c, b], -1)]), np.tile([0.0, 1.0, 0.0], (len(V), 1))


def _panel_over_detail():
    """An open panel (9², 1 m square at y = 0.05) over a denser layer (33², 2 m square at y = 0):
    the layer is occluded under the panel and open beyond it; one cell of either holds both, with
    the same normals (a body panel over the detail behind it)."""
    V1, F1, N1 = _grid(9, 0.5, 0.05)
    V2, F2, N2 = _grid(33, 1.0, 0.0)
    return np.concatenate([V1, V2]), np.concatenate([F1, F2 + len(V1)]), np.concatenate([N1, N2])


def test_probe_open_fraction_matches_a_ray_cast():
    """The 16-ray probe against the open fraction of a 64² ray-cast map (the plane and box; the
    panel over the detail, whose identical frames put every vertex's 16 rays at the same angles to
    the panel's edges): within 0.02 on average, and per vertex within the strata's error."""
    from precompute.visibility.probe import probe_open_fraction
    from precompute.visibility.rays import hemisphere_visibility

    for V, F, N in (plane_box_scene(40), _panel_over_detail()):
        o = probe_open_fraction(V, F, N)
        ref = hemisphere_visibility(V, F, N, resolution=64).reshape(len(V), -1).mean(1)
        assert o.shape == (len(V),) and set(np.unique(o * 16)) <= set(range(17))
        assert abs(o.mean() - ref.mean()) < 0.02 and np.abs(o - ref).mean() < 0.05, (o.mean(), ref.mean())


def test_representatives_have_their_clusters_open_fraction():
    """Panel over a detail: a representative's open fraction (a 16² ray cast, independent of the
    probe's rays) is its cluster's mean members', where the vertex nearest the centroid lies in the
    occluded layer (the rule before: −0.05 on average)."""
    from precompute.visibility.probe import probe_open_fraction
    from precompute.visibility.rays import hemisphere_visibility

    V, F, N = _panel_over_detail()
    o = hemisphere_visibility(V, F, N, resolution=16).reshape(len(V), -1).mean(1)
    sp = RP.vertex_spacing(V, F)
    probe = probe_open_fraction(V, F, N)
    for budget in (40, 80):
        errs = []
        for pr in (probe, None):
            cl = RP.cluster_vertices(V, N, budget, 20.0, sp, probe=pr)
            assert cl.count <= budget and np.array_equal(cl.cluster[cl.reps], np.arange(cl.count))
            cnt = np.bincount(cl.cluster)
            err = (o[cl.reps] - np.bincount(cl.cluster, o) / cnt)[cnt > 1]
            errs.append((err.mean(), np.abs(err).mean()))
        (bias, mae), (bias_old, mae_old) = errs
        assert abs(bias) < 0.015 and mae < 0.03, (budget, errs)
        assert bias_old < -0.04, (budget, errs)  # (the test sees the old rule's bias)


def test_blended_maps_keep_the_open_fraction_of_a_panel_over_a_detail(monkeypatch):
    """The fraction of open texels (V^d > 0) of the maps from 80 representatives, over all vertices,
    against every vertex's own ray-cast map; the rule before (a constant probe: one band, the
    representative nearest the centroid, distance weights only) is 0.026 below."""
    V, F, N = _panel_over_detail()
    kw = dict(resolution=16, use_cache=False, progress=False)
    own = (S.ssdf_for_mesh(V, F, N, representatives=0, **kw).reconstruct() > 0).mean()
    rep = S.ssdf_for_mesh(V, F, N, representatives=80, **kw)
    assert len(np.unique(rep.representative)) <= 80
    monkeypatch.setattr(RP, "probe_open_fraction", lambda v, *a, **k: np.zeros(len(v)))
    old = (S.ssdf_for_mesh(V, F, N, representatives=80, **kw).reconstruct() > 0).mean()
    new = (rep.reconstruct() > 0).mean()
    assert abs(new - own) < 0.008 and old < own - 0.015, (own, new, old)
