"""Equirectangular environment maps — the map convention, lookups, rotation, loading and the
procedural sky live in the scene layer (:mod:`warp_sg.envmap`: lights and scenes read maps without
importing an engine); this module re-exports every name, the ``@wp.func`` lookups included (the
same objects, so kernels may use either)."""
from warp_sg.envmap import (
    PI,
    TWO_PI,
    dir_to_texel,
    dir_to_uv,
    downsample_envmap,
    env_lookup,
    env_lookup_nearest,
    env_lookup_numpy,
    load_envmap,
    procedural_sky,
    rotate_envmap,
    rotation_matrix,
    rotation_y,
    row_solid_angles,
    sky_radiance,
    texel_directions,
    texel_solid_angles,
    uv_to_dir,
    validate_envmap,
    wp_dir_to_uv,
    wp_uv_to_dir,
)

__all__ = [
    "load_envmap",
    "validate_envmap",
    "procedural_sky",
    "sky_radiance",
    "dir_to_uv",
    "dir_to_texel",
    "uv_to_dir",
    "texel_directions",
    "row_solid_angles",
    "texel_solid_angles",
    "downsample_envmap",
    "rotation_matrix",
    "rotation_y",
    "rotate_envmap",
    "env_lookup_numpy",
    "wp_dir_to_uv",
    "wp_uv_to_dir",
    "env_lookup",
    "env_lookup_nearest",
]
