"""The rasterizer's camera is the scene's: :class:`warp_sg.camera.Camera` (a plain data class in the
scene layer, Mitsuba 3 ``look_at`` + vertical ``fov``), re-exported here so ``raster.Camera`` and
``raster.camera.Camera`` keep working."""
from warp_sg.camera import Camera

__all__ = ["Camera"]
