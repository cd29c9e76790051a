r"""Spherical Gaussian algebra (numpy), paper §3 and docs/math.md "SG algebra".

An SG is ``G(v; p, λ, μ) = μ · exp(λ (v·p − 1))`` with unit axis ``p``, sharpness ``λ > 0`` and
amplitude ``μ`` (a scalar or RGB: a trailing axis of size 3 on ``μ`` broadcasts like any other).

All functions broadcast over leading axes; axes have a trailing dimension 3. They keep the
floating-point type of their inputs (float32 or float64) and use only stable forms:

* ``v·p − 1`` is evaluated as ``−‖v − p‖² / 2`` (no cancellation near the axis);
* ``1 − e^{−2λ}`` as ``−expm1(−2λ)``;
* the product exponent ``d − λm`` (paper eq. 5) as ``−2 λ1 λ2 (1 − p1·p2) / (d + λm)`` with
  ``1 − p1·p2 = ‖p1 − p2‖²/2`` — it is ≤ 0, so nothing overflows, and it does not cancel for
  sharp lobes;
* ``(1 − e^{−2d}) / d`` uses its limit 2 as ``d → 0`` (antipodal lobes of equal sharpness).

The ``@wp.func`` twins used inside kernels live in :mod:`warp_sg.sg.algebra_wp`. This package is
the SG part of the math layer (public as ``ws.sg``): beside the algebra here it holds the
hemisphere integral ``fh``, the SG × SSDF products (``ssdf_product``), the irradiance of an SG
light (``irradiance``), the multi-lobe clamped-cosine fits (``cosine_lobes``) and the anisotropic error study.
"""
from __future__ import annotations

import numpy as np

#: The paper's negligible-value threshold ε: the effective area ``fa(λ) = −2π ln ε / λ`` of an SG
#: (paper §3, eq. 33) and the extent θv of the anisotropic NDF lobe layouts, where D falls to ε
#: (supplement eq. 14). The one source of ε (``sg_wp``, ``lights``, ``brdf`` read it from here).
EPSILON = 0.1
EPSILON_AREA = EPSILON
#: Single-lobe clamped-cosine SG (paper eq. 40): ``max(cos θ, 0) ≈ 1.170 exp(2.133 (cos θ − 1))``.
CLAMPED_COSINE_SHARPNESS = 2.133
CLAMPED_COSINE_AMPLITUDE = 1.170

_TWO_PI = 2.0 * np.pi


def _float(*xs):
    dt = np.result_type(*[np.asarray(x) for x in xs], np.float32)
    if not np.issubdtype(dt, np.floating):
        dt = np.float64
    return dt


def _amp(mu, like):
    """Amplitude as an array that broadcasts with ``like`` (scalar amplitude: add no axis)."""
    return np.asarray(mu, dtype=like.dtype)


def _dot(a, b):
    return np.sum(a * b, axis=-1)


def one_minus_dot(p1, p2):
    """``1 − p1·p2`` for unit vectors, as ``‖p1 − p2‖² / 2`` (accurate near 0)."""
    d = np.asarray(p1) - np.asarray(p2)
    return 0.5 * _dot(d, d)


def normalize(v):
    v = np.asarray(v)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1)


def evaluate(v, p, lam, mu=1.0):
    """``G(v; p, λ, μ) = μ exp(λ (v·p − 1))``; ``v``, ``p`` unit (..., 3). Returns (...) or (..., C)."""
    dt = _float(v, p, lam)
    v = np.asarray(v, dt)
    p = np.asarray(p, dt)
    lam = np.asarray(lam, dt)
    g = np.exp(-lam * one_minus_dot(v, p))
    mu = _amp(mu, g)
    return g[..., None] * mu if mu.ndim > g.ndim else g * mu


def integral(lam, mu=1.0):
    """``∫_S² G = 2π μ (1 − e^{−2λ}) / λ`` computed as ``2π μ · (−expm1(−2λ)) / λ``."""
    dt = _float(lam)
    lam = np.asarray(lam, dt)
    val = (_TWO_PI * -np.expm1(-2.0 * lam) / lam).astype(dt)
    mu = _amp(mu, val)
    return val[..., None] * mu if mu.ndim > val.ndim else val * mu


def _product_parts(p1, l1, p2, l2):
    dt = _float(p1, l1, p2, l2)
    p1 = np.asarray(p1, dt)
    p2 = np.asarray(p2, dt)
    l1 = np.asarray(l1, dt)
    l2 = np.asarray(l2, dt)
    pm = l1[..., None] * p1 + l2[..., None] * p2
    d = np.linalg.norm(pm, axis=-1)
    lm = l1 + l2
    # d − λm without cancellation (≤ 0).
    expo = -2.0 * l1 * l2 * one_minus_dot(p1, p2) / (d + lm)
    return pm, d, lm, expo


def product(p1, l1, m1, p2, l2, m2):
    """Vector product of two SGs (paper eq. 5): ``G1(v) G2(v) = G(v; pm/d, d, μ1 μ2 e^{d − λm})``.

    Returns ``(axis, sharpness, amplitude)``. When ``d`` is ~0 (opposite lobes of equal sharpness)
    the product is a constant over the sphere: the returned axis is then an arbitrary unit vector
    (+z) and the sharpness a tiny positive number, which evaluates to that constant.
    """
    pm, d, lm, expo = _product_parts(p1, l1, p2, l2)
    tiny = np.finfo(d.dtype).tiny ** 0.5
    ok = d > tiny
    axis = np.where(ok[..., None], pm / np.where(ok, d, 1)[..., None], np.array([0, 0, 1], d.dtype))
    scale = np.exp(expo)
    m1 = _amp(m1, scale)
    m2 = _amp(m2, scale)
    mu = m1 * m2
    amp = scale[..., None] * mu if mu.ndim > scale.ndim else scale * mu
    return axis, np.where(ok, d, tiny), amp


def _one_minus_exp_over(d):
    """``(1 − e^{−2d}) / d`` with the limit 2 at ``d → 0``."""
    small = d < 1e-6
    safe = np.where(small, 1.0, d)
    return np.where(small, 2.0 - 2.0 * d, -np.expm1(-2.0 * safe) / safe)


def inner_product(p1, l1, m1, p2, l2, m2):
    """``∫ G1 G2 = 2π μ1 μ2 e^{d − λm} (1 − e^{−2d}) / d`` (= 4π μ1μ2 e^{−λm} sinh(d)/d)."""
    _, d, _, expo = _product_parts(p1, l1, p2, l2)
    val = (_TWO_PI * np.exp(expo) * _one_minus_exp_over(d)).astype(d.dtype)
    mu = _amp(m1, val) * _amp(m2, val)
    return val[..., None] * mu if mu.ndim > val.ndim else val * mu


def rotate(R, p):
    """Rotate SG axes ``p`` (..., 3) by rotation matrices ``R`` (..., 3, 3): ``R p``."""
    return np.einsum("...ij,...j->...i", np.asarray(R), np.asarray(p))


def fa(lam, eps: float = EPSILON_AREA):
    """Effective area ``fa(λ) = −2π ln ε / λ`` (solid angle where the SG exceeds ε); valid for ``λ > −ln ε``."""
    return -_TWO_PI * np.log(eps) / np.asarray(lam)


def fa_inv(area, eps: float = EPSILON_AREA):
    """Inverse of :func:`fa`: the sharpness of an SG whose effective area is ``area`` (sr)."""
    return -_TWO_PI * np.log(eps) / np.asarray(area)


def clamped_cosine(normal=(0.0, 0.0, 1.0)):
    """The single-lobe clamped cosine SG about ``normal`` (eq. 40): ``(axis, 2.133, 1.170)``."""
    return np.asarray(normal, float), CLAMPED_COSINE_SHARPNESS, CLAMPED_COSINE_AMPLITUDE
