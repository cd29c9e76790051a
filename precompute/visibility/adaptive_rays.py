r"""Binary hemisphere visibility with fewer rays: coarse first, refined where the visibility changes.

The SSDF (eq. 23) needs each vertex's binary visibility ``V(j, i)`` on the ``Rr × Rr`` concentric
map (:mod:`precompute.visibility.rays`). Cast at every texel, that is ``Rr²`` rays per vertex (4096 at
the default 64²), most of them inside large regions of uniform visibility. Here the map is built
level by level, on grids of ``s × s`` cells of ``f = Rr / s`` texels each (``s = Rr/4, Rr/2, Rr``):

1. **coarse level** (``s₀ = Rr / 4`` by default): one ray per cell, at texel
   ``(j f + f/2, i f + f/2)``, with its **hit distance** (:func:`precompute.visibility.rays.ray_hit_distance`);
2. **the horizon ring** (:mod:`precompute.visibility.horizon_ring`): the texels of the map's outermost row and column (the directions just
   above the horizon, ``4 (Rr − 1)`` texels; the grid's visibility test reads them, not their hit
   distances). A vertex on a curved surface sees a strip one
   texel wide there that no coarse sample meets; it is a visibility boundary the SSDF needs. The
   ring is a 1-D map of its own, sampled like the grid: every ``RING_STEP``-th texel (4: one per
   coarse cell side, closest hit) first, then its segments are halved (any hit for the last
   halving) down to single texels where
   the samples around them (the segment's two ends and the next sample on either side) disagree
   in visibility or their hit distances differ by more than ``depth_ratio`` (as in step 3); a
   texel of a segment that is not halved takes the segment's value (not counted as known: a
   marked cell of the grid casts it in step 4). The strip runs along the ring, so it is found by
   its ends; what this can miss is an occluder crossing the horizon narrower than ``RING_STEP``
   ring texels between two samples that agree (measured: 2 texels on 2 of 400 vertices of the
   scanned head). At 64² rays the ring costs about 100 rays per vertex instead of 252;
3. **marking**: a cell is refined when, over its 3×3 neighbourhood of cells, the known samples
   (cell samples and ring texels) disagree in visibility, or the hit distances of the blocked
   ones differ by more than a factor ``depth_ratio`` (default 3): a depth discontinuity is where a
   gap between two surfaces can hide between samples (a slit behind an ear, a handle);
4. **refinement**: each child cell of a marked cell casts its own ray (a texel already cast at a
   coarser level or on the ring is reused); children of unmarked cells inherit the parent's sample.
   Steps 3–4 repeat until ``s = Rr``, where a child is one texel. On that last level a marked
   cell casts all four texels (``last="block"``, the default); ``last="bracket"`` casts its own
   sample and, of its other texels, those whose neighbouring samples disagree, the ring's and the
   map's diagonals' (:func:`_last_texels_kernel`): 25 % fewer rays, but it misses the one-texel
   corners of polygonal silhouettes, which the sun's shadow shows (docs/precompute.md).

Texels left unrefined take the visibility of the coarse sample whose uniform 3×3 neighbourhood
they lie in. What this can miss is a feature that lies entirely between samples of one uniform
neighbourhood *and* shows no depth discontinuity: in practice a ray that leaks through a crack
between two triangles of one surface (measured on a scanned head, docs/benchmarks.md "Cold path").
The error this adds against the full ``Rr²`` map is measured by ``warp-sg bench``
("SSDF error vs ray budget") and tested in ``tests/test_adaptive_rays.py``.

Rays of one vertex are consecutive threads of every launch (vertex-major layout), so they run
together and traverse the same part of the BVH; batches of vertices run on the CPU thread pool
(:func:`precompute.visibility.rays.run_batches`).

Every kernel takes the vertex batch ``(first, B)`` and works on ``(B, ·)`` arrays; the result is
the ``(B, Rr²)`` uint8 map (1 = visible) that :func:`precompute.visibility.ssdf._ssdf_batch` turns into SSDFs,
and the number of rays cast.
"""
from __future__ import annotations

import math

import numpy as np
import warp as wp

from precompute.visibility.horizon_ring import ring_kernel, ring_refine_kernel
from precompute.visibility.jump_flood import run_length
from precompute.visibility.rays import NO_HIT, ray_blocked, ray_hit_distance, vertex_ray_direction, vertex_ray_origin

#: coarse grid = ray resolution / COARSE_FACTOR
COARSE_FACTOR = 4
#: hit-distance ratio across a 3×3 neighbourhood that marks it for refinement
DEPTH_RATIO = 3.0
#: the ring is cast at every RING_STEP-th texel first, then refined where it changes (a power of 2;
#: 1: every ring texel)
RING_STEP = 4


@wp.func
def _sample_texel(j: int, i: int, f: int, Rr: int) -> int:
    """Texel index of cell (j, i)'s sample on a grid of f×f-texel cells."""
    return (j * f + f / 2) * Rr + i * f + f / 2


@wp.func
def _cast_sample(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3), vi: int,
                 dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float, k: int, c: int, tex: int,
                 vis: wp.array2d(dtype=wp.uint8), depth: wp.array2d(dtype=float), known: wp.array2d(dtype=wp.uint8),
                 cell_vis: wp.array2d(dtype=wp.uint8), cell_depth: wp.array2d(dtype=float)):
    """Cell ``c``'s sample at texel ``tex`` of vertex ``vi`` (row ``k``): a closest-hit ray, its
    visibility and hit distance written to the cell and to the texel (then known)."""
    t = ray_hit_distance(mesh, vertex_ray_origin(points, normals, vi, offset),
                         vertex_ray_direction(normals, vi, dirs[tex]), max_t)
    v = wp.where(t < NO_HIT, wp.uint8(0), wp.uint8(1))
    cell_vis[k, c] = v
    cell_depth[k, c] = t
    vis[k, tex] = v
    depth[k, tex] = t
    known[k, tex] = wp.uint8(1)


@wp.kernel(enable_backward=False)
def _coarse_kernel(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3), first: int,
                   dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float, Rr: int, s: int,
                   vis: wp.array2d(dtype=wp.uint8), depth: wp.array2d(dtype=float), known: wp.array2d(dtype=wp.uint8),
                   cell_vis: wp.array2d(dtype=wp.uint8), cell_depth: wp.array2d(dtype=float)):
    """One ray per coarse cell (closest hit): the cell's sample, also written to its texel."""
    k, c = wp.tid()
    j = c / s
    i = c - j * s
    _cast_sample(mesh, points, normals, first + k, dirs, offset, max_t, k, c, _sample_texel(j, i, Rr / s, Rr),
                 vis, depth, known, cell_vis, cell_depth)


@wp.func
def _mark_cell(cell_vis: wp.array2d(dtype=wp.uint8), cell_depth: wp.array2d(dtype=float),
               vis: wp.array2d(dtype=wp.uint8), Rr: int, s: int, f: int, log_ratio: float, k: int, j: int, i: int,
               marked: wp.array2d(dtype=wp.uint8)):
    """:func:`_mark_kernel` for cell (j, i) of vertex k."""
    lo = int(1)
    hi = int(0)
    dmin = float(NO_HIT)
    dmax = float(0.0)
    for dj in range(-1, 2):
        jj = j + dj
        if jj >= 0 and jj < s:
            for di in range(-1, 2):
                ii = i + di
                if ii >= 0 and ii < s:
                    cc = jj * s + ii
                    v = int(cell_vis[k, cc])
                    lo = wp.min(lo, v)
                    hi = wp.max(hi, v)
                    t = cell_depth[k, cc]
                    if t < NO_HIT:
                        dmin = wp.min(dmin, t)
                        dmax = wp.max(dmax, t)
                    if jj == 0 or jj == s - 1 or ii == 0 or ii == s - 1:  # a border cell: its ring texels
                        for q in range(f):
                            if jj == 0:
                                v = int(vis[k, ii * f + q])
                                lo = wp.min(lo, v)
                                hi = wp.max(hi, v)
                            if jj == s - 1:
                                v = int(vis[k, (Rr - 1) * Rr + ii * f + q])
                                lo = wp.min(lo, v)
                                hi = wp.max(hi, v)
                            if ii == 0:
                                v = int(vis[k, (jj * f + q) * Rr])
                                lo = wp.min(lo, v)
                                hi = wp.max(hi, v)
                            if ii == s - 1:
                                v = int(vis[k, (jj * f + q) * Rr + Rr - 1])
                                lo = wp.min(lo, v)
                                hi = wp.max(hi, v)
    m = wp.uint8(0)
    if lo != hi:
        m = wp.uint8(1)
    elif dmax > 0.0 and dmin < NO_HIT:
        if wp.log(dmax) - wp.log(dmin) > log_ratio:
            m = wp.uint8(1)
    marked[k, j * s + i] = m


@wp.kernel(enable_backward=False)
def _mark_kernel(cell_vis: wp.array2d(dtype=wp.uint8), cell_depth: wp.array2d(dtype=float),
                 vis: wp.array2d(dtype=wp.uint8), Rr: int, s: int, log_ratio: float,
                 run: int, marked: wp.array2d(dtype=wp.uint8)):
    """Mark cell (j, i) of the s×s grid when its 3×3 neighbourhood's samples (and the ring texels in
    those cells) disagree in visibility, or its blocked samples' hit distances differ by more than
    ``exp(log_ratio)``; thread ``(k, u)`` marks cells ``u·run … u·run + run − 1`` of one row
    (:func:`precompute.visibility.jump_flood.run_length`)."""
    k, u = wp.tid()
    f = Rr / s
    j = (u * run) / s
    for r in range(run):
        i = u * run - j * s + r
        _mark_cell(cell_vis, cell_depth, vis, Rr, s, f, log_ratio, k, j, i, marked)


@wp.kernel(enable_backward=False)
def _refine_kernel(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3), first: int,
                   dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float, Rr: int, s: int,
                   parent_vis: wp.array2d(dtype=wp.uint8), parent_depth: wp.array2d(dtype=float),
                   marked: wp.array2d(dtype=wp.uint8), vis: wp.array2d(dtype=wp.uint8),
                   depth: wp.array2d(dtype=float), known: wp.array2d(dtype=wp.uint8),
                   cell_vis: wp.array2d(dtype=wp.uint8), cell_depth: wp.array2d(dtype=float)):
    """Parent cell ``pc`` of the s×s grid and its four children on the (2s)×(2s) grid: a child of a
    marked parent gets its own sample (a ray unless its texel is known; closest hit while the grid
    is coarser than the texels, any hit on the last level), a child of an unmarked parent the
    parent's. (One thread per parent, not per child: a CPU thread's entry copies the kernel's
    arguments, and most parents are unmarked.)"""
    k, pc = wp.tid()
    vi = first + k
    s2 = 2 * s
    pj = pc / s
    pi = pc - pj * s
    pv = parent_vis[k, pc]
    pt = parent_depth[k, pc]
    split = marked[k, pc] != wp.uint8(0)
    f = Rr / s2
    for q in range(4):
        j = 2 * pj + q / 2
        i = 2 * pi + q % 2
        c = j * s2 + i
        v = pv
        t = pt
        if split:
            tex = _sample_texel(j, i, f, Rr)
            if known[k, tex] != wp.uint8(0):
                v = vis[k, tex]
                t = depth[k, tex]
            else:
                o = vertex_ray_origin(points, normals, vi, offset)
                d = vertex_ray_direction(normals, vi, dirs[tex])
                if f > 1:
                    t = ray_hit_distance(mesh, o, d, max_t)
                    v = wp.where(t < NO_HIT, wp.uint8(0), wp.uint8(1))
                else:  # the last level: no more marking, so any hit will do
                    v = wp.where(ray_blocked(mesh, o, d, max_t), wp.uint8(0), wp.uint8(1))
                vis[k, tex] = v
                depth[k, tex] = t
                known[k, tex] = wp.uint8(1)
        cell_vis[k, c] = v
        cell_depth[k, c] = t


@wp.kernel(enable_backward=False)
def _fill_kernel(cell_vis: wp.array2d(dtype=wp.uint8), vis: wp.array2d(dtype=wp.uint8),
                 known: wp.array2d(dtype=wp.uint8), run: int):
    """The last level's cells are texels: a texel no ray was cast at takes its cell's value
    (thread ``(k, u)``: texels ``u·run … u·run + run − 1``)."""
    k, u = wp.tid()
    for r in range(run):
        tex = u * run + r
        if known[k, tex] == wp.uint8(0):
            vis[k, tex] = cell_vis[k, tex]


@wp.kernel(enable_backward=False)
def _last_samples_kernel(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3),
                         first: int, dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float, Rr: int, s: int,
                         marked: wp.array2d(dtype=wp.uint8), vis: wp.array2d(dtype=wp.uint8),
                         depth: wp.array2d(dtype=float), known: wp.array2d(dtype=wp.uint8),
                         cell_vis: wp.array2d(dtype=wp.uint8), cell_depth: wp.array2d(dtype=float)):
    """The last level, step 1 (``s = Rr/2``, cells of 2×2 texels): the sample of a marked cell is
    made a ray (closest hit) where it was inherited; a cell whose sample texel is known takes
    that texel's value. After it, every marked cell's sample is a ray."""
    k, c = wp.tid()
    j = c / s
    i = c - j * s
    tex = _sample_texel(j, i, 2, Rr)
    if known[k, tex] != wp.uint8(0):
        cell_vis[k, c] = vis[k, tex]
        cell_depth[k, c] = depth[k, tex]
    elif marked[k, c] != wp.uint8(0):
        _cast_sample(mesh, points, normals, first + k, dirs, offset, max_t, k, c, tex, vis, depth, known,
                     cell_vis, cell_depth)


@wp.func
def _bracket(cell_vis: wp.array2d(dtype=wp.uint8), cell_depth: wp.array2d(dtype=float), k: int, s: int,
             j: int, i: int, lo: int, hi: int, dmin: float, dmax: float):
    """Fold the sample of cell (j, i) (skipped outside the grid) into the visibility range
    ``lo, hi`` and the blocked hit distances' range ``dmin, dmax``."""
    if j >= 0 and i >= 0:
        c = j * s + i
        v = int(cell_vis[k, c])
        t = cell_depth[k, c]
        lo = wp.min(lo, v)
        hi = wp.max(hi, v)
        if t < NO_HIT:
            dmin = wp.min(dmin, t)
            dmax = wp.max(dmax, t)
    return lo, hi, dmin, dmax


@wp.kernel(enable_backward=False)
def _last_texels_kernel(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3),
                        first: int, dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float, Rr: int, s: int,
                        log_ratio: float, run: int, marked: wp.array2d(dtype=wp.uint8),
                        cell_vis: wp.array2d(dtype=wp.uint8), cell_depth: wp.array2d(dtype=float),
                        vis: wp.array2d(dtype=wp.uint8), known: wp.array2d(dtype=wp.uint8)):
    """The last level, step 2: the texels of cell (j, i) that are not yet known. Texel
    ``(2j + a, 2i + b)`` lies between the samples of the cells ``(j − 1 + a … j, i − 1 + b … i)``
    (one, two or four of them: the samples sit at the cells' odd texel); in a marked cell it is a
    ray (any hit) when those samples disagree in visibility or their blocked hit distances differ
    by more than ``exp(log_ratio)``, else it takes their value. Two kinds of texel of a marked cell
    are always cast: a texel of the ring that no ray met (it holds its segment's guess), and a
    texel on one of the concentric map's diagonals (``x = y``, ``x + y = Rr − 1``), where the
    mapping bends and a boundary straight on the sphere has a one-texel notch that no two samples
    around it see (on a ball over a floor: 4 of 5 of the texels the rule missed). In an unmarked
    cell every texel takes the cell's value. Thread ``(k, u)``: cells ``u·run … u·run + run − 1``
    of one row."""
    k, u = wp.tid()
    j = (u * run) / s
    for r in range(run):
        i = u * run - j * s + r
        c = j * s + i
        split = marked[k, c] != wp.uint8(0)
        for q in range(4):
            a = q / 2
            b = q - 2 * a
            tex = (2 * j + a) * Rr + 2 * i + b
            if known[k, tex] == wp.uint8(0):
                if not split:
                    vis[k, tex] = cell_vis[k, c]
                else:
                    lo = int(1)
                    hi = int(0)
                    dmin = float(NO_HIT)
                    dmax = float(0.0)
                    lo, hi, dmin, dmax = _bracket(cell_vis, cell_depth, k, s, j, i, lo, hi, dmin, dmax)
                    if a == 0:
                        lo, hi, dmin, dmax = _bracket(cell_vis, cell_depth, k, s, j - 1, i, lo, hi, dmin, dmax)
                    if b == 0:
                        lo, hi, dmin, dmax = _bracket(cell_vis, cell_depth, k, s, j, i - 1, lo, hi, dmin, dmax)
                    if a == 0 and b == 0:
                        lo, hi, dmin, dmax = _bracket(cell_vis, cell_depth, k, s, j - 1, i - 1, lo, hi, dmin, dmax)
                    ty = 2 * j + a
                    tx = 2 * i + b
                    cast = lo != hi
                    if ty == 0 or tx == 0 or ty == Rr - 1 or tx == Rr - 1:
                        cast = True  # a ring texel no ray met holds its segment's guess: cast it
                    if tx == ty or tx + ty == Rr - 1:
                        cast = True  # the concentric map's diagonals, where a boundary bends at texel scale
                    if dmax > 0.0 and dmin < NO_HIT:
                        if wp.log(dmax) - wp.log(dmin) > log_ratio:
                            cast = True
                    if cast:
                        o = vertex_ray_origin(points, normals, first + k, offset)
                        d = vertex_ray_direction(normals, first + k, dirs[tex])
                        vis[k, tex] = wp.where(ray_blocked(mesh, o, d, max_t), wp.uint8(0), wp.uint8(1))
                        known[k, tex] = wp.uint8(1)
                    else:
                        vis[k, tex] = wp.uint8(lo)


def levels(ray_resolution: int, coarse_factor: int = COARSE_FACTOR) -> list[int]:
    """Grid sizes ``s₀, 2s₀, …, Rr`` of the levels (one level, plain ray casting, when the ray
    resolution is not a power-of-two multiple of the coarse grid)."""
    Rr = int(ray_resolution)
    f = int(coarse_factor)
    if f < 2 or Rr % f or f & (f - 1) or Rr // f < 2:
        return [Rr]
    out = [Rr // f]
    while out[-1] < Rr:
        out.append(out[-1] * 2)
    return out


def adaptive_visibility(ctx, dirs, Rr: int, points, normals, first: int, count: int, device, *,
                        coarse_factor: int = COARSE_FACTOR, depth_ratio: float = DEPTH_RATIO,
                        ring_step: int = RING_STEP, last: str = "block"):
    """``(vis (count, Rr²) wp.uint8 array, rays cast)`` of vertices ``first .. first+count−1`` of
    ``points``/``normals`` (module docstring). ``ctx``: :class:`precompute.visibility.rays._MeshContext`;
    ``dirs``: the ``Rr²`` local texel directions; ``ring_step``: :data:`RING_STEP`; ``last``: the
    last level's rule, ``"block"`` or ``"bracket"`` (step 4)."""
    if last not in ("block", "bracket"):
        raise ValueError(f"last must be 'block' or 'bracket', got {last!r}")
    B, N = int(count), int(Rr) * int(Rr)
    g = int(ring_step)
    M = 4 * (int(Rr) - 1)
    if g < 1 or g & (g - 1) or M % g:
        raise ValueError(f"ring step {g} is not a power of two dividing the ring's {M} texels")
    lv = levels(Rr, coarse_factor)
    if len(lv) == 1:
        raise ValueError(f"ray resolution {Rr} has no coarse level at factor {coarse_factor}")
    vis = wp.zeros((B, N), dtype=wp.uint8, device=device)
    depth = wp.empty((B, N), dtype=float, device=device)
    known = wp.zeros((B, N), dtype=wp.uint8, device=device)
    s = lv[0]
    cv = wp.empty((B, s * s), dtype=wp.uint8, device=device)
    cd = wp.empty((B, s * s), dtype=float, device=device)
    geo = [ctx.mesh.id, points, normals, int(first), dirs, ctx.offset, ctx.max_t, int(Rr)]
    wp.launch(_coarse_kernel, dim=(B, s * s), inputs=geo + [s, vis, depth, known, cv, cd], device=device)
    log_ratio = math.log(float(depth_ratio)) if depth_ratio and depth_ratio > 1 else 1.0e30
    ring_depth = wp.empty((B, M), dtype=float, device=device)
    wp.launch(ring_kernel, dim=(B, M // g), inputs=geo + [g, vis, depth, known, ring_depth], device=device)
    h = g // 2
    while h >= 1:  # halve the ring's segments where the samples around them disagree
        wp.launch(ring_refine_kernel, dim=(B, M // (2 * h)),
                  inputs=geo + [h, float(log_ratio), vis, depth, known, ring_depth], device=device)
        h //= 2
    for s in lv[:-1]:
        marked = wp.empty((B, s * s), dtype=wp.uint8, device=device)
        run = run_length(s, device)
        wp.launch(_mark_kernel, dim=(B, s * s // run), inputs=[cv, cd, vis, int(Rr), s, float(log_ratio), run, marked],
                  device=device)
        if last == "bracket" and 2 * s == Rr:
            wp.launch(_last_samples_kernel, dim=(B, s * s), inputs=geo + [s, marked, vis, depth, known, cv, cd],
                      device=device)
            wp.launch(_last_texels_kernel, dim=(B, s * s // run),
                      inputs=geo + [s, float(log_ratio), run, marked, cv, cd, vis, known], device=device)
            return vis, int(np.count_nonzero(known.numpy()))
        nv = wp.empty((B, 4 * s * s), dtype=wp.uint8, device=device)
        nd = wp.empty((B, 4 * s * s), dtype=float, device=device)
        wp.launch(_refine_kernel, dim=(B, s * s),
                  inputs=geo + [s, cv, cd, marked, vis, depth, known, nv, nd], device=device)
        cv, cd = nv, nd
    run = run_length(Rr, device)
    wp.launch(_fill_kernel, dim=(B, N // run), inputs=[cv, vis, known, run], device=device)
    return vis, int(np.count_nonzero(known.numpy()))  # every texel a ray was cast at is known


__all__ = ["adaptive_visibility", "levels", "COARSE_FACTOR", "DEPTH_RATIO"]
