"""warp_sg.tools.peer_mitsuba: Mitsuba 3 renders of our scenes agree with our Monte-Carlo reference.

Two independent renderers of the same light transport (exact visibility, Lambert BRDF, paths of
at most 8 segments — light that bounces between the sphere and the floor — or 2, direct light
only): Mitsuba 3's path tracer (``path``, the same ``max_depth``) on the converted scene, and our
reference (``warp_sg.groundtruth.region_error.box_reference``). Agreement within their combined noise checks our reference
*and* the converter (camera convention, image orientation, envmap axes and rotation, light
units). Pixels whose footprint straddles a silhouette are left out of the noise test: Mitsuba
box-filters the pixel area, our reference averages a k×k grid of points, and the two differ there
by design.

Mitsuba is the optional ``[compare]`` extra: without it (CI) the module skips with that reason.
"""
from __future__ import annotations

import numpy as np
import pytest

from warp_sg.tools import peer_mitsuba as P

try:
    import mitsuba as mi
except ImportError:  # the optional [compare] extra: mitsuba_status says so and the module skips
    mi = None

OK, WHY = P.mitsuba_status("cpu")
if not OK:
    pytest.skip(f"Mitsuba 3 is the optional [compare] extra and is not usable here: {WHY}", allow_module_level=True)

SIZE = 48  # pixels (square)
REF_SPP = 1024  # our reference: samples per pixel (4×4 sub-pixels × 64)
MI_SPP, MI_BATCHES = 256, 4  # Mitsuba: independent batches give its per-pixel standard error


@pytest.fixture(scope="module")
def plain_folder(tmp_path_factory):
    return tmp_path_factory.mktemp("plain")


def _scene(folder, light):
    from warp_sg.scene.loader import load_scene
    from warp_sg.scene.plain_scenes import write_plain_scene

    return load_scene(write_plain_scene(folder / light, obj="sphere", light=light, material="lambert", size=SIZE))


def _compare(scene, max_depth=None):
    """(chi² per degree of freedom off the silhouettes, {region: relative bias, its 1σ}) at paths of
    ``max_depth`` segments (default the full depth of both)."""
    from warp_sg.groundtruth.region_error import box_reference, scene_regions

    ref, ref_se = box_reference(scene, spp=REF_SPP, supersample=4, seed=5, return_stderr=True, max_depth=max_depth)
    mi_img, mi_se = P.mitsuba_mean(P.mitsuba_scene(scene, max_depth=max_depth), MI_SPP, MI_BATCHES, seed=17)
    regions = scene_regions(scene, supersample=8)
    keep = ~regions["silhouette"]
    d2 = ((mi_img.astype(np.float64) - ref) ** 2)[keep]
    var = (mi_se.astype(np.float64) ** 2 + ref_se.astype(np.float64) ** 2)[keep]
    chi2 = float(d2.sum() / var.sum())
    bias = {}
    for name, mask in regions.items():
        if name == "silhouette" or mask.sum() < 20:
            continue
        r, m = ref[mask].sum(), mi_img[mask].astype(np.float64).sum()
        sigma = float(np.sqrt((ref_se[mask].astype(np.float64) ** 2).sum() + (mi_se[mask].astype(np.float64) ** 2).sum())) / r
        bias[name] = (m / r - 1.0, sigma)
    return chi2, bias


def _assert_agree(chi2, bias):
    assert 0.6 < chi2 < 1.5, f"Mitsuba and our reference differ beyond their noise: chi²/dof = {chi2:.3f}"
    for name, (b, sigma) in bias.items():
        assert abs(b) < max(0.003, 4 * sigma), f"{name}: Mitsuba/reference − 1 = {b:+.4f} (1σ = {sigma:.4f})"


@pytest.mark.parametrize("max_depth", [None, 2], ids=["full-depth", "direct-only"])
def test_sun_sky_lambert_sphere_and_floor_agree_with_reference_within_noise(plain_folder, max_depth):
    # environment only; rotated so that the envmap axes *and* the rotation convention are tested
    scene = _scene(plain_folder, "sky")
    scene.environment.rotation = 40.0
    _assert_agree(*_compare(scene, max_depth))


def test_full_depth_reference_adds_the_interreflected_light_mitsuba_adds(plain_folder):
    # the light that bounces between the sphere and the floor (a few per cent of the image) is
    # there in both, equally: the full-depth images differ from the direct-only ones by the same
    from warp_sg.groundtruth.region_error import box_reference

    scene = _scene(plain_folder, "point")
    ours = [box_reference(scene, spp=256, supersample=4, seed=9, max_depth=d).astype(np.float64).sum() for d in (2, 8)]
    theirs = [P.mitsuba_mean(P.mitsuba_scene(scene, max_depth=d), 256, 2, seed=3)[0].astype(np.float64).sum()
              for d in (2, 8)]
    added, mi_added = ours[1] / ours[0] - 1, theirs[1] / theirs[0] - 1
    assert added > 0.005 and abs(added - mi_added) < 0.15 * mi_added, (added, mi_added)


def test_point_light_lambert_sphere_and_floor_agree_with_reference_within_noise(plain_folder):
    _assert_agree(*_compare(_scene(plain_folder, "point")))


def test_mitsuba_envmap_lookup_equals_our_bilinear_lookup_with_rotation():
    # Mitsuba's own emitter evaluated at random directions vs warp_sg.scene.envmap.env_lookup_numpy
    from warp_sg.scene.envmap import env_lookup_numpy
    from warp_sg.scene.lights import EnvironmentLight

    rng = np.random.default_rng(0)
    env = rng.random((12, 24, 3)).astype(np.float32) + 0.1
    light = EnvironmentLight(data=env, rotation=40.0, scale=1.5)
    emitter = mi.load_dict(P.envmap_dict(light))
    d = rng.normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*(-d.T).astype(np.float32))  # Mitsuba looks up the direction −wi
    got = np.array(emitter.eval(si)).T
    want = 1.5 * env_lookup_numpy(env, d, rotation=light.rotation_matrix())
    np.testing.assert_allclose(got, want, rtol=2e-4, atol=2e-5)


def test_glossy_and_textured_materials_are_refused_with_the_material_named(plain_folder):
    from warp_sg.scene.loader import load_scene
    from warp_sg.scene.plain_scenes import write_plain_scene

    scene = load_scene(write_plain_scene(plain_folder / "ct", obj="sphere", light="sky", material="cook_torrance",
                                         size=8))
    with pytest.raises(P.NotExpressible, match="object.*CookTorrance"):
        P.mitsuba_scene_dict(scene)
