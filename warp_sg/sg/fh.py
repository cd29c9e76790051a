r"""The hemisphere integral ``fh(θd, λ)`` of the SG × SSDF product (paper §5.3 eq. 30–31, appendix eq. 46–48).

Definition (docs/precompute.md "fh"): the visibility around an SG axis ``p`` is replaced by a hemisphere
whose boundary great circle passes ``θd`` away from ``p`` (``p`` visible when ``θd > 0``)::

    fh(θd, λ) = ∫_{i·n ≥ 0} G(i; p, λ, 1) di,      p·n = sin θd,     θd ∈ [−π/2, π/2].

Closed-form values: ``fh(π/2, λ) = (2π/λ)(1 − e^{−λ})`` (eq. 31), ``fh(0, λ) = (π/λ)(1 − e^{−2λ})``
(half the sphere integral, so the ratio at 0 is ``(1 + e^{−λ})/2``, → 1/2 for sharp lobes and
→ 1 for λ → 0), ``fh(−π/2, λ) = (2π/λ) e^{−λ}(1 − e^{−λ})`` (ratio ``e^{−λ}``).

Exact values (:func:`fh_exact`): with ``n`` as the pole, ``i·n = cos α``, the azimuthal integral is
a Bessel function, giving the 1-D integral (float64, vectorized Gauss–Legendre)::

    fh(θd, λ) = 2π ∫_0^{π/2} exp(−2λ sin²((π/2 − θd − α)/2)) · I0e(λ cos θd sin α) · sin α dα,

(``I0e(x) = e^{−x} I0(x)``; the exponent is ``λ(sin(θd + α) − 1)`` written without cancellation).
The integrand is a bump of width ~1/√λ around ``α = π/2 − θd``; the quadrature is restricted to a
±12/√λ window around it, and ``α = a + (b − a)t²`` removes the √α endpoint behaviour.

The renderer needs the ratio (eq. 31, appendix eq. 46) ``f̂h(θd, λ) = fh(θd, λ) / fh(π/2, λ)``:

* **table** (default, :func:`fh_ratio_table`): exact ratios tabulated on ``log λ`` (16 rows per
  decade, λ ∈ [1e-3, 1e5]) × ``c = θd / θmax(λ)`` (129 columns over [−1, 1]), with
  ``θmax(λ) = min(π/2, 6/√λ)`` so the columns always resolve the transition (width ~1/√λ);
  bilinear lookup, ``c`` clamped to ±1. Outside the λ range the end rows are used: for λ > 1e5 the
  ratio depends on ``θd √λ`` only (it tends to ``Φ(θd √λ)``, the normal CDF), which the column
  scaling reproduces; for λ < 1e-3 the ratio is within ~λ of 1. Max abs error ≈ 1e-3 (tests).
* **sigmoid** (paper appendix eq. 47–48, :func:`fh_ratio_sigmoid`):
  ``a / (1 + exp(−kλ θd)) + (1 − a)/2``, ``a = 1.05``, ``kλ = 0.204λ³ − 0.892λ² + 2.995λ + 0.067``,
  clamped to [0, 1]. It was fitted for modest λ: the cubic ``kλ`` grows like λ³ while the true
  transition sharpens like √λ (logistic slope ≈ 1.7√λ), so for large λ it degenerates to a step
  (errors ≈ 0.5 within ~1/√λ of the boundary), and for λ → 0 it tends to 1/2 instead of 1.
  Errors are measured in ``tests/test_fh.py`` and docs/precompute.md; the table is the default.
"""
from __future__ import annotations

import functools

import numpy as np
import warp as wp
from scipy.special import i0e

HALF_PI = 0.5 * np.pi

# ---- table layout (shared by numpy and the @wp.func) ----
FH_LOG10_LAM_MIN = -3.0
FH_LOG10_LAM_MAX = 5.0
FH_ROWS_PER_DECADE = 16
FH_N_LAM = int(round((FH_LOG10_LAM_MAX - FH_LOG10_LAM_MIN) * FH_ROWS_PER_DECADE)) + 1  # 129
FH_N_THETA = 129
#: Columns span ``θd ∈ ±min(π/2, FH_K/√λ)``.
FH_K = 6.0

SIGMOID_A = 1.05


# --------------------------------------------------------------------------------------------
# exact values (numpy, float64)
# --------------------------------------------------------------------------------------------

def fh_hemisphere(lam):
    """``fh(π/2, λ) = (2π/λ)(1 − e^{−λ})`` (paper eq. 31): the SG integral over the hemisphere about its axis."""
    lam = np.asarray(lam, np.float64)
    return 2.0 * np.pi * -np.expm1(-lam) / lam


@functools.lru_cache(maxsize=8)
def _gauss_legendre(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w  # on [0, 1]


def fh_exact(theta_d, lam, n_nodes: int = 256):
    """Exact ``fh(θd, λ)`` by quadrature (float64, broadcasts). ``θd`` is clipped to [−π/2, π/2]."""
    th, lam = np.broadcast_arrays(np.asarray(theta_d, np.float64), np.asarray(lam, np.float64))
    th = np.clip(th, -HALF_PI, HALF_PI)
    if np.any(lam <= 0) or not np.all(np.isfinite(lam)):
        raise ValueError("fh_exact: λ must be positive and finite")
    shape = th.shape
    th = th.reshape(-1, 1)
    lam = lam.reshape(-1, 1)
    a0 = HALF_PI - th  # peak position in α
    w = 12.0 / np.sqrt(lam)
    lo = np.clip(a0 - w, 0.0, HALF_PI)
    hi = np.clip(a0 + w, 0.0, HALF_PI)
    # peak outside [0, π/2] (θd < 0 or > 0 ... tails): keep at least a thin interval at the near end
    same = hi - lo < 1e-12
    lo = np.where(same, np.clip(lo - 1e-9, 0, HALF_PI), lo)
    t, wt = _gauss_legendre(n_nodes)
    alpha = lo + (hi - lo) * t**2
    jac = 2.0 * (hi - lo) * t * wt
    c = np.cos(th)
    expo = -2.0 * lam * np.sin(0.5 * (a0 - alpha)) ** 2
    f = np.exp(expo) * i0e(lam * c * np.sin(alpha)) * np.sin(alpha)
    val = 2.0 * np.pi * np.sum(f * jac, axis=-1)
    return val.reshape(shape)


def fh_ratio_exact(theta_d, lam, n_nodes: int = 256):
    """``f̂h = fh(θd, λ) / fh(π/2, λ)`` (paper appendix eq. 46) by quadrature."""
    return fh_exact(theta_d, lam, n_nodes) / fh_hemisphere(lam)


def fh_theta_max(lam):
    """Half-width ``min(π/2, FH_K/√λ)`` of the table's θd columns at sharpness λ."""
    return np.minimum(HALF_PI, FH_K / np.sqrt(np.asarray(lam, np.float64)))


@functools.lru_cache(maxsize=1)
def fh_table() -> np.ndarray:
    """The exact ratio table ``(FH_N_LAM, FH_N_THETA)`` float32 (rows: log λ, columns: c = θd/θmax(λ)),
    kept on disk (:func:`warp_sg.core.cache.cached_table`, keyed by this module's code): it depends
    on nothing else."""
    from warp_sg.core.cache import cached_table

    return cached_table("fh_ratio", (__name__,), build_fh_table)


def build_fh_table() -> np.ndarray:
    """:func:`fh_table` computed (:func:`fh_ratio_exact` at every node, clipped to [0, 1])."""
    lam = 10.0 ** np.linspace(FH_LOG10_LAM_MIN, FH_LOG10_LAM_MAX, FH_N_LAM)
    c = np.linspace(-1.0, 1.0, FH_N_THETA)
    th = c[None, :] * fh_theta_max(lam)[:, None]
    tab = fh_ratio_exact(th, lam[:, None] * np.ones_like(th))
    return np.clip(tab, 0.0, 1.0).astype(np.float32)


def fh_ratio_table_np(theta_d, lam, table: np.ndarray | None = None):
    """numpy twin of the ``@wp.func`` :func:`fh_ratio_table` (same bilinear lookup)."""
    tab = fh_table() if table is None else np.asarray(table)
    th, lam = np.broadcast_arrays(np.asarray(theta_d, np.float64), np.asarray(lam, np.float64))
    lam = np.maximum(lam, 1e-30)
    r = (np.log10(lam) - FH_LOG10_LAM_MIN) * FH_ROWS_PER_DECADE
    r = np.clip(r, 0.0, tab.shape[0] - 1.0)
    c = np.clip(th / fh_theta_max(lam), -1.0, 1.0)
    x = (c + 1.0) * 0.5 * (tab.shape[1] - 1.0)
    r0 = np.minimum(np.floor(r).astype(int), tab.shape[0] - 2)
    x0 = np.minimum(np.floor(x).astype(int), tab.shape[1] - 2)
    fr = r - r0
    fx = x - x0
    v = (tab[r0, x0] * (1 - fr) * (1 - fx) + tab[r0 + 1, x0] * fr * (1 - fx)
         + tab[r0, x0 + 1] * (1 - fr) * fx + tab[r0 + 1, x0 + 1] * fr * fx)
    return v


def sigmoid_k(lam):
    """``kλ = 0.204λ³ − 0.892λ² + 2.995λ + 0.067`` (paper appendix eq. 48)."""
    lam = np.asarray(lam, np.float64)
    return ((0.204 * lam - 0.892) * lam + 2.995) * lam + 0.067


def fh_ratio_sigmoid_np(theta_d, lam):
    """Paper appendix eq. 47: ``a / (1 + exp(−kλ θd)) + (1 − a)/2``, a = 1.05, clamped to [0, 1]."""
    x = -sigmoid_k(lam) * np.asarray(theta_d, np.float64)
    with np.errstate(over="ignore"):
        s = SIGMOID_A / (1.0 + np.exp(np.minimum(x, 700.0))) + 0.5 * (1.0 - SIGMOID_A)
    return np.clip(s, 0.0, 1.0)


def fh_np(theta_d, lam, method: str = "table"):
    """``fh(θd, λ) ≈ f̂h(θd, λ) · fh(π/2, λ)`` with ``method`` = "table" | "sigmoid" | "exact"."""
    if method == "exact":
        return fh_exact(theta_d, lam)
    ratio = fh_ratio_table_np(theta_d, lam) if method == "table" else fh_ratio_sigmoid_np(theta_d, lam)
    return ratio * fh_hemisphere(lam)


# --------------------------------------------------------------------------------------------
# Warp
# --------------------------------------------------------------------------------------------

_LOG10_LAM_MIN = wp.constant(FH_LOG10_LAM_MIN)
_ROWS_PER_DECADE = wp.constant(float(FH_ROWS_PER_DECADE))
_K = wp.constant(FH_K)
_HALF_PI = wp.constant(HALF_PI)
_A = wp.constant(SIGMOID_A)
_INV_LN10 = wp.constant(0.4342944819032518)
_TWO_PI = wp.constant(2.0 * np.pi)

_device_tables: dict = {}


def fh_table_array(device="cpu") -> wp.array:
    """The ratio table as a ``wp.array2d(dtype=float)`` on ``device`` (built once per device)."""
    from warp_sg.core.device import device_table

    return device_table(_device_tables, fh_table, device)


@wp.func
def fh_hemisphere_wp(lam: float) -> float:
    """fh(π/2, λ) = (2π/λ)(1 − e^{−λ}) (eq. 31)."""
    x = wp.max(lam, 0.0)
    if x < 1.0e-3:  # (1 − e^{−x})/x by its series; finite at λ = 0 (the sphere-half area 2π)
        return _TWO_PI * (1.0 - 0.5 * x * (1.0 - x / 3.0))
    return _TWO_PI * (1.0 - wp.exp(-x)) / x


@wp.func
def fh_theta_max_wp(lam: float) -> float:
    """θmax(λ) = min(π/2, FH_K/√λ) (:func:`fh_theta_max`): the table's f̂h is constant for θd ≥ θmax."""
    return wp.min(_HALF_PI, _K / wp.sqrt(wp.max(lam, 1.0e-30)))


@wp.func
def _fh_row(table: wp.array2d(dtype=float), lam: float):
    """Row of λ in :func:`fh_table_array`: (r0, fr, θmax(λ)), the lower row, its weight and the
    column scale (one log and one square root)."""
    nr = table.shape[0]
    l = wp.max(lam, 1.0e-30)
    r = (wp.log(l) * _INV_LN10 - _LOG10_LAM_MIN) * _ROWS_PER_DECADE
    r = wp.clamp(r, 0.0, float(nr - 1))
    r0 = wp.min(int(wp.floor(r)), nr - 2)
    return r0, r - float(r0), fh_theta_max_wp(l)


@wp.func
def _fh_at(table: wp.array2d(dtype=float), r0: int, fr: float, tmax: float, theta: float) -> float:
    """Bilinear value at θd = ``theta`` between rows r0 and r0 + 1 (weight fr) of the table."""
    nc = table.shape[1]
    c = wp.clamp(theta / tmax, -1.0, 1.0)
    x = (c + 1.0) * 0.5 * float(nc - 1)
    x0 = wp.min(int(wp.floor(x)), nc - 2)
    fx = x - float(x0)
    v0 = table[r0, x0] * (1.0 - fx) + table[r0, x0 + 1] * fx
    v1 = table[r0 + 1, x0] * (1.0 - fx) + table[r0 + 1, x0 + 1] * fx
    return v0 * (1.0 - fr) + v1 * fr


@wp.func
def fh_ratio_table(table: wp.array2d(dtype=float), theta: float, lam: float) -> float:
    """f̂h(θd, λ) = fh(θd, λ)/fh(π/2, λ) by bilinear lookup in :func:`fh_table_array` (the default)."""
    r0, fr, tmax = _fh_row(table, lam)
    return _fh_at(table, r0, fr, tmax, theta)


@wp.func
def fh_ratio_table_pair(table: wp.array2d(dtype=float), theta_a: float, theta_b: float, lam: float):
    """(f̂h(θa, λ), f̂h(θb, λ)): two lookups of :func:`fh_ratio_table` at one λ, sharing its row
    (one log and one square root instead of two)."""
    r0, fr, tmax = _fh_row(table, lam)
    return _fh_at(table, r0, fr, tmax, theta_a), _fh_at(table, r0, fr, tmax, theta_b)


@wp.func
def fh_ratio_sigmoid(theta: float, lam: float) -> float:
    """Paper appendix eq. 47–48: a/(1 + exp(−kλ θd)) + (1 − a)/2, a = 1.05, clamped to [0, 1]."""
    k = ((0.204 * lam - 0.892) * lam + 2.995) * lam + 0.067
    x = wp.min(-k * theta, 80.0)
    s = _A / (1.0 + wp.exp(x)) + 0.5 * (1.0 - _A)
    return wp.clamp(s, 0.0, 1.0)


@wp.func
def fh_table_wp(table: wp.array2d(dtype=float), theta: float, lam: float) -> float:
    """fh(θd, λ) ≈ f̂h(θd, λ) · fh(π/2, λ) with the tabulated ratio."""
    return fh_ratio_table(table, theta, lam) * fh_hemisphere_wp(lam)
