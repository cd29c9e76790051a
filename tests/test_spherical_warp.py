"""Spherical warp (paper eq. 17–22): formula, mass conservation against the exact warped NDF
(quadrature), pointwise agreement with the exact BRDF slice at normal incidence, eq. 11 error of
the warped slice, grazing guard."""
from __future__ import annotations

import numpy as np
import pytest

import warp_sg.brdf as B
from warp_sg.brdf.fitting.fit import warp_error
from warp_sg.brdf.spherical_warp import WARP_COS_EPS, eval_slice, spherical_warp


def test_warp_formula():
    pD = np.array([0.0, 0.0, 1.0])
    o = np.array([np.sin(0.6), 0.0, np.cos(0.6)])
    pW, lW, mW = spherical_warp(pD, 100.0, 0.7, o)
    np.testing.assert_allclose(pW, [-np.sin(0.6), 0, np.cos(0.6)], atol=1e-15)
    assert lW == pytest.approx(100.0 / (4 * np.cos(0.6)))
    assert mW == 0.7
    pW, lW, _ = spherical_warp(pD, 100.0, 1.0, pD)
    np.testing.assert_allclose(pW, pD)
    assert lW == pytest.approx(25.0)


def _sphere_grid(center, width, n=400):
    """Quadrature nodes on a cap of radius ≤ π about ``center`` refined within ~width."""
    tmax = min(np.pi, 12 * width)
    t = (np.arange(n) + 0.5) / n
    th = tmax * t * t
    ph = (np.arange(n) + 0.5) / n * 2 * np.pi
    T, P = np.meshgrid(th, ph, indexing="ij")
    local = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
    w = np.sin(T) * tmax * 2 * t[:, None] / n * 2 * np.pi / n
    from warp_sg.numeric.onb import to_world

    return to_world(local, np.broadcast_to(center, local.shape)), w


@pytest.mark.parametrize("theta_o", [0.0, 0.5, 1.0, 1.3])
@pytest.mark.parametrize("lam", [100.0, 3000.0])
def test_warped_lobe_keeps_the_mass_of_the_exact_warp(theta_o, lam):
    """∫ G(i; pW, λW) di = ∫ D*(h(i)) di (the exact warp of the NDF lobe) for sharp lobes."""
    o = np.array([np.sin(theta_o), 0.0, np.cos(theta_o)])
    pD = np.array([0.0, 0.0, 1.0])
    pW, lW, _ = spherical_warp(pD, lam, 1.0, o)
    I, w = _sphere_grid(pW, 1 / np.sqrt(lW))
    h = I + o
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    exact = np.sum(w * np.exp(-lam * (1 - h @ pD)))
    approx = np.sum(w * np.exp(-lW * (1 - I @ pW)))
    assert approx == pytest.approx(exact, rel=2e-2 if lam < 1000 else 3e-3)


def test_slice_matches_exact_brdf_at_normal_incidence():
    model = B.CookTorrance(ks=1.0, m=0.05)
    o = np.array([0.0, 0.0, 1.0])
    a, l, m = B.slice_lobes_numpy(model, o)
    th = np.linspace(0, 0.25, 50)
    I = np.stack([np.sin(th), 0 * th, np.cos(th)], -1)
    exact = model.eval(o, I)
    approx = eval_slice(a, l, m, I)
    # Mo is taken at the lobe centre, the SG differs from exp(−θ²/m²) at 4th order: ≤ 2 % of the peak
    assert np.max(np.abs(approx - exact)) < 0.02 * exact.max()


def test_eq11_error_of_the_warped_slice():
    """supplement Fig. 9: the warp error is bounded for Cook–Torrance (about 0.10 for m ≤ 0.2; the
    isotropic-lobe assumption dominates, it does not vanish with sharpness in this measure)."""
    errs = {m: warp_error(B.CookTorrance(m=m), n_o=12) for m in (0.05, 0.2, 0.5)}
    assert errs[0.05] < 0.12 and errs[0.2] < 0.12 and errs[0.5] < 0.25
    assert errs[0.05] <= errs[0.5]
    # Phong / Lafortune slices are their own lobes (no warp): only the SG-vs-cosine-power error
    assert warp_error(B.Phong(n=100), n_o=12) < 1e-3
    assert warp_error(B.Lafortune(), n_o=12) < 5e-3


def test_grazing_warp_is_finite():
    pD = np.array([[0.0, 0.0, 1.0], [np.sin(0.3), 0, np.cos(0.3)]])
    o = np.array([1.0, 0.0, 0.0])
    pW, lW, mW = spherical_warp(pD, np.array([10.0, 1e6]), 1.0, o)
    assert np.all(np.isfinite(pW)) and np.all(np.isfinite(lW))
    assert lW[0] == pytest.approx(10.0 / (4 * WARP_COS_EPS))
    for model in (B.CookTorrance(m=0.01), B.Ward(alpha=0.01), B.AshikhminShirley(nu=1e5, nv=10)):
        a, l, m = B.slice_lobes_numpy(model, np.array([[1.0, 0, 0], [np.cos(1e-7), 0, np.sin(1e-7)]]))
        assert np.all(np.isfinite(a)) and np.all(np.isfinite(l)) and np.all(np.isfinite(m))
