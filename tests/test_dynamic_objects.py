"""Objects that move after the precompute (``[[objects]] dynamic = true``,
``Renderer.set_object_transform``; :mod:`warp_sg.renderer.dynamic_objects`): the interface, the analytic
proxies against brute force, self-shadows that turn with the object against a ray cast, nothing
stale after a move and back, and a moved frame against the Monte-Carlo reference at that pose."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import warp_sg as ws
from warp_sg.core.errors import SceneError
from warp_sg.numeric.rigid_motion import check_motion, motion_matrix, rotation_about
from warp_sg.scene.plain_scenes import write_plain_scene


def _scene(tmp_path, obj="sphere", light="sky", size=32, **render):
    rs = {"ssdf_resolution": 16, "pca_terms": 16, "visibility_budget": 4000, **render}
    return ws.load_scene(write_plain_scene(tmp_path, obj=obj, light=light, size=size, render=rs, dynamic=True))


def _roll(x: float, z: float = 0.0, radius: float = 0.5) -> np.ndarray:
    """The ball rolled without slipping by x along +X (and moved by z): turned about −Z by x/r."""
    c = np.array([0.0, radius, 0.0])
    R = rotation_about([0.0, 0.0, -1.0], np.degrees(x / radius))
    return motion_matrix(R, c - R @ c + [x, 0.0, z])


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    return ws.Renderer(_scene(tmp_path_factory.mktemp("ball"), size=40))


def test_dynamic_key_reaches_the_scene_object(tmp_path):
    sc = _scene(tmp_path)
    assert [ob.dynamic for ob in sc.objects] == [True, False]


def test_moving_a_static_object_is_refused(ball):
    with pytest.raises(SceneError, match="'floor' is not dynamic"):
        ball.set_object_transform("floor", np.eye(4))
    with pytest.raises(SceneError, match="no object 'objct'.*did you mean 'object'"):
        ball.set_object_transform("objct", np.eye(4))


@pytest.mark.parametrize("matrix, message", [
    (np.diag([1.0, 2.0, 1.0, 1.0]), "rigid"),
    (np.diag([1.0, 1.0, -1.0, 1.0]), "positive uniform scale"),
    (np.full((4, 4), np.nan), "non-finite"),
    (np.eye(3), "4x4"),
])
def test_a_matrix_that_is_not_a_similarity_is_refused(ball, matrix, message):
    with pytest.raises(SceneError, match=message):
        ball.set_object_transform(0, matrix)


def test_similarity_is_decomposed_exactly():
    R = rotation_about([1.0, 2.0, 3.0], 37.0)
    R2, s, t = check_motion(motion_matrix(R, [1.0, -2.0, 0.5], 1.7))
    assert np.allclose(R2, R, atol=1e-12) and s == pytest.approx(1.7) and np.allclose(t, [1.0, -2.0, 0.5])


def test_move_away_and_back_is_bit_identical(ball):
    first = ball.render().copy()
    ball.set_object_transform("object", _roll(1.1, 0.4))
    moved = ball.render().copy()
    ball.set_object_transform("object", np.eye(4))
    back = ball.render()
    assert not np.array_equal(moved, first)  # (the move shows)
    assert np.array_equal(back, first)


def test_the_renderer_geometry_is_the_scene_at_the_transform(ball):
    """What the renderer draws after a move is the scene's own geometry with the motion applied
    (``r.scene`` follows, so the reference sees the same pose): the object's extent matches."""
    ball.set_object_transform("object", _roll(0.7, -0.3))
    ball.render()
    want, g = ball.scene.geometry(), ball.geometry
    box = lambda geo: geo.vertices[np.unique(geo.triangles[geo.tri_object == 0])]  # noqa: E731
    assert np.allclose(box(g).min(0), box(want).min(0), atol=1e-4)
    assert np.allclose(box(g).max(0), box(want).max(0), atol=1e-4)
    assert box(want)[:, 0].mean() > 0.6  # (it did move)
    ball.set_object_transform("object", np.eye(4))


def test_sphere_proxy_ssdf_is_the_angular_distance_to_the_cap():
    """The analytic SSDF of a sphere against brute force: the angle from each direction to the
    nearest direction whose ray hits the sphere (dense direction sample), negative inside."""
    from precompute.visibility.proxies import sphere_ssdf

    rng = np.random.default_rng(1)
    D = rng.normal(size=(20000, 3))
    D /= np.linalg.norm(D, axis=1, keepdims=True)
    P = np.array([0.3, -0.2, 0.1])
    S = np.array([[1.0, 0.5, -0.4, 0.45]])
    v = S[0, :3] - P
    hit = (D @ v) > 0
    b = D @ v
    hit &= b * b - (v @ v - S[0, 3] ** 2) >= 0  # ray-sphere intersection
    q = D[:300]
    ang = np.arccos(np.clip(q @ D.T, -1.0, 1.0))
    brute = np.where(hit[:300], -np.where(~hit[None, :], ang, np.inf).min(1), np.where(hit[None, :], ang, np.inf).min(1))
    got = sphere_ssdf(np.broadcast_to(P, q.shape), q, S)
    assert np.max(np.abs(got - brute)) < 0.03  # the sample's spacing


def test_cap_cosine_solid_angle_matches_quadrature():
    """Ω⊥ of a cap (Snyder's closed form) against a quadrature of max(n·d, 0) over the cap, above,
    straddling and below the horizon."""
    from warp_sg.shading.motion_wp import cap_cosine_solid_angle

    @wp.kernel
    def k(c: wp.array(dtype=float), s2: wp.array(dtype=float), out: wp.array(dtype=float)):
        i = wp.tid()
        out[i] = cap_cosine_solid_angle(c[i], s2[i])

    cases = [(th, al) for th in np.radians([0.0, 30.0, 70.0, 90.0, 110.0, 150.0]) for al in np.radians([5.0, 25.0, 50.0])]
    c = wp.array([np.cos(t) for t, _ in cases], dtype=float, device="cpu")
    s2 = wp.array([np.sin(a) ** 2 for _, a in cases], dtype=float, device="cpu")
    out = wp.zeros(len(cases), dtype=float, device="cpu")
    wp.launch(k, len(cases), inputs=[c, s2, out], device="cpu")
    rng = np.random.default_rng(0)
    for (th, al), got in zip(cases, out.numpy()):
        # uniform directions in the cap around a = (sin θ, 0, cos θ), n = +Z
        u = rng.random((400000, 2))
        cz = 1.0 - u[:, 0] * (1.0 - np.cos(al))
        ph = 2 * np.pi * u[:, 1]
        sz = np.sqrt(1 - cz * cz)
        local = np.stack([sz * np.cos(ph), sz * np.sin(ph), cz], 1)
        a, e1 = np.array([np.sin(th), 0, np.cos(th)]), np.array([np.cos(th), 0, -np.sin(th)])
        d = local[:, :1] * e1 + local[:, 1:2] * np.array([0, 1.0, 0]) + local[:, 2:3] * a
        want = 2 * np.pi * (1 - np.cos(al)) * np.mean(np.maximum(d[:, 2], 0.0))
        assert got == pytest.approx(want, abs=2e-3 + 0.01 * want), (np.degrees(th), np.degrees(al))


def _self_shadow_agreement(r, la, R):
    """After a turn ``R`` of the renderer's one dynamic object under the directional light
    towards ``la``: the per-vertex SSDF towards the light (its frame turned with the object) says
    which vertices the object shadows itself; against a ray cast of the turned mesh, over the
    vertices facing the light and clear of the map's texel. Returns (fraction those vertices
    shadowed, agreement of ours, agreement of the maps left unturned: the rest pose's shadows)."""
    from precompute.visibility.occluder_cone import texel_half_diagonal
    from precompute.visibility.rays import ray_visibility

    V, N, F = r.geometry.vertices, r.geometry.normals, r.geometry.triangles
    th_h = np.arcsin(np.clip(N @ la, -1, 1))
    th_d = th_h + r.vis.light_deficit.numpy()[:, 0]  # θd towards the light, read in the turned frames
    sure = (th_h > 0.1) & (np.abs(th_d) > texel_half_diagonal(16))  # facing it, clear of the map's texel
    exact = ray_visibility(V, F, V, N, np.broadcast_to(la, V.shape)).astype(bool)
    rest = ray_visibility(V @ R, F, V @ R, N @ R, np.broadcast_to(la, V.shape)).astype(bool)
    return (np.count_nonzero(~exact & sure) / np.count_nonzero(sure), np.mean((th_d > 0)[sure] == exact[sure]),
            np.mean(rest[sure] == exact[sure]))


def _one_object_scene(ob, la):
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import DirectionalLight
    from warp_sg.scene.model import Material, Scene
    from warp_sg.scene.render_settings import RenderSettings

    return Scene(camera=Camera(origin=(0, 2, 4), target=(0, 0.5, 0), up=(0, 1, 0), fov=40, width=16, height=16),
                 objects=[ob], materials={"m": Material("lambert", {"kd": [0.6, 0.6, 0.6]})},
                 lights=[DirectionalLight(direction=tuple(la), radius=0.02, intensity=(2, 2, 2))],
                 render=RenderSettings(ssdf_resolution=16, pca_terms=16, visibility_budget=0, antialias=1))


def test_self_shadows_turn_with_the_object_against_a_ray_cast():
    """A torus (it shadows its own inner side) tilted by 45° about +Z under a directional light:
    the per-vertex SSDF towards the light, its frame turned with the object, says which vertices
    the torus shadows itself as a ray cast against the tilted torus does; the maps left unturned
    (the rest pose's shadows) would not."""
    from warp_sg.scene.model import SceneObject

    la = np.array([0.5, 0.6, 0.62]) / np.linalg.norm([0.5, 0.6, 0.62])
    ring = SceneObject(material="m", primitive="torus", name="ring", dynamic=True,
                       params={"center": (0, 0.6, 0), "major_radius": 0.45, "minor_radius": 0.18,
                               "resolution": (48, 24)})
    r = ws.Renderer(_one_object_scene(ring, la))
    c, R = np.array([0.0, 0.6, 0.0]), rotation_about([0.0, 0.0, 1.0], 45.0)
    r.set_object_transform("ring", motion_matrix(R, c - R @ c))
    r.render()
    shadowed, ours, rest = _self_shadow_agreement(r, la, R)
    assert shadowed > 0.05  # it does shadow itself
    assert ours > 0.97
    assert rest < ours - 0.1


def test_a_turned_vertexs_light_deficit_is_its_rest_deficit_towards_the_light_turned_back():
    """A rigid turn R of the object under a light towards ``la`` is, in the object's frame, the
    object at rest under the light towards ``Rᵀ la``: each vertex's SSDF deficit (read in the
    frame its map is stored in, turned with it) is the same in both, up to float rounding —
    every vertex, the self-shadowed ones included."""
    from warp_sg.scene.model import SceneObject

    la = np.array([0.5, 0.6, 0.62]) / np.linalg.norm([0.5, 0.6, 0.62])
    c, R = np.array([0.0, 0.6, 0.0]), rotation_about([0.3, 0.2, 1.0], 70.0)

    def ring():
        return SceneObject(material="m", primitive="torus", name="ring", dynamic=True,
                           params={"center": tuple(c), "major_radius": 0.45, "minor_radius": 0.18,
                                   "resolution": (48, 24)})

    turned = ws.Renderer(_one_object_scene(ring(), la))
    turned.set_object_transform("ring", motion_matrix(R, c - R @ c))
    turned.render()
    rest = ws.Renderer(_one_object_scene(ring(), R.T @ la))
    rest.render()
    a, b = turned.vis.light_deficit.numpy()[:, 0], rest.vis.light_deficit.numpy()[:, 0]
    assert np.count_nonzero(b < -0.05) > 0.05 * len(b)  # (it shadows itself)
    assert np.abs(a - b).max() < 2e-3 and np.median(np.abs(a - b)) < 1e-5


def test_bunny_self_shadows_turn_with_it_on_the_turntable_against_a_ray_cast():
    """The Stanford bunny (warp-lang's USD file, 12 200 triangles, placed as in
    ``examples/rolling.py``'s turntable) turned 150° about the vertical axis under a sun 25° high:
    its ears, head and haunch shadow the rest of it as a ray cast against the turned bunny says."""
    pytest.importorskip("pxr", reason="usd-core is not installed (pip install warp-sg[usd])")
    from warp_sg.numeric.rigid_motion import motion_about
    from warp_sg.scene.model import SceneObject, Transform
    from warp_sg.scene.plain_scenes import BUNNY_PLACEMENT, warp_bunny

    e, az = np.radians(25.0), 0.5
    la = np.array([np.cos(e) * np.sin(az), np.sin(e), np.cos(e) * np.cos(az)])
    bunny = SceneObject(material="m", mesh=warp_bunny(), name="bunny", dynamic=True,
                        transform=Transform(scale=BUNNY_PLACEMENT["scale"],
                                            translate=tuple(BUNNY_PLACEMENT["translate"])))
    r = ws.Renderer(_one_object_scene(bunny, la))
    R = rotation_about([0.0, 1.0, 0.0], 150.0)
    r.set_object_transform(0, motion_about(R, [0.0, 0.5, 0.0]))
    r.render()
    shadowed, ours, rest = _self_shadow_agreement(r, la, R)
    assert shadowed > 0.05
    assert ours > 0.97
    assert rest < ours - 0.1


def test_moved_ball_matches_the_reference_per_region(tmp_path):
    """At a pose the precompute never saw, against the Monte-Carlo reference of the scene with the
    ball there (``r.scene``): object, lit floor and the ball's shadow."""
    from warp_sg.groundtruth.region_error import box_reference, region_errors, scene_regions

    r = ws.Renderer(_scene(tmp_path, size=48, bounces=0))  # (the direct light: bounces in test_interreflection_moving)
    r.set_object_transform("object", _roll(0.9, 0.3))
    img = r.render()
    ref = box_reference(r.scene, spp=256, supersample=4, max_depth=2)  # direct light
    e = region_errors(img, ref, scene_regions(r.scene))
    assert e["shadow"]["pixels"] > 5
    assert abs(e["object"]["bias"]) < 0.05
    assert abs(e["lit_floor"]["bias"]) < 0.03
    assert abs(e["shadow"]["bias"]) < 0.2


def test_floor_outline_ssdf_is_the_angular_distance_to_the_quad():
    """The SSDF a moving object sees of a finite floor (``polygon_theta``: the angle to the quad's
    outline on the sphere of directions, negative where the ray hits it) against brute force: the
    angle from each direction to the nearest direction of the other kind (hits / misses the quad,
    by ray-plane intersection), over a dense direction sample. Above its centre, near its edge, off
    it, and below it; the infinite plane it lies in differs by up to 0.28 rad at these points."""
    from warp_sg.shading.motion_wp import polygon_theta

    @wp.kernel
    def k(verts: wp.array(dtype=wp.vec3), P: wp.vec3, D: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
        i = wp.tid()
        out[i] = polygon_theta(verts, 0, verts.shape[0], wp.vec3(0.0, 1.0, 0.0), 0.0, P, D[i])

    quad = np.array([[-3, 0, -3], [-3, 0, 3], [3, 0, 3], [3, 0, -3]], np.float64)
    rng = np.random.default_rng(3)
    D = rng.normal(size=(40000, 3))
    D /= np.linalg.norm(D, axis=1, keepdims=True)
    q = D[:400]
    ang = np.arccos(np.clip(q @ D.T, -1.0, 1.0))
    worst_plane = 0.0
    for P in ([0.0, 0.4, 0.0], [2.6, 0.3, 0.5], [4.0, 1.0, -1.0], [0.5, -0.7, 0.2]):
        P = np.asarray(P)
        s = -P[1] / np.where(np.abs(D[:, 1]) > 1e-12, D[:, 1], 1e-12)
        X = P + np.maximum(s, 0.0)[:, None] * D
        hit = (s > 0) & (np.abs(X[:, 0]) <= 3) & (np.abs(X[:, 2]) <= 3)
        brute = np.where(hit[:400], -np.where(~hit[None, :], ang, np.inf).min(1),
                         np.where(hit[None, :], ang, np.inf).min(1))
        out = wp.zeros(len(q), dtype=float, device="cpu")
        wp.launch(k, len(q), inputs=[wp.array(quad.astype(np.float32), dtype=wp.vec3, device="cpu"),
                                     wp.vec3(*P.astype(np.float32)), wp.array(q.astype(np.float32), dtype=wp.vec3,
                                                                              device="cpu"), out], device="cpu")
        got = out.numpy()
        assert np.array_equal(np.sign(got[np.abs(brute) > 0.03]), np.sign(brute[np.abs(brute) > 0.03]))
        # the nearest sample of the other kind lies beyond the true outline, within the sample's spacing
        assert np.all(np.abs(got) <= np.abs(brute) + 1e-3) and np.max(np.abs(got - brute)) < 0.03
        plane = np.arcsin(np.clip(np.sign(P[1]) * q[:, 1], -1, 1))  # the infinite plane's SSDF
        worst_plane = max(worst_plane, np.max(np.abs(plane - brute)))
    assert worst_plane > 0.25  # the outline is what the test checks, not the plane


def test_a_glossy_moving_ball_sees_the_sky_past_the_floors_edge(tmp_path):
    """A dynamic Blinn–Phong ball at rest on a 6 × 6 floor under the sky, against the Monte-Carlo
    reference: its lower half reflects the floor near the horizon, where the lobe straddles the
    floor's outline; the proxies' cut is the outline's (not the infinite plane's) and the lobe's
    mean radiance is read on its visible part (before: −9.4 % on the object, −43 % just below its
    equator)."""
    from warp_sg.groundtruth.region_error import box_reference, region_errors, scene_regions

    sc = ws.load_scene(write_plain_scene(tmp_path, material="blinn_phong", size=40, dynamic=True,
                                         render={"ssdf_resolution": 16, "pca_terms": 16, "visibility_budget": 4000,
                                                 "bounces": 0}))
    r = ws.Renderer(sc)
    img = r.render()
    ref = box_reference(r.scene, spp=256, supersample=4, max_depth=2)  # direct light
    regions = scene_regions(r.scene)
    e = region_errors(img, ref, regions)
    assert abs(e["object"]["bias"]) < 0.03
    obj = regions["object"]
    rows = np.nonzero(obj.any(1))[0]
    lower = obj.copy()
    lower[: rows[0] + (rows[-1] - rows[0]) // 2] = False  # the ball's lower half in the image
    assert img[lower].mean() == pytest.approx(ref[lower].mean(), rel=0.06)


def test_outline_cosine_solid_angle_matches_quadrature():
    """Lambert's formula on a floor quad clipped to a tilted receiver's horizon, against a
    Monte-Carlo estimate of ∫ max(n·d, 0) over the directions that hit the quad."""
    from warp_sg.shading.motion_wp import polygon_cosine_solid_angle

    @wp.kernel
    def k(verts: wp.array(dtype=wp.vec3), P: wp.array(dtype=wp.vec3), n: wp.array(dtype=wp.vec3),
          out: wp.array(dtype=float)):
        i = wp.tid()
        out[i] = polygon_cosine_solid_angle(verts, 0, verts.shape[0], P[i], n[i])

    quad = np.array([[-3, 0, -3], [-3, 0, 3], [3, 0, 3], [3, 0, -3]], np.float64)
    Ps = np.array([[0.0, 0.5, 0.0], [1.0, 0.2, -2.0], [0.3, 0.05, 0.1], [0.0, 1.0, 0.0]])
    ns = np.array([[1.0, 0.0, 0.0], [0.6, -0.8, 0.0], [0.0, -1.0, 0.0], [0.0, 0.6, 0.8]])
    out = wp.zeros(len(Ps), dtype=float, device="cpu")
    wp.launch(k, len(Ps), inputs=[wp.array(quad.astype(np.float32), dtype=wp.vec3, device="cpu"),
                                  wp.array(Ps.astype(np.float32), dtype=wp.vec3, device="cpu"),
                                  wp.array(ns.astype(np.float32), dtype=wp.vec3, device="cpu"), out], device="cpu")
    rng = np.random.default_rng(2)
    D = rng.normal(size=(400000, 3))
    D /= np.linalg.norm(D, axis=1, keepdims=True)
    for P, n, got in zip(Ps, ns, out.numpy()):
        down = D[:, 1] < 0
        s = -P[1] / np.where(down, D[:, 1], -1.0)
        X = P + s[:, None] * D
        hits = down & (np.abs(X[:, 0]) <= 3) & (np.abs(X[:, 2]) <= 3)
        want = 4 * np.pi * np.mean(np.where(hits, np.maximum(D @ n, 0.0), 0.0))
        assert got == pytest.approx(want, abs=0.01 + 0.01 * want)


def test_batch_variants_move_objects_like_the_setter(ball):
    """A job's ``objects.NAME`` fields (translate/rotate/pivot) are the motion of
    ``set_object_transform``: the same frame; a static object or an unknown field is refused."""
    from warp_sg.core.errors import InputError
    from warp_sg.distributed.rendering import apply_variant, normalize_variants
    from warp_sg.numeric.rigid_motion import motion_from_fields

    fields = {"translate": [0.4, 0.0, 0.2], "rotate": [0.0, 30.0, 0.0], "pivot": [0.0, 0.5, 0.0]}
    v = normalize_variants(ball.scene, [{"objects": {"object": fields}}, {"camera": {"fov": 40.0}}])
    assert v[1]["objects"]["object"]["translate"] == [0.0, 0.0, 0.0]  # the base value filled in
    apply_variant(ball, v[0])
    a = ball.render().copy()
    M = motion_from_fields(fields)
    assert np.allclose(M[:3, :3] @ [0.0, 0.5, 0.0] + M[:3, 3], [0.4, 0.5, 0.2])  # the pivot stays put (moved)
    ball.set_object_transform("object", M)
    assert np.array_equal(ball.render(), a)
    with pytest.raises(InputError, match="not dynamic"):
        normalize_variants(ball.scene, [{"objects": {"floor": {"translate": [1, 0, 0]}}}])
    with pytest.raises(InputError, match="unknown object field"):
        normalize_variants(ball.scene, [{"objects": {"object": {"spin": 3}}}])
    ball.set_object_transform("object", np.eye(4))


def test_reference_cli_takes_a_transform(tmp_path, capsys):
    """``warp-sg reference --transform OBJECT=16 numbers`` renders the moved scene; a malformed
    one is one line and exit status 2, before any work."""
    from warp_sg.tools.cli import main

    path = write_plain_scene(tmp_path, size=8, dynamic=True)
    M = ",".join(str(x) for x in _roll(0.5).ravel())
    assert main(["reference", str(path), "-o", str(tmp_path / "r.exr"), "--spp", "4", "--no-progress",
                 "--transform", f"object={M}"]) == 0
    assert (tmp_path / "r.exr").exists()
    assert main(["reference", str(path), "-o", str(tmp_path / "s.exr"), "--transform", "object=1,2,3"]) == 2
    err = capsys.readouterr().err
    assert "--transform" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s.exr").exists()


def test_a_transform_set_before_progressive_shadows_arrive_is_kept(tmp_path):
    """A progressive renderer moved while its SSDFs are still computing: once they are installed
    (the refined mesh replaces the input one) the frame equals a renderer built with them at once
    and moved the same way."""
    sc = _scene(tmp_path, size=24)
    M = _roll(0.8, 0.2)
    p = ws.Renderer(sc, progressive=True)
    p.set_object_transform("object", M)
    p.render()
    assert p.wait(120)
    r = ws.Renderer(_scene(tmp_path / "again", size=24))
    r.set_object_transform("object", M)
    assert np.array_equal(p.render(), r.render())


def test_a_dynamic_object_keeps_its_own_vertices_unless_given_a_moving_budget(tmp_path):
    """Each moving vertex costs every frame the object moves: by default the refinement adds none
    to a dynamic object (``[render] moving_visibility_budget = 0``), and the floor keeps its
    pre-split (its vertices see only the static group, which cannot shadow itself: no edge is split
    for the blob's shadow where it stood); with a moving budget the blob, which shadows itself,
    gets at most that many more."""
    def counts(**render):  # (the object's, the floor's and the moving vertices)
        r = ws.Renderer(_scene(tmp_path / f"b{len(render)}", obj="blob", **render))
        per = np.bincount(np.asarray(r.geometry.vertex_object), minlength=2)
        return int(per[0]), int(per[1]), int(r.dynamic.all_ids.shape[0])

    own = ws.Renderer(_scene(tmp_path / "own", obj="blob", shadows=False))  # no refinement: the blob's mesh
    n_own = int(np.bincount(np.asarray(own.geometry.vertex_object))[0])
    blob, floor, moving = counts()
    assert blob == moving == n_own
    assert floor == 33 * 33  # the floor's uniform pre-split only
    more, floor2, moving2 = counts(moving_visibility_budget=150)
    assert blob < more <= blob + 150 and moving2 == more
    assert floor2 == floor
