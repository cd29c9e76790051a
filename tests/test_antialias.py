"""Edge- and contrast-adaptive antialiasing (``warp_sg.renderer.antialias``) against brute force: shading
every one of the a×a sub-pixels (``supersampling = a``) and box-filtering."""
from __future__ import annotations

import numpy as np
import pytest

import warp_sg as ws
from warp_sg.scene.camera import Camera
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight
from warp_sg.scene.model import Scene, SceneObject
from warp_sg.scene.render_settings import RenderSettings


def _scene(**render):
    cam = Camera(origin=(0.0, 0.9, 3.0), target=(0.0, 0.3, 0.0), fov=40.0, width=40, height=32)
    return Scene(camera=cam,
                 objects=[SceneObject(material="ring", primitive="torus", name="ring",
                                      params={"center": (0.0, 0.45, 0.0), "major_radius": 0.5, "minor_radius": 0.18,
                                              "resolution": (48, 24)}),
                          SceneObject(material="floor", primitive="plane", name="floor",
                                      params={"size": (4.0, 4.0), "resolution": (8, 8)})],
                 materials={"ring": ws.brdf.BlinnPhong(kd=0.3, ks=0.5, n=80.0), "floor": ws.brdf.Lambert(kd=0.7)},
                 lights=[DirectionalLight(direction=(0.4, 0.8, 0.5), radius=0.03, intensity=2.5),
                         EnvironmentLight(procedural="constant", options={"radiance": [0.2, 0.25, 0.3]})],
                 render=RenderSettings(shadows=False, **render))


def test_adaptive_antialiasing_matches_shading_every_subpixel(cache_dir):
    r = ws.Renderer(_scene(antialias=4))
    adaptive = r.render()
    t = dict(r.timings)
    full = ws.render(_scene(supersampling=4))
    point = ws.render(_scene(antialias=1))
    err = np.abs(adaptive - full).sum(-1)
    err_point = np.abs(point - full).sum(-1)
    # where it matters (edges, glints) adaptive ≈ full supersampling; point sampling is far off
    # there (measured 0.003 of point sampling's error; shading half the sub-pixels of contrast
    # pixels, tried, gave 0.09)
    assert err.mean() < 0.02 * err_point.mean(), (err.mean(), err_point.mean())
    assert np.quantile(err, 0.99) < 0.005 * full.sum(-1).max()
    # and it shades far fewer samples than full supersampling (16 per pixel)
    assert t["shaded_samples"] < 0.5 * 16 * 40 * 32
    assert t["edge_pixels"] > 0
    # contrast pixels whose probes disagree (the glints) were shaded at every sub-pixel, not all
    assert 0 < t["refined_pixels"] < t["contrast_pixels"]


def _grazing_floor_scene():
    """A 20 m floor of two triangles seen from 15 cm above it: its near border is behind the
    camera (its contour edges cross the near plane), its far border along a pixel row."""
    cam = Camera(origin=(0.0, 0.15, 3.0), target=(0.0, 0.0, -2.0), fov=40.0, width=48, height=32)
    return Scene(camera=cam, objects=[SceneObject(material="floor", primitive="plane",
                                                  params={"size": (20.0, 20.0), "resolution": (2, 2)})],
                 materials={"floor": ws.brdf.Lambert(kd=0.7)},
                 lights=[EnvironmentLight(procedural="constant", options={"radiance": [1.0, 1.0, 1.0]})],
                 render=RenderSettings(shadows=False, antialias=4))


def test_a_flat_floor_at_grazing_view_is_not_an_edge_except_at_its_border(cache_dir):
    cam = _grazing_floor_scene().camera
    r = ws.Renderer(_grazing_floor_scene())
    img = r.render()
    # the floor's far edge meets the background along one row or two: only those pixels are edges
    # (1/depth is affine across a flat triangle, so the grazing floor itself is no edge)
    assert r.timings["edge_pixels"] <= 3 * cam.width
    assert np.all(np.isfinite(img))


def _pole_scene(**render):
    """A pole thinner than a pixel (radius 0.004 at 2.2 m: ≈ 0.4 px wide) in front of a floor: the
    pixel centres miss it along much of its length."""
    import trimesh

    pole = trimesh.creation.cylinder(radius=0.004, height=1.2, sections=8)
    V = np.asarray(pole.vertices)[:, [0, 2, 1]] + np.array([0.13, 0.6, 0.8])  # z-axis -> y-axis
    F = np.asarray(pole.faces)[:, ::-1]  # (the axis swap mirrors: keep the faces outward)
    cam = Camera(origin=(0.0, 0.6, 3.0), target=(0.0, 0.4, 0.0), fov=40.0, width=40, height=32)
    return Scene(camera=cam,
                 objects=[SceneObject(material="pole", name="pole", vertices=V, triangles=F),
                          SceneObject(material="floor", primitive="plane", name="floor",
                                      params={"size": (6.0, 6.0), "resolution": (2, 2)})],
                 materials={"pole": ws.brdf.Lambert(kd=0.0), "floor": ws.brdf.Lambert(kd=0.8)},
                 lights=[EnvironmentLight(procedural="constant", options={"radiance": [1.0, 1.0, 1.0]})],
                 render=RenderSettings(shadows=False, **render))


def test_geometry_thinner_than_a_pixel_is_antialiased_where_pixel_centres_miss_it(cache_dir):
    """The contour edges flag the pole's pixels even where no pixel centre sees it: adaptive
    antialiasing matches shading every sub-pixel there, point sampling does not."""
    full = ws.render(_pole_scene(supersampling=4))
    r = ws.Renderer(_pole_scene(antialias=4))
    adaptive = r.render()
    point = ws.render(_pole_scene(antialias=1))
    floor = full[-1, 0].sum()
    covered = full.sum(-1) < 0.97 * floor  # pixels the pole darkens by > 3 % (sub-pixel coverage)
    missed = covered & (point.sum(-1) > 0.999 * floor)  # ... that point sampling does not see
    assert missed.sum() >= 5
    err = np.abs(adaptive - full).sum(-1)
    assert err[missed].max() < 0.02 * floor
    cam = r.scene.camera
    assert r.timings["candidate_pixels"] < 0.5 * cam.width * cam.height  # sub-pixels only where needed


@pytest.mark.parametrize("make", [lambda: _scene(antialias=4), _grazing_floor_scene, lambda: _pole_scene(antialias=4)],
                         ids=["torus and floor", "grazing floor", "thin pole"])
def test_every_edge_of_a_full_subpixel_raster_is_a_candidate_pixel(cache_dir, make):
    """Reference: the a×a raster of the whole image (itself checked against ray casting in
    tests/test_raster.py) classified everywhere; every pixel it finds to be an edge must be
    flagged by the contours or the 1× object changes."""
    import warp as wp

    import raster
    from raster import parallel
    from warp_sg.renderer import antialias as A
    from warp_sg.renderer import antialias_candidates as C

    r = ws.Renderer(make())
    r.render()
    cam, a, H, W = r.scene.camera, 4, r.scene.camera.height, r.scene.camera.width
    full = raster.rasterize(r.geo_arrays.positions, r.geo_arrays.tris, cam, supersample=a)
    every = wp.array(np.full(H * W, C.CAND_GEOMETRY, np.int32), dtype=int)
    edge, count = wp.empty(H * W, dtype=int), wp.empty(H * W, dtype=int)
    parallel.launch(A.classify_kernel, H * W, [wp.array(np.arange(H * W, dtype=np.int32), dtype=int), every,
                                               _per_pixel(full.tri_id, a, int), _per_pixel(full.inv_depth, a, float),
                                               r._tri_object, a, A.EDGE_DEPTH_RESIDUAL, edge, count], "cpu")
    edges = edge.numpy().astype(bool)
    vb1 = r.rasterize(1)
    img = wp.zeros((H, W), dtype=wp.vec3)  # no contrast: geometry flags only
    c = C.Candidates(vb1.tri_id, r._tri_object, r._aa.contours(cam, vb1), img, "cpu")
    flagged = c.cand.numpy() != 0
    assert c.indices().numpy().tolist() == np.flatnonzero(flagged).tolist()
    assert edges.sum() > 20
    assert not (edges & ~flagged).any()
    assert flagged.mean() < 0.5  # and far from everything


def _per_pixel(grid, a, dtype):
    """An (H·a, W·a) sub-pixel grid (a ``wp.array``) as the (H·W, a²) rows of ``raster.subsample``
    (pixel-major, sub-pixel q = j·a + i)."""
    import warp as wp

    g = grid.numpy()
    H, W = g.shape[0] // a, g.shape[1] // a
    rows = g.reshape(H, a, W, a, *g.shape[2:]).swapaxes(1, 2).reshape(H * W, a * a, *g.shape[2:])
    return wp.array(np.ascontiguousarray(rows), dtype=wp.vec2 if g.ndim == 3 else dtype)


def test_the_device_reduction_of_the_frame_counts_matches_numpy():
    """On CUDA the counts come from an atomic reduction (only three integers come back); it is
    checked here by running that kernel once on the CPU (one launch: atomics are exact there)."""
    import warp as wp

    from warp_sg.renderer import antialias as A
    from warp_sg.renderer import antialias_candidates as C

    rng = np.random.default_rng(1)
    c = rng.integers(0, 4, 5000).astype(np.int32)
    listed = np.flatnonzero(c)
    cand, idx = wp.array(c, dtype=int), wp.array(listed.astype(np.int32), dtype=int)
    edge = wp.array(rng.integers(0, 2, len(listed)).astype(np.int32), dtype=int)
    out = wp.zeros(3, dtype=int)
    wp.launch(A._counts_kernel, dim=len(listed), inputs=[idx, cand, edge, out])
    e = edge.numpy()
    want = [np.count_nonzero(c), e.sum(), np.count_nonzero(c & C.CAND_CONTRAST)]
    assert out.numpy().tolist() == [int(x) for x in want]
    got = A._counts(idx, cand, edge, "cpu")
    assert [got["candidate_pixels"], got["edge_pixels"], got["contrast_pixels"]] == [int(x) for x in want]


#: Direct3D's standard 4-sample MSAA pattern, in 1/16 pixel from the pixel centre
D3D_4X = [(-2, -6), (6, -2), (-6, 2), (2, 6)]


@pytest.mark.parametrize("a", [2, 3, 4, 8])
def test_contrast_pixels_are_probed_then_refined_at_every_sub_pixel_where_the_probes_disagree(a):
    """A contrast pixel (no edge) is first shaded at 4 probes, the sub-pixels holding the points of
    Direct3D's 4× MSAA pattern (for a = 2: all four sub-pixels), each weighted 1/4. Where the
    probes and the centre sample differ by more than ``PROBE_CONTRAST`` it is shaded at its other
    a² − 4 sub-pixels too and the pixel is the plain mean of all a² (a glint that a probe sees);
    else the probes' mean stands (a flat pixel, a glint between the probes).

    Run through ``render_adaptive`` itself on a real 1× raster (one triangle filling a 4×3 view, so
    no pixel is an edge): the shading callback gives each sample the colour of the sub-pixel cell
    its surface point projects to, and the frame is checked against numpy means of those colours."""
    import warp as wp

    import raster
    from warp_sg.renderer import antialias as A
    from warp_sg.scene.camera import Camera
    from warp_sg.shading.background import background_params

    W, H = 4, 3
    cam = Camera(origin=(0.0, 0.0, 1.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=40.0, width=W, height=H)
    verts = np.array([[-100.0, -100.0, 0.0], [100.0, -100.0, 0.0], [0.0, 100.0, 0.0]])
    tris = np.array([[0, 1, 2]], np.int32)
    pos, tri_arr = wp.array(verts, dtype=wp.vec3), wp.array(tris, dtype=wp.vec3i)
    vb = raster.rasterize(pos, tri_arr, cam, "cpu", subsamples=a)
    assert (vb.tri_id.numpy() == 0).all()

    probes = sorted({(int((8 + dy) * a // 16), int((8 + dx) * a // 16)) for dx, dy in D3D_4X})  # (row, col)
    others = [(j, i) for j in range(a) for i in range(a) if (j, i) not in probes]
    cell = np.full((H * a, W * a, 3), 0.5, np.float32)  # the colour of each sub-pixel cell
    centre = np.full((H, W, 3), 0.5, np.float32)  # the 1× frame
    (ay, ax), (by, bx) = (1, 1), (1, 2)
    centre[ay, ax] = 2.0  # pixel A contrasts with its neighbours, and its probes agree with its centre ...
    cell[ay * a:(ay + 1) * a, ax * a:(ax + 1) * a] = 2.0
    if others:
        cell[ay * a + others[0][0], ax * a + others[0][1]] = 10.0  # ... though a glint hides between them
    cell[by * a + probes[0][0], bx * a + probes[0][1]] = 10.0  # pixel B: a glint on a probe

    r, u, f = (np.asarray(v, np.float64) for v in cam.basis())
    th = np.tan(np.radians(cam.fov) / 2)

    def shade(tri_s, bary_s, bg_s, out):
        """The colour of the cell each sample's surface point projects to (0 for the background)."""
        t, b = tri_s.numpy()[0], bary_s.numpy()[0].astype(np.float64)
        P = (1 - b[:, :1] - b[:, 1:]) * verts[0] + b[:, :1] * verts[1] + b[:, 1:] * verts[2]
        v = P - np.asarray(cam.origin)
        x = ((v @ r) / (v @ f) / (th * cam.aspect) + 1) / 2 * W * a
        y = (1 - (v @ u) / (v @ f) / th) / 2 * H * a
        col = cell[np.clip(y.astype(int), 0, H * a - 1), np.clip(x.astype(int), 0, W * a - 1)]
        out.assign(wp.array(np.where((t >= 0)[:, None], col, 0.0)[None].astype(np.float32), dtype=wp.vec3))

    img = wp.array(centre, dtype=wp.vec3)
    cache = A.AntialiasCache(pos, tri_arr, "cpu")
    out, stats = A.render_adaptive(vb, img, cache, cam, wp.zeros(1, dtype=int), background_params(cam, a, None, None,
                                   1.0, "cpu"), a, H, W, shade, "cpu")
    got = out.numpy()
    block = lambda y, x: cell[y * a:(y + 1) * a, x * a:(x + 1) * a]  # noqa: E731
    want = centre.copy()  # flat pixels: the probes' mean is the centre's colour, candidates or not
    want[ay, ax] = np.mean([block(ay, ax)[j, i] for j, i in probes], 0) if a >= 3 else block(ay, ax).mean((0, 1))
    want[by, bx] = block(by, bx).mean((0, 1))  # refined (a ≥ 3), or its four probes (a = 2): all sub-pixels
    np.testing.assert_allclose(got, want, atol=1e-5)
    assert stats["edge_pixels"] == 0 and stats["contrast_pixels"] >= 2
    assert stats["refined_pixels"] == (1 if a >= 3 else 0)
    if others:
        assert abs(float(got[ay, ax, 0]) - float(block(ay, ax)[..., 0].mean())) > 0.1  # A's glint is not seen


def _background(a, W):
    """A disabled background (no environment): samples that see no object get 0."""
    from warp_sg.scene.camera import Camera
    from warp_sg.shading.background import background_params

    return background_params(Camera(width=W, height=1), a, None, None, 1.0, "cpu")


def test_an_edge_pixel_is_shaded_once_per_triangle_at_its_sub_pixels_mean_with_their_share():
    """A 4×4 block seen by two triangles and the background: the gathered samples (triangle,
    barycentrics, weight) against a numpy construction, and the weighted resolve against the
    coverage-weighted mean of given sample colours."""
    import warp as wp

    from warp_sg.renderer import antialias as A
    from warp_sg.renderer import antialias_candidates as C

    a, W = 4, 1
    rng = np.random.default_rng(3)
    tid = np.full((a, a), 7, np.int32)
    tid[:, 3] = -1  # one column of background
    tid[2:, :2] = 11  # a second triangle in a corner
    bary = rng.uniform(0.0, 0.5, (a, a, 2)).astype(np.float32)
    count = wp.zeros(W, dtype=int)
    edge = wp.zeros(W, dtype=int)
    inv_depth = wp.array(np.where(tid >= 0, 1.0, 0.0).astype(np.float32).reshape(1, a * a), dtype=float)
    tri_object = wp.array(np.arange(12, dtype=np.int32), dtype=int)  # each triangle its own object
    one = wp.zeros(W, dtype=int)  # the list: pixel 0
    wp.launch(A.classify_kernel, dim=W, inputs=[0, one, wp.array(np.array([C.CAND_GEOMETRY], np.int32), dtype=int),
                                                wp.array(tid.reshape(1, a * a), dtype=int), inv_depth, tri_object, a,
                                                A.EDGE_DEPTH_RESIDUAL, edge, count])
    assert edge.numpy()[0] == 1 and count.numpy()[0] == 2 + 4  # two triangles + four background sub-pixels
    n = 6
    tri_s, bary_s = wp.empty((1, n), dtype=int), wp.empty((1, n), dtype=wp.vec2)
    bg_s, w_s = wp.empty((1, n), dtype=wp.vec3), wp.empty(n, dtype=float)
    wp.launch(A.gather_kernel, dim=W, inputs=[0, one, wp.array(tid.reshape(1, a * a), dtype=int),
                                              wp.array(bary.reshape(1, a * a, 2), dtype=wp.vec2),
                                              _background(a, W), count, wp.zeros(W, dtype=int), edge, a, W, tri_s,
                                              bary_s, bg_s, w_s])
    t, b, w = tri_s.numpy()[0], bary_s.numpy()[0], w_s.numpy()
    for tri, cov in ((7, 8), (11, 4)):
        (q,) = np.nonzero(t == tri)[0]
        assert np.isclose(w[q], cov / 16.0)
        assert np.allclose(b[q], bary[tid == tri].mean(0), atol=1e-6)
    assert np.allclose(w[t < 0], 1.0 / 16.0) and (t < 0).sum() == 4
    assert np.isclose(w.sum(), 1.0)
    colours = rng.uniform(0.0, 1.0, (1, n, 3)).astype(np.float32)
    img = wp.array(np.full((1, 1, 3), 7.0, np.float32), dtype=wp.vec3)  # the centre sample: replaced (keep 0)
    wp.launch(A.resolve_kernel, dim=W, inputs=[0, one, wp.array(colours, dtype=wp.vec3), w_s, count,
                                               wp.zeros(W, dtype=int), W, 0.0, img])
    assert np.allclose(img.numpy()[0, 0], (colours[0] * w[:, None]).sum(0), atol=1e-6)


def test_contour_marks_are_the_pixels_the_projected_edges_cross():
    """``silhouette.mark_contours`` on one triangle (its three edges are boundary edges, always
    contours) against the edges projected in float64 and sampled every 1e-3 px: every pixel a
    sample falls in is marked, and nothing farther than ``MARK_EPS`` (+ 0.01 px) from an edge."""
    import warp as wp

    from warp_sg.scene.camera import Camera
    from warp_sg.shading import silhouette as SIL

    cam = Camera(origin=(0.1, 0.3, 2.0), target=(0.0, 0.0, 0.0), fov=50.0, width=37, height=29)
    V = np.array([[-0.7, -0.2, 0.1], [0.6, -0.5, -0.3], [0.05, 0.65, 0.2]], np.float32)
    T = np.array([[0, 1, 2]], np.int32)
    ev, ef = SIL.edge_adjacency(V, T)
    mark = SIL.mark_contours(wp.array(V, dtype=wp.vec3), wp.array(T, dtype=wp.vec3i),
                             wp.array(ev, dtype=wp.vec2i), wp.array(ef, dtype=wp.vec2i), cam, "cpu").numpy()
    r, u, f = (np.asarray(x, np.float64) for x in cam.basis())
    th = np.tan(np.radians(cam.fov) / 2)
    v = V.astype(np.float64) - np.asarray(cam.origin)
    z = v @ f
    px = np.stack([((v @ r) / (z * th * cam.width / cam.height) + 1) * 0.5 * cam.width,
                   (1 - (v @ u) / (z * th)) * 0.5 * cam.height], 1)
    t = np.linspace(0.0, 1.0, 20001)[:, None]
    pts = np.concatenate([px[a] + (px[b] - px[a]) * t for a, b in ((0, 1), (1, 2), (2, 0))])

    def cells(p):
        c = np.floor(p).astype(int)
        ok = (c[:, 0] >= 0) & (c[:, 0] < cam.width) & (c[:, 1] >= 0) & (c[:, 1] < cam.height)
        m = np.zeros_like(mark, bool)
        m[c[ok, 1], c[ok, 0]] = True
        return m

    crossed = cells(pts)
    g = float(SIL.MARK_EPS) + 0.01
    near = np.zeros_like(crossed)
    for dx in (-g, 0.0, g):
        for dy in (-g, 0.0, g):
            near |= cells(pts + [dx, dy])
    assert crossed.sum() > 40
    assert not (crossed & (mark == 0)).any()  # every crossed pixel is marked
    assert not ((mark != 0) & ~near).any()    # and nothing else (a 3×3 dilation would fail here)


def test_contours_hidden_behind_a_nearer_surface_are_not_marked():
    """A triangle behind a larger quad: with the 1× buffer its contour edges are hidden everywhere
    (no mark), without it they are marked; the quad's own border, seen against the background, is
    marked the same with and without."""
    import warp as wp

    import raster
    from warp_sg.scene.camera import Camera
    from warp_sg.shading import silhouette as SIL

    cam = Camera(origin=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fov=50.0, width=48, height=40)
    quad = np.array([[-1.0, -0.8, 0.0], [1.0, -0.8, 0.0], [1.0, 0.8, 0.0], [-1.0, 0.8, 0.0]], np.float32)
    tri = np.array([[-0.5, -0.4, -1.0], [0.6, -0.3, -1.0], [0.0, 0.5, -1.0]], np.float32)
    V = np.concatenate([quad, tri])
    F = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6]], np.int32)
    vb = raster.rasterize(V, F, cam)
    assert (vb.tri_id.numpy() == 2).sum() == 0  # the triangle is hidden

    def marks(tris, inv_depth):
        ev, ef = SIL.edge_adjacency(V, F[tris])
        return SIL.mark_contours(wp.array(V, dtype=wp.vec3), wp.array(F[tris], dtype=wp.vec3i),
                                 wp.array(ev, dtype=wp.vec2i), wp.array(ef, dtype=wp.vec2i), cam, "cpu",
                                 inv_depth=inv_depth).numpy()

    assert marks([2], None).sum() > 30 and marks([2], vb.inv_depth).sum() == 0
    border = marks([0, 1], None)
    assert border.sum() > 60 and np.array_equal(marks([0, 1], vb.inv_depth), border)


@pytest.mark.parametrize("W", [1, 63, 64, 150])
def test_candidate_flags_and_list_match_their_definition_in_numpy(W):
    """Every pixel's flags (rows tested in runs of ``CANDIDATES_PER_THREAD`` on the CPU, the last
    run of a row shorter) against the definition evaluated with numpy shifts: a contour mark, a
    4-neighbour on another object, a 4-neighbour whose luminance differs by more than
    ``CONTRAST`` of the larger; and the candidate list against ``numpy.flatnonzero``."""
    import warp as wp

    from warp_sg.renderer import antialias_candidates as C

    H = 9
    rng = np.random.default_rng(W)
    tid = rng.integers(-1, 40, (H, W)).astype(np.int32)
    tid[:, : W // 2] = 5  # a flat region: one triangle
    obj = rng.integers(0, 3, 40).astype(np.int32)
    contours = (rng.random((H, W)) < 0.05).astype(np.uint8)
    img = rng.uniform(0.5, 1.0, (H, W, 3)).astype(np.float32)
    img[:, : W // 3] = 0.8  # no contrast there
    c = C.Candidates(wp.array(tid, dtype=int), wp.array(obj, dtype=int), wp.array(contours, dtype=wp.uint8),
                     wp.array(img, dtype=wp.vec3), "cpu")
    o = np.where(tid >= 0, obj[np.maximum(tid, 0)], -1)
    lum = img.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    geo = contours != 0
    con = np.zeros((H, W), bool)
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        ys, xs = np.mgrid[0:H, 0:W]
        yy, xx = ys + dy, xs + dx
        ok = (yy >= 0) & (yy < H) & (xx >= 0) & (xx < W)
        yy, xx = np.clip(yy, 0, H - 1), np.clip(xx, 0, W - 1)
        geo |= ok & (o[yy, xx] != o)
        con |= ok & (np.abs(lum - lum[yy, xx]) > C.CONTRAST * np.maximum(lum, lum[yy, xx]))
    want = np.where(geo, C.CAND_GEOMETRY, 0) | np.where(con, C.CAND_CONTRAST, 0)
    assert c.cand.numpy().reshape(H, W).tolist() == want.tolist()
    # the list: a scan of the runs' counts, then each run writes its own
    assert c.indices().numpy().tolist() == np.flatnonzero(want.ravel()).tolist()
    assert con.any() and geo.any() or W == 1


def test_candidate_lists_are_compared_on_their_device():
    """``same_list`` (a re-shade reuses the sub-pixel coverage when its candidate list is the last
    frame's): equal, one element changed, another length; the device comparison kernel (the CUDA
    path, one integer back) run here on the CPU against numpy."""
    import warp as wp

    from warp_sg.renderer import antialias_cache as A

    x = np.arange(0, 5000, 7, dtype=np.int32)
    y = x.copy()
    y[333] += 1
    a, b, c = (wp.array(v, dtype=int) for v in (x, y, x[:-1]))
    assert A.same_list(a, wp.array(x.copy(), dtype=int))
    assert not A.same_list(a, b) and not A.same_list(a, c)
    for other, want in ((x.copy(), 0), (y, 1)):
        out = wp.zeros(1, dtype=int)
        wp.launch(A._differs_kernel, dim=len(x), inputs=[a, wp.array(other, dtype=int), out])
        assert out.numpy()[0] == want
