r"""The procedural all-frequency sky: an analytic radiance function of direction (:func:`sky_radiance`)
and its equirectangular map (:func:`procedural_sky`, each texel the mean over sub-cells uniform in
cos θ and φ), the ``procedural = "sky"`` environment of scene files. The map convention (direction
↔ uv) is :mod:`warp_sg.scene.envmap`'s.
"""
from __future__ import annotations

import numpy as np

from warp_sg.scene.envmap import uv_to_dir


def _normalize(v):
    v = np.asarray(v, dtype=np.float64)
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n == 0:
        raise ValueError(f"direction must be a non-zero vector, got {v}")
    return v / n


def sky_radiance(
    dirs,
    *,
    sun_direction=(0.45, 0.55, -0.70),
    sun_angular_radius: float = 0.035,
    sun_intensity: float = 400.0,
    sun_color=(1.0, 0.92, 0.8),
    zenith_color=(0.22, 0.40, 0.85),
    horizon_color=(0.80, 0.86, 0.95),
    ground_color=(0.30, 0.26, 0.22),
    sky_intensity: float = 1.0,
    halo: float = 0.25,
    horizon_blur: float = 0.02,
) -> np.ndarray:
    """Analytic radiance of :func:`procedural_sky` for unit directions ``(..., 3)`` (float64).

    ``sky(y) = sky_intensity · lerp(horizon, zenith, √max(y,0))`` above the horizon, ``ground`` below,
    blended over ``|y| < horizon_blur``; plus a halo ``halo · sky_intensity · sun_color · exp(−γ²/(2·0.15²))``
    (γ = angle to the sun, above the horizon), plus the sun disk of constant radiance ``sun_intensity · sun_color``
    within ``sun_angular_radius`` of ``sun_direction``.
    """
    d = np.asarray(dirs, dtype=np.float64)
    y = d[..., 1:2]
    t = np.sqrt(np.clip(y, 0.0, 1.0))
    sky = sky_intensity * ((1 - t) * np.asarray(horizon_color) + t * np.asarray(zenith_color))
    g = np.asarray(ground_color, dtype=np.float64)
    if horizon_blur > 0:
        w = np.clip(0.5 + 0.5 * y / horizon_blur, 0.0, 1.0)
    else:
        w = (y >= 0).astype(np.float64)
    w = w * w * (3 - 2 * w)
    out = w * sky + (1 - w) * g
    s = _normalize(sun_direction)
    cos_g = d @ s
    ang = np.arccos(np.clip(cos_g, -1.0, 1.0))[..., None]
    sc = np.asarray(sun_color, dtype=np.float64)
    if halo > 0:
        out = out + halo * sky_intensity * sc * np.exp(-0.5 * (ang / 0.15) ** 2) * (y > -horizon_blur)
    out = out + sun_intensity * sc * (ang <= sun_angular_radius)
    return out


def procedural_sky(
    width: int = 256,
    height: int = 128,
    *,
    sun_direction=(0.45, 0.55, -0.70),
    sun_angular_radius: float = 0.035,
    sun_intensity: float = 400.0,
    sun_color=(1.0, 0.92, 0.8),
    zenith_color=(0.22, 0.40, 0.85),
    horizon_color=(0.80, 0.86, 0.95),
    ground_color=(0.30, 0.26, 0.22),
    sky_intensity: float = 1.0,
    halo: float = 0.25,
    horizon_blur: float = 0.02,
    supersample: int = 4,
) -> np.ndarray:
    """An all-frequency test sky as a ``(height, width, 3)`` float32 equirectangular map.

    A smooth zenith→horizon gradient, a darker ground, a soft halo and a small, very bright sun
    disk (default radius 0.035 rad ≈ 2°, radiance 400: a sharp, high-energy feature next to a
    smooth low-frequency one). Each texel is the average of the analytic :func:`sky_radiance`
    over ``supersample²`` equal-solid-angle sub-cells (uniform in φ and cos θ), i.e. the box
    filter of the analytic sky. No downloads.
    """
    width, height, s = int(width), int(height), int(supersample)
    if width < 2 or height < 2 or s < 1:
        raise ValueError(f"procedural_sky needs width, height >= 2 and supersample >= 1, got {width}x{height}, {s}")
    kw = dict(
        sun_direction=sun_direction,
        sun_angular_radius=sun_angular_radius,
        sun_intensity=sun_intensity,
        sun_color=sun_color,
        zenith_color=zenith_color,
        horizon_color=horizon_color,
        ground_color=ground_color,
        sky_intensity=sky_intensity,
        halo=halo,
        horizon_blur=horizon_blur,
    )
    # sub-cell centres uniform in cos θ within each row and uniform in φ within each column
    theta_edges = np.pi * np.arange(height + 1) / height
    c0 = np.cos(theta_edges[:-1])[:, None]
    c1 = np.cos(theta_edges[1:])[:, None]
    f = (np.arange(s) + 0.5) / s
    cos_t = (c0 + (c1 - c0) * f[None, :]).reshape(-1)  # (H*s,)
    u = ((np.arange(width)[:, None] + f[None, :]) / width).reshape(-1)  # (W*s,)
    v = np.arccos(np.clip(cos_t, -1, 1)) / np.pi
    out = np.empty((height, width, 3), dtype=np.float32)
    rows_per_chunk = max(1, (1 << 20) // (width * s * s))
    for r0 in range(0, height, rows_per_chunk):  # chunks bound the memory; vectorised inside
        r1 = min(height, r0 + rows_per_chunk)
        d = uv_to_dir(u[None, :], v[r0 * s : r1 * s, None])
        rad = sky_radiance(d, **kw)
        out[r0:r1] = rad.reshape(r1 - r0, s, width, s, 3).mean(axis=(1, 3))
    return out


__all__ = ["procedural_sky", "sky_radiance"]
