"""Scene layer, importers: glTF 2.0 assets (``gltf``, ``gltf_checks``, ``gltf_material``) and USD
stages (``usd``, ``usd_material``) as scene objects, and the scene made around one asset file
(``asset``). :func:`scene_asset_reader` picks the reader of a ``mesh`` file that brings its own
scene graph and materials."""
from __future__ import annotations

from pathlib import Path


def scene_asset_reader(path):
    """``gltf_object_parts`` for a .glb/.gltf, ``usd_object_parts`` for a USD file (both
    ``(path, label, *, materials) -> (parts, material specs)``), else None (a plain mesh file)."""
    suffix = Path(str(path)).suffix.lower()
    from warp_sg.scene.importers.gltf import GLTF_SUFFIXES, gltf_object_parts
    from warp_sg.scene.importers.usd import USD_SUFFIXES, usd_object_parts

    if suffix in GLTF_SUFFIXES:
        return gltf_object_parts
    if suffix in USD_SUFFIXES:
        return usd_object_parts
    return None


def material_suffixes() -> tuple:
    """The suffixes of the files :func:`scene_asset_reader` reads (glTF, then USD)."""
    from warp_sg.scene.importers.gltf import GLTF_SUFFIXES
    from warp_sg.scene.importers.usd import USD_SUFFIXES

    return GLTF_SUFFIXES + USD_SUFFIXES


def brings_materials(path) -> bool:
    """A ``mesh`` file whose materials the object may use (glTF, USD): ``material`` is optional."""
    return scene_asset_reader(path) is not None
