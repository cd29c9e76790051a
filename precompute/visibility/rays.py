r"""Per-vertex binary visibility of the upper hemisphere by BVH ray queries (paper §5.1–5.2).

For vertex ``x`` with unit normal ``n`` and local frame ``(t, b, n)`` from :mod:`warp_sg.numeric.onb`,
texel ``(j, i)`` of an ``R×R`` Shirley–Chiu concentric map (:mod:`precompute.visibility.ssdf_wp`) holds

    V_x(j, i) = 1  if the ray  x + ε n + s·d_world,  s ∈ (0, ∞)  hits nothing, else 0,

with ``d_world = to_world(concentric_to_dir(a_i, b_j), n)``. The queries use ``wp.Mesh`` BVH
any-hit ray casts (``wp.mesh_query_ray_anyhit``) in one Warp kernel over (vertex, texel).
The self-intersection offset ``ε = offset_scale · (bbox diagonal)`` (default ``1e-4``) scales with
the mesh. A multi-object scene passes its merged mesh. With alpha cut-outs (``cutouts``, a
:class:`warp_sg.shading.cutout.CutoutData` of the mesh) a ray passes through holes: the nearest-hit
queries of :func:`warp_sg.shading.cutout.blocked` replace the any-hit query (``_visibility_cutout_kernel``). On the
CPU disjoint vertex batches run in a
small thread pool (Warp CPU launches are serial per call; several launches scale over cores).
"""
from __future__ import annotations

import concurrent.futures as cf
import threading

import numpy as np
import warp as wp

from precompute.visibility.ssdf_wp import texel_direction_array
from warp_sg.core.device import resolve_device
from warp_sg.core.errors import InputError, MeshError
from warp_sg.core.meshcheck import check_mesh
from warp_sg.core.workers import RAY_THREADS, cpu_workers
from warp_sg.numeric.onb import frame_bitangent, frame_tangent, local_to_world
from warp_sg.shading.cutout import Cutouts, blocked

#: Self-intersection offset along the normal, as a fraction of the bounding-box diagonal.
OFFSET_SCALE = 1e-4


# ---------------------------------------------------------------------------------------------
# input validation
# ---------------------------------------------------------------------------------------------

def validate_mesh(vertices, triangles, normals=None):
    """Return float64 vertices (V,3), int64 triangles (F,3), float64 unit normals (V,3) or None.

    Raises :class:`MeshError` naming the first bad element (:func:`warp_sg.core.meshcheck.check_mesh`;
    a mesh without vertices is an error, one without triangles is checked where rays are cast)."""
    return check_mesh(vertices, triangles, normals, require_vertices=True)


def bbox_diagonal(vertices) -> float:
    v = np.asarray(vertices, np.float64)
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))) if len(v) else 0.0


def needs_visibility(vertices, triangles, shadows: bool = True) -> bool:
    """Whether per-vertex visibility (SSDF) is needed: False when shadows are off, or when the
    (merged) mesh is a single closed convex body (trimesh ``is_convex``: it can't shadow itself).
    A mesh with vertices well on both sides of one of its triangles' planes
    (:func:`_clearly_not_convex`) needs it without trimesh's test (which welds the mesh first:
    0.45 s for the 339 k-vertex ferrari and its ground)."""
    if not shadows:
        return False
    import trimesh

    v, f, _ = validate_mesh(vertices, triangles)
    if len(f) == 0:
        return False
    if _clearly_not_convex(v, f):
        return True
    mesh = trimesh.Trimesh(vertices=v, faces=f, process=True)
    return not bool(mesh.is_convex)


def _clearly_not_convex(v, f, samples: int = 64, rel: float = 1e-2, chunk: int = 8) -> bool:
    """Whether vertices lie more than ``rel`` of the bounding-box diagonal on *both* sides of the
    plane of one of ``samples`` triangles (a fixed random choice; degenerate ones skipped): then no
    convex body has this surface, whatever trimesh's tolerances (a convex body lies on one side of
    each of its faces' planes; trimesh's local test fails at a concave edge, of which a bend this
    size has some). False says nothing: the caller asks trimesh."""
    v = np.asarray(v, np.float64)
    diag = bbox_diagonal(v)
    if diag <= 0.0:
        return False
    idx = np.random.default_rng(0).choice(len(f), min(int(samples), len(f)), replace=False)
    a, b, c = (v[f[idx, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    ln = np.linalg.norm(n, axis=1)
    ok = ln > 1e-12 * diag * diag
    n, a = n[ok] / ln[ok, None], a[ok]
    v32, thr = v.astype(np.float32), rel * diag
    for s in range(0, len(n), chunk):  # (V × chunk distances at a time: a few MB)
        d = v32 @ n[s:s + chunk].T.astype(np.float32) - np.einsum("ij,ij->i", a[s:s + chunk], n[s:s + chunk])[None, :]
        if np.any((d.max(axis=0) > thr) & (d.min(axis=0) < -thr)):
            return True
    return False


# ---------------------------------------------------------------------------------------------
# kernel
# ---------------------------------------------------------------------------------------------

#: hit distance :func:`ray_hit_distance` returns for a ray that escapes
NO_HIT = wp.constant(1.0e30)


@wp.func
def ray_blocked(mesh: wp.uint64, o: wp.vec3, d: wp.vec3, max_t: float) -> bool:
    """Whether the ray ``o + s·d``, ``s ∈ (0, max_t)``, hits the mesh (any hit). Every visibility
    ray of the precompute goes through this function or :func:`ray_hit_distance`: the one place a
    hit test that looks at more than the triangle (e.g. an alpha mask) changes."""
    return wp.mesh_query_ray_anyhit(mesh, o, d, max_t)


@wp.func
def ray_hit_distance(mesh: wp.uint64, o: wp.vec3, d: wp.vec3, max_t: float) -> float:
    """Distance to the nearest hit of the ray ``o + s·d`` (:data:`NO_HIT` if it escapes): the
    same hits as :func:`ray_blocked` (``ray_hit_distance < NO_HIT ⇔ ray_blocked``)."""
    q = wp.mesh_query_ray(mesh, o, d, max_t)
    if q.result:
        return q.t
    return NO_HIT


@wp.func
def vertex_ray_origin(points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3), vi: int,
                      offset: float) -> wp.vec3:
    """Origin of vertex ``vi``'s visibility rays: ``x + ε n``."""
    return points[vi] + offset * normals[vi]


@wp.func
def vertex_ray_direction(normals: wp.array(dtype=wp.vec3), vi: int, local: wp.vec3) -> wp.vec3:
    """World direction of local hemisphere direction ``local`` at vertex ``vi`` (frame of
    :mod:`warp_sg.numeric.onb`)."""
    n = normals[vi]
    return local_to_world(local, frame_tangent(n), frame_bitangent(n), n)


@wp.kernel(enable_backward=False)
def _visibility_kernel(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3),
                       first: int, dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float,
                       out: wp.array2d(dtype=wp.uint8)):
    """out[k, texel] = 1 if the ray from vertex first+k along local dir[texel] escapes."""
    k, tex = wp.tid()
    vi = first + k
    d = vertex_ray_direction(normals, vi, dirs[tex])
    hit = ray_blocked(mesh, vertex_ray_origin(points, normals, vi, offset), d, max_t)
    out[k, tex] = wp.where(hit, wp.uint8(0), wp.uint8(1))


# ---------------------------------------------------------------------------------------------
# alpha cut-outs: the same queries through holes (warp_sg.shading.cutout)
# ---------------------------------------------------------------------------------------------

@wp.kernel(enable_backward=False)
def _visibility_cutout_kernel(mesh: wp.uint64, cut: Cutouts, points: wp.array(dtype=wp.vec3),
                              normals: wp.array(dtype=wp.vec3), first: int, dirs: wp.array(dtype=wp.vec3),
                              offset: float, max_t: float, out: wp.array2d(dtype=wp.uint8)):
    """``_visibility_kernel`` whose rays pass through the holes of alpha cut-outs."""
    k, tex = wp.tid()
    vi = first + k
    n = normals[vi]
    d = local_to_world(dirs[tex], frame_tangent(n), frame_bitangent(n), n)
    hit = blocked(mesh, cut, points[vi] + offset * n, d, max_t)
    out[k, tex] = wp.where(hit, wp.uint8(0), wp.uint8(1))


@wp.kernel(enable_backward=False)
def _ray_cutout_kernel(mesh: wp.uint64, cut: Cutouts, origins: wp.array(dtype=wp.vec3),
                       normals: wp.array(dtype=wp.vec3), dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float,
                       out: wp.array(dtype=wp.uint8)):
    """``_ray_kernel`` whose rays pass through the holes of alpha cut-outs."""
    k = wp.tid()
    n = normals[k]
    d = dirs[k]
    vis = wp.uint8(0)
    if wp.dot(d, n) > 0.0:
        if not blocked(mesh, cut, origins[k] + offset * n, d, max_t):
            vis = wp.uint8(1)
    out[k] = vis


def launch_visibility(ctx, points, normals, first: int, dirs, out) -> None:
    """``out[k, texel]`` = 1 where the ray from vertex ``first + k`` along ``dirs[texel]`` escapes:
    the any-hit kernel, or with the context's cut-outs the one that sees through holes."""
    n_v, n_d = out.shape
    if ctx.cutouts is None:
        wp.launch(_visibility_kernel, dim=(n_v, n_d), device=ctx.device,
                  inputs=[ctx.mesh.id, points, normals, first, dirs, ctx.offset, ctx.max_t, out])
    else:
        wp.launch(_visibility_cutout_kernel, dim=(n_v, n_d), device=ctx.device,
                  inputs=[ctx.mesh.id, ctx.cutouts, points, normals, first, dirs, ctx.offset, ctx.max_t, out])


class _MeshContext:
    """wp.Mesh + per-vertex arrays on a device, shared by the batch workers; ``cutouts`` (a
    :class:`warp_sg.shading.cutout.CutoutData` of the mesh, or None): its alpha cut-outs on the device.
    ``normals`` None: a mesh rays are cast against only (no per-vertex normals kept)."""

    def __init__(self, vertices, triangles, normals, device, cutouts=None):
        self.device = device
        self.points = wp.array(vertices.astype(np.float32), dtype=wp.vec3, device=device)
        self.normals = None if normals is None else wp.array(normals.astype(np.float32), dtype=wp.vec3, device=device)
        self.indices = wp.array(triangles.astype(np.int32).ravel(), dtype=wp.int32, device=device)
        if len(triangles) == 0:
            raise MeshError("mesh has no triangles (nothing to cast rays against)")
        self.mesh = wp.Mesh(points=self.points, indices=self.indices)
        diag = bbox_diagonal(vertices)
        self.offset = OFFSET_SCALE * max(diag, 1e-12)
        self.max_t = 1e3 * max(diag, 1e-12)
        self.cutouts = None if cutouts is None else cutouts.device(triangles, device)


def run_batches(n_items: int, batch: int, work, device: str, progress=None, desc: str = ""):
    """Call ``work(start, stop)`` for consecutive batches; on the CPU several batches run at once
    in a thread pool. Results are returned in batch order. ``progress``: a tqdm bar (ticks by items)."""
    ranges = [(s, min(s + batch, n_items)) for s in range(0, n_items, batch)]
    results = [None] * len(ranges)
    lock = threading.Lock()

    def one(k):
        s, e = ranges[k]
        results[k] = work(s, e)
        if progress is not None:
            with lock:
                progress.update(e - s)

    nw = min(cpu_workers(device, limit=RAY_THREADS), len(ranges))
    if nw <= 1:
        for k in range(len(ranges)):
            one(k)
    elif ranges:
        one(0)  # the first batch alone: kernels compile/load once, not once per thread
        with cf.ThreadPoolExecutor(nw) as ex:
            list(ex.map(one, range(1, len(ranges))))
    return results


def _tqdm(total, desc, enabled):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit="vtx", leave=False)


def hemisphere_visibility(vertices, triangles, normals, resolution: int = 64, *, device="cpu",
                          vertex_ids=None, progress: bool = False, batch: int = 512, cutouts=None) -> np.ndarray:
    """Binary visibility maps ``(n, R, R)`` uint8 (1 = visible) of the upper hemisphere at each vertex.

    ``vertex_ids`` selects vertices (default: all). Texel ``[j, i]`` is the concentric-map texel
    with ``b`` from row ``j`` and ``a`` from column ``i`` (see :mod:`precompute.visibility.ssdf_wp`).
    ``cutouts``: the mesh's alpha cut-outs (:class:`warp_sg.shading.cutout.CutoutData`; rays pass through holes).
    """
    device = resolve_device(device)
    v, f, n = validate_mesh(vertices, triangles, normals)
    if n is None:
        raise InputError("hemisphere_visibility needs per-vertex normals")
    if resolution < 2:
        raise InputError(f"visibility resolution must be >= 2, got {resolution}")
    ids = np.arange(len(v)) if vertex_ids is None else np.asarray(vertex_ids, np.int64)
    if ids.size and (ids.min() < 0 or ids.max() >= len(v)):
        bad = int(ids[(ids < 0) | (ids >= len(v))][0])
        raise InputError(f"vertex id {bad} out of range (mesh has {len(v)} vertices)")
    ctx = _MeshContext(v, f, n, device, cutouts)
    R = int(resolution)
    dirs = texel_direction_array(R, device)
    sel_p = wp.array(v[ids].astype(np.float32), dtype=wp.vec3, device=device)
    sel_n = wp.array(n[ids].astype(np.float32), dtype=wp.vec3, device=device)
    out = np.empty((len(ids), R * R), np.uint8)
    bar = _tqdm(len(ids), "visibility", progress and len(ids) * R * R > 2_000_000)

    def work(s, e):
        buf = wp.empty((e - s, R * R), dtype=wp.uint8, device=device)
        launch_visibility(ctx, sel_p, sel_n, s, dirs, buf)
        out[s:e] = buf.numpy()

    run_batches(len(ids), batch, work, device, bar)
    if bar is not None:
        bar.close()
    return out.reshape(len(ids), R, R)


@wp.kernel(enable_backward=False)
def _ray_kernel(mesh: wp.uint64, origins: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3),
                dirs: wp.array(dtype=wp.vec3), offset: float, max_t: float, out: wp.array(dtype=wp.uint8)):
    k = wp.tid()
    n = normals[k]
    d = dirs[k]
    vis = wp.uint8(0)
    if wp.dot(d, n) > 0.0:
        if not ray_blocked(mesh, origins[k] + offset * n, d, max_t):
            vis = wp.uint8(1)
    out[k] = vis


def ray_visibility(vertices, triangles, origins, normals, directions, *, device="cpu", cutouts=None) -> np.ndarray:
    """Exact visibility (uint8, 1 = escapes) of arbitrary rays ``origins + ε normals + s·directions``
    (all (N, 3), world space); directions below the surface (``d·n ≤ 0``) are invisible.
    Used as the brute-force reference of the SSDF product (tests, bench). ``cutouts``: the mesh's
    alpha cut-outs (:class:`warp_sg.shading.cutout.CutoutData`; rays pass through holes)."""
    device = resolve_device(device)
    v, f, _ = validate_mesh(vertices, triangles)
    o = np.asarray(origins, np.float32).reshape(-1, 3)
    nn = np.broadcast_to(np.asarray(normals, np.float32), o.shape)
    d = np.broadcast_to(np.asarray(directions, np.float32), o.shape)
    ctx = _MeshContext(v, f, np.tile([0.0, 0.0, 1.0], (len(v), 1)), device, cutouts)
    out = wp.empty(len(o), dtype=wp.uint8, device=device)
    rays = [wp.array(o, dtype=wp.vec3, device=device), wp.array(np.ascontiguousarray(nn), dtype=wp.vec3, device=device),
            wp.array(np.ascontiguousarray(d), dtype=wp.vec3, device=device), ctx.offset, ctx.max_t, out]
    if ctx.cutouts is None:
        wp.launch(_ray_kernel, dim=len(o), device=device, inputs=[ctx.mesh.id, *rays])
    else:
        wp.launch(_ray_cutout_kernel, dim=len(o), device=device, inputs=[ctx.mesh.id, ctx.cutouts, *rays])
    return out.numpy()
