r"""Occluder proxies of objects: sphere sets and planes, whose SSDF is analytic.

Objects that move (:mod:`warp_sg.renderer.dynamic_objects`) shadow the rest of the scene, and are shadowed
by it, through proxies rather than through precomputed maps (Ren et al. 2006, "Real-time soft
shadows in dynamic scenes using spherical harmonic exponentiation", use sphere sets the same
way). Seen from a point ``P``:

* a **sphere** (centre ``c``, radius ``r``) occludes the cap of half-angle ``α = asin(r/|c − P|)``
  around ``a = (c − P)/|c − P|``; its SSDF (the signed angular distance of a direction ``d`` to
  the occluded set, eq. 23) is exactly ``∠(d, a) − α``;
* a **plane** (unit normal ``m``, offset ``h``: ``m·x + h = 0``, the side of ``P`` visible)
  occludes the half-sphere behind it: SSDF ``asin(σ d·m)``, ``σ = sign(m·P + h)`` — exact for an
  infinite plane, used for flat static objects (a floor) while ``P`` projects inside their
  bounding disk; the diffuse term sees the flat object's own outline (a convex polygon,
  :func:`plane_outline`, its cosine-weighted solid angle by Lambert's formula).

The SSDF of a union of occluders is the minimum of theirs, so a proxy set combines with a
precomputed SSDF by ``min`` before the SSDF × SG product (eq. 30).

The diffuse environment term integrates what a proxy hides, and the caps of a sphere set overlap
(counted once each, a compact object would hide several times its solid angle): it reads instead
the object's **occlusion field** (:mod:`precompute.visibility.occlusion_field`: the solid angle and
first moment of what the mesh hides, ray-cast in the rest pose by direction and distance around
its centre, kept in its frame; Kontkanen & Laine 2005), whose cap of the same first moment holds
the object's own shape from every side. The one sphere of the object's mean projected area
(:func:`diffuse_sphere`; the area ray-cast, :func:`mean_projected_area`, not Cauchy's quarter of
the surface area, which holds only for convex bodies) gives the field's centre, and is the
diffuse term's occluder for an object with one sphere (exact) or without a field.

Fitting (:func:`object_proxies`): a flat object (every vertex within 10⁻⁴ of the bounding diagonal
from its least-squares plane) gets a plane; an object whose vertices lie within 2 % of one sphere
(least squares, algebraic fit) gets that sphere; any other object a **sphere set** whose union fits
the object's signed distance (:mod:`precompute.visibility.sphere_fit`: least squares on samples of the
surface, of a band ±1 % of the extent about it and of a grid around it, from the k-means of its filled
voxels, with swaps towards inscribed spheres; 16 spheres, grown by 8 up to 32 while the fit's RMS
residual exceeds 1 % of the extent), so that its shadow has the object's outline from any direction,
thin parts included. Against a ray cast of the mesh, the silhouettes' IoU over 26 directions
(minimum / mean): the Stanford bunny 0.75 / 0.80 with the former k-means set (16 spheres, each of its
cluster's volume: 18 % of the silhouette over-covered, spheres 8 cm below its base), 0.90 / 0.93
now (24 spheres); the blob 0.81 / 0.84 → 0.98 / 0.98 (16 spheres). The bunny's hard sun shadow in
the benchmark's view (``scripts/moving_accuracy.py``, 256², turned 45° / 120° / 250°): its centroid
2.3 / 2.8 / 5.3 px from the mesh's with the former set, 0.6 / 0.6 / 0.8 px now. Against the
Monte-Carlo reference (docs/benchmarks.md "Objects that move", 2026-12-02): the bunny's shadow
centroid 2.51 / 5.49 / 0.36 → 1.21 / 3.26 / 1.38 px, shadow bias −6.4 / −7.6 / −9.9 → +4.0 / +10.1 /
−1.3 %, lit floor −0.9 → −0.4 %; the blob's lit floor −0.6 → −0.0 %, shadow −5.8 → +2.4 % at 120°
(what was left at 120° was the diffuse term's one sphere near the bunny's base; with the occlusion
field the centroid is 0.95 / 0.98 / 0.48 px).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from precompute.visibility.sphere_fit import MAX_SPHERES, sphere_set

#: a sphere fit is taken when the RMS radial residual is below this fraction of the radius
SPHERE_TOL = 0.02
#: an object is flat when its vertices are within this fraction of its diagonal from one plane
PLANE_TOL = 1e-4


@dataclass
class ObjectProxies:
    """An object's proxies in its rest pose (world space): ``spheres`` (K, 4) ``(c, r)``; or a
    ``plane`` (4,) ``(m, h)`` with its bounding ``disk`` (4,) ``(centre, radius)``."""

    spheres: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.float32))
    #: (4,) the one sphere the diffuse term sees (:func:`diffuse_sphere`); None for a plane
    diffuse: np.ndarray | None = None
    plane: np.ndarray | None = None
    disk: np.ndarray | None = None
    #: (P, 3) the flat object's outline: its vertices' convex hull in the plane, in order
    polygon: np.ndarray | None = None
    #: the occlusion field the diffuse term reads instead of ``diffuse`` (a sphere set's object;
    #: :mod:`precompute.visibility.occlusion_field`, about ``diffuse``'s centre); None: the sphere
    field: object = None


def fit_sphere(points) -> tuple[np.ndarray, float, float]:
    """Least-squares sphere through ``points`` (algebraic fit ``|x|² = 2c·x + k``): ``(c, r, rms)``
    with ``rms`` the RMS of ``|x − c| − r``."""
    X = np.asarray(points, np.float64)
    A = np.hstack([2.0 * X, np.ones((len(X), 1))])
    sol, *_ = np.linalg.lstsq(A, np.sum(X * X, 1), rcond=None)
    c = sol[:3]
    d = np.linalg.norm(X - c, axis=1)
    r = float(np.mean(d))
    return c, r, float(np.sqrt(np.mean((d - r) ** 2)))


def fit_plane(points, normals=None):
    """``(m, h, max distance)`` of the least-squares plane of ``points`` (m oriented along the mean
    of ``normals`` when given)."""
    X = np.asarray(points, np.float64)
    c = X.mean(0)
    _, _, Vt = np.linalg.svd(X - c, full_matrices=False)
    m = Vt[-1]
    if normals is not None and float(np.mean(np.asarray(normals, np.float64), 0) @ m) < 0.0:
        m = -m
    return m, float(-m @ c), float(np.max(np.abs((X - c) @ m)))


def mean_projected_area(vertices, triangles, n_directions: int = 64, n: int = 96) -> float:
    """The object's silhouette area averaged over directions: per direction of a Fibonacci lattice on
    the sphere (antipodes give the same area), the fraction of an ``n × n`` grid of parallel rays over
    its bounding disk that hit the mesh (:func:`precompute.visibility.rays.ray_visibility`) times the
    grid's area. For a convex body it is Cauchy's quarter of the surface area."""
    from precompute.visibility.rays import ray_visibility

    V = np.asarray(vertices, np.float64)
    i = np.arange(n_directions) + 0.5
    phi, th = np.arccos(1.0 - 2.0 * i / n_directions), np.pi * (1.0 + 5.0 ** 0.5) * i
    D = np.stack([np.cos(th) * np.sin(phi), np.cos(phi), np.sin(th) * np.sin(phi)], 1)
    e1 = np.cross(D, np.where(np.abs(D[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(D, e1)
    c = V.mean(0)
    R = 1.01 * float(np.max(np.linalg.norm(V - c, axis=1)))
    u = ((np.arange(n) + 0.5) / n * 2.0 - 1.0) * R
    U, W = (g.ravel()[None, :, None] for g in np.meshgrid(u, u, indexing="ij"))
    O = (c + U * e1[:, None] + W * e2[:, None] - 2.0 * R * D[:, None]).reshape(-1, 3)
    d = np.ascontiguousarray(np.broadcast_to(D[:, None], (n_directions, n * n, 3)).reshape(-1, 3))
    return float(np.mean(ray_visibility(V, triangles, O, d, d) == 0)) * (2.0 * R) ** 2


def diffuse_sphere(vertices, triangles) -> np.ndarray:
    """(4,) float32: the sphere of the same mean projected area ``Ā`` as the object,
    ``r = √(Ā/π)`` (:func:`mean_projected_area`), at its area centroid. The diffuse environment term
    integrates the occluder's solid angle, which a union of overlapping spheres would count once per
    sphere; this one sphere holds it (exact for a sphere). Cauchy's ``Ā = A/4`` (surface area ``A``)
    holds for convex bodies only: a non-convex one hides part of its surface behind itself (the
    Stanford bunny: r = 0.406 against √(A/4π) = 0.426 at its benchmark size), and the floor around it
    would be too dark. Cached (kind ``diffuse_spheres``)."""
    from warp_sg.core import cache

    V = np.asarray(vertices, np.float64)
    F = np.asarray(triangles, np.int64)
    a = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    c = (a[:, None] * V[F].mean(1)).sum(0) / max(a.sum(), 1e-30)
    key = cache.content_key(V.astype(np.float32), F.astype(np.int32), {"code": cache.code_key(__name__)})
    area = cache.load_or_build("diffuse_spheres", key, lambda: {"area": np.array(mean_projected_area(V, F))})["area"]
    return np.array([*c, np.sqrt(float(area) / np.pi)], np.float32)


def plane_outline(points, m) -> np.ndarray:
    """(P, 3) the convex hull of coplanar ``points`` (plane normal ``m``), counter-clockwise about m."""
    from scipy.spatial import ConvexHull

    X = np.asarray(points, np.float64)
    m = np.asarray(m, np.float64)
    e1 = np.cross(m, [1.0, 0.0, 0.0] if abs(m[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(m, e1)
    uv = np.stack([(X - X.mean(0)) @ e1, (X - X.mean(0)) @ e2], 1)
    return X[ConvexHull(uv).vertices]  # (2-D hulls are counter-clockwise in (e1, e2), i.e. about m)


def object_proxies(vertices, triangles, normals=None, max_spheres: int = MAX_SPHERES,
                   allow_plane: bool = True, with_field: bool = True) -> ObjectProxies:
    """The proxies of one object (module docstring); ``allow_plane`` False: a flat object gets
    spheres too (a moving card is not an infinite plane); ``with_field`` False: a sphere set's
    object without its occlusion field (the diffuse term then sees its diffuse sphere)."""
    V = np.asarray(vertices, np.float64)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    m, h, dev = fit_plane(V, normals)
    if allow_plane and dev <= PLANE_TOL * max(diag, 1e-30):
        c = V.mean(0)
        rad = float(np.max(np.linalg.norm(V - c, axis=1)))
        return ObjectProxies(plane=np.array([*m, h], np.float32), disk=np.array([*c, rad], np.float32),
                             polygon=plane_outline(V, m).astype(np.float32))
    c, r, rms = fit_sphere(V)
    if rms <= SPHERE_TOL * r and np.all(np.linalg.norm(V - c, axis=1) <= 1.5 * r):
        one = np.array([*c, r], np.float32)
        return ObjectProxies(spheres=one[None], diffuse=one)
    from precompute.visibility.occlusion_field import occlusion_field

    ds = diffuse_sphere(V, triangles)
    return ObjectProxies(spheres=sphere_set(V, triangles, max_spheres), diffuse=ds,
                         field=occlusion_field(V, triangles, ds[:3]) if with_field else None)


def sphere_ssdf(P, d, spheres) -> np.ndarray:
    """numpy: the SSDF of a sphere set seen from points ``P`` (..., 3) at unit directions ``d``
    (..., 3): ``min_i ∠(d, a_i) − α_i`` (−π/2 where ``P`` is inside a sphere); +π with no sphere."""
    P = np.asarray(P, np.float64)[..., None, :]
    S = np.asarray(spheres, np.float64).reshape(-1, 4)
    if not len(S):
        return np.full(np.broadcast_shapes(P.shape[:-2], np.shape(d)[:-1]), np.pi)
    v = S[:, :3] - P
    dist = np.linalg.norm(v, axis=-1)
    a = v / np.maximum(dist, 1e-30)[..., None]
    ang = np.arccos(np.clip(np.sum(np.asarray(d, np.float64)[..., None, :] * a, -1), -1.0, 1.0))
    alpha = np.arcsin(np.clip(S[:, 3] / np.maximum(dist, 1e-30), 0.0, 1.0))
    return np.where(dist <= S[:, 3], -0.5 * np.pi, ang - alpha).min(-1)


__all__ = ["ObjectProxies", "object_proxies", "fit_sphere", "fit_plane", "sphere_set", "sphere_ssdf", "diffuse_sphere",
           "mean_projected_area",
           "SPHERE_TOL", "PLANE_TOL", "MAX_SPHERES"]
