r"""Per-vertex visibility of the environment's SG lobes, cached between frames.

The diffuse environment term (eq. 39, ``warp_sg.shading``) needs, for every SG ``G_j`` of the
environment mixture, the visible fraction ``vis_ratio(p, λ)`` of the product lobe
``(p, λ) = C*(n) ⊗ G_j`` (eq. 40 places it; eq. 24, 30 give its visibility from the SSDF). The lobe
axes are fixed in world space, so this value depends on the surface point and its normal only —
not on the camera, the materials or the local lights. Evaluated per pixel it is the bulk of a
frame (one SSDF reconstruction, NV PCA terms × 4 bilinear taps, per lobe per pixel: 8 of the ≈ 11
lookups a pixel makes in the sky-lit scenes of ``docs/benchmarks.md``).

Here it is evaluated once per **vertex** (normal ``n_v``, the vertex's own SSDF, the same
``vis_ratio`` the pixel path uses)::

    V[v, j] = vis_ratio(C*(n_v) ⊗ G_j)                      (one (vertex, lobe) pair per thread)

and the shading kernel interpolates it with the barycentrics, ``Σ_k b_k V[i_k, j]`` — the paper's
own sampling rate for visibility: the SSDFs live on the vertices (§5, "per-vertex SSDFs"), and the
mesh is refined where visibility changes (``precompute.refine``). The environment lobes are broad
(product lobes of sharpness ≤ λ_j + 2.1), so the visible fraction is smooth across a triangle and
interpolating it instead of the SSDF changes little (tests/test_vertex_visibility.py measures both
against the Monte-Carlo reference). Sharp lights (a sun, point lights) and the view-dependent
specular lobes stay per pixel.

The array is rebuilt only when the lobe axes or sharpnesses change (environment rotation, a new
fit) or the visibility data does; an environment scale, material, light or camera edit reuses it.
"""
from __future__ import annotations

import warp as wp

from precompute.ssdf_wp import ssdf_point

from .shading import CC_LAM, EnvSG, Visibility, vis_ratio
from .sg_wp import sg_product


@wp.kernel(enable_backward=False)
def env_vertex_visibility_kernel(base: int, fh_mode: int, vis: Visibility, env: EnvSG,
                                 out: wp.array2d(dtype=float)):
    """``out[v, j] = vis_ratio(C*(n_v) ⊗ G_j)`` for element ``base + tid = v·J + j``."""
    e = base + wp.tid()
    nj = out.shape[1]
    v = e // nj
    j = e - v * nj
    n = wp.normalize(vis.normals[v])
    q = ssdf_point(vis.normals, v, v, v, 1.0, 0.0, 0.0, n)
    pe, le, se = sg_product(n, CC_LAM, env.axis[j], env.lam[j])
    out[v, j] = vis_ratio(1, fh_mode, vis, q, pe, le)


def env_vertex_visibility(vis: Visibility, env: EnvSG, n_vertices: int, fh_sigmoid: bool, device) -> wp.array2d:
    """(V, J) float array of :func:`env_vertex_visibility_kernel` on ``device`` (CPU: thread pool)."""
    from raster import parallel

    out = wp.empty((max(int(n_vertices), 1), max(int(env.count), 1)), dtype=float, device=device)
    if env.count > 0 and n_vertices > 0:
        parallel.launch(env_vertex_visibility_kernel, int(n_vertices) * int(env.count),
                        [1 if fh_sigmoid else 0, vis, env, out], device, min_chunk=1024)
    return out


class EnvVisibilityCache:
    """The (V, J) array of :func:`env_vertex_visibility` kept between frames: ``array(key, ...)``
    rebuilds it only when ``key`` (lobe axes and sharpnesses, visibility data, fh method) changes;
    ``key=None`` gives a (1, 1) placeholder (the variant without the cache). ``builds`` counts
    rebuilds and ``seconds`` is the last one's time."""

    def __init__(self):
        self.key = None
        self.value = None
        self.builds = 0
        self.seconds = 0.0

    def array(self, key, vis: Visibility, env: EnvSG, n_vertices: int, fh_sigmoid: bool, device) -> wp.array2d:
        import time

        if key is None:
            if self.value is None or self.key is not None:
                self.key, self.value = None, wp.zeros((1, 1), dtype=float, device=device)
        elif key != self.key:
            t = time.perf_counter()
            self.value = env_vertex_visibility(vis, env, n_vertices, fh_sigmoid, device)
            self.key = key
            self.builds += 1
            self.seconds = time.perf_counter() - t
        return self.value


__all__ = ["EnvVisibilityCache", "env_vertex_visibility", "env_vertex_visibility_kernel"]
