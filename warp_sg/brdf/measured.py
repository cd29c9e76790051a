r"""Measured BRDFs (paper §4.2, supplement §4): a general microfacet model fitted to a MERL table,
then an SG mixture fitted to its NDF.

Model (paper eq. 13–14, Wang et al. 2008; Ngan et al. 2005)::

    ρ(o, i) = kd/π + ks ∘ ρs(o, i),
    ρs(o, i) = F(|i·h|)/F(1) · S(θo) S(θi) / (π cos θo cos θi) · D(h) = Mo(o, i) · D(h)

* ``F`` — Cook–Torrance Fresnel of paper eq. 14 with relative index of refraction ``eta``
  (paper: constant η = 1.33), divided by its value at normal incidence so that ``ks`` is the
  specular scale at normal incidence (this only rescales ``ks``; it is eq. 14 otherwise).
* ``S`` — an isotropic 1-D shadowing factor (paper: "we constrain the shadowing factor to be
  isotropic"), tabulated on 90 nodes ``θ_a = a/89 · π/2`` (``S(0) = 1``) and PCA-compressed
  90-D → ``pca_terms``-D (paper: 8-D) against a basis learnt from a family of physical shadowing
  curves (Smith G1 for Beckmann and GGX roughness 0.005..3, see :func:`shadowing_basis`).
* ``D`` — the NDF, tabulated on the 90 θh bins of the MERL table (``D(first bin) = 1``), then fitted by
  an SG mixture ``D*(h) = Σk μk exp(λk (h·z − 1))`` with 1–2 lobes about z+ by Levenberg–Marquardt
  (``scipy.optimize.least_squares(method="lm")``, solid-angle weights of the θh bins), lobes
  sorted by increasing sharpness (paper §4.2). :func:`fit_ndf_sg_anisotropic` fits lobes with free
  axes by L-BFGS-B (anisotropic NDFs; MERL data are isotropic).

Fit of (kd, ks, S, D) — vectorized over the MERL cells, alternating 3 times:

1. with ``kd`` fixed, ``y = (Σc ρc − Σc kdc/π) · π cos θi cos θo / F`` satisfies
   ``log y = log(ks D(θh)) + log S(θi) + log S(θo)``: linear least squares in the 180 unknowns
   ``log D[bin]``, ``log S[node]`` (S linear between nodes), weighted by
   ``J · ((ρ − kd/π) cos θi cos θo)²`` so the log residual approximates the absolute residual of
   supplement eq. 11; ``J = cos θd sin θd sin θh · √(θh/(π/2))`` is the measure of a cell
   (``dωi dωo = 4 cos θd dωh dωd``; √θh spacing). A small second-difference penalty regularises
   bins/nodes with little data. Normal equations are accumulated with ``np.bincount``.
2. with the shape ``Φ = F S S D/(π cos cos)`` fixed, ``kd``, ``ks`` per channel by weighted linear
   least squares (``kd ≥ 0``).

``kd`` starts at π × the 5th percentile of the data over well-lit cells. Cells with
``min(cos θi, cos θo) < 0.05`` are left out.

Errors (:meth:`Measured.errors`) use supplement eq. 11 over the MERL cells (measure ``J``)::

    E = Σ (ρ − ρ^R)² (cos θi cos θo)² / Σ (ρ cos θi cos θo)²

for the full BRDF (``ρ`` the data) and the approximations ``microfacet`` (tabulated D and S),
``sg`` (SG NDF) and ``sg_pca`` (SG NDF and PCA-compressed S: what the renderer uses).

The microfacet fit and the PCA are cached with :func:`warp_sg.cache.load_or_build` (kind
``measured_fit``, keyed by the table's content hash, ``eta`` and ``pca_terms``); the SG fit of the
NDF (milliseconds) is redone for each lobe count.
"""
from __future__ import annotations

import functools
import hashlib
from pathlib import Path

import numpy as np

from ..cache import content_key, load_or_build
from ..errors import InputError
from ..pca import pca
from . import merl
from .base import SpecularBRDF, as_scalar, dirs, half_vector, upper
from .fresnel import fresnel_eq14, fresnel_normalised  # noqa: F401  (eq. 14, normalised at normal incidence)

N_S = 90
#: shadowing nodes θ_a = a/(N_S − 1) · π/2
S_THETA = np.arange(N_S) / (N_S - 1) * (np.pi / 2)
#: θh at the centres of the MERL θh bins
D_THETA = ((np.arange(merl.N_THETA_H) + 0.5) / merl.N_THETA_H) ** 2 * (np.pi / 2)
_D_EDGES = (np.arange(merl.N_THETA_H + 1) / merl.N_THETA_H) ** 2 * (np.pi / 2)
#: solid angle of each θh bin (2π (cos θ0 − cos θ1))
D_SOLID_ANGLE = 2 * np.pi * (np.cos(_D_EDGES[:-1]) - np.cos(_D_EDGES[1:]))
COS_MIN = 0.05
FIT_VERSION = 1


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
    0.005..3 and the constant 1 (:func:`warp_sg.pca.pca`)."""
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
    L-BFGS-B, via :func:`warp_sg.brdf.fit.fit_anisotropic`). Start: ``n_lobes`` lobes along the
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


# --------------------------------------------------------------------------------------------
# the model class
# --------------------------------------------------------------------------------------------
class Measured(SpecularBRDF):
    """A measured (MERL) BRDF with its fitted microfacet model and NDF SG mixture.

    ``Measured(file="x.binary", lobes=1, eta=1.33, pca_terms=8)`` or ``Measured(table=(3,90,90,180))``.

    * ``eval(o, i)`` — the exact data (nearest MERL cell, :func:`warp_sg.brdf.merl.merl_lookup`).
    * ``mo(o, i)`` — ``F(|i·h|)/F(1) · S(θo)S(θi)/(π cos θo cos θi)`` (without ks), S the
      PCA-compressed shadowing, bilinear in (θo, θi) from :meth:`mo_table` exactly like the kernel.
    * ``ndf(h)`` — the SG mixture ``D*`` (what the renderer uses); ``ndf_tabulated(h)`` the fitted
      table (linear in √θh).
    * ``ndf_sg(n_lobes=None, method="fit")`` — the LM fit about z+ (``n_lobes`` defaults to ``lobes``).
    * ``fitted_eval(o, i, which="sg_pca"|"sg"|"microfacet")`` — ``kd/π + ks ∘ Mo · D``.
    * ``errors()`` — supplement eq. 11 of each approximation against the data.
    * ``merl_table()`` (flat float32, R, G, B blocks) and ``mo_table()`` ((90, 90) float32 of
      ``S(θo_a) S(θi_b)``) for ``material_wp.pack_materials``.
    """

    NAME = "measured"
    MODEL_ID = 9
    PARAMS = ("file", "lobes", "eta", "pca_terms")

    def __init__(self, file=None, lobes=1, eta=1.33, pca_terms=8, *, table=None, cache=True):
        if (file is None) == (table is None):
            raise InputError("give exactly one of 'file' (a MERL .binary) or 'table'", where="file")
        try:
            n = int(lobes)
        except (TypeError, ValueError):
            raise InputError(f"expected a positive integer, got {lobes!r}", where="lobes") from None
        if n < 1 or n != lobes:
            raise InputError(f"must be a positive integer, got {lobes!r}", where="lobes")
        self.lobes = n
        self.own_lobes = n
        self.eta = as_scalar(eta, "eta", lo=0.0, lo_open=True)
        try:
            self.pca_terms = int(pca_terms)
        except (TypeError, ValueError):
            raise InputError(f"expected an integer, got {pca_terms!r}", where="pca_terms") from None
        if not 0 <= self.pca_terms <= N_S:
            raise InputError(f"must be in 0..{N_S}, got {pca_terms!r}", where="pca_terms")
        self.file = None if file is None else str(file)
        if file is not None:
            self.table = merl.read_merl(file)
        else:
            t = np.asarray(table, dtype=np.float64)
            if t.shape != (3,) + merl.SHAPE:
                raise InputError(f"expected shape (3, 90, 90, 180), got {t.shape}", where="table")
            if not np.all(np.isfinite(t)):
                raise InputError("table contains NaN/infinite values", where="table")
            self.table = np.maximum(t, 0.0)
        self.table.setflags(write=False)
        fit = self._fit(cache)
        self.kd = fit["kd"].copy()
        self.ks = fit["ks"].copy()
        self.ndf_table = fit["ndf"].copy()
        self.ndf_support = fit["ndf_support"].copy()
        self.shadowing = fit["shadowing"].copy()
        self.shadowing_coeffs = fit["shadowing_coeffs"].copy()
        self.shadowing_pca = fit["shadowing_pca"].copy()
        # the SG fit of the NDF is cheap (LM on 90 samples): not cached, so the cached microfacet
        # fit serves every lobe count
        self.lobe_axes, self.lobe_sharpness, self.lobe_amplitude = fit_ndf_sg(
            D_THETA, self.ndf_table, self._fit_weights(), self.lobes)
        self._mo_table = np.outer(self.shadowing_pca, self.shadowing_pca)

    # -- fitting ----------------------------------------------------------------------------
    def _fit_weights(self):
        w = D_SOLID_ANGLE * (self.ndf_support > 1e-9 * max(self.ndf_support.max(), 1e-300))
        return w

    def _build(self):
        fit = fit_microfacet(self.table, self.eta)
        coeffs, S_pca = compress_shadowing(fit["shadowing"], self.pca_terms)
        fit.update(shadowing_coeffs=coeffs, shadowing_pca=S_pca)
        return {k: np.asarray(v, dtype=np.float64) for k, v in fit.items()}

    def _fit(self, cache):
        if not cache:
            return self._build()
        digest = hashlib.sha256(np.ascontiguousarray(self.table).tobytes()).hexdigest()
        key = content_key("measured_fit", FIT_VERSION, digest, self.eta, self.pca_terms)
        return load_or_build("measured_fit", key, self._build)

    # -- contract ---------------------------------------------------------------------------
    def merl_table(self):
        """The scaled data as one flat float32 array: R, G, B blocks of 90·90·180 (``merl_eval``)."""
        return self.table.astype(np.float32).reshape(-1)

    def mo_table(self):
        """(90, 90) float32 ``S(θo_a) S(θi_b)`` on the nodes :data:`S_THETA` (``measured_mo``)."""
        return self._mo_table.astype(np.float32)

    def kernel_params(self):
        return (float(self.lobes), float(self.eta), 0.0, 0.0)

    def fresnel_record(self):
        return 2, (self.eta, self.eta, self.eta), (0.0, 0.0, 0.0)

    def ndf_analytic_lambda(self):
        return float(self.lobe_sharpness[np.argmax(self.lobe_amplitude)])

    @property
    def equivalent_m(self):
        """Cook–Torrance roughness of the single-lobe fit, ``m = √(2/λ)`` (paper eq. 12)."""
        _, lam, _ = self.ndf_sg(1)
        return float(np.sqrt(2.0 / lam[0]))

    # -- evaluation -------------------------------------------------------------------------
    def eval(self, o, i):
        """The measured BRDF (..., 3) by nearest-cell lookup; zero below the horizon."""
        o, i = dirs(o, i)
        return merl.merl_lookup(self.table, o, i)

    def _shadow(self, o, i, S):
        to = np.arctan2(np.hypot(o[..., 0], o[..., 1]), o[..., 2])
        ti = np.arctan2(np.hypot(i[..., 0], i[..., 1]), i[..., 2])
        if S is None:  # bilinear in the (90, 90) table, as in the kernel
            T = self._mo_table
            a0, a1, wa0, wa1 = _hat(to)
            b0, b1, wb0, wb1 = _hat(ti)
            return wa0 * (wb0 * T[a0, b0] + wb1 * T[a0, b1]) + wa1 * (wb0 * T[a1, b0] + wb1 * T[a1, b1])
        return _interp_S(S, to) * _interp_S(S, ti)

    def mo(self, o, i, shadowing=None):
        """``Mo(o, i)`` (..., 3) without ks; ``shadowing``: a (90,) S to use instead of the PCA one."""
        o, i = dirs(o, i)
        h = half_vector(o, i)
        c = np.abs(np.sum(i * h, axis=-1))
        ss = self._shadow(o, i, shadowing)
        val = fresnel_normalised(self.eta, c) * ss / (np.pi * np.maximum(o[..., 2], 1e-3) * np.maximum(i[..., 2], 1e-3))
        val = np.where(upper(o, i), val, 0.0)
        return np.repeat(val[..., None], 3, axis=-1)

    def ndf(self, h):
        """The SG mixture ``D*(h)`` of the ``lobes``-lobe fit (zero below the horizon)."""
        h = np.asarray(h, dtype=np.float64)
        return np.where(h[..., 2] > 0, sg_mixture(h, self.lobe_axes, self.lobe_sharpness, self.lobe_amplitude), 0.0)

    def ndf_tabulated(self, h):
        """The fitted NDF table, linear in √θh between bin centres."""
        h = np.asarray(h, dtype=np.float64)
        th = np.arctan2(np.hypot(h[..., 0], h[..., 1]), h[..., 2])
        u = np.sqrt(np.clip(th / (np.pi / 2), 0, 1)) * merl.N_THETA_H - 0.5
        return np.where(h[..., 2] > 0, np.interp(u, np.arange(merl.N_THETA_H), self.ndf_table), 0.0)

    def ndf_sg(self, n_lobes=None, method="fit"):
        """``(axes (K,3), λ (K,), μ (K,))``: LM fit about z+ of the tabulated NDF (``method`` is
        accepted for the common API; measured NDFs are always fitted)."""
        n = self.lobes if n_lobes is None else int(n_lobes)
        if n == self.lobes:
            return self.lobe_axes.copy(), self.lobe_sharpness.copy(), self.lobe_amplitude.copy()
        return fit_ndf_sg(D_THETA, self.ndf_table, self._fit_weights(), n)

    def specular(self, o, i):
        """``Mo · D*`` without ks (the SG approximation the renderer uses)."""
        o, i = dirs(o, i)
        return self.mo(o, i) * self.ndf(half_vector(o, i))[..., None]

    def fitted_eval(self, o, i, which="sg_pca", lobes=None):
        """``kd/π + ks ∘ Mo · D`` of an approximation: ``microfacet`` (tabulated D, full S),
        ``sg`` (SG D*, full S) or ``sg_pca`` (SG D*, PCA S — the renderer's); ``lobes``: SG lobe
        count (default ``self.lobes``)."""
        o, i = dirs(o, i)
        h = half_vector(o, i)
        if which == "microfacet":
            d = self.ndf_tabulated(h)
        elif which in ("sg", "sg_pca"):
            ax, lam, mu = self.ndf_sg(lobes)
            d = np.where(h[..., 2] > 0, sg_mixture(h, ax, lam, mu), 0.0)
        else:
            raise InputError(f"unknown approximation '{which}' (microfacet, sg, sg_pca)", where="which")
        mo = self.mo(o, i) if which == "sg_pca" else self.mo(o, i, self.shadowing)
        val = self.kd / np.pi + self.ks * (mo * d[..., None])
        return np.where(upper(o, i)[..., None], val, 0.0)

    def errors(self, lobes=None):
        """Supplement eq. 11 (all channels, MERL cells, full BRDF) of each approximation:
        ``{"microfacet": .., "sg": .., "sg_pca": ..}`` (``lobes``: SG lobe count, default ``self.lobes``)."""
        g = _cell_geometry()
        o, i = merl.cell_directions()
        O = o.reshape(-1, 3)[g["idx"]]
        I = i.reshape(-1, 3)[g["idx"]]
        data = self.table.reshape(3, -1)[:, g["idx"]]
        out = {}
        for which in ("microfacet", "sg", "sg_pca"):
            approx = self.fitted_eval(O, I, which, lobes).T
            out[which] = eq11(data, approx)
        return out

    def __repr__(self):
        src = self.file if self.file else "<table>"
        return f"Measured(file={src!r}, lobes={self.lobes}, eta={self.eta}, pca_terms={self.pca_terms})"


def fit_file(path, lobes=1, eta=1.33, pca_terms=8):
    """Convenience: ``Measured(file=path, ...)``."""
    return Measured(file=Path(path), lobes=lobes, eta=eta, pca_terms=pca_terms)


# --------------------------------------------------------------------------------------------
# report (docs/measured.md): python -m warp_sg.brdf.measured [OUT_DIR]
# --------------------------------------------------------------------------------------------
def synthetic_materials():
    """Analytic BRDFs standing in for MERL measurements (no downloads): name -> (model, note)."""
    from .microfacet import CookTorrance, TorranceSparrow
    from .phong import BlinnPhong
    from .ward import Ward

    return {
        "ct_m0.05": CookTorrance(kd=(0.02, 0.02, 0.02), ks=(30, 25, 20), m=0.05, fresnel={"eta": 1.33}),
        "ct_m0.1": CookTorrance(kd=(0.1, 0.05, 0.02), ks=(20, 25, 30), m=0.1, fresnel={"eta": 1.33}),
        "ct_m0.2": CookTorrance(kd=(0.1, 0.05, 0.02), ks=(20, 25, 30), m=0.2, fresnel={"eta": 1.33}),
        "ct_m0.4": CookTorrance(kd=(0.2, 0.2, 0.2), ks=(20, 20, 20), m=0.4, fresnel={"eta": 1.33}),
        "ts_m0.15": TorranceSparrow(kd=(0.3, 0.1, 0.1), ks=(1.0, 1.0, 1.0), m=0.15, fresnel={"eta": 1.5}),
        "ward_a0.12": Ward(kd=(0.05, 0.1, 0.2), ks=(0.3, 0.3, 0.3), alpha=0.12),
        "blinn_phong_n200": BlinnPhong(kd=(0.2, 0.2, 0.1), ks=(0.6, 0.6, 0.6), n=200),
    }


def error_table(models, lobes=(1, 2), eta=1.33, pca_terms=8):
    """Rows ``{material, lobes, kd.., ks.., lambda, m_equiv, err_microfacet, err_sg, err_sg_pca}``
    for named BRDF models (or (3,90,90,180) tables) tabulated as MERL tables and fitted."""
    rows = []
    for name, model in models.items():
        table = model if isinstance(model, np.ndarray) else merl.tabulate(model)
        meas = Measured(table=table, lobes=1, eta=eta, pca_terms=pca_terms)
        for k in lobes:
            e = meas.errors(k)
            _, lam, mu = meas.ndf_sg(k)
            rows.append(dict(material=name, lobes=k, kd=" ".join(f"{v:.3f}" for v in meas.kd),
                             ks=" ".join(f"{v:.3f}" for v in meas.ks),
                             sharpness=" ".join(f"{v:.1f}" for v in lam),
                             amplitude=" ".join(f"{v:.3f}" for v in mu),
                             err_microfacet=e["microfacet"], err_sg=e["sg"], err_sg_pca=e["sg_pca"]))
    return rows


def plot_fit(meas, path=None, ax=None, lobes=(1, 2), title=None):
    """NDF table and its SG fits against θh (and the shadowing S, full and PCA) — matplotlib."""
    import matplotlib.pyplot as plt

    own = ax is None
    if own:
        fig, ax = plt.subplots(1, 2, figsize=(9, 3.4))
    th = np.degrees(D_THETA)
    ax[0].semilogy(th, np.maximum(meas.ndf_table, 1e-6), "k.", ms=3, label="fitted NDF table")
    for k in lobes:
        a, lam, mu = meas.ndf_sg(k)
        d = (mu * np.exp(-lam * (1 - np.cos(D_THETA))[:, None])).sum(-1)
        ax[0].semilogy(th, np.maximum(d, 1e-6), label=f"{k} SG lobe{'s' if k > 1 else ''}")
    ax[0].set_ylim(1e-4, 2)
    ax[0].set_xlabel("θh (degrees)")
    ax[0].set_title(title or "NDF D(θh)")
    ax[0].legend(fontsize=8)
    ax[1].plot(np.degrees(S_THETA), meas.shadowing, "k-", label="S (90-D)")
    ax[1].plot(np.degrees(S_THETA), meas.shadowing_pca, "r--", label=f"S PCA ({meas.pca_terms}-D)")
    ax[1].set_xlabel("θ (degrees)")
    ax[1].set_title("shadowing S(θ)")
    ax[1].legend(fontsize=8)
    if own:
        fig.tight_layout()
        if path:
            fig.savefig(path, dpi=110)
            plt.close(fig)
    return ax


def _main(out_dir):
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    mats = synthetic_materials()
    rows = error_table(mats)
    with open(out / "measured_errors.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.3e}" if isinstance(v, float) else v) for k, v in r.items()})
    names = ["ct_m0.1", "ts_m0.15", "blinn_phong_n200"]
    fig, axs = plt.subplots(len(names), 2, figsize=(9, 3.0 * len(names)))
    for r, name in enumerate(names):
        plot_fit(Measured(table=merl.tabulate(mats[name]), lobes=1), ax=axs[r], title=f"{name}: NDF")
    fig.tight_layout()
    fig.savefig(out / "measured_fit.png", dpi=110)
    plt.close(fig)
    for r in rows:
        print(f"| {r['material']} | {r['lobes']} | {r['sharpness']} | {r['err_microfacet']:.2e} | "
              f"{r['err_sg']:.2e} | {r['err_sg_pca']:.2e} |")


if __name__ == "__main__":
    import sys

    _main(sys.argv[1] if len(sys.argv) > 1 else "docs/figures")
