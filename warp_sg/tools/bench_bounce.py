"""``warp-sg bench`` section "light that bounces" (:mod:`warp_sg.renderer.interreflection`): what
``[render] bounces`` costs, as ratios measured in one run.

Scenes: the plain-input ball on a 2-triangle floor under the sky EXR (:mod:`warp_sg.scene.plain_scenes`)
and, where the shared inputs are there, the scanned head on a 2-triangle floor under the clear-day
HDRI, Lambert and gold GGX α = 0.2 (the real-asset report's cases; ``--quick``: the ball alone, 32²).
Per scene:

* **warm frame**: frames with bounces alternate with frames without (``Renderer.set_terms``;
  nothing else changed), medians of ``timings["frame"]`` and their CPU seconds: ``ratio`` (the
  target ≤ 1.5);
* **edit frame**: an environment-scale edit before each frame (the vertices' direct light and the
  bounces run again), with bounces against without;
* **cold precompute**: a new ``Renderer`` with an empty cache, ``bounces = 4`` against ``0`` (the
  gather rows are the difference; the target ≤ 1.3), wall and CPU seconds, after one untimed run
  that compiles and loads the kernels of both;
* **gather**: references per vertex and bytes per reference (target ≤ 64).

The machine's load average closes the table (wall times of a shared machine are noisy; the ratios
of alternated frames much less so).
"""
from __future__ import annotations

import os
import statistics
import tempfile
import time
from pathlib import Path


def _scenes(quick: bool):
    """``[(label, scene)]`` (module docstring)."""
    import warp_sg as ws
    from warp_sg.scene.plain_scenes import write_plain_scene
    from warp_sg.tools.bench_first_image import SHARED_ASSETS

    tmp = Path(tempfile.mkdtemp(prefix="warp-sg-bench-bounce-"))
    size = 32 if quick else 256
    out = [("ball on a floor, Lambert, sky", ws.load_scene(write_plain_scene(tmp / "ball", size=size)))]
    head, sky = SHARED_ASSETS / "LeePerrySmith.glb", SHARED_ASSETS / "pedestrian_overpass_1k.hdr"
    if not quick and head.is_file() and sky.is_file():
        from warp_sg.scene.importers.asset import asset_scene_dict, scene_from_dict

        for mat, label in (({"model": "lambert", "kd": [0.7, 0.7, 0.7]}, "Lambert"),
                           ({"model": "ggx", "alpha": 0.2, "fresnel": "gold"}, "gold GGX α 0.2")):
            doc = asset_scene_dict(head, env=sky, view=(30.0, 25.0), width=size, height=size)
            ob, ground = doc["objects"]
            ob["material"] = "object"
            doc["materials"]["object"] = mat
            ground.update(name="floor", material="floor", resolution=[1, 1])
            doc["materials"]["floor"] = {"model": "lambert", "kd": [0.45, 0.45, 0.45]}
            doc["materials"].pop("ground", None)
            out.append((f"scanned head, {label}, clear-day HDRI", scene_from_dict(doc)))
    return out


def _alternate(r, n: int, edit=None) -> tuple[list, list, list, list]:
    """Frames with and without bounces, alternated (``edit``: called before each)."""
    on, off, c_on, c_off = [], [], [], []
    for i in range(n):
        for flag, wall, cpu in ((True, on, c_on), (False, off, c_off)):
            r.set_terms(bounces=flag)
            r.render()  # (the toggle's own frame)
            if edit is not None:
                edit(i)
            c = time.process_time()
            r.render()
            cpu.append(time.process_time() - c)
            wall.append(r.timings["frame"])
    return on, off, c_on, c_off


def _cold(scene, device, bounces: int) -> tuple[float, float, dict]:
    import copy

    from warp_sg.core.cache import fresh_cache
    from warp_sg.renderer.renderer import Renderer

    sc = copy.deepcopy(scene)
    sc.render.bounces = bounces
    with fresh_cache():
        t, c = time.perf_counter(), time.process_time()
        r = Renderer(sc, device=device)
        return time.perf_counter() - t, time.process_time() - c, r


def bounce_section(device="cpu", quick=False) -> list[dict]:
    """The section's rows (module docstring)."""
    med = statistics.median
    n = 2 if quick else 5
    rows = []
    for label, scene in _scenes(quick):
        _cold(scene, device, 4)  # (the kernels of both compiled and loaded: the runs below build data only)
        w0, c0, _ = _cold(scene, device, 0)
        w1, c1, r = _cold(scene, device, 4)
        g = r.gather
        rows.append({"case": label, "what": "cold precompute", "with_s": w1, "without_s": w0, "ratio": w1 / w0,
                     "cpu_ratio": c1 / c0, "gather_s": r.timings["precompute_parts"].get("gather", float("nan"))})
        if g is not None:
            rows.append({"case": label, "what": "gather", "refs_per_vertex": len(g.senders) / max(g.n_vertices, 1),
                         "bytes_per_reference": g.bytes_per_reference(), "MB": g.nbytes / 1e6})
        r.render()
        on, off, c_on, c_off = _alternate(r, n)
        rows.append({"case": label, "what": "warm frame", "with_s": med(on), "without_s": med(off),
                     "ratio": med(on) / med(off), "cpu_ratio": med(c_on) / med(c_off)})
        if r.env_light is not None:
            scale = float(r.env_light.scale)
            on, off, c_on, c_off = _alternate(r, n, lambda i: r.set_environment_scale(scale * (1.0 + 0.01 * (i + 1))))
            rows.append({"case": label, "what": "edit frame (environment scale)", "with_s": med(on),
                         "without_s": med(off), "ratio": med(on) / med(off), "cpu_ratio": med(c_on) / med(c_off),
                         "bounces": r.timings.get("bounces")})
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return rows + [{"case": "setup", "note": f"load average {load:.1f} over the section; frames alternated with and "
                                             "without bounces; CPU seconds of the process"}]


__all__ = ["bounce_section"]
