r"""Kernel side of the prefiltered environment ΓL (:mod:`precompute.environment.prefilter`, paper §6 eq. 34–35):
the level-build kernel (one cube-map level of ``Γn = ΓL/∫G`` per launch), the :class:`GammaTable`
struct and the lookups ``gamma_lookup`` / ``gamma_normalized`` / ``erf_filtered``. The method, the
table layout and the lookup's regimes are described in :mod:`precompute.environment.prefilter`, which
re-exports these names and builds the tables.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import warp as wp

from precompute.environment.cubemap import bordered_bilinear, cube_dir, cube_face_of
from warp_sg.scene.envmap import wp_dir_to_uv
from warp_sg.sg.algebra_wp import one_minus_dot, sg_integral

PI = wp.constant(3.141592653589793)
TWO_PI = wp.constant(6.283185307179586)


# --------------------------------------------------------------------------------------------
# Build kernel
# --------------------------------------------------------------------------------------------
_vec6 = wp.types.vector(length=6, dtype=float)


@wp.func
def _phi_cdf(x: float) -> float:
    return 0.5 * (1.0 + wp.erf(x * 0.7071067811865476))


@wp.kernel(enable_backward=False)
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
    # Sub-sampled source (sub > 1): integrate G over whole texels instead, where the lobe is narrow
    # in both directions. Exact separation 1 − cos γ = (1 − cos Δθ) + sin θ sin θp (1 − cos Δφ),
    # each factor ≈ Gaussian: ∫_texel G dΩ ≈ sin θ_m ∫ e^{−λΔθ²/2} dθ · ∫ e^{−κΔφ²/2} dφ,
    # κ = λ sin θ_m sin θp (normal-CDF differences). Rows near a pole (κ < 50) keep sub-cells.
    # A row's upper edge is the next row's lower edge: its Φ and Gaussian are carried over.
    whole = sub > 1 and cmin > -1.0
    cdf_a = float(0.0)
    e_a = float(0.0)
    if whole:
        za0 = (float(r_lo) * h_t - theta_p) * sq_lam
        cdf_a = _phi_cdf(za0)
        e_a = wp.exp(-0.5 * za0 * za0)
    for r in range(r_lo, r_hi + 1):
        t0 = float(r) * h_t
        t1 = float(r + 1) * h_t
        kappa = float(0.0)
        mass = float(0.0)
        st_c = float(0.0)
        if whole:
            # sin θ and κ at the Gaussian-weighted mean θ of the row (truncated-normal mean): the far
            # tail of a bright source is sensitive to κ, so take it where the row's weight sits
            zb = (t1 - theta_p) * sq_lam
            cdf_b = _phi_cdf(zb)
            e_b = wp.exp(-0.5 * zb * zb)
            mass = cdf_b - cdf_a
            t_m = wp.clamp(theta_p, t0, t1)
            if mass > 1.0e-12:
                t_m = wp.clamp(theta_p + 0.3989422804014327 * (e_a - e_b) / (mass * sq_lam), t0, t1)
            st_c = wp.sin(t_m)
            kappa = lam * st_c * sin_tp
            cdf_a = cdf_b
            e_a = e_b
        if whole and kappa >= 50.0:
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
                j = ((j0 % w_src) + w_src) % w_src  # (column j0 + q wrapped: stepped, not divided)
                for q in range(cnt):
                    nxt = _phi_cdf((float(j0 + q + 1) * h_pt - phi_p) * sk)
                    g = a_r * (nxt - prev) / sk
                    prev = nxt
                    wsum += g
                    acc += g * src[r, j]
                    j += 1
                    if j == w_src:
                        j = 0
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
                # sub-column jj wrapped to j, and its source texel j // sub: stepped along the row
                # (no integer division per sample: the same texels, ≈ 5 % less CPU)
                j = ((j0 % cols) + cols) % cols
                jt = j // sub
                js = j - jt * sub
                for _jj in range(cnt):
                    if sub == 1:
                        dd = src_dir[r, j]  # energy centroid of a mip texel
                    else:
                        dd = wp.vec3(st * sin_p[j], ct, -st * cos_p[j])
                    g = wr * wp.exp(-lam * one_minus_dot(dd, d))
                    wsum += g
                    acc += g * src[r, jt]
                    j += 1
                    js += 1
                    if js == sub:
                        js = 0
                        jt += 1
                    if j == cols:
                        j = 0
                        jt = 0
                        js = 0
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
    return bordered_bilinear(tab.texels, tab.level_offset[level] + face * (n + 2) * (n + 2), n, a, b)


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
    sums = _window_sums(radiance, wcol, r0, r1, c0, c1, h_t, theta_p, sigma)
    wsum = sums[3]
    if wsum <= 0.0:
        return wp.vec4(0.0)
    return wp.vec4(sums[0] / wsum, sums[1] / wsum, sums[2] / wsum, 1.0)


@wp.func
def _window_sums(radiance: wp.array2d(dtype=wp.vec3), wcol: _vec6, r0: int, r1: int, c0: int, c1: int, h_t: float,
                 theta_p: float, sigma: float) -> wp.vec4:
    """(Σ w·L, Σ w) over the window of :func:`erf_filtered`: a function of its own, whose sums its
    caller divides, because Warp's reverse pass replays a function whole but not a dynamic loop
    (``warp_sg.shading.kernel_grad``)."""
    ww = radiance.shape[1]
    acc = wp.vec4(0.0)
    for r in range(r0, r1 + 1):  # (each row's edges anew: a loop's body is replayed alone)
        wr = _phi_cdf((float(r + 1) * h_t - theta_p) / sigma) - _phi_cdf((float(r) * h_t - theta_p) / sigma)
        for q in range(c1 - c0 + 1):
            cc = (((c0 + q) % ww) + ww) % ww
            wgt = wr * wcol[q]
            L = radiance[r, cc]
            acc += wp.vec4(wgt * L[0], wgt * L[1], wgt * L[2], wgt)
    return acc


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


@wp.func
def gamma_mean(tab: GammaTable, p: wp.vec3, lam: float) -> wp.vec3:
    """``scale · ΓL(p, λ)/∫G(λ)``: the mean radiance under the lobe (eq. 35 over the lobe's
    integral), :func:`gamma_lookup` without multiplying by ∫G that the caller divides out again."""
    return gamma_normalized(tab, wp.normalize(tab.to_env * p), lam) * tab.scale


__all__ = ["GammaTable", "gamma_lookup", "gamma_mean", "gamma_normalized", "erf_filtered"]
