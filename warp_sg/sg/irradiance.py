r"""Irradiance of an SG light on a diffuse surface, accurate for any lobe sharpness (issue 11, item 2).

The renderer's clamped cosine as one SG (eq. 40: ``1.170 exp(2.133 (n·i − 1))``) is 17 % low at 54°
from the normal and has a step at the horizon. This module gives the exact form instead::

    E(n; p, λ, μ) = ∫_{S²} μ exp(λ (i·p − 1)) max(n·i, 0) di = μ · ∫G(λ) · e(c, λ),     c = n·p,
    ∫G(λ) = 2π (1 − e^{−2λ}) / λ      (evaluated with −expm1(−2λ)),

where ``e(c, λ) ∈ [0, 1]`` (the normalised irradiance: the mean of ``max(n·i, 0)`` under the lobe)
depends on ``c ∈ [−1, 1]`` and ``λ`` only. It is non-decreasing in ``c``.

Exact values (:func:`e_exact`, float64): in the lobe's frame (pole ``p``, ``n = (s, 0, c)``,
``s = √(1 − c²)``) a ring at polar angle θ sees ``n·i = A + B cos φ`` with ``A = c cos θ``,
``B = s sin θ ≥ 0``, and its azimuthal integral is closed form::

    R(θ) = ∫_0^{2π} max(A + B cos φ, 0) dφ = 2πA (A ≥ B),  0 (A ≤ −B),
                                           2 (A arccos(−A/B) + √(B² − A²)) otherwise,
    E/μ  = ∫_0^π exp(−2λ sin²(θ/2)) R(θ) sin θ dθ.

``R`` has ``(·)^{3/2}`` kinks at ``cos θ = ±s``; the θ integral is split there, each piece is cut
where the weight has fallen by ``e^{−50}`` relative to its start (so sharp lobes are resolved:
the weight is a bump of width ~1/√λ), the piece's start factor ``e^{−2λ sin²(a/2)}`` is taken out
(all exponents ≤ 0, written without cancellation) and the rest is Gauss–Legendre after a
smoothstep map that removes the end-point kinks. Converged to ~1e-13 for λ ∈ [1e-4, 1e6].

Limits:

* λ → 0 (:func:`e_small_lambda`): ``e = 1/4 + λ c / 6 + O(λ²)``. (Expand ``e^{λ(i·p − 1)}``:
  ``∫ max(n·i, 0) = π``, ``∫ i max(n·i, 0) = (2π/3) n`` and ``∫G = 4π(1 − λ) + O(λ²)``.) So below
  λ = 1e-2 the function is flat to ``|e(c, λ) − e(c, 1e-2)| ≤ 1e-2/6`` (< 0.7 %).
* λ → ∞ (:func:`e_sharp_np`, the ``@wp.func`` :func:`sg_irradiance_sharp`): in the tangent plane
  the lobe is a Gaussian of variance 1/λ per axis and ``n·i ≈ m + s u``, ``u ~ N(0, 1/λ)``, so::

      e ≈ m Φ(m/σ) + σ φ(m/σ),    m = c (1 − 1/λ),    σ = s / √λ,

  (Φ, φ the normal CDF and density). ``m`` carries the mean ``E[cos θ] = coth λ − 1/λ ≈ 1 − 1/λ``;
  with ``m = c`` the error is ``~c/λ`` (1e-3 absolute, 0.5 % relative at λ = 1e3). Measured against
  :func:`e_exact`: at λ = 1e3 the error is ≤ 0.19 % wherever e > 1e-3 and ≤ 5e-6 absolute
  everywhere; 0.6 % / 1.3e-5 at λ = 500; 2.3 % / 5.3e-5 at λ = 200; it shrinks like 1/λ.

Table (:func:`irradiance_table`, default path): the exact ``ln e`` in float32 (clamped at −80,
i.e. e ≈ 1.8e-35), rows uniform in ``log10 λ ∈ [−2, 3]`` (32 per decade, 161 rows), columns uniform
in ``c ∈ [−1, 1]`` (513); the lookup is ``exp`` of the bilinear interpolant in ``(log10 λ, c)``.
A lobe entirely above the horizon (``λ (1 − √(1 − c²)) ≥ 24``, :data:`ABOVE_HORIZON`: its value
on the horizon is e^{−24}) has ``e = c (coth λ − 1/λ) = c (1 − 1/λ)`` for λ ≥ 24, exactly, and is
not looked up (most lit points of a small light: no log, no exp); one entirely below it (the same
test with c < 0) has e ≤ e^{−24} λ/2, far below the budget's floor, and is 0 (the far side of a
small light: the shading kernel then skips its BRDF). Below λ = 1e-2 the first row is
used (flat, see above: ≤ 0.67 % off); above the switch λ = 1e3
(:data:`IRR_LAM_SWITCH`, the last row) the sharp-lobe form is used (the step there is ≤ 2.5e-5 in
``e``). ``ln e`` rather than ``e`` is tabulated because near c = −1 ``e`` decays like ``e^{−2λ}``
from row to row (bilinear ``e`` on 16 × 257 was 2.0 % off there even with the floor below); the
interpolant stays monotone in ``c``. Measured on λ ∈ [1e-2, 1e3]: ≤ 0.35 % wherever e > 1e-3.
Error budget, checked in ``tests/test_sg_irradiance.py`` against brute-force sphere integration::

    |E − E_ref| ≤ 0.02 E_ref + 1e-4 ∫G(λ)

— the absolute floor ``1e-4 ∫G`` (1e-4 in ``e``) is for the deep tail below the horizon, where the
true value underflows (``e ~ e^{−λ c²/2}`` for c < 0, ``e^{−2λ}`` at c = −1).
"""
import functools

import numpy as np
import warp as wp
from scipy.special import ndtr

from warp_sg.sg.algebra_wp import sg_integral

# ---- table layout (shared by numpy and the @wp.func) ----
IRR_LOG10_LAM_MIN = -2.0
IRR_LOG10_LAM_MAX = 3.0
IRR_ROWS_PER_DECADE = 32
IRR_N_LAM = int(round((IRR_LOG10_LAM_MAX - IRR_LOG10_LAM_MIN) * IRR_ROWS_PER_DECADE)) + 1  # 161
IRR_N_C = 513
#: Gauss–Legendre nodes per quadrature piece for the table (converged to ~1e-12 already at 64).
IRR_TABLE_NODES = 64
#: λ (1 − sin θ) from which a lobe at angle θ from the normal has no mass below the horizon that
#: matters (its value there is e^{−24}; the mass below is under λ e^{−24} ≈ 4e-11 λ of the total):
#: then e = c (1 − 1/λ), the lobe's mean cosine, exactly (no table)
ABOVE_HORIZON = 24.0
#: Above this sharpness the sharp-lobe Gaussian form replaces the table (its last row).
IRR_LAM_SWITCH = 10.0 ** IRR_LOG10_LAM_MAX
#: λ is clamped to at least this (∫G and e stay finite at λ = 0).
IRR_LAM_TINY = 1e-30
#: The table holds ``max(ln e, IRR_LOG_E_MIN)`` (e^{−80} ≈ 1.8e-35: far below any floor, float32-safe).
IRR_LOG_E_MIN = -80.0

_TWO_PI = 2.0 * np.pi
_TAIL = 50.0  # each quadrature piece stops where its weight has fallen by e^{−50}


# --------------------------------------------------------------------------------------------
# exact values and limits (numpy, float64)
# --------------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=8)
def _smooth_gauss_legendre(n):
    """Gauss–Legendre on [0, 1] after the smoothstep map ``u ↦ 3u² − 2u³``: (map, weight·map')."""
    x, w = np.polynomial.legendre.leggauss(n)
    u = 0.5 * (x + 1.0)
    return 3.0 * u**2 - 2.0 * u**3, 0.5 * w * 6.0 * u * (1.0 - u)


def ring_integral(a, b):
    """``∫_0^{2π} max(A + B cos φ, 0) dφ`` for ``B ≥ 0`` (closed form, float64, broadcasts)."""
    a, b = np.broadcast_arrays(np.asarray(a, np.float64), np.asarray(b, np.float64))
    mid = (a < b) & (a > -b)
    bs = np.where(mid, b, 1.0)
    part = 2.0 * (a * np.arccos(np.clip(-a / bs, -1.0, 1.0)) + np.sqrt(np.maximum(b * b - a * a, 0.0)))
    return np.where(mid, part, np.where(a >= b, _TWO_PI * a, 0.0))


def _e_exact_flat(c, lam, n_nodes):
    s = np.sqrt(np.maximum((1.0 - c) * (1.0 + c), 0.0))
    th1 = np.arccos(s)  # kinks of R(θ): cos θ = ±s
    u, wu = _smooth_gauss_legendre(n_nodes)
    total = np.zeros(c.shape[0])
    for a, b in ((np.zeros_like(c), th1), (th1, np.pi - th1), (np.pi - th1, np.full_like(c, np.pi))):
        sa2 = np.sin(0.5 * a) ** 2
        b_cut = 2.0 * np.arcsin(np.minimum(1.0, np.sqrt(sa2 + 0.5 * _TAIL / lam)))
        length = np.maximum(np.minimum(b, b_cut) - a, 0.0)
        th = a + length * u
        # −2λ (sin²(θ/2) − sin²(a/2)) ≤ 0 without cancellation
        expo = -2.0 * lam * np.sin(0.5 * (th - a)) * np.sin(0.5 * (th + a))
        f = np.exp(expo) * ring_integral(c * np.cos(th), s * np.sin(th)) * np.sin(th)
        total += np.exp(-2.0 * lam[:, 0] * sa2[:, 0]) * length[:, 0] * (f @ wu)
    return total / (_TWO_PI * -np.expm1(-2.0 * lam[:, 0]) / lam[:, 0])


def e_exact(c, lam, n_nodes: int = 128):
    """Exact normalised irradiance ``e(c, λ) = E / (μ ∫G)`` by quadrature (float64, broadcasts).

    ``E = ∫ μ exp(λ (i·p − 1)) max(n·i, 0) di``, ``c = n·p`` (clipped to [−1, 1]), ``λ > 0``.
    """
    c, lam = np.broadcast_arrays(np.asarray(c, np.float64), np.asarray(lam, np.float64))
    if np.any(~(lam > 0)) or not np.all(np.isfinite(lam)):
        raise ValueError("e_exact: λ must be positive and finite")
    shape = c.shape
    c = np.clip(c.reshape(-1, 1), -1.0, 1.0)
    lam = lam.reshape(-1, 1)
    out = np.empty(c.shape[0])
    step = 2048
    for i in range(0, c.shape[0], step):
        out[i:i + step] = _e_exact_flat(c[i:i + step], lam[i:i + step], n_nodes)
    return out.reshape(shape)


def e_small_lambda(c, lam):
    """λ → 0 limit ``e ≈ 1/4 + λ c / 6`` (error O(λ²))."""
    return 0.25 + np.asarray(lam, np.float64) * np.asarray(c, np.float64) / 6.0


def e_sharp_np(c, lam):
    """Sharp-lobe form ``m Φ(m/σ) + σ φ(m/σ)``, ``m = c (1 − 1/λ)``, ``σ = √(1 − c²)/√λ`` (λ ≳ 1e3)."""
    c = np.clip(np.asarray(c, np.float64), -1.0, 1.0)
    c, lam = np.broadcast_arrays(c, np.asarray(lam, np.float64))
    m = c * (1.0 - 1.0 / lam)
    sigma = np.sqrt(np.maximum((1.0 - c) * (1.0 + c), 0.0) / lam)
    ok = sigma > 0.0
    z = m / np.where(ok, sigma, 1.0)
    v = m * ndtr(z) + sigma * np.exp(-0.5 * z * z) / np.sqrt(_TWO_PI)
    return np.maximum(np.where(ok, v, m), 0.0)


@functools.lru_cache(maxsize=1)
def irradiance_table() -> np.ndarray:
    """Exact ``ln e(c, λ)`` table ``(IRR_N_LAM, IRR_N_C)`` float32, clamped at ``IRR_LOG_E_MIN``
    (161 rows: log10 λ ∈ [−2, 3], 513 columns: c ∈ [−1, 1]); the lookups return ``exp`` of its
    bilinear interpolant. It depends on nothing but this module's code, so it is kept on disk
    (:func:`warp_sg.core.cache.cached_table`, keyed by that code; 1.2 CPU-s to build) and every
    cold start after the first reads it."""
    from warp_sg.core.cache import cached_table

    return cached_table("sg_irradiance", (__name__,), build_irradiance_table)


def build_irradiance_table() -> np.ndarray:
    """:func:`irradiance_table` computed (``e_exact`` at every node, float64, then ``ln``)."""
    lam = 10.0 ** np.linspace(IRR_LOG10_LAM_MIN, IRR_LOG10_LAM_MAX, IRR_N_LAM)
    c = np.linspace(-1.0, 1.0, IRR_N_C)
    tab = np.clip(e_exact(c[None, :], lam[:, None], IRR_TABLE_NODES), 0.0, 1.0)
    with np.errstate(divide="ignore"):
        return np.maximum(np.log(tab), IRR_LOG_E_MIN).astype(np.float32)


def sg_irradiance_norm_np(c, lam, table: np.ndarray | None = None):
    """numpy twin (float64 math, same table) of the ``@wp.func`` :func:`sg_irradiance_norm`: ``e(c, λ)``."""
    tab = irradiance_table() if table is None else np.asarray(table)
    c, lam = np.broadcast_arrays(np.asarray(c, np.float64), np.asarray(lam, np.float64))
    lam = np.maximum(lam, IRR_LAM_TINY)
    c = np.clip(c, -1.0, 1.0)
    r = np.clip((np.log10(lam) - IRR_LOG10_LAM_MIN) * IRR_ROWS_PER_DECADE, 0.0, tab.shape[0] - 1.0)
    x = (c + 1.0) * 0.5 * (tab.shape[1] - 1.0)
    r0 = np.minimum(np.floor(r).astype(int), tab.shape[0] - 2)
    x0 = np.minimum(np.floor(x).astype(int), tab.shape[1] - 2)
    fr = r - r0
    fx = x - x0
    tab = tab.astype(np.float64)
    v0 = tab[r0, x0] * (1.0 - fx) + tab[r0, x0 + 1] * fx
    v1 = tab[r0 + 1, x0] * (1.0 - fx) + tab[r0 + 1, x0 + 1] * fx
    v = np.exp(v0 * (1.0 - fr) + v1 * fr)
    v = np.where(lam > IRR_LAM_SWITCH, e_sharp_np(c, lam), v)
    # the whole lobe on one side of the horizon (as _clear_of_horizon): its mean cosine above, 0 below
    clear = (lam >= ABOVE_HORIZON) & (lam * (1.0 - np.sqrt(np.maximum((1.0 - c) * (1.0 + c), 0.0))) >= ABOVE_HORIZON)
    v = np.where(clear & (c < 0), 0.0, v)
    return np.where(clear & (c > 0), c * (1.0 - 1.0 / lam), v)


def sg_irradiance_np(n, p, lam, mu=1.0, table: np.ndarray | None = None):
    """numpy twin of :func:`sg_irradiance`: ``E = μ ∫G(λ) e(n·p, λ)``, ∫G = 2π(1 − e^{−2λ})/λ.

    ``n``, ``p`` unit (..., 3); ``μ`` a scalar, or per channel with one more (trailing) axis than
    ``n·p`` as in :mod:`warp_sg.sg` (e.g. (N, 3) or (1, 3) for N normals). Returns (...) or (..., C), float64.
    """
    c = np.sum(np.asarray(n, np.float64) * np.asarray(p, np.float64), axis=-1)
    lam = np.maximum(np.asarray(lam, np.float64), IRR_LAM_TINY)
    val = _TWO_PI * -np.expm1(-2.0 * lam) / lam * sg_irradiance_norm_np(c, lam, table)
    mu = np.asarray(mu, np.float64)
    return val[..., None] * mu if mu.ndim > val.ndim else val * mu


# --------------------------------------------------------------------------------------------
# Warp
# --------------------------------------------------------------------------------------------

_LOG10_LAM_MIN = wp.constant(IRR_LOG10_LAM_MIN)
_ROWS_PER_DECADE = wp.constant(float(IRR_ROWS_PER_DECADE))
_LAM_SWITCH = wp.constant(IRR_LAM_SWITCH)
_LAM_TINY = wp.constant(IRR_LAM_TINY)
_INV_LN10 = wp.constant(0.4342944819032518)
_INV_SQRT2 = wp.constant(0.7071067811865476)
_INV_SQRT_2PI = wp.constant(0.3989422804014327)

_device_tables: dict = {}


def irradiance_table_array(device="cpu") -> wp.array:
    """The ``ln e(c, λ)`` table as a ``wp.array2d(dtype=float)`` on ``device`` (built once per device)."""
    from warp_sg.core.device import device_table

    return device_table(_device_tables, irradiance_table, device)


@wp.func
def sg_irradiance_sharp(c: float, lam: float) -> float:
    """e ≈ m Φ(m/σ) + σ φ(m/σ), m = c (1 − 1/λ), σ = √(1 − c²)/√λ (sharp lobes, λ > 1e3)."""
    m = c * (1.0 - 1.0 / lam)
    sigma = wp.sqrt(wp.max((1.0 - c) * (1.0 + c), 0.0) / lam)
    if sigma <= 0.0:
        return wp.max(m, 0.0)
    z = m / sigma
    if z > 6.0:  # Φ(z) > 1 − 1e-9 and σφ(z) < 1e-9 m: e = m to float precision (most lit points)
        return m
    if z < -6.0:  # the lobe is below the horizon: m Φ(z) + σ φ(z) < 1e-9 σ
        return 0.0
    v = m * 0.5 * wp.erfc(-z * _INV_SQRT2) + sigma * _INV_SQRT_2PI * wp.exp(-0.5 * z * z)
    return wp.max(v, 0.0)


_ABOVE = wp.constant(ABOVE_HORIZON)


@wp.func
def _clear_of_horizon(c: float, lam: float) -> float:
    """e(c, λ) where the whole lobe lies on one side of the horizon (``λ (1 − √(1 − c²)) ≥ 24``: its
    value on the horizon is under e^{−24} of its peak), else −1 — no table, no log or exp:

    * above it (c > 0): ``c (1 − 1/λ)``, the lobe's mean cosine ``c (coth λ − 1/λ)`` with
      coth λ = 1 to e^{−48}, exactly;
    * below it (c < 0): 0, since e ≤ e^{−24} λ/2 (2e-8 at λ = 1e3, far below the error budget's
      1e-4 floor; sharper lobes: the sharp form at z ≤ −√48, under 1e-11 σ) — the shading kernel
      then skips the light's BRDF."""
    if lam >= _ABOVE and c != 0.0:
        if lam * (1.0 - wp.sqrt(wp.max((1.0 - c) * (1.0 + c), 0.0))) >= _ABOVE:
            if c > 0.0:
                return c * (1.0 - 1.0 / lam)
            return 0.0
    return -1.0


@wp.func
def sg_irradiance_row(table: wp.array2d(dtype=float), lam: float) -> float:
    """The (fractional) row of λ in :func:`irradiance_table_array`, clamped to the table: a
    per-lobe constant, computed once per lobe where many points share the lobe."""
    l = wp.max(lam, _LAM_TINY)
    return wp.clamp((wp.log(l) * _INV_LN10 - _LOG10_LAM_MIN) * _ROWS_PER_DECADE, 0.0, float(table.shape[0] - 1))


@wp.func
def _norm_below(table: wp.array2d(dtype=float), cc: float, l: float, r: float) -> float:
    """e(c, λ) for a lobe that straddles the horizon (``cc`` clamped, ``l`` ≥ the tiny λ):
    the sharp-lobe form above the switch, else the table at row ``r``."""
    if l > _LAM_SWITCH:
        return sg_irradiance_sharp(cc, l)
    nr = table.shape[0]
    nc = table.shape[1]
    x = (cc + 1.0) * 0.5 * float(nc - 1)
    r0 = wp.min(int(wp.floor(r)), nr - 2)
    x0 = wp.min(int(wp.floor(x)), nc - 2)
    fr = r - float(r0)
    fx = x - float(x0)
    v0 = table[r0, x0] * (1.0 - fx) + table[r0, x0 + 1] * fx
    v1 = table[r0 + 1, x0] * (1.0 - fx) + table[r0 + 1, x0 + 1] * fx
    return wp.exp(v0 * (1.0 - fr) + v1 * fr)


@wp.func
def sg_irradiance_norm_at(table: wp.array2d(dtype=float), c: float, lam: float, r: float) -> float:
    """:func:`sg_irradiance_norm` with the row ``r = sg_irradiance_row(table, λ)`` given."""
    cc = wp.clamp(c, -1.0, 1.0)
    l = wp.max(lam, _LAM_TINY)
    e = _clear_of_horizon(cc, l)
    if e >= 0.0:
        return e
    return _norm_below(table, cc, l, r)


@wp.func
def sg_irradiance_norm(table: wp.array2d(dtype=float), c: float, lam: float) -> float:
    """e(c, λ) = E / (μ ∫G): exp of the bilinear interpolant in (log10 λ, c) of the ln e table
    (:func:`irradiance_table_array`); λ < 1e-2 uses the first row (flat there), λ > 1e3 the
    sharp-lobe form :func:`sg_irradiance_sharp`; a lobe entirely above the horizon its exact mean
    cosine, one entirely below it 0 (:func:`_clear_of_horizon`: no row, no log)."""
    cc = wp.clamp(c, -1.0, 1.0)
    l = wp.max(lam, _LAM_TINY)
    e = _clear_of_horizon(cc, l)
    if e >= 0.0:
        return e
    r = float(0.0)
    if l <= _LAM_SWITCH:  # no table row (no log) for the sharp-lobe form
        r = sg_irradiance_row(table, l)
    return _norm_below(table, cc, l, r)


@wp.func
def sg_power(lam: float, mu: wp.vec3) -> wp.vec3:
    """μ ∫G(λ), ∫G = 2π (1 − e^{−2λ}) / λ (λ at least the table's smallest): the SG's total power."""
    return mu * sg_integral(wp.max(lam, _LAM_TINY))


@wp.func
def sg_irradiance(table: wp.array2d(dtype=float), n: wp.vec3, p: wp.vec3, lam: float, mu: wp.vec3) -> wp.vec3:
    """E = ∫ μ exp(λ (i·p − 1)) max(n·i, 0) di = μ ∫G(λ) e(n·p, λ), ∫G = 2π (1 − e^{−2λ}) / λ."""
    return sg_power(lam, mu) * sg_irradiance_norm(table, wp.dot(n, p), wp.max(lam, _LAM_TINY))
