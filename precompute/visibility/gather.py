r"""The interreflection gather: per receiver vertex, which sender vertices it sees and how much
(a direct-to-indirect transfer, Hašan, Pellacini and Bala 2006, "Direct-to-indirect transfer for
cinematic relighting"; the gathering form of radiosity).

The light a diffuse receiver ``x`` (normal ``n``) gets from the scene's surfaces, per unit of the
cosine-weighted hemisphere, is their radiance ``L`` along the rays that hit them::

    G(x) = (1/π) ∫_{hits} L(y(x, d)) (n·d) dd  ≈  Σ_s T[x, s] B[s],      E_ind(x) = π G(x)

with ``B`` the outgoing (view-independent) radiance of the mesh's vertices. ``T`` is built here
once per mesh, like the SSDFs (the same vertices, normals and ray offset, :mod:`precompute.visibility.rays`):
``N = n²`` cosine-distributed rays per vertex (an ``n × n`` stratified, jittered grid mapped by the
concentric map to the disc and lifted to the hemisphere — Malley's method: each ray has weight
``1/N`` of the cosine-weighted hemisphere). A ray's nearest opaque hit (through the holes of alpha
cut-outs, :func:`warp_sg.shading.cutout.first_opaque_hit`) on face ``f`` at barycentrics
``(b0, b1, b2)`` gives its weight to the face's three vertices, ``b_k/N`` each (``B`` at the hit is
interpolated as the shading interpolates it). Rays that escape give nothing (the environment's
light is the direct term); a ray that meets a face from behind its shading normal gives nothing
either (the side it sees has no radiance of its own here).

**Compression.** Per receiver the weights of the same sender add up; a row keeps its ``K``
heaviest senders (``refs``), and each dropped sender's weight goes to the kept sender of its row
nearest in direction (a cluster of senders seen close together from the receiver: the row keeps its
total weight, and the light stays where it came from; spreading it over the kept senders instead
darkened a contact shadow lit by a ball's underside by 8 %). Stored per reference: the sender (int32), its weight
(float16) and the mean direction of its rays (an octahedral code in 16 bits, for glossy
receivers, :mod:`warp_sg.shading.bounce`): 8 bytes a reference, plus 4 per vertex (the row
offsets).

**Objects that move** (``groups``, as the SSDFs' :mod:`precompute.visibility.ssdf_groups`): the
vertices of each group — the static objects together, each dynamic object alone — gather from
their own group's triangles only. A group's rows then hold under any rigid motion of it (its
directions turn with it); the light between groups is left out of them: after each move the
renderer casts the rows that see a moving object again at the current pose
(:mod:`precompute.visibility.gather_pose`).

Cached on disk (:func:`warp_sg.core.cache.load_or_build`, kind ``gather``) under a content hash of
the mesh, the parameters and this code, beside the SSDF entry of the same mesh: light,
environment, material and camera edits reuse it (the transfer depends on geometry only).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from precompute.visibility.rays import OFFSET_SCALE, _MeshContext, _tqdm, run_batches, validate_mesh
from warp_sg.core import cache as _cache
from warp_sg.core.device import resolve_device
from warp_sg.core.errors import InputError
from warp_sg.numeric.onb import frame_bitangent, frame_tangent, local_to_world
from warp_sg.shading.cutout import Cutouts, first_opaque_hit, no_cutouts

#: rays per vertex (a ``√N × √N`` stratified grid) and references kept per row, by default
DEFAULT_RAYS = 256
DEFAULT_REFS = 192


@wp.func
def cosine_direction(i: int, j: int, n: int, u1: float, u2: float) -> wp.vec3:
    """The local direction of cell ``(i, j)`` of an ``n × n`` grid of the unit square, jittered by
    ``(u1, u2)``: Shirley–Chiu's concentric map to the disc, lifted to the hemisphere (Malley:
    density ``cos θ/π``, so every cell carries ``1/n²`` of the cosine-weighted hemisphere)."""
    a = 2.0 * (float(i) + u1) / float(n) - 1.0
    b = 2.0 * (float(j) + u2) / float(n) - 1.0
    r = float(0.0)
    phi = float(0.0)
    if a * a > b * b:
        r = a
        phi = 0.25 * wp.pi * (b / a)
    elif b != 0.0:
        r = b
        phi = 0.5 * wp.pi - 0.25 * wp.pi * (a / b)
    x = r * wp.cos(phi)
    y = r * wp.sin(phi)
    return wp.vec3(x, y, wp.sqrt(wp.max(1.0 - x * x - y * y, 0.0)))


@wp.kernel(enable_backward=False)
def gather_rays_kernel(mesh: wp.uint64, cut: Cutouts, indices: wp.array(dtype=int), points: wp.array(dtype=wp.vec3),
                       normals: wp.array(dtype=wp.vec3), ids: wp.array(dtype=int), first: int, n: int, offset: float,
                       max_t: float, sender: wp.array3d(dtype=int), weight: wp.array3d(dtype=float),
                       direction: wp.array2d(dtype=wp.vec3)):
    """Ray ``r`` of vertex ``ids[first + k]`` (module docstring): the hit face's vertices
    ``sender[k, r, :]`` with the weights ``b_c/n²`` (0 where the ray escapes or meets a back side)
    and its world direction (``indices``: the triangles of ``mesh``, whose vertices are ``points``)."""
    k, r = wp.tid()
    v = ids[first + k]
    nv = normals[v]
    st = wp.rand_init(v, r)
    d = local_to_world(cosine_direction(r % n, r // n, n, wp.randf(st), wp.randf(st)), frame_tangent(nv),
                       frame_bitangent(nv), nv)
    direction[k, r] = d
    for c in range(3):
        sender[k, r, c] = v
        weight[k, r, c] = 0.0
    hit, t, f, u, w, gn = first_opaque_hit(mesh, cut, points[v] + offset * nv, d, max_t)
    if hit:
        i0 = indices[3 * f]
        i1 = indices[3 * f + 1]
        i2 = indices[3 * f + 2]
        b2 = 1.0 - u - w  # Warp: position = u v0 + v v1 + (1 − u − v) v2
        ns = u * normals[i0] + w * normals[i1] + b2 * normals[i2]
        if wp.dot(ns, d) < 0.0:  # the sender's own side
            s = 1.0 / float(n * n)
            sender[k, r, 0] = i0
            sender[k, r, 1] = i1
            sender[k, r, 2] = i2
            weight[k, r, 0] = u * s
            weight[k, r, 1] = w * s
            weight[k, r, 2] = b2 * s


def octahedral_encode(d: np.ndarray) -> np.ndarray:
    """(n,) uint16 codes of unit directions (n, 3): the octahedral map (Meyer et al. 2010) at 8 bits
    per axis (≤ 0.8° off)."""
    d = np.asarray(d, np.float64)
    d = d / np.maximum(np.abs(d).sum(axis=1, keepdims=True), 1e-30)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    neg = z < 0
    xo = np.where(neg, (1 - np.abs(y)) * np.where(x >= 0, 1.0, -1.0), x)
    yo = np.where(neg, (1 - np.abs(x)) * np.where(y >= 0, 1.0, -1.0), y)
    qx = np.clip(np.rint((xo * 0.5 + 0.5) * 255), 0, 255).astype(np.uint16)
    qy = np.clip(np.rint((yo * 0.5 + 0.5) * 255), 0, 255).astype(np.uint16)
    return (qx | (qy << 8)).astype(np.uint16)


def octahedral_decode(code: np.ndarray) -> np.ndarray:
    """(n, 3) float32 unit directions of :func:`octahedral_encode`'s codes."""
    c = np.asarray(code, np.int64)
    x = (c & 255) / 255.0 * 2 - 1
    y = (c >> 8) / 255.0 * 2 - 1
    z = 1 - np.abs(x) - np.abs(y)
    t = np.maximum(-z, 0.0)
    x = x + np.where(x >= 0, -t, t)
    y = y + np.where(y >= 0, -t, t)
    d = np.stack([x, y, z], axis=1)
    return (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


def compress_rows(sender: np.ndarray, weight: np.ndarray, direction: np.ndarray, refs: int):
    """Rows of ``B`` receivers from their rays' hits ((B, N, 3) senders and
    weights, (B, N, 3) directions): per row the summed weight of each sender, its weight-averaged
    direction, the ``refs`` heaviest kept, each dropped one merged into the nearest kept (module docstring).
    Returns ``(counts (B,), senders, weights, directions)`` in row order."""
    B, N = sender.shape[:2]
    w = weight.reshape(B, -1)
    keep = w > 0
    row = np.broadcast_to(np.arange(B)[:, None], w.shape)[keep]
    snd = sender.reshape(B, -1)[keep].astype(np.int64)
    wk = w[keep].astype(np.float64)
    dk = np.repeat(direction.reshape(B, N, 1, 3), 3, axis=2).reshape(B, -1, 3)[keep]
    key = row.astype(np.int64) << 32 | snd
    uk, inv = np.unique(key, return_inverse=True)
    ws = np.bincount(inv, weights=wk, minlength=len(uk))
    ds = np.stack([np.bincount(inv, weights=wk * dk[:, c], minlength=len(uk)) for c in range(3)], axis=1)
    urow = (uk >> 32).astype(np.int64)
    usnd = (uk & 0xFFFFFFFF).astype(np.int64)
    order = np.lexsort((-ws, urow))  # per row, heaviest first
    urow, usnd, ws, ds = urow[order], usnd[order], ws[order], ds[order]
    ds = ds / np.maximum(np.linalg.norm(ds, axis=1, keepdims=True), 1e-30)
    start = np.searchsorted(urow, np.arange(B))
    rank = np.arange(len(urow)) - start[urow]
    kept = rank < refs
    if not kept.all():
        ws = ws + _merged_weight(urow, ws, ds, kept, start, refs)
    urow, usnd, ws, ds = urow[kept], usnd[kept], ws[kept], ds[kept]
    counts = np.bincount(urow, minlength=B)
    return counts, usnd.astype(np.int32), ws, ds


@wp.kernel(enable_backward=False)
def merge_kernel(start: wp.array(dtype=int), count: wp.array(dtype=int), refs: int, w: wp.array(dtype=float),
                 d: wp.array(dtype=wp.vec3), extra: wp.array(dtype=float)):
    """Row ``tid`` (its references ``start .. start + count − 1``, heaviest first): each reference
    past the first ``refs`` adds its weight to ``extra`` of the kept one nearest in direction."""
    r = wp.tid()
    s = start[r]
    for j in range(s + refs, s + count[r]):
        best = s
        bd = float(-2.0)
        for k in range(s, s + refs):
            c = wp.dot(d[j], d[k])
            if c > bd:
                bd = c
                best = k
        extra[best] = extra[best] + w[j]


def _merged_weight(row, w, d, kept, start, refs: int) -> np.ndarray:
    """The weight each kept reference takes over from the dropped ones of its row: every dropped
    sender's weight goes to the kept sender of its row nearest in direction (the largest ``d·d'``;
    references sorted per row, heaviest first, the first ``refs`` kept): :func:`merge_kernel` on
    the rows that drop any."""
    counts = np.bincount(row, minlength=len(start))
    rows = np.flatnonzero(counts > refs)
    extra = wp.zeros(len(w), dtype=float, device="cpu")
    wp.launch(merge_kernel, dim=len(rows), device="cpu",
              inputs=[wp.array(start[rows].astype(np.int32), dtype=int, device="cpu"),
                      wp.array(counts[rows].astype(np.int32), dtype=int, device="cpu"), int(refs),
                      wp.array(w.astype(np.float32), dtype=float, device="cpu"),
                      wp.array(d.astype(np.float32), dtype=wp.vec3, device="cpu"), extra])
    return extra.numpy().astype(np.float64)


@dataclass
class GatherData:
    """The gather rows in CSR form (module docstring): row ``v``'s references are
    ``offsets[v] .. offsets[v+1] − 1`` of ``senders`` (int32), ``weights`` (float16) and
    ``directions`` (octahedral uint16 codes). ``key``: the cache key; ``stats``: build counts."""

    offsets: np.ndarray
    senders: np.ndarray
    weights: np.ndarray
    directions: np.ndarray
    rays: int
    refs: int
    key: str = ""
    stats: dict = field(default_factory=dict)

    @property
    def n_vertices(self) -> int:
        return int(len(self.offsets) - 1)

    @property
    def nbytes(self) -> int:
        """Bytes of the rows (references and offsets)."""
        return int(sum(a.nbytes for a in (self.offsets, self.senders, self.weights, self.directions)))

    def bytes_per_reference(self) -> float:
        return self.nbytes / max(len(self.senders), 1)

    def row_weight(self) -> np.ndarray:
        """(V,) float64: each row's total weight, the fraction of its cosine-weighted hemisphere that
        sees the scene."""
        rows = np.repeat(np.arange(self.n_vertices), np.diff(self.offsets))
        return np.bincount(rows, weights=self.weights.astype(np.float64), minlength=self.n_vertices)

    def device_arrays(self, device):
        """``(offsets, senders, weights as float32, directions as vec3)`` on ``device``."""
        d = self.directions
        return (wp.array(self.offsets.astype(np.int32), dtype=int, device=device),
                wp.array(np.maximum(self.senders, 0).astype(np.int32) if len(self.senders) else np.zeros(1, np.int32),
                         dtype=int, device=device),
                wp.array(self.weights.astype(np.float32) if len(self.weights) else np.zeros(1, np.float32),
                         dtype=float, device=device),
                wp.array(octahedral_decode(d) if len(d) else np.zeros((1, 3), np.float32), dtype=wp.vec3,
                         device=device))


#: part of the cache key: the code that casts and compresses the rows
GATHER_VERSION = _cache.code_key(__name__, "warp_sg.shading.cutout")


def _check(rays: int, refs: int) -> int:
    n = int(round(np.sqrt(int(rays))))
    if n * n != int(rays) or n < 2:
        raise InputError(f"must be a square of an integer >= 2 (e.g. 64, 256), got {rays}", where="gather rays")
    if int(refs) < 1:
        raise InputError(f"must be >= 1, got {refs}", where="gather refs")
    return n


def gather_key(vertices, triangles, normals, *, rays: int | None = None, refs: int | None = None, cutouts=None,
               groups=None, receivers=None) -> str:
    """The cache key of :func:`gather_for_mesh` (a content hash; nothing is computed)."""
    rays, refs = (DEFAULT_RAYS if rays is None else rays), (DEFAULT_REFS if refs is None else refs)
    v, f, n = validate_mesh(vertices, triangles, normals)
    _check(rays, refs)
    params = {"kind": "gather", "version": GATHER_VERSION, "rays": int(rays), "refs": int(refs),
              "offset": OFFSET_SCALE}
    if cutouts is not None:
        params.update(cutouts.key())
    extra = (() if groups is None else (np.asarray(groups, np.int32),)) + \
        (() if receivers is None else (np.asarray(receivers, np.int64),))
    return _cache.content_key(v.astype(np.float32), f.astype(np.int32), n.astype(np.float32), *extra, params)


def compute_gather(vertices, triangles, normals, *, rays: int = DEFAULT_RAYS, refs: int = DEFAULT_REFS,
                   device="cpu", progress: bool = False, batch: int = 512, cutouts=None, groups=None,
                   receivers=None) -> GatherData:
    """The gather rows of every vertex of the mesh (module docstring), uncached. ``groups``: per
    triangle its group (rows gather from their own group's triangles; module docstring);
    ``receivers``: the vertices that get rows (default all; the others' rows are empty — a mesh
    whose SSDFs were computed at representatives gathers there too, and the renderer blends)."""
    device = resolve_device(device)
    n_side = _check(rays, refs)
    v, f, n = validate_mesh(vertices, triangles, normals)
    if n is None:
        raise InputError("the interreflection gather needs per-vertex normals")
    w0, c0 = time.perf_counter(), time.process_time()
    N = n_side * n_side
    if device != "cpu":
        batch = max(batch, int(2 ** 22 // N))
    bar = _tqdm(len(v), "gather", progress and len(v) * N > 1_000_000)
    if groups is None:
        sets = [(f, np.arange(len(v)))]
    else:
        groups = np.asarray(groups).reshape(-1)
        sets = [(f[groups == k], np.unique(f[groups == k])) for k in np.unique(groups)]
    if receivers is not None:
        keep = np.zeros(len(v), bool)
        keep[np.asarray(receivers, np.int64)] = True
        sets = [(tris, ids[keep[ids]]) for tris, ids in sets]
    counts = np.zeros(len(v), np.int64)
    done = []  # per group: (its receivers, the batches' compressed rows in their order)
    for tris, ids in sets:
        ctx = _MeshContext(v, tris, n, device, None if cutouts is None or groups is not None else cutouts)
        cut = ctx.cutouts if ctx.cutouts is not None else no_cutouts(device)
        ids_w = wp.array(ids.astype(np.int32), dtype=int, device=device)

        def work(s, e, ctx=ctx, cut=cut, ids_w=ids_w):
            B = e - s
            snd = wp.empty((B, N, 3), dtype=int, device=device)
            wgt = wp.empty((B, N, 3), dtype=float, device=device)
            dirs = wp.empty((B, N), dtype=wp.vec3, device=device)
            wp.launch(gather_rays_kernel, dim=(B, N), device=device,
                      inputs=[ctx.mesh.id, cut, ctx.indices, ctx.points, ctx.normals, ids_w, s, n_side, ctx.offset,
                              ctx.max_t, snd, wgt, dirs])
            return compress_rows(snd.numpy(), wgt.numpy(), dirs.numpy(), int(refs))

        parts = run_batches(len(ids), batch, work, device, bar) if len(ids) else []
        if parts:
            counts[ids] = np.concatenate([p[0] for p in parts])
            done.append((ids, parts))
    if bar is not None:
        bar.close()
    offsets = np.zeros(len(v) + 1, np.int32)
    np.cumsum(counts, out=offsets[1:])
    parts = [p for _, ps in done for p in ps]
    # each reference's row; each vertex is one group's, so a stable sort keeps its references together
    row_of = np.concatenate([np.repeat(ids, counts[ids]) for ids, _ in done]) if done else np.zeros(0, np.int64)
    order = np.argsort(row_of, kind="stable")
    senders = np.concatenate([p[1] for p in parts])[order] if parts else np.zeros(0, np.int32)
    weights = np.concatenate([p[2] for p in parts])[order].astype(np.float16) if parts else np.zeros(0, np.float16)
    dirs = np.concatenate([p[3] for p in parts])[order] if parts else np.zeros((0, 3))
    stats = {"gather_s": time.perf_counter() - w0, "gather_cpu_s": time.process_time() - c0,
             "rays_cast": int(len(v) * N), "references": int(len(senders))}
    return GatherData(offsets, senders, weights, octahedral_encode(dirs), int(rays), int(refs), stats=stats)


def gather_for_mesh(vertices, triangles, normals, *, rays: int | None = None, refs: int | None = None,
                    device="cpu", progress: bool = False, use_cache: bool = True, cutouts=None,
                    groups=None, receivers=None) -> GatherData:
    """:func:`compute_gather`, cached on disk (kind ``gather``, key :func:`gather_key`; ``rays``,
    ``refs``: default :data:`DEFAULT_RAYS`, :data:`DEFAULT_REFS`)."""
    rays, refs = (DEFAULT_RAYS if rays is None else rays), (DEFAULT_REFS if refs is None else refs)
    key = gather_key(vertices, triangles, normals, rays=rays, refs=refs, cutouts=cutouts, groups=groups,
                     receivers=receivers)
    built = {}

    def build():
        g = compute_gather(vertices, triangles, normals, rays=rays, refs=refs, device=device, progress=progress,
                           cutouts=cutouts, groups=groups, receivers=receivers)
        built["stats"] = g.stats
        return {"offsets": g.offsets, "senders": g.senders, "weights": g.weights, "directions": g.directions}

    e = _cache.load_or_build("gather", key, build) if use_cache else build()
    return GatherData(np.asarray(e["offsets"]), np.asarray(e["senders"]), np.asarray(e["weights"]),
                      np.asarray(e["directions"]), int(rays), int(refs), key=key, stats=built.get("stats", {}))


__all__ = ["GatherData", "compute_gather", "gather_for_mesh", "gather_key", "compress_rows", "cosine_direction",
           "gather_rays_kernel", "octahedral_encode", "octahedral_decode", "DEFAULT_RAYS", "DEFAULT_REFS",
           "GATHER_VERSION"]
