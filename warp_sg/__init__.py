"""warp-sg: all-frequency rendering of dynamic, spatially-varying reflectance with spherical
Gaussians (Wang et al. 2009) on NVIDIA Warp.

Public interface (docs/architecture.md "Public interface")::

    import warp_sg as ws
    scene = ws.load_scene("scene.toml")
    img = ws.render(scene, device="cpu")
    ref = ws.reference(scene, spp=256, device="cpu")
    ws.save_image("out.exr", img)

The sub-packages are the layers, bottom to top: ``core`` (base), ``numeric``, ``sg``, ``brdf``
(math), ``scene`` (with ``scene.importers``), ``shading`` (engines, with the top-level packages
``raster`` and ``precompute``), ``renderer`` and ``groundtruth`` (render), ``tools`` and
``distributed`` and ``inverse`` (tools). ``errors``, ``sg`` and ``InputError`` load with the package; the names of
:data:`_PUBLIC` load on first use (a module ``__getattr__``, PEP 562): the renderer imports
``raster`` and ``precompute``, which import ``warp_sg.core``, so importing them here eagerly
would run inside their own import.
"""
from __future__ import annotations

from warp_sg import sg
from warp_sg.core import errors
from warp_sg.core.errors import InputError
from warp_sg.core.public_names import lazy_getattr

__version__ = "0.1.0"

#: public name -> (module, attribute; None for the module itself)
_PUBLIC = {
    "brdf": ("warp_sg.brdf", None),
    "Scene": ("warp_sg.scene.model", "Scene"),
    "load_scene": ("warp_sg.scene.loader", "load_scene"),
    "render": ("warp_sg.renderer.renderer", "render"),
    "Renderer": ("warp_sg.renderer.renderer", "Renderer"),
    "reference": ("warp_sg.groundtruth.reference", "reference"),
    "save_image": ("warp_sg.core.image_io", "save_image"),
    "load_image": ("warp_sg.core.image_io", "load_image"),
    "fit": ("warp_sg.inverse.fit", "fit"),
}


__getattr__ = lazy_getattr("warp_sg", _PUBLIC, globals())


__all__ = ["errors", "sg", "InputError", *_PUBLIC]
