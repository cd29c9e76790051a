r"""SG mixture fit of an environment map for diffuse lighting (paper §6, eq. 34; Tsai & Shih 2006).

    L(i) ≈ L*(i) = Σ_k G(i; p_k, λ_k, μ_k)        (K < 10 lobes, μ_k RGB ≥ 0)

The diffuse term only sees the environment through the clamped cosine, so what matters is the
irradiance ``E(n) = ∫ max(n·i, 0) L(i) di``; the renderer evaluates it (unshadowed) as
``Σ_k ⟨C*(n), G_k⟩`` with the clamped-cosine SG ``C*`` of eq. 40 (λc = 2.133, μc = 1.170).

Algorithm (:func:`fit_environment_sgs`):

1. Work on a solid-angle-weighted downsampling of the map (default 32 × 64 texels; the sum
   ``Σ L Ω`` is kept exactly; at most 2·rows × 4·rows texels whatever the input's shape).
2. Initialisation from the brightest regions (up to K/2 lobes): blur the residual's luminance
   energy with an SG kernel (λ = 16), take its maximum, place a lobe at the energy centroid
   around it with sharpness ``1 / E[1 − p·i]`` of the residual energy there (for an SG,
   ``E[1 − p·i] ≈ 1/λ``) and the least-squares amplitude, subtract, repeat while a peak holds
   ≥ 3 % of the energy; the other lobes start broad (λ ≈ 0.6·K) on a Fibonacci sphere.
3. Refine all lobes jointly with ``scipy.optimize.least_squares`` (trust-region, bounds
   ``μ ≥ 0``, ``λ ∈ [0.05, λ_max]``) on two residual blocks: the radiance
   ``√Ω_j (L*(d_j) − L_j)`` over the texels and the irradiance ``w_E (E*(n_m) − E(n_m))`` over
   a grid of normals, where ``E*`` uses the renderer's eq. 40 clamped cosine, so the fit also
   absorbs that approximation's bias; both blocks are normalised by the map's mean radiance
   (default ``w_E = 10``: the irradiance error drops by ~2.5× for an unchanged radiance error).
   Amplitudes are eliminated by variable projection (non-negative least squares for given
   axes and sharpness, :mod:`precompute.environment.varpro`), so the solver only moves 4
   parameters per lobe, with the exact Jacobian of the reduced residual (Golub–Pereyra, for
   the NNLS free set held fixed) from the analytic derivatives of the system's columns
   (:mod:`precompute.environment.sg_design`). BLAS runs on one thread here (small matrices).

Returns :class:`EnvSGFit`, a 3-tuple ``(axes (K, 3), sharpness (K,), amplitude (K, 3))``
(float64) with the fit statistics in ``.info``. The axes are in the map's own frame: for an
environment rotated by ``R`` (environment → world) use ``R p_k``. Cached on disk
(``warp_sg.core.cache``, kind ``env_sg_fit``).

:func:`sg_irradiance` evaluates ``E*(n)`` of a mixture (numpy) and :func:`irradiance_reference`
the quadrature ``Σ_j L_j Ω_j max(n·d_j, 0)`` of the piecewise-constant map (sub-sampled).
"""
from __future__ import annotations

import math
import time

import numpy as np

from warp_sg import sg as sgm
from warp_sg.core.cache import code_key
from warp_sg.scene.envmap import downsample_envmap, row_solid_angles, texel_directions, validate_envmap

from . import sg_design, varpro
from .sg_design import LobeDesign, irradiance_matrix
from .varpro import Projection

_VERSION = code_key(__name__, sgm, downsample_envmap, sg_design, varpro)  # the producing code
from warp_sg.core.image_io import LUMINANCE  # noqa: E402


class EnvSGFit(tuple):
    """``(axes (K,3), sharpness (K,), amplitude (K,3))`` plus ``.info`` (fit statistics)."""

    def __new__(cls, axes, sharpness, amplitude, info=None):
        obj = super().__new__(cls, (axes, sharpness, amplitude))
        obj.info = dict(info or {})
        return obj

    @property
    def axes(self):
        return self[0]

    @property
    def sharpness(self):
        return self[1]

    @property
    def amplitude(self):
        return self[2]


# --------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------
def _working_map(env: np.ndarray, rows: int) -> np.ndarray:
    """Downsample to about ``rows`` × ``2 rows`` texels: exact box mips while divisible, then, if
    either side is still over twice its target (odd sizes, or an aspect far from 2:1), the exact
    solid-angle average over a ``min(H, rows)`` × ``min(W, 2 rows)`` grid (:func:`_area_resample`).
    The result has at most ``2 rows × 4 rows`` texels whatever the input's shape, which bounds the
    O(N²) peak blur and the fit."""
    env = np.asarray(env, np.float64)
    h, w = env.shape[:2]
    f = 1
    while h // f > rows and (h // f) % 2 == 0 and (w // f) % 2 == 0 and h // f // 2 >= rows:
        f *= 2
    if f > 1:  # one box pass: the solid-angle average over f × f children is that of the mip chain
        env = downsample_envmap(env, f)
        h, w = env.shape[:2]
    if h > 2 * rows or w > 4 * rows:
        env = _area_resample(env, min(h, rows), min(w, 2 * rows))
    return env


def _cell_average(a: np.ndarray, knots: np.ndarray, edges: np.ndarray, axis: int) -> np.ndarray:
    """Average over the cells ``edges[k]..edges[k+1]`` of the piecewise-constant function whose
    value in ``knots[j]..knots[j+1]`` is ``a[j]`` (along ``axis``): differences of its running
    integral, which is linear between knots (exact)."""
    a = np.moveaxis(a, axis, 0)
    run = np.concatenate([np.zeros((1,) + a.shape[1:]), np.cumsum(a * np.diff(knots).reshape((-1,) + (1,) * (a.ndim - 1)), 0)])
    j = np.clip(np.searchsorted(knots, edges, side="right") - 1, 0, len(knots) - 2)
    f = ((edges - knots[j]) / (knots[j + 1] - knots[j])).reshape((-1,) + (1,) * (a.ndim - 1))
    at = run[j] + f * (run[j + 1] - run[j])
    return np.moveaxis(np.diff(at, axis=0) / np.diff(edges).reshape((-1,) + (1,) * (a.ndim - 1)), 0, axis)


def _area_resample(env: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """The solid-angle average of the (piecewise-constant) map over each texel of a ``rows × cols``
    equirectangular grid: the measure is separable, ``dΩ = dφ · d(cos θ)``, so the map is averaged
    along u in φ and then along v in ``(1 − cos θ)/2``; ``Σ L Ω`` is kept exactly. O(H·W) time,
    row blocks of bounded memory."""
    h, w = env.shape[:2]
    u_src, u_dst = np.linspace(0.0, 1.0, w + 1), np.linspace(0.0, 1.0, cols + 1)
    mu = lambda n: (1.0 - np.cos(np.pi * np.arange(n + 1) / n)) / 2.0  # noqa: E731
    step = max(1, (1 << 22) // max(w, 1))
    along_u = np.concatenate([_cell_average(np.asarray(env[r0:r0 + step], np.float64), u_src, u_dst, 1)
                              for r0 in range(0, h, step)], 0)
    return _cell_average(along_u, mu(h), mu(rows), 0)


def irradiance_reference(env, normals, supersample: int = 1):
    """``E(n) = ∫ max(n·i, 0) L(i) di`` by quadrature over the piecewise-constant map (float64).

    Each texel is split into ``supersample²`` equal-solid-angle cells (uniform in cos θ and φ).
    """
    env = np.asarray(env, np.float64)
    h, w = env.shape[:2]
    s = int(supersample)
    theta_edges = np.pi * np.arange(h + 1) / h
    c0 = np.cos(theta_edges[:-1])[:, None]
    c1 = np.cos(theta_edges[1:])[:, None]
    f = (np.arange(s) + 0.5) / s
    cos_t = (c0 + (c1 - c0) * f[None, :]).reshape(-1)
    sin_t = np.sqrt(np.clip(1 - cos_t**2, 0, None))
    phi = 2 * np.pi * (np.arange(w * s) + 0.5) / (w * s)
    d = np.stack(np.broadcast_arrays(sin_t[:, None] * np.sin(phi)[None], cos_t[:, None], -sin_t[:, None] * np.cos(phi)[None]), -1)
    om = np.repeat(row_solid_angles(h, w) / (s * s), s)[:, None]
    vals = np.repeat(np.repeat(env, s, axis=0), s, axis=1) * om[..., None]
    d = d.reshape(-1, 3)
    vals = vals.reshape(-1, 3)
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    out = np.empty((len(n), 3))
    for i0 in range(0, len(n), 256):  # chunks bound the memory
        cos = np.maximum(n[i0 : i0 + 256] @ d.T, 0.0)
        out[i0 : i0 + 256] = cos @ vals
    return out.reshape(np.shape(normals)[:-1] + (3,))


def sg_irradiance(axes, sharpness, amplitude, normals, cosine=None):
    """``E*(n) = Σ_k ⟨C*(n), G_k⟩`` with the clamped-cosine SG ``C*`` (default eq. 40), or with
    ``cosine="exact"`` the exact irradiance of each SG (``warp_sg.sg.irradiance``, what the renderer
    evaluates).

    ``cosine``: ``"exact"`` or an optional ``(λc, μc)`` pair (or lists of them for a multi-lobe cosine fit).
    """
    return np.einsum("...k,kc->...c", irradiance_matrix(normals, axes, sharpness, cosine),
                     np.asarray(amplitude, np.float64))


def _model(d, axes, lam, mu):
    g = np.exp(-lam[None, :] * 0.5 * np.sum((d[:, None, :] - axes[None, :, :]) ** 2, -1))  # (N, K)
    return g @ mu, g


def _fibonacci_normals(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = np.pi * (3 - np.sqrt(5)) * i
    return np.stack([r * np.cos(phi), z, r * np.sin(phi)], -1)


# --------------------------------------------------------------------------------------------
# Fit
# --------------------------------------------------------------------------------------------
def _greedy_peaks(d, om, L, n_max, lam_max, min_fraction=0.03):
    """Lobes at the brightest regions: blur the residual luminance energy (SG kernel, λ = 16),
    take the maximum, put a lobe at the energy centroid there with sharpness
    ``1 / E[1 − p·i]`` (an SG's mean of ``1 − cos`` is ≈ 1/λ) and its least-squares amplitude,
    subtract it and repeat while a peak holds ≥ ``min_fraction`` of the total energy and lies
    ≥ 0.35 rad from the previous peaks."""
    resid = L.copy()
    axes, lams = [], []
    # SG blur (λ = 16) of per-texel energies: the kernel once for a working map of the default
    # size (32 MB), else in row chunks (bounded memory)
    kernel = np.exp(-16.0 * (1.0 - d @ d.T)) if len(d) <= 2048 else None

    def blur(e):
        if kernel is not None:
            return kernel @ e
        out = np.empty(len(d))
        for i0 in range(0, len(d), 1024):
            out[i0 : i0 + 1024] = np.exp(-16.0 * (1.0 - d[i0 : i0 + 1024] @ d.T)) @ e
        return out

    total = float((np.maximum(L @ LUMINANCE, 0.0) * om).sum())
    for _ in range(n_max):
        e = np.maximum(resid @ LUMINANCE, 0.0) * om
        if total <= 0 or e.sum() <= 0:
            break
        b = blur(e)
        j = int(np.argmax(b))
        near = np.exp(-64.0 * (1.0 - d @ d[j]))  # a tighter window for the moments
        wgt = e * near
        if wgt.sum() < min_fraction * total:
            break
        c = (wgt[:, None] * d).sum(0)
        p = c / np.linalg.norm(c) if np.linalg.norm(c) > 0 else d[j]
        if any(np.arccos(np.clip(p @ q, -1, 1)) < 0.35 for q in axes):
            break
        mean_omc = float((wgt * (1 - d @ p)).sum() / max(wgt.sum(), 1e-300))
        lam = float(np.clip(1.0 / max(mean_omc, 1e-6), 2.0, lam_max))
        g = np.exp(-lam * (1 - d @ p))
        mu = np.maximum((om * g) @ resid / max((om * g * g).sum(), 1e-300), 0.0)
        axes.append(p)
        lams.append(lam)
        resid = resid - g[:, None] * mu
    return axes, lams


def _fit(env, n_lobes, rows, irradiance_weight, n_normals, max_nfev, cosine=None):
    from scipy.optimize import least_squares

    t0 = time.perf_counter()
    work = _working_map(env, rows)
    h, w = work.shape[:2]
    d = texel_directions(h, w).reshape(-1, 3)
    om = np.repeat(row_solid_angles(h, w)[:, None], w, 1).reshape(-1)
    L = work.reshape(-1, 3)
    scale = float(max((L @ LUMINANCE * om).sum() / (4 * np.pi), 1e-30))  # mean luminance
    Ln = L / scale
    lam_max = float(4.0 * (h / np.pi) ** 2)  # a lobe about one working texel wide
    normals = _fibonacci_normals(n_normals)
    E = irradiance_reference(work, normals) / scale
    # the irradiance block has one row per normal (~4π/M sr each); E ~ π L: scale it like radiance
    w_e = irradiance_weight * math.sqrt(4 * math.pi / n_normals) / math.pi
    B = np.concatenate([np.sqrt(om)[:, None] * Ln] + ([w_e * E] if w_e > 0 else []), 0)

    # initial lobes: the brightest regions, then broad lobes spread over the sphere
    peaks, plams = _greedy_peaks(d, om, Ln, max(1, n_lobes // 2), lam_max)
    n_rest = n_lobes - len(peaks)
    rest = _fibonacci_normals(n_rest) if n_rest > 0 else np.zeros((0, 3))
    lam_rest = max(1.0, 0.6 * n_rest)
    axes0 = np.concatenate([np.reshape(peaks, (-1, 3)), rest], 0)
    lams0 = np.concatenate([plams, np.full(n_rest, lam_rest)])
    K = len(lams0)

    design = LobeDesign([(d, np.sqrt(om), "radiance")] + ([(normals, np.full(n_normals, w_e), "irradiance")]
                                                         if w_e > 0 else []), cosine)
    proj = Projection(design.evaluate, design.derivative, B, np.repeat(np.arange(K), 4))
    x0 = np.concatenate([axes0, np.log(lams0)[:, None]], 1).ravel()
    lo = np.tile([-np.inf] * 3 + [math.log(0.05)], K)
    hi = np.tile([np.inf] * 3 + [math.log(lam_max)], K)
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    r0 = proj.residual(x0)
    res = least_squares(proj.residual, x0, jac=proj.jacobian, bounds=(lo, hi), method="trf", tr_solver="lsmr",
                        max_nfev=max_nfev)
    ax, lam, _ = design.unpack(res.x)
    mu = proj.evaluate(res.x)[1] * scale
    # statistics on the working map
    model, _ = _model(d, ax, lam, mu)
    err2, ref2 = (om[:, None] * (model - L) ** 2).sum(), (om[:, None] * L**2).sum()
    rad_rel = float(np.sqrt(err2 / ref2)) if ref2 > 0 else (0.0 if err2 == 0 else math.inf)  # a black map: 0
    Ef = sg_irradiance(ax, lam, mu, normals, cosine=cosine)
    Et = E * scale
    e_rel = np.abs(Ef - Et).max(1) / np.maximum(np.abs(Et).max(1), 1e-300)
    order = np.argsort(-(mu @ LUMINANCE) * sgm.integral(lam))
    info = dict(
        radiance_rel_rms=rad_rel,
        irradiance_rel_max=float(e_rel.max()),
        irradiance_rel_mean=float(e_rel.mean()),
        initial_cost=float(0.5 * r0 @ r0),
        final_cost=float(res.cost),
        nfev=int(res.nfev),
        peaks=len(peaks),
        working_shape=[int(h), int(w)],
        seconds=time.perf_counter() - t0,
    )
    return ax[order], lam[order], mu[order], info


def fit_environment_sgs(
    env,
    n_lobes: int = 8,
    *,
    rows: int = 32,
    irradiance_weight: float = 10.0,
    n_normals: int = 256,
    max_nfev: int = 60,
    cosine=None,
    cache: bool = True,
) -> EnvSGFit:
    """Fit ``n_lobes`` SGs to an environment map (see the module docstring); cached on disk.

    ``env`` (H, W, 3) unscaled radiance in the map's frame. ``rows``: working resolution
    (rows × 2·rows). ``irradiance_weight`` = 0 fits the radiance only. ``cosine``: the
    clamped-cosine SG(s) ``(λc, μc)`` (scalars or lists) the renderer uses (default eq. 40);
    the irradiance block is fitted through it; ``"exact"`` fits through the exact SG irradiance
    (``warp_sg.sg.irradiance``), what the renderer evaluates. Returns
    ``EnvSGFit(axes (K,3), sharpness (K,), amplitude (K,3))``; ``.info`` has ``radiance_rel_rms``
    (solid-angle-weighted relative RMS radiance error on the working map), ``irradiance_rel_max``
    / ``irradiance_rel_mean`` (relative error of ``E*(n)`` over ``n_normals`` normals, per-normal
    max over channels) and ``seconds``.
    """
    n_lobes = int(n_lobes)
    if not 1 <= n_lobes <= 64:
        raise ValueError(f"n_lobes must be in [1, 64], got {n_lobes}")
    env = validate_envmap(env)
    if isinstance(cosine, str) and cosine != "exact":
        raise ValueError(f"cosine must be 'exact' or (λc, μc) pairs, got {cosine!r}")
    cos_key = (cosine if isinstance(cosine, str) or cosine is None
               else [np.atleast_1d(np.asarray(c, float)).tolist() for c in cosine])
    params = dict(v=_VERSION, n=n_lobes, rows=int(rows), iw=float(irradiance_weight), nn=int(n_normals),
                  nfev=int(max_nfev), cosine=cos_key)

    def build():
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):  # small matrices: OpenBLAS threads only spin
            ax, lam, mu, info = _fit(env, n_lobes, int(rows), float(irradiance_weight), int(n_normals),
                                     int(max_nfev), cosine)
        out = {"axes": ax, "sharpness": lam, "amplitude": mu}
        for k, v in info.items():
            out["info_" + k] = np.asarray(v)
        return out

    if cache:
        from warp_sg.core.cache import content_key, load_or_build

        data = load_or_build("env_sg_fit", content_key(env, params), build)
    else:
        data = build()
    info = {k[5:]: (data[k].tolist() if data[k].ndim else data[k].item()) for k in data if k.startswith("info_")}
    return EnvSGFit(np.asarray(data["axes"], np.float64), np.asarray(data["sharpness"], np.float64),
                    np.asarray(data["amplitude"], np.float64), info)


__all__ = ["EnvSGFit", "fit_environment_sgs", "sg_irradiance", "irradiance_reference"]
