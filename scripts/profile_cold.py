"""Profile the cold path of ``warp-sg render ASSET`` stage by stage (docs/benchmarks.md, "Cold path").

    python scripts/profile_cold.py ASSET [--env SKY.hdr] [--size 512 384] [--fresh-kernels] [--json OUT]
    python scripts/profile_cold.py helmet   # the generated textured helmet (warp_sg.tools.bench_assets)
    python scripts/profile_cold.py scene.toml --render visibility_budget=0   # a scene file, a setting changed

A fresh precompute cache (a temporary ``WARP_SG_CACHE_DIR``) every run, holding only the tables
that depend on no asset (``warp_sg.core.cache.cached_table``: the SG irradiance and fh tables,
which any earlier render on the machine left there): a new asset's cold start. With
``--fresh-kernels`` those tables are built too and the Warp kernel cache is fresh (what a new
installation pays: every kernel compiled). Per stage: wall
seconds and CPU seconds of the process (all threads, ``time.process_time``; the SSDF sub-stages
sum the worker threads' own CPU), so the numbers mean something on a machine shared with other
work; the 1-minute load average before and after is printed with them.

Stages: ``load`` (asset file → scene → flattened mesh), then the renderer's precompute parts
(``refine``, ``ssdf`` = ``bvh`` + ``rays`` + ``ssdf_fit`` + ``pca`` + ``cones``, ``env_peaks``,
``env_fit``, ``env_prefilter``), ``first frame`` (the first ``render()``: its kernels load or
compile there) and ``warm frame``. ``kernels`` is the sum of Warp's module load times printed
while it ran (compilation included; it overlaps the stages above).

Per thread and per phase (:class:`warp_sg.core.thread_sampler.ThreadSampler`, every 10 ms): the CPU
seconds of each thread by name, and for the phases load / constructor / first frame the mean number
of the process's runnable threads, the share of the time every core would be busy on an idle
machine and the core-seconds it would leave idle — what "both cores busy" means on a shared machine.
"""
from __future__ import annotations

import argparse
import io
import json
import os
import re
import sys
import tempfile
import time
from pathlib import Path


def peak_rss_gib() -> float:
    """The process's peak resident set size so far (GiB)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / (1 << 20)


class _Tee(io.TextIOBase):
    """stdout that also collects Warp's ``Module ... took X ms`` lines."""

    def __init__(self, out):
        self.out, self.ms, self.compiled = out, 0.0, 0

    def write(self, s):
        for m in re.finditer(r"took ([0-9.]+) ms\s*\((compiled|cached)\)", s):
            self.ms += float(m.group(1))
            self.compiled += m.group(2) == "compiled"
        return len(s)

    def flush(self):
        self.out.flush()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("asset", help="asset file, a scene file (.toml), or 'helmet' for the generated textured helmet")
    ap.add_argument("--render", action="append", default=[], metavar="KEY=VALUE",
                    help="override a [render] setting (repeatable), e.g. visibility_budget=0")
    ap.add_argument("--env", default=None, help="environment map (default: the procedural sky)")
    ap.add_argument("--size", type=int, nargs=2, default=(512, 384), metavar=("W", "H"))
    ap.add_argument("--fresh-kernels", action="store_true",
                    help="empty Warp kernel cache (compile everything) and no asset-independent tables")
    ap.add_argument("--json", default=None, help="write the stages as JSON here")
    ap.add_argument("--sequential", action="store_true",
                    help="precompute parts one after the other (Renderer.overlap_precompute = False), so the "
                         "CPU time of each is its own; default: the renderer's overlap of shadows and environment")
    a = ap.parse_args(argv)
    tmp = tempfile.mkdtemp(prefix="wsg-profile-")
    os.environ["WARP_SG_CACHE_DIR"] = os.path.join(tmp, "cache")
    import warp as wp

    if a.fresh_kernels:
        wp.config.kernel_cache_dir = os.path.join(tmp, "kernels")
    from warp_sg.core.device import resolve_device
    from warp_sg.core.stage_clock import StageClock, load_average
    from warp_sg.core.thread_sampler import ThreadSampler

    tee = _Tee(sys.stdout)
    old = sys.stdout
    sys.stdout = tee
    try:
        resolve_device("cpu")  # initialises Warp (and quietens it)
    finally:
        sys.stdout = old
    wp.config.log_level = wp.LOG_INFO  # module-load lines, collected by the tee
    if not a.fresh_kernels:  # the asset-independent tables on disk, not in this process's memory
        from warp_sg.sg.fh import fh_table
        from warp_sg.sg.irradiance import irradiance_table

        for table in (irradiance_table, fh_table):
            table()
            table.cache_clear()

    clock = StageClock()
    load0 = load_average()
    asset = a.asset
    if asset == "helmet":
        from warp_sg.tools.bench_assets import textured_helmet

        asset = str(textured_helmet(Path(tmp) / "helmet.glb"))
    sys.stdout = tee
    sampler = ThreadSampler().start()
    marks = {"start": time.perf_counter()}
    try:
        with clock.stage("load"):
            from warp_sg.renderer.renderer import Renderer
            from warp_sg.scene.importers.asset import asset_scene

            if asset.endswith(".toml"):
                from warp_sg.scene.loader import load_scene

                scene = load_scene(asset)
            else:
                scene, _ = asset_scene(asset, env=a.env, width=a.size[0], height=a.size[1])
            for kv in a.render:
                k, v = kv.split("=", 1)
                setattr(scene.render, k, type(getattr(scene.render, k))(v))
            geo = scene.geometry()
        w0, c0 = time.perf_counter(), time.process_time()
        marks["load"] = w0
        Renderer.overlap_precompute = not a.sequential  # sequential: each part's CPU is its own
        r = Renderer(scene, device="cpu")
        pre_wall, pre_cpu = time.perf_counter() - w0, time.process_time() - c0
        marks["constructor"] = time.perf_counter()
        for k, w in r.timings["precompute_parts"].items():
            clock.add(k, w, r.timings["precompute_cpu"].get(k, 0.0))
        counts = {}
        if r.ssdf is not None:
            for k, v in r.ssdf.stats.items():
                if isinstance(v, tuple) and k != "ssdf_total":
                    clock.add("  ssdf." + k, *v)
                elif not isinstance(v, tuple):
                    counts[k] = v
        with clock.stage("first frame"):
            r.render()
        marks["first frame"] = time.perf_counter()
        with clock.stage("warm frame"):
            r.render()
    finally:
        sys.stdout = old
        sampler.stop()
    stages = clock.as_dict()
    total_wall = stages["load"][0] + pre_wall + stages["first frame"][0]
    total_cpu = stages["load"][1] + pre_cpu + stages["first frame"][1]
    nv = len(r.geometry.vertices)
    print(f"asset {Path(asset).name}: {len(geo.triangles)} triangles, {len(geo.vertices)} vertices; "
          f"{nv} after refinement; {a.size[0]}x{a.size[1]}; load average {load0:.2f} -> {load_average():.2f} "
          f"on {os.cpu_count()} cores; kernels and tables {'fresh' if a.fresh_kernels else 'cached'}")
    if counts.get("rays_cast"):
        print(f"rays cast: {counts['rays_cast'] / nv:.0f} per SSDF vertex; uniform-visibility vertices: "
              f"{counts.get('uniform_vertices', 0)}")
    print("| stage | wall (s) | CPU (s) |\n|---|---:|---:|")
    for k, (w, c) in stages.items():
        print(f"| {k} | {w:.2f} | {c:.2f} |")
    print(f"| precompute (all parts) | {pre_wall:.2f} | {pre_cpu:.2f} |")
    print(f"| kernels (module loads, {tee.compiled} compiled) | {tee.ms / 1000:.2f} | |")
    print(f"peak resident memory {peak_rss_gib():.2f} GiB")
    phases = {}
    names = list(marks)
    for a0, a1 in zip(names[:-1], names[1:]):
        phases[a1] = sampler.summary(marks[a0], marks[a1])
    phases["cold first image"] = sampler.summary(marks["start"], marks["first frame"])
    print(f"| phase ({sampler.cores} cores) | runnable threads | all cores busy | idle core-s |\n|---|---:|---:|---:|")
    for k, v in phases.items():
        if v:
            print(f"| {k} | {v['runnable']:.2f} | {100 * v['all_busy']:.0f} % | {v['idle_core_s']:.2f} |")
    threads = sampler.thread_cpu()
    print("CPU s per thread: " + ", ".join(f"{k} {v:.2f}" for k, v in threads.items() if v >= 0.05))
    print(f"| **cold first image** | **{total_wall:.2f}** | **{total_cpu:.2f}** |")
    if a.json:
        Path(a.json).write_text(json.dumps({"asset": Path(asset).name, "triangles": int(len(geo.triangles)),
                                            "vertices": int(nv), "stages": stages, "precompute": [pre_wall, pre_cpu],
                                            "kernels_s": tee.ms / 1000, "total": [total_wall, total_cpu],
                                            "load": [load0, load_average()], "counts": counts,
                                            "phases": phases, "thread_cpu": threads, "compiled": tee.compiled,
                                            "peak_rss_gib": peak_rss_gib()}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
