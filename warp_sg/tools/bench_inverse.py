r"""``warp-sg bench`` section "inverse rendering: relighting" and :func:`run_relighting`: photographs
of an object with a known SVBRDF under environment A, ``ws.fit`` of the environment and the
textures (base colour, roughness), then the fitted object rendered under environment B (known)
from novel views and compared with the path tracer's photographs under B
(:mod:`warp_sg.tools.inverse_problem`). Beside it, where Mitsuba 3 is installed, Mitsuba's
differentiable path tracer fitting the same parameters for the same wall time
(:mod:`warp_sg.tools.inverse_mitsuba`), relit by Mitsuba.

Rows (``case``): the start of the fit relit (what the fit must beat), our fit, Mitsuba's fit, and
the true textures rendered by our renderer under B (the relighting PSNR our renderer reaches with
perfect parameters: the floor of the comparison). Columns: ``fit_s`` (wall time of the fit: its
precompute, photographs' reading and iterations), ``iterations``, ``relight_psnr_db`` (the object's
pixels of the novel views, :func:`~warp_sg.tools.inverse_problem.relight_errors`),
``relight_rel_mse``, ``albedo_psnr_db`` and ``roughness_mae`` (the texels the fit's views see).

Full size (``scripts/inverse_bench.py``): the scanned head of ``shared/assets/LeePerrySmith.glb``
with 1024² textures, 8 views of 256², Mitsuba's photographs; ``quick``: a sphere, 4 views of 32²,
generated skies, our Monte-Carlo reference as the truth, 6 iterations in two levels, no peer (seconds).
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from warp_sg.inverse.fit import FitResult
from warp_sg.tools.inverse_problem import Problem

FREE = ("materials.object.kd", "materials.object.alpha", "lights.0")
#: the generated skies of the quick run and the tests (A: a sun high in front; B: low behind left)
SKY_A = {"width": 128, "height": 64, "elevation": 45.0, "azimuth": 30.0, "sun_radius": 0.08,
         "sun_radiance": 60.0, "halo": 0.1, "sky_intensity": 0.8}
SKY_B = {**SKY_A, "elevation": 20.0, "azimuth": 210.0}


def generated_skies(folder: Path) -> tuple[Path, Path]:
    """Two sun-and-sky EXRs (``SKY_A``, ``SKY_B``) written into ``folder``."""
    from warp_sg.groundtruth.accuracy_matrix import write_sunsky

    folder.mkdir(parents=True, exist_ok=True)
    return write_sunsky(folder / "sky_a.exr", SKY_A), write_sunsky(folder / "sky_b.exr", SKY_B)


def quick_problem(folder: Path, size: int = 32, views: int = 4) -> Problem:
    """A sphere on the floor under the generated skies, ``views`` views of ``size``², 64² base colour."""
    a, b = generated_skies(folder)
    return Problem(folder, {"primitive": "sphere", "center": [0.0, 0.5, 0.0], "radius": 0.45,
                            "resolution": [16, 32]}, a, b, size=size, fit_views=views, novel_views=2,
                   texture=64, kd_fit=16, alpha_fit=4, distance=2.4, fov=30.0)


def head_problem(folder: Path, shared: Path, env_a: str = "blouberg_sunrise_2_1k.hdr",
                 env_b: str = "venice_sunset_1k.hdr") -> Problem:
    """The scanned head (``LeePerrySmith.glb``, placed as the accuracy matrix places it), 8 views of 256²,
    1024² true textures fitted at 128² (base colour) and 64² (roughness), a grey ball beside it."""
    from warp_sg.groundtruth.accuracy_matrix import HEAD_PLACEMENT

    return Problem(folder, {"mesh": (shared / "LeePerrySmith.glb").as_posix(), **HEAD_PLACEMENT},
                   shared / env_a, shared / env_b)


def _render(scene, cams, env: Path | None, device) -> list[np.ndarray]:
    """Our renderer's frames of ``scene`` (its environment replaced by the map ``env``, bounces on)
    from the camera tables ``cams``."""
    from dataclasses import replace

    from warp_sg.renderer.renderer import Renderer
    from warp_sg.scene.lights import EnvironmentLight

    if env is not None:
        scene.lights[0] = EnvironmentLight(file=Path(env))
    scene.render = replace(scene.render, bounces=4)
    r = Renderer(scene, device, progress=False)
    out = []
    for c in cams:
        r.set_camera(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in c.items()})
        out.append(np.asarray(r.render(), np.float32))
    return out


def _fitted_textures(scene) -> tuple[np.ndarray, np.ndarray]:
    """The object's base colour (H, W, 3) and roughness (h, w, 1) textures, linear."""
    m = scene.materials["object"]
    kd = m.textures["kd"].rgba(colour=True)[..., :3]
    al = m.textures["alpha"].rgba()[..., :1]
    return kd, al


def indirect_light(scene_path: Path, cams, device) -> list[np.ndarray]:
    """Per camera table: the light that bounces in our renderer's frame of the scene file
    ``scene_path`` (its ``[render] bounces`` set to 4): the frame with bounces less the frame without."""
    from dataclasses import replace

    from warp_sg.renderer.renderer import Renderer
    from warp_sg.scene.loader import load_scene

    scene = load_scene(scene_path)
    scene.render = replace(scene.render, bounces=4)
    r = Renderer(scene, device, progress=False)
    out = []
    for c in cams:
        r.set_camera(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in c.items()})
        r.set_terms(bounces=True)
        full = np.asarray(r.render(), np.float64)
        r.set_terms(bounces=False)
        out.append(full - np.asarray(r.render(), np.float64))
    return out


def coarse_to_fine(start: Path, cams, photos, masks, folder: Path, levels, *, env_lobes: int, progress: bool,
                   device, log) -> FitResult:
    """``ws.fit`` of :data:`FREE` in ``levels`` — ``(texture_size, iterations)`` each, ``None``: the
    textures at their own sizes — each level starting from the last one's fitted scene (its textures
    resampled up, its environment projected on the basis again). The fit shades direct light only;
    from the second level on it matches the photographs less the light that bounces in our frames of
    the last level's result (:func:`indirect_light`), so that the base colour does not take the
    interreflection in. Returns the last level's result with ``seconds`` (the indirect light's
    frames included) and ``losses`` of all levels together."""
    import warp_sg as ws
    from warp_sg.tools.inverse_problem import write_views

    folder.mkdir(parents=True, exist_ok=True)
    scene, seconds, losses, res = Path(start), 0.0, [], None
    views = write_views(folder, cams, photos, "views_level0", masks)
    for k, (size, its) in enumerate(levels):
        if k > 0:
            t = time.perf_counter()
            ind = indirect_light(scene, cams, device)
            views = write_views(folder, cams, [np.maximum(p - i, 0.0) for p, i in zip(photos, ind)],
                                f"views_level{k}", masks)
            seconds += time.perf_counter() - t
        res = ws.fit(scene, views, list(FREE), folder / f"level{k}" / "fitted.toml", iterations=its,
                     texture_size=size, env_lobes=env_lobes, progress=progress, restart=True, device=device,
                     checkpoint_every=10 ** 6)
        seconds += res.seconds
        losses += res.losses
        scene = res.scene
        log(f"fit level {k} (textures {size or 'own size'}): {res.seconds:.1f} s, "
            f"loss {res.losses[0]:.4g} -> {res.losses[-1]:.4g}")
    res.seconds, res.losses = seconds, losses
    return res


#: the full run's levels: (texture size, L-BFGS iterations); None: base colour 128², roughness 64²
LEVELS = ((8, 15), (32, 15), (None, 20), (None, 20))


def run_relighting(p: Problem, *, truth: str = "mitsuba", photo_spp: int = 128, levels=LEVELS,
                   env_lobes: int = 64, floor_stride: int = 3, peer: bool = False, peer_spp: int = 4,
                   device: str = "cpu", progress: bool = False, log=None) -> dict:
    """The whole benchmark on problem ``p`` (module docstring). Returns ``{"rows": [...], "info": {...},
    "images": {...}}``: the table's rows, the sizes and timings of the parts, and the novel views
    (truth under B; ours, the start's and Mitsuba's relit) for a figure."""
    from warp_sg.scene.loader import load_scene
    from warp_sg.tools import inverse_problem as ip

    log = log or (lambda *_: None)
    info = {"truth": truth, "photo_spp": photo_spp, "size": p.size, "fit_views": p.fit_views,
            "novel_views": p.novel_views, "texture": p.texture, "kd_fit": p.kd_fit, "alpha_fit": p.alpha_fit,
            "env_lobes": env_lobes, "env_a": Path(p.env_a).name, "env_b": Path(p.env_b).name}
    true = ip.write_scenes(p)
    sc_a, sc_b = load_scene(p.folder / "true.toml"), load_scene(p.folder / "true_b.toml")
    cams, novel = p.cameras(False), p.cameras(True)
    _, uvs, full, surface = ip.object_masks(sc_a, cams)
    masks_b = ip.object_masks(sc_b, novel)[0]
    info["triangles"] = int(len(sc_a.geometry().triangles))
    info["object_pixels"] = int(sum(int(f.sum()) for f in full))
    t = time.perf_counter()
    photos = ip.photograph(sc_a, true["kd"], true["alpha"][..., None], cams, truth, photo_spp)
    truth_b = ip.photograph(sc_b, true["kd"], true["alpha"][..., None], novel, truth, photo_spp, seed=101)
    info["photographs_s"] = time.perf_counter() - t
    log(f"photographs: {info['photographs_s']:.1f} s")
    fit_masks = [ip.fit_mask(f, floor_stride) for f in full]
    seen = ip.seen_texels(uvs, p.texture)
    info["seen_texels"] = float(seen.mean())

    res = coarse_to_fine(p.folder / "start.toml", cams, photos, fit_masks, p.folder / "fit", levels,
                         env_lobes=env_lobes, progress=progress, device=device, log=log)
    rows, images = [], {"truth": truth_b}

    def row(case, imgs, kd, al, seconds, its, **extra):
        e = ip.relight_errors(imgs, truth_b, masks_b)
        te = ip.texture_errors(kd, al, true, seen) if kd is not None else \
            {"albedo_psnr_db": float("nan"), "roughness_mae": float("nan")}
        rows.append({"case": case, "fit_s": seconds, "iterations": its, "relight_psnr_db": e["psnr_db"],
                     "relight_rel_mse": e["rel_mse"], **te, **extra})

    start = load_scene(p.folder / "start.toml")
    images["start"] = _render(start, novel, p.env_b, device)
    kd0, al0 = _fitted_textures(start)
    row("start of the fit (grey, α = 0.4)", images["start"], kd0, al0, 0.0, 0)
    fitted = load_scene(res.scene)
    kd, al = _fitted_textures(fitted)
    images["ours"] = _render(fitted, novel, p.env_b, device)
    row("warp-sg fit (L-BFGS-B)", images["ours"], kd, al, res.seconds, len(res.losses))
    images["true_textures"] = _render(load_scene(p.folder / "true_b.toml"), novel, None, device)
    row("warp-sg, true textures (renderer's floor)", images["true_textures"], None, None, float("nan"), 0)
    if peer:
        matched = [m & s for m, s in zip(fit_masks, surface)]
        row_peer = _peer(p, sc_a, sc_b, cams, novel, photos, matched, res.seconds, peer_spp, photo_spp, log)
        if isinstance(row_peer, str):
            rows.append({"case": "Mitsuba 3 prb + Adam (equal time)", "note": row_peer})
        else:
            images["mitsuba"] = row_peer["images"]
            row("Mitsuba 3 prb + Adam (equal time)", row_peer["images"], row_peer["kd"], row_peer["alpha"],
                row_peer["seconds"], row_peer["iterations"])
    info["fit_losses"] = [float(x) for x in res.losses]
    return {"rows": rows, "info": info, "images": images}


def _peer(p, sc_a, sc_b, cams, novel, photos, masks, seconds, spp, photo_spp, log):
    """Mitsuba's fit for ``seconds`` on the pixels our fit matches (``masks``) and its relighting,
    or a line saying why not."""
    try:
        import mitsuba  # noqa: F401
    except ImportError as e:
        return f"skipped: Mitsuba 3 is not installed ({e})"
    from warp_sg.tools.inverse_mitsuba import mitsuba_fit, mitsuba_relight

    out = mitsuba_fit(sc_a, cams, photos, masks, seconds, p.kd_fit, p.alpha_fit, spp=spp)
    log(f"Mitsuba fit: {out['seconds']:.1f} s, {out['iterations']} steps")
    out["images"] = mitsuba_relight(sc_b, out["kd"], out["alpha"], novel, photo_spp)
    return out


def inverse_section(device="cpu", quick=False) -> list[dict]:
    """The bench section: the quick problem (``quick``) or the head (full; needs shared/assets and
    takes minutes: ``scripts/inverse_bench.py`` runs it and writes the report)."""
    from warp_sg.groundtruth.accuracy_matrix import shared_assets

    with tempfile.TemporaryDirectory(prefix="warp_sg_inverse_") as tmp:
        if quick:
            out = run_relighting(quick_problem(Path(tmp)), truth="reference", photo_spp=32, levels=((4, 3), (None, 3)),
                                 env_lobes=16, floor_stride=2, device=device)
        else:
            shared = shared_assets()
            if shared is None:
                return [{"case": "scanned head", "note": "skipped: shared/assets is absent"}]
            try:
                import mitsuba  # noqa: F401
                truth, peer = "mitsuba", True
            except ImportError:
                truth, peer = "reference", False
            out = run_relighting(head_problem(Path(tmp), shared), truth=truth, peer=peer, device=device)
    return out["rows"]


__all__ = ["run_relighting", "inverse_section", "quick_problem", "head_problem", "generated_skies", "FREE"]
