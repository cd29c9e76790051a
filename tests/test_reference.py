"""Monte-Carlo reference: convergence to analytic answers, unbiasedness, stderr, lights, supersampling.

Most tests look at a large plane with *parallel* primary rays (orthographic), so every pixel is an
independent estimate of the same integral: the image mean is a precise estimate and the spread
over pixels and seeds checks the reported standard error.
"""
from __future__ import annotations

import numpy as np
import pytest

from warp_sg.brdf import BlinnPhong, CookTorrance, Lambert, TorranceSparrow, Ward
from warp_sg.groundtruth.reference import Light, ReferenceInputs, render_reference_inputs

PLANE_V = np.array([[-50, 0, -50], [50, 0, -50], [50, 0, 50], [-50, 0, 50]], float)
PLANE_T = np.array([[0, 2, 1], [0, 3, 2]])


def ortho_rays(n=8, view=(0.0, -1.0, 0.0), extent=1.0, height=3.0):
    """n×n parallel rays towards the plane y = 0 (pixel centres of a square of side 2·extent)."""
    v = np.asarray(view, float)
    v = v / np.linalg.norm(v)
    c = (np.arange(n) + 0.5) / n * 2 * extent - extent
    xs, zs = np.meshgrid(c, c)
    targets = np.stack([xs, np.zeros_like(xs), zs], -1)
    origins = targets - v * height / max(-v[1], 1e-3)
    return origins, np.broadcast_to(v, origins.shape).copy()


def plane_inputs(material, n=8, view=(0.0, -1.0, 0.0), env=None, lights=(), supersample=1, extent=1.0):
    o, d = ortho_rays(n, view, extent)
    return ReferenceInputs(PLANE_V, PLANE_T, np.zeros(2, int), [material], o, d, supersample=supersample,
                           lights=list(lights), environment=env)


def albedo_quadrature(model, o, n_theta=400, n_phi=800):
    """∫ f(o, i) cos θi dωi by Gauss-Legendre in cos θ × midpoint in φ (float64)."""
    x, w = np.polynomial.legendre.leggauss(n_theta)
    mu = 0.5 * (x + 1.0)  # cos θ in (0, 1)
    wm = 0.5 * w
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    M, P = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - M * M)
    i = np.stack([s * np.cos(P), s * np.sin(P), M], -1)
    f = model.eval(np.broadcast_to(o, i.shape), i)
    return np.einsum("tpc,t->c", f * M[..., None], wm) * (2 * np.pi / n_phi)


def mean_and_se(res):
    m = res.image.reshape(-1, 3).astype(np.float64).mean(0)
    se = np.sqrt(np.sum(res.stderr.reshape(-1, 3).astype(np.float64) ** 2, 0)) / res.image[..., 0].size
    return m, se


CONST_L = np.array([1.0, 0.6, 0.3])


def const_env(h=8, w=16):
    return np.ones((h, w, 3)) * CONST_L


def test_lambert_plane_in_constant_environment_is_kd_times_L(device):
    res = render_reference_inputs(plane_inputs(Lambert(kd=[0.5, 0.8, 0.2]), env=const_env()), spp=64,
                                  device=device, progress=False)
    exact = np.array([0.5, 0.8, 0.2]) * CONST_L
    m, se = mean_and_se(res)
    assert np.all(np.abs(m - exact) < 4 * se + 1e-6), (m, exact, se)
    assert np.all(se < 0.01 * exact)
    assert np.isfinite(res.image).all() and res.image.shape == (8, 8, 3)


def _uv_sphere(n_lat=48, n_lon=96, r=1.0):
    th = np.linspace(0, np.pi, n_lat + 1)
    ph = np.linspace(0, 2 * np.pi, n_lon + 1)[:-1]
    T, P = np.meshgrid(th, ph, indexing="ij")
    v = np.stack([np.sin(T) * np.cos(P), np.cos(T), np.sin(T) * np.sin(P)], -1).reshape(-1, 3)
    tris = []
    for a in range(n_lat):
        for b in range(n_lon):
            i0 = a * n_lon + b
            i1 = a * n_lon + (b + 1) % n_lon
            i2 = (a + 1) * n_lon + b
            i3 = (a + 1) * n_lon + (b + 1) % n_lon
            tris += [[i0, i2, i1], [i1, i2, i3]]
    return v * r, np.array(tris), v


def test_lambert_sphere_in_constant_environment_is_kd_times_L_with_shading_normals(device):
    v, t, nrm = _uv_sphere()
    n = 8
    c = (np.arange(n) + 0.5) / n * 1.2 - 0.6  # inside the silhouette
    xs, ys = np.meshgrid(c, c)
    org = np.stack([xs, ys, np.full_like(xs, 5.0)], -1)
    d = np.broadcast_to([0.0, 0.0, -1.0], org.shape).copy()
    inp = ReferenceInputs(v, t, np.zeros(len(t), int), [Lambert(kd=0.7)], org, d, normals=nrm,
                          environment=const_env())
    res = render_reference_inputs(inp, spp=32, device=device, progress=False)
    m, se = mean_and_se(res)
    exact = 0.7 * CONST_L
    # tessellation: directions between the shading and the geometric tangent planes are blocked
    assert np.all(np.abs(m - exact) < 4 * se + 2e-3 * exact), (m, exact, se)


@pytest.mark.parametrize(
    "model",
    [TorranceSparrow(kd=0.1, ks=0.8, m=0.3), CookTorrance(ks=0.9, m=0.25), Ward(kd=0.2, ks=0.5, alpha=0.2),
     BlinnPhong(kd=0.3, ks=0.1, n=40.0)],
    ids=lambda m: type(m).__name__,
)
def test_white_furnace_gives_quadrature_albedo_times_L(device, model):
    view = np.array([0.5, -0.8, 0.2])
    view /= np.linalg.norm(view)
    from warp_sg.numeric.onb import to_local  # the plane's local frame (normal +y)

    o_local = to_local(-view, np.array([0.0, 1.0, 0.0]))
    albedo = albedo_quadrature(model, o_local)
    env = np.ones((8, 16, 3))
    res = render_reference_inputs(plane_inputs(model, view=view, env=env), spp=64, device=device, progress=False)
    m, se = mean_and_se(res)
    assert np.all(np.abs(m - albedo) < 4.5 * se + 2e-3 * albedo), (m, albedo, se)
    if isinstance(model, TorranceSparrow):
        assert np.all(albedo < 1.0)  # energy conserving


def test_independent_seeds_average_to_the_analytic_value_and_stderr_matches_spread(device):
    model = TorranceSparrow(kd=0.3, ks=0.6, m=0.35)
    view = np.array([0.0, -1.0, 0.6])
    view /= np.linalg.norm(view)
    from warp_sg.numeric.onb import to_local

    albedo = albedo_quadrature(model, to_local(-view, np.array([0.0, 1.0, 0.0])))
    env = np.ones((8, 16, 3)) * np.linspace(0.2, 2.0, 16)[None, :, None]  # not constant: exercises the CDF
    means, ses = [], []
    for seed in range(12):
        res = render_reference_inputs(plane_inputs(model, n=4, view=view, env=np.ones((8, 16, 3))), spp=4,
                                      device=device, progress=False, seed=seed)
        m, se = mean_and_se(res)
        means.append(m)
        ses.append(se)
    means = np.array(means)
    ses = np.array(ses)
    grand = means.mean(0)
    se_grand = np.sqrt(np.sum(ses ** 2, 0)) / len(means)
    assert np.all(np.abs(grand - albedo) < 4 * se_grand), (grand, albedo, se_grand)
    spread = means.std(0, ddof=1)
    ratio = spread / ses.mean(0)
    assert np.all((ratio > 0.45) & (ratio < 1.8)), ratio
    # the non-constant map: seeds agree with each other within their stderr
    a = render_reference_inputs(plane_inputs(model, n=4, view=view, env=env), spp=16, device=device,
                                progress=False, seed=1)
    b = render_reference_inputs(plane_inputs(model, n=4, view=view, env=env), spp=16, device=device,
                                progress=False, seed=2)
    (ma, sa), (mb, sb) = mean_and_se(a), mean_and_se(b)
    assert np.all(np.abs(ma - mb) < 4.5 * np.hypot(sa, sb))
    assert not np.allclose(a.image, b.image)  # different seeds, different noise


def test_stderr_shrinks_like_one_over_sqrt_spp(device):
    inp = plane_inputs(Ward(kd=0.2, ks=0.5, alpha=0.25), env=const_env())
    r1 = render_reference_inputs(inp, spp=8, device=device, progress=False)
    r2 = render_reference_inputs(inp, spp=128, device=device, progress=False)
    ratio = r1.stderr.mean() / r2.stderr.mean()
    assert 3.0 < ratio < 5.3  # sqrt(16) = 4
    assert r2.spp == 128 and r2.passes > 1
    assert [h[0] for h in r2.history][-1] == 128


@pytest.mark.parametrize("radius", [0.0, 0.05, 0.5])
def test_sphere_light_gives_exact_lambert_irradiance(device, radius):
    # a sphere of radiance s/(πr²) fully above the horizon gives E = s cos β / d² (exact)
    s = np.array([20.0, 10.0, 5.0])
    lp = np.array([0.3, 2.0, -0.4])
    kd = 0.6
    inp = plane_inputs(Lambert(kd=kd), lights=[Light("point", position=lp, radius=radius, intensity=s)])
    res = render_reference_inputs(inp, spp=32, device=device, progress=False)
    o, _ = ortho_rays(8)
    x = o.copy()
    x[..., 1] = 0.0
    rel = lp - x
    d2 = np.sum(rel ** 2, -1)
    cosb = rel[..., 1] / np.sqrt(d2)
    exact = kd / np.pi * s * (cosb / d2)[..., None]
    err = np.abs(res.image - exact)
    assert np.all(err < 5 * res.stderr + 1e-4 * exact), np.max(err / exact)
    if radius == 0.0:
        assert np.all(res.stderr <= 1e-4 * exact)  # zero variance up to rounding


@pytest.mark.parametrize("radius", [0.0, 0.02, 0.3])
def test_directional_cone_gives_irradiance_E_cos_beta(device, radius):
    E = np.array([3.0, 2.0, 1.0])
    to_light = np.array([0.3, 1.0, 0.2])
    to_light /= np.linalg.norm(to_light)
    kd = 0.5
    inp = plane_inputs(Lambert(kd=kd), lights=[Light("directional", direction=to_light, radius=radius, intensity=E)])
    res = render_reference_inputs(inp, spp=32, device=device, progress=False)
    exact = kd / np.pi * E * to_light[1]
    m, se = mean_and_se(res)
    assert np.all(np.abs(m - exact) < 4 * se + 1e-5 * exact), (m, exact, se)


def test_occluder_casts_an_exact_shadow_from_a_delta_light(device):
    # a small square at y = 1 over the centre of the plane blocks a light straight above
    occ = np.array([[-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5]], float)
    v = np.concatenate([PLANE_V, occ])
    t = np.concatenate([PLANE_T, PLANE_T + 4])
    o, d = ortho_rays(8, extent=1.0)
    o[..., 1] = 0.5  # start rays below the occluder so they see the plane
    inp = ReferenceInputs(v, t, np.zeros(4, int), [Lambert(kd=1.0)], o, d,
                          lights=[Light("directional", direction=[0, 1, 0], radius=0.0, intensity=np.pi)])
    img = render_reference_inputs(inp, spp=1, device=device, progress=False, max_depth=2).image  # direct light
    x = np.abs(o[..., 0])
    z = np.abs(o[..., 2])
    shadowed = (x < 0.5) & (z < 0.5)
    assert np.all(img[shadowed] == 0)
    np.testing.assert_allclose(img[~shadowed], 1.0, rtol=1e-5)


def test_supersampling_box_averages_the_subpixel_grid(device):
    # zero-variance setup (delta light, Lambert): supersample 2 == 2×2 average of the fine image
    occ = np.array([[-0.33, 1, -0.21], [0.47, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.29]], float)
    v = np.concatenate([PLANE_V, occ])
    t = np.concatenate([PLANE_T, PLANE_T + 4])
    o, d = ortho_rays(16)
    o[..., 1] = 0.5
    light = [Light("point", position=[0.2, 3.0, 0.1], radius=0.0, intensity=10.0)]
    fine = ReferenceInputs(v, t, np.zeros(4, int), [Lambert(kd=0.8)], o, d, lights=light)
    coarse = ReferenceInputs(v, t, np.zeros(4, int), [Lambert(kd=0.8)], o, d, supersample=2, lights=light)
    a = render_reference_inputs(fine, spp=1, device=device, progress=False, max_depth=2).image  # direct light
    b = render_reference_inputs(coarse, spp=1, device=device, progress=False, max_depth=2).image
    assert b.shape == (8, 8, 3)
    np.testing.assert_allclose(b, a.reshape(8, 2, 8, 2, 3).mean((1, 3)), rtol=1e-6)
    # the fine image in closed form: kd/π · s cos θ / r² where the segment to the light misses the
    # occluder (two triangles at y = 1), 0 where it crosses them
    x = o.copy()
    x[..., 1] = 0.0  # hit points on the plane
    lp = np.array([0.2, 3.0, 0.1])
    q = x + (1.0 / lp[1]) * (lp - x)  # where the segment crosses y = 1
    q2 = q[..., [0, 2]]

    def in_tri(pt, t0, t1, t2):
        cross = lambda u, w: u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0]  # noqa: E731
        s1, s2, s3 = cross(t1 - t0, pt - t0), cross(t2 - t1, pt - t1), cross(t0 - t2, pt - t2)
        return ((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))

    o2 = occ[:, [0, 2]]
    blocked = in_tri(q2, o2[0], o2[2], o2[1]) | in_tri(q2, o2[0], o2[3], o2[2])
    r2 = np.sum((lp - x) ** 2, -1)
    exact = np.where(blocked, 0.0, 0.8 / np.pi * 10.0 * lp[1] / np.sqrt(r2) / r2)
    np.testing.assert_allclose(a[..., 0], exact, rtol=1e-5, atol=1e-7)
    box = exact.reshape(8, 2, 8, 2).mean((1, 3))
    np.testing.assert_allclose(b[..., 0], box, rtol=1e-5, atol=1e-7)
    mixed = blocked.reshape(8, 2, 8, 2).any((1, 3)) & ~blocked.reshape(8, 2, 8, 2).all((1, 3))
    assert mixed.sum() >= 4 and blocked.sum() >= 8 and (~blocked).sum() >= 8  # shadow, light and both in a pixel


def test_cpu_thread_split_is_deterministic_and_equals_one_launch():
    inp = plane_inputs(BlinnPhong(kd=0.3, ks=0.2, n=20.0), env=const_env())
    a = render_reference_inputs(inp, spp=8, device="cpu", progress=False, threads=1, seed=5)
    b = render_reference_inputs(inp, spp=8, device="cpu", progress=False, threads=2, seed=5)
    np.testing.assert_array_equal(a.image, b.image)


def test_background_shows_the_environment_or_black(device):
    env = np.ones((8, 16, 3)) * np.random.default_rng(0).uniform(0.5, 1.5, (8, 1, 3))  # constant per row
    o, d = ortho_rays(4, view=(0.0, 1.0, 0.0))
    o[..., 1] = 1.0  # above the plane, looking up: nothing is hit
    inp = ReferenceInputs(PLANE_V, PLANE_T, np.zeros(2, int), [Lambert()], o, d, environment=env)
    img = render_reference_inputs(inp, spp=2, device=device, progress=False).image
    np.testing.assert_allclose(img, np.broadcast_to(env[0, 0], img.shape), rtol=1e-6)  # top row = straight up
    inp.background = False
    img = render_reference_inputs(inp, spp=2, device=device, progress=False).image
    assert np.all(img == 0)


def test_progress_callback_sees_growing_spp_and_time():
    seen = []
    inp = plane_inputs(Lambert(kd=0.5), n=4, env=const_env())
    render_reference_inputs(inp, spp=20, progress=True, callback=lambda s, t, im, se: seen.append((s, t, im.shape)))
    spps = [s for s, _, _ in seen]
    assert spps[0] == 1 and spps[-1] == 20 and all(np.diff(spps) > 0)
    assert all(np.diff([t for _, t, _ in seen]) >= 0)
    assert seen[0][2] == (4, 4, 3)


def test_bad_spp_is_an_input_error():
    from warp_sg.core.errors import InputError

    with pytest.raises(InputError, match="spp"):
        render_reference_inputs(plane_inputs(Lambert()), spp=0, progress=False)


def test_textured_kd_matches_the_bilinear_texture_times_L(device):
    from warp_sg.scene.textures import sample_bilinear_np

    rng = np.random.default_rng(3)
    tex = np.concatenate([rng.uniform(0.1, 0.9, (4, 4, 3)), np.ones((4, 4, 1))], -1).astype(np.float32)
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)  # plane corners (x, z) -> uv
    slots = -np.ones((1, 6), np.int32)
    slots[0, 0] = 0
    o, d = ortho_rays(8, extent=40.0)
    inp = ReferenceInputs(PLANE_V, PLANE_T, np.zeros(2, int), [Lambert(kd=0.5)], o, d, environment=const_env(),
                          uvs=uvs, texture_slots=slots, texture_images=[tex])
    res = render_reference_inputs(inp, spp=16, device=device, progress=False)
    hit = o.copy()
    uv = np.stack([(hit[..., 0] + 50) / 100, (hit[..., 2] + 50) / 100], -1)
    expected = sample_bilinear_np(tex, uv)[..., :3] * CONST_L
    assert np.all(np.abs(res.image - expected) < 5 * res.stderr + 1e-3 * expected)


@pytest.mark.parametrize("case", ["point-light-specular", "sky-diffuse"])
def test_reference_and_sg_renderer_agree_on_a_convex_object(case, cache_dir):
    """Same camera, lights, environment orientation and units: the SG renderer is within its
    approximation error of the reference (a convention mismatch would be off by far more)."""
    import warp_sg as ws
    from warp_sg.groundtruth.reference import render_reference
    from warp_sg.groundtruth.region_error import image_errors
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import EnvironmentLight, PointLight
    from warp_sg.scene.model import Scene, SceneObject
    from warp_sg.scene.render_settings import RenderSettings

    cam = Camera(origin=(0, 0.5, 3), target=(0, 0.5, 0), up=(0, 1, 0), fov=30, width=16, height=16)
    if case == "point-light-specular":
        lights, mat = [PointLight(position=(1.5, 2, 2), radius=0.2, intensity=(5, 5, 5))], \
            TorranceSparrow(kd=0.1, ks=0.8, m=0.3)
    else:
        lights, mat = [EnvironmentLight(procedural="sky", rotation=40.0)], Lambert(kd=0.7)
    sc = Scene(camera=cam, objects=[SceneObject(material="m", primitive="sphere",
                                                params={"center": (0, 0.5, 0), "radius": 0.6})],
               materials={"m": mat}, lights=lights, render=RenderSettings(shadows=False, background=False))
    img = ws.render(sc)  # antialiased by default: compare with the box-filtered reference
    from warp_sg.groundtruth.region_error import box_reference

    ref = box_reference(sc, spp=2048, supersample=8)
    assert render_reference(sc, spp=8, progress=False).image.shape == ref.shape
    assert 0.8 < img.sum() / ref.sum() < 1.2
    e = image_errors(img, ref)
    assert e["rel_mse"] < 0.06 and e["psnr_db"] > 27
    dark = ref.sum(-1) == 0  # background or unlit: the renderer shows at most SG tails there
    assert np.all(img.sum(-1)[dark] < 0.02 * img.sum(-1).max())


# ------------------------------------------------------------------------- paths (max_depth)
def _furnace_inputs(albedo: float, emission: float, n: int = 6):
    """Camera rays from the centre of a closed, faceted sphere whose inside emits ``emission`` and
    reflects with Lambert albedo ``albedo`` (no lights, no environment): every point sees the same
    radiance, ``Le Σ_{k < depth − 1} ρ^k`` for paths of at most ``depth`` segments, ``Le/(1 − ρ)``
    without a cap (a geometric series; the radiosity of an enclosure)."""
    from warp_sg.scene.material_layers import MaterialLayers

    v, t, _ = _uv_sphere(12, 24)
    rng = np.random.default_rng(0)
    d = rng.normal(size=(n, n, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    org = np.zeros_like(d)
    # no shading normals: the faces' own (two-sided), so every cosine sample stays in the enclosure
    return ReferenceInputs(v, t, np.zeros(len(t), int), [Lambert(kd=albedo)], org, d,
                           layers=[MaterialLayers(emission=(emission,) * 3)])


@pytest.mark.parametrize("depth", [1, 2, 3, 5, 8, -1])
def test_closed_emitting_sphere_gives_the_geometric_series_of_its_albedo(device, depth):
    rho, le = 0.6, 1.5
    res = render_reference_inputs(_furnace_inputs(rho, le), spp=256, device=device, progress=False, max_depth=depth,
                                  seed=3)
    exact = le / (1 - rho) if depth < 0 else le * sum(rho ** k for k in range(max(depth - 1, 1)))
    m, se = mean_and_se(res)
    # below the Russian roulette's depth every path is exact: no variance at all
    assert np.all(np.abs(m - exact) < 4 * se + 1e-4 * exact), (depth, m, exact, se)


def test_direct_light_only_is_max_depth_two_and_more_depth_adds_light(device):
    # the plane and the square above it light each other once light bounces: the shadow gets the
    # light the plane sends to the square's underside and back (two bounces)
    occ = np.array([[-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5]], float)
    v = np.concatenate([PLANE_V, occ])
    t = np.concatenate([PLANE_T, PLANE_T + 4])
    o, d = ortho_rays(8, extent=1.0)
    o[..., 1] = 0.5
    inp = ReferenceInputs(v, t, np.zeros(4, int), [Lambert(kd=0.8)], o, d,
                          lights=[Light("directional", direction=[0.3, 1, 0.2] / np.linalg.norm([0.3, 1, 0.2]),
                                        radius=0.0, intensity=np.pi)])
    direct = render_reference_inputs(inp, spp=16, device=device, progress=False, max_depth=2, seed=1).image
    full = render_reference_inputs(inp, spp=16, device=device, progress=False, seed=1).image
    assert np.all(full >= direct - 1e-6) and full.mean() > direct.mean() * 1.01
    shadowed = direct[..., 0] == 0
    assert shadowed.sum() >= 4 and full[shadowed].mean() > 0.01 * full.mean()


@pytest.mark.parametrize("bad", [0, -2, 1.5, "x"])
def test_bad_max_depth_is_an_input_error(bad):
    from warp_sg.core.errors import InputError

    with pytest.raises(InputError, match="max_depth"):
        render_reference_inputs(plane_inputs(Lambert()), spp=1, progress=False, max_depth=bad)
