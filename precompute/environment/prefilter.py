r"""Prefiltered environment ΓL(p, λ) for specular SG lighting (paper §6, eq. 34–35).

    ΓL(p, λ) = ∫_S² G(i; p, λ, 1) L(i) di,     ⟨G(·; p, λ, μ), L⟩ = μ ΓL(p, λ)        (eq. 34–35)

``L`` is the equirectangular map read as the piecewise-constant radiance function (the
Monte-Carlo reference's reading, :mod:`warp_sg.scene.envmap`).

Files: this module is the public entry and the host side (the λ ladder, the builder and the
:class:`EnvPrefiltered` record); :mod:`precompute.environment.prefilter_wp` holds the level-build
kernel, :class:`GammaTable` and the ``@wp.func`` lookups, :mod:`precompute.environment.prefilter_numpy`
the numpy twins of the lookup and the quadrature reference, and :mod:`precompute.environment.cubemap`
the cube-face geometry.

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

    from precompute.environment.prefilter import GammaTable, gamma_lookup

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

# the cube-map geometry and the kernel side (build kernel, table struct, lookups), re-exported here
from precompute.environment.cubemap import cube_dir
from precompute.environment.prefilter_wp import GammaTable, _prefilter_level_kernel, erf_filtered, gamma_lookup
from warp_sg.core.cache import code_key
from warp_sg.core.device import resolve_device
from warp_sg.core.image_io import LUMINANCE
from warp_sg.core.workers import cpu_workers
from warp_sg.scene.envmap import downsample_envmap, row_solid_angles, validate_envmap

#: Cap of the quadrature window: texels with λ (1 − p·d) > CUTOFF are skipped (mass e^{−14}).
CUTOFF = 14.0
#: Format tag of the cached entry (bump when the table layout or algorithm changes).
_VERSION = code_key(__name__, _prefilter_level_kernel, cube_dir, downsample_envmap)  # the producing code


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
    from warp_sg.scene.envmap import uv_to_dir

    h, w = env64.shape[:2]
    cos_mid = 0.5 * (np.cos(np.pi * np.arange(h) / h) + np.cos(np.pi * np.arange(1, h + 1) / h))
    v_mid = np.arccos(cos_mid) / np.pi
    cent = uv_to_dir(((np.arange(w) + 0.5) / w)[None, :], v_mid[:, None])
    lum_w = LUMINANCE
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
    # every level's texels in chunks (a level of ≥ 4096 texels in 4 per thread), all on one pool
    # of threads: the small broad levels run beside each other instead of one after the other
    chunks = []
    for k, lam, m, sub, work in plan:
        key = (m, sub)
        if key not in src_cache:
            h, w = chain[m][0].shape[:2]
            grid = _sample_grid(h, w, sub)
            src_cache[key] = [wp.array(chain[m][0].astype(np.float32), dtype=wp.vec3, device=device),
                              wp.array(chain[m][1].astype(np.float32), dtype=wp.vec3, device=device)] + [
                wp.array(g.astype(np.float32), dtype=float, device=device) for g in grid
            ]
        cnt = int(counts[k])
        parts = n_threads * 4 if n_threads > 1 and cnt >= 4096 else 1
        bounds = np.linspace(0, cnt, parts + 1).astype(int)
        level_out = out[int(offsets[k]) : int(offsets[k]) + cnt]
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            chunks.append((int(lo), int(hi), level_out, int(sizes[k]), lam, sub, src_cache[key], work * (hi - lo) / cnt))

    def launch(chunk):
        lo, hi, level_out, n, lam, sub, src, _ = chunk
        s_arr, s_dir, ct, st, wr, cp, sp = src
        wp.launch(_prefilter_level_kernel, dim=hi - lo,
                  inputs=[s_arr, s_dir, ct, st, wr, cp, sp, int(sub), float(lam), float(cutoff), n, lo, level_out],
                  device=device)
        return chunk[-1]

    try:
        if n_threads > 1:
            wp.load_module(_prefilter_level_kernel.module, device=device)  # once, before the threads
            with ThreadPoolExecutor(n_threads) as ex:
                for done in ex.map(launch, chunks[::-1]):  # (the sharp, costly levels first)
                    if bar is not None:
                        bar.update(done)
        else:
            for chunk in chunks:
                launch(chunk)
                if bar is not None:
                    wp.synchronize_device(device)
                    bar.update(chunk[-1])
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
    ``clamp(⌈face_factor √λ⌉, 16, base_face)``. Cached on disk (``warp_sg.core.cache``, kind
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
        from warp_sg.core.cache import content_key, load_or_build

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


__all__ = [
    "GammaTable",
    "EnvPrefiltered",
    "prefilter_environment",
    "default_ladder",
    "gamma_lookup",
    "erf_filtered",
]
