r"""Occlusion fields: what an object hides of the sky of the points around it, by direction.

The diffuse environment term of a receiver near a moving object (:func:`warp_sg.shading.motion_wp.proxy_diffuse`)
needs, per receiver point ``P``, the object's occluded set of directions ``H(P)`` through two of
its moments: its solid angle and its first moment

    Ω(P) = ∫_H dω,        M(P) = ∫_H d dω,

for ``∫_H max(n·d, 0) dω = n·M`` wherever the object lies above the receiver's horizon. One
sphere of the object's mean projected area (:func:`precompute.visibility.proxies.diffuse_sphere`)
has the mean of them over directions, not the object's shape: the floor on the side of the
Stanford bunny's base it is flattest on was 60 % too dark in the shadow centroid's sense.
Kontkanen & Laine 2005 ("Ambient occlusion fields") tabulate such a field in the object's own
frame, around its centre, by direction and distance; this is that table, with the moments instead
of their fitted cap:

* **Directions** ``ω`` from the centre ``c`` (the area centroid of the surface, the diffuse sphere's
  centre): a latitude-longitude grid of ``NTH × NPHI`` cells, uniform in the polar angle ``θ``
  (``ω_z = cos θ``) and in the longitude ``φ`` (cell centres; bilinear between them, wrapped in
  ``φ``, clamped in ``θ``: within 2.8° of a pole the nearest row). Uniform in ``z = cos θ``
  instead (equal area) the rows next to the poles span 23° and the U shape of the tests was 6 %
  off above them.
* **Distances** along ``ω``: ``RINGS`` radii log-spaced from ``r_in(ω)`` — where the ray from
  ``c`` leaves the mesh for the last time, plus 2 % of the bounding radius ``ρ`` — to ``R_FAR ρ``
  (linear in ``log r`` between them).
* **Per node** (the point ``x = c + r ω``) ``(M, Ω) · (r/ρ)²``, by ``RAYS`` rays from ``x``: a spherical
  Fibonacci set in the cone of ``c``'s bounding sphere, ``cos β = √(1 − ρ²/|x − c|²)``, each of
  weight ``2π(1 − cos β)/RAYS`` (the whole sphere where ``x`` is inside it), turned about the cone's
  axis by a per-node hash; a ray counts where ``wp.mesh_query_ray_anyhit`` hits the mesh. Scaled by
  ``r²``, the moments tend to constants far away (the projected area from ``ω`` and its centroid
  direction), so interpolating them in ``r`` is smooth, and beyond ``R_FAR ρ`` they fall as ``1/r²``
  from the last ring.

Lookup (:func:`field_moments`, Warp): the receiver point in the object's frame, ``q = (sR)⁻¹(P − c')/ρ``
(``c'`` the moved centre), gives ``ω = q/|q|`` and ``r = |q|``; the four cells' values at ``r``
(each from its own rings, the distance clamped to its ``r_in``) are blended bilinearly, divided by
``max(r, r_in)²``. Solid angles do not change under a rigid motion with uniform scale, and the
moment turns back to world space by ``R``. The shading uses the cap of the same first moment,
``π sin²α = |M|`` about ``M/|M|``, in Snyder's formula (:func:`warp_sg.shading.motion_wp.cap_cosine_solid_angle`):
exact, ``n·M``, where the occluder is above the receiver's horizon, and a cap's where it straddles.

Cached (kind ``occlusion_fields``; key: the mesh, the grid, the code of this module).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_sg.numeric.fastmath import fast_asin, fast_atan2

#: the direction grid: NTH rows in the polar angle θ, NPHI columns in longitude
NTH = wp.constant(32)
NPHI = wp.constant(64)
#: distances per direction, log-spaced from r_in(ω) to R_FAR bounding radii
RINGS = wp.constant(16)
R_FAR = wp.constant(8.0)
#: the rings' spacing: u_j = j/(RINGS − 1), log(r_j/r_in) = u_j^RING_POW · log(R_FAR/r_in) (denser near the mesh)
RING_POW = wp.constant(1.5)
#: rays per node (a spherical Fibonacci set in the bounding cone)
RAYS = 1024
#: r_in(ω): the mesh's last exit along ω plus this fraction of the bounding radius
SKIN = 0.02
_GOLDEN = wp.constant(2.399963229728653)  # π(3 − √5), the golden angle


@dataclass
class OcclusionField:
    """An object's occlusion field in its rest pose (module docstring): ``centre`` (3,), bounding
    radius ``radius`` ρ, ``r_in`` (NTH·NPHI,) the first ring per cell in units of ρ, and ``table``
    (NTH·NPHI, RINGS, 4) float32: ``(M, Ω)·(r/ρ)²`` at ring ``j`` of cell ``i``."""

    centre: np.ndarray
    radius: float
    r_in: np.ndarray
    table: np.ndarray


def cell_directions(nth: int = NTH, nphi: int = NPHI) -> np.ndarray:
    """(nth·nphi, 3) the unit directions of the grid's cell centres, row-major in (θ, φ)."""
    z = np.cos(np.pi * (np.arange(nth) + 0.5) / nth)
    phi = 2.0 * np.pi * (np.arange(nphi) + 0.5) / nphi
    Z, P = np.meshgrid(z, phi, indexing="ij")
    s = np.sqrt(np.maximum(1.0 - Z * Z, 0.0))
    return np.stack([s * np.cos(P), s * np.sin(P), Z], -1).reshape(-1, 3)


def ring_radii(r_in, rings: int = RINGS, r_far: float = R_FAR) -> np.ndarray:
    """(..., rings) the ring distances (units of ρ) of cells whose first ring is ``r_in``."""
    r0 = np.asarray(r_in, np.float64)[..., None]
    return r0 * (r_far / r0) ** ((np.arange(rings) / (rings - 1)) ** RING_POW)


@wp.func
def _hash01(i: int, salt: int) -> float:
    h = wp.uint32(i) * wp.uint32(747796405) + wp.uint32(salt) * wp.uint32(1103515245) + wp.uint32(1)
    h = (h ^ (h >> wp.uint32(16))) * wp.uint32(73244475)
    h = (h ^ (h >> wp.uint32(16))) * wp.uint32(73244475)
    h = h ^ (h >> wp.uint32(16))
    return float(h & wp.uint32(16777215)) / 16777216.0


@wp.kernel(enable_backward=False)
def _exit_kernel(mesh: wp.uint64, c: wp.vec3, dirs: wp.array(dtype=wp.vec3), far: float, out: wp.array(dtype=float)):
    """The distance from ``c`` along ``dirs[i]`` where the ray leaves the mesh for the last time (0: never in it)."""
    i = wp.tid()
    d = dirs[i]
    q = wp.mesh_query_ray(mesh, c + d * far, -d, far)
    out[i] = 0.0
    if q.result:
        out[i] = far - q.t


@wp.kernel(enable_backward=False)
def _moments_kernel(mesh: wp.uint64, c: wp.vec3, rho: float, points: wp.array(dtype=wp.vec3), n_rays: int,
                    first: int, out: wp.array(dtype=wp.vec4)):
    """``(M, Ω)`` of the mesh seen from ``points[first + i]`` (module docstring)."""
    i = wp.tid() + first
    x = points[i]
    v = c - x
    dist = wp.length(v)
    a = wp.vec3(0.0, 0.0, 1.0)
    cb = float(-1.0)  # cos β: the whole sphere
    if dist > rho * 1.0001:
        a = v / dist
        cb = wp.sqrt(1.0 - (rho / dist) * (rho / dist))
    t = wp.normalize(wp.cross(a, wp.where(wp.abs(a[0]) < 0.9, wp.vec3(1.0, 0.0, 0.0), wp.vec3(0.0, 1.0, 0.0))))
    b = wp.cross(a, t)
    w = 2.0 * wp.pi * (1.0 - cb) / float(n_rays)
    turn = 2.0 * wp.pi * _hash01(i, 1)
    shift = _hash01(i, 2)
    m = wp.vec3(0.0, 0.0, 0.0)
    om = float(0.0)
    for k in range(n_rays):
        z = 1.0 - (1.0 - cb) * (float(k) + shift) / float(n_rays)
        s = wp.sqrt(wp.max(1.0 - z * z, 0.0))
        ph = turn + _GOLDEN * float(k)
        d = a * z + t * (s * wp.cos(ph)) + b * (s * wp.sin(ph))
        if wp.mesh_query_ray_anyhit(mesh, x, d, 1.0e6):
            m += d * w
            om += w
    out[i - first] = wp.vec4(m[0], m[1], m[2], om)


def mesh_moments(vertices, triangles, points, centre, radius, n_rays: int = RAYS, device="cpu") -> np.ndarray:
    """(N, 4) ``(M, Ω)`` of the mesh seen from ``points`` by :func:`_moments_kernel` (rays in the
    cone of the sphere ``(centre, radius)``, which must hold the mesh), batches on the CPU's cores."""
    from precompute.visibility.rays import run_batches

    V = wp.array(np.asarray(vertices, np.float32), dtype=wp.vec3, device=device)
    mesh = wp.Mesh(points=V, indices=wp.array(np.asarray(triangles, np.int32).ravel(), dtype=wp.int32, device=device))
    P = wp.array(np.asarray(points, np.float32).reshape(-1, 3), dtype=wp.vec3, device=device)
    c = wp.vec3(*np.asarray(centre, np.float32))

    def work(s, e):
        out = wp.empty(e - s, dtype=wp.vec4, device=device)
        wp.launch(_moments_kernel, dim=e - s, inputs=[mesh.id, c, float(radius), P, int(n_rays), s, out], device=device)
        return out.numpy()

    parts = run_batches(P.shape[0], 2048, work, device)
    return np.concatenate(parts).astype(np.float64) if parts else np.zeros((0, 4))


def build_field(vertices, triangles, centre, device="cpu") -> OcclusionField:
    """The occlusion field of a mesh around ``centre`` (module docstring), not cached."""
    V = np.asarray(vertices, np.float64)
    c = np.asarray(centre, np.float64)
    rho = 1.001 * float(np.max(np.linalg.norm(V - c, axis=1)))
    D = cell_directions()
    mesh = wp.Mesh(points=wp.array(V.astype(np.float32), dtype=wp.vec3, device=device),
                   indices=wp.array(np.asarray(triangles, np.int32).ravel(), dtype=wp.int32, device=device))
    ex = wp.empty(len(D), dtype=float, device=device)
    wp.launch(_exit_kernel, dim=len(D), inputs=[mesh.id, wp.vec3(*c.astype(np.float32)),
                                                  wp.array(D.astype(np.float32), dtype=wp.vec3, device=device),
                                                  float(2.5 * rho), ex], device=device)
    r_in = np.maximum(ex.numpy().astype(np.float64) / rho, 0.0) + SKIN
    radii = ring_radii(r_in)  # (cells, rings), units of ρ
    X = c + (D[:, None, :] * radii[..., None] * rho).reshape(-1, 3)
    mom = mesh_moments(V, triangles, X, c, rho, device=device).reshape(len(D), RINGS, 4)
    return OcclusionField(centre=c, radius=rho, r_in=r_in.astype(np.float32), table=scaled(mom, D, radii))


def scaled(mom, dirs, radii) -> np.ndarray:
    """(cells, rings, 4) float32: the table's form of the moments ``mom`` (cells, rings, 4) at the nodes
    ``c + r ω`` (``dirs`` (cells, 3) the cells' ω, ``radii`` (cells, rings) r in units of ρ): with
    ``u = −ω`` and ``M = m∥ u + M⊥``, ``(r² m∥ u + r³ M⊥, r² Ω)`` (module docstring)."""
    u = -np.asarray(dirs, np.float64)[:, None, :]
    M = np.asarray(mom, np.float64)[..., :3]
    par = np.sum(M * u, -1, keepdims=True)
    r = np.asarray(radii, np.float64)[..., None]
    out = np.concatenate([r ** 2 * par * u + r ** 3 * (M - par * u), r ** 2 * mom[..., 3:]], -1)
    return out.astype(np.float32)


def occlusion_field(vertices, triangles, centre) -> OcclusionField:
    """:func:`build_field`, cached (kind ``occlusion_fields``)."""
    from warp_sg.core import cache

    V = np.asarray(vertices, np.float32)
    F = np.asarray(triangles, np.int32)
    c = np.asarray(centre, np.float64)
    key = cache.content_key(V, F, c.astype(np.float32), {"grid": [NTH, NPHI, RINGS, R_FAR, RING_POW, RAYS, SKIN],
                                                          "code": cache.code_key(__name__)})
    got = cache.load_or_build("occlusion_fields", key, lambda: _arrays(build_field(V, F, c)))
    return OcclusionField(centre=np.asarray(got["centre"], np.float64), radius=float(got["radius"]),
                          r_in=np.asarray(got["r_in"], np.float32), table=np.asarray(got["table"], np.float32))


def _arrays(f: OcclusionField) -> dict:
    return {"centre": f.centre, "radius": np.array(f.radius), "r_in": f.r_in, "table": f.table}


# --------------------------------------------------------------------------------------------
# lookup
# --------------------------------------------------------------------------------------------
def cell_axes(r_in) -> tuple[np.ndarray, np.ndarray]:
    """What every lookup of a cell shares (:func:`_cell_value`), per cell (the fields' cells one
    object after the other): (cells, 4) float32 ``u = −ω`` of its centre direction
    (:func:`cell_directions`) and ``1/ln(R_FAR/r_in)``, the scale of its rings' ``ln r``; (cells, 2)
    float32 ``(r_in, ln r_in)`` — four sines and cosines and two logarithms per cell and lookup
    otherwise."""
    r0 = np.asarray(r_in, np.float64).reshape(-1)
    n = NTH * NPHI
    u = -np.tile(cell_directions(), (len(r0) // n, 1))
    axes = np.concatenate([u, (1.0 / np.log(float(R_FAR) / r0))[:, None]], -1).astype(np.float32)
    return axes, np.stack([r0, np.log(r0)], -1).astype(np.float32)


@wp.func
def _cell_value(table: wp.array(dtype=wp.vec4), rings: wp.array(dtype=wp.vec2), axes: wp.array(dtype=wp.vec4),
                cell: int, r: float, log_r: float) -> wp.vec4:
    """Cell ``cell``'s ``(M, Ω)`` at distance ``r`` (units of ρ; ``log_r = ln r``): its rings linear in ``log r``
    (clamped to ``[r_in, R_FAR]``), ``m∥`` and ``Ω`` divided by ``max(r, r_in)²``, ``M⊥`` by its cube
    (the table holds ``(r_j² m∥ u + r_j³ M⊥, r_j² Ω)``, :func:`scaled`; ``u = −ω`` of the cell's centre
    and its rings' scale from :func:`cell_axes`)."""
    ax = axes[cell]
    u = wp.vec3(ax[0], ax[1], ax[2])
    ring = rings[cell]
    rr = wp.max(r, ring[0])
    x = wp.clamp((log_r - ring[1]) * ax[3], 0.0, 1.0)  # ln(max(r, r_in)/r_in) / ln(R_FAR/r_in)
    s = wp.pow(x, 1.0 / RING_POW) * float(RINGS - 1)
    j0 = wp.min(int(s), RINGS - 2)
    f = s - float(j0)
    base = cell * RINGS + j0
    v = table[base] * (1.0 - f) + table[base + 1] * f
    m = wp.vec3(v[0], v[1], v[2])
    par = wp.dot(m, u)
    mm = (u * par + (m - u * par) / rr) / (rr * rr)
    return wp.vec4(mm[0], mm[1], mm[2], v[3] / (rr * rr))


@wp.func
def field_moments(table: wp.array(dtype=wp.vec4), rings: wp.array(dtype=wp.vec2), axes: wp.array(dtype=wp.vec4),
                  cell0: int, q: wp.vec3) -> wp.vec4:
    """``(M, Ω)`` at the point ``q`` of the object's frame (its centre at 0, units of its bounding
    radius; ``M`` in the object's frame) of the field whose cells start at ``cell0`` in ``table``
    (``RINGS`` vec4 per cell), ``rings`` and ``axes`` (:func:`cell_axes`; module docstring)."""
    r = wp.max(wp.length(q), 1.0e-9)
    log_r = wp.log(r)
    w = q / r
    # (the polynomial acos and atan2 of warp_sg.numeric.fastmath: ≤ 2e-6 rad, on cells 0.1 rad wide)
    fz = wp.clamp((0.5 * wp.pi - fast_asin(w[2])) / wp.pi * float(NTH) - 0.5, 0.0, float(NTH - 1))
    z0 = wp.min(int(fz), NTH - 2)
    tz = fz - float(z0)
    u = fast_atan2(w[1], w[0]) / (2.0 * wp.pi)
    u = wp.where(u < 0.0, u + 1.0, u)
    fp = u * float(NPHI) - 0.5
    fp = wp.where(fp < 0.0, fp + float(NPHI), fp)
    p0 = wp.min(int(fp), NPHI - 1)
    tp = fp - float(p0)
    p1 = (p0 + 1) % NPHI
    a = cell0 + z0 * NPHI
    b = a + NPHI
    return ((_cell_value(table, rings, axes, a + p0, r, log_r) * (1.0 - tp) + _cell_value(table, rings, axes, a + p1, r, log_r) * tp)
            * (1.0 - tz)
            + (_cell_value(table, rings, axes, b + p0, r, log_r) * (1.0 - tp) + _cell_value(table, rings, axes, b + p1, r, log_r) * tp)
            * tz)


@wp.kernel(enable_backward=False)
def _lookup_kernel(table: wp.array(dtype=wp.vec4), rings: wp.array(dtype=wp.vec2), axes: wp.array(dtype=wp.vec4),
                   q: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec4)):
    i = wp.tid()
    out[i] = field_moments(table, rings, axes, 0, q[i])


def lookup(field: OcclusionField, points, device="cpu") -> np.ndarray:
    """(N, 4) ``(M, Ω)`` of the field at world points of its rest pose (:func:`field_moments`)."""
    q = (np.asarray(points, np.float64).reshape(-1, 3) - field.centre) / field.radius
    out = wp.empty(len(q), dtype=wp.vec4, device=device)
    axes, rings = cell_axes(field.r_in)
    wp.launch(_lookup_kernel, dim=len(q), device=device,
              inputs=[wp.array(field.table.reshape(-1, 4), dtype=wp.vec4, device=device),
                      wp.array(rings, dtype=wp.vec2, device=device), wp.array(axes, dtype=wp.vec4, device=device),
                      wp.array(q.astype(np.float32), dtype=wp.vec3, device=device), out])
    return out.numpy().astype(np.float64)


__all__ = ["OcclusionField", "occlusion_field", "build_field", "field_moments", "lookup", "mesh_moments",
           "cell_directions", "cell_axes", "ring_radii", "NTH", "NPHI", "RINGS", "R_FAR", "RAYS"]
