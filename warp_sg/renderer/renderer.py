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
* materials (``brdf.kernel.material_wp.pack_materials``) and textures (one atlas).

``render()`` rasterises the camera view (``raster.rasterize``, k×k supersampled), shades every
(sub)pixel once with the kernel variant the scene needs (:mod:`warp_sg.shading.kernel`), and box-resolves
k×k blocks.

The class is put together from one module per concept: what the precompute produces and the
frames read (:mod:`warp_sg.renderer.resources`; the environment's part:
:mod:`warp_sg.renderer.environment_setup`), the kernel-variant choice (:mod:`warp_sg.renderer.variant`)
and the frame paths (:mod:`warp_sg.renderer.frame`); this module holds the construction (the
precompute's order) and the edit API. Changing materials, textures, lights, the environment rotation/scale or the camera
(the setters below) re-renders without re-running precompute. Per-frame timings (seconds) are in
``Renderer.timings``: ``precompute`` (construction; cache hits included), ``raster``, ``shade``,
``resolve``, ``frame`` (last ``render()``), ``precompute_parts`` (wall seconds of refine, ssdf,
env_peaks, env_fit, env_prefilter) and ``precompute_cpu`` (their CPU seconds, all threads).
"""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import warp as wp

from warp_sg.core.device import resolve_device
from warp_sg.core.errors import InputError, SceneError
from warp_sg.renderer import kernel_preload
from warp_sg.renderer.costs import check_frame_costs
from warp_sg.renderer.environment_setup import EnvironmentSetup
from warp_sg.renderer.frame import FramePaths
from warp_sg.renderer.gradients import GradientPaths
from warp_sg.renderer.interreflection import Interreflection
from warp_sg.renderer.resources import ResourceSetup
from warp_sg.renderer.variant import VariantChoice
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight, PointLight
from warp_sg.scene.model import Scene
from warp_sg.shading import kernel as S
from warp_sg.shading.background import BackgroundCache
from warp_sg.shading.vertex_visibility import caches


class Renderer(FramePaths, VariantChoice, ResourceSetup, EnvironmentSetup, GradientPaths, Interreflection):
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
    ``requires_grad``: frames are recorded for their adjoint (:meth:`backward`, :meth:`gradients`,
    :mod:`warp_sg.renderer.gradients`): the shading's gradients with respect to the materials,
    textures, lights and an SG-mixture environment, visibility and geometry held fixed.
    """

    #: compute the refinement and SSDFs on a thread beside the environment fit and ΓL prefilter
    #: (the same data; False: one after the other, so each part's CPU time is its own)
    overlap_precompute = True
    #: with dynamic objects, rasterise the static ones once per camera and merge the moving ones
    #: into their buffer each frame (:mod:`warp_sg.renderer.moving_raster`; False: the whole mesh
    #: every frame — the same image, bit for bit)
    incremental_raster = True
    #: terms of eq. 36 shown (:meth:`set_terms`; the viewer's check boxes)
    show_diffuse = True
    show_specular = True
    show_shadows = True

    def __init__(self, scene: Scene, device: str | None = None, progress: bool = False, *, ssdf_compute=None,
                 precomputed: dict | None = None, progressive: bool = False, requires_grad: bool = False):
        if not isinstance(scene, Scene):
            raise InputError(f"expected a warp_sg.Scene, got {type(scene).__name__}", where="scene")
        scene.render.validate()  # the scene-file model's rule, for settings edited since the Scene was built
        self.scene = scene
        self._ssdf_compute = ssdf_compute
        self._precomputed = precomputed
        self.device = resolve_device(device, "--device") if device is not None else \
            resolve_device(scene.render.device, f"{scene.path or 'scene'}: [render] device")
        self.progress = progress
        self.progressive = bool(progressive)
        self.requires_grad = bool(requires_grad)  # (warp_sg.renderer.gradients)
        self._preload = kernel_preload.get(self.device)  # the compile pool (CPU: modules compiled ahead)
        self.env_mixture = False  # the environment is its SG mixture (set_environment_mixture)
        self._grad = None  # the last taped frame (GradientPaths)
        self._job = None  # the background shadow precompute (progressive)
        self._gamma_job = None  # the background ΓL prefilter (progressive: _ensure_gamma)
        self.timings: dict = {"precompute_parts": {}, "precompute_cpu": {}}
        self._env_arrays_key = ()  # (see _env_arrays; () = not built yet)
        self._env_sg_arrays = None
        self._gamma_capped, self._gamma_reach = False, 0.0  # (_ensure_gamma)
        self.env_vis_cache, self.light_vis_cache, self.env_visible_cache = caches()  # (_vertex_visibility)
        self._bg = BackgroundCache(self.device)  # what pixels that see no object show
        self._aa = None  # antialiasing's caches between frames (warp_sg.renderer.antialias.AntialiasCache)
        self._vb_key = self._vb = self._culling = None
        self._mesh_job = None  # (geometry, the first frame's per-mesh caches on a thread: _start_mesh_caches)
        self.dynamic = None  # objects that move (warp_sg.renderer.dynamic_objects; _setup_dynamic)
        self._rest_motions = {k: ob.motion for k, ob in enumerate(scene.objects) if ob.dynamic}  # the built pose
        t0 = time.perf_counter()
        specular = any(getattr(m.brdf, "is_specular", True) for m in scene.materials.values())
        check_frame_costs(scene, scene.geometry(), shadows=scene.render.shadows,  # the watchdog, before any work
                          specular=specular)
        if self._preload is not None:
            self._preload.tables()
            self._preload.prefetch(kernel_preload.modules_for(scene.environment is not None, specular))
        with wp.ScopedDevice(self.device):
            if self._preload is not None:  # (the tables every renderer reads, built beside the above)
                self._preload.tables(wait=True)
            self._setup_env_peaks()
            self._setup_geometry()
            if self._job is not None:  # (frames with shadows read the per-vertex caches, and bounce)
                self.prefetch_modules(kernel_preload.SHADOW_FRAME_MODULES + (
                    kernel_preload.BOUNCE_FRAME_MODULES if scene.render.bounces > 0 else ()))
            if self.progressive:  # culling's and the contours' per-mesh work beside the environment setup
                self._start_mesh_caches()
            self._setup_materials()
            if self._job is not None and scene.render.bounces > 0:  # (the senders' albedo kernels, queued)
                self.load_kernels(self._sender_kernels(), wait=False)
            self._setup_environment()
            self._ensure_gamma()
            self._setup_lights()
        if self.progressive and self._job is not None:  # the shadows now get the cores the setup had
            self._job = self._job()  # (the scene's ΓL ladder starts after the first frame: _start_gamma_job)
        elif self._job is not None:  # computed beside the environment setup: install them now
            self._preload_final_shade()  # (its variant compiles while the shadows finish)
            self.wait()
        wp.synchronize_device(self.device)
        self.timings["precompute"] = time.perf_counter() - t0

    def prefetch_modules(self, names, priority: int = 30) -> None:
        """Queue Warp modules on the compile pool (:mod:`warp_sg.renderer.kernel_preload`; CPU)."""
        if self._preload is not None:
            self._preload.prefetch([(n, priority) for n in names])

    def load_modules(self, names, priority: int = 0, queued_only: bool = False) -> None:
        """Warp modules loaded before this thread launches their kernels: compiled on the pool
        (:meth:`warp_sg.renderer.kernel_preload.KernelPreload.load`), never twice; no-op on CUDA."""
        if self._preload is not None:
            self._preload.load(names, queued_only=queued_only, priority=priority)

    def load_kernels(self, kernels, wait: bool = True) -> None:
        """Kernels built per content loaded on the compile pool (``wait=False``: queued)."""
        if self._preload is not None:
            for k in kernels:
                self._preload.kernel(k, wait=wait)

    def _preload_final_shade(self) -> None:
        """Start compiling the shading variant of the frames with shadows (:meth:`final_features`)
        on the compile pool, if it is not built yet."""
        if self._preload is not None and not self.requires_grad:
            f = self.final_features()
            if not S.shade_kernel_ready(f, self.device):
                self._preload.shade(f)

    @staticmethod
    def _tick():
        return time.perf_counter(), time.process_time()

    def _tock(self, part: str, t0) -> None:
        """Record part ``part`` begun at ``t0 = _tick()``: wall seconds in ``precompute_parts``, CPU
        seconds of the process (all threads) in ``precompute_cpu``."""
        self.timings["precompute_parts"][part] = time.perf_counter() - t0[0]
        self.timings["precompute_cpu"][part] = time.process_time() - t0[1]

    # ------------------------------------------------------------------ dynamic changes
    def set_material(self, name: str, **params) -> None:
        """Change constant parameters of material ``name`` (a texture path/Texture value makes it
        textured; ``model=`` switches the model, whose constant parameters are then only this call's:
        the next frame uses the kernel variant of the new model set). No precompute is re-run."""
        if name not in self.scene.materials:
            raise SceneError(f"unknown material '{name}'", where="set_material")
        # edit a copy and swap it in only once it is valid: a bad value leaves the material as it was
        m = self.scene.materials[name].updated(name, **params)
        self.scene.materials[name] = m
        with wp.ScopedDevice(self.device):
            self._setup_materials()

    def set_terms(self, diffuse: bool | None = None, specular: bool | None = None,
                  shadows: bool | None = None, bounces: bool | None = None) -> None:
        """Show or hide terms of eq. 36 without precompute (None: unchanged). ``diffuse`` /
        ``specular`` off zero every material's kd / ks (and unbind kd / ks textures): the same
        kernel variant runs. A measured (tabulated) BRDF has no kd / ks split for local lights.
        ``shadows`` off selects the kernel variant without SSDF visibility (V = 1); ``bounces`` off the
        one without interreflected light (the paper's direct light; :mod:`warp_sg.renderer.interreflection`)."""
        for name, v in (("show_diffuse", diffuse), ("show_specular", specular), ("show_shadows", shadows),
                        ("show_bounces", bounces)):
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
        self._set_environment("set_environment_rotation", rotation=degrees)

    def set_environment_scale(self, scale: float) -> None:
        self._set_environment("set_environment_scale", scale=scale)

    def _set_environment(self, what: str, **change) -> None:
        """Change the environment light's ``scale`` or ``rotation``, checked by its record's rule
        (the scene file's: :mod:`warp_sg.scene.light_tables`) before anything changes."""
        if self.env_light is None:
            raise SceneError("the scene has no environment light", where=what)
        checked = replace(self.env_light, **change)  # the record checks; its map cache is shared
        for k in change:
            setattr(self.env_light, k, getattr(checked, k))
        self._setup_lights()

    def set_object_transform(self, obj, matrix) -> None:
        """Move dynamic object ``obj`` (index or label; ``[[objects]] dynamic = true``) by the 4×4
        rigid ``matrix`` (rotation, translation, uniform scale; :mod:`warp_sg.numeric.rigid_motion`) applied
        after its own translate/scale/rotate. The next frame shows it moved with its shading and the
        shadows it casts and receives; no precompute is re-run (:mod:`warp_sg.renderer.dynamic_objects`)."""
        if self.dynamic is None:
            from warp_sg.renderer.dynamic_objects import object_index

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


def render(scene: Scene, device: str | None = None, progress: bool = False) -> np.ndarray:
    """Render ``scene`` once: (H, W, 3) float32 linear radiance (docs/architecture.md "Public interface").
    ``device`` defaults to the scene's ``[render] device``."""
    return Renderer(scene, device, progress=progress).render()


__all__ = ["Renderer", "render"]

