"""warp_sg.scene.envmap: the Mitsuba equirectangular convention, solid angles, loading/validation,
the procedural sky and lookup-time rotation."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_sg.core.errors import ImageError
from warp_sg.core.image_io import save_image
from warp_sg.scene import envmap as em
from warp_sg.scene import sky as sk


def test_convention_matches_mitsuba_axes():
    # Mitsuba envmap: -z is u = 0 (left edge / wrap), +x is u = 1/4, +z is u = 1/2, -x is u = 3/4;
    # +y is the top row (v = 0), -y the bottom row (v = 1).
    dirs = np.array([[0, 0, -1], [1, 0, 0], [0, 0, 1], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], float)
    u, v = em.dir_to_uv(dirs)
    assert np.allclose(u[:4], [0.0, 0.25, 0.5, 0.75])
    assert np.allclose(v, [0.5, 0.5, 0.5, 0.5, 0.0, 1.0])


def test_uv_to_dir_inverts_dir_to_uv():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(1000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    u, v = em.dir_to_uv(d)
    assert np.all((u >= 0) & (u < 1))
    assert np.allclose(em.uv_to_dir(u, v), d, atol=1e-12)


@wp.kernel
def _uv_kernel(d: wp.array(dtype=wp.vec3), uv: wp.array(dtype=wp.vec2), back: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    q = em.wp_dir_to_uv(d[i])
    uv[i] = q
    back[i] = em.wp_uv_to_dir(q[0], q[1])


@wp.kernel
def _lookup_kernel(
    env: wp.array2d(dtype=wp.vec3), to_env: wp.mat33, d: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3),
    out_nearest: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    out[i] = em.env_lookup(env, to_env, d[i])
    out_nearest[i] = em.env_lookup_nearest(env, to_env, d[i])


def test_warp_convention_and_lookup_match_numpy(device):
    rng = np.random.default_rng(2)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    wd = wp.array(d.astype(np.float32), dtype=wp.vec3, device=device)
    uv = wp.zeros(500, dtype=wp.vec2, device=device)
    back = wp.zeros(500, dtype=wp.vec3, device=device)
    wp.launch(_uv_kernel, dim=500, inputs=[wd, uv, back], device=device)
    u, v = em.dir_to_uv(d)
    q = uv.numpy()
    du = np.abs(q[:, 0] - u)
    assert np.all(np.minimum(du, 1 - du) < 1e-5) and np.allclose(q[:, 1], v, atol=1e-5)
    assert np.allclose(back.numpy(), d, atol=1e-5)

    env = rng.random((16, 32, 3)).astype(np.float32)
    R = em.rotation_matrix((1, 2, 3), 40.0)
    out = wp.zeros(500, dtype=wp.vec3, device=device)
    near = wp.zeros(500, dtype=wp.vec3, device=device)
    wp.launch(_lookup_kernel, dim=500, inputs=[wp.array(env, dtype=wp.vec3, device=device),
              wp.mat33(*R.T.astype(np.float32).ravel()), wd, out, near], device=device)
    assert np.allclose(out.numpy(), em.env_lookup_numpy(env, d, rotation=R), atol=2e-4)
    ok = np.all(near.numpy() == em.env_lookup_numpy(env, d, rotation=R, bilinear=False), axis=1)
    assert ok.mean() > 0.99  # a texel boundary may round either way in float32


def test_texel_solid_angles_sum_to_4pi_and_match_sin_theta():
    om = em.texel_solid_angles(64, 128)
    assert om.shape == (64, 128)
    assert abs(om.sum() - 4 * np.pi) < 1e-12
    theta = np.pi * (np.arange(64) + 0.5) / 64
    approx = np.sin(theta) * (np.pi / 64) * (2 * np.pi / 128)
    assert np.allclose(om[:, 0], approx, rtol=1e-3)


def test_downsample_preserves_the_integral():
    env = sk.procedural_sky(64, 32)
    small = em.downsample_envmap(env, 4)
    i0 = np.einsum("hwc,hw->c", env.astype(np.float64), em.texel_solid_angles(32, 64))
    i1 = np.einsum("hwc,hw->c", small, em.texel_solid_angles(8, 16))
    assert np.allclose(i0, i1, rtol=1e-12)


def test_procedural_sky_has_a_sun_with_the_requested_energy():
    sun = np.array([0.3, 0.7, -0.5])
    sun /= np.linalg.norm(sun)
    r = 0.05
    kw = dict(sun_direction=sun, sun_angular_radius=r, sun_intensity=500.0, sun_color=(1, 1, 1), halo=0.0)
    env = sk.procedural_sky(256, 128, **kw).astype(np.float64)
    no_sun = sk.procedural_sky(256, 128, **{**kw, "sun_intensity": 0.0}).astype(np.float64)
    assert env.shape == (128, 256, 3)
    om = em.texel_solid_angles(128, 256)
    sun_energy = np.einsum("hwc,hw->c", env - no_sun, om)
    expect = 500.0 * 2 * np.pi * (1 - np.cos(r))  # radiance × cap solid angle
    assert np.allclose(sun_energy, expect, rtol=0.03)
    # brightest texel is in the sun's direction; sky above is brighter/bluer than the ground
    r_, c_ = np.unravel_index(np.argmax(env.sum(-1)), env.shape[:2])
    d = em.texel_directions(128, 256)[r_, c_]
    assert np.arccos(d @ sun) < r + 0.03
    assert no_sun[10].mean() > no_sun[-10].mean()
    assert np.all(no_sun > 0)


def test_rotation_at_lookup_equals_baked_rotation():
    env = sk.procedural_sky(128, 64, halo=0.0, sun_intensity=0.0)  # smooth part only
    R = em.rotation_matrix((0, 1, 0), 90.0)
    baked = em.rotate_envmap(env, R, supersample=1)
    d = em.texel_directions(64, 128)
    dyn = em.env_lookup_numpy(env, d, rotation=R)
    assert np.allclose(baked, dyn, atol=1e-5)
    # rotating about +y by 90° maps -z (u=0) to -x (u=3/4): a quarter-turn shift of columns
    shifted = np.roll(env, -32, axis=1)
    assert np.allclose(baked, shifted, atol=1e-4)


def _write_exr(path, chans):
    import OpenEXR

    with OpenEXR.File({"type": OpenEXR.scanlineimage}, chans) as f:
        f.write(str(path))


def test_load_envmap_reads_rgb_and_scales(tmp_path):
    env = sk.procedural_sky(32, 16)
    p = save_image(tmp_path / "sky.exr", env)
    assert np.array_equal(em.load_envmap(p), env)
    assert np.allclose(em.load_envmap(p, scale=2.5), env * 2.5)
    rgba = np.concatenate([env, np.ones_like(env[..., :1])], axis=2)
    assert np.array_equal(em.load_envmap(save_image(tmp_path / "a.exr", rgba)), env)


def test_load_envmap_rejects_bad_files_naming_them(tmp_path):
    z = np.zeros((4, 8), np.float32)
    _write_exr(tmp_path / "grey.exr", {"Y": z})
    with pytest.raises(ImageError, match=r"grey\.exr.*\[Y\].*need R, G, B"):
        em.load_envmap(tmp_path / "grey.exr")
    bad = np.ones((4, 8, 3), np.float32)
    bad[1, 2, 0] = np.nan
    with pytest.raises(ImageError, match=r"nan\.exr.*NaN or infinite.*row 1, column 2"):
        em.load_envmap(save_image(tmp_path / "nan.exr", bad))
    bad[1, 2, 0] = -1.0
    with pytest.raises(ImageError, match=r"neg\.exr.*negative"):
        em.load_envmap(save_image(tmp_path / "neg.exr", bad))
    with pytest.raises(ImageError, match=r"sky\.png.*OpenEXR"):
        em.load_envmap(save_image(tmp_path / "sky.png", np.ones((4, 8, 3))))
    with pytest.raises(ImageError, match=r"none\.exr.*not found"):
        em.load_envmap(tmp_path / "none.exr")
