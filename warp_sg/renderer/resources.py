r"""What the precompute produces and every frame reads: the :class:`~warp_sg.renderer.renderer.Renderer`'s
resources (a mixin of it).

* geometry: the scene's flattened mesh on the device, refined where the visibility changes when
  the scene has shadows, with its alpha cut-outs (:meth:`ResourceSetup._setup_geometry`);
* shadows: the refinement and per-vertex SSDFs (:mod:`warp_sg.renderer.visibility_setup`), at
  once or on a background thread (``progressive``: :meth:`ResourceSetup.poll`, :meth:`~ResourceSetup.wait`),
  and :meth:`~ResourceSetup.precomputed` to hand them to another renderer;
* materials: the packed kernel records, the texture atlas, the layers and the environment
  specular's energy correction (:meth:`ResourceSetup._setup_materials`);
* lights: the scene's local lights plus the environment's peaks (:meth:`ResourceSetup._setup_lights`);
* :meth:`ResourceSetup.cache_inputs`: the explicit record the per-vertex caches read
  (:class:`~warp_sg.shading.vertex_visibility.CacheInputs`).

The environment's own resources (peaks, irradiance, SG fit, ΓL) are :mod:`warp_sg.renderer.environment_setup`'s.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from warp_sg.brdf.kernel.term_mask import TermMask
from warp_sg.brdf.registry import has_specular
from warp_sg.core.errors import InputError, SceneError
from warp_sg.renderer.kernel_preload import BOUNCE_MODULES, SHADOW_MODULES
from warp_sg.renderer.progressive import ShadowJob
from warp_sg.renderer.visibility_setup import refine_key, visibility_arrays
from warp_sg.scene.lights import light_arrays
from warp_sg.scene.lobe_extent import gamma_reach
from warp_sg.scene.model import COLOUR_PARAMS
from warp_sg.scene.textures import build_atlas
from warp_sg.shading import kernel as S
from warp_sg.shading.cutout import CutoutScene, cutout_data
from warp_sg.shading.light_rays import LightOccluders
from warp_sg.shading.surface import (
    SLOT_KD,
    SLOT_KS,
    SLOT_NORMAL,
    SLOT_OCCLUSION,
    SLOT_P0,
    SLOT_TANGENT,
    MaterialTextures,
    material_texture_slots,
)
from warp_sg.shading.vertex_visibility import CacheInputs, caches


class ResourceSetup:
    """Geometry, shadows, materials and lights of a ``Renderer`` (which calls the ``_setup_*``
    methods in its constructor and again after an edit)."""

    def precomputed(self) -> dict:
        """The mesh refinement, SSDFs and gather rows of this renderer (plain numpy data, picklable), for
        ``Renderer(scene', precomputed=...)`` of a scene with the same geometry and visibility
        settings (camera, materials, lights and environment may differ)."""
        self.wait()
        g = self.input_geometry
        rs = self.scene.render
        dynamic = [bool(ob.dynamic) for ob in self.scene.objects]
        key = refine_key(g, rs.visibility_budget, self._refine_lights(), dynamic, rs.moving_visibility_budget)
        return {"refine_key": key if self._refined is not None else None,
                "refinement": self._refined, "ssdf": self.ssdf, "gather": self.gather}

    def _setup_geometry(self):
        """The scene's flattened mesh; with shadows, refined where the visibility changes
        (``precompute.refine_for_visibility``, ``[render] visibility_budget`` vertices at most) so
        the per-vertex SSDFs do not depend on how the user tessellated (a floor exported as two
        triangles still gets its shadows), and its SSDFs (:mod:`warp_sg.renderer.visibility_setup`). Raster,
        SSDF precompute and shading use the refined mesh. ``progressive``: the refinement and SSDFs
        are computed on a background thread (:mod:`warp_sg.renderer.progressive`) and installed by
        :meth:`poll`; until then the input mesh is shaded without shadows."""
        from warp_sg.renderer.visibility_setup import compute_visibility, needs_shadows

        g = self.scene.geometry()
        self.input_geometry = g
        self.shadows = False
        self.ssdf = None
        self._refined = None
        self._install_geometry(g, None)
        if not needs_shadows(self.scene, g):
            return
        args = (self.scene, g, self.device)
        kw = {"progress": self.progress, "compute": self._ssdf_compute, "precomputed": self._precomputed,
              "lights": self._refine_lights(), "cutouts": lambda geo: cutout_data(geo, self.scene.materials),
              "dynamic": [bool(ob.dynamic) for ob in self.scene.objects]}  # (per-group SSDFs where any)

        def shadows():  # (their modules compiled on the pool first, a progressive renderer's behind its frames')
            if self._precomputed is None:
                self.load_modules(SHADOW_MODULES + (BOUNCE_MODULES if self.scene.render.bounces > 0 else ()),
                                  priority=50 if self.progressive else 0)
            return compute_visibility(*args, **kw)

        if self.progressive:  # started once the first frame's own precompute is done (__init__)
            self._job = lambda: ShadowJob(shadows, background=True)
        elif self.overlap_precompute:  # beside the environment fit and ΓL (single-threaded parts)
            self._job = ShadowJob(shadows)
        else:
            self._install_shadows(shadows())

    def _install_geometry(self, g, ref):
        self.refinement = ref if ref is not None and len(ref.vertices) > len(self.input_geometry.vertices) else None
        self.geometry = g
        d = self.device
        ga = S.GeometryArrays()
        ga.positions = wp.array(g.vertices, dtype=wp.vec3, device=d)
        ga.normals = wp.array(g.normals, dtype=wp.vec3, device=d)
        ga.uvs = wp.array(g.uvs, dtype=wp.vec2, device=d)
        ga.tangents = wp.array(g.tangents, dtype=wp.vec3, device=d)
        ga.tris = wp.array(g.triangles, dtype=wp.vec3i, device=d)
        ga.tri_material = wp.array(g.tri_material, dtype=int, device=d)
        self.geo_arrays = ga
        self._tri_object = wp.array(np.asarray(g.tri_object, np.int32), dtype=int, device=d)
        # alpha cut-outs of the (refined) geometry: camera rays continue through their holes
        self.cut = CutoutScene(g, self.scene.materials, ga.positions, d)
        self.cutouts = self.cut.data
        # the static objects, for the lights' ray-cast visibility at the vertices (built on first use)
        self.light_occluders = LightOccluders(g, ga.positions, ga.tris, self.cut,
                                              [not ob.dynamic for ob in self.scene.objects], d)
        self.vis = visibility_arrays(None, ga.normals, len(g.vertices), d)
        self._reset_bounces(None)
        self._setup_dynamic()

    def _setup_dynamic(self):
        """The moving objects of the installed geometry (:mod:`warp_sg.renderer.dynamic_objects`;
        their transforms carried over from the last install), None in a static scene."""
        from warp_sg.shading.motion_wp import no_proxies

        self._proxies = no_proxies(self.device)
        if self._rest_motions:
            from warp_sg.renderer.dynamic_objects import DynamicObjects

            self.dynamic = DynamicObjects(self, self._rest_motions, self.dynamic)
            self._proxies = self.dynamic.px

    def _install_shadows(self, result):
        """Install :func:`warp_sg.renderer.visibility_setup.compute_visibility`'s result: the refined mesh,
        its SSDFs and the shading visibility."""
        ref, g, ssdf, parts, gather = result
        for name, (w, c) in parts.items():
            self.timings["precompute_parts"][name] = w
            self.timings["precompute_cpu"][name] = c
        self._refined = ref
        self._install_geometry(g, ref)
        self.shadows = True
        self.ssdf = ssdf
        self.vis = visibility_arrays(ssdf, self.geo_arrays.normals, len(g.vertices), self.device)
        self._reset_bounces(gather)
        if self.dynamic is not None:
            self.dynamic.attach(self)  # the vertices' SSDF frames, which turn with their objects

    @property
    def shadows_pending(self) -> bool:
        """A progressive renderer whose SSDFs are not installed yet (:meth:`poll`)."""
        return self._job is not None

    def shadows_ready(self) -> bool:
        """Whether nothing is left to wait for: no background precompute (the shadows, a
        progressive renderer's ΓL ladder), or ones that have finished (installed by the next
        :meth:`poll`)."""
        return all(j is None or isinstance(j, ShadowJob) and j.done() for j in (self._job, self._gamma_job))

    def poll(self) -> bool:
        """Install the background shadow precompute's result if it has finished (``progressive``):
        True when this call switched the renderer to shadowed frames. Never waits; an error of
        the precompute is raised here. ``render()`` calls it first. A progressive renderer's
        ΓL ladder is installed likewise when it is ready (:meth:`_poll_gamma`)."""
        self._poll_gamma()  # (each frame reads self.gamma's table: nothing else to rebuild)
        job = self._job
        if job is None or not job.done():
            return False
        self._job = None
        result = job.result()
        with wp.ScopedDevice(self.device):
            self._install_shadows(result)
            self._setup_materials()
        self.timings["shadows_ready"] = job.seconds
        self.env_vis_cache, self.light_vis_cache, self.env_visible_cache = caches()
        self._aa = None
        self._vb_key = self._vb = self._culling = None
        return True

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the shadows are installed (``progressive``; at most ``timeout`` seconds):
        whether they are. A renderer built without ``progressive`` has them already."""
        import time

        self._start_gamma_job()
        end = None if timeout is None else time.perf_counter() + timeout
        for job in (self._job, self._gamma_job):
            left = None if end is None else max(end - time.perf_counter(), 0.0)
            if job is not None and not job.wait(left):
                return False
        self.poll()
        return True

    def _setup_materials(self):
        from warp_sg.brdf.kernel.material_wp import pack_materials
        from warp_sg.shading.surface_layers import coat_models, layer_arrays

        scene = self.scene
        rs = scene.render
        names = self.geometry.material_names
        mats = [scene.materials[n] for n in names]
        lays = [m.layers for m in mats]
        coats, coat_index = coat_models(lays)  # the clear coats, packed after the materials
        models = [m.brdf for m in mats] + coats
        # the ΓL ladder's reach: the sharpest NDF lobe (a clear coat: the whole ladder)
        self._gamma_need = gamma_reach(scene, names) if not coats else float("inf")
        if not (self.show_diffuse and self.show_specular):
            models = [TermMask(b, self.show_diffuse, self.show_specular) for b in models]
        try:
            self.material_table = pack_materials(models, rs.lobes, self.device)
        except InputError as e:
            raise SceneError(f"materials: {e}") from None
        self.has_specular = has_specular(self.material_table.models)  # (the models' capability: the registry)
        # textures (atlas layout shared with the reference: warp_sg.shading.surface)
        slots, images = material_texture_slots(mats, COLOUR_PARAMS)
        self.has_textures = bool(np.any(slots[:, :SLOT_NORMAL] >= 0))
        self.has_normal_maps = bool(np.any(slots[:, [SLOT_NORMAL, SLOT_TANGENT]] >= 0))
        self.has_emission = any(lay is not None and lay.emissive for lay in lays)
        self.has_occlusion = bool(np.any(slots[:, SLOT_OCCLUSION] >= 0)) and self.scene.environment is not None
        self.has_coat = bool(coats)
        g = self.geometry
        self.layers = layer_arrays(lays, coat_index, len(mats), g.colors, g.specular_colors, 0, self.device)
        # hidden terms unbind their textures after the variant is chosen (set_terms: same kernel)
        slots[:, SLOT_KD] = np.where(self.show_diffuse, slots[:, SLOT_KD], -1)
        slots[:, SLOT_KS] = np.where(self.show_specular, slots[:, SLOT_KS], -1)
        mt = MaterialTextures()
        mt.slots = wp.array(slots, dtype=int, device=self.device)
        mt.atlas = build_atlas(images, self.device)
        self.material_textures = mt
        if self.has_specular and self.scene.environment is not None:
            # the environment specular's energy correction, per material (brdf.kernel.albedo); a textured
            # first parameter (a roughness map) gets its table over the texture's range
            from warp_sg.brdf.kernel import albedo
            from warp_sg.sg.irradiance import irradiance_table_array

            ranges = [None if s < 0 else (max(float(np.min(images[s][..., 0])), 1e-4),
                                          max(float(np.max(images[s][..., 0])), 1e-4))
                      for s in slots[:len(mats), SLOT_P0]]
            if self.requires_grad:  # ranges that stay put between edits (warp_sg.renderer.gradients)
                ranges = self._fixed_albedo_ranges(names, ranges)
            if self._preload is not None:  # (the material set's albedo kernel: compiled on the pool)
                self._preload.kernel(albedo.albedo_kernel(self.material_table.models))
            albedo.attach(self.material_table, ranges, irradiance_table_array(self.device), self.device)

    def _setup_lights(self):
        from warp_sg.sg.irradiance import irradiance_table_array

        self.shading_lights = list(self.scene.local_lights) + self.peak_lights()
        self.light_arrays = light_arrays(self.shading_lights, self.device)
        self.irr_table = irradiance_table_array(self.device)

    def cache_inputs(self) -> CacheInputs:
        """What the per-vertex caches read (:class:`~warp_sg.shading.vertex_visibility.CacheInputs`):
        this renderer's installed geometry, visibility, lights and environment arrays' key."""
        env = self.env_light
        return CacheInputs(device=self.device, n_vertices=len(self.geometry.vertices), fh=self.scene.render.fh,
                           ssdf=self.ssdf, vis=self.vis, irr_table=self.irr_table,
                           positions=self.geo_arrays.positions, shading_lights=tuple(self.shading_lights),
                           light_arrays=self.light_arrays, env_key=self._env_arrays_key,
                           env_scale=float(env.scale) if env is not None else 0.0,
                           occluders=self.light_occluders if self.shadows else None)


__all__ = ["ResourceSetup"]
