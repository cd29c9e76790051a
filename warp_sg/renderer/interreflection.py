r"""Light that bounces in the :class:`~warp_sg.renderer.renderer.Renderer` (a mixin of it):
``[render] bounces``, the gather rows and the indirect light of each frame.

The precompute adds one step to the shadows' (:func:`warp_sg.renderer.visibility_setup.compute_visibility`):
the gather rows of the refined mesh (:mod:`precompute.visibility.gather`, cached beside its SSDFs).
A frame then needs, per vertex (:mod:`warp_sg.shading.bounce`):

* the **direct irradiance** ``E_direct/π`` — the shading kernel itself evaluated at the vertices
  (as :meth:`shade_vertices` does) with every material replaced by a white Lambert one, so the
  lights, the environment and the visibility are exactly the frame's (moving objects' proxies
  included); rebuilt when a light, the environment, the geometry or the shown terms change;
* the **senders' albedo and emission** (:func:`warp_sg.shading.bounce.sender_arrays`): rebuilt when a
  material changes;
* the **bounces** (:class:`warp_sg.shading.bounce.Transfer`): when either changed.

**Objects that move** (``dynamic = true``): the rows are per group (:mod:`precompute.visibility.gather`),
so a moving object keeps the light it throws on itself (its rows' directions turned with it) and
the static objects theirs. A move (and the first frame) casts the rows of the moving objects'
vertices and of the vertices whose hemisphere sees one again, against the scene as it stands
(:meth:`_pose_rows`, :mod:`precompute.visibility.gather_pose`), in place of theirs: the light
between a moving object and the rest, and no stale light (the rows are a function of the
transforms). A move re-shades the vertices' direct light (its shadow moved) and runs the bounces again.

A camera move reuses all three, so does a frame with nothing changed: the kernel only reads the
vertices' indirect irradiance (and, for glossy materials, the lobes' amplitudes). ``timings``
gains ``bounce`` (seconds this frame spent on them) and ``bounces`` (how many ran).

Bounces need the shadows' precompute (``[render] shadows``; a scene that cannot shadow itself
cannot light itself either: a single convex object has nothing to gather). ``bounces = 0`` is the
paper's light transport (direct light only), as is :meth:`set_terms` ``(bounces=False)``.
"""
from __future__ import annotations

import time
from dataclasses import astuple, replace

import numpy as np
import warp as wp

from warp_sg.shading import kernel as S
from warp_sg.shading.bounce import Indirect, Transfer, no_indirect, sender_arrays, sender_kernel, specular_albedo
from warp_sg.shading.vertex_visibility import VertexCache


class Interreflection:
    """The indirect light of a ``Renderer``'s frames (module docstring)."""

    #: light that bounces shown (:meth:`set_terms`; the viewer's check box)
    show_bounces = True
    #: rays per vertex of the rows cast again after a move (None: the gather's own, 256; docs/benchmarks.md
    #: "Light that bounces" measures both)
    pose_rays = 64

    def _reset_bounces(self, gather=None) -> None:
        """Forget the frame state of the bounces; ``gather``: the installed geometry's rows (None: none)."""
        blend = None
        if gather is not None and self.ssdf is not None and hasattr(self.ssdf, "blend_arrays"):
            b = self.ssdf.blend_arrays(self.device)  # (rows at the SSDFs' representatives: blended as they are)
            blend = None if b is None or int(b[1].shape[0]) != gather.n_vertices else (b[1], b[2])
        self._transfer = None if gather is None else Transfer(gather, self.device, blend)
        self.gather = gather
        self._bounce_caches = (VertexCache(), VertexCache(), VertexCache())  # direct light, senders, solution
        self._vertex_buffer = None

    def _bounces_on(self) -> bool:
        """Whether frames add interreflected light: ``[render] bounces`` > 0, rows installed, the
        shadows and the bounces shown."""
        return (self.scene.render.bounces > 0 and getattr(self, "_transfer", None) is not None and self.shadows
                and self.show_shadows and self.show_bounces)

    def _vertex_samples(self):
        """The one-row "visibility buffer" that selects every vertex (cached per geometry)."""
        if self._vertex_buffer is None or self._vertex_buffer[0] is not self.geometry:
            from warp_sg.scene.geometry import vertex_samples

            g, d = self.geometry, self.device
            owner, bary = vertex_samples(g.triangles, len(g.vertices))
            nv = len(g.vertices)
            self._vertex_buffer = (g, wp.array(owner.reshape(1, nv), dtype=int, device=d),
                                   wp.array(bary.reshape(1, nv, 2), dtype=wp.vec2, device=d),
                                   wp.array(owner, dtype=int, device=d), wp.array(bary, dtype=wp.vec2, device=d))
        return self._vertex_buffer[1:]

    def _white(self):
        """A white Lambert material in every slot of the material table, and textures that bind none."""
        from warp_sg.brdf import Lambert
        from warp_sg.brdf.kernel.material_wp import pack_materials
        from warp_sg.scene.textures import build_atlas
        from warp_sg.shading.surface import N_SLOTS, MaterialTextures

        n = int(self.material_table.materials.shape[0])
        if getattr(self, "_white_tables", None) is None or self._white_tables[0] != n:
            table = pack_materials([Lambert(kd=1.0)] * n, 1, self.device)
            tex = MaterialTextures()
            tex.slots = wp.full((max(n, 1), N_SLOTS), -1, dtype=int, device=self.device)
            tex.atlas = build_atlas([], self.device)
            self._white_tables = (n, table, tex)
        return self._white_tables[1:]

    def _direct_irradiance(self, f: S.Features):
        """(V,) vec3: ``E_direct/π`` at every vertex (module docstring)."""
        table, tex = self._white()
        fw = replace(f, env_specular=S.ENV_NONE, specular=False, textures=False, normal_maps=False,
                     models=table.models, emission=False, occlusion=False, coat=False, vertex_colors=False,
                     cutouts=False, bounce=False)
        tri_id, bary, _, _ = self._vertex_samples()
        nv = int(tri_id.shape[1])
        out = wp.empty((1, nv), dtype=wp.vec3, device=self.device)
        bg = wp.zeros((1, nv), dtype=wp.vec3, device=self.device)
        reads = None if self.dynamic is None else self.dynamic.reads
        if self.dynamic is not None:  # (every vertex is read: every moving row)
            self.dynamic.reads = None
        try:
            from raster import parallel

            kern, n, args, _ = self._shade_args(tri_id, bary, bg, self.scene.camera.origin, out, fw, table.materials,
                                                tex, no_indirect(self.device))
            parallel.launch(kern, n, args, self.device, min_chunk=2048, per_thread=S.PIXELS_PER_THREAD)
        finally:
            if self.dynamic is not None:
                self.dynamic.reads = reads
        return wp.array(out.numpy().reshape(nv, 3), dtype=wp.vec3, device=self.device)

    def _sender_kernels(self):
        return sender_kernel(self.material_table.models)

    def _senders(self):
        """(albedo, emission) of every vertex as a sender (:func:`warp_sg.shading.bounce.sender_arrays`)."""
        _, _, owner, bary = self._vertex_samples()
        mt = self.material_table
        self.load_kernels(self._sender_kernels())  # (compiled on the pool: warp_sg.renderer.kernel_preload)
        spec = specular_albedo(mt.materials, mt.models, self.device)
        return sender_arrays(owner, bary, self.geo_arrays, mt.materials, mt.models, self.material_textures,
                             self.layers, spec, self.device)

    def _indirect(self, f: S.Features) -> Indirect:
        """The indirect light the kernel variant ``f`` reads this frame (:mod:`warp_sg.shading.bounce`),
        rebuilt only where its inputs changed (module docstring)."""
        if not f.bounce:
            return no_indirect(self.device)
        t0 = time.perf_counter()
        c_direct, c_send, c_solve = self._bounce_caches
        dyn = None if self.dynamic is None else self.dynamic.version
        if dyn is not None and getattr(self, "_turned", None) != (self._transfer, dyn):
            # the moved objects' rows point where their objects turned (their own group's senders),
            # and the rows the move changes are cast again at the current pose (_pose_rows)
            self._transfer.turn([(ids, self.dynamic._delta(k)[0]) for k, ids in self.dynamic.ids.items()],
                                rows=self._pose_rows())
            self._turned = (self._transfer, dyn)
        key_d = (self.light_arrays, self._env_arrays_key, self.vis, self.geometry, dyn, astuple(f))
        g_direct = c_direct.array(key_d, lambda: self._direct_irradiance(f), self.device)
        key_s = (self.material_table, self.material_textures, self.layers, self.geometry)
        albedo, emit = c_send.array(key_s, self._senders, self.device)
        rs = self.scene.render
        key = (g_direct, albedo, int(rs.bounces), bool(f.specular))

        def solve():
            ind, n = self._transfer.solve(g_direct, albedo, emit, self.geo_arrays.normals, int(rs.bounces),
                                          lobes=bool(f.specular))
            self.timings["bounces"] = n
            return ind

        ind = c_solve.array(key, solve, self.device)
        self.timings["bounce"] = self.timings.get("bounce", 0.0) + time.perf_counter() - t0
        return ind

    def _pose_rows(self):
        """``(ids, counts, senders, weights, directions)``: the gather rows a move changes, cast at
        the current pose (:mod:`precompute.visibility.gather_pose`: the moving objects' vertices and
        the vertices whose hemisphere sees one; :attr:`pose_rays` rays each, None: the gather's
        own). ``timings["pose_rows"]``, ``["pose_rows_cpu"]``: their wall and CPU seconds."""
        from precompute.visibility.gather_pose import PoseGather

        w0, c0 = time.perf_counter(), time.process_time()
        dyn, ga, t = self.dynamic, self.geo_arrays, self._transfer
        pg = getattr(self, "_pose_gather", None)
        if pg is None or pg[0] is not t or pg[1].points is not ga.positions:
            pg = (t, PoseGather(ga.positions, ga.normals, self.geometry.triangles, dyn.rest_v, self.device))
            self._pose_gather = pg
        ids = pg[1].receivers(dyn.vertex_object, dyn.flags, dyn.px.bounds)
        if t.blend is not None:  # (rows at representatives: the others are blended from theirs)
            ids = ids[t.blend[0].numpy()[ids, 0] == ids]
        rays = self.pose_rays or self.gather.rays
        rows = (ids, *pg[1].rows(ids, rays, self.gather.refs))
        self.timings["pose_rows"] = time.perf_counter() - w0
        self.timings["pose_rows_cpu"] = time.process_time() - c0
        return rows

    def indirect_irradiance(self) -> np.ndarray:
        """(V, 3) float32: each vertex's indirect irradiance of the current state (zeros when the
        frames add none)."""
        f = self.features()
        ind = self._indirect(f)
        nv = len(self.geometry.vertices)
        if not f.bounce:
            return np.zeros((nv, 3), np.float32)
        return ind.irr.numpy()[:nv]


__all__ = ["Interreflection"]
