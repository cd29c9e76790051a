"""precompute.visibility.refine: conforming visibility-driven refinement (docs/rendering.md "Shading")."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import raster
from precompute.visibility.rays import ray_visibility
from precompute.visibility.refine import refine_for_visibility

UP = np.array([0.0, 1.0, 0.0])


# ---------------------------------------------------------------------------------------------
# scenes and independent checks
# ---------------------------------------------------------------------------------------------

def _floor(half=3.0):
    v = np.array([[-half, 0, -half], [-half, 0, half], [half, 0, half], [half, 0, -half]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    return v, f, np.tile(UP, (4, 1))


def _sphere(subdivisions=3, radius=0.5, center=(0.0, 0.5, 0.0)):
    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    s.apply_translation(center)
    return np.asarray(s.vertices), np.asarray(s.faces), np.asarray(s.vertex_normals)


def _merge(*parts):
    vs, fs, ns, off = [], [], [], 0
    for v, f, n in parts:
        vs.append(v)
        fs.append(f + off)
        ns.append(n)
        off += len(v)
    return np.vstack(vs), np.vstack(fs), np.vstack(ns)


def _areas(v, f):
    p = v[f]
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def _edge_counts(f, key_of_vertex):
    """Occurrences of each undirected edge, edges named by ``key_of_vertex`` (index or weld id)."""
    a = key_of_vertex[f]
    b = key_of_vertex[np.roll(f, -1, axis=1)]
    e = np.sort(np.stack([a.ravel(), b.ravel()], axis=1), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    return uniq, counts


def _weld(v):
    _, gid = np.unique(v, axis=0, return_inverse=True)
    return gid.reshape(-1)


def _points_inside_edges(p, a, b, tol=1e-9, chunk=256):
    """Number of (point, segment) pairs with the point strictly inside the segment (2D or 3D)."""
    hits = 0
    d = b - a
    dd = np.einsum("ij,ij->i", d, d)
    for s in range(0, len(p), chunk):
        q = p[s:s + chunk, None, :] - a[None]
        t = np.einsum("pej,ej->pe", q, d) / dd
        off = q - t[..., None] * d
        dist2 = np.einsum("pej,pej->pe", off, off)
        hits += int(((t > 1e-7) & (t < 1 - 1e-7) & (dist2 < tol * tol * dd)).sum())
    return hits


def _bary_in_parent(x, tri):
    """Barycentrics of points x (K, 3) in triangles tri (K, 3, 3) (projection onto the plane)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, x - a
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("ij,ij->i", v2, v0)
    d21 = np.einsum("ij,ij->i", v2, v1)
    den = d00 * d11 - d01 * d01
    w1 = (d11 * d20 - d01 * d21) / den
    w2 = (d00 * d21 - d01 * d20) / den
    return np.stack([1 - w1 - w2, w1, w2], axis=1)


def _check_parents(V, F, N, r):
    """Output vertices 0..N-1 unchanged, per-parent areas preserved, children inside parents with
    the parent's orientation, vertex weights reproduce the positions, normals unit."""
    n = len(V)
    np.testing.assert_array_equal(r.vertices[:n], V)
    np.testing.assert_allclose(np.linalg.norm(r.normals, axis=1), 1.0, atol=1e-12)
    child_area = np.bincount(r.parent_tri, weights=_areas(r.vertices, r.triangles), minlength=len(F))
    np.testing.assert_allclose(child_area, _areas(V, F), rtol=1e-6, atol=1e-12)
    assert child_area.sum() == pytest.approx(_areas(V, F).sum(), rel=1e-9)
    P = V[F[r.parent_tri]]
    for k in range(3):
        w = _bary_in_parent(r.vertices[r.triangles[:, k]], P)
        assert w.min() > -1e-9 and w.max() < 1 + 1e-9
    pn = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    q = r.vertices[r.triangles]
    cn = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    assert (np.einsum("ij,ij->i", pn, cn) > 0).all()
    np.testing.assert_allclose(r.interpolate(V), r.vertices, atol=1e-12)
    assert (r.bary >= 0).all()
    np.testing.assert_allclose(r.bary.sum(axis=1), 1.0, atol=1e-12)


def _floor_edge_lengths(r, n_floor_tris=2):
    fl = r.parent_tri < n_floor_tris
    p = r.vertices[r.triangles[fl]]
    longest = np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2).max(axis=1)
    dist = np.linalg.norm(p.mean(axis=1)[:, [0, 2]], axis=1)  # from the contact point (0, 0, 0)
    return longest, dist


def _interpolated_shadow_area(V, F, r, n_floor_tris=2):
    """Area of the floor where the per-vertex visibility of a light straight up (ray casts against
    the input mesh), interpolated linearly over the refined floor triangles, is below 1/2.
    For binary vertex values the ½-level set cuts edges at their midpoints: a triangle with k
    occluded corners is shadowed on 0, ¼, ¾ or all of its area."""
    fl = r.parent_tri < n_floor_tris
    T = r.triangles[fl]
    ups = np.tile(UP, (len(r.vertices), 1))
    vis = ray_visibility(V, F, r.vertices, ups, ups)
    k = (vis[T] == 0).sum(axis=1)
    return float((_areas(r.vertices, T) * np.array([0.0, 0.25, 0.75, 1.0])[k]).sum())


@pytest.fixture(scope="module")
def floor_sphere():
    V, F, N = _merge(_floor(), _sphere())
    return V, F, N, refine_for_visibility(V, F, N)


# ---------------------------------------------------------------------------------------------
# conformity and bookkeeping
# ---------------------------------------------------------------------------------------------

def test_closed_mesh_stays_closed_and_children_lie_in_parents():
    slab = trimesh.creation.box(extents=(6.0, 0.2, 6.0))
    slab.apply_translation((0.0, -0.1, 0.0))
    box = (np.asarray(slab.vertices), np.asarray(slab.faces), np.asarray(slab.vertex_normals))
    V, F, N = _merge(box, _sphere(subdivisions=2))
    r = refine_for_visibility(V, F, N, budget=6000, levels=3)
    assert sum(r.stats["level_vertices"]) > 0  # the adaptive stage did split something
    assert len(V) < r.stats["presplit_vertices"] < r.stats["vertices"] <= 6000
    _, counts = _edge_counts(r.triangles, np.arange(len(r.vertices)))
    assert (counts == 2).all()  # closed, manifold: no T-junctions, no cracks
    # Euler characteristic of two spheres is kept
    assert len(r.vertices) - len(counts) + len(r.triangles) == 4
    _check_parents(V, F, N, r)


def test_split_vertices_split_together_and_coincide_exactly():
    """A box with every vertex split per face (hard edges): decisions per geometric edge, so the
    welded output is still closed and no vertex sits inside another triangle's edge."""
    slab = trimesh.creation.box(extents=(6.0, 0.2, 6.0))
    slab.apply_translation((0.0, -0.1, 0.0))
    slab.unmerge_vertices()
    fn = np.asarray(slab.face_normals)
    vn = np.zeros((len(slab.vertices), 3))
    vn[slab.faces.ravel()] = np.repeat(fn, 3, axis=0)
    V, F, N = _merge((np.asarray(slab.vertices), np.asarray(slab.faces), vn), _sphere(subdivisions=2))
    r = refine_for_visibility(V, F, N, base_edge=1.0, budget=5000, levels=2)
    assert sum(r.stats["level_vertices"]) > 0
    gid = _weld(r.vertices)
    _, counts = _edge_counts(r.triangles, gid)
    assert (counts == 2).all()
    # split vertices stay split (each side keeps its own normal) but coincide bit for bit
    n_pos = len(np.unique(r.vertices, axis=0))
    assert n_pos < len(r.vertices)
    slab_v = r.vertices[r.vertex_parent < 0][:len(slab.vertices)]
    assert len(np.unique(slab_v, axis=0)) == 8
    # no geometric T-junction on the slab's top face
    on_top = np.all(np.isclose(r.vertices[r.triangles][..., 1], 0.0), axis=1)
    T = r.triangles[(r.parent_tri < len(slab.faces)) & on_top]
    pts = np.unique(r.vertices[np.unique(T)][:, [0, 2]], axis=0)
    e = np.unique(np.sort(np.stack([T.ravel(), np.roll(T, -1, axis=1).ravel()], 1), axis=1), axis=0)
    assert _points_inside_edges(pts, r.vertices[e[:, 0]][:, [0, 2]], r.vertices[e[:, 1]][:, [0, 2]]) == 0
    _check_parents(V, F, N, r)


def _boundary_length_and_t_junctions(r, tri_mask):
    """On a planar (y = 0) part welded by position: (length of edges used by one triangle, number
    of vertices strictly inside some edge, max edge use)."""
    T = _weld(r.vertices)[r.triangles[tri_mask]]
    first = np.zeros(T.max() + 1, np.int64)
    first[_weld(r.vertices)] = np.arange(len(r.vertices))
    e = np.sort(np.stack([T.ravel(), np.roll(T, -1, axis=1).ravel()], 1), axis=1)
    e, counts = np.unique(e, axis=0, return_counts=True)
    a, b = r.vertices[first[e[:, 0]]], r.vertices[first[e[:, 1]]]
    length = np.linalg.norm(a - b, axis=1)
    pts = r.vertices[first[np.unique(T)]][:, [0, 2]]
    return length[counts == 1].sum(), _points_inside_edges(pts, a[:, [0, 2]], b[:, [0, 2]]), counts.max()


def test_uv_seam_with_different_normals_splits_both_sides():
    """The floor's diagonal is a seam (vertices split, the two sides with different shading
    normals, so their visibility signatures differ): marks are per geometric edge, so the seam
    never gets a midpoint on one side only."""
    v, f, _ = _floor()
    tilt = np.array([0.3, 1.0, 0.0]) / np.hypot(0.3, 1.0)
    fv = np.vstack([v, v[[0, 2]]])  # vertices 4, 5 duplicate 0, 2 for the second triangle
    ff = np.array([[0, 1, 2], [4, 5, 3]])
    fn = np.vstack([np.tile(UP, (3, 1)), np.tile(tilt, (3, 1))])
    V, F, N = _merge((fv, ff, fn), _sphere(subdivisions=2, center=(0.4, 0.5, -0.2)))
    r = refine_for_visibility(V, F, N, base_edge=1.0, levels=4)
    assert sum(r.stats["level_vertices"]) > 0
    boundary, inside, max_use = _boundary_length_and_t_junctions(r, r.parent_tri < 2)
    assert max_use == 2 and inside == 0
    assert boundary == pytest.approx(24.0, rel=1e-12)
    # both sides hold their own vertices on the seam, at bit-identical positions
    d = r.vertices[:, 2] - r.vertices[:, 0]  # the diagonal (−3,−3)–(3,3): z = x
    on = (d == 0) & (r.vertices[:, 1] == 0)
    pos, counts = np.unique(r.vertices[on], axis=0, return_counts=True)
    assert len(pos) > 5 and (counts >= 2).all()
    _check_parents(V, F, N, r)


def test_open_plane_has_no_t_junctions_and_budget_is_respected():
    V, F, N = _merge(_floor(), _sphere(subdivisions=2))
    r = refine_for_visibility(V, F, N, base_edge=1.0, budget=1400, levels=4)
    assert r.stats["vertices"] <= 1400
    assert r.stats["level_vertices"] and r.stats["presplit_vertices"] < r.stats["vertices"]
    boundary, inside, max_use = _boundary_length_and_t_junctions(r, r.parent_tri < 2)
    # the edges used once are exactly the quad's boundary: a T-junction would add interior ones
    assert max_use == 2 and boundary == pytest.approx(24.0, rel=1e-12)
    assert inside == 0
    _check_parents(V, F, N, r)
    # a budget below the pre-split's needs: the longest edges go first, never over budget
    small = refine_for_visibility(V, F, N, budget=800)
    assert len(V) < small.stats["vertices"] <= 800
    _check_parents(V, F, N, small)


def test_degenerate_triangles_do_not_crash():
    V, F, N = _floor()
    V = np.vstack([V, [[1.0, 0.0, 1.0], [2.0, 0.0, 2.0]]])  # collinear with vertex 2
    N = np.vstack([N, [UP, UP]])
    F = np.vstack([F, [[4, 5, 2], [4, 4, 5], [0, 0, 0]]])
    r = refine_for_visibility(V, F, N, base_edge=1.0, levels=2)
    assert np.isfinite(r.vertices).all() and np.isfinite(r.normals).all()
    np.testing.assert_allclose(np.bincount(r.parent_tri, _areas(r.vertices, r.triangles), minlength=5)[:2], 18.0)


def test_interpolate_carries_attributes():
    V, F, N = _floor()
    r = refine_for_visibility(V, F, N, base_edge=2.0, levels=0)
    uv = V[:, [0, 2]] / 6.0 + 0.5
    np.testing.assert_allclose(r.interpolate(uv), r.vertices[:, [0, 2]] / 6.0 + 0.5, atol=1e-12)
    ids = np.array([7, 7, 7, 7])
    out = r.interpolate(ids)
    assert out.dtype == ids.dtype and (out == 7).all()
    # bisection halves the 6-long sides to 1.5 (5×5 grid); the cells' 2.12-long diagonals exceed
    # base_edge = 2, so every cell gets its centre: 25 + 16 vertices, 16 × 4 triangles
    assert len(r.vertices) == 41 and len(r.triangles) == 64
    p = r.vertices[r.triangles]
    assert np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2).max() <= 2.0


# ---------------------------------------------------------------------------------------------
# the point: shadows get samples
# ---------------------------------------------------------------------------------------------

def test_floor_is_dense_near_the_sphere_and_sparse_far(floor_sphere):
    V, F, N, r = floor_sphere
    assert r.stats["vertices"] <= 20000
    assert len(r.vertices) > r.stats["presplit_vertices"]
    longest, dist = _floor_edge_lengths(r)
    near = np.median(longest[dist < 1.0])
    far = np.median(longest[dist > 2.5])
    assert near < 0.25 * far
    # far away the floor keeps the uniform pre-split (edges ≤ base edge = diagonal / 24)
    assert far <= np.linalg.norm(V.max(0) - V.min(0)) / 24
    # the floor alone has nothing to shadow: the pre-split only
    fv, ff, fn = _floor()
    alone = refine_for_visibility(fv, ff, fn)
    pre = refine_for_visibility(fv, ff, fn, levels=0)
    assert alone.stats["level_vertices"] == []
    assert len(alone.vertices) == len(pre.vertices) == 33 * 33


def test_refined_floor_rasterises_watertight(floor_sphere):
    V, F, N, r = floor_sphere
    T = r.triangles[r.parent_tri < 2]
    cam = raster.Camera(origin=(0.0, 10.0, 0.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, -1.0),
                        fov=40.0, width=128, height=128)

    def ids(tris):
        return raster.rasterize(r.vertices.astype(np.float32), tris.astype(np.int32), cam, supersample=3).tri_id.numpy()

    tri = ids(T)
    corners = np.c_[V[:4], np.ones(4)] @ cam.view_projection().T
    X = (corners[:, 0] / corners[:, 3] + 1) / 2 * cam.width
    Y = (1 - corners[:, 1] / corners[:, 3]) / 2 * cam.height
    ys, xs = (np.mgrid[0:3 * cam.height, 0:3 * cam.width] + 0.5) / 3
    inside = (xs > X.min() + 1) & (xs < X.max() - 1) & (ys > Y.min() + 1) & (ys < Y.max() - 1)
    assert inside.sum() > 0.5 * inside.size
    assert (tri[inside] >= 0).all(), f"{int((tri[inside] < 0).sum())} uncovered pixels inside the floor"
    assert (tri[~inside & ((xs < X.min() - 1) | (xs > X.max() + 1))] < 0).all()
    # the check sees a hole: drop the largest triangle near the middle
    longest, dist = _floor_edge_lengths(r)
    drop = np.argmax(np.where(dist < 1.5, longest, 0.0))
    assert (ids(np.delete(T, drop, axis=0))[inside] < 0).sum() > 0


def test_interpolated_shadow_covers_the_true_shadow_disk(floor_sphere):
    V, F, N, r = floor_sphere
    true_area = np.pi * 0.5 ** 2
    area = _interpolated_shadow_area(V, F, r)
    assert abs(area / true_area - 1) < 0.05
    # the input floor's four corners see the light: no shadow at all
    coarse = refine_for_visibility(V, F, N, base_edge=float("inf"), levels=0)
    assert len(coarse.vertices) == len(V)
    assert _interpolated_shadow_area(V, F, coarse) == 0.0


def test_signatures_are_cast_only_for_vertices_that_are_compared(monkeypatch):
    """The signatures (12² rays a vertex) of the vertices the last step adds are never compared,
    neither after the last level nor once the budget is full: none are cast for them, and the
    refinement is that of levels + 1 levels cut at the same budget (the step after finds no room)."""
    import precompute.visibility.refine as rf

    cast = []
    real = rf.hemisphere_visibility

    def counting(*a, vertex_ids=None, **k):
        cast.append(len(vertex_ids))
        return real(*a, vertex_ids=vertex_ids, **k)

    monkeypatch.setattr(rf, "hemisphere_visibility", counting)
    V, F, N = _merge(_floor(), _sphere(subdivisions=2))
    full = refine_for_visibility(V, F, N, budget=100000, levels=2)  # stops after its last level
    lv = full.stats["level_vertices"]
    assert len(lv) == 2 and lv[-1] > 0
    assert sum(cast) == full.stats["vertices"] - lv[-1]  # the last level's vertices: no rays
    cast.clear()
    budget = full.stats["presplit_vertices"] + lv[0] + lv[1] // 2  # full during the second level
    cut = refine_for_visibility(V, F, N, budget=budget, levels=4)
    assert cut.stats["vertices"] == budget and len(cut.stats["level_vertices"]) == 2
    assert sum(cast) == budget - cut.stats["level_vertices"][-1]
    monkeypatch.setattr(rf, "hemisphere_visibility", real)
    more = refine_for_visibility(V, F, N, budget=budget, levels=5)
    assert np.array_equal(more.vertices, cut.vertices) and np.array_equal(more.triangles, cut.triangles)


# ---------------------------------------------------------------------------------------------
# visibility groups (scenes with objects that move)
# ---------------------------------------------------------------------------------------------

def _bench_on_floor():
    """A slab with a post on it (two boxes, so the group shadows itself), beside the floor."""
    parts = []
    for ext, ctr in (((1.2, 0.1, 0.8), (1.0, 0.05, 0.0)), ((0.2, 0.8, 0.2), (1.0, 0.5, 0.0))):
        b = trimesh.creation.box(extents=ext)
        b.apply_translation(ctr)
        parts.append((np.asarray(b.vertices), np.asarray(b.faces), np.asarray(b.vertex_normals)))
    return _merge(*parts)


SUN = [("directional", np.array([0.5, 0.8, 0.3]) / np.linalg.norm([0.5, 0.8, 0.3]))]


def _group_vertices(r, groups, g):
    """Sorted positions of the refined vertices of group ``g`` (their parent input triangle's)."""
    tris = r.triangles[groups[r.parent_tri] == g]
    return np.unique(np.round(r.vertices[np.unique(tris)], 12), axis=0)


def test_a_group_is_refined_as_its_mesh_alone_and_the_floor_sees_no_other_groups_shadow():
    """With groups, a vertex's signatures see only its own group's triangles: the moving object's
    refinement is that of its mesh alone (same base edge), and the floor, which cannot shadow
    itself, keeps its uniform pre-split; without groups the floor is refined around the object's
    shadow (where the object stood when the precompute ran)."""
    fl, ob = _floor(), _bench_on_floor()
    V, F, N = _merge(fl, ob)
    groups = np.r_[np.zeros(len(fl[1]), np.int64), np.ones(len(ob[1]), np.int64)]
    edge = 0.25
    grouped = refine_for_visibility(V, F, N, base_edge=edge, budget=100000, lights=SUN, groups=groups)
    whole = refine_for_visibility(V, F, N, base_edge=edge, budget=100000, lights=SUN)
    # each mesh alone, with the floor's corners as unused vertices: the same scene size (the
    # shortest edge the levels split and the rays' offsets are fractions of it)
    alone_ob = refine_for_visibility(*_merge(ob, (fl[0], np.zeros((0, 3), np.int64), fl[2])), base_edge=edge,
                                     budget=100000, lights=SUN)
    alone_fl = refine_for_visibility(*fl, base_edge=edge, budget=100000, lights=SUN)
    assert alone_ob.stats["level_vertices"] and alone_ob.stats["level_vertices"][0] > 0  # it shadows itself
    used = lambda r: np.unique(np.round(r.vertices[np.unique(r.triangles)], 12), axis=0)  # noqa: E731
    np.testing.assert_array_equal(_group_vertices(grouped, groups, 1), used(alone_ob))
    np.testing.assert_array_equal(_group_vertices(grouped, groups, 0), used(alone_fl))
    assert alone_fl.stats["level_vertices"] == []  # the floor alone: its pre-split only
    n_floor = len(used(alone_fl))
    assert len(_group_vertices(whole, groups, 0)) > n_floor + 100  # refined around the object's shadow
    _check_parents(V, F, N, grouped)


def test_group_budgets_cap_what_the_levels_add_to_a_group():
    fl, ob = _floor(), _bench_on_floor()
    V, F, N = _merge(ob, _sphere(subdivisions=2, center=(-1.0, 0.6, 0.0)), fl)
    groups = np.r_[np.ones(len(ob[1]), np.int64), np.full(320, 2), np.zeros(len(fl[1]), np.int64)]
    edge = 0.25
    pre = refine_for_visibility(V, F, N, base_edge=edge, levels=0, groups=groups)
    free = refine_for_visibility(V, F, N, base_edge=edge, budget=100000, lights=SUN, groups=groups)
    n_pre = len(_group_vertices(pre, groups, 1))
    n_free = len(_group_vertices(free, groups, 1))
    assert n_free > n_pre + 60
    for cap in (0, 60):
        r = refine_for_visibility(V, F, N, base_edge=edge, budget=100000, lights=SUN, groups=groups,
                                  group_budgets={1: cap, 2: 0})
        n = len(_group_vertices(r, groups, 1))
        assert n_pre + (cap > 0) <= n <= n_pre + cap
        # the other groups are as without the cap: the floor's pre-split, the convex sphere's own vertices
        for g in (0, 2):
            np.testing.assert_array_equal(_group_vertices(r, groups, g), _group_vertices(free, groups, g))
        _check_parents(V, F, N, r)
    with pytest.raises(Exception, match="group_budgets needs groups"):
        refine_for_visibility(V, F, N, base_edge=edge, group_budgets={1: 0})


def test_ssdf_rays_cast_against_the_input_mesh_meet_the_refined_surface(floor_sphere):
    """The refinement only splits triangles, so the SSDFs of the refined vertices may cast their
    rays against the input mesh (``occluders``: a BVH of 2 + 1280 triangles instead of the refined
    mesh's thousands): the binary maps are those the refined mesh gives. And the rays do meet the
    occluders given: against the floor alone, the floor's vertices see no sphere."""
    from precompute.visibility.ssdf import compute_ssdf

    V, F, N, r = floor_sphere
    assert len(r.triangles) > 2 * len(F)
    ids = np.arange(0, len(r.vertices), max(len(r.vertices) // 400, 1))
    kw = dict(resolution=16, ray_resolution=32, vertex_ids=ids, progress=False, return_visibility=True)
    own, vis_own = compute_ssdf(r.vertices, r.triangles, r.normals, **kw)
    inp, vis_inp = compute_ssdf(r.vertices, r.triangles, r.normals, occluders=(V, F), **kw)
    assert np.mean(vis_own != vis_inp) <= 1e-4
    assert np.mean(np.abs(own - inp)) <= 1e-4
    floor_ids = np.flatnonzero(np.abs(r.vertices[ids, 1]) < 1e-9)
    shadowed = floor_ids[(vis_own[floor_ids] == 0).any(axis=(1, 2))]
    assert len(shadowed) > 10  # floor vertices that see the sphere
    _, vis_floor = compute_ssdf(r.vertices, r.triangles, r.normals, occluders=_floor()[:2], **kw)
    assert np.all(vis_floor[shadowed] == 1)
