r"""Built-in primitives: sphere, plane, torus — triangle meshes with normals, UVs and tangents.

Every generator returns a :class:`MeshData` (numpy, float32/int32) in the object's own frame
(before the per-object transform of the scene file):

* ``vertices`` (N, 3), ``normals`` (N, 3) unit, outward; ``uvs`` (N, 2) in [0, 1];
  ``tangents`` (N, 3) unit, ``∂P/∂u`` made orthogonal to the normal (the texture-space x axis
  that normal maps and anisotropic materials use); ``triangles`` (M, 3) int32, counter-clockwise
  seen from the side the normal points to (``(v1 − v0) × (v2 − v0)`` along the normal).
* UV seams duplicate vertices (u = 0 and u = 1 both exist), so textures do not smear.

Parametrisations (+Y up, docs/architecture.md "Conventions")::

    sphere(θ ∈ [0, π], φ ∈ [0, 2π]):  P = c + r (sin θ sin φ, cos θ, sin θ cos φ),  u = φ/2π, v = θ/π
    plane (x, z) ∈ [−sx/2, sx/2] × [−sz/2, sz/2], normal +Y,           u = x/sx + ½, v = z/sz + ½
    torus(φ around +Y, ψ around the tube):
          P = c + ((R + r cos ψ) sin φ, r sin ψ, (R + r cos ψ) cos φ),  u = φ/2π, v = ψ/2π

No Python loops over vertices: index grids are built with numpy.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_sg.core.errors import InputError

PRIMITIVES = ("sphere", "plane", "torus")

#: Accepted parameters (and defaults) of each primitive, used by scene validation.
PRIMITIVE_PARAMS: dict[str, dict] = {
    "sphere": {"center": (0.0, 0.0, 0.0), "radius": 1.0, "resolution": (32, 64)},
    "plane": {"center": (0.0, 0.0, 0.0), "size": (2.0, 2.0), "resolution": (32, 32)},
    "torus": {"center": (0.0, 0.0, 0.0), "major_radius": 1.0, "minor_radius": 0.3, "resolution": (64, 32)},
}


@dataclass
class MeshData:
    """One triangle mesh with per-vertex shading attributes (float32 / int32)."""

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    tangents: np.ndarray | None = None


def _grid_quads(rows: int, cols: int) -> np.ndarray:
    """Two triangles per cell of a (rows+1) × (cols+1) vertex grid, row-major vertex ids.
    Cell (i, j) has corners a=(i,j), b=(i,j+1), c=(i+1,j), d=(i+1,j+1): triangles (a, c, b), (b, c, d)."""
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = i * (cols + 1) + j
    b = a + 1
    c = a + (cols + 1)
    d = c + 1
    t1 = np.stack([a, c, b], -1).reshape(-1, 3)
    t2 = np.stack([b, c, d], -1).reshape(-1, 3)
    return np.stack([t1, t2], 1).reshape(-1, 3).astype(np.int32)


def _res(value, n: int, name: str, lo: int = 1) -> tuple:
    v = np.atleast_1d(np.asarray(value))
    if v.size == 1:
        v = np.repeat(v, n)
    if v.shape != (n,) or not np.all(np.isfinite(v.astype(float))) or np.any(v.astype(float) != np.round(v.astype(float))):
        raise InputError(f"expected {n} integer(s), got {value!r}", where=name)
    if np.any(np.abs(v.astype(float)) > 2.0 ** 31):
        raise InputError(f"expected {n} integer(s) of at most 2^31, got {value!r}", where=name)
    v = v.astype(np.int64)
    if np.any(v < lo):
        raise InputError(f"must be >= {lo}, got {v.tolist()}", where=name)
    from warp_sg.core.watchdog import MAX_TRIANGLES, check_size

    check_size("the primitive", 2 * int(np.prod(v + 1)), MAX_TRIANGLES, f"too finely divided ({' × '.join(map(str, v))})",
               "triangles", where=name)
    return tuple(int(x) for x in v)


def _vec3(value, name) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"expected 3 numbers, got {value!r}", where=name) from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InputError(f"expected 3 finite numbers, got {value!r}", where=name)
    return v


def _positive(value, name) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"expected a number, got {value!r}", where=name) from None
    if not np.isfinite(v) or v <= 0:
        raise InputError(f"must be > 0, got {value!r}", where=name)
    if v > 1e12:  # (MAX_COORDINATE of warp_sg.scene.geometry: float32 shading loses larger objects)
        raise InputError(f"must be at most 1e12, got {value!r}", where=name)
    return v


def _pack(P, N, UV, T, tri) -> MeshData:
    return MeshData(
        vertices=np.ascontiguousarray(P, np.float32),
        triangles=np.ascontiguousarray(tri, np.int32),
        normals=np.ascontiguousarray(N, np.float32),
        uvs=np.ascontiguousarray(UV, np.float32),
        tangents=np.ascontiguousarray(T, np.float32),
    )


def sphere(center=(0.0, 0.0, 0.0), radius=1.0, resolution=(32, 64), where="sphere") -> MeshData:
    """UV sphere: ``resolution = (n_theta, n_phi)`` rings × segments; the pole caps use one
    triangle per segment (no zero-area triangles)."""
    c = _vec3(center, f"{where}.center")
    r = _positive(radius, f"{where}.radius")
    nt, npf = _res(resolution, 2, f"{where}.resolution", lo=3)
    th = np.linspace(0.0, np.pi, nt + 1)
    ph = np.linspace(0.0, 2.0 * np.pi, npf + 1)
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    N = np.stack([np.sin(TH) * np.sin(PH), np.cos(TH), np.sin(TH) * np.cos(PH)], -1).reshape(-1, 3)
    N[: npf + 1] = (0.0, 1.0, 0.0)
    N[-(npf + 1):] = (0.0, -1.0, 0.0)
    P = c + r * N
    UV = np.stack([PH / (2 * np.pi), TH / np.pi], -1).reshape(-1, 2)
    T = np.stack([np.cos(PH), np.zeros_like(PH), -np.sin(PH)], -1).reshape(-1, 3)
    quads = _grid_quads(nt, npf).reshape(nt, npf, 2, 3)
    # Row 0 (top cap): keep (a, c, d) — a and b are both the pole; row nt-1: keep (a, c, b).
    top = quads[0, :, 1].copy()  # (b, c, d): replace b (pole) by a -> (a, c, d)
    top[:, 0] = quads[0, :, 0, 0]
    bottom = quads[-1, :, 0]  # (a, c, b): c is the pole, (a, c, b) is fine, (b, c, d) degenerate
    mid = quads[1:-1].reshape(-1, 3)
    tri = np.concatenate([top, mid, bottom])
    return _pack(P, N, UV, T, tri)


def plane(center=(0.0, 0.0, 0.0), size=(2.0, 2.0), resolution=(32, 32), where="plane") -> MeshData:
    """Rectangle in the XZ plane with normal +Y, ``size = (sx, sz)`` (or one number),
    ``resolution = (nx, nz)`` cells."""
    c = _vec3(center, f"{where}.center")
    s = np.atleast_1d(np.asarray(size, dtype=np.float64))
    if s.size == 1:
        s = np.repeat(s, 2)
    if s.shape != (2,) or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise InputError(f"expected one or two positive numbers, got {size!r}", where=f"{where}.size")
    nx, nz = _res(resolution, 2, f"{where}.resolution")
    u = np.linspace(0.0, 1.0, nx + 1)
    v = np.linspace(0.0, 1.0, nz + 1)
    V, U = np.meshgrid(v, u, indexing="ij")  # rows along z, columns along x
    P = np.stack([(U - 0.5) * s[0], np.zeros_like(U), (V - 0.5) * s[1]], -1).reshape(-1, 3) + c
    N = np.tile([0.0, 1.0, 0.0], (P.shape[0], 1))
    T = np.tile([1.0, 0.0, 0.0], (P.shape[0], 1))
    UV = np.stack([U, V], -1).reshape(-1, 2)
    # grid (a=(i,j), c=(i+1,j)) with rows along +z and columns along +x: (a, c, b) = (x0z0, x0z1, x1z0)
    # has (c-a) × (b-a) = +z × +x = +y. Good.
    tri = _grid_quads(nz, nx)
    return _pack(P, N, UV, T, tri)


def torus(center=(0.0, 0.0, 0.0), major_radius=1.0, minor_radius=0.3, resolution=(64, 32), where="torus") -> MeshData:
    """Torus around +Y: ``resolution = (n_major, n_minor)`` segments."""
    c = _vec3(center, f"{where}.center")
    R = _positive(major_radius, f"{where}.major_radius")
    r = _positive(minor_radius, f"{where}.minor_radius")
    if r >= R:
        raise InputError(f"must be smaller than major_radius ({R}), got {r}", where=f"{where}.minor_radius")
    nM, nm = _res(resolution, 2, f"{where}.resolution", lo=3)
    ph = np.linspace(0.0, 2 * np.pi, nM + 1)
    ps = np.linspace(0.0, 2 * np.pi, nm + 1)
    PH, PS = np.meshgrid(ph, ps, indexing="ij")
    N = np.stack([np.cos(PS) * np.sin(PH), np.sin(PS), np.cos(PS) * np.cos(PH)], -1)
    ring = np.stack([np.sin(PH), np.zeros_like(PH), np.cos(PH)], -1)
    P = (c + R * ring + r * N).reshape(-1, 3)
    T = np.stack([np.cos(PH), np.zeros_like(PH), -np.sin(PH)], -1).reshape(-1, 3)
    UV = np.stack([PH / (2 * np.pi), PS / (2 * np.pi)], -1).reshape(-1, 2)
    tri = _grid_quads(nM, nm)
    # rows along φ, columns along ψ: (c − a) × (b − a) = ∂φ × ∂ψ points along the outward normal.
    return _pack(P, N.reshape(-1, 3), UV, T, tri)


GENERATORS = {"sphere": sphere, "plane": plane, "torus": torus}


def make_primitive(kind: str, params: dict, where: str = "primitive") -> MeshData:
    """Build primitive ``kind`` from its parameter dict (keys of :data:`PRIMITIVE_PARAMS`)."""
    if kind not in GENERATORS:
        raise InputError(f"unknown primitive '{kind}' (use {', '.join(PRIMITIVES)})", where=where)
    return GENERATORS[kind](**params, where=where)


__all__ = ["MeshData", "PRIMITIVES", "PRIMITIVE_PARAMS", "sphere", "plane", "torus", "make_primitive"]
