r"""Sphere sets fitted to a closed mesh's signed distance: the occluder proxies of curved objects
(:mod:`precompute.visibility.proxies`).

An object that moves shadows the others through the union of its spheres, so what has to match is
the union's silhouette from every direction (the shadow it casts), thin parts included (a bunny's
ears). The union's distance function is

    u(x) = min_i (|x − c_i| − r_i),

exact outside the union (its signed distance there) and a bound inside. The fit minimises, over the
centres and radii,

    E = Σ_j w_j² (clip(u(x_j), −τ, τ) − s_j)²,

with ``s_j`` the mesh's signed distance (negative inside) at sample points ``x_j``
(:func:`sdf_samples`): surface samples (``s = 0``), the same moved ±ε along their normals (``s = ±ε``,
ε = 1 % of the largest extent: the union must end where the surface does, on both sides), and jittered
voxel centres of a grid around the object (``s`` clipped to ±τ, τ = 8 %: nothing sticks out, no hollow
inside). A silhouette of the union then lies within about the fit's residual of the mesh's.

Minimisation (:func:`fit_sphere_set`): each residual depends on its nearest sphere only, so the
Gauss-Newton matrix is block diagonal, one 4×4 block per sphere, and a Levenberg-Marquardt step
solves the blocks apart (:func:`_levenberg_marquardt`). The start is the k-means of the filled voxels
(each cluster a sphere of its volume); a local minimum that leaves a thin part bare is escaped by
swaps (:func:`_swap`): the sphere whose removal raises ``E`` least moves to the candidate that lowers
``E`` most — the candidates are inscribed spheres (interior voxel centres with their distance to the
surface as radius, the inner points of Dou et al. 2022, "Coverage Axis", whose set cover selects such
spheres) — and the set is fitted again while ``E`` drops. The set starts at :data:`MIN_SPHERES` and
grows by :data:`SPHERE_STEP` (the candidates that lower ``E`` most) while the RMS residual
``√(E/N)`` exceeds :data:`SET_TOL` of the extent, up to :data:`MAX_SPHERES`: the per-pixel cost of a
proxy is linear in its sphere count, so an object gets more only when it needs them. Sphere sets that
minimise a distance between the union and the solid: Wang et al. 2006, "Variational sphere set
approximation for solid objects"; Bradshaw & O'Sullivan 2004, "Adaptive medial-axis approximation for
sphere-tree construction".

The result is cached (kind ``sphere_sets``, keyed by the mesh, the parameters and this module's code).
"""
from __future__ import annotations

import numpy as np

#: a sphere set's first size, the step it grows by, and its largest size
MIN_SPHERES, SPHERE_STEP, MAX_SPHERES = 16, 8, 32
#: a sphere set grows until the RMS residual of its fit is below this fraction of the object's extent
SET_TOL = 0.01
#: ε, the surface band's half-width, and τ, where signed distances are clipped (fractions of the extent)
BAND, CLIP = 0.01, 0.08
#: samples: on the surface (each also at ±ε), in the grid around the object, and inscribed candidates
N_SURFACE, N_GRID, N_CANDIDATES = 2000, 6000, 600


def kmeans_spheres(points, k: int, pitch: float) -> np.ndarray:
    """(≤ k, 4) the k-means of voxel centres ``points`` (pitch ``pitch``), each group a sphere at its
    centroid with the group's volume, ``r = (3 N p³ / 4π)^{1/3}``."""
    from scipy.cluster.vq import kmeans2

    k = int(min(k, len(points)))
    cent, lab = kmeans2(np.asarray(points, np.float64), k, minit="++", seed=np.random.default_rng(0), missing="raise")
    cnt = np.bincount(lab, minlength=k)
    keep = cnt > 0
    r = (3.0 * cnt[keep] * pitch ** 3 / (4.0 * np.pi)) ** (1.0 / 3.0)
    return np.hstack([cent[keep], r[:, None]])


def sdf_samples(vertices, triangles, resolution: int = 32, seed: int = 0) -> dict:
    """The targets of :func:`fit_sphere_set` (module docstring): ``X`` (N, 3), ``s`` (N,) the mesh's
    signed distance clipped to ±τ, ``w`` (N,) weights (1 on the surface band, ½ in the grid), ``tau``,
    ``extent``, ``pitch`` (of the voxel grid, ``extent/resolution``), ``voxels`` (the filled voxels'
    centres) and ``candidates`` (C, 4) inscribed spheres. Inside/outside from the filled voxelisation
    (``trimesh``; grid points within half a voxel of the surface are left out), distances to 20 000
    surface samples."""
    import trimesh
    from scipy.spatial import cKDTree

    V = np.asarray(vertices, np.float64)
    mesh = trimesh.Trimesh(V, np.asarray(triangles), process=True)
    ext = float(np.max(np.ptp(V, axis=0)))
    pitch = ext / float(resolution)
    vox = mesh.voxelized(pitch).fill()
    rng = np.random.default_rng(seed)
    grid = np.pad(np.asarray(vox.matrix, bool), 3)
    idx = np.argwhere(np.ones(grid.shape, bool)) - 3.0
    pts = idx @ vox.transform[:3, :3].T + vox.transform[:3, 3] + rng.uniform(-0.3, 0.3, idx.shape) * pitch
    p, fi = trimesh.sample.sample_surface_even(mesh, N_SURFACE, seed=seed)
    dense, _ = trimesh.sample.sample_surface_even(mesh, 20000, seed=seed + 1)
    tree = cKDTree(dense)
    sd = np.where(grid.ravel(), -1.0, 1.0) * tree.query(pts)[0]
    eps, tau = BAND * ext, CLIP * ext
    far = np.flatnonzero((np.abs(sd) > 0.5 * pitch) & (sd < 2.0 * tau))
    far = rng.choice(far, min(N_GRID, len(far)), replace=False)
    nrm = np.asarray(mesh.face_normals)[fi]
    voxels = np.asarray(vox.points, np.float64)
    inner = voxels[rng.choice(len(voxels), min(N_CANDIDATES, len(voxels)), replace=False)]
    return {"X": np.vstack([p, p + eps * nrm, p - eps * nrm, pts[far]]),
            "s": np.concatenate([np.zeros(len(p)), np.full(len(p), eps), np.full(len(p), -eps),
                                 np.clip(sd[far], -tau, tau)]),
            "w": np.concatenate([np.ones(3 * len(p)), np.full(len(far), 0.5)]),
            "tau": tau, "extent": ext, "pitch": pitch, "voxels": voxels,
            "candidates": np.hstack([inner, tree.query(inner)[0][:, None]])}


def union_distance(spheres, X, second: bool = False):
    """``u(x) = min_i |x − c_i| − r_i`` at points ``X`` (N, 3), the nearest sphere's index and the unit
    vector from its centre; with ``second`` also the second smallest ``|x − c_j| − r_j``."""
    S = np.asarray(spheres, np.float64).reshape(-1, 4)
    d2 = np.sum(X * X, 1)[:, None] - 2.0 * (X @ S[:, :3].T) + np.sum(S[:, :3] ** 2, 1)[None]
    sd = np.sqrt(np.maximum(d2, 0.0)) - S[None, :, 3]
    i = np.argmin(sd, 1)
    u = sd[np.arange(len(X)), i]
    v = X - S[i, :3]
    g = v / np.maximum(np.linalg.norm(v, axis=1), 1e-30)[:, None]
    if not second:
        return u, i, g
    two = np.partition(sd, 1, axis=1)[:, 1] if len(S) > 1 else np.full(len(X), np.inf)
    return u, i, g, two


def _residual(u, t):
    return t["w"] * (np.clip(u, -t["tau"], t["tau"]) - t["s"])


def _levenberg_marquardt(S, t, iters: int = 60) -> tuple[np.ndarray, float]:
    """Minimise ``E`` (module docstring) from the spheres ``S``: damped Gauss-Newton steps, one 4×4
    block per sphere (``∂res/∂c = −w (x − c)/|x − c|``, ``∂res/∂r = −w`` for the nearest sphere,
    0 where ``u`` is clipped); a step is kept when it lowers ``E``. Returns the spheres and ``E``."""
    X, K = t["X"], len(S)
    u, i, g = union_distance(S, X)
    cost = float(np.sum(_residual(u, t) ** 2))
    mu, rmin = 1e-3, 1e-4 * t["extent"]
    for _ in range(iters):
        res = _residual(u, t)
        G = np.hstack([-g, -np.ones((len(X), 1))]) * (t["w"] * (np.abs(u) < t["tau"]))[:, None]
        H = np.stack([np.bincount(i, G[:, a] * G[:, b], K) for a in range(4) for b in range(4)], 1).reshape(K, 4, 4)
        b = np.stack([np.bincount(i, G[:, a] * res, K) for a in range(4)], 1)
        diag = np.diagonal(H, axis1=1, axis2=2)
        while True:
            Sn = S - np.linalg.solve(H + mu * (diag[:, :, None] + 1e-12) * np.eye(4), b[..., None])[..., 0]
            Sn[:, 3] = np.maximum(Sn[:, 3], rmin)
            un, i_n, gn = union_distance(Sn, X)
            cn = float(np.sum(_residual(un, t) ** 2))
            if cn < cost:
                done = cn > (1.0 - 1e-4) * cost
                S, u, i, g, cost, mu = Sn, un, i_n, gn, cn, max(mu / 3.0, 1e-7)
                break
            mu *= 4.0
            if mu > 1e6:
                return S, cost
        if done:
            break
    return S, cost


def _gains(u, t) -> np.ndarray:
    """The change of ``E`` (over the subset ``t["rows"]`` of the samples) when each candidate joins
    the set whose distance is ``u`` (``t["D"]``: the candidates' distances at those samples)."""
    rows = t["rows"]
    sub = {"s": t["s"][rows], "w": t["w"][rows], "tau": t["tau"]}
    ur = u[rows]
    return (_residual(np.minimum(ur[None], t["D"]), sub) ** 2).sum(1) - (_residual(ur, sub) ** 2).sum()


def _swap(S, t, cost: float, rounds: int = 8) -> tuple[np.ndarray, float]:
    """Move the sphere whose removal raises ``E`` least (its samples fall to their second nearest) to
    the candidate that lowers ``E`` most, fit again; kept while ``E`` drops."""
    for _ in range(rounds):
        u, i, _, two = union_distance(S, t["X"], second=True)
        loss = np.bincount(i, _residual(two, t) ** 2 - _residual(u, t) ** 2, len(S))
        T = np.delete(S, int(np.argmin(loss)), 0)
        T = np.vstack([T, t["candidates"][int(np.argmin(_gains(union_distance(T, t["X"])[0], t)))]])
        T, c = _levenberg_marquardt(T, t, iters=30)
        if c >= cost:
            break
        S, cost = T, c
    return S, cost


def fit_sphere_set(t, min_spheres: int = MIN_SPHERES, max_spheres: int = MAX_SPHERES,
                   tol: float = SET_TOL) -> tuple[np.ndarray, float]:
    """``(spheres (K, 4), RMS residual / extent)``: the fit to the samples ``t`` of :func:`sdf_samples`
    (module docstring), ``min_spheres ≤ K ≤ max_spheres``."""
    C = t["candidates"]
    rows = np.random.default_rng(1).choice(len(t["X"]), min(3000, len(t["X"])), replace=False)
    t = dict(t, rows=rows, D=np.linalg.norm(t["X"][rows][None] - C[:, None, :3], axis=-1) - C[:, None, 3])
    S = kmeans_spheres(t["voxels"], min(min_spheres, max_spheres), t["pitch"])
    while True:
        S, cost = _levenberg_marquardt(S, t)
        S, cost = _swap(S, t, cost)
        rms = float(np.sqrt(cost / len(t["X"]))) / t["extent"]
        if rms <= tol or len(S) + SPHERE_STEP > max_spheres:
            return S, rms
        u = union_distance(S, t["X"])[0]
        for _ in range(SPHERE_STEP):  # grow: one candidate at a time, each the one that lowers E most
            S = np.vstack([S, C[int(np.argmin(_gains(u, t)))]])
            u = np.minimum(u, np.linalg.norm(t["X"] - S[-1, :3], axis=1) - S[-1, 3])


def sphere_set(vertices, triangles, max_spheres: int = MAX_SPHERES, min_spheres: int = MIN_SPHERES,
               resolution: int = 32) -> np.ndarray:
    """(K, 4) float32 spheres ``(c, r)`` whose union fits a closed-ish mesh (module docstring), cached."""
    from warp_sg.core import cache

    V = np.asarray(vertices, np.float64)
    F = np.asarray(triangles, np.int64)
    key = cache.content_key(V.astype(np.float32), F.astype(np.int32),
                            {"max": int(max_spheres), "min": int(min_spheres), "res": int(resolution),
                             "code": cache.code_key(__name__)})

    def build():
        t = sdf_samples(V, F, resolution)
        if len(t["voxels"]) < 2:  # a sliver: one sphere around its vertices
            c = V.mean(0)
            return {"spheres": np.array([[*c, max(float(np.max(np.linalg.norm(V - c, axis=1))), 1e-6)]])}
        return {"spheres": fit_sphere_set(t, min_spheres, max_spheres)[0]}

    return np.asarray(cache.load_or_build("sphere_sets", key, build)["spheres"], np.float32)


__all__ = ["sphere_set", "fit_sphere_set", "sdf_samples", "union_distance", "kmeans_spheres", "MIN_SPHERES",
           "SPHERE_STEP", "MAX_SPHERES", "SET_TOL"]
