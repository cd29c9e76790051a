r"""The sharpest NDF lobe of a scene's materials: what the ΓL prefilter must reach (scene layer).

The specular environment term looks ΓL up at the sharpness of each slice lobe (eq. 41): the NDF
lobe ``(p_D, λ_D)`` warped to the view, ``λ_W = λ_D / (4 |p_D · o|)`` (eq. 17–22), combined with the
cosine. So the sharpest lookup of a material is about ``λ_D`` at 75.5° from the lobe axis
(``|p_D·o| = ¼``) and sharper only towards grazing views. :func:`sharpest_ndf_lobe` returns the
largest ``λ_D`` over the scene's specular materials: their NDF lobes (the renderer's own
``material_lobes``, at the scene's lobe count) at the constant parameters and, for a textured
parameter, at its smallest and largest texel (all combinations), since a texel's lobe is that of
its parameter value. :func:`gamma_reach` adds the clamped cosine's sharpness (the product
``C* ⊗ G`` the lookup is made at is sharper by at most that) to ``max(λ_D, MIN_REACH)``; the
renderer ends its default λ ladder at the first level at or above it
(:meth:`warp_sg.renderer.renderer.Renderer._ensure_gamma`); lookups above the ladder use the prefilter's own
blend towards the source map's filtered texels (:mod:`precompute.environment.prefilter`).
"""
from __future__ import annotations

import itertools

import numpy as np

from warp_sg.scene.model import COLOUR_PARAMS
from warp_sg.sg import CLAMPED_COSINE_SHARPNESS

#: the ladder reaches at least this λ_D (broad lobes: the cost of the levels below is small)
MIN_REACH = 8.0


def _extremes(material) -> list[dict]:
    """Constant parameters for every combination of the textured parameters' extreme texels."""
    choices = []
    for k, tex in material.textures.items():
        if k in COLOUR_PARAMS:
            continue  # kd / ks scale the lobe, they do not shape it
        v = tex.rgba(colour=False)[..., 0]
        choices.append([(k, float(v.min())), (k, float(v.max()))])
    base = dict(material.params)
    for k, tex in material.textures.items():
        if k in COLOUR_PARAMS:
            base[k] = tex.mean(colour=True).tolist()
    return [dict(base, **dict(c)) for c in itertools.product(*choices)] if choices else [base]


def sharpest_ndf_lobe(scene, names=None) -> float:
    """Largest NDF lobe sharpness λ_D of the scene's specular materials (0: none is specular);
    ``names``: the materials to consider (default: those of the scene's geometry)."""
    from warp_sg.brdf import make_model
    from warp_sg.brdf.kernel.material_struct import material_lobes

    n_lobes = int(scene.render.lobes)
    names = set(scene.geometry().material_names if names is None else names)
    top = 0.0
    for name in sorted(names):
        m = scene.materials[name]
        models = [m.brdf] if not m.textures else [make_model(m.model, **p) for p in _extremes(m)]
        for model in models:
            if not getattr(model, "is_specular", False):
                continue
            _, lam, _ = material_lobes(model, n_lobes)
            lam = np.asarray(lam, np.float64).reshape(-1)
            if lam.size:
                top = max(top, float(lam.max()))
    return top


def gamma_reach(scene, names=None) -> float:
    """The sharpness the ΓL ladder must reach for the scene (module docstring); 0 without a
    specular material."""
    lam = sharpest_ndf_lobe(scene, names)
    return max(lam, MIN_REACH) + CLAMPED_COSINE_SHARPNESS if lam > 0 else 0.0


__all__ = ["gamma_reach", "sharpest_ndf_lobe", "MIN_REACH"]
