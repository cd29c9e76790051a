r"""Separate sharp peaks (a sun, lamps) from an environment map and treat them as directional lights.

A small, very bright source is where the SG approximations are weakest: the environment's SG
mixture spends its sharpest lobe on it, the ΓL pyramid blurs it to its finest level, and the
single clamped-cosine lobe gets its irradiance wrong by up to 17 %. Treated as a directional light
(``warp_sg.scene.lights.DirectionalLight``: a cone of angular radius r and irradiance E) it is shaded with
the exact BRDF and cosine, and only its visibility comes from the SSDF (docs/rendering.md, "Exact
where it is cheap"). The broad remainder stays in the map for the SG mixture and ΓL.

Real skies are not procedural skies: a photographed sun is a 1e4–1e5 core inside a halo that is
itself far above the map's median (Poly Haven's ``pedestrian_overpass``: 55 % of the map's power
within 0.5° of the sun, the halo from 0.5° to 20° another 10 %), a night map has several lamps, a
studio map may be black but for one spot (median 0). A threshold relative to the median alone
takes the sun *and* its halo, a region too large to be a light. So each peak's **core** is found
relative to its own brightness:

:func:`extract_peaks` (map frame, Mitsuba's equirectangular convention, solid angle per texel Ω):

1. ``floor = contrast × median`` of the texel luminance (``1e-12 × max`` where the median is 0);
   the candidate is the brightest texel, ``top``; none brighter than ``floor``: stop;
2. its core is the connected region (4-neighbours, wrapping in u) around it of the texels above
   ``T = max(floor, relative × top)`` (default 1 % of its own peak: a Gaussian-blurred disk keeps
   99 % of its power, a halo stays outside); a core larger than ``max_solid_angle`` (default
   0.005 sr, a cap of 2.3°; at least four texels of the map's equator) raises ``T`` by factors of 2
   up to ``top/2``, and a core still too large is no peak (a bright broad area, the soft sun of a
   hazy sunrise: the irradiance table and the per-vertex quadrature of its visibility hold it
   exactly, where a light would replace its shape by a cap's); the core is then grown by ``grow``
   texels to take the filtered rim of the disk;
3. the background under the region is the per-channel median ``b`` of the ring of texels around
   it; the peak's radiance is the excess ``max(L − b, 0)``, and the residual keeps ``min(L, b)`` there, so map +
   peaks is the original map texel by texel (``b`` is rounded to float32 first: ``min(L, b) +
   max(L − b, 0) = L`` holds exactly for the float32 map);
4. the peak becomes a cone: direction ``normalize(Σ w d)``, irradiance ``E = Σ excess Ω`` (RGB; the
   irradiance of the cone on a surface facing it), angular radius from the second moment — a
   uniform cap of radius r has ``E[1 − cos γ] = (1 − cos r)/2`` — at least half a texel;
5. repeat while the next peak holds ≥ ``min_fraction`` of the map's luminance power, up to
   ``max_peaks``.

Cost: the whole map is read twice (luminance, median); each peak then works in the band of rows
its largest allowed core can reach (plus the ring), so a one-texel sun in a 16k × 8k map costs a
fraction of a second per peak, not a pass over the map.

Returns ``(residual (H, W, 3) float32, peaks)``, ``peaks`` a list of :class:`Peak`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from warp_sg.core.image_io import LUMINANCE
from warp_sg.scene.envmap import row_solid_angles, uv_to_dir

#: texels of the ring around a grown peak whose median is the background under it
RING = 2


@dataclass(frozen=True)
class Peak:
    """A sharp source of the map: ``direction`` (unit, map frame, towards the source), angular
    ``radius`` (rad), ``irradiance`` E (RGB) on a surface facing it, ``solid_angle`` of its texels."""

    direction: np.ndarray
    radius: float
    irradiance: np.ndarray
    solid_angle: float


def _dilate(mask: np.ndarray, n: int) -> np.ndarray:
    """4-neighbour dilation by ``n`` texels, wrapping in u (columns), clipped at the poles (rows)."""
    from scipy import ndimage

    if n <= 0:
        return mask
    w = mask.shape[1]
    n_wrap = min(n, w)
    pad = np.concatenate([mask[:, -n_wrap:], mask, mask[:, :n_wrap]], axis=1)
    return ndimage.binary_dilation(pad, iterations=n)[:, n_wrap:n_wrap + w]


def _component(mask: np.ndarray, seed: tuple[int, int]) -> np.ndarray:
    """Connected component of ``mask`` containing ``seed`` (4-neighbours). ``mask``'s seed column
    sits in the middle of its columns (the caller rolled it there), so u's wrap cannot cut it."""
    from scipy import ndimage

    lab, _ = ndimage.label(mask)
    return lab == lab[seed]


class _Band:
    """The rows ``r0:r1`` of the map around a seed, rolled in u so that the seed's column is in the
    middle: every texel a peak around the seed may touch (its core, growth and ring)."""

    def __init__(self, lum: np.ndarray, seed: tuple[int, int], rows: int):
        h, w = lum.shape
        self.r0, self.r1 = max(0, seed[0] - rows), min(h, seed[0] + rows + 1)
        self.shift = w // 2 - seed[1]
        self.seed = (seed[0] - self.r0, w // 2)
        self.h = h
        self.lum = np.roll(lum[self.r0:self.r1], self.shift, axis=1)

    def touches_edge(self, mask: np.ndarray) -> bool:
        """Whether ``mask`` reaches a band row that is not the map's first or last row (the region
        may go on beyond the band)."""
        return bool((self.r0 > 0 and mask[0].any()) or (self.r1 < self.h and mask[-1].any()))

    def map_index(self, mask: np.ndarray):
        """(rows, cols) of the map's texels under ``mask`` (band coordinates)."""
        r, c = np.nonzero(mask)
        w = mask.shape[1]
        return r + self.r0, (c - self.shift) % w


def _median_luminance(lum: np.ndarray, samples: int = 1 << 20) -> float:
    """Median texel luminance (of an evenly strided sample of at most ``samples`` texels: a
    threshold, not a statistic to report)."""
    flat = lum.reshape(-1)
    flat = flat[::max(1, -(-flat.size // samples))]
    return float(np.median(flat))


def extract_peaks(env, *, max_peaks: int = 8, contrast: float = 30.0, min_fraction: float = 0.01,
                  max_solid_angle: float = 0.005, relative: float = 0.01, grow: int = 2):
    """Split ``env`` (H, W, 3) into a residual map and up to ``max_peaks`` sharp :class:`Peak` s
    (see the module docstring). ``max_peaks = 0`` returns the map unchanged."""
    res = np.array(env, dtype=np.float32, copy=True)
    h, w = res.shape[:2]
    peaks: list[Peak] = []
    if max_peaks <= 0 or h == 0 or w == 0:
        return res, peaks
    om_row = row_solid_angles(h, w)
    lum = (res.astype(np.float64) @ LUMINANCE) if res.size <= 1 << 22 else _luminance_rows(res)
    total = float(np.sum(lum.sum(axis=1) * om_row))
    if not total > 0:
        return res, peaks
    top_all = float(lum.max())
    floor = contrast * max(_median_luminance(lum), 1e-12 * top_all)
    # the largest core allowed, and the rows around the seed it (grown, with its ring) can reach
    max_core = max(float(max_solid_angle), 4.0 * float(om_row[h // 2]))
    cap = math.acos(max(-1.0, 1.0 - max_core / (2.0 * math.pi)))
    band_rows = int(math.ceil(cap / (math.pi / h))) + grow + RING + 2
    half_texel = 0.5 * math.pi / h
    for _ in range(max_peaks):
        j = np.unravel_index(int(np.argmax(lum)), lum.shape)
        top = float(lum[j])
        if not top > floor:
            break
        band = _Band(lum, (int(j[0]), int(j[1])), band_rows)
        om_band = om_row[band.r0:band.r1][:, None]
        t = max(floor, relative * top)
        while True:
            core = _component(band.lum > t, band.seed)
            small = float(np.sum(core * om_band)) <= max_core and not band.touches_edge(core)
            if small or t >= 0.5 * top:
                break
            t = min(2.0 * t, 0.5 * top)
        if not small:
            break  # the brightest region left is broad: no more peaks
        region = _dilate(core, grow)
        ring = _dilate(region, RING) & ~region
        rr, cc = band.map_index(region)
        qr, qc = band.map_index(ring)
        L = res[rr, cc].astype(np.float64)
        bg = (np.median(res[qr, qc], axis=0) if len(qr) else np.zeros(3)).astype(np.float32).astype(np.float64)
        excess = np.maximum(L - bg, 0.0)
        o = om_row[rr]
        E = excess.T @ o
        if float(E @ LUMINANCE) < min_fraction * total:
            break
        wts = (excess @ LUMINANCE) * o
        dirs = uv_to_dir((cc + 0.5) / w, (rr + 0.5) / h)
        d = wts @ dirs
        d /= np.linalg.norm(d)
        one_minus_cos = float(np.sum(wts * (1.0 - dirs @ d)) / np.sum(wts))
        r = max(math.acos(min(max(1.0 - 2.0 * one_minus_cos, -1.0), 1.0)), half_texel)
        res[rr, cc] = np.minimum(L, bg).astype(np.float32)
        lum[rr, cc] = res[rr, cc].astype(np.float64) @ LUMINANCE
        peaks.append(Peak(direction=d, radius=r, irradiance=E, solid_angle=float(np.sum(o))))
    return res, peaks


def _luminance_rows(env: np.ndarray, rows: int = 256) -> np.ndarray:
    """Texel luminance (float64) of a large map, computed in row blocks (bounded temporaries)."""
    out = np.empty(env.shape[:2], np.float64)
    for r0 in range(0, env.shape[0], rows):
        out[r0:r0 + rows] = env[r0:r0 + rows].astype(np.float64) @ LUMINANCE
    return out


__all__ = ["Peak", "extract_peaks"]
