r"""The kernels that turn a vertex's visibility map into its signed angular distance field (steps 2–5
of :mod:`precompute.visibility.ssdf`): boundary seeds (:func:`seed_kernel`), jump flooding of
the nearest boundary direction (:func:`jfa_kernel`, Rong & Tan 2006: O(R² log R) per vertex),
the signed distance ``±arccos(d·seed)`` with the horizon as a boundary (:func:`signed_kernel`)
and the box downsampling to the stored resolution (:func:`downsample_kernel`).
"""
from __future__ import annotations

import math

import warp as wp

_HALF_PI = wp.constant(0.5 * math.pi)
#: "no boundary point yet": its dot product with any texel direction (z ≥ 1/(2Rr) > 1e-4) is
#: below −1, so every real boundary point wins over it, and the signed distance it gives is the
#: clamp π/2 (acos(−1) = π, then min with π/2): the same as no seed at all
NO_SEED = wp.constant(wp.vec3(0.0, 0.0, -1.0e4))



@wp.func
def _consider(d: wp.vec3, da: wp.vec3, best: wp.vec3, best_dot: float):
    m = wp.normalize(d + da)
    c = wp.dot(d, m)
    if c > best_dot:
        return m, c
    return best, best_dot


@wp.kernel
def seed_kernel(vis: wp.array2d(dtype=wp.uint8), dirs: wp.array(dtype=wp.vec3), R: int,
                 seeds: wp.array2d(dtype=wp.vec3)):
    """Nearest boundary midpoint among the 4-neighbour pairs of differing visibility (else
    :data:`NO_SEED`)."""
    k, tex = wp.tid()
    j = tex // R
    i = tex - j * R
    me = vis[k, tex]
    d = dirs[tex]
    best = NO_SEED
    best_dot = float(-2.0)
    if i > 0:
        if vis[k, tex - 1] != me:
            best, best_dot = _consider(d, dirs[tex - 1], best, best_dot)
    if i < R - 1:
        if vis[k, tex + 1] != me:
            best, best_dot = _consider(d, dirs[tex + 1], best, best_dot)
    if j > 0:
        if vis[k, tex - R] != me:
            best, best_dot = _consider(d, dirs[tex - R], best, best_dot)
    if j < R - 1:
        if vis[k, tex + R] != me:
            best, best_dot = _consider(d, dirs[tex + R], best, best_dot)
    seeds[k, tex] = best


@wp.kernel
def jfa_kernel(src: wp.array2d(dtype=wp.vec3), dirs: wp.array(dtype=wp.vec3), R: int, step: int,
                dst: wp.array2d(dtype=wp.vec3)):
    """One jump-flooding pass with the angular metric (largest dot product wins)."""
    k, tex = wp.tid()
    j = tex // R
    i = tex - j * R
    d = dirs[tex]
    best = src[k, tex]
    best_dot = wp.dot(d, best)  # NO_SEED's dot loses to every boundary point's (≥ −1)
    for dj in range(-1, 2):
        jj = j + dj * step
        if jj >= 0 and jj < R:
            for di in range(-1, 2):
                ii = i + di * step
                if ii >= 0 and ii < R and (di != 0 or dj != 0):
                    s = src[k, jj * R + ii]
                    c = wp.dot(d, s)
                    if c > best_dot:
                        best_dot = c
                        best = s
    dst[k, tex] = best


@wp.kernel
def signed_kernel(vis: wp.array2d(dtype=wp.uint8), seeds: wp.array2d(dtype=wp.vec3),
                   dirs: wp.array(dtype=wp.vec3), out: wp.array2d(dtype=float)):
    """Signed angular distance (eq. 23), horizon included, clamped to [−π/2, π/2]."""
    k, tex = wp.tid()
    d = dirs[tex]
    s = seeds[k, tex]
    dist = _HALF_PI
    if wp.length_sq(s) > 0.25:
        dist = wp.acos(wp.clamp(wp.dot(d, s), -1.0, 1.0))
    if vis[k, tex] != wp.uint8(0):
        out[k, tex] = wp.min(wp.min(dist, wp.asin(wp.clamp(d[2], 0.0, 1.0))), _HALF_PI)
    else:
        out[k, tex] = -wp.min(dist, _HALF_PI)


@wp.kernel
def downsample_kernel(src: wp.array2d(dtype=float), Rs: int, f: int, dst: wp.array2d(dtype=float)):
    """Box filter f×f: (B, (Rs·f)²) → (B, Rs²)."""
    k, tex = wp.tid()
    j = tex // Rs
    i = tex - j * Rs
    Rh = Rs * f
    acc = float(0.0)
    for dj in range(f):
        for di in range(f):
            acc += src[k, (j * f + dj) * Rh + i * f + di]
    dst[k, tex] = acc / float(f * f)


def jfa_steps(R: int) -> list[int]:
    steps = []
    s = 1
    while s * 2 < R:
        s *= 2
    while s >= 1:
        steps.append(s)
        s //= 2
    return steps + [2, 1] if R > 2 else steps


__all__ = ["seed_kernel", "jfa_kernel", "signed_kernel", "downsample_kernel", "jfa_steps", "NO_SEED"]
