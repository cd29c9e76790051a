"""Light records -> SG lights (eq. 32-33 with integral-preserving amplitudes) and environment rotation."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp
from scipy import integrate, optimize

from warp_sg.core.errors import InputError
from warp_sg.scene.lights import (
    DirectionalLight,
    EnvironmentLight,
    LightArrays,
    PointLight,
    directional_light_sg,
    light_arrays,
    light_sg,
    point_light_sg,
    rotate_equirect,
)


@wp.kernel
def _eval_light_sg(lights: LightArrays, x: wp.array(dtype=wp.vec3), axis: wp.array2d(dtype=wp.vec3),
                   lam: wp.array2d(dtype=float), mu: wp.array2d(dtype=wp.vec3)):
    i, j = wp.tid()
    a, l, m = light_sg(lights, j, x[i])
    axis[i, j] = a
    lam[i, j] = l
    mu[i, j] = m


def _sphere_integral(lam, mu):
    """∫ over the sphere of μ exp(λ(cos θ − 1)) by adaptive quadrature in θ (independent of sg.integral)."""
    w = 1.0 / np.sqrt(lam)
    pts = [x for x in (0.0, w, 3 * w, 10 * w, 30 * w, np.pi) if x <= np.pi]
    f = lambda t: np.exp(-2.0 * lam * np.sin(t / 2) ** 2) * np.sin(t)  # noqa: E731  (cos t − 1 = −2 sin²(t/2))
    val = sum(integrate.quad(f, a, b, epsabs=0, epsrel=1e-12, limit=200)[0] for a, b in zip(pts[:-1], pts[1:]))
    return 2 * np.pi * np.asarray(mu, float) * val


def _effective_solid_angle(lam):
    """Solid angle of the cap where the lobe exceeds ε = 0.1 of its peak (the paper's effective area),
    by root finding on the lobe itself."""
    t_eps = optimize.brentq(lambda t: np.exp(-2.0 * lam * np.sin(t / 2) ** 2) - 0.1, 0.0, np.pi, xtol=1e-15, rtol=1e-14)
    return 4 * np.pi * np.sin(t_eps / 2) ** 2  # 2π(1 − cos θε)


def test_point_light_sg_integrates_to_s_over_d_squared_and_its_sharpness_follows_the_solid_angle():
    li = PointLight(position=(0.0, 3.0, 0.0), radius=0.2, intensity=(4.0, 8.0, 12.0))
    x = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    p, lam, mu = point_light_sg(li, x)
    d2 = np.array([4.0, 10.0])
    for k in range(2):
        # irradiance of the light sphere (intensity s): s/d²
        np.testing.assert_allclose(_sphere_integral(lam[k], mu[k]), li.intensity / d2[k], rtol=1e-9)
        # eq. 32: the lobe's effective area is the light's solid angle 2πr²/d²
        assert _effective_solid_angle(lam[k]) == pytest.approx(2 * np.pi * 0.2**2 / d2[k], rel=1e-9)
    np.testing.assert_allclose(p[0], [0, 1, 0])
    np.testing.assert_allclose(p[1], np.array([-1.0, 3.0, 0.0]) / np.sqrt(10.0))


def test_directional_light_sg_integrates_to_the_irradiance():
    li = DirectionalLight(direction=(0.0, 2.0, 0.0), radius=0.05, intensity=3.0)
    p, lam, mu = directional_light_sg(li)
    np.testing.assert_allclose(p, [0, 1, 0])
    assert _effective_solid_angle(float(lam)) == pytest.approx(2 * np.pi * 0.05**2, rel=1e-9)
    np.testing.assert_allclose(_sphere_integral(float(lam), mu), [3.0, 3.0, 3.0], rtol=1e-9)


def test_kernel_light_sg_matches_numpy(device):
    lights = [PointLight(position=(1.0, 2.0, 0.5), radius=0.1, intensity=(5.0, 6.0, 7.0)),
              DirectionalLight(direction=(0.3, 1.0, -0.2), radius=0.02, intensity=(1.0, 2.0, 3.0)),
              PointLight(position=(0.0, 5.0, 0.0), radius=0.0, intensity=1.0)]  # delta light
    x = np.array([[0.0, 0.0, 0.0], [0.2, -0.3, 0.1]], np.float32)
    la = light_arrays(lights, device)
    axis = wp.zeros((2, 3), dtype=wp.vec3, device=device)
    lam = wp.zeros((2, 3), dtype=float, device=device)
    mu = wp.zeros((2, 3), dtype=wp.vec3, device=device)
    wp.launch(_eval_light_sg, dim=(2, 3), inputs=[la, wp.array(x, dtype=wp.vec3, device=device), axis, lam, mu],
              device=device)
    axis, lam, mu = axis.numpy(), lam.numpy(), mu.numpy()
    for i in range(2):
        p, l, m = point_light_sg(lights[0], x[i].astype(np.float64))
        np.testing.assert_allclose(axis[i, 0], p, atol=1e-6)
        np.testing.assert_allclose(lam[i, 0], l, rtol=1e-5)
        np.testing.assert_allclose(mu[i, 0], m, rtol=1e-5)
        p, l, m = directional_light_sg(lights[1])
        np.testing.assert_allclose(axis[i, 1], p, atol=1e-6)
        np.testing.assert_allclose(mu[i, 1], m, rtol=1e-5)
        # the delta light keeps its irradiance: ∫G = s/d² even at the sharpness cap
        np.testing.assert_allclose(_sphere_integral(float(lam[i, 2]), mu[i, 2].astype(np.float64)),
                                   1.0 / np.sum((np.array([0, 5, 0]) - x[i]) ** 2), rtol=1e-4)


def test_bad_light_values_raise_input_errors_naming_the_field():
    with pytest.raises(InputError, match="direction"):
        DirectionalLight(direction=(0, 0, 0))
    with pytest.raises(InputError, match="radius"):
        PointLight(position=(0, 1, 0), radius=-1)
    with pytest.raises(InputError, match="intensity"):
        PointLight(position=(0, 1, 0), intensity=(1, 2))
    with pytest.raises(InputError, match="procedural"):
        EnvironmentLight(procedural="moon")


def _texel_centres(h, w):
    """Unit directions of the texel centres, written from the convention of docs/environment.md:
    ``d = (sin θ sin φ, cos θ, −sin θ cos φ)``, ``φ = 2πu``, ``θ = πv``."""
    v, u = (np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w
    th, ph = np.pi * v[:, None], 2 * np.pi * u[None, :]
    return np.stack([np.sin(th) * np.sin(ph), np.cos(th) * np.ones_like(ph), -np.sin(th) * np.cos(ph)], -1)


def _rotation_about_y(deg):
    """The right-handed rotation about +Y, written out."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def test_environment_rotation_is_a_right_handed_turn_about_y():
    """``rotation`` turns the sky right-handedly about +Y: ``L_out(d) = L_in(Rᵀ d)``. A turn by a
    whole number of texels is an exact column shift (R_y(α)ᵀ adds α to φ, so 45° = 4 of 32 columns
    reads the input 4 columns on), and any turn of a smooth sky matches the sky evaluated at
    ``Rᵀ d`` up to the linear interpolation along u."""
    rng = np.random.default_rng(1)
    env = rng.random((16, 32, 3)).astype(np.float32)
    np.testing.assert_allclose(EnvironmentLight(data=env, rotation=45.0).rotation_matrix(), _rotation_about_y(45.0),
                               atol=1e-12)
    np.testing.assert_allclose(rotate_equirect(env, 45.0), np.roll(env, -4, axis=1), atol=1e-6)
    np.testing.assert_allclose(rotate_equirect(env, -90.0), np.roll(env, 8, axis=1), atol=1e-6)

    h, w = 64, 128  # a smooth sky: a broad lobe off the axis, in three colours
    a = np.array([0.6, 0.3, -0.74]) / np.linalg.norm([0.6, 0.3, -0.74])
    sky = lambda d: np.exp(np.array([1.0, 2.0, 3.0]) * (d @ a)[..., None])  # noqa: E731
    d = _texel_centres(h, w)
    R = _rotation_about_y(30.0)
    got = rotate_equirect(sky(d).astype(np.float32), 30.0)
    want = sky(d @ R)  # (Rᵀ d) for each row vector d is d R
    assert np.max(np.abs(got - want) / want) < 5e-3  # linear interpolation over 2.8° texels
    assert np.max(np.abs(got - sky(d)) / want) > 0.3  # the turn is not a no-op ...
    assert np.max(np.abs(rotate_equirect(sky(d).astype(np.float32), -30.0) - want) / want) > 0.3  # ... nor the other way


def test_constant_environment_and_scale():
    e = EnvironmentLight(procedural="constant", options={"radiance": [0.5, 1.0, 2.0], "width": 8, "height": 4},
                         scale=2.0, rotation=33.0)
    np.testing.assert_allclose(e.radiance(), np.broadcast_to([1.0, 2.0, 4.0], (4, 8, 3)))
