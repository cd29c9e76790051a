r"""Hemisphere parameterisation and kernel-side SSDF lookup (paper §5.2, eq. 24).

**Concentric map** (Shirley & Chiu 1997, "A low distortion map between disk and square"): the
square ``(a, b) ∈ [−1, 1]²`` maps to the unit disk by ``r = a, φ = (π/4)(b/a)`` when ``|a| > |b|``,
else ``r = b, φ = π/2 − (π/4)(a/b)``; the disk maps to the upper hemisphere (z = normal) by the
equal-area lift ``z = 1 − r², (x, y) = disk · √(2 − r²)``. Inverse: ``disk = (x, y)/√(1 + z)``.
Texel ``(row j, column i)`` of an ``R×R`` map has its centre at ``a = (i + ½)·2/R − 1``,
``b = (j + ½)·2/R − 1``; maps are stored ``[j, i]`` (row = b, column = a).
Directions below the horizon are clamped to the horizon point of the same azimuth.

**Reconstructed SSDF** (eq. 24): ``V^d(d) ≈ mean(d) + Σ_j w_j basis_j(d)`` with bilinear lookup on
the concentric map. For a direction below the horizon (``z < 0``) the value continues as
``min(V^d(horizon point), 0) − asin(−z)`` (directions below the horizon are invisible, and the
angular distance to the visible region grows by the depth below the horizon).

Renderer usage (``SSDFData`` from :func:`precompute.ssdf_for_mesh`, ``d`` a unit direction in the
local frame of the shading normal, built with :mod:`warp_sg.frames` — the frame used at
precompute time)::

    mean  = wp.array(data.mean,  dtype=float, device=dev)     # (R, R)
    basis = wp.array(data.basis, dtype=float, device=dev)     # (NV, R, R)
    w     = wp.array(data.weights, dtype=float, device=dev)   # (V, NV)
    # per pixel, triangle (i0, i1, i2), barycentrics (b0, b1, b2):
    theta_d = ssdf_eval_bary(mean, basis, w, i0, i1, i2, b0, b1, b2, d)
    # or at one vertex:  ssdf_eval_vertex(mean, basis, w, v, d)
"""
from __future__ import annotations

import numpy as np
import warp as wp

_PI_4 = np.pi / 4.0
_PI_2 = np.pi / 2.0


# ---------------------------------------------------------------------------------------------
# numpy
# ---------------------------------------------------------------------------------------------

def square_to_disk(a, b):
    """Shirley–Chiu concentric map, numpy: square (a, b) ∈ [−1,1]² → disk (x, y)."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    first = np.abs(a) > np.abs(b)
    sa = np.where(a == 0, 1.0, a)
    sb = np.where(b == 0, 1.0, b)
    r = np.where(first, a, b)
    phi = np.where(first, _PI_4 * (b / sa), _PI_2 - _PI_4 * (a / sb))
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return r * np.cos(phi), r * np.sin(phi)


def disk_to_square(x, y):
    """Inverse of :func:`square_to_disk`."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    r = np.hypot(x, y)
    phi = np.arctan2(y, x)
    phi = np.where(phi < -_PI_4, phi + 2 * np.pi, phi)
    k = 4.0 / np.pi
    a = np.select([phi < _PI_4, phi < 3 * _PI_4, phi < 5 * _PI_4],
                  [r, -(phi - _PI_2) * k * r, -r], (phi - 3 * _PI_2) * k * r)
    b = np.select([phi < _PI_4, phi < 3 * _PI_4, phi < 5 * _PI_4],
                  [phi * k * r, r, -(phi - np.pi) * k * r], -r)
    return a, b


def concentric_to_dir(a, b):
    """numpy: square (a, b) ∈ [−1,1]² → unit direction (..., 3) on the upper hemisphere (equal-area)."""
    x, y = square_to_disk(a, b)
    r2 = x * x + y * y
    s = np.sqrt(np.maximum(2.0 - r2, 0.0))
    return np.stack([x * s, y * s, 1.0 - r2], axis=-1)


def dir_to_concentric(d):
    """numpy: unit direction (..., 3) → square (a, b); ``z < 0`` is clamped to the horizon."""
    d = np.asarray(d, np.float64)
    z = np.clip(d[..., 2], 0.0, 1.0)
    h = np.hypot(d[..., 0], d[..., 1])
    r = np.sqrt(1.0 - z)
    scale = np.where(h > 0, r / np.where(h > 0, h, 1.0), 0.0)
    return disk_to_square(d[..., 0] * scale, d[..., 1] * scale)


def texel_directions(resolution: int) -> np.ndarray:
    """Unit directions (R, R, 3) at the texel centres of an R×R concentric map (``[row=b, col=a]``)."""
    c = (np.arange(resolution) + 0.5) * (2.0 / resolution) - 1.0
    b, a = np.meshgrid(c, c, indexing="ij")
    return concentric_to_dir(a, b)


def lookup_np(image, d):
    """numpy twin of :func:`ssdf_bilinear`: bilinear lookup of (..., R, R) maps at direction(s) ``d``."""
    image = np.asarray(image)
    R = image.shape[-1]
    a, b = dir_to_concentric(d)
    x = np.clip((a + 1.0) * 0.5 * R - 0.5, 0.0, R - 1.0)
    y = np.clip((b + 1.0) * 0.5 * R - 0.5, 0.0, R - 1.0)
    x0 = np.minimum(np.floor(x).astype(int), R - 2)
    y0 = np.minimum(np.floor(y).astype(int), R - 2)
    fx = x - x0
    fy = y - y0
    return (image[..., y0, x0] * (1 - fx) * (1 - fy) + image[..., y0, x0 + 1] * fx * (1 - fy)
            + image[..., y0 + 1, x0] * (1 - fx) * fy + image[..., y0 + 1, x0 + 1] * fx * fy)


def ssdf_eval_np(mean, basis, weights, d):
    """numpy twin of :func:`ssdf_eval_vertex` for one weight row (NV,) and directions ``d`` (..., 3)."""
    d = np.asarray(d, np.float64)
    img = mean + np.tensordot(np.asarray(weights), basis, axes=(0, 0))
    z = d[..., 2]
    v = lookup_np(img, d)
    below = z < 0
    return np.where(below, np.minimum(v, 0.0) - np.arcsin(np.clip(-z, 0, 1)), v)


# ---------------------------------------------------------------------------------------------
# Warp
# ---------------------------------------------------------------------------------------------

_WP_PI_4 = wp.constant(_PI_4)
_WP_PI_2 = wp.constant(_PI_2)
_WP_PI = wp.constant(np.pi)
_WP_4_PI = wp.constant(4.0 / np.pi)


@wp.func
def concentric_to_dir_wp(a: float, b: float) -> wp.vec3:
    """Square (a, b) ∈ [−1,1]² → unit direction on the upper hemisphere (Shirley–Chiu + equal-area lift)."""
    r = float(0.0)
    phi = float(0.0)
    if a == 0.0 and b == 0.0:
        return wp.vec3(0.0, 0.0, 1.0)
    if wp.abs(a) > wp.abs(b):
        r = a
        phi = _WP_PI_4 * (b / a)
    else:
        r = b
        phi = _WP_PI_2 - _WP_PI_4 * (a / b)
    x = r * wp.cos(phi)
    y = r * wp.sin(phi)
    r2 = x * x + y * y
    s = wp.sqrt(wp.max(2.0 - r2, 0.0))
    return wp.vec3(x * s, y * s, 1.0 - r2)


@wp.func
def dir_to_concentric_wp(d: wp.vec3) -> wp.vec2:
    """Unit direction → square (a, b) ∈ [−1,1]²; z < 0 is clamped to the horizon."""
    z = wp.clamp(d[2], 0.0, 1.0)
    h = wp.sqrt(d[0] * d[0] + d[1] * d[1])
    if h <= 0.0:
        return wp.vec2(0.0, 0.0)
    r = wp.sqrt(1.0 - z)
    x = d[0] * r / h
    y = d[1] * r / h
    phi = wp.atan2(y, x)
    if phi < -_WP_PI_4:
        phi = phi + 2.0 * _WP_PI
    a = float(0.0)
    b = float(0.0)
    if phi < _WP_PI_4:
        a = r
        b = phi * _WP_4_PI * r
    elif phi < 3.0 * _WP_PI_4:
        a = -(phi - _WP_PI_2) * _WP_4_PI * r
        b = r
    elif phi < 5.0 * _WP_PI_4:
        a = -r
        b = -(phi - _WP_PI) * _WP_4_PI * r
    else:
        a = (phi - 3.0 * _WP_PI_2) * _WP_4_PI * r
        b = -r
    return wp.vec2(a, b)


@wp.func
def _texel_coords(d: wp.vec3, R: int) -> wp.vec4:
    """(x0, y0, fx, fy) of the bilinear footprint of direction d on an R×R map (as floats)."""
    ab = dir_to_concentric_wp(d)
    x = wp.clamp((ab[0] + 1.0) * 0.5 * float(R) - 0.5, 0.0, float(R - 1))
    y = wp.clamp((ab[1] + 1.0) * 0.5 * float(R) - 0.5, 0.0, float(R - 1))
    x0 = wp.min(int(wp.floor(x)), R - 2)
    y0 = wp.min(int(wp.floor(y)), R - 2)
    return wp.vec4(float(x0), float(y0), x - float(x0), y - float(y0))


@wp.func
def ssdf_bilinear(image: wp.array2d(dtype=float), d: wp.vec3) -> float:
    """Bilinear lookup of one R×R concentric map at local direction d (clamped to the horizon)."""
    t = _texel_coords(d, image.shape[0])
    x0 = int(t[0])
    y0 = int(t[1])
    fx = t[2]
    fy = t[3]
    return ((image[y0, x0] * (1.0 - fx) + image[y0, x0 + 1] * fx) * (1.0 - fy)
            + (image[y0 + 1, x0] * (1.0 - fx) + image[y0 + 1, x0 + 1] * fx) * fy)


@wp.func
def _below_horizon(v: float, d: wp.vec3) -> float:
    if d[2] < 0.0:
        return wp.min(v, 0.0) - wp.asin(wp.min(-d[2], 1.0))
    return v


@wp.func
def ssdf_eval_bary(mean: wp.array2d(dtype=float), basis: wp.array3d(dtype=float),
                   weights: wp.array2d(dtype=float), i0: int, i1: int, i2: int,
                   b0: float, b1: float, b2: float, d: wp.vec3) -> float:
    """SSDF (eq. 24) at local direction d with PCA weights interpolated from vertices i0..i2
    (barycentrics b0..b2): mean(d) + Σ_j (b0 w[i0,j] + b1 w[i1,j] + b2 w[i2,j]) basis_j(d)."""
    R = mean.shape[0]
    t = _texel_coords(d, R)
    x0 = int(t[0])
    y0 = int(t[1])
    fx = t[2]
    fy = t[3]
    w00 = (1.0 - fx) * (1.0 - fy)
    w01 = fx * (1.0 - fy)
    w10 = (1.0 - fx) * fy
    w11 = fx * fy
    v = (mean[y0, x0] * w00 + mean[y0, x0 + 1] * w01 + mean[y0 + 1, x0] * w10 + mean[y0 + 1, x0 + 1] * w11)
    for j in range(basis.shape[0]):
        wj = b0 * weights[i0, j] + b1 * weights[i1, j] + b2 * weights[i2, j]
        v += wj * (basis[j, y0, x0] * w00 + basis[j, y0, x0 + 1] * w01
                   + basis[j, y0 + 1, x0] * w10 + basis[j, y0 + 1, x0 + 1] * w11)
    return _below_horizon(v, d)


@wp.func
def ssdf_eval_vertex(mean: wp.array2d(dtype=float), basis: wp.array3d(dtype=float),
                     weights: wp.array2d(dtype=float), vertex: int, d: wp.vec3) -> float:
    """SSDF (eq. 24) of one vertex at local direction d: mean(d) + Σ_j w[vertex, j] basis_j(d)."""
    return ssdf_eval_bary(mean, basis, weights, vertex, vertex, vertex, 1.0, 0.0, 0.0, d)
