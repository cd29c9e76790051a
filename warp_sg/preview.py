"""``warp-sg preview SCENE``: a pyvista window with the scene's meshes, coloured by our renderer.

Each mesh vertex gets the radiance the SG renderer computes there (``Renderer.shade_vertices``:
the same shading kernel as ``ws.render``, all lights, SSDF shadows, textures at the vertex UVs),
seen from the scene camera, tone-mapped to sRGB (``image_io.tonemap_srgb``) and drawn with
Gouraud interpolation (so detail finer than the tessellation — textures, sharp highlights — is
only as fine as the mesh; ``ws.render`` shades per pixel). Lights are drawn too: point lights as
spheres of their radius, directional lights as arrows pointing at the scene along the light
direction, the environment as the background colour (its mean radiance).

``--screenshot out.png`` renders off-screen (no X server needed: VTK's EGL/OSMesa fallback) with
the scene camera, and writes the PNG atomically.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .atomic import atomic_output
from .errors import InputError


def _pyvista():
    try:
        import pyvista as pv
    except ImportError as e:  # pragma: no cover - pyvista is a dependency
        raise InputError(f"the preview needs pyvista ({e})", where="preview") from None
    return pv


def build_plotter(scene, device=None, off_screen: bool = False, window_size=None, exposure: float = 0.0):
    """A ``pyvista.Plotter`` showing ``scene`` (meshes with per-vertex renderer colours + lights)."""
    pv = _pyvista()
    from .image_io import tonemap_srgb
    from .lights import DirectionalLight, PointLight
    from .render import Renderer

    if off_screen:  # VTK tries an X display first and logs a warning before falling back to EGL/OSMesa
        try:
            from vtkmodules.vtkCommonCore import vtkLogger

            vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
        except Exception:  # noqa: BLE001 - cosmetic only
            pass
    r = Renderer(scene, device=device)
    g = r.geometry
    rad = r.shade_vertices()
    rgb = (tonemap_srgb(rad, exposure) * 255 + 0.5).astype(np.uint8)
    cam = scene.camera
    size = tuple(window_size) if window_size else (int(cam.width), int(cam.height))
    pl = pv.Plotter(off_screen=off_screen, window_size=list(size))
    faces = np.hstack([np.full((len(g.triangles), 1), 3, np.int64), g.triangles.astype(np.int64)]).ravel()
    mesh = pv.PolyData(g.vertices.astype(np.float64), faces)
    mesh.point_data["rgb"] = rgb
    pl.add_mesh(mesh, scalars="rgb", rgb=True, lighting=False, smooth_shading=True, name="scene")
    # lights
    lo, hi = g.vertices.min(0), g.vertices.max(0)
    centre = 0.5 * (lo + hi)
    extent = float(np.linalg.norm(hi - lo)) or 1.0
    for j, li in enumerate(scene.local_lights):
        if isinstance(li, PointLight):
            rr = max(li.radius, 0.01 * extent)
            pl.add_mesh(pv.Sphere(radius=rr, center=li.position), color=(1.0, 0.9, 0.3), lighting=False,
                        name=f"light{j}")
        elif isinstance(li, DirectionalLight):
            start = centre + li.direction * 0.6 * extent
            pl.add_mesh(pv.Arrow(start=start, direction=-li.direction, scale=0.3 * extent), color=(1.0, 0.8, 0.2),
                        lighting=False, name=f"light{j}")
    env = scene.environment
    if env is not None:
        mean = env.radiance().reshape(-1, 3).mean(0)
        pl.set_background(tuple(float(c) for c in tonemap_srgb(mean, exposure)))
    else:
        pl.set_background((0.0, 0.0, 0.0))
    pl.camera_position = [tuple(float(x) for x in cam.origin), tuple(float(x) for x in cam.target),
                          tuple(float(x) for x in cam.up)]
    pl.camera.view_angle = float(cam.fov)
    pl.camera.clipping_range = (max(float(getattr(cam, "near", 1e-2)), 1e-3), float(getattr(cam, "far", 1e4)))
    return pl


def preview(scene, screenshot=None, device=None, window_size=None, exposure: float = 0.0):
    """Open the preview window, or write ``screenshot`` (PNG) off-screen and return its path."""
    if screenshot is None:
        pl = build_plotter(scene, device=device, off_screen=False, window_size=window_size, exposure=exposure)
        pl.show(title=f"warp-sg preview: {getattr(scene, 'path', None) or 'scene'}")
        return None
    out = Path(screenshot)
    if out.suffix.lower() != ".png":
        raise InputError("the screenshot must be a .png file", where=str(out))
    folder = out.parent if str(out.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"folder '{folder}' does not exist", where=str(out))
    pl = build_plotter(scene, device=device, off_screen=True, window_size=window_size, exposure=exposure)
    try:
        with atomic_output(out, suffix=".png") as tmp:  # umask permissions, never a partial file
            pl.screenshot(tmp)
    finally:
        pl.close()
    return out


__all__ = ["preview", "build_plotter"]
