r"""Prefiltered environment ΓL(p, λ) for specular SG lighting (paper §6, eq. 34–35).

    ΓL(p, λ) = ∫_S² G(i; p, λ, 1) L(i) di,     ⟨G(·; p, λ, μ), L⟩ = μ ΓL(p, λ)        (eq. 34–35)

``L`` is the equirectangular map read as the piecewise-constant radiance function (the
Monte-Carlo reference's reading, :mod:`warp_sg.envmap`).

Table
-----
We tabulate the *normalised* (filtered-radiance) form ``Γn(p, λ) = ΓL(p, λ) / ∫G(λ)`` with
``∫G(λ) = 2π (1 − e^{−2λ}) / λ``; ``Γn`` is a weighted mean of ``L``, so a constant map gives
exactly that constant, and interpolating it between λ levels is well behaved. Levels ``k`` sit on a
geometric ladder ``λ_k = λ_0 r^k`` (default ``λ_0 = 0.5``, ``r = √2``) up to ``λ_top``
(:func:`default_ladder`: about where the SG's angular width σ = 1/√λ is half a source texel,
or where the cube faces reach ``base_face``); level ``k`` is a cubemap with face size
``N_k = clamp(⌈c √λ_k⌉, 16, base_face)`` (``c = face_factor = 4``: the face-centre texel, 2/N rad,
is ≤ σ/2) plus a one-texel border on every face, computed at its own (slightly outside the face)
direction, so that bilinear lookups never cross a face edge.

Each texel is computed by a Warp kernel as a discrete ratio ``Σ_j w_j L_j / Σ_j w_j`` with
``w_j ≈ ∫_{cell j} G(i; p, λ, 1) di`` over cells ``j`` of the source map, restricted to the cap
``λ (1 − p·d) ≤ 14`` (the neglected SG mass is ``e^{−14} ≈ 8·10⁻⁷``; in longitude the exact
per-row extent of the cap). The source is the coarsest solid-angle-weighted mip level whose
texel is ≤ σ/2.5 (``samples_per_sigma``; a finer one while the window holds ≤ 2048 texels), with
``w_j = Ω_j G(d_j)`` and ``d_j`` the texel's luminance-weighted energy centroid. When even the
full map is coarser than that (sharp levels), ``w_j`` integrates G over the whole texel using
the exact separation ``1 − cos γ = (1 − cos Δθ) + sin θ sin θp (1 − cos Δφ)`` and a Gaussian for
each factor (normal-CDF differences over the texel's edges, ``κ = λ sin θ_m sin θp``); rows near
a pole (κ < 50) fall back to ``s × s`` sub-cells (uniform in θ and φ, exact cell solid angles).

Lookup (``@wp.func gamma_lookup(tab: GammaTable, p: wp.vec3, lam: float) -> wp.vec3``)
-------------------------------------------------------------------------------------
``p`` is a unit **world** direction; the table's ``to_env`` matrix (``Rᵀ`` of the environment's
rotation, set per frame by :meth:`EnvPrefiltered.table`) maps it to the map's frame. Returns
``scale · ΓL(p, λ)`` (RGB), i.e. multiply by the lobe amplitude μ to get ``⟨G, L⟩``:

* bilinear in ``p`` on the cube face of ``p``'s major axis, linear in ``ln λ`` between levels;
* ``λ < λ_0``: the quadratic in λ through ``(0, mean)``, ``(λ_0, level 0)``, ``(λ_1, level 1)``
  (``Γn`` is analytic in λ at 0, where it is the mean radiance ``(1/4π) ∫ L``);
* ``λ ≥ λ_erf = max(λ_top, (2H/π)²)`` (σ ≤ half a source texel): the source texels filtered by
  the planar Gaussian of std σ around ``p`` (:func:`erf_filtered`: separable normal-CDF weights
  over ±3σ, ≤ 4×6 texels — the exact limit of eq. 35 for a narrow lobe on the piecewise-constant
  map); between ``λ_top`` and ``λ_erf`` a blend, linear in ``ln λ``, of the top level and that;
  within 3σ of a pole (where the planar model fails) the blend goes from the top level to the
  map's own texel at ``λ_∞``.

Usage inside a kernel::

    from precompute.prefilter import GammaTable, gamma_lookup

    @wp.kernel
    def shade(env: GammaTable, ...):
        ...
        rgb = mu * gamma_lookup(env, p_world, lam)   # <G(.; p, lam, mu), L>

    pre = prefilter_environment(env_map, device="cuda:0")       # cached on disk
    wp.launch(shade, ..., inputs=[pre.table(rotation=R, scale=s), ...])

``gamma_lookup_numpy(pre, p, lam, rotation=None, scale=1.0)`` is the numpy twin (tests, host
code); :func:`gamma_reference` is direct quadrature of eq. 35 (the test reference).
"""
from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from warp_sg.device import resolve_device
from warp_sg.sg_wp import one_minus_dot, sg_integral
from warp_sg.envmap import downsample_envmap, row_solid_angles, validate_envmap, wp_dir_to_uv
from warp_sg.workers import cpu_workers

#: Cap of the quadrature window: texels with λ (1 − p·d) > CUTOFF are skipped (mass e^{−14}).
CUTOFF = 14.0
#: Format tag of the cached entry (bump when the table layout or algorithm changes).
_VERSION = "prefilter-v4"

PI = wp.constant(3.141592653589793)
TWO_PI = wp.constant(6.283185307179586)


# --------------------------------------------------------------------------------------------
# Cube faces: d = major + a·U + b·V, a, b ∈ [−1, 1] on the face (OpenGL-like orientation).
# --------------------------------------------------------------------------------------------
_FACE_MAJOR = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
_FACE_U = np.array([[0, 0, -1], [0, 0, 1], [1, 0, 0], [1, 0, 0], [1, 0, 0], [-1, 0, 0]], np.float64)
_FACE_V = np.array([[0, -1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [0, -1, 0], [0, -1, 0]], np.float64)


@wp.func
def cube_dir(face: int, a: float, b: float) -> wp.vec3:
    """Unnormalised direction of face coordinates ``(a, b)`` on ``face`` (+X, −X, +Y, −Y, +Z, −Z)."""
    if face == 0:
        return wp.vec3(1.0, -b, -a)
    if face == 1:
        return wp.vec3(-1.0, -b, a)
    if face == 2:
        return wp.vec3(a, 1.0, b)
    if face == 3:
        return wp.vec3(a, -1.0, -b)
    if face == 4:
        return wp.vec3(a, -b, 1.0)
    return wp.vec3(-a, -b, -1.0)


@wp.func
def cube_face_of(d: wp.vec3) -> wp.vec3:
    """(face, a, b) of direction ``d`` (face as a float), the face of the major axis."""
    ax = wp.abs(d[0])
    ay = wp.abs(d[1])
    az = wp.abs(d[2])
    if ax >= ay and ax >= az:
        if d[0] > 0.0:
            return wp.vec3(0.0, -d[2] / ax, -d[1] / ax)
        return wp.vec3(1.0, d[2] / ax, -d[1] / ax)
    if ay >= az:
        if d[1] > 0.0:
            return wp.vec3(2.0, d[0] / ay, d[2] / ay)
        return wp.vec3(3.0, d[0] / ay, -d[2] / ay)
    if d[2] > 0.0:
        return wp.vec3(4.0, d[0] / az, -d[1] / az)
    return wp.vec3(5.0, -d[0] / az, -d[1] / az)


def cube_dir_numpy(face, a, b):
    """numpy twin of :func:`cube_dir` (unnormalised)."""
    face = np.asarray(face)
    a = np.asarray(a, np.float64)[..., None]
    b = np.asarray(b, np.float64)[..., None]
    return _FACE_MAJOR[face] + a * _FACE_U[face] + b * _FACE_V[face]


def cube_face_of_numpy(d):
    """numpy twin of :func:`cube_face_of`: ``(face int, a, b)``."""
    d = np.asarray(d, np.float64)
    ad = np.abs(d)
    axis = np.where((ad[..., 0] >= ad[..., 1]) & (ad[..., 0] >= ad[..., 2]), 0, np.where(ad[..., 1] >= ad[..., 2], 1, 2))
    comp = np.take_along_axis(d, axis[..., None], -1)[..., 0]
    face = 2 * axis + (comp <= 0)
    m = np.abs(comp)
    a = np.einsum("...k,...k->...", d, _FACE_U[face]) / m
    b = np.einsum("...k,...k->...", d, _FACE_V[face]) / m
    return face, a, b


# --------------------------------------------------------------------------------------------
# Build kernel
# --------------------------------------------------------------------------------------------
_vec6 = wp.types.vector(length=6, dtype=float)


@wp.func
def _phi_cdf(x: float) -> float:
    return 0.5 * (1.0 + wp.erf(x * 0.7071067811865476))


@wp.kernel
def _prefilter_level_kernel(
    src: wp.array2d(dtype=wp.vec3),
    src_dir: wp.array2d(dtype=wp.vec3),
    cos_t: wp.array(dtype=float),
    sin_t: wp.array(dtype=float),
    w_row: wp.array(dtype=float),
    cos_p: wp.array(dtype=float),
    sin_p: wp.array(dtype=float),
    sub: int,
    lam: float,
    cutoff: float,
    n: int,
    start: int,
    out: wp.array(dtype=wp.vec3),
):
    tid = wp.tid() + start
    stride = n + 2
    face = tid // (stride * stride)
    rem = tid - face * stride * stride
    y = rem // stride
    x = rem - y * stride
    a = 2.0 * (float(x - 1) + 0.5) / float(n) - 1.0
    b = 2.0 * (float(y - 1) + 0.5) / float(n) - 1.0
    d = wp.normalize(cube_dir(face, a, b))

    h_src = src.shape[0]
    rows = cos_t.shape[0]
    cols = cos_p.shape[0]
    h_phi = TWO_PI / float(cols)
    cos_tp = wp.clamp(d[1], -1.0, 1.0)
    theta_p = wp.acos(cos_tp)
    sin_tp = wp.sqrt(wp.max(0.0, 1.0 - cos_tp * cos_tp))
    phi_p = wp.atan2(d[0], -d[2])
    if phi_p < 0.0:
        phi_p = phi_p + TWO_PI

    cmin = 1.0 - cutoff / lam
    r_lo = int(0)
    r_hi = h_src - 1
    if cmin > -1.0:
        theta_c = wp.acos(cmin)
        h_t = PI / float(h_src)
        r_lo = wp.max(0, int(wp.floor((theta_p - theta_c) / h_t)) - 1)
        r_hi = wp.min(h_src - 1, int(wp.floor((theta_p + theta_c) / h_t)) + 1)

    acc = wp.vec3(0.0)
    wsum = float(0.0)
    h_t = PI / float(h_src)
    w_src = src.shape[1]
    h_pt = TWO_PI / float(w_src)
    sq_lam = wp.sqrt(lam)
    for r in range(r_lo, r_hi + 1):
        # Sub-sampled source (sub > 1): integrate G over whole texels instead, where the lobe is narrow
        # in both directions. Exact separation 1 − cos γ = (1 − cos Δθ) + sin θ sin θp (1 − cos Δφ),
        # each factor ≈ Gaussian: ∫_texel G dΩ ≈ sin θ_m ∫ e^{−λΔθ²/2} dθ · ∫ e^{−κΔφ²/2} dφ,
        # κ = λ sin θ_m sin θp (normal-CDF differences). Rows near a pole (κ < 50) keep sub-cells.
        t0 = float(r) * h_t
        t1 = t0 + h_t
        # sin θ and κ at the Gaussian-weighted mean θ of the row (truncated-normal mean): the far
        # tail of a bright source is sensitive to κ, so take it where the row's weight sits
        za = (t0 - theta_p) * sq_lam
        zb = (t1 - theta_p) * sq_lam
        mass = _phi_cdf(zb) - _phi_cdf(za)
        t_m = wp.clamp(theta_p, t0, t1)
        if mass > 1.0e-12:
            t_m = wp.clamp(theta_p + 0.3989422804014327 * (wp.exp(-0.5 * za * za) - wp.exp(-0.5 * zb * zb))
                           / (mass * sq_lam), t0, t1)
        st_c = wp.sin(t_m)
        kappa = lam * st_c * sin_tp
        if sub > 1 and kappa >= 50.0 and cmin > -1.0:
            a_r = st_c * mass / sq_lam
            # longitude extent of the cap at the row's θ closest to θp
            tn = wp.clamp(theta_p, t0, t1)
            ctn = wp.cos(tn)
            stn = wp.sin(tn)
            xx = (cmin - ctn * cos_tp) / wp.max(stn * sin_tp, 1.0e-12)
            if xx <= 1.0:
                j0 = int(0)
                cnt = w_src
                if xx > -1.0:
                    dphi = wp.acos(xx)
                    j0 = int(wp.floor((phi_p - dphi) / h_pt)) - 1
                    j1 = int(wp.floor((phi_p + dphi) / h_pt)) + 1
                    cnt = wp.min(j1 - j0 + 1, w_src)
                sk = wp.sqrt(kappa)
                prev = _phi_cdf((float(j0) * h_pt - phi_p) * sk)
                for q in range(cnt):
                    nxt = _phi_cdf((float(j0 + q + 1) * h_pt - phi_p) * sk)
                    g = a_r * (nxt - prev) / sk
                    prev = nxt
                    j = (((j0 + q) % w_src) + w_src) % w_src
                    wsum += g
                    acc += g * src[r, j]
        else:
            for k in range(r * sub, (r + 1) * sub):
                ct = cos_t[k]
                st = sin_t[k]
                # sub-cells carry their solid angle; the texel integrals above carry ∫G dΩ / (2π)
                wr = w_row[k] / TWO_PI
                ss = st * sin_tp
                j0 = int(0)
                cnt = cols
                if cmin > -1.0 and ss > 1.0e-6:
                    xx = (cmin - ct * cos_tp) / ss
                    if xx > 1.0:
                        cnt = 0
                    elif xx > -1.0:
                        dphi = wp.acos(xx)
                        j0 = int(wp.floor((phi_p - dphi) / h_phi - 0.5)) - 1
                        j1 = int(wp.floor((phi_p + dphi) / h_phi - 0.5)) + 2
                        cnt = wp.min(j1 - j0 + 1, cols)
                elif cmin > -1.0:
                    if ct * cos_tp < cmin:
                        cnt = 0
                for jj in range(j0, j0 + cnt):
                    j = ((jj % cols) + cols) % cols
                    dd = wp.vec3(st * sin_p[j], ct, -st * cos_p[j])
                    if sub == 1:
                        dd = src_dir[r, j]  # energy centroid of a mip texel
                    g = wr * wp.exp(-lam * one_minus_dot(dd, d))
                    wsum += g
                    acc += g * src[r, j // sub]
    if wsum > 0.0:
        out[tid] = acc / wsum
    else:
        out[tid] = wp.vec3(0.0)


# --------------------------------------------------------------------------------------------
# Kernel-side table and lookup
# --------------------------------------------------------------------------------------------
@wp.struct
class GammaTable:
    """Kernel-side ΓL table (see module docstring). Build with :meth:`EnvPrefiltered.table`."""

    texels: wp.array(dtype=wp.vec3)  # all levels, faces with a one-texel border, Γn values
    level_offset: wp.array(dtype=wp.int32)  # first texel of each level
    level_size: wp.array(dtype=wp.int32)  # face size N of each level (without border)
    num_levels: int
    lam0: float  # λ of level 0
    log_lam0: float  # ln λ_0
    inv_log_step: float  # 1 / ln r
    log_lam_top: float  # ln λ_top
    inv_log_tail: float  # 1 / ln(λ_∞ / λ_top)
    lam_erf: float  # from here on: Gaussian-filtered source texels (σ ≤ half a texel)
    inv_log_erf: float  # 1 / ln(λ_erf / λ_top)  (any value when λ_erf = λ_top)
    mean: wp.vec3  # (1/4π) ∫ L : Γn at λ → 0
    radiance: wp.array2d(dtype=wp.vec3)  # the source map (λ → ∞)
    to_env: wp.mat33  # world → environment frame (Rᵀ)
    scale: float  # radiance scale (dynamic)


@wp.func
def _fetch_level(tab: GammaTable, level: int, face: int, a: float, b: float) -> wp.vec3:
    n = tab.level_size[level]
    stride = n + 2
    base = tab.level_offset[level] + face * stride * stride
    # texel centre x_t = (a+1)/2·n − 0.5 (+1 border)  ->  x ∈ [0.5, n + 0.5]
    x = (a + 1.0) * 0.5 * float(n) + 0.5
    y = (b + 1.0) * 0.5 * float(n) + 0.5
    x0 = wp.clamp(int(wp.floor(x)), 0, n)
    y0 = wp.clamp(int(wp.floor(y)), 0, n)
    fx = wp.clamp(x - float(x0), 0.0, 1.0)
    fy = wp.clamp(y - float(y0), 0.0, 1.0)
    i00 = base + y0 * stride + x0
    t0 = tab.texels[i00] * (1.0 - fx) + tab.texels[i00 + 1] * fx
    t1 = tab.texels[i00 + stride] * (1.0 - fx) + tab.texels[i00 + stride + 1] * fx
    return t0 * (1.0 - fy) + t1 * fy


@wp.func
def erf_filtered(radiance: wp.array2d(dtype=wp.vec3), d_env: wp.vec3, sigma: float) -> wp.vec4:
    """Piecewise-constant map filtered by a narrow Gaussian of angular std ``sigma`` around ``d_env``.

    Local planar model: in (θ, φ) the Gaussian is separable with ``σ_θ = σ``, ``σ_φ = σ / sin θ``,
    so each texel's weight is a product of two differences of the normal CDF (exact integral of
    the piecewise-constant map against the planar Gaussian over ±3σ). Returns ``(rgb, ok)``;
    ``ok = 0`` near the poles (the window would touch a pole or span more than 6 columns).
    """
    hh = radiance.shape[0]
    ww = radiance.shape[1]
    h_t = PI / float(hh)
    h_p = TWO_PI / float(ww)
    cos_tp = wp.clamp(d_env[1], -1.0, 1.0)
    theta_p = wp.acos(cos_tp)
    sin_tp = wp.sqrt(wp.max(0.0, 1.0 - cos_tp * cos_tp))
    if theta_p - 3.0 * sigma <= 0.0 or theta_p + 3.0 * sigma >= PI:
        return wp.vec4(0.0)
    sig_p = sigma / sin_tp
    phi_p = wp.atan2(d_env[0], -d_env[2])
    if phi_p < 0.0:
        phi_p = phi_p + TWO_PI
    r0 = int(wp.floor((theta_p - 3.0 * sigma) / h_t))
    r1 = int(wp.floor((theta_p + 3.0 * sigma) / h_t))
    c0 = int(wp.floor((phi_p - 3.0 * sig_p) / h_p))
    c1 = int(wp.floor((phi_p + 3.0 * sig_p) / h_p))
    if c1 - c0 >= 6 or r1 - r0 >= 6:
        return wp.vec4(0.0)
    r0 = wp.max(r0, 0)
    r1 = wp.min(r1, hh - 1)
    # column weights once (normal-CDF differences; consecutive edges share one erf)
    wcol = _vec6()
    prev = _phi_cdf((float(c0) * h_p - phi_p) / sig_p)
    for q in range(6):
        if c0 + q <= c1:
            nxt = _phi_cdf((float(c0 + q + 1) * h_p - phi_p) / sig_p)
            wcol[q] = nxt - prev
            prev = nxt
    acc = wp.vec3(0.0)
    wsum = float(0.0)
    rprev = _phi_cdf((float(r0) * h_t - theta_p) / sigma)
    for r in range(r0, r1 + 1):
        rnext = _phi_cdf((float(r + 1) * h_t - theta_p) / sigma)
        wr = rnext - rprev
        rprev = rnext
        for q in range(c1 - c0 + 1):
            cc = (((c0 + q) % ww) + ww) % ww
            wgt = wr * wcol[q]
            acc += wgt * radiance[r, cc]
            wsum += wgt
    if wsum <= 0.0:
        return wp.vec4(0.0)
    v = acc / wsum
    return wp.vec4(v[0], v[1], v[2], 1.0)


@wp.func
def gamma_normalized(tab: GammaTable, d_env: wp.vec3, lam: float) -> wp.vec3:
    """Γn(d, λ) = ΓL/∫G for a unit direction already in the environment frame (no scale)."""
    fab = cube_face_of(d_env)
    face = int(fab[0])
    a = fab[1]
    b = fab[2]
    if lam <= tab.lam0:
        # quadratic through (0, mean), (λ0, level 0), (λ1, level 1): Γn is analytic in λ at 0
        x = wp.max(lam, 0.0)
        x1 = tab.lam0
        x2 = tab.lam0 * wp.exp(1.0 / tab.inv_log_step)
        g1 = _fetch_level(tab, 0, face, a, b)
        g2 = _fetch_level(tab, 1, face, a, b)
        c0 = (x - x1) * (x - x2) / (x1 * x2)
        c1 = x * (x - x2) / (x1 * (x1 - x2))
        c2 = x * (x - x1) / (x2 * (x2 - x1))
        return tab.mean * c0 + g1 * c1 + g2 * c2
    ll = wp.log(lam)
    s = (ll - tab.log_lam0) * tab.inv_log_step
    k = int(wp.floor(s))
    top = tab.num_levels - 1
    if k >= top:
        # beyond the ladder: Gaussian-filtered source texels (at least as sharp as λ_erf),
        # blended from the top level in ln λ between λ_top and λ_erf
        lam_e = wp.max(lam, tab.lam_erf)
        fe = erf_filtered(tab.radiance, d_env, 1.0 / wp.sqrt(lam_e))
        gt = _fetch_level(tab, top, face, a, b)
        if fe[3] > 0.0:
            ve = wp.vec3(fe[0], fe[1], fe[2])
            if lam >= tab.lam_erf:
                return ve
            w = wp.clamp((ll - tab.log_lam_top) * tab.inv_log_erf, 0.0, 1.0)
            return gt * (1.0 - w) + ve * w
        # near a pole: blend towards the nearest texel up to λ_∞
        w = wp.clamp((ll - tab.log_lam_top) * tab.inv_log_tail, 0.0, 1.0)
        if w <= 0.0:
            return gt
        hh = tab.radiance.shape[0]
        ww = tab.radiance.shape[1]
        uv = wp_dir_to_uv(d_env)
        c = wp.clamp(int(uv[0] * float(ww)), 0, ww - 1)
        r = wp.clamp(int(uv[1] * float(hh)), 0, hh - 1)
        return gt * (1.0 - w) + tab.radiance[r, c] * w
    fr = s - float(k)
    return _fetch_level(tab, k, face, a, b) * (1.0 - fr) + _fetch_level(tab, k + 1, face, a, b) * fr


@wp.func
def gamma_lookup(tab: GammaTable, p: wp.vec3, lam: float) -> wp.vec3:
    """``scale · ΓL(p, λ) = scale · ∫ G(i; p, λ, 1) L(i) di`` (eq. 35) for a unit world direction ``p``."""
    d = wp.normalize(tab.to_env * p)
    return gamma_normalized(tab, d, lam) * (tab.scale * sg_integral(wp.max(lam, 1.0e-6)))


# --------------------------------------------------------------------------------------------
# Host side
# --------------------------------------------------------------------------------------------
@dataclass
class EnvPrefiltered:
    """The ΓL pyramid of one environment map (host copies + device arrays).

    ``lambdas`` (L,), ``face_sizes`` (L,), ``level_offsets`` (L,), ``texels`` (T, 3) float32 Γn,
    ``mean`` (3,), ``radiance`` (H, W, 3) the source map, ``lam_inf`` (where the lookup reaches the
    map's own texels). :meth:`table` returns the kernel-side :class:`GammaTable`.
    """

    lambdas: np.ndarray
    face_sizes: np.ndarray
    level_offsets: np.ndarray
    texels: np.ndarray
    mean: np.ndarray
    radiance: np.ndarray
    lam_inf: float
    device: str
    build_seconds: float = 0.0
    _wp: dict = field(default_factory=dict, repr=False)

    @property
    def lam0(self) -> float:
        return float(self.lambdas[0])

    @property
    def lam_top(self) -> float:
        return float(self.lambdas[-1])

    @property
    def lam_erf(self) -> float:
        """λ from which lookups filter the source texels directly: max(λ_top, (2H/π)²)."""
        return float(max(self.lam_top, (2.0 * self.radiance.shape[0] / math.pi) ** 2))

    @property
    def log_step(self) -> float:
        return float(math.log(self.lambdas[1] / self.lambdas[0])) if len(self.lambdas) > 1 else 1.0

    @property
    def nbytes(self) -> int:
        return int(self.texels.nbytes)

    def _arrays(self, device):
        device = resolve_device(device)
        if device not in self._wp:
            self._wp[device] = dict(
                texels=wp.array(self.texels, dtype=wp.vec3, device=device),
                level_offset=wp.array(self.level_offsets.astype(np.int32), dtype=wp.int32, device=device),
                level_size=wp.array(self.face_sizes.astype(np.int32), dtype=wp.int32, device=device),
                radiance=wp.array(np.ascontiguousarray(self.radiance, np.float32), dtype=wp.vec3, device=device),
            )
        return self._wp[device]

    def table(self, rotation=None, scale: float = 1.0, device=None) -> GammaTable:
        """Kernel-side table; ``rotation`` = R (environment → world), ``scale`` multiplies L.

        Cheap (no recomputation): rotation and scale are dynamic.
        """
        arr = self._arrays(device if device is not None else self.device)
        t = GammaTable()
        t.texels = arr["texels"]
        t.level_offset = arr["level_offset"]
        t.level_size = arr["level_size"]
        t.radiance = arr["radiance"]
        t.num_levels = int(len(self.lambdas))
        t.lam0 = float(self.lam0)
        t.log_lam0 = float(math.log(self.lam0))
        t.inv_log_step = float(1.0 / self.log_step)
        t.log_lam_top = float(math.log(self.lam_top))
        t.inv_log_tail = float(1.0 / math.log(self.lam_inf / self.lam_top))
        t.lam_erf = float(self.lam_erf)
        t.inv_log_erf = float(1.0 / max(math.log(self.lam_erf / self.lam_top), 1e-6))
        t.mean = wp.vec3(*[float(x) for x in self.mean])
        R = np.eye(3) if rotation is None else np.asarray(rotation, np.float64)
        t.to_env = wp.mat33(*R.T.astype(np.float32).ravel())
        t.scale = float(scale)
        return t


#: Smallest cube face: broad lobes are cheap to build and a bright source far off-axis still has a
#: sizeable gradient in p, so they get at least this many texels per face.
MIN_FACE = 16


def _face_sizes(lambdas, face_factor, base_face):
    return np.clip(np.ceil(face_factor * np.sqrt(np.asarray(lambdas))), min(MIN_FACE, base_face), base_face).astype(
        np.int64)


def default_ladder(height: int, *, lam0: float = 0.5, step: float = math.sqrt(2.0), base_face: int = 256,
                   face_factor: float = 4.0):
    """The λ ladder and face sizes for a map of ``height`` rows.

    ``λ_k = λ_0 r^k`` up to ``λ_top ≤ min(λ_src, (base_face/face_factor)²)`` with
    ``λ_src = (2H/π)²`` (the SG's σ = 1/√λ is half a source texel π/H) — beyond, lookups filter
    the source texels directly — or where the face size would exceed ``base_face``.
    ``N_k = clamp(⌈face_factor √λ_k⌉, 16, base_face)``; ``λ_∞ = max(8 λ_top, 4 λ_src)`` (pole fallback).
    """
    lam_src = (2.0 * height / math.pi) ** 2
    lam_cap = max(lam0 * step, min(lam_src, (base_face / face_factor) ** 2))
    n_levels = int(math.floor(math.log(lam_cap / lam0) / math.log(step) + 1e-9)) + 1
    n_levels = max(n_levels, 2)
    lambdas = lam0 * step ** np.arange(n_levels)
    sizes = _face_sizes(lambdas, face_factor, base_face)
    lam_inf = max(8.0 * lambdas[-1], 4.0 * lam_src)
    return lambdas, sizes, float(lam_inf)


def _mip_chain(env64: np.ndarray, min_rows: int = 8):
    """Solid-angle-weighted 2×2 mips with each texel's luminance-weighted energy centroid.

    Returns ``[(radiance (H_m, W_m, 3), centroid (H_m, W_m, 3) unit), ...]``. At level 0 the
    centroid is the cell centre (midpoint in cos θ and φ); a coarser texel stands for its
    children's energy at their centroid, which keeps the quadrature first-order exact for
    compact bright sources (a sun) that a coarse texel would otherwise move to its centre.
    """
    from warp_sg.envmap import uv_to_dir

    h, w = env64.shape[:2]
    cos_mid = 0.5 * (np.cos(np.pi * np.arange(h) / h) + np.cos(np.pi * np.arange(1, h + 1) / h))
    v_mid = np.arccos(cos_mid) / np.pi
    cent = uv_to_dir(((np.arange(w) + 0.5) / w)[None, :], v_mid[:, None])
    lum_w = np.array([0.2126, 0.7152, 0.0722])
    chain = [(env64, cent)]
    while True:
        rad, cen = chain[-1]
        h, w = rad.shape[:2]
        if h % 2 or w % 2 or h // 2 < min_rows:
            break
        om = row_solid_angles(h, w)
        e = (np.maximum(rad @ lum_w, 0.0) * om[:, None])[..., None]
        geo = np.broadcast_to(om[:, None, None], e.shape)
        wsum = (cen * (e + 1e-12 * geo)).reshape(h // 2, 2, w // 2, 2, 3).sum(axis=(1, 3))
        wsum /= np.linalg.norm(wsum, axis=-1, keepdims=True)
        chain.append((downsample_envmap(rad, 2), wsum))
    return chain


#: Source samples per output texel the builder may spend to use a finer mip than σ/samples_per_sigma.
SAMPLE_BUDGET = 2048


def _source_for(chain, lam: float, samples_per_sigma: float, max_sub: int, budget: int = SAMPLE_BUDGET,
                cutoff: float = CUTOFF):
    """Pick the source mip (and sub-sampling) for sharpness ``lam``.

    Among the mips whose texel is ≤ σ/samples_per_sigma, the finest whose cap window
    (fraction ``min(1, CUTOFF/(2λ))`` of the sphere) holds ≤ ``budget`` texels, else the coarsest
    of them; if even the full map is too coarse, the full map with ``s × s`` sub-cells.
    """
    sigma = 1.0 / math.sqrt(lam)
    frac = min(1.0, cutoff / (2.0 * lam))
    allowed = [m for m in range(len(chain)) if math.pi / chain[m][0].shape[0] <= sigma / samples_per_sigma]
    if allowed:
        for m in sorted(allowed):
            h, w = chain[m][0].shape[:2]
            if h * w * frac <= budget:
                return m, 1
        return max(allowed), 1
    h = chain[0][0].shape[0]
    sub = int(math.ceil((math.pi / h) / (sigma / samples_per_sigma)))
    return 0, max(1, min(sub, max_sub))


def _sample_grid(h: int, w: int, sub: int):
    """Sub-cells of every texel: ``sub`` bands uniform in θ per row (centre θ, weight = the band's
    exact solid angle) × ``sub`` columns uniform in φ. Returns ``(cos θ, sin θ, Ω per sub-cell)``
    per sub-row and ``(cos φ, sin φ)`` per sub-column. (Bands uniform in θ, not in cos θ, so the
    cells stay compact at the poles.)"""
    edges = np.pi * np.arange(h * sub + 1) / (h * sub)
    mid = 0.5 * (edges[:-1] + edges[1:])
    cos_t = np.cos(mid)
    sin_t = np.sin(mid)
    w_row = (2.0 * np.pi / (w * sub)) * (np.cos(edges[:-1]) - np.cos(edges[1:]))
    phi = 2.0 * np.pi * (np.arange(w * sub) + 0.5) / (w * sub)
    return cos_t, sin_t, w_row, np.cos(phi), np.sin(phi)


def _build_tables(env, lambdas, sizes, device, samples_per_sigma, max_sub, progress, cutoff=CUTOFF):
    env64 = np.asarray(env, np.float64)
    chain = _mip_chain(env64)
    offsets = np.zeros(len(lambdas), np.int64)
    counts = 6 * (sizes + 2) ** 2
    offsets[1:] = np.cumsum(counts)[:-1]
    total = int(counts.sum())
    out = wp.zeros(total, dtype=wp.vec3, device=device)
    src_cache = {}
    is_cpu = wp.get_device(device).is_cpu
    n_threads = cpu_workers("cpu", limit=4) if is_cpu else 1

    plan = []
    for k, lam in enumerate(lambdas):
        m, sub = _source_for(chain, float(lam), samples_per_sigma, max_sub, cutoff=cutoff)
        h, w = chain[m][0].shape[:2]
        window = min(1.0, cutoff / (2.0 * lam)) * (h * sub) * (w * sub)  # samples per texel, roughly
        plan.append((k, float(lam), m, sub, counts[k] * window))

    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=float(sum(p[4] for p in plan)), desc="prefilter ΓL", unit="smp", unit_scale=True,
                   leave=False)
    try:
        for k, lam, m, sub, work in plan:
            key = (m, sub)
            if key not in src_cache:
                h, w = chain[m][0].shape[:2]
                grid = _sample_grid(h, w, sub)
                src_cache[key] = [wp.array(chain[m][0].astype(np.float32), dtype=wp.vec3, device=device),
                                  wp.array(chain[m][1].astype(np.float32), dtype=wp.vec3, device=device)] + [
                    wp.array(g.astype(np.float32), dtype=float, device=device) for g in grid
                ]
            s_arr, s_dir, ct, st, wr, cp, sp = src_cache[key]
            n = int(sizes[k])
            level_out = out[int(offsets[k]) : int(offsets[k]) + int(counts[k])]
            cnt = int(counts[k])

            def launch(lo, hi, level_out=level_out, n=n, lam=lam, sub=sub, s_arr=s_arr, s_dir=s_dir, ct=ct, st=st,
                       wr=wr, cp=cp, sp=sp):
                wp.launch(_prefilter_level_kernel, dim=hi - lo,
                          inputs=[s_arr, s_dir, ct, st, wr, cp, sp, int(sub), float(lam), float(cutoff), n, lo, level_out],
                          device=device)

            if n_threads > 1 and cnt >= 4096:
                bounds = np.linspace(0, cnt, n_threads * 4 + 1).astype(int)
                launch(bounds[0], bounds[1])  # first chunk on this thread: the module loads once
                with ThreadPoolExecutor(n_threads) as ex:
                    list(ex.map(lambda ab: launch(*ab), zip(bounds[1:-1], bounds[2:])))
            else:
                launch(0, cnt)
            if bar is not None:
                wp.synchronize_device(device)
                bar.update(work)
    finally:
        if bar is not None:
            bar.close()
    wp.synchronize_device(device)
    return out.numpy(), offsets


def prefilter_environment(
    env,
    *,
    device="cpu",
    lambdas=None,
    base_face: int = 256,
    lam0: float = 0.5,
    step: float = math.sqrt(2.0),
    face_factor: float = 4.0,
    samples_per_sigma: float = 2.5,
    max_sub: int = 8,
    cutoff: float = CUTOFF,
    progress: bool = True,
    cache: bool = True,
) -> EnvPrefiltered:
    """Tabulate ``ΓL(p, λ) = ∫ G(i; p, λ, 1) L(i) di`` (eq. 35) as a λ-indexed pyramid of cubemaps.

    ``env`` (H, W, 3) linear radiance (unscaled: the scale and rotation are set at lookup time).
    ``lambdas``: an explicit geometric ladder (ascending, constant ratio) overriding
    ``lam0``/``step``; default :func:`default_ladder`. Face sizes follow
    ``clamp(⌈face_factor √λ⌉, 16, base_face)``. Cached on disk (``warp_sg.cache``, kind
    ``env_prefilter``) keyed by the map's content and every parameter.
    """
    import time

    env = validate_envmap(env)
    device = resolve_device(device)
    h = env.shape[0]
    if lambdas is None:
        lams, sizes, lam_inf = default_ladder(h, lam0=lam0, step=step, base_face=base_face, face_factor=face_factor)
    else:
        lams = np.asarray(lambdas, np.float64)
        if lams.ndim != 1 or len(lams) < 2 or np.any(lams <= 0):
            raise ValueError("lambdas must be an ascending 1-D list of >= 2 positive values")
        ratio = lams[1:] / lams[:-1]
        if np.any(ratio <= 1) or not np.allclose(ratio, ratio[0], rtol=1e-6):
            raise ValueError("lambdas must form a geometric ladder (constant ratio > 1)")
        sizes = _face_sizes(lams, face_factor, base_face)
        lam_inf = max(8.0 * lams[-1], 4.0 * (2.0 * h / math.pi) ** 2)

    params = dict(v=_VERSION, lambdas=[float(x) for x in lams], sizes=[int(x) for x in sizes],
                  sps=float(samples_per_sigma), max_sub=int(max_sub), cutoff=float(cutoff))

    t0 = time.perf_counter()

    def build():
        texels, offsets = _build_tables(env, lams, sizes, device, samples_per_sigma, max_sub, progress, float(cutoff))
        return {"texels": texels.astype(np.float32), "offsets": offsets.astype(np.int64)}

    if cache:
        from warp_sg.cache import content_key, load_or_build

        data = load_or_build("env_prefilter", content_key(env, params), build)
    else:
        data = build()
    om = row_solid_angles(env.shape[0], env.shape[1])
    mean = np.einsum("hwc,h->c", env.astype(np.float64), om) / (4.0 * np.pi)
    return EnvPrefiltered(
        lambdas=lams, face_sizes=np.asarray(sizes, np.int64), level_offsets=np.asarray(data["offsets"], np.int64),
        texels=np.asarray(data["texels"], np.float32), mean=mean, radiance=env, lam_inf=float(lam_inf),
        device=device, build_seconds=time.perf_counter() - t0,
    )


# --------------------------------------------------------------------------------------------
# numpy twin of the lookup, and the quadrature reference
# --------------------------------------------------------------------------------------------
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
    from warp_sg.envmap import env_lookup_numpy

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


__all__ = [
    "GammaTable",
    "EnvPrefiltered",
    "prefilter_environment",
    "default_ladder",
    "gamma_lookup",
    "gamma_normalized",
    "gamma_lookup_numpy",
    "gamma_normalized_numpy",
    "gamma_reference",
    "erf_filtered",
    "erf_filtered_numpy",
    "cube_dir",
    "cube_face_of",
    "cube_dir_numpy",
    "cube_face_of_numpy",
]
