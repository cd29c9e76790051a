r"""Compile ahead, on two threads: the Warp modules a render will need (CPU).

Warp compiles a module the first time one of its kernels is launched, on the launching thread, and
Clang builds its precompiled header of Warp's native headers once per thread (``use_precompiled_headers``:
without it every module parses them again, about 1 s each). On a machine that has never run warp-sg,
a render compiled its 19–26 modules on four or five threads (the main thread, the shadows' job, the
ΓL prefilter's, one per new shading variant), and its first frame met ten modules one after the
other while the other core had nothing to do (the first frame phase of a first LeePerrySmith
render kept both cores busy 31–36 % of its time).

Here every module of the render's path compiles on one pool of two threads (one per core, each
building its header once), queued by priority as soon as the renderer knows it will need it
(:func:`modules_for`; the shadows' job queues its own), beside the asset's
loading and the precompute (with the two tables that depend on no input, :data:`TABLES`, which a
new machine builds once); a thread that reaches a module first *waits* for it (:meth:`KernelPreload.load`,
which moves it to the front of the queue) instead of compiling it itself. The material's albedo
kernels (:meth:`KernelPreload.kernel`) and the shading variants (:meth:`KernelPreload.shade`) go
through the same pool. Warp 1.19 serialises only its Python code generation (``_codegen_lock``) and
compiles modules' C++ in parallel (its own ``wp.force_load`` loads modules from a thread pool the
same way); modules are imported on the calling thread (two threads importing modules that import
each other can meet one half-initialised). Warp has no lock per module: a module is only ever
loaded here once, and modules already in Warp's kernel cache load in milliseconds.
"""
from __future__ import annotations

import atexit
import heapq
import importlib
import itertools
import threading
from concurrent.futures import Future

import warp as wp

from warp_sg.core.device import resolve_device
from warp_sg.core.workers import cpu_workers

#: the modules of every frame (raster, antialiasing, contours, the shading's visibility terms)
FRAME_MODULES = ("raster.triangle_setup", "raster.coarse", "raster.fine", "raster.parallel", "raster.subsample",
                 "warp_sg.shading.visibility_terms", "warp_sg.shading.background", "warp_sg.shading.silhouette",
                 "warp_sg.renderer.antialias_candidates", "warp_sg.renderer.antialias")
#: the frames of a scene with shadows also read the per-vertex visibility caches
SHADOW_FRAME_MODULES = ("warp_sg.shading.vertex_visibility",)
#: the shadows' precompute: refinement, SSDF rays, representatives, the maps' fit
SHADOW_MODULES = ("precompute.visibility.signature_wp", "precompute.visibility.rays",
                  "precompute.visibility.adaptive_rays", "precompute.visibility.horizon_ring",
                  "precompute.visibility.jump_flood", "precompute.visibility.representatives")
#: light that bounces (``[render] bounces``): the gather rows beside the SSDFs, the frames' indirect light
BOUNCE_MODULES = ("precompute.visibility.gather",)
BOUNCE_FRAME_MODULES = ("warp_sg.shading.bounce",)
#: an environment map's irradiance table; its ΓL prefilter (a scene with a specular material)
ENV_MODULES = ("precompute.environment.irradiance",)
GAMMA_MODULES = ("precompute.environment.prefilter_wp",)
#: the tables that depend on no input (``warp_sg.core.cache.cached_table``: on disk once any render
#: built them; on a new machine ≈ 1 CPU-s each, of numpy): built on the pool beside the asset's reading
TABLES = (("warp_sg.sg.irradiance", "irradiance_table"), ("warp_sg.sg.fh", "fh_table"))

_LOCK = threading.Lock()
_PRELOADS: dict[str, "KernelPreload"] = {}


class KernelPreload:
    """The compile pool of ``device`` (one per process and device: :func:`get`)."""

    def __init__(self, device: str):
        self.device = str(device)
        self._heap: list = []  # (priority, order, key): lower first
        self._order = itertools.count()
        self._cv = threading.Condition()
        self._futures: dict = {}  # key (module name, or id of a kernel's module) -> Future
        self._tasks: dict = {}  # key -> the function that loads it (until a thread takes it)
        self._running: set = set()  # keys a thread is loading now
        for i in range(max(cpu_workers(self.device, 2), 1)):
            threading.Thread(target=self._work, name=f"warp-sg-compile_{i}", daemon=True).start()
        # before the interpreter's atexit handlers (Warp's removes the threads' header folders), as
        # concurrent.futures does for its pools; atexit where that hook is missing
        getattr(threading, "_register_atexit", atexit.register)(self._drain)

    def _drain(self) -> None:
        """At exit (an error before the render, or Ctrl-C): drop what is queued and let the compiles
        under way finish, so that no half-built module folder is left in Warp's kernel cache."""
        with self._cv:
            self._heap.clear()
            self._tasks.clear()
            running = [self._futures[k] for k in self._running]
        for f in running:
            try:
                f.exception(timeout=120)
            except Exception:  # noqa: BLE001 - (a timeout: leave it)
                pass

    # ------------------------------------------------------------------ the pool
    def _work(self):
        while True:
            with self._cv:
                while not self._heap:
                    self._cv.wait()
                _, _, key = heapq.heappop(self._heap)
                fn = self._tasks.pop(key, None)  # (None: taken already, by an earlier entry of a raised priority)
                if fn is not None:
                    self._running.add(key)
            if fn is None:
                continue
            fut = self._futures[key]
            try:
                fut.set_result(fn())
            except BaseException as e:  # noqa: BLE001 - raised where it is waited for
                fut.set_exception(e)
            finally:
                with self._cv:
                    self._running.discard(key)

    def _submit(self, key, fn, priority: int) -> Future:
        """Queue ``fn`` as ``key`` (once) at ``priority``; a key still queued moves up to it."""
        with self._cv:
            fut = self._futures.get(key)
            if fut is None:
                fut = self._futures[key] = Future()
                self._tasks[key] = fn
            elif key not in self._tasks:  # (running or done)
                return fut
            heapq.heappush(self._heap, (priority, next(self._order), key))
            self._cv.notify()
        return fut

    # ------------------------------------------------------------------ modules
    def prefetch(self, items) -> None:
        """Queue the modules of ``items`` (``(name, priority)`` pairs; imported here, on the calling
        thread)."""
        for n, priority in items:
            importlib.import_module(n)
            self._submit(n, lambda n=n: wp.load_module(n, device=self.device), priority)

    def load(self, names, queued_only: bool = False, priority: int = 0) -> None:
        """The modules ``names`` loaded: moved up the queue to ``priority`` (default: its front;
        queued first unless ``queued_only``: then those never queued here are left alone), then
        waited for; an error is raised here."""
        futs = []
        for n in names:
            if queued_only and n not in self._futures:
                continue
            importlib.import_module(n)
            futs.append(self._submit(n, lambda n=n: wp.load_module(n, device=self.device), priority))
        for f in futs:
            f.result()

    def tables(self, wait: bool = False) -> None:
        """Queue the :data:`TABLES` (first in line; their modules imported here); ``wait``: until they
        are built (in this process: their ``lru_cache`` then serves every later call)."""
        futs = []
        for mod, name in TABLES:
            fn = getattr(importlib.import_module(mod), name)
            futs.append(self._submit(("table", mod, name), fn, 1))
        if wait:
            for f in futs:
                f.result()

    def kernel(self, kernel, wait: bool = True):
        """``kernel`` with its module loaded (compiled on the pool, first in its queue; ``wait=False``:
        queued only): for the kernels built per content (a material set's albedo tables)."""
        from raster import parallel

        fut = self._submit(("module", id(kernel.module)), lambda: parallel.ensure_loaded(kernel, self.device),
                           0 if wait else 20)
        if wait:
            fut.result()
        return kernel

    def shade(self, features, priority: int = 5) -> Future:
        """The future of the shading kernel of ``features`` (:func:`warp_sg.shading.kernel.shade_kernel`),
        built and its module loaded on the pool (once)."""
        from raster import parallel
        from warp_sg.shading import kernel as S

        def build():
            k = S.shade_kernel(features)
            parallel.ensure_loaded(k, self.device)
            return k

        return self._submit(("shade", features), build, priority)


def get(device: str) -> KernelPreload | None:
    """The compile pool of ``device``: None on CUDA (a CUDA module compiles with NVRTC, no
    per-thread header, and GPU work does not wait on the CPU's cores)."""
    dev = str(device)
    if not dev.startswith("cpu"):
        return None
    resolve_device(dev)  # (Warp initialised the quiet way first: warp_sg.core.device)
    with _LOCK:
        pre = _PRELOADS.get(dev)
        if pre is None:
            pre = _PRELOADS[dev] = KernelPreload(dev)
        return pre


def prefetch_early(device: str) -> None:
    """Before the scene exists (the CLI, while it reads an asset, which always has an environment):
    queue the :data:`TABLES`, the environment's irradiance and the frames' modules on ``device``'s pool."""
    pre = get(device)
    if pre is not None:
        pre.tables()
        pre.prefetch(modules_for(True, False))


def modules_for(environment: bool, specular: bool) -> list[tuple[str, int]]:
    """(module, priority) that a render's constructor queues at once: the environment's (needed
    first), then the frames'. The shadows' modules are queued by their job when it starts
    (:meth:`KernelPreload.load`; a progressive renderer's after its first frame's), the vertex
    caches' once the renderer knows it has shadows."""
    order = list(ENV_MODULES if environment else ()) + list(GAMMA_MODULES if environment and specular else ())
    return [(n, 10 + i) for i, n in enumerate(order + list(FRAME_MODULES))]


__all__ = ["KernelPreload", "get", "modules_for", "prefetch_early", "FRAME_MODULES", "SHADOW_FRAME_MODULES", "SHADOW_MODULES",
           "BOUNCE_MODULES", "BOUNCE_FRAME_MODULES", "ENV_MODULES", "GAMMA_MODULES", "TABLES"]
