r"""The fit behind :class:`warp_sg.brdf.models.measured.Measured` (paper §4.2, supplement §4; the model, the
alternating fit and the error measure are described in :mod:`warp_sg.brdf.models.measured`, which
re-exports these names): the MERL cell geometry, the PCA basis of 1-D shadowing curves, the SG
mixture fits of an NDF (Levenberg–Marquardt about z+, L-BFGS-B with free axes), the vectorized
microfacet fit of (kd, ks, S, D) and supplement eq. 11.
"""
from __future__ import annotations

import functools

import numpy as np

from ...core.cache import code_key
from ...core.errors import InputError
from ...numeric.pca import pca
from .. import merl
from ..fresnel import fresnel_normalised

N_S = 90
#: shadowing nodes θ_a = a/(N_S − 1) · π/2
S_THETA = np.arange(N_S) / (N_S - 1) * (np.pi / 2)
#: θh at the centres of the MERL θh bins
D_THETA = ((np.arange(merl.N_THETA_H) + 0.5) / merl.N_THETA_H) ** 2 * (np.pi / 2)
_D_EDGES = (np.arange(merl.N_THETA_H + 1) / merl.N_THETA_H) ** 2 * (np.pi / 2)
#: solid angle of each θh bin (2π (cos θ0 − cos θ1))
D_SOLID_ANGLE = 2 * np.pi * (np.cos(_D_EDGES[:-1]) - np.cos(_D_EDGES[1:]))
COS_MIN = 0.05
#: the hash of the code that computes the fit (part of its cache key; ``warp_sg.core.cache.code_key``)
FIT_VERSION = code_key(__name__, merl, fresnel_normalised, pca)


# --------------------------------------------------------------------------------------------
# shadowing PCA
# --------------------------------------------------------------------------------------------
def _smith_family():
    t = np.tan(np.minimum(S_THETA, np.pi / 2 - 1e-6))
    rows = [np.ones(N_S)]
    for alpha in np.geomspace(0.005, 3.0, 64):
        a = 1.0 / np.maximum(alpha * t, 1e-12)
        beck = np.where(a < 1.6, (3.535 * a + 2.181 * a * a) / (1 + 2.276 * a + 2.577 * a * a), 1.0)
        ggx = 2.0 / (1.0 + np.sqrt(1.0 + (alpha * t) ** 2))
        rows += [beck, ggx]
    return np.array(rows)


@functools.lru_cache(maxsize=8)
def shadowing_basis(terms=8):
    """PCA basis of 1-D shadowing curves on the nodes :data:`S_THETA`: ``(mean (90,), basis (terms, 90))``
    learnt from Smith G1 (Beckmann, rational fit of Walter et al. 2007; GGX) for roughness
    0.005..3 and the constant 1 (:func:`warp_sg.numeric.pca.pca`)."""
    res = pca(_smith_family(), int(terms))
    return res.mean.astype(np.float64), res.basis.astype(np.float64)


def compress_shadowing(S, terms=8):
    """Project S (…, 90) on the :func:`shadowing_basis`: ``(coeffs (…, terms), reconstruction (…, 90))``."""
    S = np.asarray(S, dtype=np.float64)
    if terms <= 0:
        return np.zeros(S.shape[:-1] + (0,)), S.copy()
    mean, basis = shadowing_basis(int(terms))
    coeffs = (S - mean) @ basis.T
    return coeffs, np.maximum(mean + coeffs @ basis, 0.0)


# --------------------------------------------------------------------------------------------
# SG fits of the NDF
# --------------------------------------------------------------------------------------------
def fit_ndf_sg(theta, D, weights, n_lobes=1):
    """SG mixture about z+ of an isotropic NDF sampled at ``theta`` (radians) with ``weights``
    (e.g. solid angles): minimise ``Σ w (D − Σk μk e^{−λk (1 − cos θ)})²`` by Levenberg–Marquardt
    over ``log λk, log μk``. Returns ``(axes (K,3), λ (K,), μ (K,))`` sorted by increasing λ."""
    from scipy.optimize import least_squares

    theta = np.asarray(theta, dtype=np.float64)
    D = np.asarray(D, dtype=np.float64)
    sw = np.sqrt(np.maximum(np.asarray(weights, dtype=np.float64), 0.0))
    omc = 2.0 * np.sin(0.5 * theta) ** 2
    K = int(n_lobes)
    if K < 1:
        raise InputError(f"must be >= 1, got {n_lobes}", where="lobes")
    # start: λ from the half-maximum width of D (D = 1/2 where λ(1 − cos θ) = ln 2)
    peak = float(np.max(D)) if D.size else 1.0
    half = np.nonzero(D < 0.5 * peak)[0]
    omc_half = omc[half[0]] if half.size else omc[-1]
    lam0 = np.log(2.0) / max(omc_half, 1e-8)

    def model(x):
        lam, mu = np.exp(x[:K]), np.exp(x[K:])
        return (mu * np.exp(-lam * omc[:, None])).sum(-1)

    best = None
    for spread in ([1.0] if K == 1 else [4.0, 16.0, 64.0]):
        s = np.geomspace(1.0, spread, K) / np.sqrt(spread)
        x0 = np.concatenate([np.log(lam0 * s), np.log(np.full(K, peak / K))])
        sol = least_squares(lambda x: sw * (D - model(x)), x0, method="lm", xtol=1e-12, ftol=1e-12,
                            max_nfev=4000)
        if best is None or sol.cost < best.cost:
            best = sol
    lam, mu = np.exp(best.x[:K]), np.exp(best.x[K:])
    order = np.argsort(lam)
    return np.tile([0.0, 0.0, 1.0], (K, 1)), lam[order], mu[order]


def fit_ndf_sg_anisotropic(ndf, n_lobes, theta_max=None):
    """SG mixture with free axes for an anisotropic NDF ``ndf(h (...,3)) -> (...)`` (paper §4.2:
    L-BFGS-B, via :func:`warp_sg.brdf.fitting.fit.fit_anisotropic`). Start: ``n_lobes`` lobes along the
    principal axis of the NDF's second moments on the tangent plane, spread over the width where
    D drops to 0.1 (supplement eq. 14), common λ from the narrow width."""
    from .fit import fit_anisotropic

    K = int(n_lobes)
    nt, nphi = 64, 64
    tm = np.pi / 2 if theta_max is None else float(theta_max)
    t = (np.arange(nt) + 0.5) / nt
    th = tm * t * t
    ph = (np.arange(nphi) + 0.5) / nphi * 2 * np.pi
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1)
    w = np.sin(TH) * 2 * t[:, None]
    Dv = np.asarray(ndf(h), dtype=np.float64)
    wd = w * Dv
    xy = h[..., :2]
    cov = np.einsum("ij,ija,ijb->ab", wd, xy, xy) / max(wd.sum(), 1e-300)
    evals, evecs = np.linalg.eigh(cov)
    wide = evecs[:, 1]
    # extent along the wide axis where D ≥ 0.1 D_max
    proj = np.abs(xy @ wide)
    big = Dv >= 0.1 * Dv.max()
    theta_v = float(np.arcsin(np.clip(proj[big].max(), 0, 1))) if big.any() else 0.1
    narrow = np.sqrt(max(evals[0], 1e-12))
    lam0 = 1.0 / max(narrow * narrow, 1e-6)
    theta_i = 2 * theta_v / (K + 1)
    a = (np.arange(K) - (K - 1) / 2.0) * theta_i
    axes0 = np.stack([np.sin(a) * wide[0], np.sin(a) * wide[1], np.cos(a)], -1)
    mu0 = np.maximum(np.asarray(ndf(axes0), dtype=np.float64), 1e-3)
    if theta_max is None:
        tm = min(np.pi / 2, 2.5 * theta_v + 6.0 / np.sqrt(lam0))
    return fit_anisotropic(ndf, axes0, np.full(K, lam0), mu0, tm)


def sg_mixture(h, axes, lam, mu):
    """``Σk μk exp(λk (h·pk − 1))`` for h (..., 3)."""
    h = np.asarray(h, dtype=np.float64)
    return (mu * np.exp(-lam * (1.0 - h @ np.asarray(axes).T))).sum(-1)


# --------------------------------------------------------------------------------------------
# the microfacet fit
# --------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=4)
def _cell_geometry(cos_min=COS_MIN):
    """Flat arrays over the usable cells: index, cos θi, cos θo, cos θd, θi, θo, θh bin, measure J."""
    o, i = merl.cell_directions()
    th, td, _ = merl.cell_angles()
    ci = i[..., 2].reshape(-1)
    co = o[..., 2].reshape(-1)
    ok = (ci >= cos_min) & (co >= cos_min)
    idx = np.nonzero(ok)[0]
    u = (np.arange(merl.N_THETA_H) + 0.5) / merl.N_THETA_H
    J = (np.cos(td) * np.sin(td) * np.sin(th) * u[:, None, None]).reshape(-1)[idx]
    ih = np.broadcast_to(np.arange(merl.N_THETA_H)[:, None, None], merl.SHAPE).reshape(-1)[idx]
    ti = np.arctan2(np.hypot(i[..., 0], i[..., 1]), i[..., 2]).reshape(-1)[idx]
    to = np.arctan2(np.hypot(o[..., 0], o[..., 1]), o[..., 2]).reshape(-1)[idx]
    cd = np.cos(td).reshape(-1)[idx]
    out = dict(idx=idx, ci=ci[idx], co=co[idx], cd=cd, ti=ti, to=to, ih=ih, J=J / J.max())
    for name, theta in (("i", ti), ("o", to)):  # linear-interpolation weights on the S nodes
        a0, a1, w0, w1 = _hat(theta)
        out.update({f"{name}a0": a0, f"{name}a1": a1, f"{name}w0": w0, f"{name}w1": w1})
    for v in out.values():
        v.setflags(write=False)
    return out


def _hat(theta):
    """Linear-interpolation weights of θ on the nodes S_THETA: (a0, a1, w0, w1)."""
    u = np.clip(theta / (np.pi / 2), 0.0, 1.0) * (N_S - 1)
    a0 = np.minimum(u.astype(np.int64), N_S - 2)
    f = u - a0
    return a0, a0 + 1, 1.0 - f, f


def _interp_S(S, theta):
    a0, a1, w0, w1 = _hat(theta)
    return S[a0] * w0 + S[a1] * w1


def _second_diff(n):
    L = np.zeros((n - 2, n))
    r = np.arange(n - 2)
    L[r, r], L[r, r + 1], L[r, r + 2] = 1.0, -2.0, 1.0
    return L


def _solve_shape(y, w, g):
    """Weighted log-linear LS for log D[bin] (90) and log S[node] (90), S(0) = 1."""
    nD = merl.N_THETA_H
    n = nD + N_S
    sel = (w > 0) & (y > 0)
    ly = np.log(np.where(sel, y, 1.0))
    w = np.where(sel, w, 0.0)
    ent = [(g["ih"], None), (nD + g["ia0"], g["iw0"]), (nD + g["ia1"], g["iw1"]),
           (nD + g["oa0"], g["ow0"]), (nD + g["oa1"], g["ow1"])]
    U = np.zeros(n * n)
    diag = np.zeros(n)
    b = np.zeros(n)
    wly = w * ly
    for k, (ik, vk) in enumerate(ent):
        wk = w if vk is None else w * vk
        b += np.bincount(ik, weights=wly if vk is None else wly * vk, minlength=n)
        diag += np.bincount(ik, weights=wk if vk is None else wk * vk, minlength=n)
        for il, vl in ent[k + 1:]:  # symmetric: pairs k < l, mirrored below
            U += np.bincount(ik * n + il, weights=wk * vl, minlength=n * n)
    U = U.reshape(n, n)
    A = U + U.T + np.diag(diag)
    scale = max(np.trace(A) / n, 1e-300)
    LD = _second_diff(nD)
    LS = _second_diff(N_S)
    A[:nD, :nD] += 1e-4 * scale * LD.T @ LD
    A[nD:, nD:] += 1e-2 * scale * LS.T @ LS
    A += 1e-9 * scale * np.eye(n)
    A[nD, nD] += 1e6 * scale  # gauge: log S(0) = 0
    x = np.linalg.solve(A, b)
    support = np.bincount(g["ih"], weights=w, minlength=nD)
    return x[:nD], x[nD:], support


def _shape(g, eta, D, S):
    """Φ = F/F1 · S(θi) S(θo) D(θh bin) / (π cos θi cos θo) at the usable cells."""
    F = fresnel_normalised(eta, g["cd"])
    Si = S[g["ia0"]] * g["iw0"] + S[g["ia1"]] * g["iw1"]
    So = S[g["oa0"]] * g["ow0"] + S[g["oa1"]] * g["ow1"]
    return F * Si * So * D[g["ih"]] / (np.pi * g["ci"] * g["co"])


def _linear_kd_ks(rho, phi, wcc):
    """Per channel weighted LS ``ρc ≈ kdc/π + ksc Φ`` with kd ≥ 0. rho (3, n)."""
    a11 = np.sum(wcc) / np.pi**2
    a12 = np.sum(wcc * phi) / np.pi
    a22 = np.sum(wcc * phi * phi)
    b1 = rho @ wcc / np.pi
    b2 = rho @ (wcc * phi)
    det = a11 * a22 - a12 * a12
    kd = (a22 * b1 - a12 * b2) / det
    ks = (a11 * b2 - a12 * b1) / det
    neg = kd < 0
    kd = np.where(neg, 0.0, kd)
    ks = np.where(neg, b2 / a22, ks)
    return kd, np.maximum(ks, 0.0)


def fit_microfacet(table, eta=1.33, iterations=3):
    """Fit ``kd, ks, S, D`` (module docstring) to a (3, 90, 90, 180) MERL table.

    Returns a dict: ``kd (3,)``, ``ks (3,)``, ``ndf (90,)`` D at the θh bin centres :data:`D_THETA`,
    ``ndf_support (90,)`` (data weight per bin), ``shadowing (90,)`` S at :data:`S_THETA`."""
    g = _cell_geometry()
    rho = np.asarray(table, dtype=np.float64).reshape(3, -1)[:, g["idx"]]
    rho_sum = rho.sum(0)
    cc = g["ci"] * g["co"]
    wcc = g["J"] * cc * cc
    F = fresnel_normalised(eta, g["cd"])
    lit = (g["ci"] > 0.3) & (g["co"] > 0.3) & (g["ih"] > 45)
    kd = np.pi * np.percentile(rho[:, lit], 5, axis=1) if lit.any() else np.zeros(3)
    D = S = support = None
    for _ in range(int(iterations)):
        spec = rho_sum - kd.sum() / np.pi
        y = spec * np.pi * cc / F
        pos = spec > 1e-9 * max(float(spec.max()), 1e-300)
        w = np.where(pos, g["J"] * (spec * cc) ** 2, 0.0)
        logD, logS, support = _solve_shape(y, w, g)
        S = np.exp(np.clip(logS, -50, 50))
        ok = support > 1e-9 * support.max()
        smax = 1.0
        supported_S = _s_support(g, w)
        if supported_S.any():
            smax = max(1.0, float(S[supported_S].max()))
        S = np.minimum(S, smax)
        D = np.exp(np.clip(logD - logD[0], -200, 50))
        if ok.any():  # no data beyond the last supported bin: D = 0 there
            D[np.nonzero(ok)[0][-1] + 1:] = 0.0
        phi = _shape(g, eta, D, S)
        kd, ks = _linear_kd_ks(rho, phi, wcc)
    return dict(kd=kd, ks=ks, ndf=D, ndf_support=support, shadowing=S)


def _s_support(g, w):
    s = (np.bincount(g["ia0"], weights=w * g["iw0"], minlength=N_S)
         + np.bincount(g["ia1"], weights=w * g["iw1"], minlength=N_S))
    return s > 1e-6 * s.max()


def eq11(table, approx_table):
    """Supplement eq. 11 over the usable MERL cells (measure J), all channels:
    ``Σ J (ρ − ρ^R)² (cos θi cos θo)² / Σ J (ρ cos θi cos θo)²``. Tables (3, 90, 90, 180) or
    already-gathered (3, n_usable) arrays."""
    g = _cell_geometry()

    def gather(t):
        t = np.asarray(t, dtype=np.float64)
        return t.reshape(3, -1)[:, g["idx"]] if t.size == 3 * merl.N_CELLS else t

    a, b = gather(table), gather(approx_table)
    w = g["J"] * (g["ci"] * g["co"]) ** 2
    return float(np.sum(w * (a - b) ** 2) / np.sum(w * a * a))


__all__ = ["N_S", "S_THETA", "D_THETA", "D_SOLID_ANGLE", "COS_MIN", "FIT_VERSION", "shadowing_basis",
           "compress_shadowing", "fit_ndf_sg", "fit_ndf_sg_anisotropic", "sg_mixture", "fit_microfacet", "eq11"]
