"""Light records -> SG lights (eq. 32-33 with integral-preserving amplitudes) and environment rotation."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp
from scipy import integrate, optimize

from warp_sg.errors import InputError
from warp_sg.lights import (DirectionalLight, EnvironmentLight, LightArrays, PointLight, directional_light_sg,
                            light_arrays, light_sg, point_light_sg, rotate_equirect)


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


def test_environment_rotation_matches_precompute_envmap_rotation():
    from precompute.envmap import rotate_envmap

    rng = np.random.default_rng(1)
    env = rng.random((16, 32, 3)).astype(np.float32)
    # a rotation by a whole number of texels is an exact column shift in both implementations
    ours = rotate_equirect(env, 45.0)  # 45° = 4 texels of 32
    R = EnvironmentLight(data=env, rotation=45.0).rotation_matrix()
    theirs = rotate_envmap(env, R, supersample=1)
    np.testing.assert_allclose(ours, theirs, atol=1e-5)
    assert not np.allclose(ours, env)


def test_constant_environment_and_scale():
    e = EnvironmentLight(procedural="constant", options={"radiance": [0.5, 1.0, 2.0], "width": 8, "height": 4},
                         scale=2.0, rotation=33.0)
    np.testing.assert_allclose(e.radiance(), np.broadcast_to([1.0, 2.0, 4.0], (4, 8, 3)))
