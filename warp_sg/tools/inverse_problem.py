r"""The relighting problem of the inverse-rendering benchmark (:mod:`warp_sg.tools.bench_inverse`):
an object of known geometry with a known SVBRDF on a Lambert floor, photographed under one
environment (A) from ``fit`` views and, for the check, under another (B) from ``novel`` views.

* **The true SVBRDF** (:func:`true_textures`): GGX, base colour ``kd`` a texture (smooth colour
  blotches on a skin tone, made by code), roughness ``α`` a texture in [0.2, 0.6], ``ks`` = 1 and
  the Fresnel term of a dielectric of index 1.5. The floor and a grey ball beside the object (a
  "grey probe", as photographers put one in the frame) are Lambert 0.5 and known: an unknown
  light and an unknown base colour share the irradiance of each normal (a texel's colour times the
  light its normal receives is all a diffuse pixel says), and surfaces of known albedo facing every
  way pin it down — the floor alone pins only the light from above.
* **The scene files** (:func:`write_scenes`): ``true.toml`` (the true textures, environment A) and
  ``start.toml`` — what the fit starts from: a grey base colour, α = 0.4 and a constant
  environment, its textures at the fit's resolutions.
* **The photographs** (:func:`photograph`): a path tracer at full depth — Mitsuba 3 with its own
  BSDFs (``truth="mitsuba"``: a 50/50 ``blendbsdf`` of a ``diffuse`` of reflectance 2·kd and a GGX
  ``roughconductor`` of reflectance 2, so the sum is kd/π + the GGX lobe, α a bitmap; Mitsuba's
  Smith term is the separable one, ours the height-correlated one) or our Monte-Carlo reference
  (``truth="reference"``, :func:`warp_sg.groundtruth.reference.reference`, our BRDF exactly).
  The triangles, normals and UVs are ours (``Scene.geometry()``) in both.
* **The metrics** (:func:`relight_errors`, :func:`texture_errors`): PSNR of the object's pixels
  after one exposure (the truth's 99th percentile of the object's pixels → 0.8) and the sRGB
  encoding; the base colour's PSNR (linear, peak 1) and the roughness' mean absolute error over the
  texels the fit's views see.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: the true material's constants (the textures come from :func:`true_textures`)
KS, ETA = 1.0, 1.5
#: where the fit starts: a grey base colour, a middle roughness
KD_START, ALPHA_START = 0.5, 0.4
#: the truth's path depth (Mitsuba's ``max_depth``, as the accuracy matrix's full depth)
FULL_DEPTH = 8


@dataclass
class Problem:
    """One instance of the benchmark's problem (module docstring). Sizes in pixels and texels."""

    folder: Path
    #: the object's ``[[objects]]`` keys but its material: a mesh and its placement, or a primitive
    obj: dict
    env_a: Path
    env_b: Path
    size: int = 256
    fit_views: int = 8
    novel_views: int = 4
    texture: int = 1024
    kd_fit: int = 128
    alpha_fit: int = 64
    target: tuple = (0.0, 0.5, 0.0)
    distance: float = 2.6
    fov: float = 30.0
    seed: int = 0
    #: the grey probe: centre and radius of a Lambert 0.5 sphere (None: none)
    probe: tuple | None = ((0.4, 0.2, 0.65), 0.2)

    def cameras(self, novel: bool) -> list[dict]:
        """The camera tables of the fit views (a ring, every other one at 12° and 42° elevation) or
        of the novel views (at 28°, at other azimuths)."""
        n = self.novel_views if novel else self.fit_views
        az = (np.arange(n) + (0.5 if novel else 0.0)) * (2 * math.pi / n) + (0.3 if novel else 0.0)
        el = np.radians(np.full(n, 28.0) if novel else np.where(np.arange(n) % 2 == 0, 12.0, 42.0))
        t = np.asarray(self.target, np.float64)
        o = t + self.distance * np.stack([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)], 1)
        return [{"origin": [round(float(x), 6) for x in p], "target": list(self.target), "fov": self.fov,
                 "width": self.size, "height": self.size} for p in o]


def smooth_noise(shape: tuple, cells: int, rng, channels: int = 1) -> np.ndarray:
    """Value noise: a ``cells`` × ``cells`` grid of uniform values in [0, 1), bicubic-upsampled to
    ``shape`` (H, W) → (H, W, channels)."""
    import cv2

    g = rng.random((cells, cells, channels)).astype(np.float32)
    out = cv2.resize(g, (shape[1], shape[0]), interpolation=cv2.INTER_CUBIC)
    return np.clip(out.reshape(shape[0], shape[1], channels), 0.0, 1.0)


def true_textures(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(kd (n, n, 3), alpha (n, n, 1))`` linear: a skin tone modulated by colour blotches at three
    scales (8, 16 and 32 cells across), and a roughness 0.2–0.6 of 6 cells across."""
    rng = np.random.default_rng(seed)
    base = np.array([0.55, 0.36, 0.28], np.float32)
    lum = 0.5 * smooth_noise((n, n), 8, rng) + 0.3 * smooth_noise((n, n), 16, rng) + 0.2 * smooth_noise((n, n), 32, rng)
    hue = smooth_noise((n, n), 12, rng, 3) - 0.5
    kd = np.clip(base * (0.45 + 1.1 * lum) + 0.25 * hue, 0.03, 0.9).astype(np.float32)
    alpha = (0.2 + 0.4 * smooth_noise((n, n), 6, rng)).astype(np.float32)
    return kd, alpha


def _scene_text(p: Problem, kd: str, alpha: str, env: str | None, camera: dict, bounces: int) -> str:
    from warp_sg.scene.plain_scenes import toml_table

    light = {"type": "environment", **({"file": env} if env else
                                        {"procedural": "constant", "options": {"radiance": [1.0, 1.0, 1.0]}})}
    parts = [toml_table("camera", camera),
             toml_table("objects", {**p.obj, "material": "object", "name": "object"},
                        array=True),
             toml_table("objects", {"mesh": "floor.obj", "material": "floor", "name": "floor"}, array=True),
             toml_table("materials.object", {"model": "ggx", "kd": {"texture": kd}, "ks": [KS, KS, KS],
                                             "alpha": {"texture": alpha}, "fresnel": {"eta": ETA}}),
             toml_table("materials.floor", {"model": "lambert", "kd": [0.5, 0.5, 0.5]}),
             *([toml_table("objects", {"primitive": "sphere", "center": list(p.probe[0]), "radius": p.probe[1],
                                       "resolution": [24, 48], "material": "probe", "name": "probe"}, array=True),
                toml_table("materials.probe", {"model": "lambert", "kd": [0.5, 0.5, 0.5]})] if p.probe else []),
             toml_table("lights", light, array=True),
             toml_table("render", {"bounces": bounces})]
    return "".join(parts)


def write_scenes(p: Problem) -> dict:
    """Write ``true.toml`` (environment A), ``true_b.toml`` (environment B), ``start.toml`` and their
    textures and floor into ``p.folder``; return ``{"kd": kd, "alpha": alpha}`` (the true textures)."""
    from warp_sg.core.image_io import save_image
    from warp_sg.scene.plain_scenes import write_floor_obj

    p.folder.mkdir(parents=True, exist_ok=True)
    write_floor_obj(p.folder / "floor.obj")
    kd, alpha = true_textures(p.texture, p.seed)
    save_image(p.folder / "kd_true.exr", kd)
    save_image(p.folder / "alpha_true.exr", np.repeat(alpha, 3, 2))
    save_image(p.folder / "kd_start.exr", np.full((p.kd_fit, p.kd_fit, 3), KD_START, np.float32))
    save_image(p.folder / "alpha_start.exr", np.full((p.alpha_fit, p.alpha_fit, 3), ALPHA_START, np.float32))
    cam = p.cameras(False)[0]
    default_bounces = 4
    (p.folder / "true.toml").write_text(_scene_text(p, "kd_true.exr", "alpha_true.exr", str(p.env_a), cam,
                                                    default_bounces))
    (p.folder / "true_b.toml").write_text(_scene_text(p, "kd_true.exr", "alpha_true.exr", str(p.env_b), cam,
                                                      default_bounces))
    # the fit differentiates the direct light (warp-sg fit's limits): its scene has no bounces
    (p.folder / "start.toml").write_text(_scene_text(p, "kd_start.exr", "alpha_start.exr", None, cam, 0))
    return {"kd": kd, "alpha": alpha[..., 0]}


def with_camera(scene, cam: dict):
    """``scene`` with its camera replaced by the table ``cam`` (a copy of the camera)."""
    from dataclasses import replace

    scene.camera = replace(scene.camera, **{k: (tuple(v) if isinstance(v, list) else v) for k, v in cam.items()})
    return scene


# ------------------------------------------------------------------------------------------------
# Mitsuba 3: the truth's and the peer's scene, with Mitsuba's own BSDFs
# ------------------------------------------------------------------------------------------------
def mitsuba_bsdf(mi, kd: np.ndarray, alpha: np.ndarray) -> dict:
    """The true material with Mitsuba's own BSDFs (module docstring): bitmaps of linear values."""
    def bitmap(a):
        a = np.ascontiguousarray(a, np.float32)
        return {"type": "bitmap", "bitmap": mi.Bitmap(a if a.ndim == 3 else a[..., None]), "raw": True,
                "filter_type": "bilinear", "wrap_mode": "repeat"}
    return {"type": "blendbsdf", "weight": 0.5,
            "bsdf_0": {"type": "diffuse", "reflectance": bitmap(2.0 * np.asarray(kd))},
            "bsdf_1": {"type": "roughconductor", "distribution": "ggx", "alpha": bitmap(alpha),
                       "eta": ETA, "k": 0.0, "specular_reflectance": bitmap(np.full((1, 1, 3), 2.0 * KS))}}


def mitsuba_scene_dict(mi, scene, kd, alpha, cams: list[dict], env: dict | None = None,
                       integrator: dict | None = None) -> dict:
    """A Mitsuba scene of ``scene``'s geometry (ours: triangles, normals, UVs), the object's material
    :func:`mitsuba_bsdf` (``kd``, ``alpha``), the floor Lambert 0.5, ``scene``'s environment (or the
    dict ``env``) and one sensor per camera table of ``cams``."""
    from dataclasses import replace

    from warp_sg.tools.mitsuba.scene_dict import _camera, _lights

    g = scene.geometry()
    d = {"type": "scene", "integrator": integrator or {"type": "path", "max_depth": FULL_DEPTH,
                                                       "hide_emitters": True}}
    for i, c in enumerate(cams):
        cam = replace(scene.camera, **{k: (tuple(v) if isinstance(v, list) else v) for k, v in c.items()})
        d[f"sensor_{i}"] = _camera(mi, cam, 16)
    for m, name in enumerate(g.material_names):
        sel = g.tri_material == m
        used, inv = np.unique(g.triangles[sel], return_inverse=True)
        faces = inv.reshape(-1, 3).astype(np.uint32)
        props = mi.Properties()
        bsdf = mitsuba_bsdf(mi, kd, alpha) if name == "object" else \
            {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}
        props["bsdf"] = mi.load_dict(bsdf)
        mesh = mi.Mesh(f"mesh_{name}", len(used), len(faces), props=props, has_vertex_normals=True,
                       has_vertex_texcoords=True)
        params = mi.traverse(mesh)
        uv = g.uvs[used].astype(np.float32).copy()
        uv[:, 1] = 1.0 - uv[:, 1]  # ours: origin bottom-left; Mitsuba's bitmaps: row 0 at v = 0
        for k, a in (("vertex_positions", g.vertices[used]), ("vertex_normals", g.normals[used]),
                     ("vertex_texcoords", uv), ("faces", faces)):
            params[k] = type(params[k])(np.ascontiguousarray(a, np.uint32 if k == "faces" else np.float32).ravel())
        params.update()
        d[f"mesh_{name}"] = mesh
    if env is None:
        d.update(_lights(mi, scene, Path(scene.path).parent if getattr(scene, "path", None) else None))
    else:
        d["light_0"] = env
    return d


def photograph(scene, kd, alpha, cams: list[dict], truth: str, spp: int, seed: int = 0) -> list[np.ndarray]:
    """The path tracer's photographs of ``scene`` (its environment) from the camera tables ``cams``:
    Mitsuba (``truth="mitsuba"``) or our Monte-Carlo reference (``"reference"``), full depth."""
    if truth == "mitsuba":
        import mitsuba as mi

        from warp_sg.tools.mitsuba.render import set_fastest_variant

        set_fastest_variant()
        msc = mi.load_dict(mitsuba_scene_dict(mi, scene, kd, alpha, cams))
        return [np.array(mi.render(msc, sensor=i, spp=spp, seed=seed + 7919 * i), np.float32)
                for i in range(len(cams))]
    if truth == "reference":
        from warp_sg.groundtruth.reference import reference

        return [reference(with_camera(scene, c), spp=spp, progress=False, seed=seed + 7919 * i)
                for i, c in enumerate(cams)]
    raise ValueError(f"unknown truth {truth!r} (mitsuba or reference)")


def write_views(folder: Path, cams: list[dict], images: list[np.ndarray], stem: str,
                masks: list[np.ndarray] | None = None) -> Path:
    """``stem_N.exr`` per photograph (and ``stem_N_mask.png`` per mask) and the views file
    ``stem.toml`` of ``warp-sg fit``."""
    from warp_sg.core.image_io import save_image
    from warp_sg.scene.plain_scenes import toml_table

    parts = []
    for i, (c, img) in enumerate(zip(cams, images)):
        save_image(folder / f"{stem}_{i}.exr", np.asarray(img, np.float32))
        t = {**c, "image": f"{stem}_{i}.exr"}
        if masks is not None:
            save_image(folder / f"{stem}_{i}_mask.png", np.repeat(masks[i][..., None], 3, 2).astype(np.float32))
            t["mask"] = f"{stem}_{i}_mask.png"
        parts.append(toml_table("views", t, array=True))
    path = folder / f"{stem}.toml"
    path.write_text("".join(parts))
    return path


# ------------------------------------------------------------------------------------------------
# Metrics
# ------------------------------------------------------------------------------------------------
def object_masks(scene, cams: list[dict]) -> tuple[list, list, list, list]:
    """Per camera: the pixels that see the object, less a one-pixel band along its silhouette
    (H, W) bool; the object's (u, v) at those pixels (N, 2) (rasterized pixel centres); every pixel
    that sees the object or the probe (H, W) bool; the pixels that see any surface, less the band
    (H, W) bool (those ``ws.fit`` matches)."""
    from warp_sg.inverse.fit import _erode
    from warp_sg.renderer.renderer import Renderer

    r = Renderer(scene, "cpu", progress=False)
    g = r.geometry  # (the installed geometry: refined where the shadows asked for it)
    obj = g.material_names.index("object")
    probe = g.material_names.index("probe") if "probe" in g.material_names else -2
    masks, uvs, full, surface = [], [], [], []
    for c in cams:
        r.set_camera(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in c.items()})
        vb = r.rasterize(1)
        tri = vb.tri_id.numpy().reshape(c["height"], c["width"])
        mat = np.where(tri >= 0, g.tri_material[np.maximum(tri, 0)], -1)
        m = _erode(mat == obj)
        full.append((mat == obj) | (mat == probe))
        surface.append(_erode(tri >= 0))
        b = vb.bary.numpy().reshape(c["height"], c["width"], 2)[m]
        t = g.triangles[tri[m]]
        w = np.stack([1.0 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)
        uvs.append(np.einsum("nk,nkc->nc", w, g.uvs[t]))
        masks.append(m)
    return masks, uvs, full, surface


def fit_mask(full: np.ndarray, stride: int) -> np.ndarray:
    """The pixels a fit matches: the object's and the probe's (``full``), and elsewhere one pixel in
    ``stride`` × ``stride`` (of the known floor, every pixel is not needed)."""
    grid = np.zeros_like(full)
    grid[::stride, ::stride] = True
    return full | grid


def seen_texels(uvs: list[np.ndarray], n: int) -> np.ndarray:
    """(n, n) bool: the texels of an n × n texture that a pixel of the views lands in (nearest)."""
    uv = np.concatenate(uvs) % 1.0
    x = np.clip((uv[:, 0] * n).astype(np.int64), 0, n - 1)
    y = np.clip(((1.0 - uv[:, 1]) * n).astype(np.int64), 0, n - 1)
    seen = np.zeros((n, n), bool)
    seen[y, x] = True
    return seen


def exposure(truth: list[np.ndarray], masks: list[np.ndarray]) -> float:
    """One scale for all views: the truth's 99th percentile of the object's pixels → 0.8."""
    v = np.concatenate([t[m].ravel() for t, m in zip(truth, masks)])
    return 0.8 / max(float(np.percentile(v, 99.0)), 1e-12)


def psnr(a: np.ndarray, b: np.ndarray, peak: float = 1.0) -> float:
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return 10.0 * math.log10(peak * peak / mse) if mse > 0 else float("inf")


def relight_errors(images: list[np.ndarray], truth: list[np.ndarray], masks: list[np.ndarray]) -> dict:
    """``psnr_db`` over the object's pixels of every view (one exposure, sRGB-encoded, module
    docstring) and ``rel_mse`` (linear, Σ|I − T|²/Σ|T|²)."""
    from warp_sg.core.image_io import linear_to_srgb

    s = exposure(truth, masks)
    a = np.concatenate([np.asarray(i, np.float64)[m] for i, m in zip(images, masks)])
    b = np.concatenate([np.asarray(t, np.float64)[m] for t, m in zip(truth, masks)])
    enc = [linear_to_srgb(np.clip(x * s, 0.0, 1.0).astype(np.float32)) for x in (a, b)]
    return {"psnr_db": psnr(*enc), "rel_mse": float(np.sum((a - b) ** 2) / max(np.sum(b * b), 1e-30))}


def texture_errors(kd: np.ndarray, alpha: np.ndarray, true: dict, seen: np.ndarray) -> dict:
    """``albedo_psnr_db`` (linear base colour, peak 1) and ``roughness_mae`` of the fitted textures
    (any size: resampled to the truth's) over the truth's texels marked in ``seen`` (the truth's size)."""
    from warp_sg.inverse.outputs import resize

    n = true["kd"].shape[0]
    kd = resize(np.asarray(kd, np.float64).reshape(*np.shape(kd)[:2], -1), n, n)[..., :3]
    al = resize(np.asarray(alpha, np.float64).reshape(*np.shape(alpha)[:2], -1), n, n)[..., 0]
    return {"albedo_psnr_db": psnr(kd[seen], true["kd"][seen]),
            "roughness_mae": float(np.mean(np.abs(al[seen] - true["alpha"][seen])))}


__all__ = ["Problem", "true_textures", "write_scenes", "photograph", "write_views", "mitsuba_scene_dict",
           "mitsuba_bsdf", "object_masks", "fit_mask", "seen_texels", "relight_errors", "texture_errors", "with_camera",
           "FULL_DEPTH"]
