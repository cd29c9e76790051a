r"""What a (sub)pixel that sees no object shows: the environment along its camera ray.

:func:`background_at` computes the pinhole ray through (sub)pixel centre (j, i) exactly as
:meth:`warp_sg.scene.camera.Camera.ray_directions` does (``d ∝ f + x·tan(fov/2)·aspect·r + y·tan(fov/2)·u``
at ``x = (i + ½)/W·2 − 1``, ``y = 1 − (j + ½)/H·2``) and reads the environment bilinearly
(:func:`warp_sg.scene.envmap.env_lookup`, rotation and scale applied); zero when the scene has no
environment or ``[render] background = false``.

The antialiased path evaluates it only for the samples it gathers that see no object
(``warp_sg.renderer.antialias.gather_kernel``): an a×a background image at 512² with a = 4 would be
4 M environment lookups per camera change (about 0.3 s of CPU), of which a frame uses a few
percent. :func:`background_image` fills a whole (sub)pixel grid (the supersampling path).
"""
# NOTE: no ``from __future__ import annotations`` (Warp reads the kernel annotations).
import math

import numpy as np
import warp as wp

from warp_sg.scene.envmap import env_lookup


@wp.struct
class Background:
    """The camera's ray frame on a (k·H, k·W) sub-pixel grid and the environment it shows."""

    right: wp.vec3
    up: wp.vec3
    fwd: wp.vec3
    tx: float  # tan(fov/2) · aspect
    ty: float  # tan(fov/2)
    width: int  # sub-pixel grid
    height: int
    radiance: wp.array2d(dtype=wp.vec3)
    to_env: wp.mat33
    scale: float
    enabled: int


@wp.func
def background_at(bg: Background, j: int, i: int) -> wp.vec3:
    """scale · L(Rᵀ d) for the pinhole ray d through sub-pixel (row j, column i); 0 if disabled."""
    if bg.enabled == 0:
        return wp.vec3(0.0, 0.0, 0.0)
    x = ((float(i) + 0.5) / float(bg.width) * 2.0 - 1.0) * bg.tx
    y = (1.0 - (float(j) + 0.5) / float(bg.height) * 2.0) * bg.ty
    d = wp.normalize(bg.fwd + bg.right * x + bg.up * y)
    return env_lookup(bg.radiance, bg.to_env, d) * bg.scale


@wp.func
def background_along(bg: Background, d: wp.vec3) -> wp.vec3:
    """scale · L(Rᵀ d) along the unit world direction ``d`` (a camera ray that passed through a
    cut-out, :mod:`warp_sg.shading.cutout`); 0 if disabled."""
    if bg.enabled == 0:
        return wp.vec3(0.0, 0.0, 0.0)
    return env_lookup(bg.radiance, bg.to_env, d) * bg.scale


@wp.kernel(enable_backward=False)
def background_kernel(base: int, bg: Background, masked: int, tri_id: wp.array2d(dtype=int),
                      out: wp.array2d(dtype=wp.vec3)):
    """out[j, i] = background_at(bg, j, i) over the whole grid (``masked``: only where
    ``tri_id < 0``, 0 elsewhere)."""
    k = base + wp.tid()
    j = k / bg.width
    i = k - j * bg.width
    if masked != 0:
        if tri_id[j, i] >= 0:
            out[j, i] = wp.vec3(0.0, 0.0, 0.0)
            return
    out[j, i] = background_at(bg, j, i)


def background_params(camera, k: int, radiance, rotation, scale: float, device) -> Background:
    """The :class:`Background` of ``camera`` at k×k sub-pixels; ``radiance`` None (a
    ``wp.array2d(vec3)`` otherwise) for a black background."""
    bg = Background()
    r, u, f = (np.asarray(v, np.float32) for v in camera.basis())
    th = math.tan(math.radians(camera.fov) * 0.5)
    bg.right, bg.up, bg.fwd = wp.vec3(*r), wp.vec3(*u), wp.vec3(*f)
    bg.tx, bg.ty = float(th * camera.aspect), float(th)
    bg.width, bg.height = int(camera.width * k), int(camera.height * k)
    bg.enabled = int(radiance is not None)
    bg.radiance = radiance if radiance is not None else wp.zeros((1, 1), dtype=wp.vec3, device=device)
    R = np.eye(3) if rotation is None else np.asarray(rotation)
    bg.to_env = wp.mat33(*np.asarray(R, np.float32).T.reshape(-1))
    bg.scale = float(scale)
    return bg


def background_image(bg: Background, device, tri_id: wp.array | None = None) -> wp.array:
    """(k·H, k·W) ``wp.array(vec3)``: :func:`background_at` at every sub-pixel centre; with
    ``tri_id`` (the visibility buffer of the same grid) only where it sees no object (the shading
    kernel reads nothing else), 0 elsewhere."""
    from raster import parallel

    out = wp.empty((bg.height, bg.width), dtype=wp.vec3, device=device)
    mask = tri_id if tri_id is not None else wp.zeros((1, 1), dtype=int, device=device)
    parallel.launch(background_kernel, bg.height * bg.width, [bg, int(tri_id is not None), mask, out], device,
                    min_chunk=4096)
    return out


class BackgroundCache:
    """What a renderer's (sub)pixels that see no object show, frame by frame: the environment map
    on the device (uploaded once) and, for a camera that stays put, the (k·H, k·W) image.

    :meth:`for_frame`: a new view gets the camera rays (a :class:`Background`; the shading kernel
    reads the environment along them for its background pixels, no separate pass over the
    image); a re-shade (a material, light or environment edit: the same camera and visibility
    buffer as the frame before) builds the image once and reuses it."""

    def __init__(self, device):
        self.device = device
        self._radiance = None
        self._image_key = self._vb = self._image = None
        self._placeholders = None
        self._params = {}  # (camera, k, environment, show) -> Background, the last few

    @staticmethod
    def _key(camera, k: int, env_light, show: bool) -> tuple:
        return repr(camera), k, None if env_light is None else (env_light.rotation, env_light.scale), show

    def params(self, camera, k: int, env_light, env_base, show: bool) -> Background:
        """The :class:`Background` of ``camera`` at k×k sub-pixels (black without an environment
        or with ``show`` off)."""
        key = self._key(camera, k, env_light, show)
        if key not in self._params:
            radiance = None
            if env_light is not None and show:
                if self._radiance is None:
                    self._radiance = wp.array(np.ascontiguousarray(env_base, np.float32), dtype=wp.vec3,
                                              device=self.device)
                radiance = self._radiance
            if len(self._params) > 8:
                self._params.clear()
            self._params[key] = background_params(camera, k, radiance, None if env_light is None else
                                                  env_light.rotation_matrix(), 1.0 if env_light is None else
                                                  env_light.scale, self.device)
        return self._params[key]

    def for_frame(self, camera, k: int, env_light, env_base, show: bool, vb, reused: bool):
        """The cached image when it is this frame's (``vb``: the visibility buffer it was masked
        with), else the rays of a new view, or the image built now for a re-shade (``reused``)."""
        key = self._key(camera, k, env_light, show)
        if key != self._image_key or self._vb is not vb:
            rays = self.params(camera, k, env_light, env_base, show)
            if not reused:
                return rays
            self._image = None  # only where the visibility buffer sees no object
            self._image = background_image(rays, self.device, vb.tri_id)
            self._image_key, self._vb = key, vb
        return self._image

    def kernel_args(self, bg) -> list:
        """The shading kernel's ``(background, rays, use_rays)`` for ``bg``: an image or gathered
        samples (``wp.array``), or the camera rays (:class:`Background`)."""
        if self._placeholders is None:
            none = wp.zeros((1, 1), dtype=wp.vec3, device=self.device)
            rays = Background()  # disabled: never read (use_rays = 0)
            rays.radiance = none
            self._placeholders = (none, rays)
        if isinstance(bg, wp.array):
            return [bg, self._placeholders[1], 0]
        return [self._placeholders[0], bg, 1]


__all__ = ["Background", "BackgroundCache", "background_at", "background_along", "background_kernel",
           "background_params", "background_image"]
