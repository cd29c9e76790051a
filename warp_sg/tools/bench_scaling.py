r"""``warp-sg bench`` section "frame scaling": how a warm frame's time grows with pixels and with
triangles, full shading (environment SG mixture + ΓL specular, two spherical point lights, SSDF
shadows, antialiasing as configured).

The scene (:func:`scaling_scene`) is a Cook–Torrance torus of about N triangles over a Lambert floor
under the procedural sky. A frame's cost does not depend on what the SSDFs contain, only on their
layout (``pca_terms`` PCA terms of an R×R map per lookup), so the SSDFs are precomputed cheaply
(R = 8 from 16² rays per vertex) with the default number of PCA terms; see docs/benchmarks.md
"Frame scaling" for the precompute at full resolution.

Two times per row, medians of warm frames: **new view** (the camera moves every frame: rasterise
and shade) and **re-shade** (same camera, a material or light edit: the visibility buffer is
reused and only shading runs).
"""
from __future__ import annotations

import statistics
import time

import numpy as np


def scaling_scene(n_triangles: int, size: int, device: str = "cpu"):
    """The scaling scene with a torus of ≈ ``n_triangles`` triangles, rendered at size × size."""
    import trimesh

    from warp_sg import brdf as B
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import EnvironmentLight, PointLight
    from warp_sg.scene.model import Scene, SceneObject
    from warp_sg.scene.render_settings import RenderSettings

    minor = max(3, int(round(np.sqrt(n_triangles / 8.0))))
    major = max(3, int(round(n_triangles / (2.0 * minor))))
    torus = trimesh.creation.torus(major_radius=0.6, minor_radius=0.25, major_sections=major, minor_sections=minor)
    V = np.asarray(torus.vertices, np.float64) + np.array([0.0, 0.3, 0.0])
    F = np.asarray(torus.faces, np.int64)
    cam = Camera(origin=(0.0, 1.5, 3.0), target=(0.0, 0.3, 0.0), fov=40.0, width=int(size), height=int(size))
    return Scene(camera=cam,
                 objects=[SceneObject(material="metal", vertices=V, triangles=F),
                          SceneObject(material="floor", primitive="plane",
                                      params={"size": (6.0, 6.0), "resolution": (16, 16)})],
                 materials={"metal": B.CookTorrance(kd=[0.1, 0.08, 0.05], ks=[4.0, 3.0, 1.5], m=0.2),
                            "floor": B.Lambert(kd=[0.6, 0.6, 0.6])},
                 lights=[EnvironmentLight(procedural="sky"),
                         PointLight(position=(2.0, 3.0, 1.0), radius=0.2, intensity=(8.0, 8.0, 8.0)),
                         PointLight(position=(-2.0, 2.5, 2.0), radius=0.2, intensity=(5.0, 5.0, 5.0))],
                 render=RenderSettings(shadows=True, visibility_budget=0, ssdf_resolution=8, device=device))


def _median_frames(r, n, move: bool):
    """Median wall time of n warm frames; ``move`` nudges the camera every frame (re-rasterise).
    Returns (median frame time, median raster time)."""
    cam = r.scene.camera
    o = np.asarray(cam.origin, np.float64)
    r.render()
    ts, rs = [], []
    for i in range(n):
        if move:
            r.set_camera(origin=tuple(o + (0.0, 0.0, 1e-3 * ((i % 2) * 2 - 1))))
        else:
            r.set_material("floor", kd=[0.6, 0.6, 0.6 - 1e-3 * (i % 2)])
        t = time.perf_counter()
        r.render()
        ts.append(time.perf_counter() - t)
        rs.append(r.timings.get("raster", float("nan")))
    return statistics.median(ts), statistics.median(rs)


def scaling_section(device="cpu", quick=False, frames=None, pixels=None, triangles=None):
    """Rows: frame time by pixel count (fixed triangles) and by triangle count (fixed pixels)."""
    from warp_sg.renderer.renderer import Renderer

    n = frames or (1 if quick else 7)  # medians of 7: this shared machine swings a single frame by ±10 %
    cuda = not str(device).startswith("cpu")
    pixels = pixels or ((32, 64) if quick else (128, 256, 512, 1024))
    triangles = triangles or ((2_000, 8_000) if quick else
                              (10_000, 100_000, 1_000_000) if cuda else (10_000, 100_000))
    fixed_tris = triangles[-1] if quick else 100_000
    fixed_px = pixels[-1] if quick else 512
    rows = []
    for label, cases in (("pixels", [(fixed_tris, p) for p in pixels]),
                         ("triangles", [(t, fixed_px) for t in triangles])):
        base = None
        for tris, px in cases:
            r = Renderer(scaling_scene(tris, px, device), device=device)
            new_view, raster_s = _median_frames(r, n, move=True)
            reshade, _ = _median_frames(r, n, move=False)
            base = base or new_view
            nt = len(r.geometry.triangles)
            rows.append({"case": f"{nt} triangles, {px}²", "grows with": label, "triangles": nt, "pixels": f"{px}²",
                         "new view s": new_view, "re-shade s": reshade, "fps (new view)": 1.0 / new_view,
                         "ratio": new_view / base, "raster s (new view)": raster_s})
    return rows


__all__ = ["scaling_scene", "scaling_section"]
