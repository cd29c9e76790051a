r"""The frame paths of the :class:`~warp_sg.renderer.renderer.Renderer` (a mixin of it).

``render()`` rasterises the camera view (``raster.rasterize``, k×k supersampled, the buffer kept
while the camera stays), shades every (sub)pixel once with the kernel variant the scene needs
(:mod:`warp_sg.renderer.variant`, :mod:`warp_sg.shading.kernel`) and box-resolves k×k blocks; with
``[render] antialias`` a > 1 and no supersampling the edge- and contrast-adaptive path of
:mod:`warp_sg.renderer.antialias` runs instead. ``shade_vertices`` evaluates the same kernel at
the mesh vertices (the pyvista preview). Every shading launch first brings the per-vertex caches
up to date (:func:`warp_sg.shading.vertex_visibility.update_caches`).
"""
from __future__ import annotations

import time

import numpy as np
import warp as wp

from warp_sg.renderer.kernel_preload import FRAME_MODULES, SHADOW_FRAME_MODULES
from warp_sg.shading import kernel as S
from warp_sg.shading.vertex_visibility import update_caches

_FRAME_MODULES = FRAME_MODULES + SHADOW_FRAME_MODULES


def _timer(device):
    wp.synchronize_device(device)
    return time.perf_counter()


class FramePaths:
    """Rasterise, shade and resolve one frame of a ``Renderer``."""

    def _vertex_visibility(self, es, f):
        """The per-vertex caches, brought up to date for the variant ``f``
        (:func:`warp_sg.shading.vertex_visibility.update_caches`, fed :meth:`cache_inputs`)."""
        caches = (self.env_vis_cache, self.light_vis_cache, self.env_visible_cache)
        es, seconds = update_caches(caches, self.cache_inputs(), f, es)
        self.timings["vertex_visibility"] = seconds
        if self.dynamic is not None:  # the moved vertices' rows
            t = time.perf_counter()
            self.dynamic.patch_caches(self, es)
            self.timings["motion_caches"] = self.timings.get("motion_caches", 0.0) + time.perf_counter() - t
        return es

    def _move(self) -> None:
        """Dynamic objects' transforms into the device arrays (timed as ``timings["motion"]``)."""
        if self.dynamic is not None:
            t = time.perf_counter()
            self.timings["motion_caches"] = 0.0  # (the moved vertices' cache rows, summed over the frame)
            with wp.ScopedDevice(self.device):
                self.dynamic.apply(self)
            self.timings["motion"] = time.perf_counter() - t

    def _background(self, k: int, rays: bool = False):
        """What the (sub)pixels of the k× grid that see no object show
        (:class:`warp_sg.shading.background.BackgroundCache`): the camera rays, or this frame's image."""
        args = self._bg_args(k)
        if rays:
            return self._bg.params(*args)
        vb, reused = self._vb, bool(self.timings.get("raster_reused"))
        if vb is not None and vb._over is not None:  # moving objects drawn over the static ones' buffer:
            vb, reused = vb._over, True  # the image where the static objects leave the background, per camera
        bg = self._bg.for_frame(*args, vb, reused)
        self.timings["background"] = "image" if isinstance(bg, wp.array) else "rays"  # (what the frame read)
        return bg

    def _bg_args(self, k: int) -> tuple:
        return self.scene.camera, k, self.env_light, getattr(self, "env_base", None), self.scene.render.background

    def rasterize(self, k: int | None = None, subsamples: int = 1):
        """The visibility buffer of the current camera at k×k sub-pixels (``subsamples`` a > 1: with
        the tile queues antialiasing reads a×a sub-pixels from, ``raster.subsample``). The geometry
        is static and was validated once (``_setup_geometry``): it is rasterised from its device
        arrays, and the buffer is reused while the camera and k stay the same (material, light and
        environment edits re-shade only). With dynamic objects (and :attr:`incremental_raster`) the
        static objects' buffer is kept per camera and only the moving ones are rasterised again
        (:mod:`warp_sg.renderer.moving_raster`; the same buffer bit for bit)."""
        import raster

        k = self.scene.render.supersampling if k is None else k
        key = (repr(self.scene.camera), int(k), int(subsamples))
        if self._vb_key != key and self.dynamic is not None and self.incremental_raster:
            self._vb = self.dynamic.raster.rasterize(self.geo_arrays.positions, self.scene.camera, k, subsamples,
                                                     self._cull_flags(), self.dynamic.version)
            self._vb_key = key
            self.timings["raster_reused"] = False
            # (the moving vertices' cache rows this frame reads: those of the triangles its queue holds)
            self.dynamic.reads = self.dynamic.raster.moving.vb if subsamples > 1 else None
        elif self._vb_key != key:  # the old buffer's arrays are overwritten when the size matches
            if self.dynamic is not None:
                self.dynamic.reads = None
            old, self._vb = self._vb, None
            self._vb = raster.rasterize(self.geo_arrays.positions, self.geo_arrays.tris, self.scene.camera,
                                        device=self.device, supersample=k, validate=False, reuse=old,
                                        subsamples=subsamples, cull_backfaces=self._cull_flags())
            self._vb_key = key
            self.timings["raster_reused"] = False
        else:
            self.timings["raster_reused"] = True
        return self._vb

    def render(self) -> np.ndarray:
        """One frame: (H, W, 3) float32 linear radiance.

        With ``[render] supersampling`` k > 1 every one of the k×k sub-pixels is shaded and box-
        filtered. Otherwise, with ``antialias`` a > 1 (the default, 4), coverage is rasterised at
        a×a sub-pixels and shading is edge-adaptive: a pixel whose sub-pixels all see the same
        object at similar depth is shaded once (at its centre), an edge pixel once per triangle its
        sub-pixels see, weighted by coverage, a contrasting one at 4 probes and, where they
        disagree, at every sub-pixel (:mod:`warp_sg.renderer.antialias`) — antialiased silhouettes at a
        fraction of the cost of shading every sub-pixel. A ``progressive`` renderer first installs
        its shadows if they have become ready (:meth:`poll`)."""
        self.load_modules(_FRAME_MODULES, queued_only=True)  # (compiling ahead on the pool: kernel_preload)
        self.poll()
        self._move()
        self.timings["bounce"] = 0.0  # (light that bounces: this frame's seconds, summed over its launches)
        try:
            return self._render()
        finally:
            self._start_gamma_job()  # (a progressive renderer's ΓL ladder: after its first frame)
            if self.shadows_pending:  # (and the variant its shadowed frames will run)
                self._preload_final_shade()

    def _adaptive(self) -> bool:
        """Whether frames take the edge- and contrast-adaptive path (:meth:`render`): no
        supersampling, ``antialias`` > 1 and no gradients (a ``requires_grad`` renderer's frames
        shade k×k sub-pixels, :mod:`warp_sg.renderer.gradients`)."""
        rs = self.scene.render
        return rs.supersampling == 1 and rs.antialias > 1 and not self.requires_grad

    def _render(self) -> np.ndarray:
        rs = self.scene.render
        if self.requires_grad:  # recorded for the backward pass (warp_sg.renderer.gradients)
            return self._render_grad()
        if self._adaptive():
            return self._render_adaptive(int(rs.antialias))
        d = self.device
        k = rs.supersampling
        cam = self.scene.camera
        t0 = _timer(d)
        vb = self.rasterize()
        t1 = _timer(d)
        bg = self._background(k)
        hs, ws_ = cam.height * k, cam.width * k
        out = wp.empty((hs, ws_), dtype=wp.vec3, device=d)
        self._launch_shade(vb.tri_id, vb.bary, bg, cam.origin, out)
        t2 = _timer(d)
        if k > 1:
            res = wp.empty((cam.height, cam.width), dtype=wp.vec3, device=d)
            wp.launch(S.resolve_box, dim=(cam.height, cam.width), inputs=[out, k], outputs=[res], device=d)
            out = res
        img = out.numpy().reshape(cam.height, cam.width, 3)  # float32; on the CPU a view of this frame's own buffer
        t3 = time.perf_counter()
        self.timings.update(raster=t1 - t0, shade=t2 - t1, resolve=t3 - t2, frame=t3 - t0, shaded_samples=hs * ws_)
        return img

    def _render_adaptive(self, a: int) -> np.ndarray:
        """Edge- and contrast-adaptive antialiasing on the device (:mod:`warp_sg.renderer.antialias`): the
        1× frame, then a×a sub-pixels where it needs them."""
        from warp_sg.renderer.antialias import AntialiasCache, render_adaptive

        d, cam = self.device, self.scene.camera
        if self._aa is None:
            split = self.dynamic is not None and self.incremental_raster
            ready = self._mesh_caches()
            self._aa = AntialiasCache(self.geo_arrays.positions, self.geo_arrays.tris, d,
                                      moving=self.dynamic.raster.tri_moving if split else None,
                                      adjacency=ready[1] if ready is not None else None)
        shade = lambda tri, bary, bg, out: self._launch_shade(tri, bary, bg, cam.origin, out)  # noqa: E731
        t0 = _timer(d)
        vb = self.rasterize(1, subsamples=a)
        t1 = _timer(d)
        img = wp.empty((cam.height, cam.width), dtype=wp.vec3, device=d)
        shade(vb.tri_id, vb.bary, self._background(1), img)
        img, st = render_adaptive(vb, img, self._aa, cam, self._tri_object, self._background(a, rays=True), a,
                                  cam.height, cam.width, shade, d)
        t2 = _timer(d)
        out = img.numpy()  # float32; on the CPU a view of this frame's own buffer (not reused)
        t3 = time.perf_counter()
        sub = st["raster_seconds"]  # the sub-pixel coverage, inside render_adaptive
        self.timings.update(raster=t1 - t0 + sub, shade=t2 - t1 - sub, resolve=t3 - t2, frame=t3 - t0,
                            shaded_samples=st["pass1_samples"] + st["pass2_samples"], edge_pixels=st["edge_pixels"],
                            contrast_pixels=st["contrast_pixels"], refined_pixels=st["refined_pixels"],
                            candidate_pixels=st["candidate_pixels"],
                            subpixel_tiles=st["tile_fraction"], subpixel_seconds=sub)
        return out

    def _start_mesh_caches(self) -> None:
        """Build the installed geometry's per-mesh caches of the first frame on a thread —
        back-face culling's closedness (:class:`warp_sg.scene.culling.BackfaceCulling`) and the
        contours' edge adjacency (:func:`warp_sg.shading.silhouette.edge_adjacency`, of the
        float32 positions the device arrays hold), numpy sorts that release the GIL — so that they
        are ready when the first ``render()`` asks (:meth:`_mesh_caches`): a progressive renderer
        starts it beside its environment setup, whose SG fit leaves a core idle."""
        from warp_sg.renderer.progressive import ShadowJob
        from warp_sg.scene.culling import BackfaceCulling
        from warp_sg.shading.silhouette import edge_adjacency

        g, d = self.geometry, self.device
        # the adaptive path's; not with moving objects, whose first frame may move the vertex
        # positions the adjacency reads
        contours = self._adaptive() and self.dynamic is None
        job = ShadowJob(lambda: (BackfaceCulling(g, d),
                                 edge_adjacency(g.vertices, g.triangles) if contours else None),
                        name="warp-sg-mesh-caches")
        self._mesh_job = (g, job)

    def _mesh_caches(self):
        """``(BackfaceCulling, (edge_v, edge_f) or None)`` of the installed geometry from
        :meth:`_start_mesh_caches` (waited for), or None when none was started for it (they are
        then built where they are needed)."""
        g, job = self._mesh_job or (None, None)
        if job is None or g is not self.geometry:
            self._mesh_job = None  # (a job for an earlier geometry: its result is not this mesh's)
            return None
        job.wait()
        return job.result()

    def _cull_flags(self):
        """The back faces the raster may drop (``warp_sg.scene.culling``: closed objects seen from outside)."""
        from warp_sg.scene.culling import BackfaceCulling

        if self._culling is None:
            ready = self._mesh_caches()
            self._culling = ready[0] if ready is not None else BackfaceCulling(self.geometry, self.device)
            if self.dynamic is not None:  # (the moving objects' boxes: a function of their transforms)
                self.dynamic.place_culling(self._culling)
        return self._culling.flags(self.scene.camera)

    def shade_vertices(self, eye=None) -> np.ndarray:
        """The renderer's shading evaluated at every mesh vertex (V, 3) float32, seen from ``eye``
        (default: the camera origin). Uses the same kernel as :meth:`render` on a one-row
        "visibility buffer" whose entries select each vertex of a triangle that contains it
        (used by the pyvista preview). Unreferenced vertices get 0."""
        from warp_sg.scene.geometry import vertex_samples

        self.poll()
        self._move()
        d, nv = self.device, len(self.geometry.vertices)
        owner, bary = vertex_samples(self.geometry.triangles, nv)
        tri_id = wp.array(owner.reshape(1, nv), dtype=int, device=d)
        bary_w = wp.array(bary.reshape(1, nv, 2), dtype=wp.vec2, device=d)
        bg = wp.zeros((1, nv), dtype=wp.vec3, device=d)
        eye = np.asarray(self.scene.camera.origin if eye is None else eye, np.float32)
        out = wp.empty((1, nv), dtype=wp.vec3, device=d)
        reads = None if self.dynamic is None else self.dynamic.reads
        if self.dynamic is not None:  # (every vertex is read: every moving row)
            self.dynamic.reads = None
        try:
            self._launch_shade(tri_id, bary_w, bg, eye, out)
        finally:
            if self.dynamic is not None:
                self.dynamic.reads = reads
            self._start_gamma_job()
        return out.numpy().reshape(nv, 3)

    def _launch_shade(self, tri_id, bary, bg, eye, out):
        from raster import parallel

        kern, n, args, _ = self._shade_args(tri_id, bary, bg, eye, out)
        parallel.launch(kern, n, args, self.device, min_chunk=2048, per_thread=S.PIXELS_PER_THREAD)

    def _shade_args(self, tri_id, bary, bg, eye, out, f=None, materials=None, textures=None, ind=None):
        """``(kernel, samples, arguments after (base, per), EnvSG)`` of one shading launch: the
        variant of the current state, the per-vertex caches brought up to date; or the variant
        ``f`` with these materials, textures and indirect light ``ind`` (the vertices' direct light
        of :mod:`warp_sg.renderer.interreflection`)."""
        d = self.device
        if f is None:
            self._ensure_gamma()  # a material may have become specular
            f = self.features()
            ind = self._indirect(f)  # (light that bounces: shades the vertices first when the light changed)
            materials, textures = self.material_table.materials, self.material_textures
        from raster import parallel

        # a new variant is built and its module loaded beside the vertex caches
        loading = None if S.shade_kernel_ready(f, d) else (
            self._preload.shade(f, priority=0) if self._preload is not None else parallel.load_beside(lambda: S.shade_kernel(f), d))
        es = self._vertex_visibility(self._env_arrays(), f)
        kern = S.shade_kernel(f) if loading is None else loading.result()
        if f.env_specular == S.ENV_PREFILTERED:
            env = self.env_light
            gamma = self.gamma.table(rotation=env.rotation_matrix(), scale=env.scale, device=d)
        else:
            gamma = es  # the mixture's lobes (ENV_MIXTURE), or a placeholder of the variant without ΓL
        n = int(tri_id.shape[0]) * int(tri_id.shape[1])
        self.layers.n_local = len(self.scene.local_lights)  # (the rest are the environment's peaks)
        args = [tri_id, bary, *self._bg.kernel_args(bg), wp.vec3(*np.asarray(eye, np.float32)), self.geo_arrays,
                materials, textures, self.irr_table, self.light_arrays, es, gamma, self.vis, self._proxies,
                self.layers, self.cut.arrays, self.cut.mesh_id, self._bg.params(*self._bg_args(1)), ind, out]
        return kern, n, args, es


__all__ = ["FramePaths"]
