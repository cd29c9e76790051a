"""``warp-sg preview SCENE``: the interactive per-pixel viewer and editor (pyvista).

The window shows ``Renderer.render()`` for the current pyvista camera — the image ``warp-sg
render`` writes from that pose, environment background included — drawn behind the scene's
(invisible, pickable) meshes (:mod:`warp_sg.tools.viewer`), with widgets that edit materials, lights,
the environment and the exposure live (:mod:`warp_sg.tools.viewer_widgets`). Precompute runs once, at
start-up, with progress bars; view changes and edits only call the ``Renderer`` setters.

* Desktop: ``preview(scene)`` opens a window.
* Headless: ``preview(scene, screenshot="out.png")`` renders off-screen (no X server needed:
  VTK's EGL/OSMesa fallback) from the scene camera and writes the PNG atomically.
* Jupyter: :func:`open_viewer` then ``Viewer.show()``; with the optional ``notebook`` extra
  (pyvista's trame backend) the widget is interactive, otherwise ``show`` returns the frame as
  an image (see ``notebooks/05_viewer.ipynb``).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from warp_sg.core.errors import InputError
from warp_sg.core.files import atomic_output


def _pyvista():
    try:
        import pyvista as pv
    except ImportError as e:  # pragma: no cover - pyvista is a dependency
        raise InputError(f"the preview needs pyvista ({e})", where="preview") from None
    return pv


def has_notebook_backend() -> bool:
    """Whether pyvista's interactive Jupyter backend (trame, the ``notebook`` extra) is installed."""
    try:
        import trame  # noqa: F401
        import trame_vtk  # noqa: F401
    except ImportError:
        return False
    return True


#: how long the window's event loop sleeps between rounds of window events (the GIL is free
#: meanwhile: the background precompute's Python parts run)
LOOP_SLEEP_S = 0.005


class Viewer:
    """A renderer, its plotter, the per-pixel :class:`~warp_sg.tools.viewer.Viewport` and (unless
    ``widgets=False``) the :class:`~warp_sg.tools.viewer_widgets.Editor`."""

    def __init__(self, renderer, plotter, viewport, editor=None):
        self.renderer = renderer
        self.plotter = plotter
        self.viewport = viewport
        self.editor = editor

    @property
    def image(self) -> np.ndarray:
        """The last full-resolution frame (linear float32 (H, W, 3))."""
        if self.viewport.image is None or self.viewport._dirty:
            self.viewport.render_frame()
        return self.viewport.image

    def show(self, title: str | None = None, notebook: bool | None = None):
        """Open the window (desktop), or in Jupyter the trame widget when the ``notebook`` extra
        is installed, else the current frame as a static image."""
        pl = self.plotter
        self.viewport.update()
        if notebook is None:
            notebook = _in_notebook()
        if notebook:
            backend = "trame" if has_notebook_backend() else "static"
            return pl.show(jupyter_backend=backend, return_viewer=backend == "trame")
        pl.show(title=title or "warp-sg preview", interactive_update=True, auto_close=False)
        try:
            self.run()
        finally:
            self.close()
        return None

    def run(self, until=None, timeout: float | None = None, between=None) -> bool:
        """The window's event loop until the window is closed (or ``until()`` is true, or
        ``timeout`` seconds have passed; whether ``until`` was met): VTK's non-blocking
        ``ProcessEvents`` (mouse and keys, VTK's timers: the frames), then
        :meth:`~warp_sg.tools.viewer.Viewport.tick` (the shadows when they are ready, a held-back
        frame, the rest frame), then ``between()`` if given (a test's or a script's mouse events),
        then a :data:`LOOP_SLEEP_S` sleep.

        A loop in Python rather than VTK's ``Start()``: the wrapped ``Start`` keeps Python's GIL
        for as long as the window is open, and a progressive renderer's background precompute then
        only runs while a callback does (measured in a real X window: the background thread got 5 %
        of the work it does alone; with this loop all of it). An off-screen plotter runs the same
        loop (its interactor has no window events to wait for)."""
        iren = self.plotter.iren
        it = None if iren is None else iren.interactor
        end = None if timeout is None else time.perf_counter() + float(timeout)
        while True:
            if it is not None:
                if not self.plotter.off_screen:
                    it.ProcessEvents()
                if it.GetDone():
                    return False
            self.viewport.tick()
            if between is not None:
                between()
            if until is not None and until():
                return True
            if end is not None and time.perf_counter() >= end:
                return False
            time.sleep(LOOP_SLEEP_S)

    def screenshot(self, path) -> Path:
        """The window as a PNG, written atomically (with the shadows: a progressive renderer's
        precompute is waited for)."""
        out = Path(path)
        if self.renderer.wait():
            self.viewport.invalidate()
        self.viewport.draw()
        with atomic_output(out, suffix=".png") as tmp:  # umask permissions, never a partial file
            self.plotter.screenshot(tmp)
        return out

    def close(self) -> None:
        self.plotter.close()


def _in_notebook() -> bool:
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    ip = get_ipython()
    return ip is not None and type(ip).__name__ == "ZMQInteractiveShell"


def open_viewer(scene, device=None, off_screen: bool = False, window_size=None, exposure: float = 0.0,
                widgets: bool = True, progress: bool = True, hud: bool = True, screenshot_dir=".",
                progressive: bool | None = None) -> Viewer:
    """Precompute ``scene`` once (progress bars) and build the viewer; nothing is shown yet.

    ``window_size`` (W, H) defaults to the scene camera's resolution, so the first frame is the
    scene's ``warp-sg render`` image. ``hud``: show the frame time. ``progressive`` (default: on
    screen, not off screen): the window opens with unshadowed frames while the SSDFs are computed
    on a background thread, and switches to shadowed frames when they are ready
    (``Renderer(..., progressive=True)``; the event loop, :meth:`Viewer.run`, checks between window events)."""
    pv = _pyvista()
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.tools.viewer import Viewport, quiet_vtk

    if off_screen:
        quiet_vtk()
    if progressive is None:
        progressive = not off_screen
    r = Renderer(scene, device=device, progress=progress and not progressive, progressive=progressive)
    cam = scene.camera
    size = tuple(int(v) for v in window_size) if window_size else (int(cam.width), int(cam.height))
    pl = pv.Plotter(off_screen=off_screen, window_size=list(size))
    pl.set_background((0.0, 0.0, 0.0))
    vp = Viewport(r, pl, exposure=exposure)
    if not hud:
        vp._set_text("")
        vp._set_text = lambda msg: None
    editor = None
    if widgets:
        from warp_sg.tools.viewer_widgets import Editor

        stem = Path(getattr(scene, "path", None) or "scene").stem + "_view"
        editor = Editor(vp, screenshot_dir=screenshot_dir, screenshot_stem=stem)
    vp.install_observers()
    vp.update()
    return Viewer(r, pl, vp, editor)


def build_plotter(scene, device=None, off_screen: bool = False, window_size=None, exposure: float = 0.0):
    """A ``pyvista.Plotter`` showing ``scene`` per pixel (no widgets)."""
    return open_viewer(scene, device=device, off_screen=off_screen, window_size=window_size, exposure=exposure,
                       widgets=False, progress=False, hud=False).plotter


def preview(scene, screenshot=None, device=None, window_size=None, exposure: float = 0.0):
    """Open the viewer window, or write ``screenshot`` (PNG) off-screen and return its path."""
    if screenshot is None:
        v = open_viewer(scene, device=device, window_size=window_size, exposure=exposure)
        v.show(title=f"warp-sg preview: {getattr(scene, 'path', None) or 'scene'}", notebook=False)
        return None
    out = Path(screenshot)
    if out.suffix.lower() != ".png":
        raise InputError("the screenshot must be a .png file", where=str(out))
    folder = out.parent if str(out.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"folder '{folder}' does not exist", where=str(out))
    v = open_viewer(scene, device=device, off_screen=True, window_size=window_size, exposure=exposure,
                    widgets=False, hud=False)
    try:
        v.screenshot(out)
    finally:
        v.close()
    return out


__all__ = ["preview", "open_viewer", "build_plotter", "Viewer", "has_notebook_backend"]
