"""A Mitsuba 3 reference image of one of our scenes through the independent peer
(:func:`warp_sg.tools.mitsuba.scene_dict.independent_scene_dict`): the mean of independent batches and
its per-pixel standard error (the spread of the batch means), as ``warp-sg report --truth mitsuba``,
``scripts/mitsuba_refs.py`` and the accuracy matrix use it."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .variant import MIN_LLVM, llvm_problem

#: the variants tried, fastest first (llvm needs a system libLLVM; scalar runs anywhere)
VARIANTS = ("llvm_ad_rgb", "scalar_rgb")


@dataclass
class MitsubaImage:
    image: np.ndarray  # (H, W, 3) float32, the batches' mean
    stderr: np.ndarray  # (H, W, 3) float32, its standard error
    spp: int
    seconds: float
    variant: str


def set_fastest_variant(preferred: str | None = None) -> str:
    """Set and return ``preferred`` or the fastest usable variant of :data:`VARIANTS`."""
    import mitsuba as mi

    for v in (preferred,) if preferred else VARIANTS:
        if v.startswith("llvm"):
            why = llvm_problem(v)
            if why is None:
                return v
            if preferred:
                raise RuntimeError(f"Mitsuba variant {v} unusable: {why}")
            continue
        mi.set_variant(v)
        return v
    raise RuntimeError("no Mitsuba variant is usable")


def mitsuba_reference(scene, spp: int, max_depth: int = 2, batches: int = 8, seed: int = 0,
                      variant: str | None = None) -> MitsubaImage:
    """Render ``scene`` with Mitsuba in ``batches`` independent batches of ``spp // batches`` samples."""
    import mitsuba as mi

    from .scene_dict import independent_scene_dict

    v = set_fastest_variant(variant)
    batches = max(2, int(batches))
    per = max(1, int(spp) // batches)
    t0 = time.perf_counter()
    msc = mi.load_dict(independent_scene_dict(scene, spp=per, max_depth=max_depth))
    imgs = np.stack([np.array(mi.render(msc, spp=per, seed=seed + 7919 * b), dtype=np.float64)
                     for b in range(batches)])
    mean = imgs.mean(0)
    se = imgs.std(0, ddof=1) / np.sqrt(batches)
    return MitsubaImage(mean.astype(np.float32), se.astype(np.float32), per * batches, time.perf_counter() - t0, v)


__all__ = ["MitsubaImage", "mitsuba_reference", "set_fastest_variant", "llvm_problem", "VARIANTS", "MIN_LLVM"]
