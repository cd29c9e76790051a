"""Per-pixel interpolation of per-vertex attributes through the visibility buffer.

``interpolate(vb, triangles, attr)`` → ``wp.array`` (k·H, k·W, C) float32: for every pixel with a
triangle, ``(1 − b1 − b2)·a[i0] + b1·a[i1] + b2·a[i2]``; zeros where empty. The barycentrics are
already perspective-correct, so this is the perspective-correct attribute.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from warp_sg.core.errors import InputError

wp.set_module_options({"enable_backward": False})


@wp.kernel
def interpolate_kernel(
    tri_id: wp.array2d(dtype=wp.int32),
    bary: wp.array2d(dtype=wp.vec2),
    tris: wp.array(dtype=wp.vec3i),
    attr: wp.array2d(dtype=wp.float32),
    out: wp.array3d(dtype=wp.float32),
):
    y, x = wp.tid()
    t = tri_id[y, x]
    C = attr.shape[1]
    if t < 0:
        for c in range(C):
            out[y, x, c] = 0.0
        return
    b = bary[y, x]
    w0 = 1.0 - b[0] - b[1]
    ids = tris[t]
    for c in range(C):
        out[y, x, c] = w0 * attr[ids[0], c] + b[0] * attr[ids[1], c] + b[1] * attr[ids[2], c]


def interpolate(vb, triangles, attr) -> wp.array:
    """Interpolate ``attr`` (N, C) or (N,) per-vertex values to the pixels of ``vb``."""
    dev = vb.device
    if isinstance(triangles, wp.array):
        triangles = triangles.numpy()
    if isinstance(attr, wp.array):
        attr = attr.numpy()
    a = np.asarray(attr, dtype=np.float32)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise InputError(f"attr must have shape (N, C), got {a.shape}", where="attr")
    t = np.ascontiguousarray(np.asarray(triangles, dtype=np.int32).reshape(-1, 3))
    if t.size and (t.min() < 0 or t.max() >= a.shape[0]):
        raise InputError(f"attr has {a.shape[0]} rows but triangles index up to {int(t.max())}", where="attr")
    H, W = vb.tri_id.shape
    out = wp.zeros((H, W, a.shape[1]), dtype=wp.float32, device=dev)
    if t.shape[0] == 0 or a.shape[1] == 0:
        return out
    wp.launch(interpolate_kernel, dim=(H, W),
              inputs=[vb.tri_id, vb.bary, wp.array(t, dtype=wp.vec3i, device=dev),
                      wp.array(np.ascontiguousarray(a), dtype=wp.float32, device=dev)],
              outputs=[out], device=dev)
    return out
