r"""Orthonormal frames from a normal, shared by precompute (per-vertex visibility/SSDF) and the
renderer (shading), so that a direction maps to the same local coordinates in both.

Branchless ONB of Duff et al., "Building an Orthonormal Basis, Revisited" (JCGT 2017):
``s = copysign(1, n.z)``, ``a = −1/(s + n.z)``, ``b = n.x n.y a``,
``t = (1 + s n.x² a, s b, −s n.x)``, ``b = (b, s + n.y² a, −n.y)``; the local frame is
(x = t, y = b, z = n), right-handed.
"""
from __future__ import annotations

import numpy as np
import warp as wp


def frame_from_normal(n):
    """numpy: (..., 3) unit normals -> (t, b) each (..., 3)."""
    n = np.asarray(n)
    s = np.where(n[..., 2] >= 0, 1.0, -1.0).astype(n.dtype)
    a = -1.0 / (s + n[..., 2])
    b = n[..., 0] * n[..., 1] * a
    t = np.stack([1.0 + s * n[..., 0] ** 2 * a, s * b, -s * n[..., 0]], axis=-1)
    bb = np.stack([b, s + n[..., 1] ** 2 * a, -n[..., 1]], axis=-1)
    return t, bb


def to_local(v, n):
    """numpy: world directions ``v`` into the frame of normal ``n`` (z = n)."""
    t, b = frame_from_normal(n)
    return np.stack([np.sum(v * t, -1), np.sum(v * b, -1), np.sum(v * n, -1)], axis=-1)


def to_world(v, n):
    t, b = frame_from_normal(n)
    return v[..., :1] * t + v[..., 1:2] * b + v[..., 2:3] * np.asarray(n)


@wp.func
def frame_tangent(n: wp.vec3) -> wp.vec3:
    s = wp.where(n[2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + n[2])
    b = n[0] * n[1] * a
    return wp.vec3(1.0 + s * n[0] * n[0] * a, s * b, -s * n[0])


@wp.func
def frame_bitangent(n: wp.vec3) -> wp.vec3:
    s = wp.where(n[2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + n[2])
    b = n[0] * n[1] * a
    return wp.vec3(b, s + n[1] * n[1] * a, -n[1])


@wp.func
def frame_basis(n: wp.vec3):
    """(t, b) of unit normal n in one pass: the same values as frame_tangent(n), frame_bitangent(n)."""
    s = wp.where(n[2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + n[2])
    b = n[0] * n[1] * a
    return wp.vec3(1.0 + s * n[0] * n[0] * a, s * b, -s * n[0]), wp.vec3(b, s + n[1] * n[1] * a, -n[1])


@wp.func
def world_to_local(v: wp.vec3, t: wp.vec3, b: wp.vec3, n: wp.vec3) -> wp.vec3:
    return wp.vec3(wp.dot(v, t), wp.dot(v, b), wp.dot(v, n))


@wp.func
def local_to_world(v: wp.vec3, t: wp.vec3, b: wp.vec3, n: wp.vec3) -> wp.vec3:
    return v[0] * t + v[1] * b + v[2] * n
