r"""Spherical signed distance functions (SSDF, paper §5.1–5.2, eq. 23–24).

Per vertex, on the concentric map of the upper hemisphere (:mod:`precompute.visibility.ssdf_wp`)::

    V^d(i) = + min_{t: V(t)=0} arccos(t·i)   if V(i) = 1      (eq. 23)
             − min_{t: V(t)=1} arccos(t·i)   if V(i) = 0

with directions below the horizon invisible. Pipeline per batch of vertices, all in Warp kernels
on the device (:func:`compute_ssdf`; the kernels of steps 2–5 are :mod:`precompute.visibility.jump_flood`'s):

1. binary visibility at ``ray_resolution²`` texels by BVH ray casts (:mod:`precompute.visibility.rays`):
   coarse first and refined where the visibility changes (:mod:`precompute.visibility.adaptive_rays`, the
   default ``rays = "adaptive"``: about a third of the rays), or one ray per texel (``"full"``);
   a vertex whose map is uniform (all visible or all blocked) skips steps 2–4 (its SSDF is one of
   two fixed maps);
2. **boundary seeds**: every pair of 4-neighbour texels with different visibility contributes the
   boundary point ``normalize(d_a + d_b)`` (midpoint on the sphere); each texel keeps its nearest;
3. **jump flooding** (Rong & Tan 2006) on the concentric grid with the angular metric: passes with
   steps R/2, R/4, …, 1, then 2, 1 again ("JFA+2"); each texel keeps, among the seeds held by its
   8 neighbours at the current step and itself, the one with the largest dot product. Cost
   O(R² log R) per vertex, not O(R⁴). When the rays are cast finer than the stored grid (the
   default 64² → 32²) the flooding runs on the stored grid over seed texels and a local pass
   brings each ray texel its nearest seed (:mod:`precompute.visibility.jump_flood`, "Coarse-to-fine");
4. signed distance ``±arccos(d·seed)`` with true angles; visible texels also take ``min`` with their
   elevation ``asin(z)`` (the horizon is a boundary); values are clamped to [−π/2, π/2] (a texel
   with nothing visible anywhere gets −π/2; ``fh`` ratios below −π/2 are ≤ e^{−λ} anyway);
5. box downsampling ``ray_resolution → resolution`` (paper: 512² → 128²; defaults here 64² → 32²,
   see docs/precompute.md for the measured error of each setting).

Then all vertices are compressed with PCA (:mod:`warp_sg.numeric.pca`, eq. 24) and cached on disk
(:func:`warp_sg.core.cache.load_or_build`) under a content hash of mesh + parameters; within the
decompression budget the maps themselves are kept and cached instead (``SSDFData.maps``; why:
docs/precompute.md, "PCA"), and their PCA is computed when it is first read
(:class:`warp_sg.numeric.pca.DeferredPCA`; the renderer, which reads the maps, never does).
"""
from __future__ import annotations

import contextlib
import time

import numpy as np
import warp as wp

from precompute.visibility.adaptive_rays import adaptive_visibility, levels
from precompute.visibility.jump_flood import (
    coarse_seed_kernel,
    downsample_kernel,
    fine_seed_kernel,
    fine_signed_kernel,
    jfa_steps,
    jfa_texel_kernel,
    run_length,
    seed_at_kernel,
    seed_kernel,
    signed_kernel,
)
from precompute.visibility.occluder_cone import occluder_cones
from precompute.visibility.rays import OFFSET_SCALE, _MeshContext, _tqdm, launch_visibility, run_batches, validate_mesh
from precompute.visibility.representatives import (
    DEFAULT_BUDGET,
    DEFAULT_MAX_ANGLE,
    build_at_representatives,
    representative_params,
)
from precompute.visibility.ssdf_data import DEFAULT_RAY_RESOLUTION, SSDFData, decompress_budget, memory_budget
from precompute.visibility.ssdf_wp import texel_direction_array, texel_directions
from warp_sg.core import cache as _cache
from warp_sg.core.device import resolve_device
from warp_sg.core.errors import InputError
from warp_sg.core.stage_clock import StageClock, thread_cpu
from warp_sg.numeric.pca import pca

#: Defaults (see docs/precompute.md for the error/time trade-off).
DEFAULT_RESOLUTION = 32
DEFAULT_PCA_TERMS = 24
#: how the binary visibility maps are cast: coarse first and refined where the visibility changes
#: (:mod:`precompute.visibility.adaptive_rays`), or one ray per texel
RAYS = ("adaptive", "full")
DEFAULT_RAYS = "adaptive"

#: Part of the "ssdf" cache key: the hash of the code that computes the maps (``warp_sg.core.cache.code_key``).
SSDF_VERSION = _cache.code_key(__name__, "precompute.visibility.jump_flood", occluder_cones, texel_directions,
                               launch_visibility, pca)  # the producing code
#: the hash of the adaptive ray schedule's code (precompute.visibility.adaptive_rays), part of the cache key
ADAPTIVE_VERSION = _cache.code_key(adaptive_visibility, "precompute.visibility.horizon_ring")  # the adaptive ray cast's code


# ---------------------------------------------------------------------------------------------
# per-vertex SSDFs
# ---------------------------------------------------------------------------------------------

def _check_rays(rays):
    rays = DEFAULT_RAYS if rays is None else rays
    if rays not in RAYS:
        raise InputError(f"rays must be one of {', '.join(RAYS)}, got {rays!r}", where="rays")
    return rays


def _check_resolutions(resolution, ray_resolution):
    if int(resolution) != resolution or resolution < 2:
        raise InputError(f"SSDF resolution must be an integer >= 2, got {resolution}", where="ssdf_resolution")
    if int(ray_resolution) != ray_resolution or ray_resolution < resolution or ray_resolution % resolution:
        raise InputError(f"ray_resolution ({ray_resolution}) must be a multiple of the SSDF resolution "
                         f"({resolution})", where="ray_resolution")


def _flood(a, dirs, Rr, R, device):
    """Jump flooding of seed-texel indices on the ``R²`` grid (:mod:`precompute.visibility.jump_flood`)
    from the seeds ``a`` (B, Rr²): ``(B, R²)`` indices of the flooded seed texels. When ``Rr = f·R``
    with f ≥ 2 each cell starts from the best of its f×f texels' seeds ("Coarse-to-fine"), at f = 1
    each texel from its own seed."""
    B = int(a.shape[0])
    f, M = Rr // R, R * R
    cdirs = dirs if f == 1 else texel_direction_array(R, device)
    ca = wp.empty((B, M), dtype=int, device=device)
    cb = wp.empty((B, M), dtype=int, device=device)
    wp.launch(coarse_seed_kernel, dim=(B, M), device=device, inputs=[a, cdirs, R, f, ca])
    run = run_length(R, device)
    for step in jfa_steps(R):
        wp.launch(jfa_texel_kernel, dim=(B, M // run), device=device, inputs=[ca, a, cdirs, R, step, run, cb])
        ca, cb = cb, ca
    return ca


def _nearest_seeds(a, dirs, Rr, R, device):
    """The nearest boundary point of every ray texel, from the seeds ``a`` (B, Rr²): :func:`_flood`,
    then at f = Rr/R ≥ 2 the local fine pass (``fine_seed_kernel``), at f = 1 the seed each
    flooded index points at. (:func:`_fit_maps` fuses the fine pass with the signed distance and
    the downsampling instead: ``fine_signed_kernel``, the same values.)"""
    B, N = int(a.shape[0]), Rr * Rr
    f = Rr // R
    ca = _flood(a, dirs, Rr, R, device)
    b = wp.empty((B, N), dtype=wp.vec3, device=device)
    if f == 1:
        wp.launch(seed_at_kernel, dim=(B, N), device=device, inputs=[a, ca, b])
    else:
        wp.launch(fine_seed_kernel, dim=(B, N), device=device, inputs=[a, ca, dirs, Rr, f, b])
    return b


def _fit_maps(vis, dirs, Rr, R, device, fused: bool = True):
    """(B, R²) SSDFs of the (B, Rr²) visibility maps ``vis`` (steps 2–5 of the module docstring).
    ``fused`` (Rr > R): the fine seed pass, the signed distance and the box filter in one kernel
    (``fine_signed_kernel``); False: one kernel each (the same values)."""
    B, N = int(vis.shape[0]), Rr * Rr
    a = wp.empty((B, N), dtype=wp.vec3, device=device)
    run = run_length(Rr, device)
    wp.launch(seed_kernel, dim=(B, N // run), device=device, inputs=[vis, dirs, Rr, run, a])
    if Rr != R and fused:
        ds = wp.empty((B, R * R), dtype=float, device=device)
        wp.launch(fine_signed_kernel, dim=(B, R * R), device=device,
                  inputs=[a, _flood(a, dirs, Rr, R, device), vis, dirs, Rr, Rr // R, ds])
        return ds.numpy()
    a = _nearest_seeds(a, dirs, Rr, R, device)
    sd = wp.empty((B, N), dtype=float, device=device)
    wp.launch(signed_kernel, dim=(B, N), device=device, inputs=[vis, a, dirs, sd])
    if Rr != R:
        ds = wp.empty((B, R * R), dtype=float, device=device)
        wp.launch(downsample_kernel, dim=(B, R * R), device=device, inputs=[sd, R, Rr // R, ds])
        sd = ds
    return sd.numpy()


_UNIFORM: dict = {}


def _uniform_maps(dirs, Rr, R, device):
    """The SSDFs of an all-occluded and an all-visible map (rows 0 and 1), through the same kernels:
    a vertex with uniform visibility has no boundary to search for (−π/2, resp. its horizon bound)."""
    key = (Rr, R, str(device))
    if key not in _UNIFORM:
        vis = wp.array(np.stack([np.zeros(Rr * Rr, np.uint8), np.ones(Rr * Rr, np.uint8)]), dtype=wp.uint8,
                       device=device)
        _UNIFORM[key] = _fit_maps(vis, dirs, Rr, R, device)
    return _UNIFORM[key]


def _ssdf_batch(ctx, dirs, Rr, R, points, normals, s, e, device, out_vis=None, clock=None, rays=None, adaptive=None):
    """SSDFs ``(e − s, R²)`` of vertices ``s..e−1`` of ``points``/``normals``: binary visibility
    (``rays = "adaptive"``: :mod:`precompute.visibility.adaptive_rays`; ``"full"``: a ray per texel), then the
    distance search (skipped for vertices whose map is uniform: their SSDF is one of two fixed maps)."""
    rays = DEFAULT_RAYS if rays is None else rays
    B = e - s
    N = Rr * Rr
    w0, c0 = time.perf_counter(), thread_cpu()
    if rays == "adaptive" and len(levels(Rr)) > 1 and ctx.cutouts is None:
        vis, n_rays = adaptive_visibility(ctx, dirs, Rr, points, normals, s, B, device, **(adaptive or {}))
    else:  # a ray per texel (and, through cut-outs' holes, the cut-out kernel: launch_visibility)
        vis = wp.empty((B, N), dtype=wp.uint8, device=device)
        launch_visibility(ctx, points, normals, s, dirs, vis)
        n_rays = B * N
    vn = vis.numpy()
    w1, c1 = time.perf_counter(), thread_cpu()
    if out_vis is not None:
        out_vis[s:e] = vn
    lo, hi = vn.min(axis=1), vn.max(axis=1)
    mixed = np.flatnonzero(lo != hi)
    if len(mixed) == B or not wp.get_device(device).is_cpu:
        out = _fit_maps(vis, dirs, Rr, R, device)
    else:
        out = np.empty((B, R * R), np.float32)
        out[:] = _uniform_maps(dirs, Rr, R, device)[np.minimum(lo, 1).astype(np.int64)]
        if len(mixed):
            out[mixed] = _fit_maps(wp.array(vn[mixed], dtype=wp.uint8, device=device), dirs, Rr, R, device)
    if clock is not None:
        clock.add("rays", w1 - w0, c1 - c0)
        clock.add("ssdf_fit", time.perf_counter() - w1, thread_cpu() - c1)
        clock.count("rays_cast", n_rays)
        clock.count("uniform_vertices", B - len(mixed))
    return out


def compute_ssdf(vertices, triangles, normals, *, resolution: int = DEFAULT_RESOLUTION,
                 ray_resolution: int = DEFAULT_RAY_RESOLUTION, device="cpu", vertex_ids=None,
                 progress: bool = True, batch: int = 256, return_visibility: bool = False, clock=None,
                 rays: str = None, adaptive: dict | None = None, out=None, cutouts=None, occluders=None):
    """Uncompressed SSDFs ``(n, R, R)`` float32 (radians) of the selected vertices (default all).

    With ``return_visibility`` also returns the binary maps ``(n, Rr, Rr)`` uint8 at ray resolution.
    ``rays``: ``"adaptive"`` (default, :data:`DEFAULT_RAYS`; :mod:`precompute.visibility.adaptive_rays`) or
    ``"full"`` (a ray per texel, the reference the adaptive maps are measured against);
    ``adaptive``: keyword arguments of :func:`precompute.visibility.adaptive_rays.adaptive_visibility`
    (``coarse_factor``, ``depth_ratio``: the ray budget; ``ssdf_for_mesh`` uses the defaults).
    ``out``: a float32 ``(n, R²)`` array (e.g. a ``numpy.memmap``) the rows are written into
    batch by batch (and which is returned, reshaped); default a new array.
    ``clock`` (:class:`warp_sg.core.stage_clock.StageClock`): adds the stages ``bvh``, ``rays`` and
    ``ssdf_fit`` (CPU: the sum over the worker threads; wall: summed per batch too, so over the
    threads) and the counts ``rays_cast`` and ``uniform_vertices``.
    ``cutouts``: the mesh's alpha cut-outs (:class:`warp_sg.shading.cutout.CutoutData`; rays pass through
    holes). A mesh with cut-outs casts a ray per texel (the adaptive levels test hits without them).
    ``occluders``: ``(vertices, triangles)`` of a mesh of the same surface to cast the rays against
    instead (the mesh before a refinement that only split its triangles,
    :mod:`precompute.visibility.refine`: the same hits from a BVH of fewer triangles — on the helmet
    19.5 k instead of 39.7 k, 15 % less ray time, the same maps); ignored with ``cutouts`` (their
    holes are per triangle of this mesh).
    """
    device = resolve_device(device)
    _check_resolutions(resolution, ray_resolution)
    rays = _check_rays(rays)
    v, f, n = validate_mesh(vertices, triangles, normals)
    if n is None:
        raise InputError("compute_ssdf needs per-vertex normals")
    ids = np.arange(len(v)) if vertex_ids is None else np.asarray(vertex_ids, np.int64)
    w0, c0 = time.perf_counter(), time.process_time()
    if occluders is not None and cutouts is None:
        ov, of, _ = validate_mesh(*occluders)
        ctx = _MeshContext(ov, of, None, device)
    else:
        ctx = _MeshContext(v, f, n, device, cutouts)
    if clock is not None:
        clock.add("bvh", time.perf_counter() - w0, time.process_time() - c0)
    R, Rr = int(resolution), int(ray_resolution)
    dirs = texel_direction_array(Rr, device)
    pts = wp.array(v[ids].astype(np.float32), dtype=wp.vec3, device=device)
    nrm = wp.array(n[ids].astype(np.float32), dtype=wp.vec3, device=device)
    vis_out = np.empty((len(ids), Rr * Rr), np.uint8) if return_visibility else None
    if device != "cpu":
        batch = max(batch, int(2 ** 24 // (Rr * Rr)))  # bigger batches on GPUs
    bar = _tqdm(len(ids), "SSDF", progress and len(ids) * Rr * Rr > 1_000_000)
    if out is None:
        out = np.empty((len(ids), R * R), np.float32)
    elif out.shape != (len(ids), R * R) or out.dtype != np.float32:
        raise InputError(f"out must be float32 of shape {(len(ids), R * R)}, got {out.dtype} {out.shape}", where="out")

    def work(s, e):  # each batch writes its own rows: nothing is held twice
        out[s:e] = _ssdf_batch(ctx, dirs, Rr, R, pts, nrm, s, e, device, vis_out, clock, rays, adaptive)

    run_batches(len(ids), batch, work, device, bar)
    if bar is not None:
        bar.close()
    out = out.reshape(len(ids), R, R)
    if return_visibility:
        return out, vis_out.reshape(len(ids), Rr, Rr)
    return out


# ---------------------------------------------------------------------------------------------
# compressed, cached per mesh (the record: precompute.visibility.ssdf_data)
# ---------------------------------------------------------------------------------------------

@contextlib.contextmanager
def _disk_rows(n: int, d: int):
    """A float32 ``(n, d)`` ``numpy.memmap`` in a temporary file of the cache folder, deleted after."""
    import tempfile

    folder = _cache.cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="ssdf-rows-", dir=folder) as tmp:
        mm = np.memmap(f"{tmp}/rows.f32", dtype=np.float32, mode="w+", shape=(int(n), int(d)))
        try:
            yield mm
        finally:
            del mm


def _ssdf_params(resolution, ray_resolution, pca_terms, rays=None, cutouts=None, reps=None):
    if ray_resolution is None:
        ray_resolution = 2 * int(resolution)
    _check_resolutions(resolution, ray_resolution)
    if int(pca_terms) != pca_terms or pca_terms < 1:
        raise InputError(f"pca_terms must be a positive integer, got {pca_terms}", where="pca_terms")
    rays = _check_rays(rays)
    if rays == "adaptive" and (len(levels(int(ray_resolution))) == 1 or cutouts is not None):
        rays = "full"  # no coarse level at this ray resolution (or cut-outs: compute_ssdf): the same maps
    params = {"kind": "ssdf", "version": SSDF_VERSION, "resolution": int(resolution),
              "ray_resolution": int(ray_resolution), "pca_terms": int(pca_terms), "offset": OFFSET_SCALE,
              "rays": rays if rays == "full" else f"adaptive-{ADAPTIVE_VERSION}"}
    if cutouts is not None:  # (the key of a mesh without cut-outs is unchanged)
        params.update(cutouts.key())
    params.update(representative_params(*reps) if reps is not None else {})  # (none within the budget)
    if reps is not None and "representatives" not in params:  # the maps themselves kept (SSDFData.maps)?
        params["maps"] = int(int(reps[0]) * int(resolution) ** 2 * 4 <= decompress_budget())
    return params


def _pca_and_cones(X, normals, R: int, pca_terms: int, clock):
    """``(pca(X, pca_terms), occluder_cones(X, normals, R))``, the cones on a second thread while
    the PCA runs on this one (both only read ``X``; the PCA's BLAS is one thread): stages ``pca``
    and ``cones`` of ``clock``, each with its own thread's CPU."""
    from concurrent.futures import ThreadPoolExecutor

    def timed(name, fn):
        w0, c0 = time.perf_counter(), thread_cpu()
        out = fn()
        clock.add(name, time.perf_counter() - w0, thread_cpu() - c0)
        return out

    with ThreadPoolExecutor(1, thread_name_prefix="ssdf-cones") as ex:
        cones = ex.submit(timed, "cones", lambda: occluder_cones(X, normals, R))
        p = timed("pca", lambda: pca(X, pca_terms))
        return p, cones.result()


def _cones_threaded(X, normals, R: int):
    """:func:`occluder_cones` of the rows ``X``, the two halves on two threads (numpy releases the
    GIL in its loops; BLAS held to one thread each)."""
    from concurrent.futures import ThreadPoolExecutor

    from threadpoolctl import threadpool_limits

    h = len(X) // 2
    if h < 1024:
        return occluder_cones(X, normals, R)
    with threadpool_limits(limits=1, user_api="blas"), ThreadPoolExecutor(1, thread_name_prefix="ssdf-cones") as ex:
        top = ex.submit(occluder_cones, X[h:], normals[h:], R)
        return np.concatenate([occluder_cones(X[:h], normals[:h], R), top.result()])


def ssdf_key(vertices, triangles, normals, *, resolution: int = DEFAULT_RESOLUTION, ray_resolution: int | None = None,
             pca_terms: int = DEFAULT_PCA_TERMS, rays: str | None = None, cutouts=None,
             representatives: int | None = DEFAULT_BUDGET, rep_max_angle: float = DEFAULT_MAX_ANGLE) -> str:
    """The cache key of :func:`ssdf_for_mesh` for these arguments (a content hash; no SSDF is computed)."""
    v, f, n = validate_mesh(vertices, triangles, normals)
    params = _ssdf_params(resolution, ray_resolution, pca_terms, rays, cutouts, (len(v), representatives, rep_max_angle))
    if n is None:
        raise InputError("ssdf_for_mesh needs per-vertex normals")
    return _cache.content_key(v.astype(np.float32), f.astype(np.int32), n.astype(np.float32), params)


def ssdf_for_mesh(vertices, triangles, normals, *, resolution: int = DEFAULT_RESOLUTION,
                  ray_resolution: int | None = None, pca_terms: int = DEFAULT_PCA_TERMS,
                  device="cpu", progress: bool = True, use_cache: bool = True, compute=None,
                  rays: str | None = None, cutouts=None, representatives: int | None = DEFAULT_BUDGET,
                  rep_max_angle: float = DEFAULT_MAX_ANGLE, occluders=None) -> SSDFData:
    """Per-vertex SSDFs of a (merged) mesh, PCA-compressed (eq. 23–24), cached on disk.

    ``ray_resolution`` defaults to ``2 × resolution`` (paper: 4×, 512 → 128). The cache key is a
    content hash of vertices, triangles, normals and all parameters (not the device, not
    ``compute``). ``compute`` replaces :func:`compute_ssdf` (same keyword arguments: ``resolution``,
    ``ray_resolution``, ``device``, ``progress``), e.g. the Dask version of
    :mod:`warp_sg.distributed.precompute`; it must return the same per-vertex SSDFs, so a
    distributed result and a local one are the same cache entry; it casts the default ``rays``
    (:data:`DEFAULT_RAYS`). PCA and the cache write run here. ``stats`` of the result: the build's
    stages and counts (:meth:`compute_ssdf`'s ``clock``; empty on a cache hit). ``cutouts``: the
    mesh's alpha cut-outs (:class:`warp_sg.shading.cutout.CutoutData`; the SSDF's rays pass through holes;
    passed on to ``compute`` as ``cutouts=`` when given). A mesh of more than ``representatives``
    vertices (default :data:`~precompute.visibility.representatives.DEFAULT_BUDGET`; 0 or None: no
    limit) gets its maps at that many representative vertices at most, clustered with normals at
    most ``rep_max_angle`` degrees apart, and transferred to the others
    (:mod:`precompute.visibility.representatives`; ``compute`` is called with ``vertex_ids``).
    Without them, the uncompressed maps are kept where they fit :func:`decompress_budget` (``maps``).
    ``occluders``: a mesh of the same surface the local :func:`compute_ssdf` casts the rays against
    (see there; not part of the cache key: the maps are the surface's).
    """
    v, f, n = validate_mesh(vertices, triangles, normals)
    params = _ssdf_params(resolution, ray_resolution, pca_terms, rays, cutouts, (len(v), representatives, rep_max_angle))
    ray_resolution = params["ray_resolution"]
    if n is None:
        raise InputError("ssdf_for_mesh needs per-vertex normals")
    key = _cache.content_key(v.astype(np.float32), f.astype(np.int32), n.astype(np.float32), params)
    compute = compute_ssdf if compute is None else compute

    clock = StageClock()

    def build():
        R = int(resolution)
        kw = {"clock": clock, "rays": rays, "occluders": occluders} if compute is compute_ssdf else {}
        if cutouts is not None:
            kw["cutouts"] = cutouts
        if compute is not compute_ssdf and _check_rays(rays) != DEFAULT_RAYS:
            raise InputError(f"rays={rays!r} needs the local compute_ssdf", where="rays")
        if "representatives" in params:
            return build_at_representatives(v, f, n, compute, resolution=resolution, ray_resolution=ray_resolution,
                                            pca_terms=pca_terms, budget=representatives, max_angle=rep_max_angle,
                                            device=device, progress=progress, kw=kw, clock=clock,
                                            pca_and_cones=_pca_and_cones)
        with contextlib.ExitStack() as stack:
            if compute is compute_ssdf and len(v) * R * R * 4 > memory_budget():
                kw["out"] = stack.enter_context(_disk_rows(len(v), R * R))
            with clock.stage("ssdf_total"):
                X = compute(v, f, n, resolution=resolution, ray_resolution=ray_resolution, device=device,
                            progress=progress, **kw).reshape(len(v), -1)
            if params.get("maps") and "out" not in kw:  # maps kept: their PCA when someone reads it
                X = np.asarray(X, np.float32)
                with clock.stage("cones"):
                    cones = _cones_threaded(X, n, R)
                return {"maps": X, "cones": cones}
            p, cones = _pca_and_cones(X, n, R, int(pca_terms), clock)
            del X
        return {"mean": p.mean.reshape(R, R), "basis": p.basis.reshape(-1, R, R), "weights": p.weights,
                "pca_rms_error": p.rms_error, "cones": cones}

    data = _cache.load_or_build("ssdf", key, build) if use_cache else build()
    return SSDFData.from_entry(data, resolution=int(resolution), pca_terms=int(pca_terms),
                               ray_resolution=int(ray_resolution), key=key, stats={**clock.as_dict(), **clock.counts})
