r"""The linear system of the SG mixture fit's amplitudes and its derivatives in the lobe parameters.

For lobes ``k`` with axis ``p_k = v_k / |v_k|`` (``v_k`` free in R³) and sharpness
``λ_k = exp(ℓ_k)``, every row of the stacked system of :mod:`precompute.environment.sg_fit` is a
weight times a function of ``c = x·p_k`` and ``λ_k`` for a fixed unit vector ``x`` (a texel
direction ``d_j`` or a normal ``n_m``)::

    A[j, k] = w_j F(x_j·p_k, λ_k)

    radiance rows    F = G(c, λ) = exp(λ (c − 1)),         ∂F/∂c = λ G,   ∂F/∂λ = (c − 1) G
    irradiance rows  F = ∫G(λ) e(c, λ)        (cosine="exact": the renderer's table, warp_sg.sg.irradiance)
                     F = Σ_l ⟨G(n; λc_l, μc_l), G_k⟩   (clamped-cosine SG lobes, eq. 40 by default)

and the chain rule gives, for the 4 parameters of lobe ``k`` (only column ``k`` depends on them)::

    ∂A[j, k]/∂v_k = w_j ∂F/∂c · (x_j − c p_k) / |v_k|,       ∂A[j, k]/∂ℓ_k = w_j λ_k ∂F/∂λ.

Exact irradiance: ``∫G = 2π(1 − e^{−2λ})/λ`` has ``λ ∂ln∫G/∂λ = 2λ e^{−2λ}/(1 − e^{−2λ}) − 1``;
``e`` is the exp of a bilinear interpolant of ``ln e`` in ``(log10 λ, c)`` (its derivatives are
those of the interpolant inside a cell), the sharp-lobe form ``m Φ(m/σ) + σ φ(m/σ)`` above the
table (``∂/∂m = Φ``, ``∂/∂σ = φ``) and ``c (1 − 1/λ)`` or 0 for a lobe clear of the horizon —
the branches of :func:`warp_sg.sg.irradiance.sg_irradiance_norm_np`, whose values are used.

Clamped-cosine SG (paper eq. 6): ``⟨G(n; λc, μc), G(p; λ, 1)⟩ = 4π μc e^{−λc−λ} sinh(d)/d`` with
``d = |λc n + λ p| = √(λc² + λ² + 2 λc λ c)``, so with the Langevin function
``𝓛(d) = coth d − 1/d``: ``∂/∂c = f 𝓛(d) λc λ / d`` and ``∂/∂λ = f (𝓛(d) (λ + λc c)/d − 1)``.
"""
from __future__ import annotations

import numpy as np
from scipy.special import ndtr

from warp_sg import sg as sgm
from warp_sg.sg import irradiance as irr

_LN10 = float(np.log(10.0))


def _langevin_over_d(d):
    """``(coth d − 1/d) / d`` with its limit ``1/3 − d²/45`` near 0."""
    small = d < 1e-3
    s = np.where(small, 1.0, d)
    return np.where(small, 1.0 / 3.0 - d * d / 45.0, (1.0 / np.tanh(s) - 1.0 / s) / s)


def _sharp_grad(c, lam):
    """``(∂e/∂c, ∂e/∂λ)`` of the sharp-lobe form :func:`warp_sg.sg.irradiance.e_sharp_np`."""
    m = c * (1.0 - 1.0 / lam)
    sig = np.sqrt(np.maximum((1.0 - c) * (1.0 + c), 0.0) / lam)
    ok = sig > 0.0
    s = np.where(ok, sig, 1.0)
    z = m / s
    big_phi, phi = ndtr(z), np.exp(-0.5 * z * z) / np.sqrt(2.0 * np.pi)
    de_dc = np.where(ok, big_phi * (1.0 - 1.0 / lam) - phi * c / (lam * s), (m > 0) * (1.0 - 1.0 / lam))
    de_dl = np.where(ok, big_phi * c / lam**2 - phi * s / (2.0 * lam), (m > 0) * c / lam**2)
    positive = np.where(ok, m * big_phi + s * phi, m) > 0.0
    return de_dc * positive, de_dl * positive


def exact_norm_grad(c, lam, e, table=None):
    """``(∂e/∂c, ∂e/∂λ)`` of ``e = sg_irradiance_norm_np(c, λ)`` (given as ``e``), branch by branch
    (module docstring); 0 where an argument is clamped."""
    tab = (irr.irradiance_table() if table is None else np.asarray(table)).astype(np.float64)
    lam = np.maximum(lam, irr.IRR_LAM_TINY)
    inside = np.abs(c) < 1.0
    c = np.clip(c, -1.0, 1.0)
    r_raw = (np.log10(lam) - irr.IRR_LOG10_LAM_MIN) * irr.IRR_ROWS_PER_DECADE
    r = np.clip(r_raw, 0.0, tab.shape[0] - 1.0)
    x = (c + 1.0) * 0.5 * (tab.shape[1] - 1.0)
    r0 = np.minimum(np.floor(r).astype(int), tab.shape[0] - 2)
    x0 = np.minimum(np.floor(x).astype(int), tab.shape[1] - 2)
    fr = r - r0
    d0 = tab[r0, x0 + 1] - tab[r0, x0]
    d1 = tab[r0 + 1, x0 + 1] - tab[r0 + 1, x0]
    fx = x - x0
    v0, v1 = tab[r0, x0] + d0 * fx, tab[r0 + 1, x0] + d1 * fx
    de_dc = e * (d0 * (1.0 - fr) + d1 * fr) * 0.5 * (tab.shape[1] - 1.0)
    r_free = (r_raw > 0.0) & (r_raw < tab.shape[0] - 1.0)
    de_dl = np.where(r_free, e * (v1 - v0) * irr.IRR_ROWS_PER_DECADE / (lam * _LN10), 0.0)
    sharp = lam > irr.IRR_LAM_SWITCH
    if np.any(sharp):
        sc, sl = _sharp_grad(c, lam)
        de_dc, de_dl = np.where(sharp, sc, de_dc), np.where(sharp, sl, de_dl)
    clear = (lam >= irr.ABOVE_HORIZON) & (lam * (1.0 - np.sqrt(np.maximum((1.0 - c) * (1.0 + c), 0.0)))
                                          >= irr.ABOVE_HORIZON)
    de_dc = np.where(clear, np.where(c > 0, 1.0 - 1.0 / lam, 0.0), de_dc)
    de_dl = np.where(clear, np.where(c > 0, c / lam**2, 0.0), de_dl)
    return de_dc * inside, de_dl


def _cosine_lobes(cosine):
    lc, mc = cosine if cosine is not None else (sgm.CLAMPED_COSINE_SHARPNESS, sgm.CLAMPED_COSINE_AMPLITUDE)
    return zip(np.atleast_1d(np.asarray(lc, np.float64)), np.atleast_1d(np.asarray(mc, np.float64)))


def _cosine_terms(n, axes, lam, cosine):
    """``[(λc, ⟨G(n; λc, μc), G(p_k; λ_k, 1)⟩ (..., K))]`` per lobe of the clamped cosine."""
    return [(l_c, sgm.inner_product(n[..., None, :], l_c, m_c, axes, lam, 1.0)) for l_c, m_c in _cosine_lobes(cosine)]


def irradiance_matrix(normals, axes, lam, cosine=None):
    """Irradiance at each normal of each unit-amplitude SG, (..., K): ``⟨C*(n), G_k⟩`` through the
    clamped-cosine SG(s) ``cosine = (λc, μc)`` (scalars or lists of a multi-lobe fit; default
    eq. 40), or with ``cosine="exact"`` ``∫ G_k max(n·i, 0) di`` by ``warp_sg.sg.irradiance``
    (within 2 %, what the renderer evaluates)."""
    n = np.asarray(normals, np.float64)
    ax = np.asarray(axes, np.float64)
    c = np.einsum("...d,kd->...k", n, ax)
    return _block_value("exact" if isinstance(cosine, str) else "cosine", n, c, ax, np.asarray(lam, np.float64),
                        cosine)[0]


def _dlog_integral(lam):
    """``∂ ln∫G/∂λ = 2e^{−2λ}/(1 − e^{−2λ}) − 1/λ`` (→ −1 + λ/3 as λ → 0)."""
    small = lam < 1e-3
    s = np.where(small, 1.0, lam)
    return np.where(small, -1.0 + lam / 3.0, 2.0 * np.exp(-2.0 * s) / -np.expm1(-2.0 * s) - 1.0 / s)


def _block_value(kind, x, c, ax, lam, cosine):
    """``F`` (rows, K) of a block and what :func:`_block_grad` reuses."""
    if kind == "radiance":
        f = np.exp(lam * (c - 1.0))
        return f, f
    if kind == "exact":
        e = irr.sg_irradiance_norm_np(c, np.broadcast_to(lam, c.shape))
        return e * sgm.integral(lam, 1.0), e
    terms = _cosine_terms(x, ax, lam, cosine)
    return sum(t for _, t in terms), terms  # a sum over the cosine's lobes


def _block_grad(kind, c, lam, keep):
    """``(∂F/∂c, ∂F/∂λ)`` (rows, K) of a block (module docstring)."""
    if kind == "radiance":
        return lam * keep, (c - 1.0) * keep
    if kind == "exact":
        de_dc, de_dl = exact_norm_grad(c, np.broadcast_to(lam, c.shape), keep)
        ig = sgm.integral(lam, 1.0)
        return ig * de_dc, ig * (de_dl + _dlog_integral(lam) * keep)
    f_c = f_l = 0.0
    for l_c, t in keep:
        d = np.sqrt(np.maximum(l_c * l_c + lam * lam + 2.0 * l_c * lam * c, 0.0))
        g = _langevin_over_d(d)
        f_c = f_c + t * g * l_c * lam
        f_l = f_l + t * (g * (lam + l_c * c) - 1.0)
    return f_c, f_l


class LobeDesign:
    """The stacked system ``A(p, λ)`` (rows: the blocks in order) and ``∂A/∂x`` for the packed
    parameters ``x = (v_k, ℓ_k)_k`` (module docstring).

    ``blocks``: ``(x (rows, 3) unit vectors, w (rows,), kind)`` with kind ``"radiance"``, or
    ``"irradiance"`` through ``cosine`` (``"exact"``, or the clamped-cosine SG(s), default eq. 40)."""

    def __init__(self, blocks, cosine=None):
        kind_of = {"radiance": "radiance", "irradiance": "exact" if isinstance(cosine, str) else "cosine"}
        self.blocks = [(np.asarray(x, np.float64), np.asarray(w, np.float64), kind_of[kind]) for x, w, kind in blocks]
        self.cosine = cosine

    @staticmethod
    def unpack(x):
        """``(axes (K, 3), λ (K,), |v| (K,))`` of the packed parameters ``x`` (4K,)."""
        x = np.asarray(x, np.float64).reshape(-1, 4)
        nv = np.linalg.norm(x[:, :3], axis=1)
        return x[:, :3] / nv[:, None], np.exp(x[:, 3]), nv

    def evaluate(self, x):
        """``(A (rows, K), state)``; ``state`` feeds :meth:`derivative`."""
        ax, lam, nv = self.unpack(x)
        parts, state = [], []
        for xb, w, kind in self.blocks:
            c = xb @ ax.T
            f, keep = _block_value(kind, xb, c, ax, lam, self.cosine)
            parts.append(w[:, None] * f)
            state.append((c, keep))
        return np.concatenate(parts, 0), (ax, lam, nv, state)

    def derivative(self, state):
        """``∂A[:, k]/∂x_{4k+i}`` as (rows, 4K): column ``4k + i`` is the derivative of column ``k``."""
        ax, lam, nv, per_block = state
        out = []
        for (xb, w, kind), (c, keep) in zip(self.blocks, per_block):
            f_c, f_l = _block_grad(kind, c, lam, keep)
            g = w[:, None] * f_c / nv
            gc = g * c
            planes = [g * xb[:, i:i + 1] - gc * ax[:, i] for i in range(3)] + [w[:, None] * lam * f_l]
            out.append(np.stack(planes, -1).reshape(len(w), -1))
        return np.concatenate(out, 0)
