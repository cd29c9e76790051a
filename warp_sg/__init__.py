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
``warp_sg.core.errors`` and ``warp_sg.sg`` without an import cycle.
"""
from __future__ import annotations

from warp_sg.core import errors
from warp_sg import sg
from .core.errors import InputError
from .lazy import lazy_getattr

__version__ = "0.1.0"

_LAZY = {
    "brdf": ("warp_sg.brdf", None),
    "Scene": ("warp_sg.scene", "Scene"),
    "load_scene": ("warp_sg.scene", "load_scene"),
    "render": ("warp_sg.renderer.renderer", "render"),
    "Renderer": ("warp_sg.renderer.renderer", "Renderer"),
    "reference": ("warp_sg.groundtruth.reference", "reference"),
    "save_image": ("warp_sg.core.image_io", "save_image"),
    "load_image": ("warp_sg.core.image_io", "load_image"),
}


__getattr__ = lazy_getattr(globals(), _LAZY)


__all__ = ["errors", "sg", "InputError", *_LAZY]
