r"""What a (sub)pixel that sees no object shows: the environment along its camera ray.

:func:`background_at` computes the pinhole ray through (sub)pixel centre (j, i) exactly as
:meth:`warp_sg.camera.Camera.ray_directions` does (``d ∝ f + x·tan(fov/2)·aspect·r + y·tan(fov/2)·u``
at ``x = (i + ½)/W·2 − 1``, ``y = 1 − (j + ½)/H·2``) and reads the environment bilinearly
(:func:`warp_sg.envmap.env_lookup`, rotation and scale applied); zero when the scene has no
environment or ``[render] background = false``.

The antialiased path evaluates it only for the samples it gathers that see no object
(``warp_sg.antialias.gather_kernel``): an a×a background image at 512² with a = 4 would be
4 M environment lookups per camera change (about 0.3 s of CPU), of which a frame uses a few
percent. :func:`background_image` fills a whole (sub)pixel grid (the supersampling path).
"""
# NOTE: no ``from __future__ import annotations`` (Warp reads the kernel annotations).
import math

import numpy as np
import warp as wp

from .envmap import env_lookup


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


__all__ = ["Background", "background_at", "background_kernel", "background_params", "background_image"]
