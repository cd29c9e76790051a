r"""The numpy twins of the ΓL lookup (:func:`gamma_lookup_numpy`, :func:`gamma_normalized_numpy`,
:func:`erf_filtered_numpy`) and the direct quadrature reference :func:`gamma_reference` of
``ΓL(p, λ) = ∫ G(i; p, λ, 1) L(i) di`` (paper eq. 34–35) that the tests check the pyramid against
(:mod:`precompute.environment.prefilter` builds the pyramid; the kernels' lookups are
:mod:`precompute.environment.prefilter_wp`'s).
"""
from __future__ import annotations

import math

import numpy as np

from precompute.environment.cubemap import cube_face_of_numpy
from precompute.environment.prefilter import EnvPrefiltered, _sample_grid


def _fetch_level_numpy(pre: EnvPrefiltered, level, face, a, b):
    level = np.asarray(level, np.int64)
    n = pre.face_sizes[level]
    stride = n + 2
    base = pre.level_offsets[level] + face * stride * stride
    x = (a + 1.0) * 0.5 * n + 0.5
    y = (b + 1.0) * 0.5 * n + 0.5
    x0 = np.clip(np.floor(x).astype(np.int64), 0, n)
    y0 = np.clip(np.floor(y).astype(np.int64), 0, n)
    fx = np.clip(x - x0, 0, 1)[..., None]
    fy = np.clip(y - y0, 0, 1)[..., None]
    t = pre.texels.astype(np.float64)
    i00 = base + y0 * stride + x0
    t0 = t[i00] * (1 - fx) + t[i00 + 1] * fx
    t1 = t[i00 + stride] * (1 - fx) + t[i00 + stride + 1] * fx
    return t0 * (1 - fy) + t1 * fy


def _ncdf(x):
    from scipy.special import erf

    return 0.5 * (1.0 + erf(x / math.sqrt(2.0)))


def erf_filtered_numpy(radiance, d_env, sigma):
    """numpy twin of :func:`erf_filtered`: returns ``(rgb (..., 3), ok (...) bool)``."""
    env = np.asarray(radiance, np.float64)
    hh, ww = env.shape[:2]
    d = np.asarray(d_env, np.float64)
    sigma = np.broadcast_to(np.asarray(sigma, np.float64), d.shape[:-1])
    h_t, h_p = math.pi / hh, 2 * math.pi / ww
    theta = np.arccos(np.clip(d[..., 1], -1, 1))
    sin_t = np.sqrt(np.maximum(0, 1 - np.clip(d[..., 1], -1, 1) ** 2))
    phi = np.arctan2(d[..., 0], -d[..., 2]) % (2 * math.pi)
    ok = (theta - 3 * sigma > 0) & (theta + 3 * sigma < math.pi)
    sig_p = sigma / np.maximum(sin_t, 1e-30)
    r0 = np.floor((theta - 3 * sigma) / h_t).astype(np.int64)
    r1 = np.floor((theta + 3 * sigma) / h_t).astype(np.int64)
    with np.errstate(invalid="ignore", over="ignore"):
        c0 = np.floor(np.where(ok, (phi - 3 * sig_p) / h_p, 0)).astype(np.int64)
        c1 = np.floor(np.where(ok, (phi + 3 * sig_p) / h_p, 0)).astype(np.int64)
    ok &= (c1 - c0 < 6) & (r1 - r0 < 6)
    acc = np.zeros(d.shape[:-1] + (3,))
    wsum = np.zeros(d.shape[:-1])
    sig_ps = np.where(ok, sig_p, 1.0)
    for dr in range(6):
        r = r0 + dr
        vr = ok & (r <= r1) & (r >= 0) & (r < hh)
        wr = _ncdf(((r + 1) * h_t - theta) / sigma) - _ncdf((r * h_t - theta) / sigma)
        for dc in range(6):
            c = c0 + dc
            v = vr & (c <= c1)
            wc = _ncdf(((c + 1) * h_p - phi) / sig_ps) - _ncdf((c * h_p - phi) / sig_ps)
            wgt = np.where(v, wr * wc, 0.0)
            acc += wgt[..., None] * env[np.clip(r, 0, hh - 1), c % ww]
            wsum += wgt
    ok &= wsum > 0
    return acc / np.where(wsum > 0, wsum, 1.0)[..., None], ok


def gamma_normalized_numpy(pre: EnvPrefiltered, d_env, lam):
    """numpy twin of :func:`gamma_normalized` (directions in the map's frame, unit)."""
    from warp_sg.scene.envmap import env_lookup_numpy

    d = np.asarray(d_env, np.float64)
    lam = np.broadcast_to(np.asarray(lam, np.float64), d.shape[:-1])
    face, a, b = cube_face_of_numpy(d)
    L = len(pre.lambdas)
    lam_safe = np.maximum(lam, 1e-30)
    ll = np.log(lam_safe)
    s = (ll - math.log(pre.lam0)) / pre.log_step
    k = np.clip(np.floor(s).astype(np.int64), 0, L - 1)
    k1 = np.minimum(k + 1, L - 1)
    fr = np.clip(s - k, 0, 1)[..., None]
    mid = _fetch_level_numpy(pre, k, face, a, b) * (1 - fr) + _fetch_level_numpy(pre, k1, face, a, b) * fr
    g1 = _fetch_level_numpy(pre, np.zeros_like(k), face, a, b)
    g2 = _fetch_level_numpy(pre, np.ones_like(k), face, a, b)
    x = np.maximum(lam, 0)[..., None]
    x1, x2 = pre.lam0, float(pre.lambdas[1])
    low = (pre.mean * ((x - x1) * (x - x2) / (x1 * x2)) + g1 * (x * (x - x2) / (x1 * (x1 - x2)))
           + g2 * (x * (x - x1) / (x2 * (x2 - x1))))
    gt = _fetch_level_numpy(pre, np.full_like(k, L - 1), face, a, b)
    # beyond the ladder
    lam_erf = pre.lam_erf
    ve, ok = erf_filtered_numpy(pre.radiance, d, 1.0 / np.sqrt(np.maximum(lam_safe, lam_erf)))
    w_e = np.clip((ll - math.log(pre.lam_top)) / max(math.log(lam_erf / pre.lam_top), 1e-6), 0, 1)[..., None]
    w_e = np.where((lam >= lam_erf)[..., None], 1.0, w_e)
    erf_part = gt * (1 - w_e) + ve * w_e
    w = np.clip((ll - math.log(pre.lam_top)) / math.log(pre.lam_inf / pre.lam_top), 0, 1)[..., None]
    texel = env_lookup_numpy(pre.radiance, d, bilinear=False)
    pole_part = gt * (1 - w) + texel * w
    high = np.where(ok[..., None], erf_part, pole_part)
    out = np.where((lam <= pre.lam0)[..., None], low, np.where((s >= L - 1)[..., None], high, mid))
    return out


def gamma_lookup_numpy(pre: EnvPrefiltered, p, lam, rotation=None, scale: float = 1.0):
    """numpy twin of :func:`gamma_lookup`: ``scale · ΓL(p, λ)`` for world directions ``p`` (..., 3)."""
    from warp_sg.sg import integral

    d = np.asarray(p, np.float64)
    if rotation is not None:
        d = d @ np.asarray(rotation, np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    lam = np.asarray(lam, np.float64)
    g = gamma_normalized_numpy(pre, d, lam)
    return g * (scale * integral(np.maximum(np.broadcast_to(lam, d.shape[:-1]), 1e-6)))[..., None]


def gamma_reference(env, p, lam, *, cells_per_sigma: float = 6.0, max_sub: int = 64, cutoff: float = 25.0):
    """Direct quadrature of eq. 35 for one direction ``p`` (map frame) and sharpness ``λ`` (float64).

    The map is the piecewise-constant function of its texels; each texel is split into ``s × s``
    cells uniform in θ and φ (``s`` so that a cell is ≤ σ/``cells_per_sigma``, σ = 1/√λ) and
    ``∫_cell G`` is taken as ``Ω_cell · G(centre)``; cells with ``λ(1 − p·d) > cutoff`` are skipped.
    Returns ``ΓL(p, λ)`` (RGB, not normalised).
    """
    env = np.asarray(env, np.float64)
    h, w = env.shape[:2]
    p = np.asarray(p, np.float64)
    p = p / np.linalg.norm(p)
    sigma = 1.0 / math.sqrt(lam)
    sub = int(min(max_sub, max(1, math.ceil((math.pi / h) / (sigma / cells_per_sigma)))))
    theta_p = math.acos(max(-1.0, min(1.0, p[1])))
    phi_p = math.atan2(p[0], -p[2]) % (2 * math.pi)
    cmin = 1.0 - cutoff / lam
    if cmin <= -1.0:
        r0, r1 = 0, h - 1
        cols = np.arange(w * sub)
    else:
        tc = math.acos(cmin)
        r0 = max(0, int(math.floor((theta_p - tc) / (math.pi / h))) - 1)
        r1 = min(h - 1, int(math.floor((theta_p + tc) / (math.pi / h))) + 1)
        if theta_p - tc <= 0 or theta_p + tc >= math.pi:
            cols = np.arange(w * sub)
        else:
            dphi = math.asin(min(1.0, math.sin(tc) / math.sin(theta_p)))
            hp = 2 * math.pi / (w * sub)
            j0 = int(math.floor((phi_p - dphi) / hp)) - 2
            j1 = int(math.floor((phi_p + dphi) / hp)) + 2
            cols = np.arange(j0, min(j1, j0 + w * sub - 1) + 1) % (w * sub)
    cos_t, sin_t, w_row, cos_p, sin_p = _sample_grid(h, w, sub)
    rows = np.arange(r0 * sub, (r1 + 1) * sub)
    ct = cos_t[rows][:, None]
    st = sin_t[rows][:, None]
    dirs = np.stack(np.broadcast_arrays(st * sin_p[cols][None, :], ct, -st * cos_p[cols][None, :]), axis=-1)
    diff = dirs - p
    g = np.exp(-lam * 0.5 * np.einsum("...k,...k->...", diff, diff)) * w_row[rows][:, None]
    vals = env[(rows // sub)[:, None], (cols // sub)[None, :]]
    return np.einsum("rc,rck->k", g, vals)


__all__ = ["gamma_lookup_numpy", "gamma_normalized_numpy", "gamma_reference", "erf_filtered_numpy"]
