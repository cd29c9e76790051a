"""Objects that move (issue 30): cost and accuracy of frames after ``set_object_transform``.

    python scripts/moving_accuracy.py [--size 256] [--spp 1024] [--cases ball,blob]

Per case (a 2-triangle floor under the sky EXR with a sun, :mod:`warp_sg.scene.plain_scenes`): ``ball``
rolls across the floor (the icosphere, dynamic), ``blob`` (the lumpy example asset, dynamic) turns
on a turntable. For several poses the precompute never saw, prints the per-region bias of the
frame against the Monte-Carlo reference of the scene at that pose (``r.scene``), and the distance
between the moved object's shadow centroid in ours and in the reference (each against its own
image with the object taken away, :func:`warp_sg.groundtruth.region_error.shadow_centroid`). Then the cost: a
static frame (the camera nudged: raster and shade), a frame after ``set_object_transform``, and a
new ``Renderer`` with a cold cache (its construction and first frame).
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np

import warp_sg as ws
from warp_sg.scene.plain_scenes import write_plain_scene
from warp_sg.groundtruth.region_error import box_reference, region_errors, scene_regions, shadow_centroid
from warp_sg.numeric.rigid_motion import motion_about, rolling, rotation_about

AWAY = np.eye(4)
AWAY[:3, 3] = [400.0, 0.0, 0.0]  # the object taken away (far off the floor)


def poses(case):
    if case == "ball":
        return [("x=+0.6", rolling(0.6)), ("x=-0.9,z=+0.4", rolling(-0.9) @ _shift(0, 0, 0.4)),
                ("x=+1.2,z=-0.5", rolling(1.2) @ _shift(0, 0, -0.5))]
    return [(f"turn {a}°", motion_about(rotation_about([0, 1, 0], a), [0.0, 0.5, 0.0])) for a in (45, 120, 250)]


def _shift(x, y, z):
    M = np.eye(4)
    M[:3, 3] = [x, y, z]
    return M


def _median_frame(r, n=3, nudge=None):
    ts = []
    for i in range(n):
        if nudge is not None:
            nudge(i)
        t = time.perf_counter()
        r.render()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def run_case(case, size, spp, folder):
    sc = ws.load_scene(write_plain_scene(folder, obj="sphere" if case == "ball" else "blob", light="sky", size=size,
                                         dynamic=True))
    r = ws.Renderer(sc)
    r.render()
    o = np.asarray(sc.camera.origin, np.float64)
    reshade = _median_frame(r)
    static = _median_frame(r, nudge=lambda i: r.set_camera(origin=tuple(o + [0.002 * (i + 1), 0, 0])))
    r.set_camera(origin=tuple(o))
    rows = []
    moved_t = []
    for name, M in poses(case):
        r.set_object_transform("object", M)
        t = time.perf_counter()
        img = r.render().copy()
        moved_t.append(time.perf_counter() - t)
        ref = box_reference(r.scene, spp=spp, supersample=4)
        reg = scene_regions(r.scene)
        e = region_errors(img, ref, reg)
        r.set_object_transform("object", AWAY)
        u_ours = r.render().copy()
        u_ref = box_reference(r.scene, spp=spp, supersample=4)
        floor = reg["lit_floor"] | reg["shadow"]
        c_ours, c_ref = shadow_centroid(img, u_ours, floor), shadow_centroid(ref, u_ref, floor)
        rows.append((name, e, float(np.linalg.norm(c_ours - c_ref))))
    # moved frames at steady state (another pose each frame)
    ps = [M for _, M in poses(case)]
    moved = _median_frame(r, n=6, nudge=lambda i: r.set_object_transform("object", ps[i % len(ps)]))
    return rows, (reshade, static), moved, moved_t


def cold_construction(case, size, folder):
    """A new Renderer of the scene at a new pose, with an empty cache: construction + first frame."""
    sc = ws.load_scene(write_plain_scene(folder, obj="sphere" if case == "ball" else "blob", light="sky", size=size))
    from warp_sg.renderer.dynamic_objects import scene_with_transforms  # noqa: F401  (same pose semantics)

    old = os.environ.get("WARP_SG_CACHE_DIR")
    with tempfile.TemporaryDirectory() as cache:
        os.environ["WARP_SG_CACHE_DIR"] = cache
        try:
            t = time.perf_counter()
            ws.Renderer(sc).render()
            return time.perf_counter() - t
        finally:
            if old is None:
                os.environ.pop("WARP_SG_CACHE_DIR", None)
            else:
                os.environ["WARP_SG_CACHE_DIR"] = old


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--cases", default="ball,blob")
    ap.add_argument("--no-cold", action="store_true", help="skip the cold-cache construction")
    a = ap.parse_args()
    print(f"{a.size}² px, reference {a.spp} spp (4×4 box), AA 4\n")
    print("| case | pose | object | lit floor | shadow (leak) | silhouette | shadow centroid Δ (px) |")
    print("|---|---|---|---|---|---|---|")
    costs = []
    for case in a.cases.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            rows, static, moved, first = run_case(case, a.size, a.spp, tmp)
            for name, e, dc in rows:
                sh = e["shadow"]
                leak = f" ({100 * sh['leak']:+.1f} %)" if "leak" in sh else ""
                print(f"| {case} | {name} | {100 * e['object']['bias']:+.1f} % | {100 * e['lit_floor']['bias']:+.1f} % | "
                      f"{100 * sh['bias']:+.1f} %{leak} | {100 * e['silhouette']['bias']:+.1f} % | {dc:.2f} |")
            cold = None if a.no_cold else cold_construction(case, a.size, tmp + "/cold")
            costs.append((case, static, moved, cold))
    print("\n| case | static frame: shaded again / camera nudged (s) | frame after set_object_transform (s) | "
          "ratio to shaded again / nudged | new Renderer, cold cache (s) | cold / moved |")
    print("|---|---|---|---|---|---|")
    for case, (reshade, static), moved, cold in costs:
        c = "—" if cold is None else f"{cold:.1f}"
        rr = "—" if cold is None else f"{cold / moved:.0f}×"
        print(f"| {case} | {reshade:.3f} / {static:.3f} | {moved:.3f} | {moved / reshade:.2f}× / {moved / static:.2f}× "
              f"| {c} | {rr} |")


if __name__ == "__main__":
    main()
