"""The viewer's per-pixel viewport: ``Renderer.render()`` for the current pyvista camera.

:class:`Viewport` ties a :class:`warp_sg.renderer.renderer.Renderer` to a ``pyvista.Plotter``:

* **Camera sync.** The pyvista camera (``position``, ``focal_point``, ``view_up``, vertical
  ``view_angle``; VTK and :mod:`warp_sg.scene.camera` both use a vertical field of view) and the window
  size become the renderer's camera (``Renderer.set_camera``), so the frame is the image
  ``warp-sg render`` writes from that pose, environment background included.
* **Display.** The linear HDR frame is tone-mapped (``image_io.tonemap_srgb`` with the viewer's
  exposure) and drawn as the renderer's background texture (``vtkViewport.SetBackgroundTexture``:
  a screen-aligned quad behind every actor), one texel per pixel at full resolution.
* **Geometry stays in the scene.** Each material's triangles are an actor of opacity 0: invisible
  (the background shows through untouched). A click ray-casts them with ``vtkCellPicker``
  (software picking on the actors' meshes; VTK's pickers skip opacity-0 actors, so they are made
  opaque for the pick only, no render happens in between) and names the material under the
  cursor (:meth:`Viewport.pick`).
* **Progressive frames.** Before every VTK render (the renderer's ``StartEvent``) the frame is
  brought up to date: while the camera or a widget is being dragged a *coarse* frame is rendered
  (1/k of the resolution, k ∈ {1, 2, 4, 8} the smallest whose estimated cost — the last full
  frame's time / k² — fits ``budget_s``; edge antialiasing off), drawn stretched with bilinear
  texture filtering; the full frame follows when the interaction ends, or when the view rests
  for ``rest_ms`` with the button still down (a one-shot interactor timer).
* **Shadows arrive later** with a progressive renderer (``Renderer(..., progressive=True)``, the
  viewer's default on screen): the window's event loop (:meth:`warp_sg.tools.preview.Viewer.run`,
  a Python loop of VTK's non-blocking ``ProcessEvents``, not VTK's blocking ``Start``, whose C++
  loop holds Python's GIL and so starves the background precompute) calls :meth:`Viewport.tick`
  between events; when the background precompute is done the frame is redrawn, and that render
  installs the SSDFs. Until then frames are unshadowed and interaction never waits, and while the
  user drags, the frames (ours and VTK's drawing of them) take at most
  :data:`PENDING_FRAME_SHARE` of the time: after a frame the interactor's renders of the camera
  moves pause until the next one is due, and the frame then shows the pose the camera has reached.
  Frames first, the precompute never starved.
* Nothing here runs precompute: only the ``Renderer`` setters (camera, materials, lights,
  environment) are used. The last frame's time is shown in the upper-right corner.
"""
from __future__ import annotations

import time

import numpy as np

from warp_sg.core.image_io import tonemap_srgb

#: coarse resolution divisors tried while interacting, finest first
COARSE_STEPS = (1, 2, 4, 8)
#: while a progressive renderer's precompute runs, the share of the wall time the interactive
#: (coarse) frames may take: after a frame of t seconds the next waits until t / share has passed
PENDING_FRAME_SHARE = 0.25


def quiet_vtk() -> None:
    """VTK tries an X display first and logs a warning before falling back to EGL/OSMesa."""
    try:
        from vtkmodules.vtkCommonCore import vtkLogger

        vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    except Exception:  # noqa: BLE001 - cosmetic only
        pass


def _pv():
    import pyvista as pv

    return pv


def camera_pose(scene_camera) -> list:
    """A warp-sg camera as a pyvista ``camera_position`` [origin, target, up]."""
    return [tuple(float(x) for x in scene_camera.origin), tuple(float(x) for x in scene_camera.target),
            tuple(float(x) for x in scene_camera.up)]


class Viewport:
    """Per-pixel viewport on ``plotter`` for ``renderer`` (see the module docstring).

    Attributes: ``image`` (last full-resolution frame, linear float32 (H, W, 3)), ``displayed``
    (the sRGB uint8 frame on screen, coarse or full), ``last`` (the last frame: ``coarse`` divisor,
    ``width``, ``height``, ``seconds`` from the start of the frame to the texture update),
    ``frames`` (frames rendered), ``exposure`` (stops).
    """

    def __init__(self, renderer, plotter, exposure: float = 0.0, budget_s: float = 0.05, rest_ms: int = 200):
        pv = _pv()
        import vtk

        self.renderer = renderer
        self.plotter = plotter
        self.exposure = float(exposure)
        self.budget_s = float(budget_s)
        self.rest_ms = int(rest_ms)
        self.home = camera_pose(renderer.scene.camera)
        self.home_fov = float(renderer.scene.camera.fov)
        self.image = None
        self.displayed = None
        self.last: dict = {}
        self.frames = 0
        self._full_seconds = None
        self._shown = None  # (pose, coarse divisor) of the frame on screen
        self._dirty = True  # a scene edit not yet rendered
        self._interacting = 0
        self._rest = False
        self._last_coarse_t = 0.0
        self._vimg = None
        self._awaiting = not renderer.shadows_ready()  # a progressive renderer's precompute not shown yet
        self._frame_start = None  # (perf_counter) a frame's start, until its VTK render has ended
        self._frame_end = 0.0  # when the last frame was on screen, and how long it took (ours and
        self._frame_dt = 0.0  # VTK's drawing): the pace of the frames while a precompute runs
        self._deferred = False  # a coarse frame held back for that pace (tick renders it when due)
        self._paused = False  # VTK's renders of the style's camera moves paused meanwhile
        self._texture = vtk.vtkTexture()
        self._texture.InterpolateOff()
        pl = plotter
        pl.renderer.SetBackgroundTexture(self._texture)
        self._pick_actors = self._add_pick_actors(pv)
        self._text = pl.add_text("", position="upper_right", font_size=8, name="warp_sg_frame_time")
        pl.camera_position = self.home
        pl.camera.view_angle = self.home_fov
        pl.renderer.AddObserver("StartEvent", lambda *_: self.update())
        pl.renderer.AddObserver("EndEvent", lambda *_: self._frame_drawn())
        self._picker = vtk.vtkCellPicker()
        self._picker.SetTolerance(0.0)
        self._picker.PickFromListOn()  # the scene's meshes only (not the widgets)
        for a in self._pick_actor_list:
            self._picker.AddPickList(a)

    # ------------------------------------------------------------------ scene actors
    def _add_pick_actors(self, pv) -> dict:
        """One opacity-0 actor per material (the input mesh's triangles): {actor address: name}."""
        g = self.renderer.input_geometry
        tri = np.asarray(g.triangles, np.int64)
        verts = np.asarray(g.vertices, np.float64)
        mat = np.asarray(g.tri_material)
        out = {}
        self._pick_actor_list = []
        for mi, name in enumerate(g.material_names):
            sel = tri[mat == mi]
            if not len(sel):
                continue
            faces = np.hstack([np.full((len(sel), 1), 3, np.int64), sel]).ravel()
            actor = self.plotter.add_mesh(pv.PolyData(verts, faces), opacity=0.0, lighting=False,
                                          name=f"warp_sg_material_{name}", reset_camera=False)
            out[actor.GetAddressAsString("vtkObject")] = name
            self._pick_actor_list.append(actor)
        return out

    def pick(self, x: float, y: float):
        """The material under display position (x, y) (pixels, origin bottom-left), or None."""
        actors = self._pick_actor_list
        for a in actors:
            a.GetProperty().SetOpacity(1.0)
        try:
            hit = self._picker.Pick(float(x), float(y), 0.0, self.plotter.renderer)
        finally:
            for a in actors:
                a.GetProperty().SetOpacity(0.0)
        if not hit:
            return None
        actor = self._picker.GetActor()
        return None if actor is None else self._pick_actors.get(actor.GetAddressAsString("vtkObject"))

    # ------------------------------------------------------------------ camera
    def pose(self) -> tuple:
        """(origin, target, up, fov, width, height) of the pyvista camera and window."""
        cam = self.plotter.camera
        w, h = (int(v) for v in self.plotter.window_size)
        return (tuple(float(v) for v in cam.position), tuple(float(v) for v in cam.focal_point),
                tuple(float(v) for v in cam.up), float(cam.view_angle), w, h)

    def set_pose(self, origin, target, up=(0.0, 1.0, 0.0), fov=None) -> None:
        """Move the pyvista camera (the next update renders from there)."""
        self.plotter.camera_position = [tuple(map(float, origin)), tuple(map(float, target)), tuple(map(float, up))]
        if fov is not None:
            self.plotter.camera.view_angle = float(fov)

    def reset_view(self) -> None:
        """Back to the scene file's camera."""
        self.set_pose(*self.home, fov=self.home_fov)
        self.draw()

    # ------------------------------------------------------------------ interaction state
    def begin_interaction(self) -> None:
        self._interacting += 1
        self._rest = False

    def end_interaction(self) -> None:
        self._interacting = max(self._interacting - 1, 0)
        self.draw()

    @property
    def interacting(self) -> bool:
        return self._interacting > 0

    def invalidate(self) -> None:
        """The scene changed (a setter ran): the next update renders a new frame."""
        self._dirty = True
        self._rest = False

    def install_observers(self) -> None:
        """Camera interaction (the interactor style's Start/EndInteractionEvent) and the rest
        timer (a one-shot interactor timer after each coarse frame, delivered to the style)."""
        iren = self.plotter.iren
        if iren is None:
            return
        style = iren.interactor.GetInteractorStyle()
        if style is not None:
            style.AddObserver("StartInteractionEvent", lambda *_: self.begin_interaction())
            style.AddObserver("EndInteractionEvent", lambda *_: self.end_interaction())
            # The interactor hands timer events to its style; a style with a TimerEvent observer
            # calls it instead of its own OnTimer, which in the rotate / pan state would repeat the
            # last mouse delta (the camera would keep spinning while the button is held still).
            style.AddObserver("TimerEvent", lambda *_: self._on_timer())

    def _on_timer(self) -> None:
        self.tick()

    def tick(self) -> None:
        """What the event loop does between window events (and VTK's timer events): show the
        shadows once a progressive renderer's background precompute is done (the frame that
        installs them), a frame held back for the precompute's share when it is due, and the full
        frame when the view has rested ``rest_ms`` with the button still down."""
        if self._awaiting and self.renderer.shadows_ready():
            self._awaiting = False
            self._pause_renders(False)
            self.invalidate()  # the next frame installs the shadows (Renderer.poll)
            self.draw()
            return
        if (self._deferred or self._paused) and not self._hold_back():
            self._pause_renders(False)
            self.draw()  # (the pose the camera has reached meanwhile, if it moved)
            return
        if self.interacting and self._shown and self._shown[1] > 1 and not self._paused \
                and time.perf_counter() - self._last_coarse_t >= 0.9 * self.rest_ms / 1000.0:
            self._rest = True  # (not while the moves' renders pause: the camera may be moving)
            self.draw()

    def _hold_back(self) -> bool:
        """Whether an interactive frame waits now: a background precompute runs and the last frame
        has not yet had its share of the time (:data:`PENDING_FRAME_SHARE`)."""
        if not self._awaiting:
            return False
        return time.perf_counter() - self._frame_end < self._frame_dt * (1.0 / PENDING_FRAME_SHARE - 1.0)

    def _frame_drawn(self) -> None:
        """The VTK render of a frame has ended (the renderer's ``EndEvent``): its whole time, ours
        and VTK's drawing (software OpenGL costs CPU too), sets the pace; while a precompute runs,
        the interactor's renders of the style's camera moves pause until the next frame is due."""
        if self._frame_start is None:
            return
        now = time.perf_counter()
        self._frame_end, self._frame_dt, self._frame_start = now, now - self._frame_start, None
        if self.interacting and self._hold_back():
            self._pause_renders(True)

    def _pause_renders(self, on: bool) -> None:
        iren = self.plotter.iren
        if iren is not None and on != self._paused:
            iren.interactor.SetEnableRender(not on)
            self._paused = on

    # ------------------------------------------------------------------ frames
    def coarse_divisor(self) -> int:
        """The k of the coarse frame: the smallest whose estimated cost fits the budget."""
        est = self._full_seconds
        if est is None:
            return COARSE_STEPS[-1]
        for k in COARSE_STEPS:
            if est / (k * k) <= self.budget_s:
                return k
        return COARSE_STEPS[-1]

    def update(self) -> bool:
        """Render a new frame if the pose, the scene or the coarse/full state asks for one."""
        pose = self.pose()
        want_coarse = self.interacting and not self._rest
        moved = self._shown is not None and self._shown[0] != pose
        if moved and self.interacting and self._rest:  # moving again after a rest: coarse frames again
            self._rest, want_coarse = False, True
        stale = self._dirty or self._shown is None or moved or (not want_coarse and self._shown[1] > 1)
        if not stale:
            return False
        self._deferred = want_coarse and self._hold_back()
        if self._deferred:  # (the frame on screen stays; tick() renders this one when it is due)
            self._last_coarse_t = time.perf_counter()  # (the view is not at rest)
            return False
        self.render_frame(coarse=want_coarse, pose=pose)
        self._frame_start = self._frame_end - self._frame_dt  # (its VTK render ends it: _frame_drawn)
        return True

    def draw(self) -> None:
        """Bring the frame up to date and redraw the window."""
        self.update()
        self.plotter.render()

    def render_frame(self, coarse: bool = False, pose=None) -> np.ndarray:
        """Render the pose (default: the current one), full or coarse, and show it."""
        t0 = time.perf_counter()
        pose = self.pose() if pose is None else pose
        origin, target, up, fov, w, h = pose
        r = self.renderer
        k = self.coarse_divisor() if coarse else 1
        k = max(1, min(k, w, h))
        rs = r.scene.render
        saved = (rs.antialias, rs.supersampling)
        if k > 1:
            rs.antialias, rs.supersampling = 1, 1
        try:
            r.set_camera(origin=origin, target=target, up=up, fov=fov, width=max(w // k, 1), height=max(h // k, 1))
            img = r.render()
        finally:
            rs.antialias, rs.supersampling = saved
        if k == 1:
            self.image = img
        self._show(img, interpolate=k > 1)
        dt = time.perf_counter() - t0
        if k == 1:
            self._full_seconds = dt
        else:
            self._last_coarse_t = time.perf_counter()
            self._schedule_rest()
        self._shown = (pose, k)
        self._frame_end, self._frame_dt = time.perf_counter(), dt
        self._dirty = False
        self.frames += 1
        self.last = {"coarse": k, "width": img.shape[1], "height": img.shape[0], "seconds": dt}
        self._set_text(f"{dt * 1e3:.0f} ms  {img.shape[1]}x{img.shape[0]}" + (f"  (1/{k})" if k > 1 else ""))
        return img

    def set_exposure(self, stops: float) -> None:
        """Change the display exposure: the last frame is tone-mapped again (no render)."""
        self.exposure = float(stops)
        if self.image is not None and self._shown is not None and self._shown[1] == 1:
            self._show(self.image, interpolate=False)
        else:
            self._dirty = True

    def _show(self, img, interpolate: bool) -> None:
        rgb = (tonemap_srgb(img, self.exposure) * 255.0 + 0.5).astype(np.uint8)
        self.displayed = rgb
        h, w = rgb.shape[:2]
        flat = np.ascontiguousarray(rgb[::-1]).reshape(-1, 3)  # VTK images start at the bottom row
        if self._vimg is None or tuple(self._vimg.dimensions[:2]) != (w, h):
            self._vimg = _pv().ImageData(dimensions=(w, h, 1))
            self._vimg.point_data["rgb"] = flat
            self._texture.SetInputData(self._vimg)
        else:
            self._vimg.point_data["rgb"][:] = flat
            self._vimg.Modified()
        self._texture.SetInterpolate(bool(interpolate))
        self.plotter.renderer.TexturedBackgroundOn()

    def _set_text(self, msg: str) -> None:
        try:
            self._text.SetText(3, msg)  # vtkCornerAnnotation: 3 = upper right
        except (AttributeError, TypeError):
            self._text.SetInput(msg)

    def _schedule_rest(self) -> None:
        iren = self.plotter.iren
        if iren is not None and not self.plotter.off_screen and self.rest_ms > 0:
            iren.interactor.CreateOneShotTimer(self.rest_ms)


__all__ = ["Viewport", "camera_pose", "quiet_vtk", "COARSE_STEPS", "PENDING_FRAME_SHARE"]
