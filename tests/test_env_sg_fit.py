"""precompute.environment.sg_fit: SG mixture of an environment for diffuse lighting (paper §6, eq. 34).

The measure that matters is the irradiance E(n) = ∫ max(n·i, 0) L(i) di that the renderer
computes from the fit through the eq. 40 clamped-cosine SG."""
from __future__ import annotations

import numpy as np
import pytest

from precompute.environment.sg_fit import fit_environment_sgs, irradiance_reference, sg_irradiance
from warp_sg.core.errors import ImageError
from warp_sg.scene import envmap as em
from warp_sg.scene import sky as sk

SUN = np.array([0.45, 0.55, -0.70]) / np.linalg.norm([0.45, 0.55, -0.70])


def _normals(n, seed=0):
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def sky():
    return sk.procedural_sky(128, 64)


@pytest.fixture(scope="module")
def fit8(sky):
    return fit_environment_sgs(sky, 8, cache=False)


def _rel(a, b):
    return np.abs(a - b).max(-1) / np.abs(b).max(-1)


def test_irradiance_of_the_fit_matches_quadrature(sky, fit8):
    n = _normals(400)
    E = irradiance_reference(sky, n)
    rel = _rel(sg_irradiance(*fit8, n), E)
    # the floor of eq. 40 itself: the exact map seen through the single-lobe clamped cosine
    d = em.texel_directions(64, 128).reshape(-1, 3)
    om = em.texel_solid_angles(64, 128).reshape(-1)
    floor = _rel(1.170 * np.exp(2.133 * (n @ d.T - 1)) @ (sky.reshape(-1, 3) * om[:, None]), E)
    print(f"\nirradiance rel. error, 8 lobes: mean {rel.mean():.4f} p95 {np.percentile(rel, 95):.4f} max {rel.max():.4f}"
          f" | exact map through eq. 40: mean {floor.mean():.4f} max {floor.max():.4f}"
          f" | radiance rel. RMS {fit8.info['radiance_rel_rms']:.3f}")
    assert rel.mean() < 0.06 and np.percentile(rel, 95) < 0.12 and rel.max() < 0.2
    assert rel.mean() < 0.5 * floor.mean()  # the fit absorbs the clamped cosine's bias
    assert abs(fit8.info["irradiance_rel_mean"] - rel.mean()) < 0.02  # reported statistic is honest


def test_brightest_lobe_is_a_sharp_lobe_on_the_sun(fit8):
    axes, lam, mu = fit8
    assert axes.shape == (8, 3) and lam.shape == (8,) and mu.shape == (8, 3)
    assert np.allclose(np.linalg.norm(axes, axis=1), 1.0)
    assert np.all(mu >= 0) and np.all(lam > 0)
    ang = np.degrees(np.arccos(np.clip(axes[0] @ SUN, -1, 1)))
    assert ang < 2.0 and lam[0] > 100.0


def test_more_lobes_fit_better(sky, fit8):
    n = _normals(200, seed=1)
    E = irradiance_reference(sky, n)
    e2 = _rel(sg_irradiance(*fit_environment_sgs(sky, 2, cache=False), n), E).mean()
    e8 = _rel(sg_irradiance(*fit8, n), E).mean()
    assert e8 < 0.5 * e2


def test_constant_map_gives_uniform_irradiance_pi_L():
    L = np.array([0.5, 1.0, 2.0], np.float32)
    env = np.broadcast_to(L, (16, 32, 3)).copy()
    f = fit_environment_sgs(env, 3, cache=False)
    n = _normals(100, seed=2)
    assert np.allclose(sg_irradiance(*f, n), np.pi * L, rtol=0.01)


def test_fit_is_cached_and_validated(cache_dir):
    env = sk.procedural_sky(32, 16)
    a = fit_environment_sgs(env, 4)
    assert len(list((cache_dir / "env_sg_fit").glob("*.npz"))) == 1
    b = fit_environment_sgs(env, 4)
    assert all(np.array_equal(x, y) for x, y in zip(a, b)) and b.info["nfev"] == a.info["nfev"]
    with pytest.raises(ValueError, match="n_lobes"):
        fit_environment_sgs(env, 0)
    bad = env.copy()
    bad[2, 3, 1] = np.nan
    with pytest.raises(ImageError, match="NaN"):
        fit_environment_sgs(bad, 4)


def test_fitting_through_a_multi_lobe_clamped_cosine_lowers_the_irradiance_error(sky, fit8):
    from warp_sg.sg import cosine_lobes as CC

    cos2 = CC.LOBES[2]  # signed amplitudes
    f2 = fit_environment_sgs(sky, 8, cosine=cos2, cache=False)
    n = _normals(300, seed=3)
    E = irradiance_reference(sky, n)
    e1 = _rel(sg_irradiance(*fit8, n), E)
    e2 = _rel(sg_irradiance(*f2, n, cosine=cos2), E)
    assert e2.mean() < 0.85 * e1.mean() and e2.max() < e1.max()
