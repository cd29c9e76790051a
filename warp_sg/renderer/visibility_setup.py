r"""The renderer's visibility precompute as functions of the scene (render layer).

:class:`warp_sg.renderer.renderer.Renderer` needs, when the scene has shadows, the mesh refined where its
visibility changes (``precompute.refine_cached``, ``[render] visibility_budget`` vertices at most)
and the per-vertex SSDFs of the refined mesh (``precompute.ssdf_for_mesh``; a mesh over the same
budget has its maps computed at that many representative vertices,
:mod:`precompute.visibility.representatives`; 0: every vertex its own). :func:`compute_visibility`
computes both from the flattened input mesh and touches no renderer state, so the renderer runs it
either in its constructor or, with ``progressive=True``, on a background thread
(:mod:`warp_sg.renderer.progressive`) while it shows unshadowed frames; either way the renderer installs
the same data, so the shadowed frames are the same bit for bit. :func:`visibility_arrays` turns
SSDF data into the shading kernel's :class:`warp_sg.shading.kernel.Visibility`.
"""
from __future__ import annotations

import time

import numpy as np
import warp as wp

from warp_sg.core.errors import InputError
from warp_sg.scene.geometry import refined_geometry
from warp_sg.shading import kernel as S


def visibility_groups(g, dynamic=()):
    """Per triangle of the flattened mesh ``g``, its visibility group (0: the static objects,
    1 + k: dynamic object k; :mod:`precompute.visibility.ssdf_groups`), or None when no object is
    dynamic (``dynamic``: per object, ``SceneObject.dynamic``)."""
    if not any(dynamic):
        return None
    to = np.asarray(g.tri_object, np.int64)
    return np.where(np.asarray(dynamic, bool)[to], 1 + to, 0)


def moving_budgets(dynamic=(), moving_budget: int = 0):
    """``{group: vertices}`` the refinement may add to each dynamic object's group
    (``[render] moving_visibility_budget``), or None when no object is dynamic."""
    if not any(dynamic):
        return None
    return {1 + k: int(moving_budget) for k, d in enumerate(dynamic) if d}


def refine_key(g, budget: int, lights=(), dynamic=(), moving_budget: int = 0) -> str:
    """The key that ties ``precomputed["refinement"]`` to a mesh, a budget, the key lights and the
    objects that move (and their own budget)."""
    from warp_sg.core.cache import content_key

    groups = visibility_groups(g, dynamic)
    extra = () if groups is None else (groups,)
    params = {"budget": int(budget), "lights": [(k, np.ravel(v).tolist()) for k, v in lights]}
    if groups is not None:
        params["moving_budget"] = int(moving_budget)
    return content_key(np.asarray(g.vertices), np.asarray(g.triangles), np.asarray(g.normals), *extra, params)


def needs_shadows(scene, g) -> bool:
    """``[render] shadows`` is on and the merged mesh can shadow itself (``precompute.needs_visibility``)."""
    if not scene.render.shadows:
        return False
    import precompute

    return bool(precompute.needs_visibility(g.vertices, g.triangles, shadows=True))


def _timed(parts: dict, name: str, fn):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    parts[name] = (time.perf_counter() - w0, time.process_time() - c0)
    return out


def compute_visibility(scene, g, device, *, progress=False, compute=None, precomputed=None, lights=(),
                       cutouts=None, dynamic=()):
    """``(refinement or None, refined geometry, SSDFData, parts, gather rows or None)`` of the flattened input mesh ``g``
    of ``scene`` (shadows assumed on). ``precomputed``: :meth:`Renderer.precomputed` data to reuse
    (checked against the mesh and settings: a mismatch is an :class:`InputError`). ``parts``:
    ``{name: (wall s, CPU s)}`` of ``refine`` and ``ssdf`` (CPU: the whole process's). ``lights``:
    the key lights the refinement places shadow edges for (``Renderer._refine_lights``);
    ``cutouts``: a function of a geometry returning its alpha cut-outs
    (:func:`warp_sg.shading.cutout.cutout_data`), whose holes the refinement's and the SSDFs' rays pass.
    ``dynamic``: per object, whether it may move (``SceneObject.dynamic``); with any, the SSDFs are
    computed per group, each dynamic object alone (:mod:`precompute.visibility.ssdf_groups`). With
    ``[render] bounces`` > 0 also the refined mesh's gather rows (:mod:`precompute.visibility.gather`,
    part ``gather``; reused from ``precomputed`` when it holds them for this mesh)."""
    cut_of = cutouts if cutouts is not None else (lambda geo: None)
    import precompute

    rs = scene.render
    parts: dict = {}
    ref = None
    with wp.ScopedDevice(device):
        if rs.visibility_budget > len(g.vertices):
            from precompute.visibility.refine import refine_cached

            def refine():
                if precomputed is not None:
                    if (precomputed.get("refinement") is None
                            or precomputed.get("refine_key") != refine_key(g, rs.visibility_budget, lights, dynamic,
                                                                         rs.moving_visibility_budget)):
                        raise InputError("precomputed data is for a different mesh or visibility_budget",
                                         where="precomputed")
                    return precomputed["refinement"]
                groups = visibility_groups(g, dynamic)  # (each vertex refined for its own group's shadows)
                by_group = {"cutouts": cut_of(g)} if groups is None else {
                    "groups": groups, "group_budgets": moving_budgets(dynamic, rs.moving_visibility_budget)}
                return refine_cached(g.vertices, g.triangles, g.normals, budget=rs.visibility_budget, device=device,
                                     lights=lights, progress=progress, **by_group)

            ref = _timed(parts, "refine", refine)
        gr = refined_geometry(g, ref) if ref is not None and len(ref.vertices) > len(g.vertices) else g
        cut = cut_of(gr)

        groups = visibility_groups(gr, dynamic)  # (None: one group)

        def ssdf():
            if precomputed is not None and precomputed.get("ssdf") is not None:
                from precompute.visibility.ssdf import ssdf_key
                from precompute.visibility.ssdf_groups import ssdf_groups_key

                data = precomputed["ssdf"]
                want = ssdf_key(gr.vertices, gr.triangles, gr.normals, resolution=rs.ssdf_resolution,
                                ray_resolution=data.ray_resolution, pca_terms=rs.pca_terms, cutouts=cut,
                                representatives=rs.visibility_budget) \
                    if groups is None else ssdf_groups_key(gr.vertices, gr.triangles, gr.normals, groups,
                                                           resolution=rs.ssdf_resolution,
                                                           ray_resolution=data.ray_resolution, pca_terms=rs.pca_terms)
                if want != data.key:
                    raise InputError("precomputed SSDFs are for a different mesh or SSDF settings", where="precomputed")
                return data
            if groups is not None:
                from precompute.visibility.ssdf_groups import ssdf_for_groups

                return ssdf_for_groups(gr.vertices, gr.triangles, gr.normals, groups, resolution=rs.ssdf_resolution,
                                       pca_terms=rs.pca_terms, device=device, progress=progress, compute=compute)
            return precompute.ssdf_for_mesh(gr.vertices, gr.triangles, gr.normals, resolution=rs.ssdf_resolution,
                                            pca_terms=rs.pca_terms, device=device, progress=progress, compute=compute,
                                            cutouts=cut, representatives=rs.visibility_budget,
                                            occluders=(g.vertices, g.triangles) if gr is not g else None)

        data = _timed(parts, "ssdf", ssdf)
        rows = None
        if rs.bounces > 0:
            from precompute.visibility.gather import gather_for_mesh, gather_key

            def gather():
                # (SSDFs at representatives: the rows there too, blended as the maps were)
                reps = np.unique(data.representative) if len(getattr(data, "blend_index", ())) else None
                kw = {"cutouts": cut, "groups": groups, "receivers": reps}
                old = (precomputed or {}).get("gather")
                if old is not None and old.key == gather_key(gr.vertices, gr.triangles, gr.normals, **kw):
                    return old
                return gather_for_mesh(gr.vertices, gr.triangles, gr.normals, device=device, progress=progress, **kw)

            rows = _timed(parts, "gather", gather)
    return ref, gr, data, parts, rows


def visibility_arrays(ssdf, normals, n_vertices: int, device) -> S.Visibility:
    """The shading kernel's visibility (``ssdf`` None: no shadows, V = 1) for a mesh of
    ``n_vertices`` vertices with the device normals ``normals``."""
    from precompute.visibility.occluder_cone import no_cones, texel_half_diagonal
    from warp_sg.sg.fh import fh_table_array

    d = device
    vis = S.Visibility()
    vis.fh_table = fh_table_array(d)
    vis.normals = normals
    if ssdf is not None:
        import precompute

        vis.mean, vis.basis, vis.weights = ssdf.device_arrays(d, precompute.visibility.ssdf.decompress_budget())
        cones = ssdf.cones if len(ssdf.cones) == n_vertices else no_cones(n_vertices)
        vis.cones = wp.array(cones, dtype=wp.vec4, device=d)
        vis.cone_band = texel_half_diagonal(ssdf.resolution)
    else:
        vis.mean = wp.zeros((2, 2), dtype=float, device=d)
        vis.basis = wp.zeros((2, 2, 0), dtype=float, device=d)
        vis.weights = wp.zeros((1, 1), dtype=float, device=d)
        vis.cones = wp.array(no_cones(1), dtype=wp.vec4, device=d)
        vis.cone_band = 1.0
    vis.light_deficit = wp.zeros((1, 1), dtype=float, device=d)
    vis.frame_t = vis.frame_b = wp.zeros(1, dtype=wp.vec3, device=d)  # (the frames of the normals)
    return vis


__all__ = ["compute_visibility", "moving_budgets", "needs_shadows", "refine_key", "visibility_arrays",
           "visibility_groups"]
