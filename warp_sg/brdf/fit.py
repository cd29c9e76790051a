r"""SG mixture fits of NDFs (supplement §2–3; paper §4.1–4.2) and the supplement eq. 11 error.

Analytic fits (``method="analytic"``):

* isotropic, one lobe about z+ (supplement §2): Cook–Torrance and Torrance–Sparrow ``λ = 2/m²``,
  Ward ``λ = 2/α²``, Blinn–Phong / Phong / isotropic Ashikhmin–Shirley ``λ = n``; ``μ = 1``
  (a two-term Taylor expansion of the exponent at the normal);
* anisotropic (Ashikhmin–Shirley, anisotropic Ward), supplement eq. 14: N lobes (odd) spread along
  the wide tangent axis at angles ``(k − (N−1)/2) θi``, ``θi = 2θv/(N+1)``, common sharpness,
  amplitudes ``D(pk)`` (see :func:`aniso_lobes`).

Nonlinear fits (``method="fit"``), cached per parameter set:

* isotropic: least squares (``scipy.optimize.least_squares``) of
  ``∫_{H²} (D(h) − Σk μk e^{λk(h·z − 1)})² dω_h`` on a θ grid refined near the normal; one lobe
  fits λ with μ = 1 (solid curves of supplement Fig. 2); K lobes fit all λk, μk (LM-style, paper
  §4.2), sorted by increasing sharpness;
* anisotropic: L-BFGS-B (paper §4.2) over all lobe axes, sharpnesses and amplitudes, started from
  the analytic construction, same L2 objective on a (θ, φ) grid.
"""
from __future__ import annotations

import functools

import numpy as np

from ..errors import InputError

EPSILON = 0.1
METHODS = ("analytic", "fit")


# --------------------------------------------------------------------------------------------
# analytic constructions
# --------------------------------------------------------------------------------------------
def aniso_lobes(n_lobes, lam, theta_v, wide_x, ndf):
    """Supplement eq. 14: ``n_lobes`` (odd) lobes along the wide axis (x if ``wide_x`` else y)."""
    N = int(n_lobes)
    theta_i = 2.0 * theta_v / (N + 1)
    a = (np.arange(N) - (N - 1) / 2.0) * theta_i
    axes = np.zeros((N, 3))
    axes[:, 0 if wide_x else 1] = np.sin(a)
    axes[:, 2] = np.cos(a)
    amp = ndf(axes)
    return axes, np.full(N, float(lam)), np.asarray(amp, dtype=np.float64)


def aniso_setup(model):
    """``(lam, theta_v, wide_x)`` of the anisotropic construction for AS / Ward."""
    name = model.NAME
    if name == "ashikhmin_shirley":
        nmin, nmax = min(model.nu, model.nv), max(model.nu, model.nv)
        theta_v = np.arccos(EPSILON ** (1.0 / (nmin + 1.0)))
        return nmax, theta_v, model.nu < model.nv  # wide along x when the x exponent is smaller
    if name == "ward":
        amin, amax = min(model.alpha_x, model.alpha_y), max(model.alpha_x, model.alpha_y)
        theta_v = np.arctan(amax * np.sqrt(-np.log(EPSILON)))
        return 2.0 / amin**2, theta_v, model.alpha_x > model.alpha_y
    raise InputError(f"model '{name}' has no anisotropic construction", where="model")


def is_anisotropic(model):
    return model.NAME in ("ashikhmin_shirley", "ward") and not model.isotropic


def lobe_count(model, n_lobes):
    """Number of NDF lobes used for ``model`` when ``n_lobes`` is asked for."""
    if model.NAME == "lafortune":
        return len(model.N)
    if getattr(model, "own_lobes", None):
        return int(model.own_lobes)
    n = int(n_lobes)
    if is_anisotropic(model) and n % 2 == 0:
        n += 1  # the construction needs an odd count
    return n


# --------------------------------------------------------------------------------------------
# nonlinear fits
# --------------------------------------------------------------------------------------------
def _iso_grid(lam0, n=600):
    """θ grid on [0, θmax] refined near 0 (t² spacing), with sin θ dθ weights."""
    theta_max = min(np.pi / 2, 10.0 / np.sqrt(max(lam0, 1e-9)))
    t = (np.arange(n) + 0.5) / n
    theta = theta_max * t * t
    w = np.sin(theta) * theta_max * 2.0 * t / n * 2.0 * np.pi
    return theta, w


def _one_minus_cos(theta):
    return 2.0 * np.sin(0.5 * theta) ** 2


def fit_isotropic(ndf_theta, lam0, n_lobes):
    """Least-squares SG mixture about z+ of an isotropic NDF given as a function of θ."""
    from scipy.optimize import least_squares

    theta, w = _iso_grid(lam0)
    D = ndf_theta(theta)
    sw = np.sqrt(w)
    omc = _one_minus_cos(theta)
    K = int(n_lobes)
    if K == 1:
        def res(x):
            return sw * (D - np.exp(-np.exp(x[0]) * omc))

        sol = least_squares(res, [np.log(lam0)], method="lm", xtol=1e-12, ftol=1e-12)
        lam = np.exp(sol.x)
        mu = np.ones(1)
    else:
        def res(x):
            lam, mu = np.exp(x[:K]), np.exp(x[K:])
            return sw * (D - (mu * np.exp(-lam * omc[:, None])).sum(-1))

        spread = np.geomspace(0.5, 2.0, K)
        x0 = np.concatenate([np.log(lam0 * spread), np.log(np.full(K, 1.0 / K))])
        sol = least_squares(res, x0, method="lm", xtol=1e-12, ftol=1e-12, max_nfev=4000)
        lam, mu = np.exp(sol.x[:K]), np.exp(sol.x[K:])
        order = np.argsort(lam)
        lam, mu = lam[order], mu[order]
    axes = np.tile([0.0, 0.0, 1.0], (K, 1))
    return axes, lam, mu


def fit_anisotropic(ndf, axes0, lam0, mu0, theta_max):
    """L-BFGS-B fit of K free lobes (axis angles, log λ, log μ) to ``ndf(h)`` on a (θ, φ) grid."""
    from scipy.optimize import minimize

    nt, nphi = 72, 96
    t = (np.arange(nt) + 0.5) / nt
    th = theta_max * t * t
    ph = (np.arange(nphi) + 0.5) / nphi * 2 * np.pi
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1).reshape(-1, 3)
    w = (np.sin(TH) * theta_max * 2 * t[:, None] / nt * 2 * np.pi / nphi).reshape(-1)
    D = ndf(h)
    K = len(lam0)
    scale = float(np.sum(w * D * D)) or 1.0

    def unpack(x):
        a, b = x[:K], x[K:2 * K]
        axes = np.stack([np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), np.cos(a)], -1)
        return axes, np.exp(x[2 * K:3 * K]), np.exp(x[3 * K:])

    def f(x):
        axes, lam, mu = unpack(x)
        dots = h @ axes.T
        g = mu * np.exp(-lam * (1.0 - dots))
        r = D - g.sum(-1)
        val = np.sum(w * r * r) / scale
        # analytic gradient
        wr = -2.0 * w * r / scale  # d val / d approx
        dg_dlam = g * -(1.0 - dots)
        # derivative of dots wrt angles
        a, b = x[:K], x[K:2 * K]
        dax_da = np.stack([np.cos(a) * np.cos(b), np.cos(a) * np.sin(b), -np.sin(a)], -1)
        dax_db = np.stack([-np.sin(a) * np.sin(b), np.sin(a) * np.cos(b), np.zeros(K)], -1)
        gl = g * lam
        grad = np.concatenate([
            (wr[:, None] * gl * (h @ dax_da.T)).sum(0),
            (wr[:, None] * gl * (h @ dax_db.T)).sum(0),
            (wr[:, None] * dg_dlam * lam).sum(0),
            (wr[:, None] * g).sum(0),
        ])
        return val, grad

    a0 = np.arccos(np.clip(axes0[:, 2], -1, 1))
    b0 = np.arctan2(axes0[:, 1], axes0[:, 0])
    x0 = np.concatenate([a0, b0, np.log(lam0), np.log(np.maximum(mu0, 1e-6))])
    sol = minimize(f, x0, jac=True, method="L-BFGS-B", options={"maxiter": 500})
    axes, lam, mu = unpack(sol.x)
    order = np.argsort(lam, kind="stable")
    return axes[order], lam[order], mu[order]


def _iso_ndf_theta(model):
    def f(theta):
        h = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], -1)
        return model.ndf(h)

    return f


@functools.lru_cache(maxsize=256)
def _cached(key, model_ref):
    model, n_lobes, method = model_ref.model, key[-2], key[-1]
    return _compute(model, n_lobes, method)


class _Ref:
    """Carries the model into the cache without making it part of the key."""

    def __init__(self, model):
        self.model = model

    def __hash__(self):
        return 0

    def __eq__(self, other):
        return isinstance(other, _Ref)


def _compute(model, n_lobes, method):
    K = lobe_count(model, n_lobes)
    if is_anisotropic(model):
        lam, theta_v, wide_x = aniso_setup(model)
        axes, lams, amps = aniso_lobes(K, lam, theta_v, wide_x, model.ndf)
        if method == "fit":
            theta_max = min(np.pi / 2, 2.5 * theta_v + 6.0 / np.sqrt(lam))
            axes, lams, amps = fit_anisotropic(model.ndf, axes, lams, amps, theta_max)
        return axes, lams, amps
    lam0 = model.ndf_analytic_lambda()
    if method == "analytic" and K == 1:
        return np.array([[0.0, 0.0, 1.0]]), np.array([lam0]), np.ones(1)
    return fit_isotropic(_iso_ndf_theta(model), lam0, K)


def ndf_sg_for(model, n_lobes=1, method="analytic"):
    """``(axes (K,3), sharpness (K,), amplitude (K,))`` of the NDF SG mixture of ``model``.

    ``method="analytic"`` with ``n_lobes > 1`` on an isotropic model falls back to the
    nonlinear fit (there is no analytic multi-lobe rule)."""
    if method not in METHODS:
        from .base import suggest

        raise InputError(f"unknown fit method '{method}'{suggest(method, METHODS)}", where="method")
    try:
        n = int(n_lobes)
    except (TypeError, ValueError):
        raise InputError(f"expected a positive integer, got {n_lobes!r}", where="n_lobes") from None
    if n < 1 or n != n_lobes:
        raise InputError(f"must be a positive integer, got {n_lobes!r}", where="n_lobes")
    key = (model.NAME, tuple(model.kernel_params()), getattr(model, "own_lobes", None), n, method)
    axes, lam, mu = _cached(key, _Ref(model))
    return axes.copy(), lam.copy(), mu.copy()


# --------------------------------------------------------------------------------------------
# supplement eq. 11 error
# --------------------------------------------------------------------------------------------
def _quad_setup(lam, n_o=24, n_phi_o=1, n_th=96, n_ph=64):
    """Directions o (Gauss–Legendre in cos θo × φo) and h (θh refined near z × φh) with weights."""
    x, wx = np.polynomial.legendre.leggauss(n_o)
    co = 0.5 * (x + 1.0)
    wco = 0.5 * wx
    phio = (np.arange(n_phi_o) + 0.5) / n_phi_o * (np.pi if n_phi_o > 1 else 0.0)
    so = np.sqrt(1 - co**2)
    CO, PO = np.meshgrid(co, phio, indexing="ij")
    SO = np.sqrt(1 - CO**2)
    o = np.stack([SO * np.cos(PO), SO * np.sin(PO), CO], -1).reshape(-1, 3)
    wo = np.repeat(wco, n_phi_o) * (2 * np.pi / n_phi_o)
    del so
    theta_max = min(np.pi / 2, 12.0 / np.sqrt(max(lam, 1e-9)))
    t = (np.arange(n_th) + 0.5) / n_th
    th = theta_max * t * t
    ph = (np.arange(n_ph) + 0.5) / n_ph * 2 * np.pi
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1).reshape(-1, 3)
    wh = (np.sin(TH) * theta_max * 2 * t[:, None] / n_th * 2 * np.pi / n_ph).reshape(-1)
    return o, wo, h, wh


def eq11_error(model, approx, n_o=24, n_phi_o=None, n_th=96, n_ph=64):
    """Supplement eq. 11 weighted error of ``approx(o, i) -> (..., 3)`` against ``ρs`` (ks = 1):

    ``Σ (ρs − ρs^R)² ((i·n)(o·n))² / Σ (ρs (i·n)(o·n))²`` as integrals over (o, i), computed in
    (o, h) with ``dω_i = 4 (o·h) dω_h`` on a grid refined around the NDF peak (green channel)."""
    lam = float(np.max(model.ndf_sg(1, "analytic")[1])) if model.is_specular else 1.0
    if n_phi_o is None:
        n_phi_o = 8 if is_anisotropic(model) else 1
    o, wo, h, wh = _quad_setup(lam, n_o, n_phi_o, n_th, n_ph)
    O = o[:, None, :]
    H = h[None, :, :]
    oh = np.sum(O * H, -1)
    I = 2 * oh[..., None] * H - O
    valid = (I[..., 2] > 0) & (oh > 0)
    w = wo[:, None] * wh[None, :] * 4 * np.maximum(oh, 0) * valid
    cc = (I[..., 2] * O[..., 2]) ** 2
    rho = model.specular(O, I)[..., 1]
    rr = np.asarray(approx(np.broadcast_to(O, I.shape), I))[..., 1]
    num = np.sum(w * (rho - rr) ** 2 * cc)
    den = np.sum(w * rho**2 * cc)
    return float(num / den)


def fit_error(model, n_lobes=1, method="analytic", **kw):
    """eq. 11 error of ``Mo(o, i) · D*(h)`` (the NDF fit alone; supplement Fig. 3)."""
    axes, lam, mu = model.ndf_sg(n_lobes, method)

    def approx(o, i):
        from .base import half_vector

        hh = half_vector(o, i)
        d = (mu * np.exp(-lam * (1.0 - hh @ axes.T))).sum(-1)
        return model.mo(o, i) * d[..., None]

    return eq11_error(model, approx, **kw)


def warp_error(model, n_lobes=1, method="analytic", **kw):
    """eq. 11 error of the spherically warped SG slice (paper eq. 22; supplement Fig. 9), ks = 1."""
    from .warp import eval_slice, slice_lobes_numpy

    def approx(O, I):
        o = O[:, 0, :]
        a, l, m = slice_lobes_numpy(model, o, n_lobes, method)
        m = m / np.where(model.ks > 0, model.ks, 1.0)
        return eval_slice(a[:, None], l[:, None], m[:, None], I)

    return eq11_error(model, approx, **kw)
