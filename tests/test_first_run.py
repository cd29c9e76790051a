"""A first run on a new machine: Warp's module loads as recorded (:mod:`warp_sg.core.module_loads`),
the frame's modules compiled ahead on a thread pool (:mod:`warp_sg.renderer.kernel_preload`) and
the process's threads as sampled (:mod:`warp_sg.core.thread_sampler`).

The references are the file system and the scheduler: a module Warp compiled is a new folder in its
kernel cache (checked in a fresh process with an empty cache), a busy thread is one the kernel
reports running."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time

import numpy as np
from conftest import LIT_SPHERE  # (a lit sphere, no shadows: the frame's modules only)

CHILD = """
import json, sys
from warp_sg.core.device import resolve_device
resolve_device("cpu")
from warp_sg.core.module_loads import ModuleLoads
import warp_sg as ws
scene = ws.load_scene(sys.argv[1])
with ModuleLoads() as loads:
    img = ws.Renderer(scene, device="cpu").render()
print(json.dumps({"records": [[r.name, r.compiled, r.thread] for r in loads.records], "mean": float(img.mean())}))
"""


def _child(tmp_path, kernels):
    scene = tmp_path / "scene.toml"
    scene.write_text(LIT_SPHERE)
    env = {**os.environ, "WARP_CACHE_PATH": str(kernels), "WARP_SG_CACHE_DIR": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-c", CHILD, str(scene)], capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stderr
    assert r.stderr == "" and r.stdout.count("\n") == 1, (r.stdout, r.stderr)  # Warp's lines kept, not printed
    return json.loads(r.stdout)


def _module_dirs(kernels):
    return sorted(p.name for p in kernels.rglob("wp_*") if p.is_dir())


def test_a_first_render_compiles_each_module_once_on_the_compile_pool(tmp_path):
    """In a fresh process with an empty kernel cache: every module Warp compiled is one new folder
    of the cache (the file system's count), compiled once, on the pool's threads; a second process
    loads them all without compiling."""
    kernels = tmp_path / "kernels"
    first = _child(tmp_path, kernels)
    compiled = [(n, th) for n, c, th in first["records"] if c]
    names = [n for n, _ in compiled]
    dirs = _module_dirs(kernels)
    assert len(names) == len(set(names)) == len(dirs) > 5, (names, dirs)
    assert sorted(d.rsplit("_", 1)[0] for d in dirs) == sorted(f"wp_{n}" for n in names), (names, dirs)
    assert all(th.startswith("warp-sg-compile") for _, th in compiled), compiled
    again = _child(tmp_path, kernels)
    assert not [n for n, c, _ in again["records"] if c] and again["mean"] == first["mean"]
    assert _module_dirs(kernels) == dirs


def test_a_renderer_without_the_compile_pool_renders_the_same_frame(cache_dir, monkeypatch):
    from warp_sg.renderer import kernel_preload
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.tools.bench import bench_scene

    r = Renderer(bench_scene(48, 36, quick=True), device="cpu")
    assert r._preload is kernel_preload.get("cpu")  # one pool per process and device
    img = r.render()
    for name in kernel_preload.FRAME_MODULES + kernel_preload.SHADOW_FRAME_MODULES:
        fut = r._preload._futures[name]
        assert fut.done() and fut.exception() is None, name
    monkeypatch.setattr(kernel_preload, "get", lambda device: None)
    other = Renderer(bench_scene(48, 36, quick=True), device="cpu")
    assert other._preload is None
    assert np.array_equal(other.render(), img)


def test_the_thread_sampler_sees_busy_threads_and_their_cpu():
    import hashlib

    from warp_sg.core.thread_sampler import ThreadSampler

    block = bytes(1 << 20)

    def spin(seconds):
        # hashing a large buffer releases the GIL: both threads run at once, as compiler threads do
        # (two pure-Python loops take turns holding the GIL, and starve the sampler's thread)
        end = time.thread_time() + seconds  # (CPU seconds: the same work on a loaded machine)
        while time.thread_time() < end:
            hashlib.sha256(block).digest()

    with ThreadSampler(interval=0.005, cores=2) as s:
        time.sleep(0.2)  # nobody works
        t0 = time.perf_counter()
        ths = [threading.Thread(target=spin, args=(0.4,), name=f"spinner_{i}") for i in range(2)]
        for t in ths:
            t.start()
        for t in ths:
            t.join()
        t1 = time.perf_counter()
    idle, busy = s.summary(None, t0), s.summary(t0 + 0.05, t1 - 0.05)
    assert idle and busy, f"the sampler took {len(s.samples)} samples, none in a window"
    assert idle["runnable"] < 0.5 and idle["all_busy"] < 0.2
    assert busy["runnable"] > 1.5 and busy["all_busy"] > 0.8
    cpu = s.thread_cpu()
    assert 0.6 <= cpu["spinner"] <= 1.2  # two threads of 0.4 CPU-s each, by the kernel's count
