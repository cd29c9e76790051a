r"""Rigid motions of scene objects: a 4×4 matrix ``M = [s·R | t; 0 0 0 1]`` (rotation ``R``,
uniform scale ``s > 0``, translation ``t``), applied after an object's own ``translate`` / ``scale``
/ ``rotate`` (``SceneObject.motion``, ``Renderer.set_object_transform``)::

    P' = s R P + t,     n' = R n,     tangent' = R tangent

Only similarity transforms keep per-vertex visibility valid under the motion: an object's own
SSDF (angles between directions) is invariant under ``s R`` and rotates with ``R``
(:mod:`warp_sg.renderer.dynamic_objects`). :func:`check_motion` refuses anything else (shear, mirror,
non-uniform scale, a projective row) with a one-line :class:`~warp_sg.core.errors.SceneError`.
"""
from __future__ import annotations

import numpy as np

from warp_sg.core.errors import SceneError

#: tolerance on ``(A/s)ᵀ(A/s) = I`` (a matrix typed with 6 significant digits passes)
ORTHO_TOL = 1e-4


def check_motion(matrix, where: str = "transform") -> tuple[np.ndarray, float, np.ndarray]:
    """``(R (3, 3), s, t (3,))`` of a 4×4 rigid motion with uniform scale; a 3×4 matrix (the top
    rows) is accepted too. Raises :class:`SceneError` naming ``where`` otherwise."""
    try:
        M = np.asarray(matrix, np.float64)
    except (TypeError, ValueError):
        raise SceneError(f"must be a 4x4 matrix of numbers, got {matrix!r}", where=where) from None
    if M.shape == (3, 4):
        M = np.vstack([M, [0.0, 0.0, 0.0, 1.0]])
    if M.shape != (4, 4):
        raise SceneError(f"must be a 4x4 matrix, got shape {M.shape}", where=where)
    if not np.all(np.isfinite(M)):
        raise SceneError("has a non-finite entry", where=where)
    if not np.allclose(M[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise SceneError(f"last row must be [0, 0, 0, 1], got {M[3].tolist()}", where=where)
    A = M[:3, :3]
    det = float(np.linalg.det(A))
    if not det > 0.0:
        raise SceneError(f"must be a rotation with a positive uniform scale (determinant {det:.3g})", where=where)
    s = det ** (1.0 / 3.0)
    R = A / s
    if np.max(np.abs(R.T @ R - np.eye(3))) > ORTHO_TOL:
        raise SceneError("must be rigid: a rotation, a translation and one uniform scale (no shear, no "
                         "per-axis scale)", where=where)
    # the nearest rotation (SVD), so the normals stay unit after many frames
    U, _, Vt = np.linalg.svd(R)
    return U @ Vt, float(s), M[:3, 3].copy()


def motion_matrix(rotation=None, translation=(0.0, 0.0, 0.0), scale: float = 1.0) -> np.ndarray:
    """The 4×4 matrix of ``P' = scale · rotation · P + translation`` (rotation default identity)."""
    M = np.eye(4)
    M[:3, :3] = float(scale) * (np.eye(3) if rotation is None else np.asarray(rotation, np.float64))
    M[:3, 3] = np.asarray(translation, np.float64)
    return M


def rotation_about(axis, degrees: float) -> np.ndarray:
    """(3, 3) rotation by ``degrees`` about ``axis`` (right-handed, Rodrigues)."""
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    th = np.radians(float(degrees))
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(th) * K + (1.0 - np.cos(th)) * (K @ K)


#: the fields of a motion given by parts (a batch job's ``[frames.objects.NAME]``)
MOTION_FIELDS = ("matrix", "translate", "rotate", "scale", "pivot")


def motion_from_fields(fields: dict, where: str = "objects") -> np.ndarray:
    """The 4×4 motion of ``{"matrix": 4×4}`` or of ``{"translate": t, "rotate": (x°, y°, z°),
    "scale": s, "pivot": p}`` (each optional): ``P' = s R (P − p) + p + t`` with ``R = Rz·Ry·Rx``
    (Euler degrees, as an object's own ``rotate``). Bad fields raise :class:`SceneError`."""
    unknown = sorted(set(fields) - set(MOTION_FIELDS))
    if unknown:
        raise SceneError(f"unknown field(s) {', '.join(unknown)} (use {', '.join(MOTION_FIELDS)})", where=where)
    if "matrix" in fields:
        if len(fields) > 1:
            raise SceneError("give either 'matrix' or translate/rotate/scale/pivot", where=where)
        R, s, t = check_motion(fields["matrix"], where=f"{where}.matrix")
        return motion_matrix(R, t, s)
    def vec(k, default):
        try:
            v = np.asarray(fields.get(k, default), np.float64).reshape(3)
        except (TypeError, ValueError):
            raise SceneError(f"must be 3 numbers, got {fields[k]!r}", where=f"{where}.{k}") from None
        if not np.all(np.isfinite(v)):
            raise SceneError(f"must be finite, got {v.tolist()}", where=f"{where}.{k}")
        return v

    t, p, rot = vec("translate", (0, 0, 0)), vec("pivot", (0, 0, 0)), vec("rotate", (0, 0, 0))
    s = fields.get("scale", 1.0)
    if isinstance(s, bool) or not isinstance(s, (int, float)) or not (s > 0 and np.isfinite(s)):
        raise SceneError(f"must be a number > 0, got {s!r}", where=f"{where}.scale")
    R = euler_rotation(rot)
    return motion_matrix(R, p + t - float(s) * R @ p, float(s))


def euler_rotation(degrees) -> np.ndarray:
    """``Rz·Ry·Rx`` of Euler angles (degrees) about X, then Y, then Z (an object's ``rotate``)."""
    ax, ay, az = (np.radians(float(a)) for a in np.asarray(degrees, np.float64).reshape(3))
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def motion_about(rotation, pivot, translation=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The 4×4 motion turning by ``rotation`` about the point ``pivot``, then moving by
    ``translation``: ``P' = R (P − pivot) + pivot + translation``."""
    R = np.asarray(rotation, np.float64)
    p = np.asarray(pivot, np.float64)
    return motion_matrix(R, p - R @ p + np.asarray(translation, np.float64))


def rolling(distance, direction=(1.0, 0.0, 0.0), radius: float = 0.5, centre=(0.0, 0.5, 0.0),
            up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """A ball of ``radius`` (rest centre ``centre``) rolled without slipping by ``distance`` along
    the floor direction ``direction``: turned by ``distance/radius`` about ``up × direction``."""
    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    R = rotation_about(np.cross(np.asarray(up, np.float64), d), np.degrees(float(distance) / float(radius)))
    return motion_about(R, centre, float(distance) * d)


def apply_motion(matrix, vertices, normals=None, tangents=None):
    """``(vertices, normals, tangents)`` moved by ``matrix`` (float32; None stays None)."""
    R, s, t = check_motion(matrix)
    v = (np.asarray(vertices, np.float64) @ (s * R).T + t).astype(np.float32)
    n = None if normals is None else (np.asarray(normals, np.float64) @ R.T).astype(np.float32)
    tg = None if tangents is None else (np.asarray(tangents, np.float64) @ R.T).astype(np.float32)
    return v, n, tg


__all__ = ["check_motion", "motion_matrix", "rotation_about", "apply_motion", "motion_from_fields", "euler_rotation",
           "motion_about", "rolling", "MOTION_FIELDS",
           "ORTHO_TOL"]
