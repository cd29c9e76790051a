"""precompute: everything cached on disk before rendering (docs/precompute.md): per-vertex visibility by
BVH ray queries, SSDFs with PCA, environment prefiltering and SG mixture fits.

Names load on first use (PEP 562) so importing one step does not compile the others' kernels.
"""
from __future__ import annotations

from warp_sg.lazy import lazy_getattr

_LAZY = {
    "cache": ("precompute.cache", None),
    "cache_dir": ("precompute.cache", "cache_dir"),
    "content_key": ("precompute.cache", "content_key"),
    "load_or_build": ("precompute.cache", "load_or_build"),
    "hemisphere_visibility": ("precompute.visibility", "hemisphere_visibility"),
    "needs_visibility": ("precompute.visibility", "needs_visibility"),
    "SSDFData": ("precompute.ssdf", "SSDFData"),
    "ssdf_for_mesh": ("precompute.ssdf", "ssdf_for_mesh"),
    "compute_ssdf": ("precompute.ssdf", "compute_ssdf"),
    "ray_visibility": ("precompute.visibility", "ray_visibility"),
    "Refinement": ("precompute.refine", "Refinement"),
    "refine_for_visibility": ("precompute.refine", "refine_for_visibility"),
    "refine_cached": ("precompute.refine", "refine_cached"),
    "envmap": ("precompute.envmap", None),
    "load_envmap": ("precompute.envmap", "load_envmap"),
    "procedural_sky": ("precompute.envmap", "procedural_sky"),
    "EnvPrefiltered": ("precompute.prefilter", "EnvPrefiltered"),
    "prefilter_environment": ("precompute.prefilter", "prefilter_environment"),
    "fit_environment_sgs": ("precompute.env_sg_fit", "fit_environment_sgs"),
}


__getattr__ = lazy_getattr(globals(), _LAZY)


__all__ = list(_LAZY)
