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
  fits λ with μ = 1 (solid curves of supplement Fig. 2); K lobes fit all λk, μk (paper §4.2),
  distinct and sorted by increasing sharpness, with alternating-sign amplitudes under bounds and a
  non-negative mixture (non-negative same-axis lobes cannot beat one lobe for these NDFs; see
  :func:`fit_isotropic`);
* anisotropic: L-BFGS-B (paper §4.2) over all lobe axes, sharpnesses and amplitudes, started from
  the analytic construction, same L2 objective on a (θ, φ) grid.
"""
from __future__ import annotations

import functools

import numpy as np

from ...core.errors import InputError
from ...sg import EPSILON  # noqa: F401  (ε of supplement eq. 14, for the models' layouts)
from ..helpers import half_vector, suggest
from ..spherical_warp import WARP_COS_EPS

METHODS = ("analytic", "fit")


# --------------------------------------------------------------------------------------------
# analytic constructions
# --------------------------------------------------------------------------------------------
def aniso_lobes(n_lobes, lam, theta_v, wide_x, ndf, normalise=False):
    """Supplement eq. 14: ``n_lobes`` (odd) lobes along the wide axis (x if ``wide_x`` else y).

    ``normalise`` (GGX): amplitude k is ``D(pk)`` divided by the overlap of the lobes at pk,
    ``Σ_j e^{−λ(1 − cos((k − j)θi))}``, so the mixture at the lobe axes is ≈ D instead of summing
    up to several times it when the lobes are wide against their spacing."""
    N = int(n_lobes)
    theta_i = 2.0 * theta_v / (N + 1)
    a = (np.arange(N) - (N - 1) / 2.0) * theta_i
    axes = np.zeros((N, 3))
    axes[:, 0 if wide_x else 1] = np.sin(a)
    axes[:, 2] = np.cos(a)
    amp = np.asarray(ndf(axes), dtype=np.float64)
    if normalise:
        k = np.arange(N)
        amp = amp / np.exp(-lam * _one_minus_cos((k[:, None] - k[None, :]) * theta_i)).sum(1)
    return axes, np.full(N, float(lam)), amp


def aniso_setup(model):
    """``(lam, theta_v, wide_x)`` of the anisotropic construction: the model's ``aniso_layout``
    hook (Ashikhmin–Shirley, Ward, GGX)."""
    layout = getattr(model, "aniso_layout", None)
    if layout is None:
        raise InputError(f"model '{model.NAME}' has no anisotropic construction", where="model")
    return layout()


def is_anisotropic(model):
    """The model has an anisotropic layout (``aniso_layout``) and is not isotropic."""
    return hasattr(model, "aniso_layout") and not model.isotropic


def lobe_count(model, n_lobes):
    """Number of NDF lobes used for ``model`` when ``n_lobes`` is asked for (a model's own count,
    ``own_lobes``, wins)."""
    if getattr(model, "own_lobes", None):
        return int(model.own_lobes)
    n = int(n_lobes)
    if is_anisotropic(model) and n % 2 == 0:
        n += 1  # the construction needs an odd count
    return n


# --------------------------------------------------------------------------------------------
# nonlinear fits
# --------------------------------------------------------------------------------------------
def _iso_grid(lam0, n=600, theta_max=None):
    """θ grid on [0, θmax] refined near 0 (t² spacing), with sin θ dθ weights; θmax defaults to
    ``min(π/2, 10/√λ0)`` (a long-tailed NDF such as GGX passes its own)."""
    if theta_max is None:
        theta_max = min(np.pi / 2, 10.0 / np.sqrt(max(lam0, 1e-9)))
    t = (np.arange(n) + 0.5) / n
    theta = theta_max * t * t
    w = np.sin(theta) * theta_max * 2.0 * t / n * 2.0 * np.pi
    return theta, w


def _one_minus_cos(theta):
    return 2.0 * np.sin(0.5 * theta) ** 2


#: multi-lobe isotropic fits (:func:`fit_isotropic`): bound on each amplitude |μk|, on their sum
#: Σ|μk| (with Σμk ≈ 1 the negative lobes sum to ≥ −1), and the range of the sharpness ratio of
#: neighbouring lobes λ_{k+1}/λ_k (the lower end keeps the lobes distinct)
MULTI_AMP_BOUND = 2.0
MULTI_TOTAL_BOUND = 3.0
MULTI_MIN_RATIO = 1.1
MULTI_MAX_RATIO = 8.0
#: the multi-lobe mixture is ≥ −NONNEG_TOL (peak 1) everywhere on the sphere
NONNEG_TOL = 1e-10


def _lobe_matrix(omc, lam):
    return np.exp(-np.multiply.outer(omc, lam))


def _free_single(sw, D, omc, lam0):
    """Best single lobe with free amplitude (the start of the multi-lobe fits)."""
    from scipy.optimize import least_squares

    def res(x):
        return sw * (D - x[1] * np.exp(-np.exp(x[0]) * omc))

    sol = least_squares(res, [np.log(lam0), 1.0], method="lm", xtol=1e-12, ftol=1e-12)
    return np.exp(sol.x[:1]), sol.x[1:]


def _signs(K, positive=False):
    """Alternating amplitude signs, broadest lobe positive: ``(+, −, +, …)``; all ``+`` if ``positive``."""
    return np.ones(K) if positive else (-1.0) ** np.arange(K)


def _fit_signed(w, D, omc, u_pos, starts, K, ref, positive=False):
    """SLSQP fit of ``Σk μk e^{−λk u}`` to ``D`` minimising ``Σ w (mixture − D)² / ref``.

    Variables ``y = (ln λ1, ln λ2/λ1, …, ln λK/λ_{K−1}, p1 … pK)``, ``μk = (−1)^{k−1} pk`` with
    ``0 ≤ pk ≤ B``, ``Σ pk ≤ S`` (so ``Σ|μk| ≤ S``), ``MULTI_MIN_RATIO ≤ λ_{k+1}/λ_k ≤
    MULTI_MAX_RATIO`` and the mixture ``≥ 0`` at ``u_pos`` (``positive``: every ``μk = pk ≥ 0``). Returns the best feasible
    ``(λ, μ, objective)`` over ``starts`` (a list of ``(λ, μ)``; each start is itself a candidate)."""
    from scipy.optimize import minimize

    B, S = MULTI_AMP_BOUND, MULTI_TOTAL_BOUND
    sg = _signs(K, positive)

    def unpack(y):
        return np.exp(np.cumsum(y[:K])), sg * y[K:]

    def chain(g_ln):  # d/d ln λk -> d/d y (ln λ is the cumulative sum of y[:K]); last axis
        return np.cumsum(g_ln[..., ::-1], axis=-1)[..., ::-1]

    def f(y):
        lam, mu = unpack(y)
        E = _lobe_matrix(omc, lam)
        r = E @ mu - D
        wr = 2.0 * w * r / ref
        g_ln = (wr @ (E * -omc[:, None])) * mu * lam
        return float(np.sum(w * r * r) / ref), np.concatenate([chain(g_ln), (wr @ E) * sg])

    def pos(y):  # the mixture divided by e^{−λ1 u} (same sign, no underflow)
        lam, mu = unpack(y)
        return _lobe_matrix(u_pos, lam - lam[0]) @ mu

    def pos_jac(y):
        lam, mu = unpack(y)
        E = _lobe_matrix(u_pos, lam - lam[0])
        g_ln = E * -u_pos[:, None] * mu * lam
        g_ln[:, 0] = u_pos * lam[0] * (E[:, 1:] @ mu[1:])
        return np.concatenate([chain(g_ln), E * sg], axis=1)

    tv_jac = np.concatenate([np.zeros(K), -np.ones(K)])
    cons = [{"type": "ineq", "fun": pos, "jac": pos_jac},
            {"type": "ineq", "fun": lambda y: S - np.sum(y[K:]), "jac": lambda y: tv_jac}]
    ln0 = np.log(starts[0][0][0])
    bounds = ([(ln0 - 4.0, ln0 + 4.0)] + [(np.log(MULTI_MIN_RATIO), np.log(MULTI_MAX_RATIO))] * (K - 1)
              + [(0.0, B)] * K)
    lo = np.array([b[0] for b in bounds]) - 1e-12
    hi = np.array([b[1] for b in bounds]) + 1e-12
    best = None
    for lam_s, mu_s in starts:
        y0 = np.concatenate([[np.log(lam_s[0])], np.diff(np.log(lam_s)), np.maximum(sg * mu_s, 0.0)])
        sol = minimize(f, np.clip(y0, lo, hi), jac=True, method="SLSQP", bounds=bounds, constraints=cons,
                       options={"maxiter": 200, "ftol": 1e-13})
        for y in (y0, sol.x):
            feasible = (np.all(np.isfinite(y)) and np.all(y >= lo) and np.all(y <= hi)
                        and np.sum(y[K:]) <= S + 1e-9 and np.min(pos(y)) >= -NONNEG_TOL)
            if feasible:
                val = f(y)[0]
                if best is None or val < best[2]:
                    lam, mu = unpack(y)
                    best = (lam, mu, val)
    return best


def _fit_nonneg(w, D, omc, u_pos, u_dense, starts, K, ref, positive=False):
    """:func:`_fit_signed`, then cutting planes: while the mixture dips below zero between the
    constraint points (checked on ``u_dense``), add its negative local minima to them and refit
    from the result. ``starts[0]`` must be non-negative on ``u_dense`` (the fallback)."""
    best = _fit_signed(w, D, omc, u_pos, starts, K, ref, positive)
    for _ in range(8):
        v = _lobe_matrix(u_dense, best[0] - best[0][0]) @ best[1]  # mixture / e^{−λ1 u}
        if np.min(v) >= -NONNEG_TOL:
            return best[0], best[1]
        vm = np.concatenate([[np.inf], v, [np.inf]])
        dips = np.flatnonzero((v < -NONNEG_TOL) & (v <= vm[:-2]) & (v <= vm[2:]))
        u_pos = np.union1d(u_pos, u_dense[dips])
        best = _fit_signed(w, D, omc, u_pos, [(best[0], best[1]), starts[0]], K, ref, positive)
    return starts[0]


def _bounded_amplitudes(sw, D, omc, lam, positive=False):
    """Least-squares amplitudes with the signs and bounds of :func:`_fit_signed` (Σ|μ| scaled
    down to the bound if needed)."""
    from scipy.optimize import lsq_linear

    sg = _signs(len(lam), positive)
    A = _lobe_matrix(omc, lam) * (sw[:, None] * sg)
    p = lsq_linear(A, sw * D, bounds=(0.0, MULTI_AMP_BOUND)).x
    return sg * p * min(1.0, MULTI_TOTAL_BOUND / max(np.sum(p), 1e-300))


def fit_isotropic(ndf_theta, lam0, n_lobes, prev=None, theta_max=None, positive=False):
    """Least-squares SG mixture about z+ of an isotropic NDF given as a function of θ.

    One lobe: λ fitted with μ = 1 (supplement Fig. 2). K > 1 lobes: all λk and μk, the lobes
    distinct (``λ_{k+1}/λ_k ≥ MULTI_MIN_RATIO``), sorted by increasing sharpness.

    Why multi-lobe amplitudes are *signed*: with every axis at the normal the mixture is a sum of
    exponentials ``Σ μk e^{−λk u}`` in ``u = 1 − cos θ``. With all ``μk ≥ 0`` such a sum is
    log-convex in u, while the Cook–Torrance, Ward and Blinn–Phong NDFs are log-concave in u
    (``θ² = 2u + u²/3 + …``, ``tan²θ = 2u + 3u² + …``, ``−ln(1 − u) = u + u²/2 + …``); the L2
    optimum over non-negative mixtures is then a single lobe (non-negative least squares over a
    dense λ grid returns one lobe; a free fit collapses every lobe onto it), so extra
    non-negative lobes cannot lower the error at all. A broad positive lobe minus a sharper
    smaller one flattens the peak the way these NDFs do, so the amplitudes alternate in sign from
    the broadest (positive) lobe on, ``μk = (−1)^{k−1} pk``, with safeguards: ``pk ≤
    MULTI_AMP_BOUND`` and ``Σ|μk| ≤ MULTI_TOTAL_BOUND`` (the unconstrained optimum degenerates into
    huge cancelling pairs that float32 tables and per-lobe lighting approximations would
    amplify), and the mixture itself ``≥ 0`` for ``u ∈ [0, 2]`` (the whole sphere) and on to
    ``u = 0.5/WARP_COS_EPS``, so the NDF stays non-negative, and so does the warped slice (its
    lobes share one axis and one sharpness scale, paper eq. 17–22, and it evaluates the mixture
    at ``u = (1 − i·pW)/(4|pD·o|)``).

    The K-lobe fit (SLSQP, deterministic) starts from the (K−1)-lobe fit plus a zero-amplitude
    sharpest lobe (a candidate itself, so the error never exceeds the (K−1)-lobe error; the
    2-lobe fit starts from the single lobe with free amplitude, which is at least as good as the
    μ = 1 lobe) and from geometric spreads of λ about the dominant lobe, and keeps the best.
    Where more lobes cannot help visibly the error still does not increase, and a lobe may then
    get (near) zero amplitude: sharp Blinn–Phong, ``(n·h)^n = e^{−n u}(1 − n u²/2 + …)``, is
    within ~4e-7 relative L2 of one lobe at n = 500 already (~1e-9 with two lobes, ~1e-12 with
    four). Relative L2 errors for K = 1 (μ = 1), 2, 3, 4: Cook–Torrance m = 0.15: 1.3e-6, 5.2e-9,
    9.0e-11, 7.2e-12; Ward α = 0.3: 1.3e-3, 6.9e-5, 2.9e-5, 5.4e-6. About 0.1–0.3 s per lobe
    count (cached by :func:`ndf_sg_for`).

    ``prev``: the ``(λ, μ)`` of this NDF's (K−1)-lobe fit, if already known (K > 2; saves
    refitting the chain; the result is the same). ``theta_max``: the θ range of the fit (default
    ``min(π/2, 10/√λ0)``; GGX covers its long tail, :meth:`warp_sg.brdf.models.ggx.GGX.ndf_fit_extent`).
    ``positive``: all amplitudes ``≥ 0`` instead of alternating signs — for NDFs that are log-convex
    in u, where a sum of non-negative exponentials is the natural fit: GGX,
    ``D̂ = 1/(1 − u(2 − u)(1 − 1/α²))²`` with its heavy ``(α/θ)⁴`` tail."""
    from scipy.optimize import least_squares

    theta, w = _iso_grid(lam0, theta_max=theta_max)
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
        lam, mu = _free_single(sw, D, omc, lam0)
        # non-negativity on u ∈ [0, U]: the sphere (u ≤ 2) and the warped slice, which evaluates
        # the mixture at u = (1 − i·pW)/(4|pD·o|) ≤ 2/(4 WARP_COS_EPS)
        U = 0.5 / WARP_COS_EPS
        u_pos = np.concatenate([[0.0], np.geomspace(1e-2 / lam[0], 2.0, 48), np.geomspace(2.5, U, 12)])
        u_dense = np.union1d(np.geomspace(1e-6 / lam[0], U, 12288), np.linspace(0.0, 2.0, 16385))
        k_first = 2
        if prev is not None and K > 2 and len(prev[0]) == K - 1:
            lam, mu = (np.asarray(v, dtype=np.float64).copy() for v in prev)
            k_first = K
        for k in range(k_first, K + 1):
            err_prev = float(np.sum(w * (_lobe_matrix(omc, lam) @ mu - D) ** 2))
            scale = max(err_prev, 1e-30)
            # the (k−1)-lobe fit plus a zero-amplitude sharpest lobe (its error: the (k−1)-lobe
            # error) and geometric spreads of λ about the dominant lobe, amplitudes by bounded LS
            starts = [(np.append(lam, lam[-1] * 1.25), np.append(mu, 0.0))]
            lam_dom = lam[np.argmax(np.abs(mu))]
            for c in (1.0, 1.25):
                for s in (1.2, 1.6, 2.5):
                    ls = c * lam_dom * np.geomspace(1 / s, s, k)
                    starts.append((ls, _bounded_amplitudes(sw, D, omc, ls, positive)))
            lam, mu = _fit_nonneg(w, D, omc, u_pos, u_dense, starts, k, scale, positive)
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


def _key(model, n_lobes, method):
    return (model.NAME, tuple(model.kernel_params()), getattr(model, "own_lobes", None), n_lobes, method)


def _compute(model, n_lobes, method):
    K = lobe_count(model, n_lobes)
    if is_anisotropic(model):
        lam, theta_v, wide_x = aniso_setup(model)
        axes, lams, amps = aniso_lobes(K, lam, theta_v, wide_x, model.ndf,
                                       normalise=bool(getattr(model, "aniso_normalised", False)))
        if method == "fit":
            theta_max = min(np.pi / 2, 2.5 * theta_v + 6.0 / np.sqrt(lam))
            axes, lams, amps = fit_anisotropic(model.ndf, axes, lams, amps, theta_max)
        return axes, lams, amps
    lam0 = model.ndf_analytic_lambda()
    if method == "analytic" and K == 1:
        return np.array([[0.0, 0.0, 1.0]]), np.array([lam0]), np.ones(1)
    prev = None
    if K > 2 and lobe_count(model, K - 1) == K - 1:  # (a model's own count would recurse)
        _, lam_p, mu_p = _cached(_key(model, K - 1, "fit"), _Ref(model))
        prev = (lam_p, mu_p)
    extent = model.ndf_fit_extent() if hasattr(model, "ndf_fit_extent") else None
    return fit_isotropic(_iso_ndf_theta(model), lam0, K, prev, theta_max=extent,
                         positive=bool(getattr(model, "ndf_log_convex", False)))


def ndf_sg_for(model, n_lobes=1, method="analytic"):
    """``(axes (K,3), sharpness (K,), amplitude (K,))`` of the NDF SG mixture of ``model``.

    ``method="analytic"`` with ``n_lobes > 1`` on an isotropic model falls back to the
    nonlinear fit (there is no analytic multi-lobe rule)."""
    if method not in METHODS:
        raise InputError(f"unknown fit method '{method}'{suggest(method, METHODS)}", where="method")
    try:
        n = int(n_lobes)
    except (TypeError, ValueError):
        raise InputError(f"expected a positive integer, got {n_lobes!r}", where="n_lobes") from None
    if n < 1 or n != n_lobes:
        raise InputError(f"must be a positive integer, got {n_lobes!r}", where="n_lobes")
    axes, lam, mu = _cached(_key(model, n, method), _Ref(model))
    return axes.copy(), lam.copy(), mu.copy()


# --------------------------------------------------------------------------------------------
# supplement eq. 11 error
# --------------------------------------------------------------------------------------------
def _quad_setup(lam, n_o=24, n_phi_o=1, n_th=96, n_ph=64, theta_max=None):
    """Directions o (Gauss–Legendre in cos θo × φo) and h (θh refined near z × φh, up to
    ``theta_max``, default ``min(π/2, 12/√λ)``) with weights."""
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
    if theta_max is None:
        theta_max = min(np.pi / 2, 12.0 / np.sqrt(max(lam, 1e-9)))
    t = (np.arange(n_th) + 0.5) / n_th
    th = theta_max * t * t
    ph = (np.arange(n_ph) + 0.5) / n_ph * 2 * np.pi
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1).reshape(-1, 3)
    wh = (np.sin(TH) * theta_max * 2 * t[:, None] / n_th * 2 * np.pi / n_ph).reshape(-1)
    return o, wo, h, wh


def eq11_error(model, approx, n_o=24, n_phi_o=None, n_th=96, n_ph=64, theta_max=None):
    """Supplement eq. 11 weighted error of ``approx(o, i) -> (..., 3)`` against ``ρs`` (ks = 1):

    ``Σ (ρs − ρs^R)² ((i·n)(o·n))² / Σ (ρs (i·n)(o·n))²`` as integrals over (o, i), computed in
    (o, h) with ``dω_i = 4 (o·h) dω_h`` on a grid refined around the NDF peak (green channel);
    ``theta_max``: the θh range (default ``min(π/2, 12/√λ)``; long-tailed NDFs need π/2)."""
    lam = float(np.max(model.ndf_sg(1, "analytic")[1])) if model.is_specular else 1.0
    if n_phi_o is None:
        n_phi_o = 8 if is_anisotropic(model) else 1
    o, wo, h, wh = _quad_setup(lam, n_o, n_phi_o, n_th, n_ph, theta_max)
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
        hh = half_vector(o, i)
        d = (mu * np.exp(-lam * (1.0 - hh @ axes.T))).sum(-1)
        return model.mo(o, i) * d[..., None]

    return eq11_error(model, approx, **kw)


def warp_error(model, n_lobes=1, method="analytic", **kw):
    """eq. 11 error of the spherically warped SG slice (paper eq. 22; supplement Fig. 9), ks = 1."""
    from ..spherical_warp import eval_slice, slice_lobes_numpy

    def approx(O, I):
        o = O[:, 0, :]
        a, l, m = slice_lobes_numpy(model, o, n_lobes, method)
        m = m / np.where(model.ks > 0, model.ks, 1.0)
        return eval_slice(a[:, None], l[:, None], m[:, None], I)

    return eq11_error(model, approx, **kw)
