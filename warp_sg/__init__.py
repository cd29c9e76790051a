"""warp-sg: all-frequency rendering of dynamic, spatially-varying reflectance with spherical
Gaussians (Wang et al. 2009) on NVIDIA Warp.

Public interface (docs/architecture.md "Public interface")::

    import warp_sg as ws
    scene = ws.load_scene("scene.toml")
    img = ws.render(scene, device="cpu")
    ref = ws.reference(scene, spp=256, device="cpu")
    ws.save_image("out.exr", img)

The light modules (``errors``, ``sg``, ``brdf``) load eagerly; the renderer, reference and scene
loading load on first use (PEP 562), so ``raster`` and ``precompute`` can import
``warp_sg.errors`` and ``warp_sg.sg`` without an import cycle.
"""
from __future__ import annotations

from . import errors, sg
from .errors import InputError
from .lazy import lazy_getattr

__version__ = "0.1.0"

_LAZY = {
    "brdf": ("warp_sg.brdf", None),
    "Scene": ("warp_sg.scene", "Scene"),
    "load_scene": ("warp_sg.scene", "load_scene"),
    "render": ("warp_sg.render", "render"),
    "Renderer": ("warp_sg.render", "Renderer"),
    "reference": ("warp_sg.reference", "reference"),
    "save_image": ("warp_sg.image_io", "save_image"),
    "load_image": ("warp_sg.image_io", "load_image"),
}


__getattr__ = lazy_getattr(globals(), _LAZY)


__all__ = ["errors", "sg", "InputError", *_LAZY]
