r"""Peer comparison with Mitsuba 3: our scenes as Mitsuba scene dicts, and Mitsuba's error-vs-time curve.

Optional: needs the ``[compare]`` extra (``pip install -e '.[compare]'``, Mitsuba ≥ 3.5) and, for
the LLVM variant, a recent system libLLVM (Debian: ``apt install libllvm19``; Dr.Jit fails on
LLVM 14/15 with "Cannot select fminimum"; point ``DRJIT_LIBLLVM_PATH`` at the library if Dr.Jit
does not find it). :func:`mitsuba_status` says whether it works and, if not, why, in one line.

What the conversion (:func:`mitsuba_scene`) renders is the light transport of our Monte-Carlo
reference (:mod:`warp_sg.groundtruth.reference`): Mitsuba's ``path`` integrator with the reference's
``max_depth`` (default its full path tracer's, ``warp_sg.groundtruth.path_wp.DEFAULT_MAX_DEPTH``;
``max_depth=2``: direct lighting only), camera rays through a box-filtered pixel, environment
visible in the background.

* **Geometry** — ``Scene.geometry()`` (the input geometry, as the reference ray-casts it), one
  ``mi.Mesh`` per material with our per-vertex shading normals (Mitsuba interpolates and
  normalises them barycentrically, as we do).
* **Camera** — ``perspective``, ``fov_axis="y"``, ``to_world = look_at(origin, target, up)``,
  same near/far: :class:`warp_sg.scene.camera.Camera` is defined by that convention (row 0 at the top,
  image +x = forward × up).
* **Materials** — only :class:`warp_sg.brdf.Lambert` → ``diffuse`` (``reflectance = kd``, BRDF
  ``kd/π`` in both); with ``approximate=True`` (the real-asset report's peer column) also GGX
  conductors → ``roughconductor`` (same NDF, Mitsuba's separable Smith term). Not expressible, so
  refused (:class:`NotExpressible`): our microfacet models
  use the V-cavity shadowing term ``min(1, 2(n·h)(n·o)/(o·h), 2(n·h)(n·i)/(i·h))``
  (:mod:`warp_sg.brdf.models.microfacet`) where Mitsuba's ``roughconductor``/``roughplastic`` use Smith
  masking (and ``roughplastic`` adds a Fresnel-weighted internal-scattering diffuse); our
  :class:`~warp_sg.brdf.GGX` has the height-correlated Smith term ``G2 = 1/(1 + Λ(o) + Λ(i))``
  where Mitsuba's GGX ``roughconductor`` uses the separable ``G1(o) G1(i)`` (its
  ``MicrofacetDistribution::G``), so it is not converted either; Mitsuba 3 has no Phong/Blinn–Phong
  or Ward plugin; Oren–Nayar, Ashikhmin–Shirley, Lafortune, measured
  BRDFs and textures are not converted either.
* **Point light** (sphere of radius r, intensity s) → a ``sphere`` shape with an ``area`` emitter
  of radiance ``s/(π r²)`` and a black BSDF; Mitsuba samples the subtended cone, as we do. A
  radius-0 point light → ``point`` emitter with ``intensity = s``.
* **Directional light** (direction, angular radius r, irradiance E): r = 0 → ``directional`` with
  ``irradiance = E``; r > 0 → a sphere emitter of radiance ``E/(π sin² r)`` at distance
  ``D = 1000 ×`` the scene's bounding radius with radius ``D sin r`` (the same cone seen from the
  scene's centre; elsewhere its direction and solid angle are off by ≲ 1/1000).
* **Environment** → ``envmap`` from an in-memory bitmap, ``to_world`` = the light's rotation about
  +Y. Mitsuba interpolates its map bilinearly with columns at ``φ = 2π (c + ½)/W`` (as ours) but
  rows at ``θ = π j/(H − 1)`` (poles on the first and last rows); ours are at ``θ = π (r + ½)/H``.
  :func:`mitsuba_envmap` writes a grid of 2H + 1 rows at ``θ = π j/(2H)``: odd rows are our rows,
  even rows the mean of their two neighbours (the end rows at the poles): Mitsuba's bilinear
  lookup of it is exactly our bilinear lookup (``envmap.env_lookup_numpy``), which is what our
  renderer and reference show in the background. Our reference *lights* with the
  piecewise-constant texels; the bilinear function has the same integral up to the second-order
  effect of the sin θ weight and blurs the sun by one texel (tests: agreement within noise).

Differences that remain (documented, all small): Mitsuba's light spheres block the environment
behind them and each other (ours add without occluding; 2π(1 − cos r) sr each), a light sphere in
view would be visible in Mitsuba (:func:`mitsuba_scene` refuses one in the view frustum), and
pixels are box-filtered over the pixel area (ours: the k × k sub-pixel grid of the truth).

Timing (:func:`mitsuba_curve`): ``mi.render`` at 1, 2, 4, … spp after one untimed warm-up render
per sample count (kernel compilation / kernel-cache load excluded, as our frames are warm), the
median of a few timed renders (each evaluated and copied to the host); scene
loading (BVH, envmap distribution) excluded as our precompute is; Dr.Jit uses
``cpu_workers(device)`` threads, the same count our CPU kernels use.
"""
from __future__ import annotations

import functools
import math
import time

import numpy as np

from warp_sg.core.errors import InputError
from warp_sg.core.workers import cpu_workers

#: the Mitsuba variant used on the CPU (LLVM JIT, RGB) and on a CUDA device
VARIANTS = {"cpu": "llvm_ad_rgb", "cuda": "cuda_ad_rgb"}
#: distance of a directional light's emitter sphere, in scene bounding radii
DIRECTIONAL_DISTANCE = 1000.0
#: sample counts of the error-vs-time curve
CURVE_SPP = (1, 2, 4, 8, 16, 32, 64)

INSTALL_HINT = ("optional extra: pip install -e '.[compare]' (mitsuba>=3.5) and apt install libllvm19 "
                "(set DRJIT_LIBLLVM_PATH if Dr.Jit does not find it)")


class NotExpressible(InputError):
    """The scene uses something Mitsuba cannot render identically (the message says what)."""


def _variant(device: str) -> str:
    return VARIANTS["cuda" if str(device).startswith("cuda") else "cpu"]


def _modules():
    """``(drjit, mitsuba, None)``, or ``(None, None, ImportError)`` without the ``[compare]`` extra."""
    try:
        import drjit
        import mitsuba
    except ImportError as e:
        return None, None, e
    return drjit, mitsuba, None


@functools.lru_cache(maxsize=None)
def mitsuba_status(device: str = "cpu") -> tuple[bool, str]:
    """``(True, "mitsuba X.Y.Z, variant V, N threads")`` when Mitsuba imports, its variant for
    ``device`` can be set and Dr.Jit can JIT-compile a kernel; else ``(False, one-line reason)``
    (cached per device)."""
    dr, mi, err = _modules()
    if err is not None:
        return False, f"Mitsuba 3 not importable ({type(err).__name__}: {err}); {INSTALL_HINT}"
    var = _variant(device)
    if var.startswith("llvm"):
        from warp_sg.tools.mitsuba.variant import llvm_problem

        why = llvm_problem(var)
        if why is not None:
            return False, f"Mitsuba {mi.__version__} variant {var} unusable ({why}); {INSTALL_HINT}"
    try:
        mi.set_variant(var)
        if var.startswith("llvm"):
            dr.set_thread_count(cpu_workers(device))
        x = mi.Float([1.0, 2.0]) * 2.0
        dr.eval(x)
        float(x[1])
    except Exception as e:  # noqa: BLE001 - a missing/old libLLVM shows up here, in any exception type
        return False, f"Mitsuba {mi.__version__} variant {var} unusable ({type(e).__name__}: {e}); {INSTALL_HINT}"
    threads = dr.thread_count() if var.startswith("llvm") else 0
    return True, f"mitsuba {mi.__version__}, variant {var}" + (f", {threads} threads" if threads else "")


def _mi(device="cpu"):
    """The ``mitsuba`` module with the variant for ``device`` set (RuntimeError naming why not)."""
    ok, why = mitsuba_status(device)
    if not ok:
        raise RuntimeError(why)
    mi = _modules()[1]
    mi.set_variant(_variant(device))
    return mi


# --------------------------------------------------------------------------------------------
# conversion
# --------------------------------------------------------------------------------------------
def mitsuba_envmap(radiance: np.ndarray) -> np.ndarray:
    """Our (H, W, 3) map as Mitsuba's (2H + 1, W, 3) bilinear grid (module docstring): row 2r + 1
    is our row r, row 2r the mean of our rows r − 1 and r (clamped at the poles)."""
    a = np.asarray(radiance, np.float32)
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] < 1 or a.shape[1] < 2:
        raise InputError(f"environment must be (H, W, 3) with W >= 2, got {a.shape}", where="environment light")
    h = a.shape[0]
    j = np.arange(2 * h + 1)
    above = np.clip((j - 1) // 2, 0, h - 1)  # our row at or above θ_j
    below = np.clip(j // 2, 0, h - 1)  # our row at or below θ_j
    return (0.5 * (a[above] + a[below])).astype(np.float32)


def _check_material(name, brdf, approximate: bool = False):
    """The Mitsuba BSDF dict of one of our materials: Lambert → ``diffuse`` (identical); with
    ``approximate``, a GGX conductor (kd = 0) → ``roughconductor`` (``distribution = "ggx"``, α or
    (α_u, α_v), ``specular_reflectance = ks``; Fresnel: (η, k) as given, Schlick f0 as the real η of
    the same normal reflectance, none as ``material = "none"``) — the same NDF, but Mitsuba's
    separable Smith term ``G1(o) G1(i)`` instead of our height-correlated ``G2`` (darker at grazing
    angles), so only an approximate peer."""
    from warp_sg.brdf import GGX, Lambert
    from warp_sg.brdf.fresnel import Conductor, Dielectric, NoFresnel, Schlick

    if type(brdf) is Lambert:
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [float(x) for x in brdf.kd]}}
    if approximate and type(brdf) is GGX and not np.any(np.asarray(brdf.kd) > 0):
        d = {"type": "roughconductor", "distribution": "ggx", "sample_visible": True,
             "specular_reflectance": {"type": "rgb", "value": [float(x) for x in brdf.ks]}}
        if brdf.isotropic:
            d["alpha"] = float(brdf.alpha_x)
        else:
            d["alpha_u"], d["alpha_v"] = float(brdf.alpha_x), float(brdf.alpha_y)
        f = brdf.fresnel
        if isinstance(f, NoFresnel):
            d["material"] = "none"
        elif isinstance(f, (Conductor, Dielectric, Schlick)):
            if isinstance(f, Schlick):  # the η of a dielectric with the same normal reflectance
                r = np.sqrt(np.clip(np.asarray(f.f0, np.float64), 0.0, 0.999))
                eta, k = (1 + r) / (1 - r), np.zeros(3)
            else:
                eta = np.asarray(f.eta, np.float64)
                k = np.asarray(getattr(f, "k", np.zeros(3)), np.float64)
            d["eta"] = {"type": "rgb", "value": [float(x) for x in np.broadcast_to(eta, 3)]}
            d["k"] = {"type": "rgb", "value": [float(x) for x in np.broadcast_to(k, 3)]}
        return d
    raise NotExpressible(f"material '{name}' is {type(brdf).__name__}; only Lambert materials render identically "
                         "in Mitsuba 3 (GGX conductors approximately; see warp_sg.tools.peer_mitsuba)",
                         where=f"[materials.{name}]")


def _meshes(mi, scene, approximate: bool = False) -> dict:
    g = scene.geometry()
    out = {}
    for m, name in enumerate(g.material_names):
        sel = g.tri_material == m
        if not np.any(sel):
            continue
        mat = scene.materials[name]
        if getattr(mat, "textures", None) or getattr(mat, "normal_map", None) or getattr(mat, "tangent_map", None):
            raise NotExpressible(f"material '{name}' is textured; textures are not converted",
                                 where=f"[materials.{name}]")
        bsdf = mi.load_dict(_check_material(name, mat.brdf, approximate))
        tris = g.triangles[sel]
        used, inv = np.unique(tris, return_inverse=True)
        faces = inv.reshape(-1, 3).astype(np.uint32)
        props = mi.Properties()
        props["bsdf"] = bsdf
        mesh = mi.Mesh(f"mat_{m}", len(used), len(faces), props=props, has_vertex_normals=True)
        params = mi.traverse(mesh)
        params["vertex_positions"] = mi.Float(np.ascontiguousarray(g.vertices[used], np.float32).ravel())
        params["vertex_normals"] = mi.Float(np.ascontiguousarray(g.normals[used], np.float32).ravel())
        params["faces"] = mi.UInt32(faces.ravel())
        params.update()
        out[f"mesh_{m}"] = mesh
    return out


def _in_view(cam, centre, radius) -> bool:
    """Whether a sphere intersects the camera's view frustum (conservative: cone test)."""
    r, u, f = cam.basis()
    v = np.asarray(centre, np.float64) - np.asarray(cam.origin, np.float64)
    z = float(v @ f)
    if z <= -radius:
        return False
    ty = math.tan(math.radians(cam.fov) / 2)
    tx = ty * cam.aspect
    half = math.atan(math.hypot(tx, ty))
    ang = math.acos(max(-1.0, min(1.0, z / max(np.linalg.norm(v), 1e-30))))
    return ang - math.asin(min(1.0, radius / max(np.linalg.norm(v), 1e-30))) < half


def _sphere_light(mi, centre, radius, radiance):
    return {"type": "sphere", "center": [float(x) for x in centre], "radius": float(radius),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [float(x) for x in radiance]}}}


def _lights(mi, scene) -> dict:
    from warp_sg.scene.lights import DirectionalLight, PointLight

    g = scene.geometry()
    lo, hi = g.vertices.min(0).astype(np.float64), g.vertices.max(0).astype(np.float64)
    centre, brad = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))
    out = {}
    for j, li in enumerate(scene.lights):
        key = f"light_{j}"
        if isinstance(li, PointLight):
            if li.radius == 0.0:
                out[key] = {"type": "point", "position": li.position.tolist(),
                            "intensity": {"type": "rgb", "value": li.intensity.tolist()}}
                continue
            if _in_view(scene.camera, li.position, li.radius):
                raise NotExpressible(f"point light #{j + 1} is in view: Mitsuba would show its sphere, ours does not",
                                     where=f"[[lights]] #{j + 1}")
            out[key] = _sphere_light(mi, li.position, li.radius, li.intensity / (math.pi * li.radius ** 2))
        elif isinstance(li, DirectionalLight):
            if li.radius == 0.0:
                out[key] = {"type": "directional", "direction": (-li.direction).tolist(),
                            "irradiance": {"type": "rgb", "value": li.intensity.tolist()}}
                continue
            dist = DIRECTIONAL_DISTANCE * max(brad, 1e-3)
            pos = centre + dist * li.direction
            rad = dist * math.sin(li.radius)
            if _in_view(scene.camera, pos, rad):
                raise NotExpressible(f"directional light #{j + 1} is in view: Mitsuba would show its disc, ours does "
                                     "not", where=f"[[lights]] #{j + 1}")
            out[key] = _sphere_light(mi, pos, rad, li.intensity / (math.pi * math.sin(li.radius) ** 2))
        else:
            out[key] = envmap_dict(li)
    return out


def envmap_dict(light, device: str = "cpu") -> dict:
    """The ``envmap`` emitter dict of an :class:`~warp_sg.scene.lights.EnvironmentLight` (its map as
    :func:`mitsuba_envmap`, ``scale``, ``to_world`` = its rotation)."""
    mi = _mi(device)
    m = np.eye(4)
    m[:3, :3] = light.rotation_matrix()
    return {"type": "envmap", "bitmap": mi.Bitmap(mitsuba_envmap(light.base_radiance())), "scale": float(light.scale),
            "to_world": mi.ScalarTransform4f(m.tolist())}


def mitsuba_scene_dict(scene, spp: int = 1, device: str = "cpu", approximate: bool = False,
                       max_depth: int | None = None) -> dict:
    """The Mitsuba scene dict of ``scene`` (module docstring); raises :class:`NotExpressible`.
    ``approximate``: GGX conductors too (:func:`_check_material`). ``max_depth``: the ``path``
    integrator's (default our reference's full depth; 2: direct light only)."""
    from warp_sg.groundtruth.path_wp import DEFAULT_MAX_DEPTH

    mi = _mi(device)
    max_depth = DEFAULT_MAX_DEPTH if max_depth is None else int(max_depth)
    cam = scene.camera
    d = {"type": "scene",
         "integrator": {"type": "path", "max_depth": max_depth, "hide_emitters": not scene.render.background},
         "sensor": {"type": "perspective", "fov": float(cam.fov), "fov_axis": "y",
                    "near_clip": float(cam.near), "far_clip": float(cam.far),
                    "to_world": mi.ScalarTransform4f().look_at(origin=list(cam.origin), target=list(cam.target),
                                                               up=list(cam.up)),
                    "sampler": {"type": "independent", "sample_count": int(spp)},
                    "film": {"type": "hdrfilm", "width": int(cam.width), "height": int(cam.height),
                             "pixel_format": "rgb", "rfilter": {"type": "box"}}}}
    d.update(_meshes(mi, scene, approximate))
    d.update(_lights(mi, scene))
    return d


def mitsuba_scene(scene, device: str = "cpu", approximate: bool = False, max_depth: int | None = None):
    """``mi.load_dict(mitsuba_scene_dict(scene))`` (the loaded scene: BVH and envmap sampling built)."""
    mi = _mi(device)
    return mi.load_dict(mitsuba_scene_dict(scene, device=device, approximate=approximate, max_depth=max_depth))


def mitsuba_render(mscene, spp: int, seed: int = 0, device: str = "cpu") -> tuple[np.ndarray, float]:
    """``(image (H, W, 3) float32, seconds)`` of one ``mi.render`` (evaluated and copied to host)."""
    mi = _mi(device)
    t0 = time.perf_counter()
    img = np.array(mi.render(mscene, spp=int(spp), seed=int(seed)), dtype=np.float32)
    return img, time.perf_counter() - t0


def mitsuba_mean(mscene, spp: int, batches: int = 4, seed: int = 0, device: str = "cpu"):
    """``(mean image, per-pixel standard error)`` from ``batches`` independent renders of ``spp``
    samples each (the standard error from the spread of the batch means)."""
    imgs = np.stack([mitsuba_render(mscene, spp, seed + 7919 * b, device)[0] for b in range(int(batches))])
    mean = imgs.mean(0, dtype=np.float64)
    se = imgs.std(0, ddof=1, dtype=np.float64) / math.sqrt(len(imgs))
    return mean.astype(np.float32), se.astype(np.float32)


def mitsuba_curve(scene, truth: np.ndarray, spps=CURVE_SPP, device: str = "cpu", seed: int = 1, repeats: int = 3,
                  stop_below: float | None = None, max_spp: int = 4096,
                  progress: bool = False, max_depth: int | None = None) -> list[tuple[int, float, float]]:
    """Mitsuba's error-vs-time curve ``[(spp, rel_mse against truth, seconds)]``: each sample
    count rendered once untimed (warm-up), then ``repeats`` times with other seeds; the error is
    the mean of their relative MSEs, the time their median. With ``stop_below``: powers of two
    from 1 until the error is at most ``stop_below`` (or ``max_spp``) instead of ``spps``.
    ``max_depth``: the path integrator's (:func:`mitsuba_scene_dict`)."""
    from warp_sg.groundtruth.region_error import image_errors

    mscene = mitsuba_scene(scene, device, max_depth=max_depth)
    if stop_below is not None:
        spps = [2 ** i for i in range(int(math.log2(max(1, max_spp))) + 1)]
    spps = [int(s) for s in spps]
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(spps), desc="mitsuba", unit="level", leave=False)
    curve = []
    try:
        for spp in spps:
            mitsuba_render(mscene, spp, seed + 100_003 * spp, device)  # warm-up: kernel compile / cache load
            errs, secs = [], []
            for r in range(max(1, int(repeats))):
                img, sec = mitsuba_render(mscene, spp, seed + 100_003 * spp + 1 + r, device)
                errs.append(image_errors(img, truth)["rel_mse"])
                secs.append(sec)
            curve.append((spp, float(np.mean(errs)), float(np.median(secs))))
            if bar is not None:
                bar.update(1)
            if stop_below is not None and curve[-1][1] <= stop_below:
                break
    finally:
        if bar is not None:
            bar.close()
    return curve


__all__ = ["NotExpressible", "mitsuba_status", "mitsuba_envmap", "envmap_dict", "mitsuba_scene_dict", "mitsuba_scene",
           "mitsuba_render", "mitsuba_mean", "mitsuba_curve", "VARIANTS", "CURVE_SPP",
           "INSTALL_HINT"]
