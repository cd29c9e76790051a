r"""The watchdog: every step whose time or memory grows with the size of an input has a bound on
that size, checked before the step's work starts; input over the bound is refused with one line
naming the size and the bound (never a hang, never a machine out of memory).

==========================  ===================================  ===================  ==========================================
step                        size                                 bound                what grows with it
==========================  ===================================  ===================  ==========================================
environment map             H × W texels (file header)           2^27 = 16384 × 8192  load, peak extraction, SG fit and ΓL input:
                                                                                      ~80 B a texel at the peak step (float64)
texture                     H × W texels (file header)           2^27                 the RGBA float32 atlas: 16 B a texel
mesh                        triangles of the scene               2^25 (33.5 M)        validation, orientation, BVH, refinement,
                                                                                      raster: a few hundred B a triangle
SSDF precompute             vertices × ssdf_resolution²          2^31                 the SSDF matrix before PCA, 4 B an entry
                            (the refined count: ``max(V,                              (8 GiB); rays ∝ it
                            visibility_budget)``)
ΓL prefilter                cube texels ``6 Σ N_k²`` of the      2^27                 the pyramid (12 B a texel) and its
                            λ ladder                                                  quadrature
raster + shading            width · height · supersampling²      2^27                 the G-buffer and the shading, tens of B a
                                                                                      sample
==========================  ===================================  ===================  ==========================================

A 16k × 8k map, a 1 M-triangle mesh and a 4k image are within every bound; a 1e9-texel
texture is refused when its header is read, a 2 × 20000 map by its aspect
(:func:`warp_sg.scene.envmap.check_envmap_shape`). The bounds are where this machine class (2 cores,
24 GiB) still finishes in minutes, not hours; they are constants of this module, documented in
``docs/rendering.md`` ("Sizes the renderer refuses").

Within its bound a map is also **reduced** when it is larger than :data:`MAX_ENV_WORK_TEXELS`
(4096 × 2048): read, checked, then averaged down by whole texel blocks, weighted by solid angle so
that its light (∑ L Ω over every block, and over the sphere) is kept
(:func:`warp_sg.scene.envmap.reduce_envmap`), with one warning saying to what size. The steps
after loading — peaks, the SG fit, ΓL, the reference's sampling tables — hold several float64
copies of the map (~80 B a texel at the peak step): a 16k × 8k map (134 M texels) would need
over 10 GiB there and was killed by the kernel on a 24 GiB machine. Reading it peaks at about
two float32 copies (3.2 GiB for 16k × 8k) before the reduction.
"""
from __future__ import annotations

from warp_sg.core.errors import InputError

#: texels of an environment map (16384 × 8192)
MAX_ENV_TEXELS = 1 << 27
#: texels of an environment map the steps after loading work on (4096 × 2048): larger maps are
#: reduced to it at load, with one warning
MAX_ENV_WORK_TEXELS = 1 << 23
#: texels of one texture
MAX_TEXTURE_TEXELS = 1 << 27
#: triangles of a scene (after flattening every object)
MAX_TRIANGLES = 1 << 25
#: entries of the SSDF matrix before PCA: vertices × ssdf_resolution²
MAX_SSDF_ENTRIES = 1 << 31
#: texels of the ΓL pyramid's cube maps, 6 Σ N_k²
MAX_PREFILTER_TEXELS = 1 << 27
#: raster samples of a frame: width · height · supersampling²
MAX_SAMPLES = 1 << 27


def check_size(what: str, size: int, bound: int, detail: str, unit: str, *, where: str | None = None,
               error: type = InputError) -> None:
    """Refuse ``size`` over ``bound``: ``error`` (an :class:`~warp_sg.core.errors.InputError` type) with
    ``"<what> is <detail>: <size> <unit>; at most <bound> <unit> are accepted (...)"``."""
    size, bound = int(size), int(bound)
    if size > bound:
        raise error(f"{what} is {detail}: {size:,} {unit}; at most {bound:,} {unit} are accepted (a bound of "
                    f"warp_sg.core.watchdog: beyond it the work would not finish in reasonable time or memory)",
                    where=where)


__all__ = ["MAX_ENV_TEXELS", "MAX_ENV_WORK_TEXELS", "MAX_TEXTURE_TEXELS", "MAX_TRIANGLES", "MAX_SSDF_ENTRIES", "MAX_PREFILTER_TEXELS",
           "MAX_SAMPLES", "check_size"]
