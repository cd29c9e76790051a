"""The watchdog's checks of a whole frame (:mod:`warp_sg.core.watchdog`), run by
:class:`warp_sg.renderer.renderer.Renderer` before its first precompute step: the raster samples of the frame,
the SSDF matrix the precompute would build (at the refined vertex count) and the ΓL pyramid's cube
texels, and the rasterizer's limit per axis (``raster.triangle_setup.MAX_RESOLUTION``). Each refusal is one
:class:`~warp_sg.core.errors.SceneError` line naming the size and the
settings that make it. (Triangles, textures and environment maps are bounded where they are read.)
"""
from __future__ import annotations

from warp_sg.core.errors import SceneError
from warp_sg.core.watchdog import MAX_PREFILTER_TEXELS, MAX_SAMPLES, MAX_SSDF_ENTRIES, check_size


def check_frame_costs(scene, geometry, *, shadows: bool, specular: bool) -> None:
    """Refuse a frame of ``scene`` whose raster, SSDF precompute (``shadows``) or ΓL prefilter
    (``specular`` materials under an environment) would exceed the watchdog's bounds."""
    from raster.triangle_setup import MAX_RESOLUTION

    rs, cam = scene.render, scene.camera
    k = int(rs.supersampling)
    for name, n in (("width", cam.width), ("height", cam.height)):
        if n * k > MAX_RESOLUTION:
            raise SceneError(f"{name} {n} × supersampling {k} = {n * k} pixels: the rasterizer takes at most "
                             f"{MAX_RESOLUTION} per axis", where="[camera]")
    check_size("the frame", cam.width * cam.height * k * k, MAX_SAMPLES,
               f"{cam.width}×{cam.height} pixels × supersampling {k}²", "samples", where="[camera]", error=SceneError)
    if shadows:
        v = max(len(geometry.vertices), int(rs.visibility_budget))
        r = int(rs.ssdf_resolution)
        check_size("the SSDF precompute", v * r * r, MAX_SSDF_ENTRIES,
                   f"{v:,} vertices (visibility_budget, or the mesh's own) × ssdf_resolution {r}²", "entries",
                   where="[render]", error=SceneError)
    env = scene.environment
    if env is not None and specular:
        from precompute.environment.prefilter import default_ladder

        lams, sizes, _ = default_ladder(env.base_radiance().shape[0], base_face=rs.gamma_resolution)
        if rs.gamma_levels > 0:  # the same λ range in gamma_levels steps: no face larger than the ladder's
            texels, detail = 6 * rs.gamma_levels * int(max(sizes)) ** 2, f"6 × {rs.gamma_levels} levels × {max(sizes)}²"
        else:
            texels, detail = 6 * int(sum(int(n) ** 2 for n in sizes)), f"6 faces × Σ N² over {len(sizes)} levels"
        check_size("the ΓL prefilter", texels, MAX_PREFILTER_TEXELS,
                   f"{detail} (gamma_levels {rs.gamma_levels}, gamma_resolution {rs.gamma_resolution})", "cube texels",
                   where="[render]", error=SceneError)


__all__ = ["check_frame_costs"]
