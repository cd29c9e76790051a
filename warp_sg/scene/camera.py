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
from dataclasses import dataclass, fields, replace

import numpy as np
from pydantic import model_validator

from warp_sg.scene.values import Table, check_record, fail, integer, number, vector


@dataclass
class Camera:
    """Pinhole camera (see module docstring). ``near``/``far`` bound the visible depth range.
    Checked by :class:`CameraTable`, the ``[camera]`` table's model, so a camera built in Python
    is refused in the words of the scene file (``[camera] key 'fov' must be <= 179.0, got 180.0``)."""

    origin: tuple = (0.0, 1.0, 4.0)
    target: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    fov: float = 40.0
    width: int = 256
    height: int = 256
    near: float = 1e-2
    far: float = 1e4

    def __post_init__(self):
        t = check_record(CameraTable, {f.name: getattr(self, f.name) for f in fields(self)}, "[camera]")
        for f in fields(self):
            setattr(self, f.name, getattr(t, f.name))

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


_POS = dict(lo=0, lo_open=True)


class CameraTable(Table):
    """Pinhole camera (Mitsuba ``look_at``): vertical field of view in degrees."""

    origin: vector(description="eye position") = Camera.origin
    target: vector(description="point looked at") = Camera.target
    up: vector(description="up direction") = Camera.up
    fov: number(lo=0, lo_open=True, hi=179.0, description="vertical field of view (degrees)") = Camera.fov
    width: integer(lo=1, description="image width (pixels)") = Camera.width
    height: integer(lo=1, description="image height (pixels)") = Camera.height
    near: number(**_POS, description="near clipping distance") = Camera.near
    far: number(**_POS, description="far clipping distance") = Camera.far

    @model_validator(mode="after")
    def _geometry(self):
        o, t, u = self.origin, self.target, self.up
        d = tuple(b - a for a, b in zip(o, t))
        if all(abs(x) <= 1e-8 * (1 + abs(a)) for x, a in zip(d, o)):
            fail("origin and target coincide")
        c = (d[1] * u[2] - d[2] * u[1], d[2] * u[0] - d[0] * u[2], d[0] * u[1] - d[1] * u[0])
        if math.hypot(*c) < 1e-9 * math.hypot(*d) * max(math.hypot(*u), 1e-30):
            fail("up is parallel to the viewing direction (or zero)")
        if not self.near < self.far:
            fail(f"must be less than far = {self.far}, got {self.near}", key="near")
        return self


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
