r"""SSDFs at representative vertices of a mesh denser than its visibility needs.

A mesh with more vertices than the SSDF budget (:data:`DEFAULT_BUDGET`, the default
``[render] visibility_budget``) pays the rays and the distance fit (:mod:`precompute.visibility.ssdf`)
once per vertex although neighbouring vertices — far below a pixel apart at the sizes rendered —
see nearly the same hemisphere. Here the vertices are **clustered** and the maps are computed at
one **representative** per cluster only; every other vertex gets its representative's map
re-expressed in its own tangent frame (:func:`transfer_maps`).

**Clusters** (:func:`cluster_vertices`). A vertex's cell of a cubic grid of side ``h`` (origin
the bounding box's minimum corner) is split by normal only as far as needed
(:func:`normal_caps`): greedily, the cell's first vertex left is a seed, the cap's centre ``c`` is
moved once to the mean direction of the normals left within ``0.75 max_angle`` of it (kept only
if the seed stays in the cap), and every vertex left whose normal is within ``max_angle / 2`` of
``c`` joins the cluster; until the cell is used up. Two normals of a cluster are therefore at most
``max_angle`` apart (both within ``max_angle / 2`` of ``c``; nor on both sides of a thin part:
opposite normals are 180° apart) and two positions at most the cell diagonal ``√3 h``. Where a
cell's normals are few directions (a panel, a rim) it has as many clusters, not one per fixed
bin they straddle: on the ferrari 24.4 k clusters at ``h`` = 0.3 m where 20° cube-map bins gave
41.6 k. ``h`` is the smallest cell side whose cluster count is at most the budget (bisection on
``log h`` until the bracket is within :data:`CELL_TOLERANCE`). Everything is a function of the
arrays alone (sorted cells, in-order greedy, on the CPU), so deterministic.

**Probe** (:mod:`precompute.visibility.probe`). Position and normal do not tell an outer panel
from the shadowed detail or second layer just behind it, and the vertex nearest a cluster's
centroid lies in whichever is denser (on the ferrari in the detail: the representatives' maps
were on average more occluded than those of the vertices they stood for). So every vertex first
casts 16 stratified rays, its open fraction ``o`` (:func:`precompute.visibility.probe.probe_open_fraction`),
and (1) a cell is split by the band ``⌊o · PROBE_BANDS⌋`` of its vertices' ``o``
(:func:`probe_band`, 4 bands) before its normal caps; (2) the representative of a cluster is its
member whose ``o`` is nearest the cluster's mean ``o`` (ties: nearest the centroid, then the
lowest index); (3) the blend weights (:func:`blend_weights`) are multiplied by ``exp(−((o_v − o_r)/σ)²)``
(σ = :data:`PROBE_SIGMA`): a vertex takes the maps of the representatives as open as itself
among those around it. Without a probe (``probe=None``) the cells are not split and the
representative is the vertex nearest the centroid. The probe's rays are cast on the device (the
clusters are deterministic per device; a GPU's rounding could flip a ray where the CPU's does not).

**Transfer** (:func:`transfer_maps`, eq. 23 in the other frame). A map is stored in its vertex's
frame ``F = (t, b, n)`` (:mod:`warp_sg.numeric.onb`). For texel direction ``d_l`` of vertex ``v``
(world ``d = F_v d_l``), the representative ``r`` is read at ``F_rᵀ d`` (bilinear, as the
renderer reads it; below ``r``'s horizon continued as ``min(V^d(h), 0) − asin(−z)``,
:mod:`precompute.visibility.ssdf_wp`) and the horizon of ``v`` re-applied::

    V^d_v(d_l) ≈ min(V^d_r(F_rᵀ F_v d_l), asin(d_l·z))

(eq. 23: the signed distance to the nearer of the occluders and the horizon; the occluders are
taken as seen from ``r``). Where ``r``'s value is its own horizon's (``V^d_r = asin(z_r)``: no
occluder nearer than ``r``'s horizon, which ``r`` cannot see past), the value moves with the
horizon, ``V^d_r + asin(d_l·z) − asin(z_r)``: a smooth switch over one texel side
(:data:`HORIZON_TOL`, :func:`transfer_kernel`); below ``r``'s horizon an occluded horizon
continues as occluded, an open one as open. The transferred maps go through the representatives' PCA basis
(eq. 24, weights ``(X − mean) 𝕍ᵀ``) and through the occluder cones like computed ones.
The measured error of the transfer against each vertex's own ray-cast map: docs/precompute.md,
"Representative vertices".
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from precompute.visibility import probe as _probe
from precompute.visibility.probe import probe_open_fraction
from precompute.visibility.ssdf_wp import _texel_coords, texel_direction_array
from warp_sg.core.cache import code_key
from warp_sg.core.errors import InputError
from warp_sg.numeric.fastmath import fast_asin
from warp_sg.numeric.onb import frame_bitangent, frame_tangent, local_to_world, world_to_local

#: SSDF vertices beyond which the maps are computed at representatives only (the default
#: ``[render] visibility_budget``); 0 or None: every vertex its own map
DEFAULT_BUDGET = 20000
#: the largest angle (degrees) between the normals of two vertices of one cluster
DEFAULT_MAX_ANGLE = 20.0
#: the transfer's tolerance ``tol`` in texel sides ``√(2π)/R``: a value within ``tol`` of the
#: source's horizon elevation is horizon-bound (:func:`transfer_kernel`)
HORIZON_TOL = 1.0


# ---------------------------------------------------------------------------------------------
# clustering
# ---------------------------------------------------------------------------------------------

#: mean-shift steps that centre each normal cap on the normals around its seed
CAP_SHIFTS = 1
#: the radius (in max_angle) of the normals each shift averages
CAP_SHIFT_RADIUS = 0.75


@wp.kernel(enable_backward=False)
def normal_caps_kernel(start: wp.array(dtype=int), count: wp.array(dtype=int), cos_half: wp.float64,
                       cos_full: wp.float64, shifts: int, work: wp.array(dtype=int), wn: wp.array(dtype=wp.vec3d),
                       label: wp.array(dtype=int), caps: wp.array(dtype=int)):
    """Greedy normal caps of one cell (thread = cell): ``work[start : start + count]`` holds the
    cell's vertices (ascending), ``wn`` their unit normals; until none is left, the first left
    is the seed, the cap's centre ``c`` its normal moved ``shifts`` times to the normalised sum of
    the normals left within ``acos(cos_full)`` of ``c`` (kept only while the seed stays within
    the cap), and every vertex left with ``n·c ≥ cos_half`` gets ``label`` = the cap's index in
    the cell and leaves (the rest is compacted in order, in place). ``caps[cell]``: the caps made."""
    cell = wp.tid()
    s = start[cell]
    e = s + count[cell]
    k = int(0)
    while e > s:
        seed = wn[s]
        cen = seed
        for _it in range(shifts):
            acc = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
            for j in range(s, e):
                q = wn[j]
                if wp.dot(q, cen) >= cos_full:
                    acc = acc + q
            L = wp.length(acc)
            if L > wp.float64(0.0):
                cand = acc / L
                if wp.dot(seed, cand) >= cos_half:
                    cen = cand
        label[work[s]] = k  # (the seed: within by construction)
        w = int(s)
        for j in range(s + 1, e):
            q = wn[j]
            if wp.dot(q, cen) >= cos_half:
                label[work[j]] = k
            else:
                work[w] = work[j]
                wn[w] = q
                w = w + 1
        e = w
        k = k + 1
    caps[cell] = k


def normal_caps(cell, normals, max_angle: float = DEFAULT_MAX_ANGLE) -> tuple[np.ndarray, int]:
    """``(cluster (V,) int64, count)``: the vertices of each ``cell`` (V,) int64 grouped by normal
    (:func:`normal_caps_kernel`): every group lies in a cap of angular radius ``max_angle / 2``
    about a unit centre, so two normals of one group are at most ``max_angle`` apart. Clusters
    are numbered by cell (ascending id), then cap. ``normals``: unit (V, 3)."""
    if not 0.0 < float(max_angle) <= 180.0:
        raise InputError(f"max_angle must be in (0, 180] degrees, got {max_angle}", where="max_angle")
    cell = np.asarray(cell, np.int64)
    V = len(cell)
    if V == 0:
        return np.zeros(0, np.int64), 0
    _, cid = np.unique(cell, return_inverse=True)
    cid = cid.reshape(-1)
    order = np.argsort(cid, kind="stable").astype(np.int32)
    cnt = np.bincount(cid).astype(np.int32)
    st = (np.cumsum(cnt) - cnt).astype(np.int32)
    th = math.radians(float(max_angle))
    cos_half, cos_shift = math.cos(0.5 * th), math.cos(min(CAP_SHIFT_RADIUS * th, math.pi))
    d = "cpu"  # (the same clusters on every machine)
    label = wp.empty(V, dtype=int, device=d)
    caps = wp.empty(len(cnt), dtype=int, device=d)
    wp.launch(normal_caps_kernel, dim=len(cnt), device=d,
              inputs=[wp.array(st, dtype=int, device=d), wp.array(cnt, dtype=int, device=d),
                      wp.float64(cos_half), wp.float64(cos_shift), int(CAP_SHIFTS),
                      wp.array(order, dtype=int, device=d),
                      wp.array(np.ascontiguousarray(np.asarray(normals, np.float64)[order]), dtype=wp.vec3d, device=d),
                      label, caps])
    k = caps.numpy().astype(np.int64)
    first = np.cumsum(k) - k
    return first[cid] + label.numpy().astype(np.int64), int(k.sum())


@dataclass
class Clustering:
    """``cluster`` (V,) int64: each vertex's cluster; ``reps`` (K,) int64: cluster k's
    representative vertex; ``cell``: the grid side ``h``; ``max_angle``: degrees."""

    cluster: np.ndarray
    reps: np.ndarray
    cell: float
    max_angle: float

    @property
    def count(self) -> int:
        return int(len(self.reps))


def _cells(p, lo, h, spacing=None) -> np.ndarray:
    """(V,) int64 cell ids of the grid of side ``h``; a vertex whose ``spacing`` exceeds ``h`` has
    a cell of its own."""
    ijk = np.floor((p - lo) / h).astype(np.int64)
    dims = ijk.max(axis=0) + 1
    key = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    if spacing is not None:
        key = np.where(spacing > h, int(dims.prod()) + np.arange(len(p)), key)
    return key


def vertex_spacing(vertices, triangles) -> np.ndarray:
    """(V,) the longest edge at each vertex (0 for a vertex of no triangle)."""
    p = np.asarray(vertices, np.float64)
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    L = np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1)
    out = np.zeros(len(p))
    np.maximum.at(out, e[:, 0], L)
    np.maximum.at(out, e[:, 1], L)
    return out


#: the bisection on ``log h`` stops when the bracket's sides are within this ratio
CELL_TOLERANCE = 1.02
#: the bands of the probe's open fraction ``o`` that split a cell: ``⌊o · PROBE_BANDS⌋``
PROBE_BANDS = 4
#: the width σ of the probe similarity of the blend weights, ``exp(−(Δo/σ)²)``
PROBE_SIGMA = 0.125


def probe_band(probe) -> np.ndarray:
    """(V,) int64: the band ``min(⌊o · PROBE_BANDS⌋, PROBE_BANDS − 1)`` of each vertex's open
    fraction ``o`` (:func:`precompute.visibility.probe.probe_open_fraction`)."""
    o = np.asarray(probe, np.float64)
    return np.clip(np.floor(o * PROBE_BANDS), 0, PROBE_BANDS - 1).astype(np.int64)


def cluster_vertices(vertices, normals, budget: int = DEFAULT_BUDGET,
                     max_angle: float = DEFAULT_MAX_ANGLE, spacing=None, probe=None) -> Clustering:
    """At most ``budget`` clusters of the vertices (module docstring), unless the normals alone
    need more (then the caps of the coarsest grid, two cells a side: a bounded scene extent).
    ``spacing`` (V,) (:func:`vertex_spacing`): a vertex whose edges are longer than the cell side
    (a coarse part of the mesh, e.g. a floor under a detailed object) is a cluster of its own.
    ``probe`` (V,) (:func:`precompute.visibility.probe.probe_open_fraction`): cells split by its
    band (:func:`probe_band`), the representative the member whose probe is nearest its
    cluster's mean (ties: nearest the centroid, then the lowest index); without it the
    representative is the member nearest the centroid (ties: the lowest index)."""
    p = np.asarray(vertices, np.float64)
    nrm = np.asarray(normals, np.float64)
    nrm = nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    sp = None if spacing is None else np.asarray(spacing, np.float64)
    lo = p.min(axis=0)
    ext = float(np.max(p.max(axis=0) - lo))
    ext = ext if ext > 0 else 1.0
    hi_h, lo_h = 2.0 * ext, ext / 2.0 ** 14  # (≤ 2^15 cells a side: the key stays in int64)

    band = None if probe is None else probe_band(probe)

    def ids(h):
        c = _cells(p, lo, h, sp)
        return normal_caps(c if band is None else c * PROBE_BANDS + band, nrm, max_angle)

    best = None
    a, b = math.log(lo_h), math.log(hi_h)
    while b - a > math.log(CELL_TOLERANCE):
        mid = math.exp(0.5 * (a + b))
        inv_m, cnt_m = ids(mid)
        if cnt_m <= budget:
            b = math.log(mid)
            if best is None or cnt_m > best[1]:
                best = (inv_m, cnt_m, mid)
        else:
            a = math.log(mid)
    if best is None:
        best = ids(hi_h) + (hi_h,)
    inv, cnt, h = best
    counts = np.bincount(inv, minlength=cnt).astype(np.float64)
    cen = np.stack([np.bincount(inv, p[:, k], minlength=cnt) for k in range(3)], -1) / counts[:, None]
    d2 = np.sum((p - cen[inv]) ** 2, axis=1)
    keys = (np.arange(len(p)), d2, inv)
    if probe is not None:  # the member whose probe is nearest the cluster's mean first
        o = np.asarray(probe, np.float64)
        keys = (np.arange(len(p)), d2, np.abs(o - np.bincount(inv, o, minlength=cnt)[inv] / counts[inv]), inv)
    order = np.lexsort(keys)
    first = np.r_[0, np.flatnonzero(np.diff(inv[order])) + 1]
    return Clustering(cluster=inv.astype(np.int64), reps=order[first].astype(np.int64), cell=float(h),
                      max_angle=float(max_angle))


# ---------------------------------------------------------------------------------------------
# transfer of the representatives' maps
# ---------------------------------------------------------------------------------------------

@wp.kernel(enable_backward=False)
def transfer_kernel(maps: wp.array2d(dtype=float), src: wp.array(dtype=int), src_n: wp.array(dtype=wp.vec3),
                    dst_n: wp.array(dtype=wp.vec3), dirs: wp.array(dtype=wp.vec3), R: int, tol: float,
                    out: wp.array2d(dtype=float)):
    """``out[i, t]``: row ``r = src[i]`` of ``maps`` (R² texels, row-major, in the frame of
    ``src_n[r]``) read at texel t's direction of the frame of ``dst_n[i]`` and given that frame's
    horizon (module docstring, "Transfer"): ``(1 − β) min(U', e_i) + β min(U + e_i − e_r, e_i)`` with
    ``U`` the bilinear read, ``U'`` the same continued below r's horizon (``min(U, 0) − asin(−z)``),
    ``e_i = asin(z_i)``, ``e_r = asin(max(z_r, 0))`` the elevations in the two frames and
    ``β = clamp((U − e_r + 2 tol)/tol, 0, 1)``: 1 where r's value is its own horizon's, which then
    moves with the horizon. The same frame gives the map itself."""
    i, t = wp.tid()
    r = src[i]
    n = wp.normalize(dst_n[i])
    dl = dirs[t]
    d = local_to_world(dl, frame_tangent(n), frame_bitangent(n), n)
    m = wp.normalize(src_n[r])
    dr = world_to_local(d, frame_tangent(m), frame_bitangent(m), m)
    c = _texel_coords(dr, R)
    x0 = int(c[0])
    y0 = int(c[1])
    fx = c[2]
    fy = c[3]
    k = y0 * R + x0
    u = ((maps[r, k] * (1.0 - fx) + maps[r, k + 1] * fx) * (1.0 - fy)
         + (maps[r, k + R] * (1.0 - fx) + maps[r, k + R + 1] * fx) * fy)
    e_r = fast_asin(wp.clamp(dr[2], 0.0, 1.0))
    e_i = fast_asin(wp.clamp(dl[2], 0.0, 1.0))
    beta = wp.clamp((u - e_r + 2.0 * tol) / tol, 0.0, 1.0)
    bound = wp.min(u + e_i - e_r, e_i)  # horizon-bound: moved with the horizon
    if dr[2] < 0.0:
        u = wp.min(u, 0.0) - fast_asin(wp.min(-dr[2], 1.0))
    out[i, t] = (1.0 - beta) * wp.min(u, e_i) + beta * bound


def transfer_maps(rep_maps, rep_normals, src, normals, resolution: int, device="cpu") -> np.ndarray:
    """``(n, R²)`` float32: the maps ``rep_maps[src[i]]`` (``(K, R²)``, in the frames of the unit
    normals ``rep_normals``) re-expressed in the frames of ``normals[i]`` (:func:`transfer_kernel`)."""
    R = int(resolution)
    n = len(src)
    out = wp.empty((max(n, 1), R * R), dtype=float, device=device)
    if n:
        dirs = texel_direction_array(R, device)
        wp.launch(transfer_kernel, dim=(n, R * R), device=device,
                  inputs=[rep_maps if isinstance(rep_maps, wp.array) else
                          wp.array(np.ascontiguousarray(rep_maps, np.float32), dtype=float, device=device),
                          wp.array(np.asarray(src, np.int32), dtype=int, device=device),
                          wp.array(np.asarray(rep_normals, np.float32), dtype=wp.vec3, device=device),
                          wp.array(np.asarray(normals, np.float32), dtype=wp.vec3, device=device), dirs, R,
                          float(HORIZON_TOL * math.sqrt(2.0 * math.pi) / R), out])
    return out.numpy()[:n]


#: neighbouring representatives a vertex's map is blended from (its own and the nearest others)
BLEND_NEIGHBOURS = 6
#: the blend radius ρ in cell diagonals √3 h (> 1: the own representative is within √3 h)
BLEND_RADIUS = 2.0


def _blend_table(P, nr, cell: float, max_angle: float, k: int = BLEND_NEIGHBOURS):
    """``(nb (K, k), ok (K, k))``: per representative itself (column 0) and its ``k − 1`` nearest
    other representatives (positions ``P``), ``ok`` where such a neighbour's normal is within
    ``max_angle`` of its own and it is closer than the blend radius ``2√3 h``."""
    from scipy.spatial import cKDTree

    K = len(P)
    kk = min(k, K)
    dn, nb = cKDTree(P).query(P, kk)
    dn, nb = dn.reshape(K, kk), nb.reshape(K, kk)
    self_ = np.arange(K)[:, None]
    others = nb != self_
    # column 0 itself, then the others in distance order (a point can tie with itself at d = 0)
    order = np.argsort(~others, axis=1, kind="stable")
    nb2 = np.concatenate([self_, np.take_along_axis(nb, order, 1)[:, : kk - 1]], 1)
    d2 = np.concatenate([np.zeros((K, 1)), np.take_along_axis(dn, order, 1)[:, : kk - 1]], 1)
    oth = np.concatenate([np.ones((K, 1), bool), np.take_along_axis(others, order, 1)[:, : kk - 1]], 1)
    cos = np.sum(nr[nb2] * nr[:, None, :], -1)
    ok = oth & (cos >= math.cos(math.radians(max_angle))) & (d2 < BLEND_RADIUS * math.sqrt(3.0) * cell)
    ok[:, 0] = True
    return nb2, ok


def blend_weights(x, P, nb, ok, cell: float, probe=None, rep_probe=None) -> np.ndarray:
    """``(n, k)`` weights of the representatives ``nb`` (rows: each vertex's own representative's
    table row, positions ``P``) at the vertex positions ``x``: ``a_j ∝ (1 − d_j/ρ)₊² / (d_j² + ε²)``,
    ``ρ = 2√3 h``, ``ε = h/10`` (inverse-distance weights that fall to 0 at the blend radius: a
    vertex at a representative takes its map, one between two takes both), normalised. With
    ``probe`` (n,) (the vertices' open fractions) and ``rep_probe`` (K,) (the representatives'),
    ``a_j`` is multiplied by ``exp(−((probe − rep_probe_j)/σ)²)`` (σ = :data:`PROBE_SIGMA`) before."""
    rho, eps = BLEND_RADIUS * math.sqrt(3.0) * cell, 0.1 * cell
    d = np.linalg.norm(x[:, None, :] - P[nb], axis=-1)
    a = np.where(ok, np.maximum(1.0 - d / rho, 0.0) ** 2 / (d * d + eps * eps), 0.0)
    if probe is not None:
        a = a * np.exp(-((np.asarray(probe, np.float64)[:, None] - rep_probe[nb]) / PROBE_SIGMA) ** 2)
    a[:, 0] = np.maximum(a[:, 0], 1e-12)  # (the own representative is within √3 h < ρ: never 0)
    return a / a.sum(1, keepdims=True)


def build_at_representatives(v, f, n, compute, *, resolution, ray_resolution, pca_terms, budget, max_angle,
                             device, progress, kw, clock, pca_and_cones, batch: int = 8192) -> dict:
    """The cache entry of :func:`precompute.visibility.ssdf.ssdf_for_mesh` with the maps computed
    at the representatives of :func:`cluster_vertices` only (``compute(..., vertex_ids=reps)``) and
    the PCA (eq. 24) fitted to them, the clusters and blend weights using every vertex's probe
    (:func:`precompute.visibility.probe.probe_open_fraction`, the compute's ``cutouts``). Every
    other vertex ``v`` of cluster ``c`` (representative ``r_c``) gets the blend
    ``Σ_j a_j T_{r_c←r_j}(m_j)`` (:func:`blend_weights`) of its representative's neighbours' maps,
    each transferred to ``r_c``'s frame (:func:`transfer_maps`; blended as PCA weights), then
    transferred to its own frame; from that map its weights (``(X − mean) 𝕍ᵀ``) and occluder cone.
    Stages of ``clock``: ``probe``, ``cluster``, the compute's, ``pca``, ``cones`` (the
    representatives'), ``blend table`` and ``transfer`` (the other vertices': blend, transfer,
    projection, cones; batches of ``batch`` on the CPU threads).
    Entries ``representative`` (V,) int32: each vertex's own representative vertex;
    ``blend_index``, ``blend_weight`` (V, k): the representatives (vertex ids) and weights of each
    vertex's blend (a representative: itself, weight 1), which the renderer's per-vertex caches
    reuse (:mod:`warp_sg.shading.vertex_visibility`)."""
    import time

    from threadpoolctl import threadpool_limits

    from precompute.visibility.occluder_cone import occluder_cones
    from precompute.visibility.rays import run_batches
    from warp_sg.core.stage_clock import thread_cpu

    R = int(resolution)
    with clock.stage("probe"):
        probe = probe_open_fraction(v, f, n, device=device, cutouts=kw.get("cutouts"))
    with clock.stage("cluster"):
        cl = cluster_vertices(v, n, budget, max_angle, vertex_spacing(v, f), probe)
    reps = cl.reps
    with clock.stage("ssdf_total"):
        Xr = compute(v, f, n, resolution=resolution, ray_resolution=ray_resolution, device=device,
                     progress=progress, vertex_ids=reps, **kw).reshape(len(reps), -1)
    p, cones_r = pca_and_cones(Xr, n[reps], R, int(pca_terms), clock)
    V, K, NV = len(v), len(reps), p.basis.shape[0]
    mean, basis = p.mean.astype(np.float32), p.basis.astype(np.float32)
    P = np.asarray(v, np.float64)[reps]
    nr = np.asarray(n, np.float64)[reps]
    nr /= np.maximum(np.linalg.norm(nr, axis=1, keepdims=True), 1e-30)
    with clock.stage("blend table"), threadpool_limits(limits=1, user_api="blas"):
        nb, ok = _blend_table(P, nr, cl.cell, max_angle)
        W = np.zeros(nb.shape + (NV,), np.float32)  # W[c, j]: rep nb[c, j]'s map in rep c's frame
        W[:, 0] = p.weights
        pc, pj = np.nonzero(ok[:, 1:])
        rep_maps = wp.array(np.ascontiguousarray(Xr, np.float32), dtype=float, device=device)
        for s in range(0, len(pc), batch):
            c, j = pc[s:s + batch], pj[s:s + batch] + 1
            W[c, j] = (transfer_maps(rep_maps, nr, nb[c, j], nr[c], R, device) - mean) @ basis.T
    del rep_maps
    weights = np.empty((V, NV), np.float32)
    cones = np.empty((V, 4), np.float32)
    weights[reps], cones[reps] = p.weights, cones_r
    others = np.setdiff1d(np.arange(V), reps)
    k = nb.shape[1]
    blend_index = np.repeat(np.arange(V, dtype=np.int32)[:, None], k, 1)  # representatives: themselves
    blend_weight = np.zeros((V, k), np.float32)
    blend_weight[:, 0] = 1.0
    x = np.asarray(v, np.float64)
    clock.count("representatives", K)

    def work(s, e):
        w0, c0 = time.perf_counter(), thread_cpu()
        idx = others[s:e]
        c = cl.cluster[idx]
        a = blend_weights(x[idx], P, nb[c], ok[c], cl.cell, probe[idx], probe[reps]).astype(np.float32)
        blend_index[idx], blend_weight[idx] = reps[nb[c]], a
        Y = mean + np.einsum("ij,ijk->ik", a, W[c]) @ basis  # the blend in r_c's frame
        Y = transfer_maps(Y, nr[c], np.arange(len(idx)), n[idx], R, device)
        weights[idx] = (Y - mean) @ basis.T
        cones[idx] = occluder_cones(Y, n[idx], R)
        clock.add("transfer", time.perf_counter() - w0, thread_cpu() - c0)

    with threadpool_limits(limits=1, user_api="blas"):  # (one BLAS thread per batch thread)
        run_batches(len(others), batch, work, device)
    return {"mean": p.mean.reshape(R, R), "basis": p.basis.reshape(-1, R, R), "weights": weights,
            "pca_rms_error": p.rms_error, "cones": cones, "representative": reps[cl.cluster].astype(np.int32),
            "blend_index": blend_index, "blend_weight": blend_weight}


#: the hash of this module's code (clustering and transfer) and the probe's, part of the SSDF cache key
REPRESENTATIVES_VERSION = code_key(__name__, _probe)


def representative_params(n_vertices: int, budget, max_angle) -> dict:
    """The cache-key entries of the representatives (empty when every vertex has its own map:
    the key of a mesh within the budget is unchanged)."""
    if not budget or int(n_vertices) <= int(budget):
        return {}
    return {"representatives": int(budget), "rep_max_angle": float(max_angle), "rep_version": REPRESENTATIVES_VERSION}


__all__ = ["Clustering", "cluster_vertices", "normal_caps", "normal_caps_kernel", "transfer_maps", "transfer_kernel",
           "representative_params", "build_at_representatives", "vertex_spacing", "blend_weights", "probe_band",
           "BLEND_NEIGHBOURS", "PROBE_BANDS", "PROBE_SIGMA", "DEFAULT_BUDGET", "DEFAULT_MAX_ANGLE",
           "REPRESENTATIVES_VERSION"]
