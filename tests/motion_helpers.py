"""Helpers of the moving-object tests: the benchmark scene's bunny as a mesh, and one step of a
scripted sequence (an object moved or the camera moved) applied to a renderer."""
from __future__ import annotations

import numpy as np
import pytest


def bunny_mesh(folder):
    """The bunny of the benchmark scene (``write_plain_scene(obj="bunny")``): vertices, triangles."""
    pytest.importorskip("pxr", reason="usd-core is not installed (pip install warp-sg[usd])")
    import warp_sg as ws
    from warp_sg.scene.plain_scenes import write_plain_scene

    g = ws.load_scene(write_plain_scene(folder, obj="bunny", size=8, dynamic=True)).geometry()
    T = np.asarray(g.triangles, np.int64)[np.asarray(g.tri_object) == 0]
    ids = np.unique(T)
    return np.asarray(g.vertices, np.float64)[ids], np.searchsorted(ids, T)


def apply_step(renderer, kind: str, value) -> None:
    """``("move", 4×4 matrix)``: the object named "object" moved; ``("camera", origin)``: the camera
    moved; anything else: nothing."""
    if kind == "move":
        renderer.set_object_transform("object", value)
    elif kind == "camera":
        renderer.set_camera(origin=value)
