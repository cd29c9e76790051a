"""``warp-sg bench`` section "objects that move" (:mod:`warp_sg.renderer.dynamic_objects`): what a frame
costs after ``Renderer.set_object_transform``, as ratios.

The scene is the plain-input ball of :mod:`warp_sg.scene.plain_scenes` (icosphere, ``dynamic = true``,
on a 2-triangle floor under the sky EXR with a sun). Rows: a static frame shaded again with nothing
changed (the visibility buffer reused), one with the camera nudged (raster and shading again), a
frame after the ball rolled to a new pose and its ratio to the first (target ≤ 1.5), and a new ``Renderer`` of the scene at that pose with an empty cache
(construction and first frame: what each frame would cost without dynamic objects) over the moved
frame (target ≥ 100).
"""
from __future__ import annotations

import statistics
import tempfile
import time

import numpy as np


def motion_section(device="cpu", quick=False, frames=None):
    import warp_sg as ws

    from warp_sg.core.cache import fresh_cache
    from warp_sg.renderer.dynamic_objects import scene_with_transforms
    from warp_sg.scene.plain_scenes import write_plain_scene
    from warp_sg.numeric.rigid_motion import rolling

    size = 32 if quick else 256
    n = frames or (2 if quick else 5)
    render = {"ssdf_resolution": 16, "pca_terms": 8, "visibility_budget": 1500, "env_lobes": 4} if quick else None
    poses = [rolling(x) for x in np.linspace(-1.0, 1.0, n + 1)]
    with tempfile.TemporaryDirectory() as tmp, fresh_cache():
        scene = ws.load_scene(write_plain_scene(tmp, size=size, dynamic=True, render=render))
        r = ws.Renderer(scene, device=device)
        r.render()
        o = np.asarray(scene.camera.origin, np.float64)
        static, reshade, moved = [], [], []
        for i in range(n):
            t = time.perf_counter()
            r.render()
            reshade.append(time.perf_counter() - t)
        for i in range(n):
            r.set_camera(origin=tuple(o + [1e-3 * (i + 1), 0.0, 0.0]))
            t = time.perf_counter()
            r.render()
            static.append(time.perf_counter() - t)
        for M in poses[1:]:
            r.set_object_transform("object", M)
            t = time.perf_counter()
            r.render()
            moved.append(time.perf_counter() - t)
        fixed = scene_with_transforms(scene, {"object": poses[-1]})
        fixed.objects[0].dynamic = False
        with fresh_cache():
            t = time.perf_counter()
            ws.Renderer(fixed, device=device).render()
            cold = time.perf_counter() - t
    s0, s, m = statistics.median(reshade), statistics.median(static), statistics.median(moved)
    return [{"case": f"static frame, shaded again, {size}²", "frame_s": s0},
            {"case": "static frame, camera nudged", "frame_s": s, "ratio": s / s0},
            {"case": "frame after set_object_transform", "frame_s": m, "ratio": m / s0},
            {"case": "new Renderer at the pose, empty cache", "frame_s": cold, "ratio": cold / m}]


__all__ = ["motion_section"]
