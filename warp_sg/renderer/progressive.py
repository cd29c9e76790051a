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

A progressive renderer's jobs run ``background``: on Linux the job's thread lowers its own
scheduling priority (nice +:data:`BACKGROUND_NICE`; the worker threads it starts for the rays and
the prefilter inherit it), so that where the cores are contended the rendering thread and its
pool get them first and the jobs take what is left — the frames come at the pace of a renderer
with nothing in the background, and the jobs lose no CPU time when the frames are idle. Elsewhere
(no per-thread priority) the job runs as before.
"""
from __future__ import annotations

import os
import sys
import threading
import time

#: how much a background job's threads lower their priority (nice 0 → 10: the kernel's scheduler
#: then gives a contending rendering thread about nine tenths of a core)
BACKGROUND_NICE = 10


def lower_thread_priority(nice: int = BACKGROUND_NICE) -> bool:
    """Lower the calling thread's scheduling priority by ``nice`` (Linux, where a priority is per
    thread and threads started later inherit it); whether it did. Never the process's main thread
    (its id is the process's), and a platform without per-thread priorities is left alone."""
    if not sys.platform.startswith("linux"):
        return False
    tid = threading.get_native_id()
    if tid == os.getpid():
        return False
    try:
        os.setpriority(os.PRIO_PROCESS, tid, min(os.getpriority(os.PRIO_PROCESS, tid) + int(nice), 19))
    except (AttributeError, OSError):
        return False
    return True


class ShadowJob:
    """Runs ``fn()`` on a daemon thread; :meth:`result` returns its value or raises its exception."""

    def __init__(self, fn, name: str = "warp-sg-shadows", background: bool = False):
        self._fn = fn
        self.background = bool(background)  # (lower_thread_priority at the start of the thread)
        self._value = None
        self._error: BaseException | None = None
        self._done = threading.Event()
        self.started = time.perf_counter()
        self.seconds: float | None = None  # wall time of the job once done
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self):
        try:
            if self.background:
                lower_thread_priority()
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


__all__ = ["BACKGROUND_NICE", "ShadowJob", "lower_thread_priority"]
