r"""Kernel of the refinement's signature comparison across curved edges (:mod:`precompute.visibility.refine`).

For an edge (i, j) whose endpoint normals differ, :func:`precompute.visibility.refine._signature_difference`
compares the binary hemisphere maps of i and j in common *world* directions: for each texel
direction ``d`` of i's ``R × R`` map (local frame of ``n_i``), ``w = F_i d`` in world space is
looked up in j's frame, ``l = F_jᵀ w``; where ``l_z > 0`` (above j's horizon) the lookup counts, and
it disagrees when i's value differs from all four texels of j's map around the concentric-map
point of ``l`` (the bilinear footprint of :func:`precompute.visibility.ssdf_wp.lookup_np`). The fraction of
counted directions that disagree is the edge's difference.

One thread per (edge, texel), float32, the frames of :mod:`warp_sg.numeric.onb` and the concentric map
of :func:`precompute.visibility.ssdf_wp.dir_to_concentric_wp`; the per-edge sums are taken on the host.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from precompute.visibility.ssdf_wp import dir_to_concentric_wp
from warp_sg.numeric.onb import frame_bitangent, frame_tangent, local_to_world, world_to_local


@wp.kernel(enable_backward=False)
def _world_disagreement_kernel(sig: wp.array2d(dtype=wp.uint8), normals: wp.array(dtype=wp.vec3),
                               ei: wp.array(dtype=int), ej: wp.array(dtype=int), dirs: wp.array(dtype=wp.vec3),
                               R: int, counted: wp.array2d(dtype=wp.uint8), differs: wp.array2d(dtype=wp.uint8)):
    e, t = wp.tid()
    i = ei[e]
    j = ej[e]
    ni = normals[i]
    nj = normals[j]
    w = local_to_world(dirs[t], frame_tangent(ni), frame_bitangent(ni), ni)
    loc = world_to_local(w, frame_tangent(nj), frame_bitangent(nj), nj)
    if loc[2] <= 0.0:
        counted[e, t] = wp.uint8(0)
        differs[e, t] = wp.uint8(0)
        return
    uv = dir_to_concentric_wp(loc)
    fr = float(R)
    x0 = wp.clamp(int(wp.floor((uv[0] + 1.0) * 0.5 * fr - 0.5)), 0, R - 2)
    y0 = wp.clamp(int(wp.floor((uv[1] + 1.0) * 0.5 * fr - 0.5)), 0, R - 2)
    mine = sig[i, t]
    agree = (sig[j, y0 * R + x0] == mine or sig[j, y0 * R + x0 + 1] == mine
             or sig[j, (y0 + 1) * R + x0] == mine or sig[j, (y0 + 1) * R + x0 + 1] == mine)
    counted[e, t] = wp.uint8(1)
    differs[e, t] = wp.where(agree, wp.uint8(0), wp.uint8(1))


def world_disagreement(sig, normals, i, j, R: int, device="cpu", batch: int = 4096) -> np.ndarray:
    """(E,) fraction of i's counted texel directions in which the maps of edges (i[e], j[e])
    disagree (module docstring). ``sig`` (V, R²) bool/uint8, ``normals`` (V, 3) unit. Batches of
    edges run on the CPU thread pool (:func:`precompute.visibility.rays.run_batches`)."""
    from precompute.visibility.rays import run_batches
    from precompute.visibility.ssdf_wp import texel_direction_array

    out = np.zeros(len(i))
    if not len(i):
        return out
    sig_w = wp.array(np.ascontiguousarray(sig, dtype=np.uint8), dtype=wp.uint8, device=device)
    nrm = wp.array(np.asarray(normals, np.float32), dtype=wp.vec3, device=device)
    dirs = texel_direction_array(R, device)
    ei = wp.array(np.asarray(i, np.int64), dtype=int, device=device)
    ej = wp.array(np.asarray(j, np.int64), dtype=int, device=device)

    def work(s, e):
        counted = wp.empty((e - s, R * R), dtype=wp.uint8, device=device)
        differs = wp.empty((e - s, R * R), dtype=wp.uint8, device=device)
        wp.launch(_world_disagreement_kernel, dim=(e - s, R * R), device=device,
                  inputs=[sig_w, nrm, ei[s:e], ej[s:e], dirs, int(R), counted, differs])
        out[s:e] = differs.numpy().sum(axis=1) / np.maximum(counted.numpy().sum(axis=1), 1)

    run_batches(len(out), batch, work, device)
    return out


__all__ = ["world_disagreement"]
