r"""Separate sharp peaks (a sun) from an environment map and treat them as directional lights.

A small, very bright source is where the SG approximations are weakest: the environment's SG
mixture spends its sharpest lobe on it, the ΓL pyramid blurs it to its finest level, and the
single clamped-cosine lobe gets its irradiance wrong by up to 17 %. Treated as a directional light
(``warp_sg.lights.DirectionalLight``: a cone of angular radius r and irradiance E) it is shaded with
the exact BRDF and cosine, and only its visibility comes from the SSDF (DESIGN.md "Exact where it
is cheap"). The broad remainder stays in the map for the SG mixture and ΓL.

:func:`extract_peaks` (map frame, Mitsuba's equirectangular convention, solid angle per texel Ω):

1. ``T = contrast × median`` of the texel luminance; a peak is the connected region (4-neighbours,
   wrapping in u) around the brightest texel above ``T``, grown by ``grow`` texels to take the
   filtered rim of the disk;
2. the background under the peak is the per-channel median of the ring of texels around the grown
   region; the peak's radiance is the excess ``max(L − L_bg, 0)``, and the residual map keeps
   ``min(L, L_bg)`` there (the energy ``Σ L Ω`` of map + peaks is kept exactly);
3. the peak becomes a cone: direction ``normalize(Σ w d)``, irradiance ``E = Σ excess Ω`` (RGB; the
   irradiance of the cone on a surface facing it), angular radius from the second moment — a
   uniform cap of radius r has ``E[1 − cos γ] = (1 − cos r)/2`` — at least half a texel;
4. repeat while the next peak holds ≥ ``min_fraction`` of the map's luminance power and its
   region is smaller than ``max_solid_angle`` (a broad bright region is no peak), up to ``max_peaks``.

Returns ``(residual (H, W, 3) float32, peaks)``, ``peaks`` a list of :class:`Peak`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_sg.envmap import texel_directions, texel_solid_angles

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@dataclass(frozen=True)
class Peak:
    """A sharp source of the map: ``direction`` (unit, map frame, towards the source), angular
    ``radius`` (rad), ``irradiance`` E (RGB) on a surface facing it, ``solid_angle`` of its texels."""

    direction: np.ndarray
    radius: float
    irradiance: np.ndarray
    solid_angle: float


def _label_around(mask: np.ndarray, seed: tuple[int, int]) -> np.ndarray:
    """Connected component of ``mask`` containing ``seed`` (4-neighbours, wrapping in u)."""
    from scipy import ndimage

    h, w = mask.shape
    shift = w // 2 - seed[1]  # put the seed in the middle column so the wrap cannot cut its region
    m = np.roll(mask, shift, axis=1)
    lab, _ = ndimage.label(m)
    comp = lab == lab[seed[0], w // 2]
    return np.roll(comp, -shift, axis=1)


def _dilate(mask: np.ndarray, n: int) -> np.ndarray:
    from scipy import ndimage

    if n <= 0:
        return mask
    w = mask.shape[1]
    pad = np.concatenate([mask[:, -n:], mask, mask[:, :n]], axis=1)
    return ndimage.binary_dilation(pad, iterations=n)[:, n:n + w]


def extract_peaks(env, *, max_peaks: int = 4, contrast: float = 30.0, min_fraction: float = 0.02,
                  max_solid_angle: float = 0.05, grow: int = 2):
    """Split ``env`` (H, W, 3) into a residual map and up to ``max_peaks`` sharp :class:`Peak` s
    (see the module docstring). ``max_peaks = 0`` returns the map unchanged."""
    L = np.array(env, dtype=np.float64, copy=True)
    h, w = L.shape[:2]
    om = texel_solid_angles(h, w)
    dirs = texel_directions(h, w)
    lum = L @ LUMINANCE
    total = float(np.sum(lum * om))
    peaks: list[Peak] = []
    if max_peaks <= 0 or total <= 0:
        return L.astype(np.float32), peaks
    thresh = contrast * max(float(np.median(lum)), 1e-12 * float(lum.max()))
    for _ in range(max_peaks):
        lum = L @ LUMINANCE
        j = np.unravel_index(int(np.argmax(lum)), lum.shape)
        if lum[j] <= thresh:
            break
        core = _label_around(lum > thresh, j)
        region = _dilate(core, grow)
        ring = _dilate(region, 2) & ~region
        bg = np.median(L[ring], axis=0) if np.any(ring) else np.zeros(3)
        excess = np.maximum(L[region] - bg, 0.0)
        o = om[region][:, None]
        E = np.sum(excess * o, axis=0)
        if float(E @ LUMINANCE) < min_fraction * total or float(np.sum(om[region])) > max_solid_angle:
            break
        wts = (excess @ LUMINANCE) * om[region]
        d = np.sum(dirs[region] * wts[:, None], axis=0)
        d /= np.linalg.norm(d)
        one_minus_cos = float(np.sum(wts * (1.0 - dirs[region] @ d)) / np.sum(wts))
        half_texel = 0.5 * np.pi / h
        r = max(float(np.arccos(np.clip(1.0 - 2.0 * one_minus_cos, -1.0, 1.0))), half_texel)
        L[region] = np.minimum(L[region], bg)
        peaks.append(Peak(direction=d, radius=r, irradiance=E, solid_angle=float(np.sum(om[region]))))
    return L.astype(np.float32), peaks


__all__ = ["Peak", "extract_peaks"]
