r"""The shadow precompute on a background thread (``Renderer(..., progressive=True)``).

A renderer built with ``progressive=True`` sets up everything but the visibility (the mesh as
the user gave it, materials, environment fit and ΓL, lights) and renders unshadowed frames at
once: exact local lights and environment peaks, the environment unshadowed — the frames of the
same scene with ``[render] shadows = false``. Meanwhile a :class:`ShadowJob` computes the refined
mesh and its SSDFs (:func:`warp_sg.renderer.visibility_setup.compute_visibility`, the constructor's own
work otherwise); the renderer installs them at the start of the first ``render()`` after the job
has finished (:meth:`warp_sg.renderer.renderer.Renderer.poll`), and from then on its frames are those of a
renderer built without ``progressive``, bit for bit.

The job never holds the renderer's state: it only computes numpy/Warp data, which the rendering
thread installs. ``render()`` never waits for it (Warp releases the GIL while a kernel runs, so
frames and rays share the cores); :meth:`ShadowJob.wait` does. An exception in the job (a broken
mesh) is raised in the rendering thread by the next ``poll()``.
"""
from __future__ import annotations

import threading
import time


class ShadowJob:
    """Runs ``fn()`` on a daemon thread; :meth:`result` returns its value or raises its exception."""

    def __init__(self, fn, name: str = "warp-sg-shadows"):
        self._fn = fn
        self._value = None
        self._error: BaseException | None = None
        self._done = threading.Event()
        self.started = time.perf_counter()
        self.seconds: float | None = None  # wall time of the job once done
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self):
        try:
            self._value = self._fn()
        except BaseException as e:  # noqa: BLE001 - handed to the rendering thread
            self._error = e
        finally:
            self.seconds = time.perf_counter() - self.started
            self._done.set()

    def done(self) -> bool:
        return self._done.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the job is done (or ``timeout`` seconds passed); whether it is done."""
        return self._done.wait(timeout)

    def result(self):
        """The job's value (it must be done); its exception is raised here."""
        if not self._done.is_set():
            raise RuntimeError("the shadow precompute is still running")
        if self._error is not None:
            raise self._error
        return self._value


__all__ = ["ShadowJob"]
