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
local frame of the shading normal, built with :mod:`warp_sg.numeric.onb` — the frame used at
precompute time)::

    mean, basis, w = data.device_arrays(dev)   # (R, R), (R, R, NV) texel-major, (V, NV)
    # per pixel, triangle (i0, i1, i2), barycentrics (b0, b1, b2):
    theta_d = ssdf_eval_bary(mean, basis, w, i0, i1, i2, b0, b1, b2, d)
    # or at one vertex:  ssdf_eval_vertex(mean, basis, w, v, d)

**Frame seam and** :func:`ssdf_eval_world`. Each vertex's SSDF is stored in *that vertex's* frame
(:mod:`warp_sg.numeric.onb`, Duff et al.). That frame field is discontinuous where ``n.z`` changes sign:
across it the tangent turns by up to 180° about the normal (``t⁺·t⁻ = n_y² − n_x²`` on ``n.z = 0``).
On a triangle whose vertices lie on both sides, blending PCA weights and looking them up in the
pixel's frame (:func:`ssdf_eval_bary`) reads some vertices' maps at directions rotated by up to
180° — a visible seam in the shadows. :func:`ssdf_eval_world` takes a *world* direction and
evaluates the SSDF of each vertex whose frame is far from the pixel frame in that vertex's own frame,
``V^d_k(F_k^T p)``, and interpolates with the barycentrics; vertices whose frames agree with the
pixel frame share the one-lookup blended-weight path (see its docstring)::

    normals = wp.array(unit per-vertex normals used by ssdf_for_mesh, dtype=wp.vec3)   # (V,)
    theta_d = ssdf_eval_world(mean, basis, w, normals, i0, i1, i2, b0, b1, b2, p_world, ng)

**Per-pixel reuse.** A shading point evaluates its SSDF at many directions (one per light and
lobe). Everything that depends only on the point — the pixel frame, the three vertex frames, the
blend coefficients — is computed once by :func:`ssdf_point` into an :class:`SSDFPoint`;
:func:`ssdf_at` then costs one or a few bilinear footprints per direction
(``ssdf_eval_world(...) == ssdf_at(..., ssdf_point(...), p)``).

**Device layout.** ``basis`` is stored texel-major on the device, ``(R, R, NV)``
(:meth:`precompute.visibility.ssdf.SSDFData.device_arrays`): the NV basis values of one bilinear tap are
contiguous, so a lookup reads 4 runs of NV floats instead of 4·NV values ``R²`` floats apart
(measured 1.4× on the whole shading kernel on the CPU, docs/benchmarks.md "Frame profile").
"""
from __future__ import annotations

import numpy as np
import warp as wp

from warp_sg.numeric.fastmath import fast_asin, fast_atan_unit
from warp_sg.numeric.onb import frame_bitangent, frame_tangent, world_to_local

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


_TEXEL_DIRS: dict = {}


def texel_direction_array(resolution: int, device) -> wp.array:
    """:func:`texel_directions` as an ``R²`` row-major float32 ``wp.vec3`` array on ``device`` (kept)."""
    key = (int(resolution), str(device))
    if key not in _TEXEL_DIRS:
        _TEXEL_DIRS[key] = wp.array(texel_directions(int(resolution)).reshape(-1, 3).astype(np.float32),
                                    dtype=wp.vec3, device=device)
    return _TEXEL_DIRS[key]


def lookup_np(image, d):
    """Bilinear lookup of (..., R, R) maps at direction(s) ``d`` (the footprint of :func:`_texel_coords`)."""
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


def _maps_at_np(mean, basis, d):
    """Bilinear values of the mean (N,) and of every basis image (N, NV) at local directions d (N, 3)."""
    img = np.concatenate([np.asarray(mean, np.float64)[None], np.asarray(basis, np.float64)])  # (1+NV, R, R)
    v = lookup_np(img, d)  # (1+NV, N)
    return v[0], v[1:].T


def _frame_cos_np(nk, t, b, n):
    """cos of the rotation angle between the frame of unit normals nk and the frame (t, b, n)."""
    from warp_sg.numeric.onb import frame_from_normal

    tk, bk = frame_from_normal(nk)
    return 0.5 * (np.sum(tk * t, -1) + np.sum(bk * b, -1) + np.sum(nk * n, -1) - 1.0)


def _smoothstep_np(e0, e1, x):
    u = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def ssdf_eval_world_np(mean, basis, weights, normals, tris, bary, p_world, ng):
    """numpy twin of :func:`ssdf_eval_world` (float64) for N points: ``tris`` (N, 3) vertex ids,
    ``bary`` (N, 3), ``p_world`` (N, 3) unit world directions, ``ng`` (N, 3) unit shading normals."""
    from warp_sg.numeric.onb import frame_from_normal, to_local

    weights = np.asarray(weights, np.float64)
    normals = np.asarray(normals, np.float64)
    tris = np.asarray(tris)
    bary = np.asarray(bary, np.float64)
    p = np.asarray(p_world, np.float64)
    ng = np.asarray(ng, np.float64)
    t, b = frame_from_normal(ng)
    nk = normals[tris]
    nk = nk / np.linalg.norm(nk, axis=-1, keepdims=True)  # (N, 3, 3)
    lo, hi = float(FRAME_COS_EXACT), float(FRAME_COS_FAST)
    alpha = _smoothstep_np(lo, hi, _frame_cos_np(nk, t[:, None], b[:, None], ng[:, None]))  # (N, 3)
    c = alpha * bary
    d = np.stack([np.sum(p * t, -1), np.sum(p * b, -1), np.sum(p * ng, -1)], -1)
    m, B = _maps_at_np(mean, basis, d)
    csum = c.sum(-1)
    u = csum * m + np.einsum("nk,nkj,nj->n", c, weights[tris], B)
    z = d[:, 2]
    out = np.where(z < 0, np.minimum(u, 0.0) - csum * np.arcsin(np.clip(-z, 0, 1)), u)
    for k in range(3):
        dk = to_local(p, nk[:, k])
        mk, Bk = _maps_at_np(mean, basis, dk)
        vk = mk + np.sum(weights[tris[:, k]] * Bk, -1)
        zk = dk[:, 2]
        vk = np.where(zk < 0, np.minimum(vk, 0.0) - np.arcsin(np.clip(-zk, 0, 1)), vk)
        out = out + (1.0 - alpha[:, k]) * bary[:, k] * vk
    return out


# ---------------------------------------------------------------------------------------------
# Warp
# ---------------------------------------------------------------------------------------------

_WP_PI_4 = wp.constant(_PI_4)
_WP_PI_2 = wp.constant(_PI_2)
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
    """Unit direction → square (a, b) ∈ [−1,1]²; z < 0 is clamped to the horizon.

    The disk point is ``(d_x, d_y)·√(1 − z)/h`` (h = |(d_x, d_y)|), so its radius is ``√(1 − z)``
    and its slope ``d_y/d_x``: where ``|d_x| ≥ |d_y|``, ``a = ±√(1 − z)`` (the sign of d_x) and
    ``b = a (4/π) atan(d_y/d_x)``; else ``b = ±√(1 − z)`` and ``a = b (4/π) atan(d_x/d_y)`` (the
    inverse of both branches of :func:`concentric_to_dir_wp`). One square root, one division and
    one polynomial ``atan`` on [−1, 1] (``warp_sg.numeric.fastmath``, ≈2e-6 rad)."""
    ax = wp.abs(d[0])
    ay = wp.abs(d[1])
    if ax <= 0.0 and ay <= 0.0:
        return wp.vec2(0.0, 0.0)
    r = wp.sqrt(1.0 - wp.clamp(d[2], 0.0, 1.0))
    if ax >= ay:
        a = wp.where(d[0] >= 0.0, r, -r)
        return wp.vec2(a, a * _WP_4_PI * fast_atan_unit(d[1] / d[0]))
    b = wp.where(d[1] >= 0.0, r, -r)
    return wp.vec2(b * _WP_4_PI * fast_atan_unit(d[0] / d[1]), b)


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
def _pca_sum(basis: wp.array3d(dtype=float), weights: wp.array2d(dtype=float), i0: int, i1: int, i2: int,
             c0: float, c1: float, c2: float, x0: int, y0: int, w00: float, w01: float, w10: float, w11: float) -> float:
    """Σ_j (Σ_k c_k w[i_k, j]) basis_j at the bilinear footprint (x0, y0; w..): the PCA part of
    :func:`_ssdf_combo`, a function of its own so that the rule below the horizon applied after it
    sees its value in Warp's reverse pass (which replays a function whole, not a dynamic loop)."""
    v = float(0.0)
    for j in range(basis.shape[2]):
        wj = c0 * weights[i0, j] + c1 * weights[i1, j] + c2 * weights[i2, j]
        v += wj * (basis[y0, x0, j] * w00 + basis[y0, x0 + 1, j] * w01
                   + basis[y0 + 1, x0, j] * w10 + basis[y0 + 1, x0 + 1, j] * w11)
    return v


@wp.func
def _ssdf_combo(mean: wp.array2d(dtype=float), basis: wp.array3d(dtype=float),
                weights: wp.array2d(dtype=float), i0: int, i1: int, i2: int,
                c0: float, c1: float, c2: float, d: wp.vec3) -> float:
    """Σ_k c_k V^d_k(d) for local direction d (one bilinear footprint; below-horizon rule applied to
    the combination as ``min(U, 0) − (Σc_k)·asin(−z)``: a direction below a vertex's horizon is at
    least its angle below it from the visible set). ``basis`` texel-major (R, R, NV); NV = 0: the
    decompressed form, ``weights`` (V, R²) the vertices' maps (``SSDFData.device_arrays``)."""
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
    csum = c0 + c1 + c2
    v = float(0.0)
    if basis.shape[2] == 0:  # decompressed (SSDFData.device_arrays): weights[i] is vertex i's map
        k = y0 * R + x0
        if c0 != 0.0:
            v += c0 * (weights[i0, k] * w00 + weights[i0, k + 1] * w01 + weights[i0, k + R] * w10
                       + weights[i0, k + R + 1] * w11)
        if c1 != 0.0:
            v += c1 * (weights[i1, k] * w00 + weights[i1, k + 1] * w01 + weights[i1, k + R] * w10
                       + weights[i1, k + R + 1] * w11)
        if c2 != 0.0:
            v += c2 * (weights[i2, k] * w00 + weights[i2, k + 1] * w01 + weights[i2, k + R] * w10
                       + weights[i2, k + R + 1] * w11)
    else:
        v = csum * (mean[y0, x0] * w00 + mean[y0, x0 + 1] * w01 + mean[y0 + 1, x0] * w10
                    + mean[y0 + 1, x0 + 1] * w11)
        v += _pca_sum(basis, weights, i0, i1, i2, c0, c1, c2, x0, y0, w00, w01, w10, w11)
    if d[2] < 0.0:
        return wp.min(v, 0.0) - csum * fast_asin(wp.min(-d[2], 1.0))
    return v


@wp.func
def ssdf_eval_bary(mean: wp.array2d(dtype=float), basis: wp.array3d(dtype=float),
                   weights: wp.array2d(dtype=float), i0: int, i1: int, i2: int,
                   b0: float, b1: float, b2: float, d: wp.vec3) -> float:
    """SSDF (eq. 24) at local direction d with PCA weights interpolated from vertices i0..i2
    (barycentrics b0..b2): mean(d) + Σ_j (b0 w[i0,j] + b1 w[i1,j] + b2 w[i2,j]) basis_j(d)."""
    return _ssdf_combo(mean, basis, weights, i0, i1, i2, b0, b1, b2, d)


@wp.func
def ssdf_eval_vertex(mean: wp.array2d(dtype=float), basis: wp.array3d(dtype=float),
                     weights: wp.array2d(dtype=float), vertex: int, d: wp.vec3) -> float:
    """SSDF (eq. 24) of one vertex at local direction d: mean(d) + Σ_j w[vertex, j] basis_j(d)."""
    return ssdf_eval_bary(mean, basis, weights, vertex, vertex, vertex, 1.0, 0.0, 0.0, d)


#: Per-vertex path thresholds of :func:`ssdf_eval_world`, on ``c_k = cos∠(F_k, F)`` (rotation angle
#: between the frame of vertex k and the pixel frame): ``c_k ≥ FRAME_COS_FAST`` (within 20°) → the
#: vertex joins the shared blended-weight lookup in the pixel frame; ``c_k ≤ FRAME_COS_EXACT``
#: (30° or more) → its own lookup in its own frame; smoothstep blend between.
FRAME_COS_FAST = wp.constant(float(np.cos(np.radians(20.0))))   # 0.940
FRAME_COS_EXACT = wp.constant(float(np.cos(np.radians(30.0))))  # 0.866


@wp.func
def _own_frame_term(mean: wp.array2d(dtype=float), basis: wp.array3d(dtype=float),
                    weights: wp.array2d(dtype=float), vertex: int, c: float, nk: wp.vec3, tk: wp.vec3,
                    bk: wp.vec3, p: wp.vec3) -> float:
    """c · V^d_vertex(F_k^T p): one vertex's SSDF at world direction p in its own frame (0 if c = 0)."""
    if c == 0.0:
        return 0.0
    return c * ssdf_eval_vertex(mean, basis, weights, vertex, world_to_local(p, tk, bk, nk))


@wp.struct
class SSDFPoint:
    """What :func:`ssdf_eval_world` needs of a shading point, independent of the direction
    (:func:`ssdf_point`): the triangle's vertices, the pixel frame (t, b, ng), the shared-lookup
    coefficients ``c_k = α_k b_k`` and the own-frame coefficients ``e_k = (1 − α_k) b_k`` with the
    vertex frames (n_k, t_k, s_k)."""

    i0: int
    i1: int
    i2: int
    t: wp.vec3
    b: wp.vec3
    ng: wp.vec3
    c0: float
    c1: float
    c2: float
    e0: float
    e1: float
    e2: float
    n0: wp.vec3
    t0: wp.vec3
    s0: wp.vec3
    n1: wp.vec3
    t1: wp.vec3
    s1: wp.vec3
    n2: wp.vec3
    t2: wp.vec3
    s2: wp.vec3


@wp.func
def _frame_blend(q: SSDFPoint, b0: float, b1: float, b2: float) -> SSDFPoint:
    """The shared-lookup and own-frame coefficients of :func:`ssdf_point` from its frames."""
    ng = q.ng
    # cos of the rotation angle between F_k and F: (trace(F_k^T F) − 1) / 2
    a0 = wp.smoothstep(FRAME_COS_EXACT, FRAME_COS_FAST,
                       0.5 * (wp.dot(q.t0, q.t) + wp.dot(q.s0, q.b) + wp.dot(q.n0, ng) - 1.0))
    a1 = wp.smoothstep(FRAME_COS_EXACT, FRAME_COS_FAST,
                       0.5 * (wp.dot(q.t1, q.t) + wp.dot(q.s1, q.b) + wp.dot(q.n1, ng) - 1.0))
    a2 = wp.smoothstep(FRAME_COS_EXACT, FRAME_COS_FAST,
                       0.5 * (wp.dot(q.t2, q.t) + wp.dot(q.s2, q.b) + wp.dot(q.n2, ng) - 1.0))
    q.c0 = a0 * b0
    q.c1 = a1 * b1
    q.c2 = a2 * b2
    q.e0 = (1.0 - a0) * b0
    q.e1 = (1.0 - a1) * b1
    q.e2 = (1.0 - a2) * b2
    return q


@wp.func
def ssdf_point(normals: wp.array(dtype=wp.vec3), i0: int, i1: int, i2: int, b0: float, b1: float, b2: float,
               ng: wp.vec3) -> SSDFPoint:
    """The direction-independent part of :func:`ssdf_eval_world` for the point with barycentrics
    (b0, b1, b2) in triangle (i0, i1, i2) and unit interpolated normal ``ng`` (computed once per
    pixel, used for every light and lobe by :func:`ssdf_at`)."""
    q = SSDFPoint()
    q.i0 = i0
    q.i1 = i1
    q.i2 = i2
    q.ng = ng
    q.t = frame_tangent(ng)
    q.b = frame_bitangent(ng)
    q.n0 = wp.normalize(normals[i0])
    q.n1 = wp.normalize(normals[i1])
    q.n2 = wp.normalize(normals[i2])
    q.t0 = frame_tangent(q.n0)
    q.s0 = frame_bitangent(q.n0)
    q.t1 = frame_tangent(q.n1)
    q.s1 = frame_bitangent(q.n1)
    q.t2 = frame_tangent(q.n2)
    q.s2 = frame_bitangent(q.n2)
    return _frame_blend(q, b0, b1, b2)


@wp.func
def ssdf_point_framed(normals: wp.array(dtype=wp.vec3), frame_t: wp.array(dtype=wp.vec3),
                      frame_b: wp.array(dtype=wp.vec3), i0: int, i1: int, i2: int, b0: float, b1: float, b2: float,
                      ng: wp.vec3) -> SSDFPoint:
    """:func:`ssdf_point` with the vertex frames stored per vertex (``frame_t``, ``frame_b``: the
    tangent and bitangent of the frame each vertex's SSDF is stored in, which turn with a moving
    object, :mod:`warp_sg.renderer.dynamic_objects`); arrays of another length than ``normals`` (a
    placeholder): the frames of the normals, exactly :func:`ssdf_point`."""
    q = ssdf_point(normals, i0, i1, i2, b0, b1, b2, ng)
    if frame_t.shape[0] != normals.shape[0]:
        return q
    q.t0 = frame_t[i0]
    q.s0 = frame_b[i0]
    q.t1 = frame_t[i1]
    q.s1 = frame_b[i1]
    q.t2 = frame_t[i2]
    q.s2 = frame_b[i2]
    return _frame_blend(q, b0, b1, b2)


@wp.func
def ssdf_at(mean: wp.array2d(dtype=float), basis: wp.array3d(dtype=float), weights: wp.array2d(dtype=float),
            q: SSDFPoint, p_world: wp.vec3) -> float:
    """SSDF θd (eq. 24, radians) of the point ``q`` (:func:`ssdf_point`) at unit world direction
    ``p_world``; see :func:`ssdf_eval_world` for the formula."""
    v = float(0.0)
    if q.c0 != 0.0 or q.c1 != 0.0 or q.c2 != 0.0:
        v = _ssdf_combo(mean, basis, weights, q.i0, q.i1, q.i2, q.c0, q.c1, q.c2,
                        world_to_local(p_world, q.t, q.b, q.ng))
    v += _own_frame_term(mean, basis, weights, q.i0, q.e0, q.n0, q.t0, q.s0, p_world)
    v += _own_frame_term(mean, basis, weights, q.i1, q.e1, q.n1, q.t1, q.s1, p_world)
    v += _own_frame_term(mean, basis, weights, q.i2, q.e2, q.n2, q.t2, q.s2, p_world)
    return v


@wp.func
def ssdf_eval_world(mean: wp.array2d(dtype=float), basis: wp.array3d(dtype=float),
                    weights: wp.array2d(dtype=float), normals: wp.array(dtype=wp.vec3),
                    i0: int, i1: int, i2: int, b0: float, b1: float, b2: float,
                    p_world: wp.vec3, ng: wp.vec3) -> float:
    """SSDF θd (eq. 24, radians) of a point inside triangle (i0, i1, i2) with barycentrics
    (b0, b1, b2) at the unit WORLD direction ``p_world``, consistent across the frame seam.

    ``normals``: the per-vertex normals given to :func:`precompute.ssdf_for_mesh` (normalised here,
    as there); ``ng``: the interpolated unit shading normal, which defines the pixel frame ``F``.

    Computed, with ``F_k`` the frame of vertex k (:mod:`warp_sg.numeric.onb`, the frame its SSDF was
    computed in), ``α_k = smoothstep(FRAME_COS_EXACT, FRAME_COS_FAST, cos∠(F_k, F))`` and
    ``c_k = α_k b_k``::

        θd = H(Σ_k c_k V^d_k(F^T p), p·ng; Σ_k c_k) + Σ_k (1 − α_k) b_k H(V^d_k(F_k^T p), p·n_k; 1)
        H(v, z; c) = v if z ≥ 0 else min(v, 0) − c·asin(−z)       (the below-horizon rule, scaled)

    * vertices whose frame is within 20° of the pixel frame (α_k = 1) share ONE lookup in the pixel
      frame with their PCA weights blended — where all three do, this is :func:`ssdf_eval_bary`
      (the paper's interpolation, one lookup);
    * a vertex whose frame is 30° or more away (α_k = 0; e.g. across ``n.z = 0``, where the Duff
      frame turns by up to 180°) is read in its own frame at the same world direction: one more
      lookup, below-horizon rule at ``p·n_k`` (the below-horizon rule, per vertex);
    * between, a smoothstep blend, so θd is continuous in the barycentrics and across triangle edges
      (a vertex with ``b_k = 0`` contributes nothing, and α_k depends only on F_k and F).

    The SSDF is 1-Lipschitz in the direction, so the pixel-frame read of a vertex differs from its
    own-frame read by at most the angle between the frames (< 30°), plus the PCA error. Cost: three
    frames and dot products per call on top of the lookups (≈ +10 % over :func:`ssdf_eval_bary` on
    a finely tessellated scene, ≈ +40 % on a coarse one where more vertices need their own lookup).
    """
    return ssdf_at(mean, basis, weights, ssdf_point(normals, i0, i1, i2, b0, b1, b2, ng), p_world)
