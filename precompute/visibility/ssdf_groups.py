r"""Per-vertex SSDFs of a mesh split into groups that each shadow only themselves.

A scene with moving objects (:mod:`warp_sg.renderer.dynamic_objects`) cannot keep one SSDF of everything:
the SSDF of a floor vertex would hold the shadow of a ball that has since rolled away. Its
visibility is therefore precomputed per **group** — the static objects together, and each
dynamic object alone — and every vertex's map holds only the occluders of its own group::

    SSDF_v(d) = min(θh(d), dist(d, O_g(v)))       (eq. 23, O_g the directions group g blocks)

The occlusion between groups (a ball's shadow on the floor, the floor under the ball) comes at
render time from analytic proxies (:mod:`precompute.visibility.proxies`), combined with these maps by a
minimum — the SSDF of a union of occluders. A dynamic object's map is in its own frame: it moves
with the object unchanged (angles are invariant under a similarity transform).

A group that cannot shadow itself (one closed convex object: ``needs_visibility``; a flat one)
costs no ray: its maps are the horizon ``θh(d) = asin(d_z)`` exactly and its vertices have no
occluder cone. The maps of all groups are PCA-compressed together (one basis, eq. 24) and
cached on disk by content (kind ``ssdf_groups``), like :func:`precompute.visibility.ssdf.ssdf_for_mesh`.
"""
from __future__ import annotations

import numpy as np

from precompute.visibility.occluder_cone import no_cones, occluder_cones
from precompute.visibility.rays import needs_visibility, validate_mesh
from precompute.visibility.ssdf import SSDF_VERSION, _ssdf_params, compute_ssdf
from precompute.visibility.ssdf_data import SSDFData
from precompute.visibility.ssdf_wp import texel_directions
from warp_sg.core import cache as _cache
from warp_sg.core.errors import InputError
from warp_sg.numeric.pca import pca

#: the producing code (this module and the proxies' flatness test): a change rebuilds the entries
_VERSION = _cache.code_key(__name__, "precompute.visibility.proxies")


def group_submesh(vertices, triangles, normals, tri_group, g):
    """``(vertex ids, local triangles)`` of group ``g``: the vertices its triangles use."""
    F = np.asarray(triangles)[np.asarray(tri_group) == g]
    ids = np.unique(F)
    remap = np.full(len(vertices), -1, np.int64)
    remap[ids] = np.arange(len(ids))
    return ids, remap[F]


def horizon_maps(n_vertices: int, resolution: int) -> np.ndarray:
    """(n, R²) float32 SSDFs of unoccluded vertices: the horizon angle ``asin(d_z)`` per texel."""
    z = texel_directions(int(resolution)).reshape(-1, 3)[:, 2]
    return np.broadcast_to(np.arcsin(np.clip(z, 0.0, 1.0)).astype(np.float32), (int(n_vertices), z.size)).copy()


def _flat(points) -> bool:
    """Whether the points lie in one plane (a flat group cannot shadow itself): within
    ``precompute.visibility.proxies.PLANE_TOL`` of the diagonal from their least-squares plane."""
    from precompute.visibility.proxies import PLANE_TOL, fit_plane

    p = np.asarray(points, np.float64)
    return len(p) < 4 or fit_plane(p)[2] <= PLANE_TOL * max(float(np.linalg.norm(np.ptp(p, axis=0))), 1e-30)


def group_casts_rays(vertices, triangles) -> bool:
    """Whether a group's mesh can shadow itself, so that its vertices need rays: not flat
    (:func:`_flat`) and not one closed convex body (:func:`precompute.visibility.rays.needs_visibility`)."""
    v = np.asarray(vertices, np.float64)
    return len(v) > 0 and not _flat(v) and needs_visibility(v, triangles, shadows=True)


def _inputs(vertices, triangles, normals, tri_group, resolution, ray_resolution, pca_terms):
    params = _ssdf_params(resolution, ray_resolution, pca_terms)
    v, f, n = validate_mesh(vertices, triangles, normals)
    if n is None:
        raise InputError("ssdf_for_groups needs per-vertex normals")
    tg = np.asarray(tri_group, np.int64).reshape(-1)
    if tg.shape != (len(f),):
        raise InputError(f"tri_group has {tg.size} entries for {len(f)} triangles", where="tri_group")
    key = _cache.content_key(v.astype(np.float32), f.astype(np.int32), n.astype(np.float32), tg,
                             dict(params, groups=_VERSION, base=SSDF_VERSION))
    return key, (v, f, n, tg), params


def ssdf_groups_key(vertices, triangles, normals, tri_group, *, resolution: int = 32, ray_resolution=None,
                    pca_terms: int = 32) -> str:
    """The cache key of :func:`ssdf_for_groups` for these arguments (nothing is computed)."""
    return _inputs(vertices, triangles, normals, tri_group, resolution, ray_resolution, pca_terms)[0]


def ssdf_for_groups(vertices, triangles, normals, tri_group, *, resolution: int = 32, ray_resolution=None,
                    pca_terms: int = 32, device="cpu", progress: bool = False, compute=None) -> SSDFData:
    """:class:`~precompute.visibility.ssdf.SSDFData` of every vertex, each seeing only the triangles of its
    own group (``tri_group`` (M,) ints; a vertex belongs to the group of the triangles that use
    it: groups share no vertex). ``compute`` replaces :func:`compute_ssdf` as in ``ssdf_for_mesh``."""
    key, (v, f, n, tg), params = _inputs(vertices, triangles, normals, tri_group, resolution, ray_resolution,
                                         pca_terms)
    R = int(resolution)
    compute = compute_ssdf if compute is None else compute

    def build():
        X = horizon_maps(len(v), R)
        cones = no_cones(len(v))
        cones[:, 3] = -1.0  # nothing occludes a vertex of a group that cannot shadow itself
        for g in np.unique(tg):
            ids, F = group_submesh(v, f, n, tg, g)
            if not group_casts_rays(v[ids], F):
                continue
            maps = compute(v[ids], F, n[ids], resolution=R, ray_resolution=params["ray_resolution"], device=device,
                           progress=progress).reshape(len(ids), -1)
            X[ids] = maps
            cones[ids] = occluder_cones(maps, n[ids], R)
        p = pca(X, int(pca_terms))
        return {"mean": p.mean.reshape(R, R), "basis": p.basis.reshape(-1, R, R), "weights": p.weights,
                "pca_rms_error": p.rms_error, "cones": cones}

    data = _cache.load_or_build("ssdf_groups", key, build)
    return SSDFData.from_entry(data, resolution=R, pca_terms=int(pca_terms), ray_resolution=int(params["ray_resolution"]),
                               key=key)


__all__ = ["group_casts_rays", "ssdf_for_groups", "ssdf_groups_key", "group_submesh", "horizon_maps"]
