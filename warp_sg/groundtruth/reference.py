r"""Monte-Carlo reference renderer: ``ws.reference(scene, spp=256, device="cpu")``.

It renders exactly the light transport of :func:`warp_sg.renderer.renderer` — direct lighting, one bounce —
with the exact (unfitted) BRDFs (``material_wp.brdf_eval``) and exact visibility (``wp.Mesh`` ray
casts), so ``render`` vs ``reference`` measures only the SG approximation error (docs/architecture.md "Conventions").

Per pixel
    Primary visibility by ray casting from the renderer's camera through the centres of the
    k×k supersampled grid (``Camera.ray_directions(supersample=k)``); each sub-pixel is
    point-sampled (no jitter) and the k×k block is box-averaged, as the renderer does.
    Pixels that see nothing show the environment (when ``background`` is on) or black.

Per shading point ``x`` (shading normal ``n``, view ``o``), one *sample* is
    * one light sample per light (environment: luminance CDF over the equirectangular map with
      the solid angle of each texel, :mod:`warp_sg.groundtruth.sampling`; sphere lights: uniform in the cone
      of directions subtended by the sphere; directional lights: uniform in their cone), and
    * one BRDF sample (a mixture of cosine sampling for the diffuse part and
      ``material_wp.brdf_sample`` for the specular part), whose ray is tested against every light,
    combined by multiple importance sampling (power heuristic, β = 2, per light). Delta lights
    (radius 0) are evaluated directly. Shadow rays are exact ``wp.Mesh`` queries.

Lights (docs/math.md "Lights"):
    * point light (position ``l``, radius ``r``, intensity ``s``): a sphere of uniform radiance
      ``s/(π r²)``, so its irradiance at distance ``d`` facing it is ``s/d²``;
    * directional light (direction, angular radius ``r``, irradiance ``E``): a cone of uniform
      radiance ``E / (π sin² r)``, so the irradiance on a surface facing it is ``E``;
    * environment: piecewise-constant equirectangular radiance (nearest texel) times ``scale``.
    Lights do not occlude each other (they add, as in the renderer).

Progressive: passes of ``pass_spp`` samples; per-pixel sums and sums of squares are kept in
float64 on the host and give a per-pixel standard error of the mean
(``reference(..., return_stderr=True)`` or :func:`render_reference` -> :class:`ReferenceResult`).

Files: this module is the host side and the public entry; the kernels and their structs are in
:mod:`warp_sg.groundtruth.reference_wp` (re-exported here).
"""
from __future__ import annotations

import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import warp as wp

from warp_sg.brdf.kernel import material_wp as M  # contract: Material, pack_materials, brdf_*
from warp_sg.core.device import add_device_argument, device_for, resolve_device
from warp_sg.core.errors import InputError
from warp_sg.core.workers import RAY_THREADS, cpu_workers
from warp_sg.groundtruth import sampling as S
from warp_sg.groundtruth.depth import DEFAULT_MAX_DEPTH, check_max_depth, matching_transport
from warp_sg.groundtruth.path_wp import _reference_pass
from warp_sg.groundtruth.reference_wp import Geometry, LightTable
from warp_sg.scene.culling import camera_mesh
from warp_sg.scene.lights import LIGHT_DIRECTIONAL, LIGHT_POINT, DirectionalLight, PointLight
from warp_sg.scene.textures import build_atlas
from warp_sg.shading.cutout import no_cutouts
from warp_sg.shading.surface import N_SLOTS, MaterialTextures
from warp_sg.shading.surface_layers import coat_models, layer_arrays

#: Relative offset of shadow-ray origins (times the scene's diameter).
RAY_EPS = 1.0e-4


# --------------------------------------------------------------------------------------------
# Host side
# --------------------------------------------------------------------------------------------
def Light(kind: str, position=None, direction=None, radius: float = 0.0, intensity=(1.0, 1.0, 1.0)):
    """The reference's lights are the scene's :class:`~warp_sg.scene.lights.PointLight` /
    :class:`~warp_sg.scene.lights.DirectionalLight`; this builds one from the older record form
    ``Light("point" | "directional", position=..., direction=..., radius=0, intensity=...)``."""
    if kind == "point":
        return PointLight(position=position, radius=radius, intensity=intensity)
    if kind == "directional":
        return DirectionalLight(direction=direction, radius=radius, intensity=intensity)
    raise InputError(f"unknown light type {kind!r} (use point or directional)", where="light.type")


@dataclass
class ReferenceInputs:
    """Everything the reference kernel needs, as plain arrays (built from a Scene or by hand)."""

    vertices: np.ndarray  # (V, 3)
    triangles: np.ndarray  # (T, 3) int
    tri_material: np.ndarray  # (T,) int, index into ``materials``
    materials: list  # warp_sg.brdf model instances (exact BRDFs)
    ray_origins: np.ndarray  # (kH, kW, 3)
    ray_directions: np.ndarray  # (kH, kW, 3) unit
    supersample: int = 1
    normals: np.ndarray | None = None  # (V, 3) per-vertex shading normals
    lights: list = field(default_factory=list)  # [PointLight | DirectionalLight] (warp_sg.scene.lights)
    environment: np.ndarray | None = None  # (H, W, 3) radiance (scale applied)
    background: bool = True
    uvs: np.ndarray | None = None  # (V, 2)
    tangents: np.ndarray | None = None  # (V, 3) shading-frame x axis (anisotropic materials)
    texture_slots: np.ndarray | None = None  # (n_materials, N_SLOTS) int: atlas index per slot, -1 = constant
    texture_images: list | None = None  # [(h, w, 4) float32] the atlas (same order as the slots)
    background_image: np.ndarray | None = None  # (kH, kW, 3): what misses show (default: env lookup)
    #: per material its layers (warp_sg.scene.material_layers.MaterialLayers or None): emission, coat
    #: (occlusion and coat maps come with the texture slots)
    layers: list | None = None
    colors: np.ndarray | None = None  # (V, 4) vertex colours (kd, alpha) and (V, 3) their ks factor
    specular_colors: np.ndarray | None = None
    cutouts: object = None  # warp_sg.shading.cutout.CutoutData of the mesh (alpha cut-outs), or None
    #: (T,) bool: triangles whose back faces camera rays do not see (single-sided objects,
    #: ``warp_sg.scene.culling``); None: every triangle double-sided
    single_sided: np.ndarray | None = None


@dataclass
class ReferenceResult:
    image: np.ndarray  # (H, W, 3) float32, box-resolved
    stderr: np.ndarray  # (H, W, 3) float32, standard error of the mean per pixel
    spp: int
    seconds: float
    passes: int
    history: list = field(default_factory=list)  # [(spp, seconds)] after each pass


def _light_table(lights, device) -> LightTable:
    n = len(lights)
    kind = np.zeros(max(n, 1), np.int32)
    pos = np.zeros((max(n, 1), 3), np.float32)
    rad = np.zeros(max(n, 1), np.float32)
    le = np.zeros((max(n, 1), 3), np.float32)
    omc = np.zeros(max(n, 1), np.float32)
    for j, li in enumerate(lights):  # validated by the light classes (finite, radius >= 0, unit direction)
        r = float(li.radius)
        s = np.asarray(li.intensity, np.float64) * np.ones(3)
        if isinstance(li, PointLight):
            kind[j] = LIGHT_POINT
            pos[j] = li.position
            le[j] = s / (np.pi * r * r) if r > 0 else s
        elif isinstance(li, DirectionalLight):
            kind[j] = LIGHT_DIRECTIONAL
            pos[j] = li.direction
            if r > 0:
                r = min(r, np.pi / 2)
                le[j] = s / (np.pi * math.sin(r) ** 2)
                omc[j] = S.one_minus_cos_from_sin2(math.sin(r) ** 2)
            else:
                le[j] = s
        else:
            raise InputError(f"not a point or directional light: {li!r}", where=f"lights[{j}]")
        rad[j] = r
    t = LightTable()
    t.count = n
    t.kind = wp.array(kind, dtype=int, device=device)
    t.pos = wp.array(pos, dtype=wp.vec3, device=device)
    t.radius = wp.array(rad, dtype=float, device=device)
    t.radiance = wp.array(le, dtype=wp.vec3, device=device)
    t.omc = wp.array(omc, dtype=float, device=device)
    return t


class _Prepared:
    def __init__(self, inp: ReferenceInputs, device: str):
        v = np.ascontiguousarray(inp.vertices, np.float32)
        tri = np.ascontiguousarray(inp.triangles, np.int32)
        self.device = device
        self.points = wp.array(v, dtype=wp.vec3, device=device)
        self.indices = wp.array(tri.reshape(-1), dtype=int, device=device)
        self.mesh = wp.Mesh(points=self.points, indices=self.indices)
        geo = Geometry()
        geo.mesh = self.mesh.id
        self.camera_mesh = camera_mesh(inp.single_sided, inp.ray_origins, v, tri, self.points, device)
        geo.camera = (self.mesh if self.camera_mesh is None else self.camera_mesh).id
        geo.indices = self.indices
        if inp.normals is not None:
            geo.normals = wp.array(np.ascontiguousarray(inp.normals, np.float32), dtype=wp.vec3, device=device)
            geo.has_normals = 1
        else:
            geo.normals = wp.zeros(1, dtype=wp.vec3, device=device)
            geo.has_normals = 0
        geo.tri_material = wp.array(np.ascontiguousarray(inp.tri_material, np.int32), dtype=int, device=device)
        nv = len(v)
        uvs = np.zeros((max(nv, 1), 2), np.float32) if inp.uvs is None else np.ascontiguousarray(inp.uvs, np.float32)
        geo.uvs = wp.array(uvs, dtype=wp.vec2, device=device)
        if inp.tangents is not None:
            geo.tangents = wp.array(np.ascontiguousarray(inp.tangents, np.float32), dtype=wp.vec3, device=device)
            geo.has_tangents = 1
        else:
            geo.tangents = wp.zeros(1, dtype=wp.vec3, device=device)
            geo.has_tangents = 0
        tex = MaterialTextures()
        slots = inp.texture_slots
        if slots is not None and np.any(np.asarray(slots) >= 0):
            if inp.uvs is None:
                raise InputError("textured materials need uvs", where="reference inputs")
            slots = np.asarray(slots, np.int32).reshape(len(slots), -1)
            if slots.shape[1] < N_SLOTS:  # (older six-slot layouts: no layer maps)
                slots = np.pad(slots, ((0, 0), (0, N_SLOTS - slots.shape[1])), constant_values=-1)
            tex.slots = wp.array(np.ascontiguousarray(slots, np.int32), dtype=int, device=device)
            tex.atlas = build_atlas(list(inp.texture_images or []), device)
        else:
            tex.slots = wp.full((max(len(inp.materials), 1), N_SLOTS), -1, dtype=int, device=device)
            tex.atlas = build_atlas([], device)
        self.tex = tex
        extent = float(np.max(np.ptp(v, axis=0))) if len(v) else 1.0
        scale = max(extent, float(np.max(np.abs(v))) if len(v) else 1.0, 1e-30)
        geo.eps = RAY_EPS * scale
        geo.cut = no_cutouts(device) if inp.cutouts is None else inp.cutouts.device(tri, device)
        self.geo = geo
        lays = list(inp.layers or [None] * len(inp.materials))
        coats, coat_index = coat_models(lays)
        table = M.pack_materials(list(inp.materials) + coats, 1, device)
        self.layers = layer_arrays(lays, coat_index, len(inp.materials), inp.colors, inp.specular_colors, 0, device)
        self.material_table = table
        self.materials = table.materials
        self.env = S.make_env_sampler(inp.environment, 1.0, device)
        self.lights = _light_table(inp.lights, device)
        kh, kw = inp.ray_directions.shape[:2]
        self.shape = (kh, kw)
        self.origins = wp.array(np.ascontiguousarray(inp.ray_origins.reshape(-1, 3), np.float32), dtype=wp.vec3,
                                device=device)
        dirs = np.asarray(inp.ray_directions, np.float64).reshape(-1, 3)
        dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
        self.dirs = wp.array(dirs.astype(np.float32), dtype=wp.vec3, device=device)
        self.n = kh * kw
        self.sum = wp.zeros(self.n, dtype=wp.vec3, device=device)
        self.sq = wp.zeros(self.n, dtype=wp.vec3, device=device)
        self.background = 1 if inp.background else 0
        if inp.background_image is not None:
            bgi = np.asarray(inp.background_image, np.float32).reshape(-1, 3)
            if len(bgi) != kh * kw:
                raise InputError(f"background image has {len(bgi)} pixels, expected {kh * kw}", where="background")
            self.bg_image = wp.array(np.ascontiguousarray(bgi), dtype=wp.vec3, device=device)
            self.background = 2
        else:
            self.bg_image = wp.zeros(1, dtype=wp.vec3, device=device)
        wp.load_module(_reference_pass.module, device=device)  # compile once, before any thread launches

    def launch_pass(self, spp: int, seed: int, sample_offset: int, threads: int, max_depth: int = DEFAULT_MAX_DEPTH):
        args = [self.geo, self.materials, self.tex, self.layers, self.env, self.lights, self.origins, self.dirs, self.background,
                self.bg_image, spp, seed, sample_offset, int(max_depth)]
        n = self.n
        if self.device == "cpu" and threads > 1 and n >= 2 * threads:
            # a CPU launch runs on one core: disjoint ranges from a thread pool scale (docs/raster.md "Performance")
            bounds = np.linspace(0, n, threads + 1).astype(int)

            def run(j):
                lo, hi = int(bounds[j]), int(bounds[j + 1])
                wp.launch(_reference_pass, dim=hi - lo, inputs=args + [lo, self.sum, self.sq], device="cpu")

            with ThreadPoolExecutor(threads) as ex:
                list(ex.map(run, range(threads)))
        else:
            wp.launch(_reference_pass, dim=n, inputs=args + [0, self.sum, self.sq], device=self.device)
        wp.synchronize_device(self.device)
        return self.sum.numpy().astype(np.float64), self.sq.numpy().astype(np.float64)


def _resolve(acc, acc2, total, shape, k):
    kh, kw = shape
    mean = acc / total
    var = np.maximum(acc2 / total - mean * mean, 0.0) * (total / max(total - 1, 1))
    var_mean = var / total  # variance of each sub-pixel's mean
    h, w = kh // k, kw // k
    img = mean.reshape(h, k, w, k, 3).mean(axis=(1, 3))
    se = np.sqrt(var_mean.reshape(h, k, w, k, 3).sum(axis=(1, 3))) / (k * k)
    return img.astype(np.float32), se.astype(np.float32)


def render_reference_inputs(
    inp: ReferenceInputs,
    spp: int = 256,
    device="cpu",
    progress: bool = True,
    seed: int = 0,
    pass_spp: int | None = None,
    callback: Callable | None = None,
    threads: int | None = None,
    max_depth: int = DEFAULT_MAX_DEPTH,
) -> ReferenceResult:
    """Progressive Monte-Carlo rendering of :class:`ReferenceInputs`.

    ``max_depth``: the most segments of a path (:func:`check_max_depth`; Mitsuba's count: 2 is
    direct light only, the paper's transport; the default :data:`DEFAULT_MAX_DEPTH` a full path
    tracer; −1 no cap).

    ``callback(spp_done, seconds, image, stderr)`` is called after every pass (for error-vs-spp
    curves); passes grow geometrically from ``pass_spp`` (default: 1, 1, 2, 4, ... capped at 64
    samples) so a callback sees every power of two.
    """
    spp = int(spp)
    if spp < 1:
        raise InputError(f"spp must be >= 1, got {spp}", where="--spp")
    max_depth = check_max_depth(max_depth)
    device = resolve_device(device)
    k = int(inp.supersample)
    t0 = time.perf_counter()
    prep = _Prepared(inp, device)
    if threads is None:
        threads = cpu_workers(device, limit=RAY_THREADS)
    kh, kw = prep.shape
    if kh % k or kw % k:
        raise InputError(f"ray grid {kh}x{kw} is not a multiple of supersampling {k}", where="supersample")
    acc = np.zeros((prep.n, 3))
    acc2 = np.zeros((prep.n, 3))
    done = 0
    passes = 0
    history = []
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=spp, desc="reference", unit="spp", leave=False)
    try:
        while done < spp:
            if pass_spp:
                n = min(int(pass_spp), spp - done)
            else:
                n = min(max(done, 1), 64, spp - done)
            s, s2 = prep.launch_pass(n, int(seed), done, threads, max_depth)
            acc += s
            acc2 += s2
            done += n
            passes += 1
            el = time.perf_counter() - t0
            history.append((done, el))
            if bar is not None:
                bar.update(n)
            if callback is not None:
                img, se = _resolve(acc, acc2, done, prep.shape, k)
                callback(done, el, img, se)
    finally:
        if bar is not None:
            bar.close()
    img, se = _resolve(acc, acc2, done, prep.shape, k)
    return ReferenceResult(img, se, done, time.perf_counter() - t0, passes, history)


# --------------------------------------------------------------------------------------------
# Scene adapter
# --------------------------------------------------------------------------------------------
def texture_tables(scene, material_names):
    """(slots (n_materials, N_SLOTS) int, images [(h, w, 4)]) for the scene's textured parameters,
    normal/tangent maps and layer maps, with the renderer's slot layout (``warp_sg.shading.surface``)."""
    from warp_sg.scene.model import COLOUR_PARAMS
    from warp_sg.shading.surface import material_texture_slots

    return material_texture_slots([scene.materials[n] for n in material_names], COLOUR_PARAMS)


def inputs_from_scene(scene, device="cpu") -> ReferenceInputs:
    """Build :class:`ReferenceInputs` from a :class:`warp_sg.Scene`: the renderer's geometry
    (shading normals, uvs, tangents), camera rays of the k×k supersampled grid, exact constant
    materials (``Material.brdf``) plus the same textures / normal maps, the point and directional
    lights, the world-space environment (scale and rotation applied), and the renderer's
    background (bilinear environment lookup) for pixels that see no object."""
    from warp_sg.core.watchdog import MAX_SAMPLES, check_size
    from warp_sg.shading.cutout import cutout_data

    k, cam = scene.render.supersampling, scene.camera
    check_size("the frame", cam.width * cam.height * k * k, MAX_SAMPLES, f"{cam.width}×{cam.height} pixels × "
               f"supersampling {k}²", "samples", where=f"{scene.path or 'scene'}: [camera]", error=InputError)
    g = scene.geometry()
    dirs = np.asarray(scene.camera.ray_directions(supersample=k), np.float32)
    origins = np.broadcast_to(np.asarray(scene.camera.origin, np.float32), dirs.shape).copy()
    env = scene.environment
    inp = ReferenceInputs(
        vertices=g.vertices, triangles=g.triangles, tri_material=g.tri_material,
        materials=[scene.materials[n].brdf for n in g.material_names],
        ray_origins=origins, ray_directions=dirs, supersample=k, normals=g.normals,
        lights=list(scene.local_lights), environment=None if env is None else env.radiance(),
        background=scene.render.background, uvs=g.uvs, tangents=g.tangents,
        layers=[scene.materials[n].layers for n in g.material_names], colors=g.colors,
        specular_colors=g.specular_colors, cutouts=cutout_data(g, scene.materials),
        single_sided=None if g.one_sided is None else g.one_sided[g.tri_object])
    slots, images = texture_tables(scene, g.material_names)
    if np.any(slots >= 0):
        inp.texture_slots, inp.texture_images = slots, images
    if env is not None and scene.render.background:
        from warp_sg.scene.envmap import env_lookup_numpy

        inp.background_image = (env_lookup_numpy(env.base_radiance(), np.asarray(inp.ray_directions, np.float64),
                                                 rotation=env.rotation_matrix()) * env.scale).astype(np.float32)
    return inp


def render_reference(scene, spp=256, device="cpu", progress=True, seed=0, pass_spp=None, callback=None,
                     threads=None, max_depth: int = DEFAULT_MAX_DEPTH) -> ReferenceResult:
    """:func:`reference` returning a :class:`ReferenceResult` (image, stderr, timings)."""
    max_depth = check_max_depth(max_depth)
    inp = scene if isinstance(scene, ReferenceInputs) else inputs_from_scene(scene, device)
    return render_reference_inputs(inp, spp, device, progress, seed, pass_spp, callback, threads, max_depth)


def reference(scene, spp: int = 256, device="cpu", progress: bool = True, seed: int = 0,
              return_stderr: bool = False, pass_spp: int | None = None, max_depth: int = DEFAULT_MAX_DEPTH):
    """Monte-Carlo reference image (H, W, 3) float32 of ``scene`` (a Scene or ReferenceInputs).

    ``return_stderr=True`` returns ``(image, stderr)`` with the per-pixel standard error.
    ``max_depth``: the most segments of a path (default :data:`DEFAULT_MAX_DEPTH`, a full path
    tracer; 2: direct light only, the paper's transport; −1: no cap).
    """
    res = render_reference(scene, spp, device, progress, seed, pass_spp, max_depth=max_depth)
    return (res.image, res.stderr) if return_stderr else res.image


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def add_cli_arguments(p) -> None:
    p.add_argument("scene", help="scene file (TOML)")
    p.add_argument("-o", "--output", required=True,
                   help="output image: .exr (linear HDR) or .png (sRGB); missing folders are created")
    p.add_argument("--spp", type=int, default=256, help="samples per (sub)pixel (default 256)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-depth", type=int, default=DEFAULT_MAX_DEPTH, metavar="N",
                   help=f"the most segments of a path (default {DEFAULT_MAX_DEPTH}: a full path tracer with Russian "
                        "roulette; 2: direct light only, the paper's transport; -1: no cap)")
    add_device_argument(p)
    p.add_argument("--stderr", default=None, help="also write the per-pixel standard error image here")
    p.add_argument("--transform", action="append", default=[], metavar="OBJECT=M00,...,M33",
                   help="render with dynamic object OBJECT (label or index) moved by the 4x4 rigid matrix "
                        "(16 numbers, row-major), as Renderer.set_object_transform; repeatable")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def cli_main(args) -> int:
    from warp_sg.core.files import check_output_path, make_parents
    from warp_sg.core.image_io import save_image
    from warp_sg.scene.loader import load_scene

    if args.spp < 1:
        raise InputError(f"must be >= 1, got {args.spp}", where="--spp")
    check_max_depth(args.max_depth, "--max-depth")
    # fail before any work; folders are created only once the images exist (never a partial file)
    out = check_output_path(args.output, create_parents=True)
    err_out = check_output_path(args.stderr, create_parents=True) if args.stderr else None
    if err_out is not None and os.path.abspath(err_out) == os.path.abspath(out):
        raise InputError(f"names the same file as -o ({out}): the standard error would overwrite the image",
                         where="--stderr")
    scene = load_scene(args.scene)
    if args.transform:
        from warp_sg.renderer.dynamic_objects import parse_transform_argument, scene_with_transforms

        scene = scene_with_transforms(scene, dict(parse_transform_argument(a) for a in args.transform))
    res = render_reference(scene, spp=args.spp, device=device_for(args.device, scene), progress=not args.no_progress,
                           seed=args.seed, max_depth=args.max_depth)
    make_parents(out)
    save_image(out, res.image)
    if err_out is not None:
        make_parents(err_out)
        save_image(err_out, res.stderr)
    return 0


__all__ = [
    "reference",
    "render_reference",
    "render_reference_inputs",
    "ReferenceInputs",
    "ReferenceResult",
    "Light",
    "check_max_depth",
    "matching_transport",
    "DEFAULT_MAX_DEPTH",
    "inputs_from_scene",
    "add_cli_arguments",
    "cli_main",
]

