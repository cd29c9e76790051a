r"""SSDF precompute on a Dask cluster, and the ``warp-sg precompute SCENE [--cluster ...]`` command.

:class:`DaskSSDF` is a drop-in for ``precompute.compute_ssdf`` (``ssdf_for_mesh(..., compute=...)``,
``Renderer(..., ssdf_compute=...)``): the mesh ``(V, F, N)`` is scattered once to every worker
(``broadcast=True``); the vertices are cut into chunks of ``chunk`` consecutive vertices, and one task
per chunk (:func:`ssdf_chunk`) casts the visibility rays and runs the jump-flood SSDF of
:mod:`precompute.visibility.ssdf` for its vertices. Each worker builds the ``wp.Mesh`` BVH of a mesh once and
keeps it (:func:`_mesh_context`, a worker-local cache keyed by the mesh's content hash). The
client places the chunks into the (V, R, R) array as they arrive; PCA and the atomic cache write
stay in ``precompute.ssdf_for_mesh`` on the client, so a distributed result is the same cache
entry as a local one (same key). Per vertex the kernels see the same mesh, the same float32
position and normal and the same texel directions as the local run, and nothing in them depends
on the batch a vertex is in: the distributed SSDFs equal the local ones bit for bit.

Data moved per chunk of ``c`` vertices: to the worker, the task's arguments (a mesh key, two
integers, a few settings: < 1 KiB; the mesh itself travels once per worker,
as float64 positions and normals and int64 triangles: ``48·V + 24·F`` bytes); back to the client,
``c · R² · 4`` bytes (float32 SSDFs: 4 KiB per vertex at R = 32).

Tasks are pure (the same chunk gives the same array), submitted with ``retries``; a worker that
dies mid-chunk has the chunk re-run elsewhere, and as workers never write files, nothing partial
can be left behind (the client writes the cache entry atomically after PCA).
"""
from __future__ import annotations

import threading
import time

import numpy as np

from warp_sg.core.errors import InputError

#: Vertices per task (256 at R = 32: 1 MiB back per task; a few hundred ms of work on one core).
DEFAULT_CHUNK = 256

_MESH_LOCK = threading.Lock()
_MESHES: dict = {}  # (mesh key, ray resolution, device) -> (_MeshContext, texel directions)
_MESH_KEEP = 2


def _mesh_context(mesh, mesh_key, ray_resolution, device):
    """The worker's ``(wp.Mesh context, texel directions)`` of ``mesh``: built once per worker
    process and kept (the two most recent meshes)."""
    from precompute.visibility.rays import _MeshContext
    from precompute.visibility.ssdf_wp import texel_direction_array

    k = (mesh_key, int(ray_resolution), str(device))
    with _MESH_LOCK:
        hit = _MESHES.get(k)
        if hit is None:
            v, f, n = mesh
            hit = (_MeshContext(v, f, n, device), texel_direction_array(int(ray_resolution), device))
            _MESHES[k] = hit
            while len(_MESHES) > _MESH_KEEP:
                _MESHES.pop(next(iter(_MESHES)))
        return hit


def _ssdf_rows(ctx, dirs, Rr, R, pts, nrm, s, e, device):
    """SSDFs of rows ``s..e`` of ``pts``/``nrm`` (the local kernels, ``precompute.visibility.ssdf._ssdf_batch``)."""
    from precompute.visibility.ssdf import _ssdf_batch

    return _ssdf_batch(ctx, dirs, Rr, R, pts, nrm, s, e, device)


def ssdf_chunk(mesh, mesh_key: str, rows, resolution: int, ray_resolution: int, device: str,
               version: str, batch: int = 256) -> np.ndarray:
    """Task: float32 SSDFs ``(m, R²)`` of the scattered mesh's vertices ``rows`` (a ``(start, stop)``
    range or an array of m vertex ids)."""
    import warp as wp

    from warp_sg.core.device import resolve_device
    from warp_sg.distributed.cluster import ensure_version

    ensure_version(version)
    device = resolve_device(device)
    ctx, dirs = _mesh_context(mesh, mesh_key, ray_resolution, device)
    v, _, n = mesh
    sel = slice(*rows) if isinstance(rows, tuple) else np.asarray(rows, np.int64)
    pts = wp.array(v[sel].astype(np.float32), dtype=wp.vec3, device=device)
    nrm = wp.array(n[sel].astype(np.float32), dtype=wp.vec3, device=device)
    m = len(pts)
    parts = [_ssdf_rows(ctx, dirs, int(ray_resolution), int(resolution), pts, nrm, s, min(s + batch, m), device)
             for s in range(0, m, batch)]  # serially: Dask runs one task per worker thread
    return np.concatenate(parts) if parts else np.zeros((0, int(resolution) ** 2), np.float32)


class DaskSSDF:
    """``precompute.compute_ssdf`` on a Dask ``client`` (see the module docstring).

    ``chunk``: vertices per task; ``resources``: worker resources every task needs (e.g.
    ``{"GPU": 1}`` with ``device="cuda"``); ``retries``: per task. ``stats`` after a call: tasks,
    bytes returned per chunk, seconds."""

    def __init__(self, client, chunk: int = DEFAULT_CHUNK, retries: int | None = None, resources: dict | None = None):
        from warp_sg.distributed.cluster import RETRIES

        if int(chunk) < 1:
            raise InputError(f"chunk must be >= 1, got {chunk}", where="chunk")
        self.client = client
        self.chunk = int(chunk)
        self.retries = RETRIES if retries is None else int(retries)
        self.resources = resources
        self.stats: dict = {}

    def __call__(self, vertices, triangles, normals, *, resolution, ray_resolution, device="cpu", progress=True,
                 vertex_ids=None, cutouts=None):
        from precompute.visibility.rays import _tqdm, validate_mesh
        from precompute.visibility.ssdf import _check_resolutions
        from warp_sg.core.cache import content_key
        from warp_sg.distributed.cluster import gather_in_order, project_version

        if cutouts is not None:
            raise InputError("the distributed SSDF precompute does not see through alpha cut-outs (glTF alphaMode "
                             "MASK); compute it without --cluster", where="cutouts")
        t0 = time.perf_counter()
        _check_resolutions(resolution, ray_resolution)
        v, f, n = validate_mesh(vertices, triangles, normals)
        if n is None:
            raise InputError("the distributed SSDF precompute needs per-vertex normals")
        if len(f) == 0:
            from warp_sg.core.errors import MeshError

            raise MeshError("mesh has no triangles (nothing to cast rays against)")
        ids = None if vertex_ids is None else np.asarray(vertex_ids, np.int64).reshape(-1)
        if ids is not None and ids.size and (ids.min() < 0 or ids.max() >= len(v)):
            raise InputError(f"vertex ids out of range (mesh has {len(v)} vertices)", where="vertex_ids")
        count = len(v) if ids is None else len(ids)
        R, Rr = int(resolution), int(ray_resolution)
        mesh_key = content_key(v, f, n)
        mesh_f = self.client.scatter([(v, f, n)], broadcast=True, hash=False)[0]
        version = project_version()
        ranges = [(s, min(s + self.chunk, count)) for s in range(0, count, self.chunk)]
        dev = str(device)
        tag = "" if ids is None else content_key(ids)[:8] + "-"
        futs = [self.client.submit(ssdf_chunk, mesh_f, mesh_key, (s, e) if ids is None else ids[s:e], R, Rr, dev,
                                   version, retries=self.retries, resources=self.resources,
                                   key=f"warp-sg-ssdf-{mesh_key[:16]}-{tag}{R}-{Rr}-{s}-{e}")
                for s, e in ranges]
        out = np.empty((count, R * R), np.float32)
        bar = _tqdm(count, "SSDF (dask)", progress and count * Rr * Rr > 1_000_000)

        def place(i, block):
            s, e = ranges[i]
            out[s:e] = block
            if bar is not None:
                bar.update(e - s)

        try:
            gather_in_order(futs, None, place)
        finally:
            if bar is not None:
                bar.close()
            mesh_f.release()
        self.stats = {"tasks": len(ranges), "chunk": self.chunk, "bytes_per_chunk": self.chunk * R * R * 4,
                      "mesh_bytes_per_worker": int(v.nbytes + f.nbytes + n.nbytes),
                      "seconds": time.perf_counter() - t0}
        return out.reshape(count, R, R)


def renderer(scene, device=None, progress=False, cluster=None):
    """A :class:`~warp_sg.renderer.renderer.Renderer` of ``scene`` whose SSDFs are computed on ``cluster``
    (a spec, Client or cluster object; ``None``: locally, without Dask)."""
    from warp_sg.renderer.renderer import Renderer

    if cluster is None:
        return Renderer(scene, device=device, progress=progress)
    from warp_sg.distributed.cluster import connect

    with connect(cluster) as client:
        return Renderer(scene, device=device, progress=progress, ssdf_compute=DaskSSDF(client))


# --------------------------------------------------------------------------------------------
# CLI: warp-sg precompute SCENE [--cluster ...]
# --------------------------------------------------------------------------------------------
def add_cli_arguments(p) -> None:
    from warp_sg.core.device import add_device_argument
    from warp_sg.distributed.cluster import add_cluster_argument

    p.add_argument("scene", help="scene file (TOML)")
    add_device_argument(p)
    add_cluster_argument(p)
    p.add_argument("--chunk", type=int, default=DEFAULT_CHUNK, help=f"vertices per task (default {DEFAULT_CHUNK})")
    p.add_argument("--no-progress", action="store_true", help="hide progress bars")


def cli_main(args) -> int:
    """Fill the disk cache for SCENE (refinement, SSDFs + PCA, environment fits) and print where."""
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.scene.loader import load_scene

    if args.chunk < 1:
        raise InputError(f"must be >= 1, got {args.chunk}", where="--chunk")
    scene = load_scene(args.scene)
    t0 = time.perf_counter()
    compute = None
    if args.cluster:
        from warp_sg.distributed.cluster import connect

        with connect(args.cluster) as client:
            compute = DaskSSDF(client, chunk=args.chunk)
            r = Renderer(scene, device=args.device, progress=not args.no_progress, ssdf_compute=compute)
            workers = len(client.scheduler_info().get("workers", {}))
    else:
        r = Renderer(scene, device=args.device, progress=not args.no_progress)
        workers = 0
    seconds = time.perf_counter() - t0
    where = f"on {workers} Dask worker(s)" if args.cluster else "locally"
    if r.ssdf is not None:
        from warp_sg.core.cache import entry_path

        print(f"SSDFs of {len(r.geometry.vertices)} vertices ({r.ssdf.resolution}², {r.ssdf.pca_terms} PCA terms) "
              f"{where}: {entry_path('ssdf', r.ssdf.key)}")
    else:
        print("the scene needs no SSDFs (shadows off or a single convex object)")
    print(f"precompute {seconds:.2f} s")
    return 0


__all__ = ["DaskSSDF", "ssdf_chunk", "renderer", "DEFAULT_CHUNK", "add_cli_arguments", "cli_main"]
