"""Per-stage and per-lobe profile of a warm frame (docs/benchmarks.md "Frame profile").

    python scripts/profile_frame.py [SCENE.toml | torus:N | lambert:SCENE.toml ...] [--size 512]
                                    [--repeat 5] [--visibility-sampling vertex|pixel] [--kernel-cache DIR]

(``torus:N`` is the frame-scaling bench scene with a torus of about N triangles,
``warp_sg.tools.bench_scaling.scaling_scene``; ``lambert:SCENE.toml`` is the scene with every material
made Lambert with its own kd: a one-model scene with the same geometry and lights.)

For each scene: precompute once, then

* **stages** (wall, median of ``repeat`` frames, camera nudged every frame so that it rasterises):
  raster sub-stages (``raster.rasterize(profile=True)``), background, shading, resolve;
* **shading parts** (process CPU time of a re-shade, visibility buffer reused): the full kernel
  and the kernel variants without shadows, environment diffuse, environment specular and local
  lights; the difference divided by the number of lobes (or lights) is the cost of one lobe;
* **material-model variants** (``brdf.kernel.material_variants``): the re-shade CPU time of the kernel
  specialised to the scene's material models against the generic all-model kernel (measured
  alternately, best of each), and the CPU time to compile each (a real compile only with an empty
  Warp kernel cache: ``--kernel-cache`` names a fresh folder).

CPU time, not wall time, because these machines are shared: other processes inflate wall times.
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np


def _cpu_reshade(r, repeat):
    r.render()
    ts = []
    for i in range(repeat):
        r.set_environment_scale(1.0 + 1e-6 * (i % 2)) if r.env_light is not None else None
        c = time.process_time()
        r.render()
        ts.append(time.process_time() - c)
    return min(ts)


def _wall_new_view(r, repeat):
    o = np.asarray(r.scene.camera.origin, np.float64)
    r.render()
    rows = []
    for i in range(repeat):
        r.set_camera(origin=tuple(o + (0.0, 0.0, 1e-3 * (i % 2 * 2 - 1))))
        t = time.perf_counter()
        r.render()
        rows.append((time.perf_counter() - t, dict(r.timings)))
    rows.sort(key=lambda x: x[0])
    return rows[len(rows) // 2]


def profile(path, size, repeat, visibility_sampling=None):

    import raster
    import warp_sg as ws
    from warp_sg.renderer.renderer import Renderer

    if path.startswith("torus:"):
        from warp_sg.tools.bench_scaling import scaling_scene

        scene = scaling_scene(int(path.split(":")[1]), size)
    elif path.startswith("lambert:"):
        scene = ws.load_scene(path.split(":", 1)[1])
        for m in scene.materials.values():
            kd = m.params.get("kd", [0.6, 0.6, 0.6])
            m.model, m.params, m.normal_map, m.tangent_map = "lambert", {"kd": kd}, None, None
            m.textures = {k: t for k, t in m.textures.items() if k == "kd"}
            m.invalidate()
    else:
        scene = ws.load_scene(path)
    scene.camera = replace(scene.camera, width=size, height=size)
    if visibility_sampling:
        scene.render.visibility_sampling = visibility_sampling
    r = Renderer(scene, device="cpu")
    g = r.geometry
    f = r.features()
    compile_s = _compile_times(f)
    n_env = r._env_arrays().count if f.env_diffuse else 0
    n_lights = len(r.shading_lights)
    print(f"\n### {path} at {size}², visibility_sampling {scene.render.visibility_sampling}: "
          f"{len(g.triangles)} triangles, {len(g.vertices)} vertices; "
          f"{n_env} environment lobes, {n_lights} lights (incl. sun peaks), "
          f"{r.ssdf.pca_terms if r.ssdf else 0} PCA terms\n")
    print("| antialias | frame ms | raster ms | shade ms | resolve ms | shaded samples | raster stages (ms) |")
    print("|---|---|---|---|---|---|---|")
    for aa in (1, scene.render.antialias):
        scene.render.antialias = aa
        wall, t = _wall_new_view(r, repeat)
        # the 1x raster (with antialiasing: keeping the triangles of the a×a sub-samples and the
        # tile queues) and the sub-pixel coverage of the frame's candidate pixels
        vb = None
        for _ in range(2):  # the second time into the first one's buffers, as the renderer does
            vb = raster.rasterize(r.geo_arrays.positions, r.geo_arrays.tris, scene.camera, device="cpu",
                                  profile=True, validate=False, reuse=vb, subsamples=aa,
                                  cull_backfaces=r._cull_flags())
        times = {n: v for n, v in vb.stats["times"].items() if n != "resolve"}  # (depth: not in a frame)
        st = "1×: " + ", ".join(f"{n} {1e3 * v:.1f}" for n, v in times.items())
        if aa > 1:
            st += (f"; {aa}×{aa} sub-pixels of {t.get('candidate_pixels')} pixels "
                   f"({100 * t.get('subpixel_tiles', 0):.0f} % of the tiles): {1e3 * t.get('subpixel_seconds', 0):.1f}")
        print(f"| {aa} | {1e3 * wall:.1f} | {1e3 * t['raster']:.1f} | {1e3 * t['shade']:.1f} | "
              f"{1e3 * t['resolve']:.1f} | {t.get('shaded_samples')} | {st} |")
    scene.render.antialias = 1
    full = _cpu_reshade(r, repeat)
    parts = [("shadows (SSDF lookups)", replace(f, shadows=False), None),
             ("environment diffuse", replace(f, env_diffuse=0), n_env),
             ("environment specular", replace(f, env_specular=0), None),
             ("local lights", replace(f, lights=False), n_lights)]
    print(f"\nshading CPU time, antialias 1, re-shade: full kernel {1e3 * full:.1f} ms\n")
    print("| without | CPU ms | saved ms | per lobe / light ms |")
    print("|---|---|---|---|")
    orig = r.features
    for name, ff, n in parts:
        r.features = lambda ff=ff: ff
        c = _cpu_reshade(r, repeat)
        per = f"{1e3 * (full - c) / n:.1f}" if n else ""
        print(f"| {name} | {1e3 * c:.1f} | {1e3 * (full - c):.1f} | {per} |")
    r.features = orig
    _model_variants(r, f, repeat, compile_s)


def _generic(f):
    from warp_sg.brdf.kernel.material_variants import ALL_MODELS

    return replace(f, models=tuple(sorted(ALL_MODELS)))


def _compile_times(f):
    """CPU seconds to build (or load from the kernel cache) the scene's variant and the generic one."""
    from warp_sg.shading import kernel as S

    S.resolve_box.module.load("cpu")  # the compiler's one-time start-up is not a variant's cost
    out = []
    for ff in (f, _generic(f)):
        c = time.process_time()
        S.shade_kernel(ff).module.load("cpu")
        out.append(time.process_time() - c)
    return out


def _model_variants(r, f, repeat, compile_s):
    gen = _generic(f)
    orig = r.features
    best = {f: float("inf"), gen: float("inf")}
    for _ in range(3):  # alternate, so that both see the same machine load
        for ff in best:
            r.features = lambda ff=ff: ff
            best[ff] = min(best[ff], _cpu_reshade(r, repeat))
    r.features = orig
    print(f"\nmaterial-model variants (re-shade CPU time, best of {3 * repeat}; compile CPU s):\n")
    print("| kernel | models | CPU ms | compile s |")
    print("|---|---|---|---|")
    print(f"| scene's variant | {f.models} | {1e3 * best[f]:.1f} | {compile_s[0]:.1f} |")
    print(f"| generic | all {len(gen.models)} | {1e3 * best[gen]:.1f} | {compile_s[1]:.1f} |")
    print(f"\ngeneric / specialised: {best[gen] / best[f]:.3f}")


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="*", default=["examples/cook_torrance.toml"])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--visibility-sampling", choices=("vertex", "pixel"), default=None)
    ap.add_argument("--kernel-cache", default=None, help="Warp kernel cache folder (a fresh one: real compile times)")
    a = ap.parse_args(argv)
    if a.kernel_cache:
        import warp as wp

        wp.config.kernel_cache_dir = a.kernel_cache
    for s in a.scenes:
        profile(s, a.size, a.repeat, a.visibility_sampling)


if __name__ == "__main__":
    main()
