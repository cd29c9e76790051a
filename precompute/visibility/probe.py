r"""A cheap visibility probe at every vertex: the open fraction of a few stratified rays.

The representatives of :mod:`precompute.visibility.representatives` stand for the vertices of
their clusters; a cluster can hold an outer panel and a shadowed detail or a second layer behind
it, whose hemispheres differ although their positions and normals are close. The probe measures
each vertex's openness with ``P = R_p²`` rays (:data:`PROBE_RESOLUTION` ``R_p`` = 4: 16 rays) at
the texel centres of an ``R_p × R_p`` concentric map of its upper hemisphere (equal-area strata,
:func:`precompute.visibility.ssdf_wp.texel_directions`), cast exactly as the SSDF's own rays
(:func:`precompute.visibility.rays.launch_visibility`: the origin ``x + ε n``, the any-hit test,
alpha cut-outs seen through)::

    o_v = (1/P) Σ_k V_v(d_k),   V_v(d) = 1 if the ray from x_v + ε n_v along F_v d escapes

an unbiased estimate of the fraction of the vertex's SSDF texels that are open (the texels are
equal-area cells of the same map), with a standard error ≤ 1/(2√P) (less: stratified).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from precompute.visibility.rays import _MeshContext, launch_visibility, run_batches, validate_mesh
from precompute.visibility.ssdf_wp import texel_direction_array

#: the probe's map side ``R_p``: ``R_p²`` rays per vertex
PROBE_RESOLUTION = 4


def probe_open_fraction(vertices, triangles, normals, *, resolution: int = PROBE_RESOLUTION, device="cpu",
                        cutouts=None, batch: int = 16384) -> np.ndarray:
    """(V,) float64: each vertex's open fraction ``o_v`` (module docstring) from ``resolution²``
    rays; ``cutouts``: the mesh's alpha cut-outs (:class:`warp_sg.shading.cutout.CutoutData`)."""
    v, f, n = validate_mesh(vertices, triangles, normals)
    R = int(resolution)
    ctx = _MeshContext(v, f, n, device, cutouts)
    dirs = texel_direction_array(R, device)
    out = np.empty(len(v), np.float64)

    def work(s, e):
        buf = wp.empty((e - s, R * R), dtype=wp.uint8, device=device)
        launch_visibility(ctx, ctx.points, ctx.normals, s, dirs, buf)
        out[s:e] = buf.numpy().sum(axis=1) / float(R * R)

    run_batches(len(v), batch, work, device)
    return out


__all__ = ["PROBE_RESOLUTION", "probe_open_fraction"]
