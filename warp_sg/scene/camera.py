"""Pinhole camera: Mitsuba 3 ``look_at`` + ``fov`` (``fov_axis = "y"``) convention.

Scene layer: a plain data class (numpy only) that the scene holds and the engines read —
``raster.Camera`` is this class.

World space is right-handed with +Y up. The camera looks from ``origin`` towards ``target``;
``up`` fixes the roll. The image has ``width`` × ``height`` pixels, row 0 at the top, pixel
(x, y) centred at (x + 0.5, y + 0.5). ``fov`` is the *vertical* field of view in degrees.

Matrices follow OpenGL: the view matrix maps world to eye space (eye looks down −Z, +Y up,
+X right); the projection matrix maps eye space to clip space with ``w_clip = −z_eye`` (the
distance along the view axis, which is what the visibility buffer stores as ``depth``) and
NDC x, y in [−1, 1] across the image (NDC +y = top row). A clip-space point maps to pixel
coordinates ``X = (x/w + 1)/2 · W``, ``Y = (1 − y/w)/2 · H``.

``ray_directions`` / ``ray_origins`` give the primary rays through the pixel centres of the
same camera (for ray casting references); they agree with the projection to float precision.
:func:`with_resolution` is a scene's copy with its camera at another resolution.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace

import numpy as np

from warp_sg.core.errors import InputError


def _vec3(v, name):
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InputError(f"must be 3 finite numbers, got {v!r}", where=f"camera.{name}")
    return tuple(float(x) for x in a)


@dataclass
class Camera:
    """Pinhole camera (see module docstring). ``near``/``far`` bound the visible depth range."""

    origin: tuple = (0.0, 1.0, 4.0)
    target: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    fov: float = 40.0
    width: int = 256
    height: int = 256
    near: float = 1e-2
    far: float = 1e4

    def __post_init__(self):
        self.origin = _vec3(self.origin, "origin")
        self.target = _vec3(self.target, "target")
        self.up = _vec3(self.up, "up")
        try:
            self.fov = float(self.fov)
            self.near = float(self.near)
            self.far = float(self.far)
        except (TypeError, ValueError) as e:
            raise InputError(f"fov/near/far must be numbers ({e})", where="camera") from None
        if not (0.0 < self.fov < 180.0):
            raise InputError(f"must be in (0, 180) degrees, got {self.fov}", where="camera.fov")
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or int(v) < 1:
                raise InputError(f"must be a positive integer, got {v!r}", where=f"camera.{name}")
            setattr(self, name, int(v))
        if not (0.0 < self.near < self.far) or not math.isfinite(self.far):
            raise InputError(f"need 0 < near < far < inf, got near={self.near}, far={self.far}", where="camera.near")
        f = np.subtract(self.target, self.origin)
        if np.linalg.norm(f) == 0.0:
            raise InputError("origin and target coincide", where="camera.target")
        if np.linalg.norm(np.cross(f, self.up)) <= 1e-12 * np.linalg.norm(f) * np.linalg.norm(self.up):
            raise InputError("up is parallel to the view direction", where="camera.up")

    # ------------------------------------------------------------------ frame
    def basis(self):
        """(right, up, forward) unit vectors in world space (float64)."""
        o, t, u = (np.asarray(x, np.float64) for x in (self.origin, self.target, self.up))
        f = t - o
        f /= np.linalg.norm(f)
        r = np.cross(f, u)
        r /= np.linalg.norm(r)
        uu = np.cross(r, f)
        return r, uu, f

    @property
    def aspect(self) -> float:
        return self.width / self.height

    def view_matrix(self) -> np.ndarray:
        """4×4 world → eye (OpenGL: eye looks down −Z), float64."""
        r, u, f = self.basis()
        o = np.asarray(self.origin, np.float64)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = r, u, -f
        m[:3, 3] = -m[:3, :3] @ o
        return m

    def projection_matrix(self) -> np.ndarray:
        """4×4 eye → clip (OpenGL perspective, z in [−w, w] between near and far), float64."""
        th = math.tan(math.radians(self.fov) * 0.5)
        n, fa = self.near, self.far
        p = np.zeros((4, 4))
        p[0, 0] = 1.0 / (th * self.aspect)
        p[1, 1] = 1.0 / th
        p[2, 2] = -(fa + n) / (fa - n)
        p[2, 3] = -2.0 * fa * n / (fa - n)
        p[3, 2] = -1.0
        return p

    def view_projection(self) -> np.ndarray:
        return self.projection_matrix() @ self.view_matrix()

    # ------------------------------------------------------------------ rays
    def ray_directions(self, supersample: int = 1) -> np.ndarray:
        """(k·H, k·W, 3) float32 world-space unit directions through the (sub)pixel centres."""
        k = int(supersample)
        r, u, f = self.basis()
        h, w = self.height * k, self.width * k
        th = math.tan(math.radians(self.fov) * 0.5)
        x = ((np.arange(w) + 0.5) / w * 2.0 - 1.0) * th * self.aspect
        y = (1.0 - (np.arange(h) + 0.5) / h * 2.0) * th
        d = f + x[None, :, None] * r + y[:, None, None] * u
        return (d / np.linalg.norm(d, axis=-1, keepdims=True)).astype(np.float32)

    def ray_origins(self, supersample: int = 1) -> np.ndarray:
        """(k·H, k·W, 3) float32: the camera origin for every (sub)pixel (pinhole)."""
        k = int(supersample)
        o = np.asarray(self.origin, np.float32)
        return np.ascontiguousarray(np.broadcast_to(o, (self.height * k, self.width * k, 3)))

    def forward(self) -> np.ndarray:
        """Unit view axis (float64); ``depth = t · dot(ray_direction, forward)``."""
        return self.basis()[2]


def with_resolution(scene, width=None, height=None):
    """A copy of ``scene`` whose camera renders ``width`` × ``height`` (one given: keep the aspect)."""
    if not width and not height:
        return scene
    cam = scene.camera
    if width and not height:
        height = max(1, round(cam.height * width / cam.width))
    if height and not width:
        width = max(1, round(cam.width * height / cam.height))
    sc = copy.copy(scene)
    sc.camera = replace(cam, width=int(width), height=int(height))
    return sc
