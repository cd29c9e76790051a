r"""Polynomial ``atan2`` and ``asin`` for the shading kernels' lookups (@wp.func).

A per-pixel shading point evaluates its SSDF at one direction per light and lobe: each lookup
maps the direction to the concentric square (an ``atan2``) and compares it with the horizon (an
``asin``). On the CPU these libm calls were a quarter of a frame's time (``perf``, docs/benchmarks.md
"Frame profile"). The table lookups they feed are bilinear over texels ≥ 0.05 rad wide, so
single-precision polynomial forms with errors of ≈ 2e-6 rad or less are exact for the purpose:

* ``fast_atan2(y, x)``: range reduction to |t| ≤ 1 and the odd minimax polynomial of degree 11
  for ``atan(t)``, ``fast_atan_unit(t)`` (max error ≈ 2e-6 rad over [−1, 1], checked against
  ``numpy.arctan2`` in ``tests/test_fastmath.py``);
* ``fast_asin(x)``: Abramowitz & Stegun 4.4.46, ``asin x = π/2 − √(1−x) Σ_{k=0..7} a_k x^k`` for
  0 ≤ x ≤ 1 (|ε| ≤ 2e-8 in exact arithmetic), odd extension for x < 0.
"""
# NOTE: no ``from __future__ import annotations`` (Warp reads the annotations).
import warp as wp

_HALF_PI = wp.constant(1.5707963267948966)
_PI = wp.constant(3.141592653589793)


@wp.func
def fast_atan_unit(t: float) -> float:
    """atan(t) for |t| ≤ 1 (odd minimax polynomial, degree 11)."""
    t2 = t * t
    p = -0.01172120
    p = p * t2 + 0.05265332
    p = p * t2 - 0.11643287
    p = p * t2 + 0.19354346
    p = p * t2 - 0.33262347
    p = p * t2 + 0.99997726
    return p * t


@wp.func
def fast_atan2(y: float, x: float) -> float:
    """atan2(y, x) in (−π, π] (0 at the origin), max error ≈ 2e-6 rad."""
    ax = wp.abs(x)
    ay = wp.abs(y)
    if ax == 0.0 and ay == 0.0:
        return 0.0
    r = float(0.0)
    if ay <= ax:
        r = fast_atan_unit(ay / ax)
    else:
        r = _HALF_PI - fast_atan_unit(ax / ay)
    if x < 0.0:
        r = _PI - r
    if y < 0.0:
        r = -r
    return r


@wp.func
def fast_asin(x: float) -> float:
    """asin(x) for x ∈ [−1, 1] (clamped), Abramowitz & Stegun 4.4.46."""
    a = wp.min(wp.abs(x), 1.0)
    p = -0.0012624911
    p = p * a + 0.0066700901
    p = p * a - 0.0170881256
    p = p * a + 0.0308918810
    p = p * a - 0.0501743046
    p = p * a + 0.0889789874
    p = p * a - 0.2145988016
    p = p * a + 1.5707963050
    r = _HALF_PI - wp.sqrt(1.0 - a) * p
    if x < 0.0:
        return -r
    return r


__all__ = ["fast_atan2", "fast_atan_unit", "fast_asin"]
