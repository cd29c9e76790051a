"""A Mitsuba 3 reference image of one of our scenes through the independent peer
(:func:`warp_sg.tools.mitsuba.scene_dict.independent_scene_dict`): the mean of independent batches and
its per-pixel standard error (the spread of the batch means), as ``warp-sg report --truth mitsuba``,
``scripts/mitsuba_refs.py`` and the accuracy matrix use it."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

#: the variants tried, fastest first (llvm needs a system libLLVM; scalar runs anywhere)
VARIANTS = ("llvm_ad_rgb", "scalar_rgb")
#: the oldest system libLLVM the LLVM variants are used with: with LLVM 14 and 15 (Debian 12's default)
#: Dr.Jit's first kernel that takes a minimum aborts the whole process ("Cannot select fminimum"),
#: which no exception reports; 19 (Debian: libllvm19) runs every kernel here
MIN_LLVM = (19, 0, 0)


def llvm_problem(variant: str = "llvm_ad_rgb") -> str | None:
    """None when Mitsuba's LLVM ``variant`` can be set and runs here; else why not, in a few words
    (no libLLVM found, one older than :data:`MIN_LLVM`, or a kernel that fails)."""
    import mitsuba as mi

    try:
        mi.set_variant(variant)
        import drjit as dr

        version = getattr(dr.detail, "llvm_version", lambda: None)()
        if version is not None and tuple(version)[:1] == (0,):
            return "no system libLLVM found"
        if version is not None and tuple(version) < MIN_LLVM:
            return (f"system libLLVM {'.'.join(map(str, version))} is older than {MIN_LLVM[0]}, with which "
                    f"Mitsuba's kernels abort the process (Debian: apt install libllvm19; DRJIT_LIBLLVM_PATH "
                    f"names the library)")
        dr.eval(mi.Float([1.0]) * 2.0)
    except Exception as e:  # noqa: BLE001 - a missing or unusable libLLVM, in any exception type
        return f"{type(e).__name__}: {e}"
    return None


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
