r"""Equirectangular environment maps: loading, the direction ↔ (u, v) convention, solid angles,
a procedural all-frequency sky and dynamic rotation (docs/environment.md "Equirectangular maps", paper §6).

Scene layer: what a map *is* (the lights, the engines and the reference all read it this way);
the precompute facade names this module ``precompute.envmap``.

Convention (Mitsuba 3 ``envmap``, unrotated emitter), for a unit direction ``d`` in the
environment's own frame::

    u = atan2(d.x, −d.z) / (2π)   wrapped to [0, 1)        (column = u · W)
    v = acos(d.y) / π                                       (row = v · H, row 0 at the top)
    d(u, v) = (sin θ sin φ, cos θ, −sin θ cos φ),  φ = 2π u, θ = π v

Texel ``(r, c)`` covers ``θ ∈ [π r/H, π (r+1)/H]``, ``φ ∈ [2π c/W, 2π (c+1)/W]`` and the map is the
piecewise-constant radiance function that the Monte-Carlo reference uses; its solid angle is
``Ω_r = (2π/W)(cos θ_r − cos θ_{r+1})`` (:func:`texel_solid_angles`).

Rotation is dynamic: an environment carries a rotation ``R`` (environment → world, Mitsuba's
``to_world``); lookups map a world direction to the map's frame with ``Rᵀ d`` at lookup time
(:func:`env_lookup` / :func:`env_lookup_numpy`, the prefiltered ΓL table and the SG fit axes
``R p``), so rotating the light needs no precomputation. :func:`rotate_envmap` bakes a rotation
into a resampled map for tests and export.

Public API: :func:`load_envmap`, :func:`~warp_sg.scene.sky.procedural_sky` (in :mod:`warp_sg.scene.sky`),
:func:`dir_to_uv`, :func:`uv_to_dir`,
:func:`dir_to_texel`, :func:`texel_directions`, :func:`row_solid_angles`, :func:`texel_solid_angles`,
:func:`downsample_envmap`, :func:`rotation_matrix`, :func:`rotation_y`, :func:`rotate_envmap`,
:func:`env_lookup_numpy`, and the ``@wp.func`` twins ``wp_dir_to_uv(d) -> vec2``, ``wp_uv_to_dir(u, v) -> vec3``,
``env_lookup(radiance: array2d(vec3), to_env: mat33, d: vec3) -> vec3`` (bilinear) and
``env_lookup_nearest(radiance, to_env, d)`` (piecewise constant).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import math
from pathlib import Path

import numpy as np
import warp as wp

from warp_sg.core import watchdog
from warp_sg.core.errors import ImageError
from warp_sg.core.watchdog import MAX_ENV_TEXELS, check_size
from warp_sg.numeric.fastmath import fast_asin, fast_atan2

PI = wp.constant(3.141592653589793)
TWO_PI = wp.constant(6.283185307179586)


# --------------------------------------------------------------------------------------------
# Convention (numpy)
# --------------------------------------------------------------------------------------------
def dir_to_uv(d):
    """Unit directions ``(..., 3)`` → ``(u, v)`` in [0, 1) × [0, 1] (Mitsuba envmap convention)."""
    d = np.asarray(d, dtype=np.float64)
    u = np.arctan2(d[..., 0], -d[..., 2]) / (2.0 * np.pi)
    u = u - np.floor(u)
    u = np.where(u >= 1.0, 0.0, u)
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi
    return u, v


def dir_to_texel(d, height: int, width: int):
    """Unit directions ``(..., 3)`` → ``(row, col)`` int64 arrays of the texel that contains them
    (the piecewise-constant lookup of :func:`env_lookup_nearest` and the reference's sampler)."""
    u, v = dir_to_uv(d)
    c = np.clip((u * width).astype(np.int64), 0, width - 1)
    r = np.clip((v * height).astype(np.int64), 0, height - 1)
    return r, c


def uv_to_dir(u, v):
    """``(u, v)`` → unit directions ``(..., 3)``: ``(sin θ sin φ, cos θ, −sin θ cos φ)``, φ = 2πu, θ = πv."""
    phi = 2.0 * np.pi * np.asarray(u, dtype=np.float64)
    theta = np.pi * np.asarray(v, dtype=np.float64)
    phi, theta = np.broadcast_arrays(phi, theta)
    st = np.sin(theta)
    return np.stack([st * np.sin(phi), np.cos(theta), -st * np.cos(phi)], axis=-1)


def texel_directions(height: int, width: int) -> np.ndarray:
    """(H, W, 3) float64 unit directions through the texel centres (``u = (c+½)/W``, ``v = (r+½)/H``)."""
    v = (np.arange(height) + 0.5) / height
    u = (np.arange(width) + 0.5) / width
    return uv_to_dir(u[None, :], v[:, None])


def row_solid_angles(height: int, width: int) -> np.ndarray:
    """(H,) solid angle of one texel in each row: ``(2π/W)(cos θ_r − cos θ_{r+1})`` (float64)."""
    theta = np.pi * np.arange(height + 1) / height
    return (2.0 * np.pi / width) * (np.cos(theta[:-1]) - np.cos(theta[1:]))


def texel_solid_angles(height: int, width: int) -> np.ndarray:
    """(H, W) float64 solid angle of every texel (exact for the θ-φ cell); sums to 4π."""
    return np.repeat(row_solid_angles(height, width)[:, None], width, axis=1)


def downsample_envmap(env: np.ndarray, factor: int = 2) -> np.ndarray:
    """Box-downsample by ``factor`` in both axes, weighting by texel solid angle.

    Each coarse texel gets the solid-angle average of its children, so ``Σ L Ω`` over any
    coarse texel (and the whole sphere) is preserved exactly. ``H`` and ``W`` must be divisible
    by ``factor``.
    """
    env = np.asarray(env, dtype=np.float64)
    h, w = env.shape[:2]
    if factor == 1:
        return env.copy()
    if h % factor or w % factor:
        raise ValueError(f"map size {h}x{w} is not divisible by {factor}")
    om = row_solid_angles(h, w)
    weighted = env * om[:, None, None]
    s = weighted.reshape(h // factor, factor, w // factor, factor, -1).sum(axis=(1, 3))
    om_c = om.reshape(h // factor, factor).sum(axis=1) * factor
    return s / om_c[:, None, None]


# --------------------------------------------------------------------------------------------
# Convention (Warp)
# --------------------------------------------------------------------------------------------
@wp.func
def wp_dir_to_uv(d: wp.vec3) -> wp.vec2:
    """(u, v) of unit direction ``d`` (u wrapped to [0, 1)); polynomial atan2 / asin
    (``warp_sg.numeric.fastmath``, ≈ 2e-6 rad: 1/1000 of a texel of a 2048-wide map)."""
    u = fast_atan2(d[0], -d[2]) / TWO_PI
    u = u - wp.floor(u)
    if u >= 1.0:
        u = 0.0
    v = (0.5 * PI - fast_asin(wp.clamp(d[1], -1.0, 1.0))) / PI
    return wp.vec2(u, v)


@wp.func
def wp_uv_to_dir(u: float, v: float) -> wp.vec3:
    phi = TWO_PI * u
    theta = PI * v
    st = wp.sin(theta)
    return wp.vec3(st * wp.sin(phi), wp.cos(theta), -st * wp.cos(phi))


@wp.func
def env_lookup_nearest(radiance: wp.array2d(dtype=wp.vec3), to_env: wp.mat33, d: wp.vec3) -> wp.vec3:
    """Piecewise-constant radiance from world direction ``d`` (``to_env = Rᵀ``)."""
    h = radiance.shape[0]
    w = radiance.shape[1]
    uv = wp_dir_to_uv(wp.normalize(to_env * d))
    c = wp.clamp(int(uv[0] * float(w)), 0, w - 1)
    r = wp.clamp(int(uv[1] * float(h)), 0, h - 1)
    return radiance[r, c]


@wp.func
def env_lookup(radiance: wp.array2d(dtype=wp.vec3), to_env: wp.mat33, d: wp.vec3) -> wp.vec3:
    """Bilinear radiance from world direction ``d`` (``to_env = Rᵀ``): wraps in u, clamps in v."""
    h = radiance.shape[0]
    w = radiance.shape[1]
    uv = wp_dir_to_uv(wp.normalize(to_env * d))
    x = uv[0] * float(w) - 0.5
    y = wp.clamp(uv[1] * float(h) - 0.5, 0.0, float(h - 1))
    x0f = wp.floor(x)
    y0f = wp.floor(y)
    fx = x - x0f
    fy = y - y0f
    x0 = int(x0f)
    y0 = int(y0f)
    x0 = ((x0 % w) + w) % w
    x1 = (x0 + 1) % w
    y1 = wp.min(y0 + 1, h - 1)
    a = radiance[y0, x0] * (1.0 - fx) + radiance[y0, x1] * fx
    b = radiance[y1, x0] * (1.0 - fx) + radiance[y1, x1] * fx
    return a * (1.0 - fy) + b * fy


def env_lookup_numpy(env, dirs, rotation=None, bilinear: bool = True) -> np.ndarray:
    """numpy twin of :func:`env_lookup` / :func:`env_lookup_nearest` for world directions ``(..., 3)``.

    ``rotation`` is ``R`` (environment → world); the map is read at ``Rᵀ d``.
    """
    env = np.asarray(env)
    h, w = env.shape[:2]
    d = np.asarray(dirs, dtype=np.float64)
    if rotation is not None:
        d = d @ np.asarray(rotation, dtype=np.float64)  # (Rᵀ d)ᵀ = dᵀ R
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    if not bilinear:
        r, c = dir_to_texel(d, h, w)
        return env[r, c]
    u, v = dir_to_uv(d)
    x = u * w - 0.5
    y = np.clip(v * h - 0.5, 0.0, h - 1)
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[..., None]
    fy = (y - y0)[..., None]
    x0 = x0.astype(np.int64) % w
    x1 = (x0 + 1) % w
    y0 = y0.astype(np.int64)
    y1 = np.minimum(y0 + 1, h - 1)
    a = env[y0, x0] * (1 - fx) + env[y0, x1] * fx
    b = env[y1, x0] * (1 - fx) + env[y1, x1] * fx
    return a * (1 - fy) + b * fy


# --------------------------------------------------------------------------------------------
# Rotation
# --------------------------------------------------------------------------------------------
def rotation_matrix(axis=(0.0, 1.0, 0.0), angle_deg: float = 0.0) -> np.ndarray:
    """3×3 rotation by ``angle_deg`` degrees about ``axis`` (right-handed, Rodrigues)."""
    a = np.asarray(axis, dtype=np.float64)
    n = np.linalg.norm(a)
    if not np.isfinite(n) or n == 0:
        raise ValueError(f"rotation axis must be a non-zero vector, got {axis}")
    k = a / n
    t = np.deg2rad(angle_deg)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * (K @ K)


def rotation_y(degrees: float) -> np.ndarray:
    """``R_y(degrees)``: :func:`rotation_matrix` about +Y in closed form (exact entries), the
    rotation of an ``EnvironmentLight`` (``world = R · map frame``)."""
    t = math.radians(degrees)
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _is_y_rotation(R) -> bool:
    return bool(abs(R[1, 1] - 1.0) <= 1e-12 and np.all(np.abs(R[[0, 1, 1, 2], [1, 0, 2, 1]]) <= 1e-12))


def _shift_u(env: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``out(d) = env(Rᵀ d)`` for a rotation about +Y: only the azimuth moves, so this is an exact
    linear resampling along u (wrapping), whatever the resolution."""
    h, w = env.shape[:2]
    # u = atan2(x, −z)/2π. The u shift of Rᵀ on one direction is the shift of every direction.
    s = R.T @ np.array([0.0, 0.0, -1.0])  # u = 0
    du = (math.atan2(s[0], -s[2]) / (2 * math.pi)) % 1.0
    x = (np.arange(w) + 0.5) / w + du  # source u of each output column
    xs = x * w - 0.5
    x0 = np.floor(xs).astype(np.int64)
    f = (xs - x0)[None, :, None]
    return env[:, x0 % w] * (1 - f) + env[:, (x0 + 1) % w] * f


def rotate_envmap(env, rotation, supersample: int = 2) -> np.ndarray:
    """Resample ``env`` so that the result, read unrotated, equals ``env`` rotated by ``R``.

    ``out(d) = env(Rᵀ d)`` (bilinear, ``supersample²`` samples per output texel); a rotation about
    +Y (an ``EnvironmentLight``'s) is the exact linear resampling along u instead, and the
    identity returns the map unchanged. Returns float32. Rendering never needs this — rotation is
    applied at lookup time — except the Monte-Carlo reference, which reads the rotated map.
    """
    R = np.asarray(rotation, dtype=np.float64)
    if np.array_equal(R, np.eye(3)):
        return np.asarray(env).astype(np.float32)
    if _is_y_rotation(R):
        return _shift_u(np.asarray(env), R).astype(np.float32)
    env = np.asarray(env, dtype=np.float64)
    h, w = env.shape[:2]
    s = int(supersample)
    d = texel_directions(h * s, w * s)
    vals = env_lookup_numpy(env, d, rotation=rotation, bilinear=True)
    return vals.reshape(h, s, w, s, -1).mean(axis=(1, 3)).astype(np.float32)


# --------------------------------------------------------------------------------------------
# Loading
# --------------------------------------------------------------------------------------------
#: largest radiance of a texel: 18 orders of magnitude below float32's 3.4e38 leave room for the SG
#: amplitudes, BRDF peaks and exposure that multiply it (a real sun in an HDRI is below 1e6)
MAX_RADIANCE = 1e20
#: accepted width / height of an equirectangular map (exactly 2 for the full sphere): a map far from
#: 2:1 is not an equirectangular map (its texels would be stretched) and is refused
ASPECT_RANGE = (1.0, 4.0)


def check_envmap_shape(height: int, width: int, where: str = "environment map") -> None:
    """Refuse a map smaller than 2 × 2, with more texels than :data:`warp_sg.core.watchdog.MAX_ENV_TEXELS`
    or whose aspect W/H is outside :data:`ASPECT_RANGE`, with an :class:`ImageError` naming
    ``where`` and the size (before any work on the texels)."""
    try:
        h, w = int(height), int(width)
    except (TypeError, ValueError):
        raise ImageError(f"environment map width and height must be integers, got {width!r}×{height!r}",
                         where=where) from None
    if h < 2 or w < 2:
        raise ImageError(f"environment map must be at least 2×2 texels, got {w}×{h} (W×H)", where=where)
    check_size("the environment map", h * w, MAX_ENV_TEXELS, f"{w}×{h} texels", "texels", where=where, error=ImageError)
    lo, hi = ASPECT_RANGE
    if not lo <= w / h <= hi:
        raise ImageError(f"environment map is {w}×{h} texels (W×H), W/H = {w / h:.3g}: an equirectangular map is "
                         f"twice as wide as it is tall (W/H from {lo:g} to {hi:g} is accepted)", where=where)


def validate_envmap(env, where: str = "environment map") -> np.ndarray:
    """Check an in-memory map: ``(H, W, 3)`` (:func:`check_envmap_shape`), finite, non-negative,
    at most :data:`MAX_RADIANCE`. Returns float32.

    Raises :class:`ImageError` naming ``where`` and the first bad texel.
    """
    a = np.asarray(env)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ImageError(f"environment map must be (H, W, 3) with H, W >= 2, got shape {a.shape}", where=where)
    check_envmap_shape(a.shape[0], a.shape[1], where)
    a = a.astype(np.float32, copy=False)
    bad_nan = ~np.isfinite(a)
    if bad_nan.any():
        r, c, _ = np.argwhere(bad_nan)[0]
        n = int(bad_nan.any(axis=2).sum())
        raise ImageError(f"{n} texel(s) are NaN or infinite (first at row {r}, column {c})", where=where)
    hot = a > MAX_RADIANCE
    if hot.any():
        r, c, _ = np.argwhere(hot)[0]
        n = int(hot.any(axis=2).sum())
        raise ImageError(f"{n} texel(s) have radiance above {MAX_RADIANCE:g} (first at row {r}, column {c}: "
                         f"{a[r, c].tolist()}); shading in float32 (at most 3.4e38) would overflow", where=where)
    neg = a < 0
    if neg.any():
        r, c, _ = np.argwhere(neg)[0]
        n = int(neg.any(axis=2).sum())
        raise ImageError(
            f"{n} texel(s) have negative radiance (first at row {r}, column {c}: {a[r, c].tolist()})", where=where
        )
    return a


def reduce_envmap(env: np.ndarray, bound: int, where: str = "environment map") -> np.ndarray:
    """``env`` (H, W, 3) when it has at most ``bound`` texels, else averaged down to the largest
    ``(H/f) × (W/f)`` (integer f, sizes rounded down) within it: every output texel the
    solid-angle-weighted mean of its block of input texels, ``L' = Σ L Ω / Σ Ω``, so that ``Σ L Ω``
    over each block (and the whole sphere) is kept. Done by blocks of rows in float64 (no full
    float64 copy); one :class:`~warp_sg.core.errors.InputWarning` names the sizes."""
    import warnings

    from warp_sg.core.errors import InputWarning

    h, w = env.shape[:2]
    if h * w <= bound:
        return env
    f = max(2, math.ceil(math.sqrt(h * w / bound)))
    while (h // f) * (w // f) > bound:
        f += 1
    h2, w2 = max(h // f, 2), max(w // f, 2)
    rows = np.linspace(0, h, h2 + 1).round().astype(np.int64)
    cols = np.linspace(0, w, w2 + 1).round().astype(np.int64)
    om = row_solid_angles(h, w)
    out = np.empty((h2, w2, env.shape[2]), np.float32)
    step = max(1, (1 << 22) // max(w * int(rows[1] - rows[0]), 1))  # output rows per block: ~4 M texels
    for i0 in range(0, h2, step):
        i1 = min(i0 + step, h2)
        block = env[rows[i0]:rows[i1]].astype(np.float64) * om[rows[i0]:rows[i1], None, None]
        by_row = np.add.reduceat(block, rows[i0:i1] - rows[i0], axis=0)  # (rows of output, W, 3)
        sums = np.add.reduceat(by_row, cols[:-1], axis=1)
        weight = np.add.reduceat(om[rows[i0]:rows[i1]], rows[i0:i1] - rows[i0])[:, None] * np.diff(cols)[None, :]
        out[i0:i1] = sums / weight[..., None]
    warnings.warn(f"{where}: the {w}×{h} environment map is reduced to {w2}×{h2} texels (solid-angle-weighted "
                  f"means of {f}×{f} blocks: its light is kept) to bound memory; at most {bound:,} texels are "
                  f"worked on (warp_sg.core.watchdog.MAX_ENV_WORK_TEXELS)", InputWarning, stacklevel=3)
    return out


def load_envmap(path, scale: float = 1.0) -> np.ndarray:
    """Read an equirectangular environment map as ``(H, W, 3)`` float32 radiance × ``scale``:
    OpenEXR (``R``, ``G``, ``B`` channels; extras such as ``A`` ignored) or Radiance RGBE ``.hdr``
    (:func:`warp_sg.core.image_io.read_hdr`, OpenCV).

    NaN/inf or negative texels, a grey-only EXR, a file of another format or an unreadable file
    raise :class:`ImageError` naming the file. A map larger than
    :data:`warp_sg.core.watchdog.MAX_ENV_WORK_TEXELS` is reduced (:func:`reduce_envmap`, one warning).
    """
    from warp_sg.core.image_io import exr_channel_names, is_hdr_file, read_exr, read_hdr

    path = Path(path)
    where = str(path)
    if not path.exists():
        raise ImageError("environment map file not found", where=where)
    try:
        with open(path, "rb") as f:
            magic = f.read(4)
    except OSError as e:
        raise ImageError(f"cannot open environment map ({e.strerror or e})", where=where) from None
    if magic == b"\x76\x2f\x31\x01" or is_hdr_file(path):
        from warp_sg.core.image_io import image_size

        h, w, _ = image_size(path)
        check_envmap_shape(h, w, where)  # from the header: a huge or stretched map is refused unread
    if magic == b"\x76\x2f\x31\x01":
        names = {n.rsplit(".", 1)[-1] for n in exr_channel_names(path)}
        if not {"R", "G", "B"} <= names:
            raise ImageError(
                f"environment map has channels [{', '.join(sorted(exr_channel_names(path)))}]; need R, G, B",
                where=where,
            )
        img = read_exr(path)[..., :3]
    elif is_hdr_file(path):
        img = read_hdr(path)
    else:
        raise ImageError("environment maps must be OpenEXR (.exr) or Radiance HDR (.hdr) files (linear radiance)",
                         where=where)
    s = float(scale)
    if not np.isfinite(s) or s < 0:
        raise ImageError(f"scale must be a finite non-negative number, got {scale}", where=where)
    env = validate_envmap(img, where=where)
    del img
    env = reduce_envmap(env, watchdog.MAX_ENV_WORK_TEXELS, where)
    return (env * np.float32(s)).astype(np.float32) if s != 1.0 else env


__all__ = [
    "load_envmap",
    "reduce_envmap",
    "validate_envmap",
    "check_envmap_shape",
    "ASPECT_RANGE",
    "MAX_RADIANCE",
    "dir_to_uv",
    "dir_to_texel",
    "uv_to_dir",
    "texel_directions",
    "row_solid_angles",
    "texel_solid_angles",
    "downsample_envmap",
    "rotation_matrix",
    "rotation_y",
    "rotate_envmap",
    "env_lookup_numpy",
    "wp_dir_to_uv",
    "wp_uv_to_dir",
    "env_lookup",
    "env_lookup_nearest",
]
