"""NDF SG fits (supplement §2–3, paper §4.1–4.2): analytic single lobes, nonlinear least-squares
fits (1–k lobes) checked against an independent scipy quadrature optimum, the Ashikhmin–Shirley
N-lobe construction (supplement eq. 12–14), and supplement eq. 11 errors below stated bounds."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, optimize

import warp_sg.brdf as B
from warp_sg.brdf.fit import EPSILON, fit_error
from warp_sg.errors import InputError


@pytest.mark.parametrize("model, lam", [
    (B.CookTorrance(m=0.2), 2 / 0.2**2), (B.TorranceSparrow(m=0.1), 2 / 0.1**2), (B.Ward(alpha=0.3), 2 / 0.3**2),
    (B.BlinnPhong(n=77), 77.0), (B.Phong(n=12), 12.0), (B.AshikhminShirley(nu=40, nv=40), 40.0),
])
def test_analytic_single_lobe(model, lam):
    a, l, m = model.ndf_sg(1, "analytic")
    np.testing.assert_allclose(a, [[0, 0, 1]])
    np.testing.assert_allclose(l, [lam], rtol=1e-12)
    np.testing.assert_allclose(m, [1.0])


def _l2(ndf_theta, lam):
    f = lambda t: (ndf_theta(t) - np.exp(-lam * 2 * np.sin(t / 2) ** 2)) ** 2 * np.sin(t)  # noqa: E731
    w = 1 / np.sqrt(lam)
    pts = sorted({x for x in (0, w, 3 * w, 10 * w, np.pi / 2) if x <= np.pi / 2})
    return sum(integrate.quad(f, a, b, epsabs=0, epsrel=1e-11, limit=200)[0] for a, b in zip(pts[:-1], pts[1:]))


@pytest.mark.parametrize("model", [B.CookTorrance(m=0.3), B.BlinnPhong(n=20), B.Ward(alpha=0.1)],
                         ids=["ct", "bp", "ward"])
def test_single_lobe_fit_is_the_l2_optimum(model):
    ndf_t = lambda t: model.ndf(np.stack([np.sin(t), 0 * t, np.cos(t)], -1))  # noqa: E731
    lam_fit = model.ndf_sg(1, "fit")[1][0]
    lam0 = model.ndf_sg(1, "analytic")[1][0]
    res = optimize.minimize_scalar(lambda x: _l2(ndf_t, np.exp(x)), bracket=(np.log(lam0) - 0.3, np.log(lam0) + 0.3),
                                   tol=1e-10)
    assert lam_fit == pytest.approx(np.exp(res.x), rel=2e-3)
    # supplement Fig. 2: the analytic Taylor rule tracks the nonlinear fit
    assert lam0 == pytest.approx(lam_fit, rel=0.3)
    assert _l2(ndf_t, lam_fit) <= _l2(ndf_t, lam0) * (1 + 1e-9)


def test_fitted_sharpness_converges_to_analytic_for_sharp_lobes():
    # supplement Fig. 2: dashed (analytic) and solid (fit) curves meet as the lobe sharpens
    for m in (0.05, 0.1):
        lf = B.CookTorrance(m=m).ndf_sg(1, "fit")[1][0]
        assert lf == pytest.approx(2 / m**2, rel=0.01)
    lf = B.BlinnPhong(n=2000).ndf_sg(1, "fit")[1][0]
    assert lf == pytest.approx(2000, rel=0.01)


def test_multi_lobe_fits_improve_with_lobes():
    model = B.BlinnPhong(n=8)
    errs = [fit_error(model, k, "fit", n_o=12) for k in (1, 2, 3)]
    assert errs[1] < errs[0] and errs[2] <= errs[1] * 1.01
    a, l, m = model.ndf_sg(3, "fit")
    assert np.all(np.diff(l) >= 0)  # sorted by sharpness (paper §4.2)
    assert np.all(l > 0) and np.all(m > 0)


@pytest.mark.parametrize("model, bound_analytic, bound_fit", [
    (B.CookTorrance(m=0.05), 1e-6, 1e-6),
    (B.CookTorrance(m=0.2), 3e-5, 1e-5),
    (B.CookTorrance(m=0.4), 3e-4, 1e-4),
    (B.BlinnPhong(n=10), 3e-3, 1e-3),
    (B.BlinnPhong(n=1000), 1e-6, 1e-6),
    (B.Ward(alpha=0.05), 1e-5, 1e-5),
], ids=["ct.05", "ct.2", "ct.4", "bp10", "bp1000", "ward.05"])
def test_eq11_error_of_single_lobe_fits(model, bound_analytic, bound_fit):
    ea = fit_error(model, 1, "analytic", n_o=12)
    ef = fit_error(model, 1, "fit", n_o=12)
    assert ea < bound_analytic and ef < bound_fit
    assert ef <= ea * 1.05


def test_ashikhmin_shirley_lobe_construction_eq14():
    nu, nv, N = 75.0, 1200.0, 7
    model = B.AshikhminShirley(nu=nu, nv=nv, lobes=N)
    a, l, m = model.ndf_sg(N, "analytic")
    assert a.shape == (N, 3)
    np.testing.assert_allclose(l, max(nu, nv))
    # the x exponent (nu) is the smaller: lobes spread along x
    np.testing.assert_allclose(a[:, 1], 0.0, atol=1e-15)
    theta_v = np.arccos(EPSILON ** (1 / (min(nu, nv) + 1)))
    theta_i = 2 * theta_v / (N + 1)
    ang = np.arctan2(a[:, 0], a[:, 2])
    np.testing.assert_allclose(np.diff(np.sort(ang)), theta_i, rtol=1e-9)
    np.testing.assert_allclose(ang[N // 2], 0.0, atol=1e-15)
    np.testing.assert_allclose(m, model.ndf(a), rtol=1e-12)
    # swap nu, nv: lobes along y
    a2 = B.AshikhminShirley(nu=nv, nv=nu, lobes=N).ndf_sg(N)[0]
    np.testing.assert_allclose(a2[:, 0], 0.0, atol=1e-15)
    # errors (eq. 11): more lobes better; the L-BFGS-B fit beats the construction
    e = {k: fit_error(B.AshikhminShirley(nu=nu, nv=nv, lobes=k), k, "analytic", n_o=12, n_phi_o=4) for k in (1, 3, 7)}
    assert e[7] < e[3] < e[1]
    assert e[7] < 0.05
    ef = fit_error(model, N, "fit", n_o=12, n_phi_o=4)
    assert ef < 0.5 * e[7]


def test_anisotropic_ward_lobes():
    model = B.Ward(alpha_x=0.3, alpha_y=0.08)
    a, l, m = model.ndf_sg(5)
    assert len(l) == 5
    np.testing.assert_allclose(a[:, 1], 0.0, atol=1e-15)  # wide along x
    np.testing.assert_allclose(l, 2 / 0.08**2)
    e1 = fit_error(model, 1, "analytic", n_o=12, n_phi_o=4)
    e5 = fit_error(model, 5, "analytic", n_o=12, n_phi_o=4)
    assert e5 < e1


def test_bad_fit_arguments_raise():
    with pytest.raises(InputError, match="method"):
        B.CookTorrance().ndf_sg(1, "magic")
    with pytest.raises(InputError, match="n_lobes"):
        B.CookTorrance().ndf_sg(0)
