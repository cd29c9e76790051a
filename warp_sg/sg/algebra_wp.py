r"""``@wp.func`` twins of :mod:`warp_sg.sg` for use inside Warp kernels (float32).

Unit-amplitude forms: amplitudes (scalar or RGB) are multiplied by the caller, which keeps one
function for any number of channels. The same stable forms as the numpy module are used
(see its docstring): exponents are kept ≤ 0 and ``expm1`` is used for ``1 − e^{−x}``.

* ``sg_eval(v, p, lam)``            = exp(λ (v·p − 1))
* ``sg_integral(lam)``              = 2π (1 − e^{−2λ}) / λ
* ``sg_product(p1, l1, p2, l2)``    -> (axis, sharpness, scale) with G1·G2 = scale · G(axis, sharpness)
* ``sg_product_lobe(p1, l1, p2, l2)`` -> (axis, sharpness) of the product alone (no ``exp``)
* ``sg_inner(p1, l1, p2, l2)``      = ∫ G1 G2 (unit amplitudes)
* ``sg_fa_inv(area)``               = sharpness whose effective area is ``area``
"""
from __future__ import annotations

import math

import warp as wp

from warp_sg.sg import EPSILON

TWO_PI = wp.constant(6.283185307179586)
#: −2π ln ε: numerator of fa(λ) = −2π ln ε / λ (ε: :data:`warp_sg.sg.EPSILON`).
FA_NUMERATOR = wp.constant(-2.0 * math.pi * math.log(EPSILON))


@wp.func
def one_minus_dot(a: wp.vec3, b: wp.vec3) -> float:
    """1 − a·b for unit vectors as ‖a − b‖²/2."""
    d = a - b
    return 0.5 * wp.dot(d, d)


@wp.func
def expm1_neg(x: float) -> float:
    """1 − e^{−x} for x ≥ 0, accurate for small x (series below 1e-3). From x = 18 on it is 1.0:
    e^{−18} ≈ 1.5e-8 is under half a float32 ulp below 1 (3.0e-8), so ``1 − exp(−x)`` rounds to 1
    there anyway, and the ``exp`` call is saved (sg_integral of every lobe with λ ≥ 9)."""
    if x < 1.0e-3:
        return x * (1.0 - 0.5 * x * (1.0 - x / 3.0))
    if x >= 18.0:
        return 1.0
    return 1.0 - wp.exp(-x)


@wp.func
def sg_eval(v: wp.vec3, p: wp.vec3, lam: float) -> float:
    return wp.exp(-lam * one_minus_dot(v, p))


@wp.func
def sg_integral(lam: float) -> float:
    return TWO_PI * expm1_neg(2.0 * lam) / lam


@wp.func
def _one_minus_exp_over(d: float) -> float:
    # (1 − e^{−2d}) / d, limit 2 at d → 0
    if d < 1.0e-6:
        return 2.0 - 2.0 * d
    return expm1_neg(2.0 * d) / d


@wp.func
def sg_product(p1: wp.vec3, l1: float, p2: wp.vec3, l2: float):
    """Vector product (paper eq. 5). Returns (axis, sharpness, scale = e^{d − λm} ≤ 1)."""
    pm = l1 * p1 + l2 * p2
    d = wp.length(pm)
    lm = l1 + l2
    expo = -2.0 * l1 * l2 * one_minus_dot(p1, p2) / (d + lm)
    axis = wp.vec3(0.0, 0.0, 1.0)
    sharp = float(1.0e-19)
    if d > 1.0e-19:
        axis = pm / d
        sharp = d
    return axis, sharp, wp.exp(expo)


@wp.func
def sg_product_lobe(p1: wp.vec3, l1: float, p2: wp.vec3, l2: float):
    """(axis, sharpness) of the product G1·G2 (eq. 5) without its scale: where only the lobe's
    place and size are used, the scale's ``exp`` (a libm call the compiler cannot drop) is not
    paid. Same values as the first two of :func:`sg_product`."""
    pm = l1 * p1 + l2 * p2
    d = wp.length(pm)
    if d > 1.0e-19:
        return pm / d, d
    return wp.vec3(0.0, 0.0, 1.0), float(1.0e-19)


@wp.func
def sg_inner(p1: wp.vec3, l1: float, p2: wp.vec3, l2: float) -> float:
    """∫ G1 G2 for unit amplitudes: 2π e^{d − λm} (1 − e^{−2d}) / d."""
    pm = l1 * p1 + l2 * p2
    d = wp.length(pm)
    lm = l1 + l2
    expo = -2.0 * l1 * l2 * one_minus_dot(p1, p2) / (d + lm)
    return TWO_PI * wp.exp(expo) * _one_minus_exp_over(d)


@wp.func
def sg_fa_inv(area: float) -> float:
    return FA_NUMERATOR / area
