"""Cube-map geometry of the ΓL pyramid (:mod:`precompute.environment.prefilter`): six faces +X, −X, +Y, −Y, +Z,
−Z, a direction ``d = major + a·U + b·V`` with face coordinates ``a, b ∈ [−1, 1]`` (OpenGL-like
orientation). ``@wp.func`` :func:`cube_dir` / :func:`cube_face_of` and their numpy twins.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import numpy as np
import warp as wp

# --------------------------------------------------------------------------------------------
# Cube faces: d = major + a·U + b·V, a, b ∈ [−1, 1] on the face (OpenGL-like orientation).
# --------------------------------------------------------------------------------------------
_FACE_MAJOR = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
_FACE_U = np.array([[0, 0, -1], [0, 0, 1], [1, 0, 0], [1, 0, 0], [1, 0, 0], [-1, 0, 0]], np.float64)
_FACE_V = np.array([[0, -1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [0, -1, 0], [0, -1, 0]], np.float64)


@wp.func
def cube_dir(face: int, a: float, b: float) -> wp.vec3:
    """Unnormalised direction of face coordinates ``(a, b)`` on ``face`` (+X, −X, +Y, −Y, +Z, −Z)."""
    if face == 0:
        return wp.vec3(1.0, -b, -a)
    if face == 1:
        return wp.vec3(-1.0, -b, a)
    if face == 2:
        return wp.vec3(a, 1.0, b)
    if face == 3:
        return wp.vec3(a, -1.0, -b)
    if face == 4:
        return wp.vec3(a, -b, 1.0)
    return wp.vec3(-a, -b, -1.0)


@wp.func
def cube_face_of(d: wp.vec3) -> wp.vec3:
    """(face, a, b) of direction ``d`` (face as a float), the face of the major axis."""
    ax = wp.abs(d[0])
    ay = wp.abs(d[1])
    az = wp.abs(d[2])
    if ax >= ay and ax >= az:
        if d[0] > 0.0:
            return wp.vec3(0.0, -d[2] / ax, -d[1] / ax)
        return wp.vec3(1.0, d[2] / ax, -d[1] / ax)
    if ay >= az:
        if d[1] > 0.0:
            return wp.vec3(2.0, d[0] / ay, d[2] / ay)
        return wp.vec3(3.0, d[0] / ay, -d[2] / ay)
    if d[2] > 0.0:
        return wp.vec3(4.0, d[0] / az, -d[1] / az)
    return wp.vec3(5.0, -d[0] / az, -d[1] / az)


def cube_dir_numpy(face, a, b):
    """numpy twin of :func:`cube_dir` (unnormalised)."""
    face = np.asarray(face)
    a = np.asarray(a, np.float64)[..., None]
    b = np.asarray(b, np.float64)[..., None]
    return _FACE_MAJOR[face] + a * _FACE_U[face] + b * _FACE_V[face]


def cube_face_of_numpy(d):
    """numpy twin of :func:`cube_face_of`: ``(face int, a, b)``."""
    d = np.asarray(d, np.float64)
    ad = np.abs(d)
    axis = np.where((ad[..., 0] >= ad[..., 1]) & (ad[..., 0] >= ad[..., 2]), 0, np.where(ad[..., 1] >= ad[..., 2], 1, 2))
    comp = np.take_along_axis(d, axis[..., None], -1)[..., 0]
    face = 2 * axis + (comp <= 0)
    m = np.abs(comp)
    a = np.einsum("...k,...k->...", d, _FACE_U[face]) / m
    b = np.einsum("...k,...k->...", d, _FACE_V[face]) / m
    return face, a, b


@wp.func
def bordered_bilinear(texels: wp.array(dtype=wp.vec3), base: int, n: int, a: float, b: float) -> wp.vec3:
    """Bilinear read at face coordinates ``(a, b)`` of an ``n×n`` face stored from ``base`` with a
    one-texel border (row stride ``n + 2``): texel centre ``x_t = (a+1)/2·n − 0.5`` (+1 border), so
    ``x ∈ [0.5, n + 0.5]`` and the border makes every read in range."""
    stride = n + 2
    x = (a + 1.0) * 0.5 * float(n) + 0.5
    y = (b + 1.0) * 0.5 * float(n) + 0.5
    x0 = wp.clamp(int(wp.floor(x)), 0, n)
    y0 = wp.clamp(int(wp.floor(y)), 0, n)
    fx = wp.clamp(x - float(x0), 0.0, 1.0)
    fy = wp.clamp(y - float(y0), 0.0, 1.0)
    i00 = base + y0 * stride + x0
    t0 = texels[i00] * (1.0 - fx) + texels[i00 + 1] * fx
    t1 = texels[i00 + stride] * (1.0 - fx) + texels[i00 + stride + 1] * fx
    return t0 * (1.0 - fy) + t1 * fy


__all__ = ["bordered_bilinear", "cube_dir", "cube_face_of", "cube_dir_numpy", "cube_face_of_numpy"]
