"""CUDA checks that need a GPU (run by scripts/gpu_check.sh on a machine with one).

    python scripts/gpu_check.py agree       # CPU vs CUDA: render and reference on three scenes
    python scripts/gpu_check.py fps         # 1080p, ~1 M triangles, full shading: frames per second

Prints one line per measurement; exits 1 when an agreement check fails.
"""
from __future__ import annotations

import sys
import tempfile
import time

import numpy as np


def agree() -> int:
    import warp_sg as ws
    from warp_sg.scene.plain_scenes import write_plain_scene

    bad = 0
    for case in ("sphere:sky:lambert", "sphere:point:ward", "blob:sky:blinn_phong"):
        obj, light, mat = case.split(":")
        with tempfile.TemporaryDirectory() as d:
            path = write_plain_scene(d, obj=obj, light=light, material=mat, size=96)
            a = ws.render(ws.load_scene(path), device="cpu")
            b = ws.render(ws.load_scene(path), device="cuda")
            rel = float(np.sum((a - b) ** 2) / np.sum(a ** 2))
            ra = ws.reference(ws.load_scene(path), spp=64, device="cpu", progress=False)
            rb = ws.reference(ws.load_scene(path), spp=64, device="cuda", progress=False)
            rel_ref = abs(float(rb.mean() / ra.mean()) - 1.0)
            ok = rel < 1e-4 and rel_ref < 0.02
            bad += not ok
            print(f"{'ok  ' if ok else 'FAIL'} {case}: render cpu/cuda rel. MSE {rel:.2e}; "
                  f"reference mean ratio off by {100 * rel_ref:.2f} %")
    return 1 if bad else 0


def fps() -> int:
    import trimesh

    import warp_sg as ws
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import EnvironmentLight, PointLight
    from warp_sg.scene.model import Scene, SceneObject
    from warp_sg.scene.render_settings import RenderSettings

    knot = trimesh.creation.torus(major_radius=0.6, minor_radius=0.25, major_sections=1000, minor_sections=500)
    V, F = np.asarray(knot.vertices), np.asarray(knot.faces)
    V[:, 1] += 0.3
    cam = Camera(origin=(0.0, 1.5, 3.0), target=(0.0, 0.3, 0.0), fov=40.0, width=1920, height=1080)
    sc = Scene(camera=cam,
               objects=[SceneObject(material="m", vertices=V, triangles=F),
                        SceneObject(material="floor", primitive="plane", params={"size": (6.0, 6.0)})],
               materials={"m": ws.brdf.CookTorrance(kd=0.2, ks=0.8, m=0.2), "floor": ws.brdf.Lambert(kd=0.6)},
               lights=[EnvironmentLight(procedural="sky"), PointLight(position=(2, 3, 1), radius=0.2, intensity=8.0),
                       PointLight(position=(-2, 2.5, 2), radius=0.2, intensity=5.0)],
               render=RenderSettings(shadows=True, visibility_budget=0, device="cuda"))
    t = time.perf_counter()
    r = ws.Renderer(sc, device="cuda")
    nv = len(r.geometry.vertices)
    ssdf_s = r.timings["precompute_parts"].get("ssdf", float("nan"))
    print(f"precompute {time.perf_counter() - t:.1f} s for {nv} vertices, {len(r.geometry.triangles)} triangles; "
          f"SSDF {ssdf_s:.1f} s = {nv / ssdf_s:,.0f} vertices/s (32² maps from 64² rays, PCA included; target 50 k)")
    r.render()
    times = []
    o = np.asarray(cam.origin, np.float64)
    for i in range(10):  # a new view every frame: raster + shading (the camera nudged back and forth)
        r.set_camera(origin=tuple(o + (0.0, 0.0, 1e-3 * ((i % 2) * 2 - 1))))
        r.render()
        times.append(r.timings["frame"])
    f = float(np.median(times))
    print(f"1920x1080 full shading: {1000 * f:.1f} ms/frame = {1 / f:.1f} fps "
          f"(raster {1000 * r.timings['raster']:.1f} ms, shade {1000 * r.timings['shade']:.1f} ms)")
    return 0


if __name__ == "__main__":
    sys.exit({"agree": agree, "fps": fps}[sys.argv[1]]())
