r"""Test references of the precompute: brute-force answers the fast paths are checked against.

* Test scenes: :func:`plane_box_scene` (a tessellated floor with a cube on it), :func:`bowl_scene`
  (the inside of a hemispherical bowl).
* :func:`brute_force_ssdf`: eq. 23 on a binary visibility map by exhaustive search.
* :func:`sg_visibility_reference`: ``⟨G(·; p, λ, 1), V_x⟩`` by ray casting — ``∫G · E_{i∼G}[V_x(i)]``
  with stratified SG-distributed directions (``cos θ = 1 + ln(1 − u(1 − e^{−2λ}))/λ``) and exact
  BVH visibility (directions below the vertex's horizon are invisible).
* :func:`product_error`: error of the SSDF product ``fh(SSDF_x(p), λ)`` against that reference,
  normalised by ``fh(π/2, λ)`` (the unshadowed hemisphere integral), per λ.

Used by the tests and by ``warp_sg.tools.bench_precompute``; production code does not import this module.
"""
from __future__ import annotations

import numpy as np

from precompute.visibility.rays import ray_visibility
from precompute.visibility.ssdf_wp import lookup_np, texel_directions
from warp_sg.numeric.onb import to_world
from warp_sg.sg.fh import fh_hemisphere, fh_ratio_table_np

# ---------------------------------------------------------------------------------------------
# scenes
# ---------------------------------------------------------------------------------------------

def plane_box_scene(n: int = 20, size: float = 4.0, box: float = 1.0):
    """Floor ``[−size/2, size/2]²`` (y = 0, n×n vertices, normals +y) plus a cube of edge ``box``
    standing on it at the origin. Returns ``(vertices, triangles, normals)``; floor vertices first."""
    import trimesh

    g = np.linspace(-size / 2, size / 2, n)
    X, Z = np.meshgrid(g, g, indexing="ij")
    V = np.stack([X.ravel(), np.zeros(X.size), Z.ravel()], -1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.stack([a, d, c], -1), np.stack([a, c, b], -1)])
    N = np.tile([0.0, 1.0, 0.0], (len(V), 1))
    bx = trimesh.creation.box(extents=[box, box, box])
    bx.apply_translation([0, box / 2, 0])
    return (np.concatenate([V, bx.vertices]), np.concatenate([F, bx.faces + len(V)]),
            np.concatenate([N, bx.vertex_normals]))


def bowl_scene(subdivisions: int = 3, depth: float = 0.0):
    """Inside of a unit hemispherical bowl (opening up, +y): an icosphere's lower part
    ``y ≤ depth`` with inward normals. Returns ``(vertices, triangles, normals)``."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    keep_face = (s.vertices[s.faces][:, :, 1] <= depth + 1e-9).all(axis=1)
    faces = s.faces[keep_face]
    used = np.unique(faces)
    remap = -np.ones(len(s.vertices), np.int64)
    remap[used] = np.arange(len(used))
    V = s.vertices[used]
    F = remap[faces][:, ::-1]
    return V, F, -V / np.linalg.norm(V, axis=1, keepdims=True)


# ---------------------------------------------------------------------------------------------
# brute-force SSDF
# ---------------------------------------------------------------------------------------------

def brute_force_ssdf(visibility: np.ndarray) -> np.ndarray:
    """Reference for tests: eq. 23 on a binary map (R, R) by exhaustive search over all boundary
    midpoints (O(R⁴), numpy) with the same discretisation as the kernels (horizon included)."""
    vis = np.asarray(visibility).astype(bool)
    R = vis.shape[0]
    d = texel_directions(R)
    mids = []
    for axis in (0, 1):
        a = vis[:-1, :] if axis == 0 else vis[:, :-1]
        b = vis[1:, :] if axis == 0 else vis[:, 1:]
        da = d[:-1, :] if axis == 0 else d[:, :-1]
        db = d[1:, :] if axis == 0 else d[:, 1:]
        m = (da + db)[a != b]
        mids.append(m / np.linalg.norm(m, axis=-1, keepdims=True))
    mids = np.concatenate(mids)
    flat = d.reshape(-1, 3)
    if len(mids):
        dist = np.arccos(np.clip(flat @ mids.T, -1, 1)).min(axis=1)
    else:
        dist = np.full(len(flat), np.pi / 2)
    dist = np.minimum(dist, np.pi / 2)
    elev = np.arcsin(np.clip(flat[:, 2], 0, 1))
    out = np.where(vis.ravel(), np.minimum(dist, elev), -dist)
    return out.reshape(R, R).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# brute-force reference of the SSDF product
# ---------------------------------------------------------------------------------------------

def _fibonacci_lattice(m: int, shift):
    k = np.arange(m)
    u = ((k + 0.5) / m + shift[0]) % 1.0
    v = (k * 0.6180339887498949 + shift[1]) % 1.0
    return u, v


def sample_sg(p, lam, m: int, rng):
    """``m`` stratified directions distributed ∝ G(·; p, λ) for each axis/sharpness: (..., m, 3)."""
    p = np.asarray(p, np.float64)
    lam = np.asarray(lam, np.float64)
    u, v = _fibonacci_lattice(m, rng.random(2))
    lam_ = lam[..., None]
    cos_t = 1.0 + np.log1p(-u * -np.expm1(-2.0 * lam_)) / lam_
    cos_t = np.clip(cos_t, -1.0, 1.0)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t**2))
    phi = 2.0 * np.pi * v
    local = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], -1)  # about +z
    pz = np.broadcast_to(p[..., None, :], local.shape)
    return to_world(local, pz)


def sg_visibility_reference(vertices, triangles, normals, vertex_ids, axes, lams, *, samples: int = 1024,
                            device="cpu", seed: int = 0):
    """``⟨G(·; p, λ, 1), V_x⟩`` by ray casting. ``axes`` (n, A, 3) world unit axes per vertex,
    ``lams`` (L,). Returns (n, A, L)."""
    rng = np.random.default_rng(seed)
    V = np.asarray(vertices, np.float64)
    N = np.asarray(normals, np.float64)
    N = N / np.linalg.norm(N, axis=1, keepdims=True)
    ids = np.asarray(vertex_ids)
    axes = np.asarray(axes, np.float64)
    lams = np.asarray(lams, np.float64)
    n, A = axes.shape[:2]
    L = len(lams)
    P = np.broadcast_to(axes[:, :, None, :], (n, A, L, 3))
    LL = np.broadcast_to(lams, (n, A, L))
    dirs = sample_sg(P, LL, samples, rng)  # (n, A, L, m, 3)
    org = np.broadcast_to(V[ids][:, None, None, None, :], dirs.shape)
    nrm = np.broadcast_to(N[ids][:, None, None, None, :], dirs.shape)
    vis = ray_visibility(vertices, triangles, org.reshape(-1, 3), nrm.reshape(-1, 3), dirs.reshape(-1, 3),
                         device=device).reshape(dirs.shape[:-1])
    full = 2.0 * np.pi * -np.expm1(-2.0 * lams) / lams
    return vis.mean(axis=-1) * full


def product_error(vertices, triangles, normals, ssdf_images, vertex_ids, lams, *, n_axes: int = 48,
                  samples: int = 1024, device="cpu", seed: int = 1, near_boundary: bool = True,
                  select_with=None):
    """Error of ``fh(SSDF_x(p), λ)`` (table) against :func:`sg_visibility_reference`.

    ``ssdf_images`` (n, R, R): the SSDFs (reconstructed or exact) of ``vertex_ids``. Axes ``p`` are
    drawn uniformly on each vertex's upper hemisphere; with ``near_boundary`` only axes whose
    |SSDF| < 0.5 rad are kept (elsewhere both are trivially 0 or full); ``select_with`` (n, R', R')
    selects them with other (e.g. exact) SSDFs so that settings are compared on the same axes. Returns dict with
    ``lam``, ``mean`` and ``max`` abs errors (normalised by fh(π/2, λ)), and ``n`` axes used."""
    rng = np.random.default_rng(seed)
    Nn = np.asarray(normals, np.float64)
    Nn = Nn / np.linalg.norm(Nn, axis=1, keepdims=True)
    ids = np.asarray(vertex_ids)
    imgs = np.asarray(ssdf_images, np.float64)
    cand = 8 * n_axes if near_boundary else n_axes
    z = rng.random((len(ids), cand))
    phi = rng.random((len(ids), cand)) * 2 * np.pi
    r = np.sqrt(1 - z**2)
    loc = np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)  # uniform on the hemisphere
    if near_boundary:
        sel = imgs if select_with is None else np.asarray(select_with, np.float64)
        ts = np.stack([lookup_np(sel[k], loc[k]) for k in range(len(ids))])
        score = np.abs(ts) + 10.0 * (np.abs(ts) > 0.5)
        order = np.argsort(score, axis=1)[:, :n_axes]
        loc = np.take_along_axis(loc, order[..., None], axis=1)
    th = np.stack([lookup_np(imgs[k], loc[k]) for k in range(len(ids))])
    world = to_world(loc, np.broadcast_to(Nn[ids][:, None, :], loc.shape))
    lams = np.asarray(lams, np.float64)
    ref = sg_visibility_reference(vertices, triangles, normals, ids, world, lams, samples=samples,
                                  device=device, seed=seed)
    approx = fh_ratio_table_np(th[..., None], lams) * fh_hemisphere(lams)
    err = np.abs(approx - ref) / fh_hemisphere(lams)
    return {"lam": lams, "mean": err.reshape(-1, len(lams)).mean(0), "max": err.reshape(-1, len(lams)).max(0),
            "n": int(err.shape[0] * err.shape[1])}


__all__ = ["plane_box_scene", "bowl_scene", "brute_force_ssdf", "sample_sg", "sg_visibility_reference",
           "product_error"]
