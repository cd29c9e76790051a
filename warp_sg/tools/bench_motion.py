"""``warp-sg bench`` section "objects that move" (:mod:`warp_sg.renderer.dynamic_objects`): what a frame
costs after ``Renderer.set_object_transform``, as ratios measured in one run.

Two scenes of :mod:`warp_sg.scene.plain_scenes` (a 2-triangle floor under the sky EXR with a sun):
the **ball** (icosphere, ``dynamic = true``, convex: no self-shadow) rolls across the floor, the
**blob** (the lumpy example asset, ``dynamic = true``, shadows itself) and the **bunny**
(warp-lang's Stanford bunny, 12 200 triangles, refined to 12.9 k moving vertices; skipped where
the installation lacks the USD file or its reader) turn on a turntable (``--quick``: the ball
alone, 32²). Per scene, after a first frame:

* a frame after ``set_object_transform`` (a new pose each time) alternates with a static frame
  shaded again (nothing changed: the visibility buffer reused), so that both see the same load;
  ``vs_reshade`` is the ratio of their medians (the target: ≤ 1.5 with ``[render] bounces = 0``; with
  bounces a move also casts the gather rows it changes again, :mod:`precompute.visibility.gather_pose`:
  4–6× at 256², docs/benchmarks.md "Light that bounces");
* static frames with the camera nudged (raster and shading again): ``vs_nudged``;
* a new ``Renderer`` of the scene at the last pose, the object static, with an empty cache (its
  construction and first frame: what each frame would cost without dynamic objects):
  ``cold_over_moved`` (the target: ≥ 100).

The moved row also gives the medians of its raster (``Renderer.timings["raster"]``: the moving
objects drawn over the static ones' buffer, and the antialiasing's sub-pixels), of writing the
transforms (``motion``) and of the moved vertices' cache rows (``motion_caches``), and the CPU
seconds of both frames (``cpu_s``, ``time.process_time``). The last row
notes the load average over the run (a shared machine's wall times are noisy; the ratios of
alternated frames much less so).
"""
from __future__ import annotations

import os
import statistics
import tempfile
import time

import numpy as np


def _poses(case: str, n: int) -> list:
    from warp_sg.numeric.rigid_motion import motion_about, rolling, rotation_about

    if case == "ball":
        return [rolling(x) for x in np.linspace(-1.0, 1.0, n)]
    return [motion_about(rotation_about([0.0, 1.0, 0.0], a), [0.0, 0.5, 0.0]) for a in np.linspace(20.0, 340.0, n)]


def _timed(r) -> tuple[float, dict]:
    c, t = time.process_time(), time.perf_counter()
    r.render()
    tm = dict(r.timings)
    tm["cpu"] = time.process_time() - c
    return time.perf_counter() - t, tm


def _case(case: str, size: int, n: int, render, device) -> list[dict]:
    import warp_sg as ws
    from warp_sg.core.cache import fresh_cache
    from warp_sg.renderer.dynamic_objects import scene_with_transforms
    from warp_sg.scene.plain_scenes import write_plain_scene

    poses = _poses(case, n)
    with tempfile.TemporaryDirectory() as tmp:
        scene = ws.load_scene(write_plain_scene(tmp, obj={"ball": "sphere"}.get(case, case), size=size,
                                                dynamic=True, render=render))
        obj = next(i for i, ob in enumerate(scene.objects) if ob.dynamic)
        r = ws.Renderer(scene, device=device)
        r.render()
        o = np.asarray(scene.camera.origin, np.float64)
        nudged = []
        for i in range(n):
            r.set_camera(origin=tuple(o + [1e-3 * (i + 1), 0.0, 0.0]))
            nudged.append(_timed(r)[0])
        r.set_camera(origin=tuple(o))
        r.render()
        moved, reshade, parts, cpu0 = [], [], [], []
        for M in poses:  # alternated: the same load on both
            r.set_object_transform(obj, M)
            t, tm = _timed(r)
            moved.append(t)
            parts.append(tm)
            t, tm = _timed(r)
            reshade.append(t)
            cpu0.append(tm["cpu"])
        fixed = scene_with_transforms(scene, {obj: poses[-1]})
        fixed.objects[obj].dynamic = False
        with fresh_cache():
            t = time.perf_counter()
            ws.Renderer(fixed, device=device).render()
            cold = time.perf_counter() - t
    s0, s, m = statistics.median(reshade), statistics.median(nudged), statistics.median(moved)
    med = lambda key: statistics.median(p.get(key, 0.0) for p in parts)  # noqa: E731
    label = f"{case} ({int(r.dynamic.all_ids.shape[0])} moving vertices), {size}²"
    return [{"case": f"{label}: static frame, shaded again", "frame_s": s0, "cpu_s": statistics.median(cpu0)},
            {"case": f"{label}: static frame, camera nudged", "frame_s": s},
            {"case": f"{label}: frame after set_object_transform", "frame_s": m, "vs_reshade": m / s0,
             "vs_nudged": m / s, "raster_s": med("raster"), "motion_s": med("motion"),
             "motion_caches_s": med("motion_caches"), "cpu_s": med("cpu")},
            {"case": f"{label}: new Renderer at the pose, empty cache", "frame_s": cold, "cold_over_moved": cold / m}]


def _bunny_available() -> bool:
    try:
        import pxr  # noqa: F401

        from warp_sg.scene.plain_scenes import warp_bunny

        warp_bunny()
    except Exception:  # noqa: BLE001 - any missing piece skips the case
        return False
    return True


def motion_section(device="cpu", quick=False, frames=None):
    size = 32 if quick else 256
    n = frames or (3 if quick else 9)
    render = {"ssdf_resolution": 16, "pca_terms": 8, "visibility_budget": 1500, "env_lobes": 4} if quick else None
    load0 = os.getloadavg()[0]
    rows = []
    for case in (("ball",) if quick else ("ball", "blob", "bunny")):
        if case == "bunny" and not _bunny_available():
            rows.append({"case": "bunny", "note": "skipped: no bunny.usd in warp-lang or no USD reader "
                                                  "(pip install warp-sg[usd])"})
            continue
        rows += _case(case, size, n, render, device)
    return rows + [{"case": "setup", "note": f"{n} poses per scene; load average {load0:.1f} → "
                                             f"{os.getloadavg()[0]:.1f} (1 min) over the run"}]


__all__ = ["motion_section"]
