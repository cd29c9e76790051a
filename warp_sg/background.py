r"""What a (sub)pixel that sees no object shows: the environment along its camera ray.

:func:`background_kernel` computes the pinhole ray of every (sub)pixel centre exactly as
:meth:`warp_sg.camera.Camera.ray_directions` does (``d ∝ f + x·tan(fov/2)·aspect·r + y·tan(fov/2)·u``
at ``x = (i + ½)/W·2 − 1``, ``y = 1 − (j + ½)/H·2``) and reads the environment bilinearly
(:func:`warp_sg.envmap.env_lookup`, rotation and scale applied). One launch per camera change, on
the device: at 512² with 4×4 antialiasing that is 4 M directions, which the numpy twin took
about a second for.
"""
# NOTE: no ``from __future__ import annotations`` (Warp reads the kernel annotations).
import math

import numpy as np
import warp as wp

from .envmap import env_lookup


@wp.kernel(enable_backward=False)
def background_kernel(base: int, right: wp.vec3, up: wp.vec3, fwd: wp.vec3, tx: float, ty: float,
                      radiance: wp.array2d(dtype=wp.vec3), to_env: wp.mat33, scale: float,
                      out: wp.array2d(dtype=wp.vec3)):
    """out[j, i] = scale · L(Rᵀ d_ij) for the pinhole ray d_ij through (sub)pixel (j, i)."""
    H = out.shape[0]
    W = out.shape[1]
    k = base + wp.tid()
    j = k / W
    i = k - j * W
    x = ((float(i) + 0.5) / float(W) * 2.0 - 1.0) * tx
    y = (1.0 - (float(j) + 0.5) / float(H) * 2.0) * ty
    d = wp.normalize(fwd + right * x + up * y)
    out[j, i] = env_lookup(radiance, to_env, d) * scale


def background_image(camera, k: int, radiance: wp.array, rotation: np.ndarray, scale: float, device) -> wp.array:
    """(k·H, k·W) ``wp.array(vec3)``: the environment seen through every (sub)pixel centre."""
    from raster import parallel

    r, u, f = (np.asarray(v, np.float32) for v in camera.basis())
    th = math.tan(math.radians(camera.fov) * 0.5)
    h, w = camera.height * k, camera.width * k
    out = wp.empty((h, w), dtype=wp.vec3, device=device)
    to_env = wp.mat33(*np.asarray(rotation, np.float32).T.reshape(-1))
    parallel.launch(background_kernel, h * w, [wp.vec3(*r), wp.vec3(*u), wp.vec3(*f), float(th * camera.aspect),
                                               float(th), radiance, to_env, float(scale), out], device,
                    min_chunk=4096)
    return out


__all__ = ["background_kernel", "background_image"]
