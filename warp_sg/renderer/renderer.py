r"""The renderer: ``ws.render(scene, device)`` and the stateful ``ws.Renderer``.

Data flow (docs/architecture.md "Conventions"): ``scene → precompute (cached) → raster (visibility buffer) → shading → image``.

``Renderer(scene, device)`` does the precompute once and keeps everything on the device:

* geometry arrays (positions, normals, uvs, tangents, triangles, per-triangle material);
* visibility: per-vertex SSDFs with PCA (``precompute.ssdf_for_mesh``, cached on disk) only when
  ``[render] shadows`` is on and the scene can shadow itself (``precompute.needs_visibility``:
  a single convex object cannot);
* environment (when there is one): the SG mixture fit for the diffuse term
  (``precompute.fit_environment_sgs``, eq. 34) and the prefiltered ΓL pyramid for the specular
  term (``precompute.prefilter_environment``, eq. 35), both of the *unrotated, unscaled* map, so
  rotation and scale changes cost nothing;
* materials (``brdf.material_wp.pack_materials``) and textures (one atlas).

``render()`` rasterises the camera view (``raster.rasterize``, k×k supersampled), shades every
(sub)pixel once with the kernel variant the scene needs (:mod:`warp_sg.shading.kernel`), and box-resolves
k×k blocks. Changing materials, textures, lights, the environment rotation/scale or the camera
(the setters below) re-renders without re-running precompute. Per-frame timings (seconds) are in
``Renderer.timings``: ``precompute`` (construction; cache hits included), ``raster``, ``shade``,
``resolve``, ``frame`` (last ``render()``), ``precompute_parts`` (wall seconds of refine, ssdf,
env_peaks, env_fit, env_prefilter) and ``precompute_cpu`` (their CPU seconds, all threads).
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
import warp as wp

from warp_sg.shading.background import BackgroundCache
from warp_sg.renderer.costs import check_frame_costs
from warp_sg.shading.cutout import CutoutScene, cutout_data
from warp_sg.core.device import resolve_device
from warp_sg.core.errors import InputError, SceneError
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight, PointLight, light_arrays
from warp_sg.scene.model import COLOUR_PARAMS, Material, Scene
from warp_sg.scene.geometry import Geometry
from warp_sg.shading.surface import material_texture_slots
from warp_sg.shading import kernel as S
from warp_sg.scene.textures import Texture, build_atlas
from warp_sg.brdf.term_mask import TermMask
from warp_sg.renderer.progressive import ShadowJob
from warp_sg.renderer.environment import EnvironmentSetup
from warp_sg.shading.vertex_visibility import caches
from warp_sg.scene.lobe_extent import gamma_reach
from warp_sg.renderer.visibility_setup import refine_key, visibility_arrays


def _timer(device):
    wp.synchronize_device(device)
    return time.perf_counter()


class Renderer(EnvironmentSetup):
    """Stateful renderer: precompute once, then ``render()`` any number of frames.

    ``progress``: show progress bars for the precompute steps. ``ssdf_compute``: replaces
    ``precompute.compute_ssdf`` inside ``precompute.ssdf_for_mesh`` (same cache entry; e.g. the Dask
    version, :mod:`warp_sg.distributed.precompute`). ``precomputed``: :meth:`precomputed` of a
    renderer of a scene with the same geometry and visibility settings (refinement and SSDFs are
    reused instead of recomputed; a mismatch is an :class:`InputError`): how batch workers share
    one precompute. ``progressive``: the mesh refinement and SSDFs run on a background thread
    (:mod:`warp_sg.renderer.progressive`); frames are unshadowed (those of ``[render] shadows = false``)
    until they are installed (:meth:`poll`, called by :meth:`render`; :meth:`wait`;
    :attr:`shadows_pending`), then equal to a non-progressive renderer's, bit for bit.
    """

    #: compute the refinement and SSDFs on a thread beside the environment fit and ΓL prefilter
    #: (the same data; False: one after the other, so each part's CPU time is its own)
    overlap_precompute = True
    #: terms of eq. 36 shown (:meth:`set_terms`; the viewer's check boxes)
    show_diffuse = True
    show_specular = True
    show_shadows = True

    def __init__(self, scene: Scene, device: str | None = None, progress: bool = False, *, ssdf_compute=None,
                 precomputed: dict | None = None, progressive: bool = False):
        if not isinstance(scene, Scene):
            raise InputError(f"expected a warp_sg.Scene, got {type(scene).__name__}", where="scene")
        self.scene = scene
        self._ssdf_compute = ssdf_compute
        self._precomputed = precomputed
        self.device = resolve_device(device if device is not None else scene.render.device)
        self.progress = progress
        self.progressive = bool(progressive)
        self._job = None  # the background shadow precompute (progressive)
        self.timings: dict = {"precompute_parts": {}, "precompute_cpu": {}}
        self._env_arrays_key = ()  # (see _env_arrays; () = not built yet)
        self._env_sg_arrays = None
        self._gamma_capped, self._gamma_reach = False, 0.0  # (_ensure_gamma)
        self.env_vis_cache, self.light_vis_cache, self.env_visible_cache = caches()  # (_vertex_visibility)
        self._bg = BackgroundCache(self.device)  # what pixels that see no object show
        self._aa = None  # antialiasing's caches between frames (warp_sg.renderer.antialias.AntialiasCache)
        self._vb_key = self._vb = self._culling = None
        self.dynamic = None  # objects that move (warp_sg.scene.dynamic_objects; _setup_dynamic)
        self._rest_motions = {k: ob.motion for k, ob in enumerate(scene.objects) if ob.dynamic}  # the built pose
        t0 = time.perf_counter()
        check_frame_costs(scene, scene.geometry(), shadows=scene.render.shadows,  # the watchdog, before any work
                          specular=any(getattr(m.brdf, "is_specular", True) for m in scene.materials.values()))
        with wp.ScopedDevice(self.device):
            self._setup_env_peaks()
            self._setup_geometry()
            self._setup_materials()
            self._setup_environment()
            self._ensure_gamma()
            self._setup_lights()
        if self.progressive and self._job is not None:  # the shadows now get the cores the setup had
            self._job = self._job()
        elif self._job is not None:  # computed beside the environment setup: install them now
            self.wait()
        wp.synchronize_device(self.device)
        self.timings["precompute"] = time.perf_counter() - t0

    @staticmethod
    def _tick():
        return time.perf_counter(), time.process_time()

    def _tock(self, part: str, t0) -> None:
        """Record part ``part`` begun at ``t0 = _tick()``: wall seconds in ``precompute_parts``, CPU
        seconds of the process (all threads) in ``precompute_cpu``."""
        self.timings["precompute_parts"][part] = time.perf_counter() - t0[0]
        self.timings["precompute_cpu"][part] = time.process_time() - t0[1]

    def precomputed(self) -> dict:
        """The mesh refinement and SSDFs of this renderer (plain numpy data, picklable), for
        ``Renderer(scene', precomputed=...)`` of a scene with the same geometry and visibility
        settings (camera, materials, lights and environment may differ)."""
        self.wait()
        g = self.input_geometry
        budget = self.scene.render.visibility_budget
        return {"refine_key": refine_key(g, budget, self._refine_lights()) if self._refined is not None else None,
                "refinement": self._refined, "ssdf": self.ssdf}

    # ------------------------------------------------------------------ setup
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
        if self.progressive:  # started once the first frame's own precompute is done (__init__)
            self._job = lambda: ShadowJob(lambda: compute_visibility(*args, **kw))
        elif self.overlap_precompute:  # beside the environment fit and ΓL (single-threaded parts)
            self._job = ShadowJob(lambda: compute_visibility(*args, **kw))
        else:
            self._install_shadows(compute_visibility(*args, **kw))

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
        self.vis = visibility_arrays(None, ga.normals, len(g.vertices), d)
        self._setup_dynamic()

    def _setup_dynamic(self):
        """The moving objects of the installed geometry (:mod:`warp_sg.scene.dynamic_objects`; their
        transforms carried over from the last install), None in a static scene."""
        from warp_sg.shading.motion_wp import no_proxies

        self._proxies = no_proxies(self.device)
        if self._rest_motions:
            from warp_sg.scene.dynamic_objects import DynamicObjects

            self.dynamic = DynamicObjects(self, self._rest_motions, self.dynamic)
            self._proxies = self.dynamic.px

    def _install_shadows(self, result):
        """Install :func:`warp_sg.renderer.visibility_setup.compute_visibility`'s result: the refined mesh,
        its SSDFs and the shading visibility."""
        ref, g, ssdf, parts = result
        for name, (w, c) in parts.items():
            self.timings["precompute_parts"][name] = w
            self.timings["precompute_cpu"][name] = c
        self._refined = ref
        self._install_geometry(g, ref)
        self.shadows = True
        self.ssdf = ssdf
        self.vis = visibility_arrays(ssdf, self.geo_arrays.normals, len(g.vertices), self.device)
        if self.dynamic is not None:
            self.dynamic.attach(self)  # the vertices' SSDF frames, which turn with their objects

    @property
    def shadows_pending(self) -> bool:
        """A progressive renderer whose SSDFs are not installed yet (:meth:`poll`)."""
        return self._job is not None

    def shadows_ready(self) -> bool:
        """Whether nothing is left to wait for: no background precompute, or one that has finished
        (installed by the next :meth:`poll`)."""
        return self._job is None or self._job.done()

    def poll(self) -> bool:
        """Install the background shadow precompute's result if it has finished (``progressive``):
        True when this call switched the renderer to shadowed frames. Never waits; an error of
        the precompute is raised here. ``render()`` calls it first."""
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
        job = self._job
        if job is not None and not job.wait(timeout):
            return False
        self.poll()
        return True

    def _vertex_sampled(self) -> bool:
        """Visibility of fixed directions sampled per vertex (``[render] visibility_sampling =
        "vertex"``) with shadows shown."""
        return self.scene.render.visibility_sampling == "vertex" and self.shadows and self.show_shadows

    def _env_visible_vertex(self) -> bool:
        """The diffuse environment term as the exact irradiance times the per-vertex visible fraction
        (``visibility_sampling = "vertex"`` with shadows shown; needs ρd = kd/π, no Oren–Nayar)."""
        return self.features().env_visible_vertex  # (gated by shading.Features)

    def _vertex_visibility(self, es):
        """The per-vertex caches, brought up to date (:func:`warp_sg.shading.vertex_visibility.update_caches`)."""
        from warp_sg.shading.vertex_visibility import update_caches

        es = update_caches(self, es)
        if self.dynamic is not None:  # the moved vertices' rows
            t = time.perf_counter()
            self.dynamic.patch_caches(self, es)
            self.timings["motion_caches"] = self.timings.get("motion_caches", 0.0) + time.perf_counter() - t
        return es

    def _setup_materials(self):
        from warp_sg.brdf.material_wp import pack_materials
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
        self.has_specular = any(r["model"] >= 2 for r in self.material_table.records)
        # textures (atlas layout shared with the reference: warp_sg.shading.surface)
        slots, images = material_texture_slots(mats, COLOUR_PARAMS)
        self.has_textures = bool(np.any(slots[:, :S.SLOT_NORMAL] >= 0))
        self.has_normal_maps = bool(np.any(slots[:, [S.SLOT_NORMAL, S.SLOT_TANGENT]] >= 0))
        self.has_emission = any(lay is not None and lay.emissive for lay in lays)
        self.has_occlusion = bool(np.any(slots[:, S.SLOT_OCCLUSION] >= 0)) and self.scene.environment is not None
        self.has_coat = bool(coats)
        g = self.geometry
        self.layers = layer_arrays(lays, coat_index, len(mats), g.colors, g.specular_colors, 0, self.device)
        # hidden terms unbind their textures after the variant is chosen (set_terms: same kernel)
        slots[:, S.SLOT_KD] = np.where(self.show_diffuse, slots[:, S.SLOT_KD], -1)
        slots[:, S.SLOT_KS] = np.where(self.show_specular, slots[:, S.SLOT_KS], -1)
        mt = S.MaterialTextures()
        mt.slots = wp.array(slots, dtype=int, device=self.device)
        mt.atlas = build_atlas(images, self.device)
        self.material_textures = mt
        if self.has_specular and self.scene.environment is not None:
            # the environment specular's energy correction, per material (brdf.albedo); a textured
            # first parameter (a roughness map) gets its table over the texture's range
            from warp_sg.brdf import albedo
            from warp_sg.sg.irradiance import irradiance_table_array

            ranges = [None if s < 0 else (max(float(np.min(images[s][..., 0])), 1e-4),
                                          max(float(np.max(images[s][..., 0])), 1e-4))
                      for s in slots[:len(mats), S.SLOT_P0]]
            albedo.attach(self.material_table, ranges, irradiance_table_array(self.device), self.device)

    def _setup_lights(self):
        from warp_sg.sg.irradiance import irradiance_table_array

        self.shading_lights = list(self.scene.local_lights) + self.peak_lights()
        self.light_arrays = light_arrays(self.shading_lights, self.device)
        self.irr_table = irradiance_table_array(self.device)

    # ------------------------------------------------------------------ features
    def features(self) -> S.Features:
        return S.Features(
            env_diffuse=self.env_diffuse_mode,
            env_specular=self.env_specular_mode if self.has_specular else S.ENV_NONE,
            lights=len(self.shading_lights) > 0,
            specular=self.has_specular,
            shadows=self.shadows and self.show_shadows,
            textures=self.has_textures,
            normal_maps=self.has_normal_maps,
            fh_sigmoid=self.scene.render.fh == "sigmoid",
            env_vis_vertex=self._vertex_sampled() and self.env_diffuse_mode == S.ENV_SG,
            light_vis_vertex=self._vertex_sampled() and len(self.shading_lights) > 0,
            env_visible_vertex=self._vertex_sampled(),
            models=self.material_table.models,
            emission=self.has_emission, occlusion=self.has_occlusion, coat=self.has_coat,
            vertex_colors=self.geometry.colors is not None, cutouts=self.cutouts is not None,
            moving=self.dynamic is not None and self.shadows and self.show_shadows,
        )

    # ------------------------------------------------------------------ dynamic changes
    def set_material(self, name: str, **params) -> None:
        """Change constant parameters of material ``name`` (a texture path/Texture value makes it
        textured; ``model=`` switches the model, whose constant parameters are then only this call's:
        the next frame uses the kernel variant of the new model set). No precompute is re-run."""
        if name not in self.scene.materials:
            raise SceneError(f"unknown material '{name}'", where="set_material")
        # edit a copy and swap it in only once it is valid: a bad value leaves the material as it was
        m = replace(self.scene.materials[name], params=dict(self.scene.materials[name].params),
                    textures=dict(self.scene.materials[name].textures), _brdf=None)
        if "model" in params:
            m.model, m.params = str(params.pop("model")), {}
        for k, v in params.items():
            if isinstance(v, Texture):
                m.textures[k] = v
                m.params.pop(k, None)
            elif k in ("normal_map", "tangent_map"):
                setattr(m, k, v)
            else:
                m.textures.pop(k, None)
                m.params[k] = v
        try:
            _ = m.brdf
        except InputError as e:
            raise SceneError(f"[materials.{name}] {e}") from None
        self.scene.materials[name] = m
        with wp.ScopedDevice(self.device):
            self._setup_materials()

    def set_terms(self, diffuse: bool | None = None, specular: bool | None = None,
                  shadows: bool | None = None) -> None:
        """Show or hide terms of eq. 36 without precompute (None: unchanged). ``diffuse`` /
        ``specular`` off zero every material's kd / ks (and unbind kd / ks textures): the same
        kernel variant runs. A measured (tabulated) BRDF has no kd / ks split for local lights.
        ``shadows`` off selects the kernel variant without SSDF visibility (V = 1)."""
        for name, v in (("show_diffuse", diffuse), ("show_specular", specular), ("show_shadows", shadows)):
            if v is not None:
                setattr(self, name, bool(v))
        with wp.ScopedDevice(self.device):
            self._setup_materials()

    def set_lights(self, lights: list) -> None:
        """Replace the point/directional lights (the environment stays)."""
        env = [li for li in self.scene.lights if isinstance(li, EnvironmentLight)]
        for li in lights:
            if not isinstance(li, (PointLight, DirectionalLight)):
                raise SceneError(f"not a point or directional light: {li!r}", where="set_lights")
        self.scene.lights = env + list(lights)
        self._setup_lights()

    def update_light(self, index: int, **fields) -> None:
        """Change fields of local light ``index`` (position, direction, radius, intensity)."""
        lights = self.scene.local_lights
        if not 0 <= index < len(lights):
            raise SceneError(f"no local light #{index}", where="update_light")
        li = lights[index]
        new = replace(li, **fields)
        lights[index] = new
        self.set_lights(lights)

    def set_environment_rotation(self, degrees: float) -> None:
        if self.env_light is None:
            raise SceneError("the scene has no environment light", where="set_environment_rotation")
        self.env_light.rotation = float(degrees)
        self._setup_lights()

    def set_environment_scale(self, scale: float) -> None:
        if self.env_light is None:
            raise SceneError("the scene has no environment light", where="set_environment_scale")
        if not (scale >= 0 and math.isfinite(scale)):
            raise SceneError(f"must be >= 0, got {scale}", where="environment scale")
        self.env_light.scale = float(scale)
        self._setup_lights()

    def set_object_transform(self, obj, matrix) -> None:
        """Move dynamic object ``obj`` (index or label; ``[[objects]] dynamic = true``) by the 4×4
        rigid ``matrix`` (rotation, translation, uniform scale; :mod:`warp_sg.numeric.rigid_motion`) applied
        after its own translate/scale/rotate. The next frame shows it moved with its shading and the
        shadows it casts and receives; no precompute is re-run (:mod:`warp_sg.scene.dynamic_objects`)."""
        if self.dynamic is None:
            from warp_sg.scene.dynamic_objects import object_index

            k = object_index(self.scene, obj)
            raise SceneError(f"object '{self.scene.objects[k].label(k)}' is not dynamic (give its [[objects]] "
                             f"table dynamic = true)", where="set_object_transform")
        self.dynamic.set_transform(self.scene, obj, matrix)

    def set_camera(self, **fields) -> None:
        """Change camera fields (origin, target, up, fov, width, height)."""
        cam = self.scene.camera
        self.scene.camera = replace(cam, **fields) if hasattr(cam, "__dataclass_fields__") else type(cam)(
            **{**{k: getattr(cam, k) for k in ("origin", "target", "up", "fov", "width", "height", "near", "far")},
               **fields})

    # ------------------------------------------------------------------ frame
    def _background(self, k: int, rays: bool = False):
        """What the (sub)pixels of the k× grid that see no object show
        (:class:`warp_sg.shading.background.BackgroundCache`): the camera rays, or this frame's image."""
        args = self._bg_args(k)
        if rays:
            return self._bg.params(*args)
        return self._bg.for_frame(*args, self._vb, bool(self.timings.get("raster_reused")))

    def _bg_args(self, k: int) -> tuple:
        return self.scene.camera, k, self.env_light, getattr(self, "env_base", None), self.scene.render.background

    def rasterize(self, k: int | None = None, subsamples: int = 1):
        """The visibility buffer of the current camera at k×k sub-pixels (``subsamples`` a > 1: with
        the tile queues antialiasing reads a×a sub-pixels from, ``raster.subsample``). The geometry
        is static and was validated once (``_setup_geometry``): it is rasterised from its device
        arrays, and the buffer is reused while the camera and k stay the same (material, light and
        environment edits re-shade only)."""
        import raster

        k = self.scene.render.supersampling if k is None else k
        key = (repr(self.scene.camera), int(k), int(subsamples))
        if self._vb_key != key:  # the old buffer's arrays are overwritten when the size matches
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
        self.poll()
        self._move()
        rs = self.scene.render
        if rs.supersampling == 1 and rs.antialias > 1:
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
            self._aa = AntialiasCache(self.geo_arrays.positions, self.geo_arrays.tris, d)
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

    def _cull_flags(self):
        """The back faces the raster may drop (``warp_sg.scene.culling``: closed objects seen from outside)."""
        from warp_sg.scene.culling import BackfaceCulling

        if self._culling is None:
            self._culling = BackfaceCulling(self.geometry, self.device)
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
        self._launch_shade(tri_id, bary_w, bg, eye, out)
        return out.numpy().reshape(nv, 3)

    def _move(self) -> None:
        """Dynamic objects' transforms into the device arrays (timed as ``timings["motion"]``)."""
        if self.dynamic is not None:
            t = time.perf_counter()
            self.timings["motion_caches"] = 0.0  # (the moved vertices' cache rows, summed over the frame)
            with wp.ScopedDevice(self.device):
                self.dynamic.apply(self)
            self.timings["motion"] = time.perf_counter() - t

    def _launch_shade(self, tri_id, bary, bg, eye, out):
        d = self.device
        self._ensure_gamma()  # a material may have become specular
        es = self._vertex_visibility(self._env_arrays())
        f = self.features()
        kern = S.shade_kernel(f)
        if f.env_specular == S.ENV_PREFILTERED:
            env = self.env_light
            gamma = self.gamma.table(rotation=env.rotation_matrix(), scale=env.scale, device=d)
        else:
            gamma = es  # placeholder argument of the variant without ΓL
        from raster import parallel

        n = int(tri_id.shape[0]) * int(tri_id.shape[1])
        self.layers.n_local = len(self.scene.local_lights)  # (the rest are the environment's peaks)
        args = [tri_id, bary, *self._bg.kernel_args(bg), wp.vec3(*np.asarray(eye, np.float32)), self.geo_arrays,
                self.material_table.materials, self.material_textures, self.irr_table, self.light_arrays, es, gamma,
                self.vis, self._proxies, self.layers, self.cut.arrays, self.cut.mesh_id, self._bg.params(*self._bg_args(1)), out]
        parallel.launch(kern, n, args, d, min_chunk=2048, per_thread=S.PIXELS_PER_THREAD)


def render(scene: Scene, device: str | None = None, progress: bool = False) -> np.ndarray:
    """Render ``scene`` once: (H, W, 3) float32 linear radiance (docs/architecture.md "Public interface").
    ``device`` defaults to the scene's ``[render] device``."""
    return Renderer(scene, device, progress=progress).render()


__all__ = ["Renderer", "render"]

