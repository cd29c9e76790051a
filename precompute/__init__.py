"""precompute: everything cached on disk before rendering (docs/precompute.md): per-vertex visibility by
BVH ray queries, SSDFs with PCA, environment prefiltering and SG mixture fits.

Sub-packages: ``visibility`` (ray queries, refinement, SSDFs) and ``environment`` (peaks,
irradiance, ΓL prefiltering, SG fit). The names below load on first use (a module ``__getattr__``,
PEP 562) so importing one step does not import the others; ``precompute.cache`` and
``precompute.envmap`` are the base layer's cache (:mod:`warp_sg.core.cache`) and the scene layer's
maps (:mod:`warp_sg.scene.envmap`).
"""
from __future__ import annotations

from warp_sg.core.public_names import lazy_getattr

#: public name -> (module, attribute; None for the module itself)
_PUBLIC = {
    "cache": ("warp_sg.core.cache", None),
    "cache_dir": ("warp_sg.core.cache", "cache_dir"),
    "content_key": ("warp_sg.core.cache", "content_key"),
    "load_or_build": ("warp_sg.core.cache", "load_or_build"),
    "hemisphere_visibility": ("precompute.visibility.rays", "hemisphere_visibility"),
    "needs_visibility": ("precompute.visibility.rays", "needs_visibility"),
    "SSDFData": ("precompute.visibility.ssdf_data", "SSDFData"),
    "ssdf_for_mesh": ("precompute.visibility.ssdf", "ssdf_for_mesh"),
    "compute_ssdf": ("precompute.visibility.ssdf", "compute_ssdf"),
    "ray_visibility": ("precompute.visibility.rays", "ray_visibility"),
    "Refinement": ("precompute.visibility.refine", "Refinement"),
    "refine_for_visibility": ("precompute.visibility.refine", "refine_for_visibility"),
    "refine_cached": ("precompute.visibility.refine", "refine_cached"),
    "envmap": ("warp_sg.scene.envmap", None),
    "load_envmap": ("warp_sg.scene.envmap", "load_envmap"),
    "procedural_sky": ("warp_sg.scene.sky", "procedural_sky"),
    "EnvPrefiltered": ("precompute.environment.prefilter", "EnvPrefiltered"),
    "prefilter_environment": ("precompute.environment.prefilter", "prefilter_environment"),
    "fit_environment_sgs": ("precompute.environment.sg_fit", "fit_environment_sgs"),
}


__getattr__ = lazy_getattr("precompute", _PUBLIC, globals())


__all__ = list(_PUBLIC)
