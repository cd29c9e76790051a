r"""The peer of the inverse-rendering benchmark: Mitsuba 3's differentiable path tracer (``prb``)
fitting the same parameters from the same photographs for a given wall time
(:mod:`warp_sg.tools.bench_inverse`).

What it optimises, with ``mi.ad.Adam``: the object's base colour and roughness as bitmaps of the
fit's resolutions (the BSDF of :func:`warp_sg.tools.inverse_problem.mitsuba_bsdf`, the truth's own
model: the base colour's bitmap holds 2·kd), and the environment as an equirectangular bitmap
(``envmap``, ``env_res``), started where our fit starts (grey 0.5, α = 0.4, a constant 1). Each
step renders one view (in turn) at ``spp`` samples per pixel with ``prb`` at ``max_depth`` and
takes the gradient of the same loss as ours, the relative squared error over the view's mask
``Σ m|I − T|² / Σ m|T|²``; values are clamped to their bounds after each step (kd ∈ [0, 0.999],
α ∈ [0.01, 1], radiance ≥ 0). It stops at the first step that ends past ``seconds`` (the
scene's loading and Dr.Jit's compilation count).
"""
from __future__ import annotations

import time

import numpy as np

KD_KEY = "mesh_object.bsdf.bsdf_0.reflectance.data"
ALPHA_KEY = "mesh_object.bsdf.bsdf_1.alpha.data"
ENV_KEY = "light_0.data"


def mitsuba_fit(scene, cams, photos, masks, seconds: float, kd_size: int, alpha_size: int, *,
                start_kd: float = 0.5, start_alpha: float = 0.4, env_res: tuple = (32, 64), spp: int = 4,
                max_depth: int = 4, lr: float = 0.03, seed: int = 0) -> dict:
    """Fit with Mitsuba for ``seconds`` of wall time (module docstring). ``scene``: the problem's scene
    (its geometry); ``cams``, ``photos``, ``masks``: the fit's camera tables, photographs and masks
    (bool). Returns ``{"kd" (kd_size², 3), "alpha" (alpha_size², 1), "env" (env_res, 3),
    "iterations", "seconds", "losses"}``."""
    import drjit as dr
    import mitsuba as mi

    from warp_sg.tools.inverse_problem import mitsuba_scene_dict
    from warp_sg.tools.mitsuba.render import set_fastest_variant

    t0 = time.perf_counter()
    set_fastest_variant("llvm_ad_rgb")
    kd0 = np.full((kd_size, kd_size, 3), start_kd, np.float32)
    al0 = np.full((alpha_size, alpha_size, 1), start_alpha, np.float32)
    env = {"type": "envmap", "bitmap": mi.Bitmap(np.ones((*env_res, 3), np.float32))}
    integ = {"type": "prb", "max_depth": int(max_depth), "hide_emitters": True}
    msc = mi.load_dict(mitsuba_scene_dict(mi, scene, kd0, al0, cams, env=env, integrator=integ))
    params = mi.traverse(msc)
    opt = mi.ad.Adam(lr=lr)
    for k in (KD_KEY, ALPHA_KEY, ENV_KEY):
        opt[k] = params[k]
    params.update(opt)
    targets = [mi.TensorXf(np.asarray(p, np.float32)) for p in photos]
    weights = [mi.TensorXf(np.repeat(np.asarray(m, np.float32)[..., None], 3, 2)) for m in masks]
    norms = [float(np.sum(np.asarray(m, np.float64)[..., None] * np.asarray(p, np.float64) ** 2))
             for p, m in zip(photos, masks)]
    losses, it = [], 0
    while time.perf_counter() - t0 < seconds:
        v = it % len(cams)
        img = mi.render(msc, params, sensor=v, spp=int(spp), seed=seed + it)
        loss = dr.sum(weights[v] * dr.square(img - targets[v]), axis=None) / max(norms[v], 1e-30)
        dr.backward(loss)
        opt.step()
        opt[KD_KEY] = dr.clip(opt[KD_KEY], 0.0, 2.0 * 0.999)
        opt[ALPHA_KEY] = dr.clip(opt[ALPHA_KEY], 0.01, 1.0)
        opt[ENV_KEY] = dr.maximum(opt[ENV_KEY], 0.0)
        params.update(opt)
        losses.append(float(loss.array[0]))
        it += 1
    return {"kd": 0.5 * np.array(params[KD_KEY], np.float64).reshape(kd_size, kd_size, 3),
            "alpha": np.array(params[ALPHA_KEY], np.float64).reshape(alpha_size, alpha_size, 1),
            "env": np.array(params[ENV_KEY], np.float64), "iterations": it,
            "seconds": time.perf_counter() - t0, "losses": losses}


def mitsuba_relight(scene_b, kd, alpha, cams, spp: int, seed: int = 1) -> list[np.ndarray]:
    """Mitsuba's photographs (path tracer, full depth) of the fitted textures ``kd``, ``alpha`` under
    ``scene_b``'s environment from the camera tables ``cams``: how Mitsuba's fit relights."""
    from warp_sg.tools.inverse_problem import photograph

    return photograph(scene_b, kd, alpha, cams, "mitsuba", spp, seed=seed)


__all__ = ["mitsuba_fit", "mitsuba_relight"]
