"""Objects that move (issue 30): cost and accuracy of frames after ``set_object_transform``.

    python scripts/moving_accuracy.py [--size 256] [--spp 1024] [--cases ball,blob,bunny]

Per case (a 2-triangle floor under the sky EXR with a sun, :mod:`warp_sg.scene.plain_scenes`): ``ball``
rolls across the floor (the icosphere, dynamic), ``blob`` (the lumpy example asset) and ``bunny``
(warp-lang's Stanford bunny, USD: ``pip install warp-sg[usd]``) turn on a turntable. For several
poses the precompute never saw, the animation report (:func:`warp_sg.tools.report_animation.run_animation_report`,
what ``warp-sg report SCENE --animation JOB.toml`` runs) gives the per-region bias of the frame against
the Monte-Carlo reference of the scene at that pose, and the distance between the moved object's
shadow centroid in ours and in the reference (each against its own image with the object taken
away); its files go to ``--out``/CASE. Then the cost: a static frame (the camera nudged: raster and
shade), a frame after ``set_object_transform``, and a new ``Renderer`` with a cold cache (its
construction and first frame).
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np

import warp_sg as ws
from warp_sg.numeric.rigid_motion import motion_about, rolling, rotation_about
from warp_sg.scene.plain_scenes import write_plain_scene
from warp_sg.tools.report_animation import run_animation_report

OBJECTS = {"ball": "sphere", "blob": "blob", "bunny": "bunny"}


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


def run_case(case, size, spp, folder, out):
    sc = ws.load_scene(write_plain_scene(folder, obj=OBJECTS[case], light="sky", size=size, dynamic=True))
    obj = next(i for i, ob in enumerate(sc.objects) if ob.dynamic)
    named = poses(case)
    rep = run_animation_report(sc, [{"objects": {obj: {"matrix": M.tolist()}}} for _, M in named], out, spp=spp,
                               supersample=4, progress=False)
    rows = [(name, row) for (name, _), row in zip(named, rep.rows)]
    r = ws.Renderer(sc)  # the costs (the precompute is in the cache now)
    r.render()
    o = np.asarray(sc.camera.origin, np.float64)
    reshade = _median_frame(r)
    static = _median_frame(r, nudge=lambda i: r.set_camera(origin=tuple(o + [0.002 * (i + 1), 0, 0])))
    r.set_camera(origin=tuple(o))
    # moved frames at steady state (another pose each frame)
    ps = [M for _, M in named]
    moved = _median_frame(r, n=6, nudge=lambda i: r.set_object_transform(obj, ps[i % len(ps)]))
    return rows, (reshade, static), moved


def cold_construction(case, size, folder):
    """A new Renderer of the scene at a new pose, with an empty cache: construction + first frame."""
    sc = ws.load_scene(write_plain_scene(folder, obj=OBJECTS[case], light="sky", size=size))

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
    ap.add_argument("--cases", default="ball,blob", help="comma-separated: ball, blob, bunny")
    ap.add_argument("--out", default="out/moving_accuracy", help="the animation reports, one folder per case")
    ap.add_argument("--no-cold", action="store_true", help="skip the cold-cache construction")
    a = ap.parse_args()
    print(f"{a.size}² px, reference {a.spp} spp (4×4 box), AA 4\n")
    print("| case | pose | object | lit floor | shadow (leak) | silhouette | shadow centroid Δ (px) |")
    print("|---|---|---|---|---|---|---|")
    costs = []
    for case in a.cases.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            rows, static, moved = run_case(case, a.size, a.spp, tmp, os.path.join(a.out, case))
            for name, e in rows:
                print(f"| {case} | {name} | {100 * e['object_bias']:+.1f} % | {100 * e['lit_floor_bias']:+.1f} % | "
                      f"{100 * e['shadow_bias']:+.1f} % ({100 * e['shadow_leak']:+.1f} %) | "
                      f"{100 * e['silhouette_bias']:+.1f} % | {e['centroid_px']:.2f} |")
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
