r"""Per-vertex visibility of the directions that do not depend on the view, cached between frames:
the environment's SG lobes and the lights.

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
against the Monte-Carlo reference). The view-dependent specular lobes stay per pixel.

The array is rebuilt only when the lobe axes or sharpnesses change (environment rotation, a new
fit) or the visibility data does; an environment scale, material, light or camera edit reuses it.

**Lights** (:func:`light_vertex_deficit`): per vertex and light the SSDF *deficit*
``min(θd_v(l_v) − θh_v(l_v), 0)`` towards the light (direction ``l_v`` from the vertex, read in the
vertex's own frame; 0 where the occluder cone is clear, ``precompute.occluder_cone``). The shading
kernel takes ``θd = θh + Σ_k b_k deficit_k`` with the pixel's own ``θh = asin(l·n)`` and the usual
``fh(θd, λ)/fh(θh, λ)``: the SSDF is interpolated as in the paper (so a sharp shadow edge falls
where the interpolated SSDF crosses zero, inside a triangle), an unoccluded point is exactly lit,
and each vertex is read towards the light as seen from that vertex. Rebuilt when a light moves or
changes size.
"""
from __future__ import annotations

import time

import warp as wp

from precompute.ssdf_wp import ssdf_at, ssdf_point

from .fastmath import fast_asin
from .lights import LightArrays, light_irradiance
from .shading import CC_LAM, EnvSG, Visibility, lookup_skip, vis_ratio
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


@wp.kernel(enable_backward=False)
def light_vertex_deficit_kernel(base: int, fh_mode: int, vis: Visibility, positions: wp.array(dtype=wp.vec3),
                                lights: LightArrays, out: wp.array2d(dtype=float)):
    """``out[v, j] = min(θd_v(l_v) − θh_v(l_v), 0)``: vertex v's SSDF towards light j (direction
    ``l_v`` from the vertex, its own frame) less its horizon value ``asin(l_v·n_v)`` — 0 where no
    occluder is closer than the horizon (and where the occluder cone is clear: no lookup)."""
    e = base + wp.tid()
    nl = out.shape[1]
    v = e // nl
    j = e - v * nl
    n = wp.normalize(vis.normals[v])
    la, ll, E = light_irradiance(lights, j, positions[v])
    q = ssdf_point(vis.normals, v, v, v, 1.0, 0.0, 0.0, n)
    th_h = fast_asin(wp.clamp(wp.dot(la, n), -1.0, 1.0))
    s = lookup_skip(fh_mode, vis, q, la, th_h, ll)
    d = float(0.0)
    if s < 1.0:
        d = (1.0 - s) * wp.min(ssdf_at(vis.mean, vis.basis, vis.weights, q, la) - th_h, 0.0)
    out[v, j] = d


def _vertex_table(kernel, n_vertices: int, n_cols: int, inputs: list, device) -> wp.array2d:
    """(V, n_cols) float array of a per-(vertex, column) ``kernel`` (element ``v·n_cols + j``;
    CPU: thread pool); (1, 1) zeros when there is nothing to compute."""
    from raster import parallel

    out = wp.zeros((max(int(n_vertices), 1), max(int(n_cols), 1)), dtype=float, device=device)
    if n_cols > 0 and n_vertices > 0:
        parallel.launch(kernel, int(n_vertices) * int(n_cols), [*inputs, out], device, min_chunk=1024)
    return out


def light_vertex_deficit(vis: Visibility, positions, lights: LightArrays, n_vertices: int, fh_sigmoid: bool,
                         device) -> wp.array2d:
    """(V, lights) array of :func:`light_vertex_deficit_kernel`."""
    return _vertex_table(light_vertex_deficit_kernel, n_vertices, lights.count,
                         [1 if fh_sigmoid else 0, vis, positions, lights], device)


def env_vertex_visibility(vis: Visibility, env: EnvSG, n_vertices: int, fh_sigmoid: bool, device) -> wp.array2d:
    """(V, J) array of :func:`env_vertex_visibility_kernel`."""
    return _vertex_table(env_vertex_visibility_kernel, n_vertices, env.count, [1 if fh_sigmoid else 0, vis, env],
                         device)


def _same_key(a, b) -> bool:
    """Keys match element by element: plain values by ``==``, objects (arrays, structs) by identity."""
    if a is None or b is None or len(a) != len(b):
        return False
    return all(x is y or (isinstance(x, (tuple, str, int, float)) and type(x) is type(y) and x == y)
               for x, y in zip(a, b))


class VertexCache:
    """A per-vertex array kept between frames: ``array(key, build, device)`` calls ``build()`` only
    when ``key`` changes (:func:`_same_key`: values by ``==``, objects by identity — the key holds
    them, so a rebuilt object never matches a stale key); ``key=None`` gives a (1, 1) placeholder
    (the kernel variant without the cache). ``builds`` counts rebuilds; ``seconds`` is the time the
    last ``array`` call spent building (0 when it reused the array)."""

    def __init__(self):
        self.key = None
        self.value = None
        self.builds = 0
        self.seconds = 0.0

    def array(self, key, build, device) -> wp.array2d:
        self.seconds = 0.0
        if key is None:
            if self.value is None or self.key is not None:
                self.key, self.value = None, wp.zeros((1, 1), dtype=float, device=device)
        elif not _same_key(key, self.key):
            t = time.perf_counter()
            self.value = build()
            self.key = key
            self.builds += 1
            self.seconds = time.perf_counter() - t
        return self.value


__all__ = ["VertexCache", "env_vertex_visibility", "env_vertex_visibility_kernel", "light_vertex_deficit",
           "light_vertex_deficit_kernel"]
