"""The viewer's event loop (``Viewer.run``, what ``Viewer.show`` runs for a window): with a
progressive renderer the window shows the shadowed frame once the background precompute is done,
whether the user waits or keeps dragging, and keeps rendering the drag's frames meanwhile.

Driven off-screen through VTK's own interactor (its style turns the mouse events into camera
moves and renders), the same loop as on a display; where an X display is present the same test
runs in a real window too. The reference is independent of the viewer: a non-progressive
``Renderer`` of the scene from the pose the window ends at."""
from __future__ import annotations

import os
import threading

import numpy as np
import pytest

from precompute.visibility.ssdf import compute_ssdf
from warp_sg.renderer.renderer import Renderer
from warp_sg.tools.bench import bench_scene

SIZE = (64, 48)


def _scene(shadows=True):
    return bench_scene(*SIZE, quick=True, shadows=shadows)


def _windows():
    out = ["off-screen"]
    if os.environ.get("DISPLAY"):
        out.append("window")
    return out


@pytest.mark.parametrize("window", _windows())
@pytest.mark.parametrize("drag", [False, True], ids=["idle", "dragging"])
def test_the_event_loop_shows_the_shadowed_frame_idle_and_while_dragging(cache_dir, monkeypatch, window, drag):
    from warp_sg.tools.preview import open_viewer

    release = threading.Event()

    def held_ssdf(*args, **kw):  # the real computation, held until the drag has had frames
        assert release.wait(120)
        return compute_ssdf(*args, **kw)

    init = Renderer.__init__
    with monkeypatch.context() as m:  # (the viewer's renderer computes its SSDFs with held_ssdf)
        m.setattr(Renderer, "__init__", lambda self, *a, **k: init(self, *a, **{**k, "ssdf_compute": held_ssdf}))
        v = open_viewer(_scene(), off_screen=window == "off-screen", progressive=True, widgets=False, hud=False,
                        progress=False)
    try:
        vp, r = v.viewport, v.renderer
        it = v.plotter.iren.interactor
        it.Initialize()  # (so that it delivers events off-screen)
        if window == "window":
            v.plotter.show(interactive_update=True, auto_close=False)
        assert r.shadows_pending and not r.shadows
        unshadowed = v.image.copy()
        w, h = SIZE
        step, pending_frames = [0], [0]

        def between():  # a drag going round in circles, the button never let go
            if drag:
                a = 0.3 * step[0]
                it.SetEventPosition(int(w / 2 + 12 * np.cos(a)), int(h / 2 + 12 * np.sin(a)))
                it.LeftButtonPressEvent() if step[0] == 0 else it.MouseMoveEvent()
                step[0] += 1
            if not release.is_set():
                pending_frames[0] = vp.frames
                release.set() if vp.frames >= (4 if drag else 1) else None

        assert v.run(until=lambda: not vp._awaiting, timeout=300, between=between)
        assert r.shadows and not r.shadows_pending
        if drag:  # the drag's frames came while the precompute ran; then the button is let go
            assert pending_frames[0] >= 4 and vp.interacting
            it.SetEventPosition(w // 2, h // 2)
            it.LeftButtonReleaseEvent()  # the full frame of the pose the drag ended at
            assert not vp.interacting and vp.last["coarse"] == 1
        o, t, u, f, _, _ = vp.pose()
        sc = _scene()
        sc.camera = type(sc.camera)(origin=o, target=t, up=u, fov=f, width=w, height=h)
        np.testing.assert_allclose(v.image, Renderer(sc).render(), rtol=1e-5, atol=1e-6)
        if not drag:  # the pose of the first frame: the shadows made the difference
            assert not np.allclose(unshadowed, v.image, atol=1e-3)
    finally:
        v.close()
