"""Tile-based software triangle rasterizer on NVIDIA Warp (Laine & Karras 2011 structure).

``rasterize(vertices, triangles, camera, device=..., supersample=1, cull_backfaces=False,
coverage_count=False) -> VisibilityBuffer`` (tri_id / bary / depth as ``wp.array``);
``interpolate(vb, triangles, attr)``; ``Camera`` (Mitsuba look_at + vertical fov).
Stages: triangle_setup.py → bin.py → coarse.py → fine.py, orchestrated by rasterize.py; the camera is
the scene's (:mod:`warp_sg.scene.camera`, a plain data class).
"""
from warp_sg.scene.camera import Camera

from .interpolate import interpolate
from .rasterize import VisibilityBuffer, rasterize, tile_grid

__all__ = ["Camera", "VisibilityBuffer", "interpolate", "rasterize", "tile_grid"]
