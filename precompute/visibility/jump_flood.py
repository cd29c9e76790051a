r"""The kernels that turn a vertex's visibility map into its signed angular distance field (steps 2–5
of :mod:`precompute.visibility.ssdf`): boundary seeds (:func:`seed_kernel`), jump flooding of
the nearest boundary direction (:func:`jfa_texel_kernel`, Rong & Tan 2006: O(R² log R) per vertex),
the signed distance ``±arccos(d·seed)`` with the horizon as a boundary (:func:`signed_kernel`)
and the box downsampling to the stored resolution (:func:`downsample_kernel`).

**Coarse-to-fine search** (when the rays are cast at ``Rr = f·R``, f ≥ 2, the default 64² → 32²):
the flooding runs on the stored ``R × R`` grid instead of the ray grid, over *seed texels*:

1. :func:`coarse_seed_kernel`: each coarse cell keeps the fine texel, among its ``f × f``, whose
   boundary seed is nearest the cell's own direction (−1: none has a seed);
2. :func:`jfa_texel_kernel`: jump flooding of those texel indices on the coarse grid (steps R/2 … 1,
   2, 1), compared by the seed each index points at;
3. :func:`fine_seed_kernel`: each fine texel takes the best of its own seed, the seeds of the 3×3
   coarse cells around its own, and the fine seeds within ``f/2`` texels of the best one's texel
   (the kept seeds are ``f`` texels apart along a boundary; the true nearest is within ``f/2`` of one).

It reads ``(log R + 2)·9·R² + (10 + (f+1)²)·Rr²`` seeds instead of ``(log Rr + 2)·9·Rr²`` (at 64² → 32²:
1.5× less CPU per vertex, measured in docs/benchmarks.md), at a mean error of 3·10⁻⁴ rad against
the exhaustive eq. 23 (plain flooding at 64²: 9·10⁻⁵ rad; both far below the error of the 64² rays
themselves against a 256² truth, 0.007–0.013 rad; ``tests/test_ssdf.py``).
"""
from __future__ import annotations

import math

import warp as wp

_HALF_PI = wp.constant(0.5 * math.pi)
#: "no boundary point yet": its dot product with any texel direction (z ≥ 1/(2Rr) > 1e-4) is
#: below −1, so every real boundary point wins over it, and the signed distance it gives is the
#: clamp π/2 (acos(−1) = π, then min with π/2): the same as no seed at all
NO_SEED = wp.constant(wp.vec3(0.0, 0.0, -1.0e4))



_ivec9 = wp.types.vector(length=9, dtype=int)


@wp.func
def _consider(d: wp.vec3, da: wp.vec3, best: wp.vec3, best_dot: float):
    m = wp.normalize(d + da)
    c = wp.dot(d, m)
    if c > best_dot:
        return m, c
    return best, best_dot


@wp.func
def _run_start(u: int, run: int, R: int):
    """(row, first column) of thread ``u``'s run of ``run`` cells on an R-wide grid (``run``
    divides R: the run lies in one row; :func:`run_length`)."""
    j = (u * run) // R
    return j, u * run - j * R


@wp.kernel(enable_backward=False)
def seed_kernel(vis: wp.array2d(dtype=wp.uint8), dirs: wp.array(dtype=wp.vec3), R: int, run: int,
                seeds: wp.array2d(dtype=wp.vec3)):
    """Nearest boundary midpoint among the 4-neighbour pairs of differing visibility (else
    :data:`NO_SEED`); thread ``(k, u)`` does texels ``u·run … u·run + run − 1`` (:func:`run_length`)."""
    k, u = wp.tid()
    j, i0 = _run_start(u, run, R)
    for r in range(run):
        i = i0 + r
        tex = j * R + i
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


@wp.func
def _signed(visible: wp.uint8, d: wp.vec3, s: wp.vec3) -> float:
    """Signed angular distance (eq. 23) of a texel of direction ``d`` whose nearest boundary point
    is ``s``, the horizon included, clamped to [−π/2, π/2]."""
    dist = _HALF_PI
    if wp.length_sq(s) > 0.25:
        dist = wp.acos(wp.clamp(wp.dot(d, s), -1.0, 1.0))
    if visible != wp.uint8(0):
        return wp.min(wp.min(dist, wp.asin(wp.clamp(d[2], 0.0, 1.0))), _HALF_PI)
    return -wp.min(dist, _HALF_PI)


@wp.kernel(enable_backward=False)
def signed_kernel(vis: wp.array2d(dtype=wp.uint8), seeds: wp.array2d(dtype=wp.vec3),
                   dirs: wp.array(dtype=wp.vec3), out: wp.array2d(dtype=float)):
    """Signed angular distance (eq. 23), horizon included, clamped to [−π/2, π/2]."""
    k, tex = wp.tid()
    out[k, tex] = _signed(vis[k, tex], dirs[tex], seeds[k, tex])


@wp.kernel(enable_backward=False)
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


@wp.kernel(enable_backward=False)
def coarse_seed_kernel(seeds: wp.array2d(dtype=wp.vec3), cdirs: wp.array(dtype=wp.vec3), Rc: int, f: int,
                       out: wp.array2d(dtype=int)):
    """Coarse cell ``c`` of the ``Rc × Rc`` grid: the fine texel (of its ``f × f``) whose seed is nearest
    the cell's direction ``cdirs[c]``, or −1 when none of them holds a seed (:data:`NO_SEED`'s dot
    product with any direction is below −2)."""
    k, c = wp.tid()
    cj = c // Rc
    ci = c - cj * Rc
    Rf = Rc * f
    d = cdirs[c]
    best = int(-1)
    best_dot = float(-2.0)
    for dj in range(f):
        for di in range(f):
            t = (cj * f + dj) * Rf + ci * f + di
            x = wp.dot(d, seeds[k, t])
            if x > best_dot:
                best_dot = x
                best = t
    out[k, c] = best


@wp.func
def _seed_dot(seeds: wp.array2d(dtype=wp.vec3), k: int, t: int, d: wp.vec3) -> float:
    """``d · seed`` of fine texel ``t`` (−2 for the empty index −1)."""
    if t < 0:
        return -2.0
    return wp.dot(d, seeds[k, t])


@wp.kernel(enable_backward=False)
def jfa_texel_kernel(src: wp.array2d(dtype=int), seeds: wp.array2d(dtype=wp.vec3), cdirs: wp.array(dtype=wp.vec3),
                     Rc: int, step: int, run: int, dst: wp.array2d(dtype=int)):
    """One jump-flooding pass on the coarse grid over seed-texel indices (largest dot product of
    the seed an index points at wins); thread ``(k, u)`` does cells ``u·run … u·run + run − 1``."""
    k, u = wp.tid()
    j, i0 = _run_start(u, run, Rc)
    for r in range(run):
        i = i0 + r
        c = j * Rc + i
        d = cdirs[c]
        best = src[k, c]
        best_dot = _seed_dot(seeds, k, best, d)
        for dj in range(-1, 2):
            jj = j + dj * step
            if jj >= 0 and jj < Rc:
                for di in range(-1, 2):
                    ii = i + di * step
                    if ii >= 0 and ii < Rc and (di != 0 or dj != 0):
                        t = src[k, jj * Rc + ii]
                        x = _seed_dot(seeds, k, t, d)
                        if x > best_dot:
                            best_dot = x
                            best = t
        dst[k, c] = best


@wp.kernel(enable_backward=False)
def seed_at_kernel(seeds: wp.array2d(dtype=wp.vec3), idx: wp.array2d(dtype=int), out: wp.array2d(dtype=wp.vec3)):
    """The seed each texel's index points at (:data:`NO_SEED` for the empty index −1): the result of
    flooding on the ray grid itself."""
    k, t = wp.tid()
    src = idx[k, t]
    if src >= 0:
        out[k, t] = seeds[k, src]
    else:
        out[k, t] = NO_SEED


@wp.kernel(enable_backward=False)
def fine_seed_kernel(seeds: wp.array2d(dtype=wp.vec3), coarse: wp.array2d(dtype=int), dirs: wp.array(dtype=wp.vec3),
                     Rf: int, f: int, out: wp.array2d(dtype=wp.vec3)):
    """Fine texel ``t``'s nearest boundary point: the best of its own seed, the seeds the 3×3 coarse
    cells around its cell hold, and the fine seeds within ``f/2`` texels of the best of those."""
    k, t = wp.tid()
    out[k, t] = _fine_seed(seeds, coarse, dirs, k, t, Rf, f)


@wp.kernel(enable_backward=False)
def fine_signed_kernel(seeds: wp.array2d(dtype=wp.vec3), coarse: wp.array2d(dtype=int), vis: wp.array2d(dtype=wp.uint8),
                       dirs: wp.array(dtype=wp.vec3), Rf: int, f: int, out: wp.array2d(dtype=float)):
    """:func:`fine_seed_kernel`, :func:`signed_kernel` and :func:`downsample_kernel` in one pass:
    stored cell ``c`` (of the ``Rf/f`` grid) is the mean of the signed distances of its ``f × f``
    ray texels, each to its nearest boundary point — the same values, summed in the same order,
    without the two ``(B, Rf²)`` arrays in between."""
    k, c = wp.tid()
    Rc = Rf / f
    cj = c // Rc
    ci = c - cj * Rc
    # the seed indices of the 3×3 coarse cells around c (−1: outside the grid, or none), read once
    # for the f×f texels (in fine_seed_kernel's order, so each texel compares the same candidates)
    nb = _ivec9()
    for q in range(9):
        jj = cj + q / 3 - 1
        ii = ci + q - (q / 3) * 3 - 1
        st = int(-1)
        if jj >= 0 and jj < Rc and ii >= 0 and ii < Rc:
            st = coarse[k, jj * Rc + ii]
        nb[q] = st
    acc = float(0.0)
    for dj in range(f):
        for di in range(f):
            t = (cj * f + dj) * Rf + ci * f + di
            d = dirs[t]
            best = seeds[k, t]
            best_dot = wp.dot(d, best)
            src = int(-1)
            for q in range(9):
                st = nb[q]
                if st >= 0:
                    x = wp.dot(d, seeds[k, st])
                    if x > best_dot:
                        best_dot = x
                        best = seeds[k, st]
                        src = st
            acc += _signed(vis[k, t], d, _fine_window(seeds, k, d, src, best, best_dot, Rf, f))
    out[k, c] = acc / float(f * f)


@wp.func
def _fine_seed(seeds: wp.array2d(dtype=wp.vec3), coarse: wp.array2d(dtype=int), dirs: wp.array(dtype=wp.vec3),
               k: int, t: int, Rf: int, f: int) -> wp.vec3:
    """The nearest boundary point of fine texel ``t`` of vertex ``k`` (:func:`fine_seed_kernel`)."""
    j = t // Rf
    i = t - j * Rf
    Rc = Rf / f
    cj = j / f
    ci = i / f
    d = dirs[t]
    best = seeds[k, t]
    best_dot = wp.dot(d, best)
    src = int(-1)
    for dj in range(-1, 2):
        jj = cj + dj
        if jj >= 0 and jj < Rc:
            for di in range(-1, 2):
                ii = ci + di
                if ii >= 0 and ii < Rc:
                    st = coarse[k, jj * Rc + ii]
                    if st >= 0:  # (−1: no seed anywhere, a uniform map; never read seeds[k, −1])
                        x = wp.dot(d, seeds[k, st])
                        if x > best_dot:
                            best_dot = x
                            best = seeds[k, st]
                            src = st
    return _fine_window(seeds, k, d, src, best, best_dot, Rf, f)


@wp.func
def _fine_window(seeds: wp.array2d(dtype=wp.vec3), k: int, d: wp.vec3, src: int, best: wp.vec3, best_dot: float,
                 Rf: int, f: int) -> wp.vec3:
    """``best`` or a nearer fine seed within ``f/2`` texels of fine texel ``src`` (−1: none)."""
    if src >= 0:
        r = wp.max(f / 2, 1)
        sj = src // Rf
        si = src - sj * Rf
        for dj in range(-r, r + 1):
            jj = sj + dj
            if jj >= 0 and jj < Rf:
                for di in range(-r, r + 1):
                    ii = si + di
                    if ii >= 0 and ii < Rf:
                        s = seeds[k, jj * Rf + ii]
                        x = wp.dot(d, s)
                        if x > best_dot:
                            best_dot = x
                            best = s
    return best


def run_length(R: int, device) -> int:
    """Texels (or cells) per thread of :func:`seed_kernel` and :func:`jfa_texel_kernel` on a grid
    ``R`` wide: a whole row on the CPU, where a launch runs its threads one after the other and a
    thread that walks a row keeps the arrays' addresses and its neighbours' cells at hand (the
    flooding passes 40 % less CPU, measured in docs/benchmarks.md "Cold path"); one on a GPU,
    whose threads run side by side. The results are the same either way."""
    return int(R) if wp.get_device(device).is_cpu else 1


def jfa_steps(R: int) -> list[int]:
    steps = []
    s = 1
    while s * 2 < R:
        s *= 2
    while s >= 1:
        steps.append(s)
        s //= 2
    return steps + [2, 1] if R > 2 else steps


__all__ = ["seed_kernel", "signed_kernel", "downsample_kernel", "jfa_steps", "run_length", "NO_SEED",
           "coarse_seed_kernel", "jfa_texel_kernel", "seed_at_kernel", "fine_seed_kernel",
           "fine_signed_kernel"]
