r"""``warp-sg bench`` sections on the cold path (tools layer).

**time to first image** (:func:`first_image_section`): for the generated textured helmet
(:func:`warp_sg.tools.bench_assets.textured_helmet`, 17 k triangles) and each asset of the shared inputs
folder (``../shared/assets``, :func:`_shared_assets`: a scanned head, a material ball, the clear-coat test, the 359 k-triangle
Draco Ferrari; rows say "skipped" with the reason when the folder or a decoder is missing), as
``warp-sg render ASSET`` renders it (ground plane, procedural sky, 512×384; quick: the helmet at
64×48 only), each with an empty precompute cache:

* ``cold_s`` — asset file to the final (shadowed) first frame: load, refinement, SSDFs,
  environment fit and ΓL, first frame (kernels from Warp's kernel cache: an untimed tiny run of the
  asset compiles them first);
* ``first_frame_s`` — the same to the first frame of ``Renderer(..., progressive=True)`` (no
  shadows yet), and ``shadows_s`` until its shadowed frame;
* ``warm_s`` — a frame once everything is set up (median of 3);
* ``cold_cpu_s`` — the CPU seconds of the cold run (all threads) and the machine's load average,
  since the wall times of a shared machine say little alone.

With the optional ``[compare]`` extra, Mitsuba 3 at equal error on the same asset with Lambert
materials (its conversion has no GGX, :mod:`warp_sg.tools.peer_mitsuba`): ``mitsuba_cold_s`` (scene
load and the first render at the sample count that reaches our error, JIT included) and
``mitsuba_warm_s`` (that render warm), with ``cold_ratio`` and ``warm_ratio`` (Mitsuba's time over
ours).

**first run** (:func:`first_run_section`): what a new installation meets, per asset of the same list,
each in a fresh process (Warp compiles a module once per process and machine) with an empty Warp
kernel cache and an empty precompute cache: ``first_frame_s`` (process start to the progressive
first frame: imports, asset, constructor, frame), ``final_s`` (to the shadowed frame), ``cpu_s``,
``compile_s`` (the summed load time of the modules Warp compiled, :mod:`warp_sg.core.module_loads`;
loads on parallel threads overlap, so it can exceed the wall time they took) and ``modules`` (how
many); then the same with the kernels that first run compiled and the asset-independent tables it
built (``first_frame_compiled_s``, ``final_compiled_s``, ``cpu_compiled_s``): a new asset on a
machine that has rendered before.
Quick: the 2 k-triangle helmet at 64×48 with the machine's own kernel cache (a smoke test).

**SSDF error vs ray budget** (:func:`ray_budget_section`): the adaptive visibility rays
(:mod:`precompute.visibility.adaptive_rays`) at several budgets against a ray per texel on the same vertices:
rays per vertex, CPU ms per vertex, the SSDF's mean difference from the full-ray SSDF near
boundaries and its error against a 256²-ray truth (the metric of ``warp_sg.tools.bench_precompute``).
"""
from __future__ import annotations

import copy
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from warp_sg.core.stage_clock import load_average


def _shared_assets() -> Path:
    """The shared inputs' folder: ``$WARP_SG_SHARED_ASSETS``, else ``shared/assets`` beside the
    repository or beside one of its parent folders (a checkout in a subfolder); the first that
    exists (else the one beside the repository, which the rows then name as missing)."""
    env = os.environ.get("WARP_SG_SHARED_ASSETS")
    if env:
        return Path(env)
    root = Path(__file__).resolve().parents[2]
    for up in (root.parent, root.parent.parent, root.parent.parent.parent):
        if (up / "shared" / "assets").is_dir():
            return up / "shared" / "assets"
    return root.parent / "shared" / "assets"


#: the shared inputs (tests and benchmarks skip with a reason when absent)
SHARED_ASSETS = _shared_assets()
#: shared assets of the section, in order (file, label)
ASSETS = (("LeePerrySmith.glb", "scanned head (17.7 k triangles)"), ("ShaderBall.glb", "material ball (88 k)"),
          ("ClearcoatTest.glb", "clear-coat test"), ("ferrari.glb", "Ferrari (359 k, Draco)"))
SIZE = (512, 384)


def _asset_scene(path, size, quick=False):
    from warp_sg.scene.importers.asset import asset_scene

    scene, _ = asset_scene(path, width=size[0], height=size[1])
    if quick:  # CI-sized precompute
        rs = scene.render
        rs.visibility_budget, rs.ssdf_resolution, rs.pca_terms = 1500, 16, 8
        rs.gamma_resolution, rs.gamma_levels, rs.env_lobes = 16, 4, 4
    return scene


def _cold(path, size, device, progressive: bool, quick=False):
    """One cold run with a fresh cache: (wall s to the first frame, wall s to the shadowed frame,
    CPU s of the whole run, the renderer)."""
    from warp_sg.core.cache import fresh_cache
    from warp_sg.renderer.renderer import Renderer

    with fresh_cache():
        w0, c0 = time.perf_counter(), time.process_time()
        scene = _asset_scene(path, size, quick)
        r = Renderer(scene, device=device, progressive=progressive)
        r.render()
        first = time.perf_counter() - w0
        if progressive:
            r.wait()
            r.render()
        return first, time.perf_counter() - w0, time.process_time() - c0, r


def _warm_up(path, device):
    """Compile (or load) every kernel the timed runs use, untimed: a tiny frame of the asset with
    and without shadows, at CI-sized precompute settings (the kernel variants depend on the
    scene's features, not on its sizes)."""
    from warp_sg.core.cache import fresh_cache
    from warp_sg.renderer.renderer import Renderer

    with fresh_cache():
        Renderer(_asset_scene(path, (32, 24), quick=True), device=device).render()
        sc = _asset_scene(path, (32, 24), quick=True)
        sc.render.shadows = False
        Renderer(sc, device=device).render()


def _warm(r, n=3):
    r.render()
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        r.render()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts)


def _lambert(scene):
    """The scene with every material Lambert (kd = the material's mean diffuse colour, or grey)."""
    from warp_sg.scene.model import Material

    sc = copy.copy(scene)
    mats = {}
    for name, m in scene.materials.items():
        kd = m.params.get("kd")
        if "kd" in m.textures:
            kd = m.textures["kd"].mean(colour=True).tolist()
        kd = [0.5, 0.5, 0.5] if kd is None else (list(np.broadcast_to(np.asarray(kd, float), 3)))
        mats[name] = Material(model="lambert", params={"kd": [float(x) for x in kd]}, name=name)
    sc.materials = mats
    return sc


def _mitsuba_row(path, size, device, quick):
    """Mitsuba's cold and warm time at our error on the Lambert version of the asset."""
    from warp_sg.core.cache import fresh_cache
    from warp_sg.groundtruth.reference import render_reference
    from warp_sg.groundtruth.region_error import image_errors
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.tools import peer_mitsuba as pm
    from warp_sg.tools.spp_curve import spp_for_error

    scene = _lambert(_asset_scene(path, size, quick))
    with fresh_cache():
        w0 = time.perf_counter()
        r = Renderer(scene, device=device)
        img = r.render()
        ours_cold = time.perf_counter() - w0
        ours_warm = _warm(r)
    ref = copy.deepcopy(scene)
    k = max(1, ref.render.antialias) if ref.render.supersampling == 1 else ref.render.supersampling
    ref.render.supersampling = k
    truth = render_reference(ref, spp=max(1, (64 if quick else 512) // (k * k)), device=device, seed=5,
                             progress=False).image
    err = image_errors(img, truth)["rel_mse"]
    w0 = time.perf_counter()
    mscene = pm.mitsuba_scene(scene, device)
    load = time.perf_counter() - w0
    curve = pm.mitsuba_curve(scene, truth, device=device, seed=3, repeats=1, stop_below=err,
                             max_spp=16 if quick else 1024)
    spp, warm = spp_for_error(curve, err)
    w0 = time.perf_counter()
    pm.mitsuba_render(mscene, max(1, int(round(spp))), seed=99, device=device)  # same spp, a new seed
    first = time.perf_counter() - w0
    cold = load + max(first, warm)
    return {"rel_mse": err, "mitsuba_spp": spp, "mitsuba_cold_s": cold, "mitsuba_warm_s": warm,
            "cold_ratio": cold / ours_cold, "warm_ratio": warm / ours_warm}


def first_image_section(device="cpu", quick=False):
    """Rows of "time to first image" (module docstring)."""
    from warp_sg.tools.bench_assets import textured_helmet
    from warp_sg.tools.peer_mitsuba import mitsuba_status

    size = (64, 48) if quick else SIZE
    ok, status = mitsuba_status(device)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        items = [(textured_helmet(Path(d) / "helmet.glb", triangles=2000 if quick else 16000),
                  "generated textured helmet" + (" (2 k triangles)" if quick else " (17 k triangles)"))]
        if not quick:
            for name, label in ASSETS:
                p = SHARED_ASSETS / name
                items.append((p if p.is_file() else None, label if p.is_file() else
                              f"{label}: skipped (no {p}; the shared inputs are not here)"))
        for path, label in items:
            if path is None:
                rows.append({"case": label})
                continue
            row = {"case": label, "load": load_average()}
            try:
                _warm_up(path, device)
                first, shadows, _, _ = _cold(path, size, device, progressive=True, quick=quick)
                _, cold, cpu, r = _cold(path, size, device, progressive=False, quick=quick)
                row.update(cold_s=cold, cold_cpu_s=cpu, first_frame_s=first, shadows_s=shadows, warm_s=_warm(r),
                           vertices=len(r.geometry.vertices))
                if ok:
                    row.update(_mitsuba_row(path, size, device, quick))
                elif not rows:
                    row["note"] = f"Mitsuba skipped: {status}"
            except Exception as e:  # noqa: BLE001 - one asset that cannot load must not hide the rest
                row["note"] = f"skipped: {type(e).__name__}: {e}"
            rows.append(row)
    return rows


def first_run_child(path, size, quick, device) -> dict:
    """One progressive render of ``path`` in this (fresh) process, timed from ``FIRST_RUN_T0`` (the
    parent's record of the process start, else now): :func:`first_run_section`'s columns."""
    t0 = float(os.environ.get("FIRST_RUN_T0", time.time()))
    from warp_sg.core.device import resolve_device
    from warp_sg.core.module_loads import ModuleLoads

    dev = resolve_device(device)
    with ModuleLoads() as loads:
        from warp_sg.renderer.renderer import Renderer

        r = Renderer(_asset_scene(path, size, quick), device=dev, progressive=True)
        r.render()
        first = time.time() - t0
        r.wait()
        r.render()
        final = time.time() - t0
    return {"first_frame_s": first, "final_s": final, "cpu_s": time.process_time(),
            "compile_s": loads.compile_seconds, "modules": len(loads.compiled)}


def _first_run(path, size, quick, device, kernels, tables) -> dict:
    """:func:`first_run_child` in a new interpreter with ``kernels`` as Warp's kernel cache and an
    empty precompute cache but for the asset-independent tables in ``tables`` when it exists (a
    machine that has rendered before has them; the first run's are kept there)."""
    import json
    import shutil
    import subprocess
    import sys

    code = ("import json, sys; from warp_sg.tools.bench_first_image import first_run_child; "
            "print(json.dumps(first_run_child(sys.argv[1], (int(sys.argv[2]), int(sys.argv[3])), "
            "sys.argv[4] == '1', sys.argv[5])))")
    with tempfile.TemporaryDirectory() as cache:
        if Path(tables).is_dir():
            shutil.copytree(tables, Path(cache) / "tables")
        env = {**os.environ, "WARP_SG_CACHE_DIR": cache, "FIRST_RUN_T0": repr(time.time())}
        if kernels is not None:
            env["WARP_CACHE_PATH"] = str(kernels)
        out = subprocess.run([sys.executable, "-c", code, str(path), str(size[0]), str(size[1]), "1" if quick else "0",
                              str(device)], env=env, capture_output=True, text=True, timeout=3600)
        if not Path(tables).exists() and (Path(cache) / "tables").is_dir():
            shutil.copytree(Path(cache) / "tables", tables)
    if out.returncode != 0:
        raise RuntimeError(out.stderr.strip().splitlines()[-1] if out.stderr.strip() else f"exit {out.returncode}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def first_run_section(device="cpu", quick=False):
    """Rows of "first run" (module docstring)."""
    from warp_sg.tools.bench_assets import textured_helmet

    size = (64, 48) if quick else SIZE
    rows = []
    with tempfile.TemporaryDirectory() as d:
        items = [(textured_helmet(Path(d) / "helmet.glb", triangles=2000 if quick else 16000),
                  "generated textured helmet" + (" (2 k triangles)" if quick else " (17 k triangles)"))]
        if not quick:
            items += [(SHARED_ASSETS / n if (SHARED_ASSETS / n).is_file() else None,
                       lb if (SHARED_ASSETS / n).is_file() else f"{lb}: skipped (no {SHARED_ASSETS / n})")
                      for n, lb in ASSETS]
        for k, (path, label) in enumerate(items):
            if path is None:
                rows.append({"case": label})
                continue
            row = {"case": label + (" (kernels as cached here)" if quick else ""), "load": load_average()}
            kernels = None if quick else Path(d) / f"kernels{k}"
            try:
                tables = Path(d) / f"tables{k}"
                row.update(_first_run(path, size, quick, device, kernels, tables))
                again = _first_run(path, size, quick, device, kernels, tables)
                row.update(first_frame_compiled_s=again["first_frame_s"], final_compiled_s=again["final_s"],
                           cpu_compiled_s=again["cpu_s"])
            except Exception as e:  # noqa: BLE001 - one asset that cannot load must not hide the rest
                row["note"] = f"skipped: {type(e).__name__}: {e}"
            rows.append(row)
    return rows


def ray_budget_section(device="cpu", quick=False):
    """Rows of "SSDF error vs ray budget" (module docstring): the plane-and-box mesh of
    ``warp_sg.tools.bench_precompute`` (floor vertices around the box), and the scanned head of the shared
    inputs when present (a sample of its refined vertices)."""
    from precompute.visibility import ssdf as S
    from warp_sg.core.stage_clock import StageClock
    from warp_sg.tools.bench_precompute import _near_box_floor_ids, bench_mesh, ssdf_error

    meshes = []
    V, F, N = bench_mesh(300 if quick else 2000)
    meshes.append(("plane + box", V, F, N, _near_box_floor_ids(V, count=8 if quick else 48)))
    head = SHARED_ASSETS / "LeePerrySmith.glb"
    if not quick and head.is_file():
        from precompute.visibility.refine import refine_cached

        g = _asset_scene(head, SIZE).geometry()
        ref = refine_cached(g.vertices, g.triangles, g.normals, budget=20000, device=device)
        ids = np.random.default_rng(0).choice(len(ref.vertices), 120, replace=False)
        meshes.append(("scanned head", ref.vertices, ref.triangles, ref.normals, np.sort(ids)))
    budgets = [("full (a ray per texel)", "full", None), ("adaptive (default)", "adaptive", None),
               ("adaptive, last level between samples", "adaptive", {"last": "bracket"}),
               ("adaptive, no depth test", "adaptive", {"depth_ratio": 0}),
               ("adaptive, 8² coarse grid", "adaptive", {"coarse_factor": 8}),
               ("adaptive, 32² coarse grid", "adaptive", {"coarse_factor": 2})]
    rows = []
    for name, V, F, N, ids in meshes:
        truth = S.compute_ssdf(V, F, N, resolution=256, ray_resolution=256, vertex_ids=ids, progress=False,
                               rays="full", device=device)
        full = None
        for label, rays, kw in budgets:
            clock = StageClock()
            sd = S.compute_ssdf(V, F, N, resolution=32, ray_resolution=64, vertex_ids=ids, progress=False,
                                rays=rays, adaptive=kw, clock=clock, device=device)
            full = sd if full is None else full
            n = len(ids)
            idx = np.arange(n)
            rows.append({"case": f"{name}: {label}", "rays_per_vertex": clock.counts["rays_cast"] / n,
                         "ray_ratio": clock.counts["rays_cast"] / (n * 64 * 64),
                         "cpu_ms_per_vertex": 1e3 * (clock.cpu["rays"] + clock.cpu["ssdf_fit"]) / n,
                         "err_vs_full_rad": ssdf_error(V, F, N, idx, sd, full),
                         "err_vs_256_rad": ssdf_error(V, F, N, idx, sd, truth)})
    return rows


__all__ = ["first_image_section", "first_run_section", "first_run_child", "ray_budget_section", "SHARED_ASSETS",
           "ASSETS"]
