r"""Importance sampling for the Monte-Carlo reference (:mod:`warp_sg.groundtruth.reference`).

Host side (numpy, float64) builds the tables; the ``@wp.func``\ s sample and evaluate them in
kernels (float32).

Environment (docs/environment.md "Equirectangular maps", Mitsuba 3 ``envmap``): for a unit direction ``d``,
``u = atan2(d.x, −d.z)/(2π)`` wrapped to [0, 1), ``v = acos(d.y)/π``, row 0 at the top. The
reference treats the map as **piecewise constant** (texel ``(r, c)`` covers
``θ ∈ [π r/H, π (r+1)/H]``, ``φ ∈ [2π c/W, 2π (c+1)/W]``), which is the exact radiance function of
the file. Texel ``(r, c)`` is chosen with probability ``∝ (lum + ε) · Ω_rc`` where
``Ω_rc = (2π/W)(cos θ_r − cos θ_{r+1})`` is its solid angle (this is the sin θ factor, integrated
exactly; the convention, the solid angles and the texel lookup are ``warp_sg.scene.envmap``'s:
``row_solid_angles``, ``dir_to_texel``, ``wp_dir_to_uv``); inside the texel the direction is uniform in solid angle
(uniform φ and cos θ), so the
solid-angle pdf is constant per texel: ``pdf = P_rc / Ω_rc``. ``ε`` (a 1e-4 fraction of the mean
luminance) keeps the pdf positive wherever the map may be non-zero.

Spherical emitters and cones: uniform sampling of the cone of directions subtended by a sphere
(half-angle θmax, ``sin θmax = r/d``) or of a directional light's cone (half-angle ``r``):
``pdf = 1 / (2π (1 − cos θmax))`` with ``1 − cos θmax`` computed without cancellation.

Multiple importance sampling: :func:`power_heuristic` (β = 2) and :func:`balance_heuristic`.
"""
from __future__ import annotations

import math

import numpy as np
import warp as wp

from warp_sg.numeric.onb import frame_bitangent, frame_tangent, local_to_world
from warp_sg.scene.envmap import row_solid_angles, wp_dir_to_uv
from warp_sg.sg.algebra_wp import one_minus_dot

PI = wp.constant(3.141592653589793)
TWO_PI = wp.constant(6.283185307179586)
INV_PI = wp.constant(0.3183098861837907)

#: Relative luminance weights (Rec. 709) used for the environment CDF.
from warp_sg.core.image_io import LUMINANCE  # noqa: E402


# --------------------------------------------------------------------------------------------
# Environment: host-side tables
# --------------------------------------------------------------------------------------------
@wp.struct
class EnvSampler:
    """Kernel-side environment: radiance texels, sampling CDFs and the per-texel pdf."""

    present: int
    width: int
    height: int
    radiance: wp.array2d(dtype=wp.vec3)  # (H, W), already multiplied by the light's scale
    marginal_cdf: wp.array(dtype=float)  # (H + 1,) over rows
    conditional_cdf: wp.array2d(dtype=float)  # (H, W + 1) over columns of each row
    texel_pdf: wp.array2d(dtype=float)  # (H, W) solid-angle pdf inside each texel


def env_tables(env: np.ndarray, scale=1.0):
    """Sampling tables of an equirectangular map, float64.

    Returns ``(radiance (H,W,3), marginal_cdf (H+1,), conditional_cdf (H,W+1), texel_pdf (H,W))``;
    ``texel_pdf`` is the solid-angle density of the sampling strategy inside each texel.
    """
    env = np.asarray(env, dtype=np.float64)
    if env.ndim != 3 or env.shape[2] != 3 or env.shape[0] < 1 or env.shape[1] < 1:
        raise ValueError(f"environment map must be (H, W, 3), got {env.shape}")
    rad = env * np.asarray(scale, dtype=np.float64)
    h, w, _ = rad.shape
    lum = np.clip(rad, 0.0, None) @ LUMINANCE
    lum = np.where(np.isfinite(lum), lum, 0.0)
    omega = row_solid_angles(h, w)
    mean = float(np.sum(lum * omega[:, None]) / (4.0 * np.pi))
    eps = 1e-4 * mean if mean > 0 else 1.0
    weight = (lum + eps) * omega[:, None]
    row_w = weight.sum(axis=1)
    total = row_w.sum()
    marginal = np.concatenate([[0.0], np.cumsum(row_w)]) / total
    marginal[-1] = 1.0
    cond = np.concatenate([np.zeros((h, 1)), np.cumsum(weight, axis=1)], axis=1) / row_w[:, None]
    cond[:, -1] = 1.0
    prob = weight / total
    texel_pdf = prob / omega[:, None]
    return rad, marginal, cond, texel_pdf


def make_env_sampler(env: np.ndarray | None, scale=1.0, device="cpu") -> EnvSampler:
    """Upload the environment tables (``env=None``: an absent environment, 1×1 black)."""
    s = EnvSampler()
    if env is None:
        rad = np.zeros((1, 1, 3))
        marg = np.array([0.0, 1.0])
        cond = np.array([[0.0, 1.0]])
        pdf = np.full((1, 1), 1.0 / (4.0 * np.pi))
        s.present = 0
    else:
        rad, marg, cond, pdf = env_tables(env, scale)
        s.present = 1
    s.height, s.width = int(rad.shape[0]), int(rad.shape[1])
    s.radiance = wp.array(rad.astype(np.float32), dtype=wp.vec3, device=device)
    s.marginal_cdf = wp.array(marg.astype(np.float32), dtype=float, device=device)
    s.conditional_cdf = wp.array(cond.astype(np.float32), dtype=float, device=device)
    s.texel_pdf = wp.array(pdf.astype(np.float32), dtype=float, device=device)
    return s


# --------------------------------------------------------------------------------------------
# Environment: kernel side
# --------------------------------------------------------------------------------------------
@wp.func
def cdf_search_1d(cdf: wp.array(dtype=float), n: int, u: float) -> int:
    """Index ``k`` in [0, n) with ``cdf[k] <= u < cdf[k+1]`` (zero-width bins never returned)."""
    lo = int(0)
    hi = n
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if cdf[mid] <= u:
            lo = mid
        else:
            hi = mid
    # skip zero-probability bins (possible only with a degenerate table)
    while lo < n - 1 and cdf[lo + 1] <= cdf[lo]:
        lo = lo + 1
    return lo


@wp.func
def cdf_search_row(cdf: wp.array2d(dtype=float), row: int, n: int, u: float) -> int:
    lo = int(0)
    hi = n
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if cdf[row, mid] <= u:
            lo = mid
        else:
            hi = mid
    while lo < n - 1 and cdf[row, lo + 1] <= cdf[row, lo]:
        lo = lo + 1
    return lo


@wp.func
def env_texel(env: EnvSampler, d: wp.vec3) -> wp.vec2i:
    """(row, col) of the texel containing unit direction ``d`` (kernel twin of ``envmap.dir_to_texel``)."""
    uv = wp_dir_to_uv(d)
    c = wp.min(int(uv[0] * float(env.width)), env.width - 1)
    r = wp.min(int(uv[1] * float(env.height)), env.height - 1)
    return wp.vec2i(wp.max(r, 0), wp.max(c, 0))


@wp.func
def env_radiance(env: EnvSampler, d: wp.vec3) -> wp.vec3:
    """Radiance arriving from direction ``d`` (piecewise constant; zero when absent)."""
    if env.present == 0:
        return wp.vec3(0.0)
    rc = env_texel(env, d)
    return env.radiance[rc[0], rc[1]]


@wp.func
def env_pdf(env: EnvSampler, d: wp.vec3) -> float:
    """Solid-angle pdf of :func:`env_sample` for direction ``d``."""
    if env.present == 0:
        return 0.0
    rc = env_texel(env, d)
    return env.texel_pdf[rc[0], rc[1]]


@wp.func
def env_sample(env: EnvSampler, u1: float, u2: float, u3: float, u4: float) -> wp.vec3:
    """Sample a direction ∝ (luminance + ε) · solid angle; pdf is :func:`env_pdf`."""
    r = cdf_search_1d(env.marginal_cdf, env.height, u1)
    c = cdf_search_row(env.conditional_cdf, r, env.width, u2)
    phi = TWO_PI * (float(c) + u3) / float(env.width)
    c0 = wp.cos(PI * float(r) / float(env.height))
    c1 = wp.cos(PI * float(r + 1) / float(env.height))
    cos_t = c0 + (c1 - c0) * u4
    sin_t = wp.sqrt(wp.max(0.0, 1.0 - cos_t * cos_t))
    return wp.vec3(sin_t * wp.sin(phi), cos_t, -sin_t * wp.cos(phi))


# --------------------------------------------------------------------------------------------
# Cones (spherical emitters, directional lights) and hemisphere sampling
# --------------------------------------------------------------------------------------------
def one_minus_cos_from_sin2(sin2: float) -> float:
    """Host twin of :func:`cone_omc`: ``1 − sqrt(1 − s²)`` = ``s² / (1 + sqrt(1 − s²))``."""
    sin2 = min(max(sin2, 0.0), 1.0)
    return sin2 / (1.0 + math.sqrt(1.0 - sin2))


@wp.func
def cone_omc(sin2: float) -> float:
    """``1 − cos θ`` from ``sin² θ`` (θ ≤ π/2) without cancellation."""
    s2 = wp.clamp(sin2, 0.0, 1.0)
    return s2 / (1.0 + wp.sqrt(1.0 - s2))


@wp.func
def cone_sample(axis: wp.vec3, omc: float, u1: float, u2: float) -> wp.vec3:
    """Uniform direction in the cone around unit ``axis`` with ``1 − cos θmax = omc`` (≤ 2)."""
    x = u1 * omc  # 1 - cos θ
    cos_t = 1.0 - x
    sin_t = wp.sqrt(wp.max(0.0, x * (2.0 - x)))
    phi = TWO_PI * u2
    local = wp.vec3(sin_t * wp.cos(phi), sin_t * wp.sin(phi), cos_t)
    t = frame_tangent(axis)
    b = frame_bitangent(axis)
    return wp.normalize(local_to_world(local, t, b, axis))


@wp.func
def cone_pdf(omc: float) -> float:
    return 1.0 / (TWO_PI * omc)


@wp.func
def in_cone(axis: wp.vec3, omc: float, d: wp.vec3) -> bool:
    return one_minus_dot(axis, d) <= omc


@wp.func
def cosine_sample_local(u1: float, u2: float) -> wp.vec3:
    """Cosine-weighted direction in the local upper hemisphere (z+); pdf = cos θ / π."""
    r = wp.sqrt(u1)
    phi = TWO_PI * u2
    return wp.vec3(r * wp.cos(phi), r * wp.sin(phi), wp.sqrt(wp.max(0.0, 1.0 - u1)))


@wp.func
def sphere_hit_distance(center_rel: wp.vec3, radius: float, d: wp.vec3) -> float:
    """Distance along unit ``d`` from the origin to a sphere at ``center_rel`` (−1 when missed).

    From outside: the entry point; from inside: the exit point.
    """
    b = wp.dot(center_rel, d)
    cr = wp.cross(center_rel, d)
    h2 = wp.dot(cr, cr)  # squared distance of the centre to the line (no cancellation)
    disc = radius * radius - h2
    if disc < 0.0:
        return -1.0
    s = wp.sqrt(disc)
    d2 = wp.dot(center_rel, center_rel)
    if d2 <= radius * radius:
        return b + s
    if b < 0.0:
        return -1.0
    # entry point b - s, computed as (d² − r²)/(b + s) to avoid cancellation for small spheres
    return (d2 - radius * radius) / (b + s)


# --------------------------------------------------------------------------------------------
# MIS
# --------------------------------------------------------------------------------------------
@wp.func
def power_heuristic(pa: float, pb: float) -> float:
    """Weight of strategy a (one sample each), β = 2; ratio form so huge pdfs cannot overflow."""
    if pa <= 0.0:
        return 0.0
    if pa >= pb:
        r = pb / pa
        return 1.0 / (1.0 + r * r)
    r = pa / pb
    return r * r / (1.0 + r * r)


@wp.func
def balance_heuristic(pa: float, pb: float) -> float:
    if pa + pb <= 0.0:
        return 0.0
    return pa / (pa + pb)


def power_heuristic_np(pa, pb):
    pa = np.asarray(pa, np.float64)
    pb = np.asarray(pb, np.float64)
    s = pa * pa + pb * pb
    return np.where(s > 0, pa * pa / np.where(s > 0, s, 1.0), 0.0)


__all__ = [
    "EnvSampler",
    "env_tables",
    "make_env_sampler",
    "env_texel",
    "env_radiance",
    "env_pdf",
    "env_sample",
    "cdf_search_1d",
    "cone_omc",
    "cone_sample",
    "cone_pdf",
    "in_cone",
    "cosine_sample_local",
    "sphere_hit_distance",
    "power_heuristic",
    "balance_heuristic",
    "one_minus_cos_from_sin2",
    "power_heuristic_np",
]
