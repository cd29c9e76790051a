"""``Renderer(..., progressive=True)``: unshadowed frames at once, the shadows from a background
thread, then the frames of a non-progressive renderer bit for bit (warp_sg.renderer.progressive)."""
from __future__ import annotations

import sys
import threading

import numpy as np
import pytest

from precompute.visibility.ssdf import compute_ssdf
from warp_sg.core.errors import InputError
from warp_sg.renderer.renderer import Renderer
from warp_sg.tools.bench import bench_scene


def _scene(shadows=True):
    return bench_scene(64, 48, quick=True, shadows=shadows)


def test_first_frame_is_the_unshadowed_render_and_the_final_one_the_non_progressive_render(cache_dir):
    r = Renderer(_scene(), progressive=True)
    first = r.render()
    unshadowed = Renderer(_scene(shadows=False)).render()
    r.wait()
    assert not r.shadows_pending and r.ssdf is not None and r.shadows
    final = r.render()
    reference = Renderer(_scene()).render()
    if r.shadows_pending:  # pragma: no cover - wait() installs them
        pytest.fail("shadows still pending after wait()")
    assert np.array_equal(final, reference)
    assert not np.array_equal(unshadowed, final)  # the shadows change the image
    # the first frame may have been rendered after the job finished (then it is shadowed); with
    # the job held back (next test) it is always the unshadowed one
    assert np.array_equal(first, unshadowed) or np.array_equal(first, final)


def test_the_environment_built_beside_its_prefilter_equals_the_one_built_after_it(cache_dir, monkeypatch):
    """The ΓL prefilter runs on threads beside the irradiance and the SG fit (overlap_precompute):
    the same tables, lobes and image as one part after the other, each with a fresh cache."""
    from warp_sg.core.cache import fresh_cache

    built = {}
    for overlap in (False, True):
        monkeypatch.setattr(Renderer, "overlap_precompute", overlap)
        with fresh_cache():
            r = Renderer(_scene())
            built[overlap] = (r, r.render())
    (a, img_a), (b, img_b) = built[False], built[True]
    assert a.gamma is not None and b.gamma is not None
    assert np.array_equal(a.gamma.texels, b.gamma.texels) and np.array_equal(a.gamma.lambdas, b.gamma.lambdas)
    for x, y in zip(a._env_sg_base, b._env_sg_base):
        assert np.array_equal(x, y)
    assert np.array_equal(img_a, img_b)


def test_the_first_frame_reads_the_mesh_caches_built_beside_the_environment_setup(cache_dir):
    """A progressive renderer builds back-face culling's closedness and the contours' edge
    adjacency on a thread during its constructor; the first frame takes them (the same objects),
    they equal the ones built where they are needed, and once the shadows install a refined mesh
    the job's result (of the input mesh) is not used for it."""
    from warp_sg.scene.culling import BackfaceCulling
    from warp_sg.shading.silhouette import edge_adjacency

    release = threading.Event()

    def held_ssdf(*args, **kw):  # the real computation, held back until the first frame is drawn
        assert release.wait(120)
        return compute_ssdf(*args, **kw)

    r = Renderer(_scene(), progressive=True, ssdf_compute=held_ssdf)
    g, job = r._mesh_job
    assert g is r.geometry and job.wait(60)
    culling, (ev, ef) = job.result()
    first = r.render()
    assert r.geometry is g and r.shadows_pending  # (the shadows are held: the input mesh's frame)
    assert r._culling is culling
    assert np.array_equal(r._aa.edges[0].numpy(), ev) and np.array_equal(r._aa.edges[1].numpy(), ef)
    assert np.array_equal(first, Renderer(_scene(shadows=False)).render())
    release.set()
    direct = BackfaceCulling(g)
    assert np.array_equal(culling.closed, direct.closed) and culling.closed.any() and not culling.closed.all()
    assert np.array_equal(culling.corners, direct.corners)
    dv, df = edge_adjacency(g.vertices, g.triangles)
    assert np.array_equal(ev, dv) and np.array_equal(ef, df)
    r.wait()
    r.render()
    assert r.geometry is not g and r._mesh_job is None  # the refined mesh's own caches
    assert len(r._aa.edges[0]) > len(ev)


def test_frames_do_not_wait_for_the_shadows_and_switch_when_they_are_ready(cache_dir):
    release = threading.Event()
    started = threading.Event()

    def slow_ssdf(*args, **kw):  # the real computation, held back until the test lets it go
        started.set()
        assert release.wait(120)
        return compute_ssdf(*args, **kw)

    r = Renderer(_scene(), progressive=True, ssdf_compute=slow_ssdf)
    assert started.wait(120)
    unshadowed = Renderer(_scene(shadows=False)).render()
    for _ in range(2):  # several frames while the precompute is held: all unshadowed
        assert np.array_equal(r.render(), unshadowed)
        assert r.shadows_pending and not r.shadows_ready()
    assert not r.wait(timeout=0.05)
    r.set_camera(width=40, height=30)  # edits work meanwhile
    assert r.render().shape == (30, 40, 3)
    r.set_camera(width=64, height=48)
    release.set()
    assert r.wait(120)
    assert np.array_equal(r.render(), Renderer(_scene()).render())
    assert r.timings["shadows_ready"] > 0 and "ssdf" in r.timings["precompute_parts"]


def test_an_error_of_the_background_precompute_is_raised_by_the_next_frame(cache_dir):
    def broken(*args, **kw):
        raise InputError("no rays today", where="ssdf")

    r = Renderer(_scene(), progressive=True, ssdf_compute=broken)
    r._job.wait(60)
    with pytest.raises(InputError, match="no rays today"):
        r.render()


def test_a_scene_without_shadows_has_nothing_pending(cache_dir):
    r = Renderer(_scene(shadows=False), progressive=True)
    assert not r.shadows_pending and r.shadows_ready() and r.wait(0)


def test_cli_first_frame_writes_the_unshadowed_frame_then_the_final_one(cache_dir, tmp_path):
    from warp_sg.core.image_io import load_image
    from warp_sg.tools.cli import main

    scene_file = tmp_path / "s.toml"
    scene_file.write_text('''
[camera]
origin = [0.0, 1.6, 4.2]
target = [0.0, 0.45, 0.0]
fov = 38.0
width = 48
height = 36
[[objects]]
primitive = "sphere"
center = [0.0, 0.5, 0.0]
radius = 0.5
resolution = [8, 16]
material = "m"
[[objects]]
primitive = "plane"
center = [0.0, 0.0, 0.0]
size = [5.0, 5.0]
resolution = [4, 4]
material = "m"
[materials.m]
model = "lambert"
kd = [0.6, 0.6, 0.6]
[[lights]]
type = "directional"
direction = [-0.4, 1.0, 0.3]
radius = 0.05
intensity = [1.0, 1.0, 1.0]
[render]
ssdf_resolution = 16
pca_terms = 8
visibility_budget = 800
''')
    first, final, plain = tmp_path / "first.exr", tmp_path / "final.exr", tmp_path / "plain.exr"
    assert main(["render", str(scene_file), "--first-frame", str(first), "-o", str(final), "--no-progress"]) == 0
    assert main(["render", str(scene_file), "-o", str(plain), "--no-progress"]) == 0
    flat = tmp_path / "flat.exr"
    assert main(["render", str(scene_file), "-o", str(flat), "--no-shadows", "--no-progress"]) == 0
    assert np.array_equal(load_image(final), load_image(plain))
    a = load_image(first)
    assert np.array_equal(a, load_image(flat)) or np.array_equal(a, load_image(plain))
    assert main(["render", str(scene_file), "--first-frame", str(first)]) == 2  # needs -o


def _sharp_scene(shadows=True):
    """The bench scene with a near-mirror metal (NDF λ ≈ 2/m² = 800) and the default ΓL ladder at
    128² (its top λ = 1024): a ladder the preview stops short of."""
    from warp_sg import brdf as B
    from warp_sg.scene.model import Material

    sc = bench_scene(64, 48, quick=True, shadows=shadows)
    sc.materials["metal"] = Material.from_brdf(B.TorranceSparrow(kd=[0.05, 0.02, 0.01], ks=[0.9, 0.6, 0.4], m=0.05),
                                               name="metal")
    sc.render.gamma_levels, sc.render.gamma_resolution = 0, 128
    return sc


def test_a_progressive_renderer_previews_glossy_reflections_then_shows_the_scenes_ladder(cache_dir):
    """The first frames read a ΓL ladder cut at PREVIEW_GAMMA_LAMBDA (most of the prefilter's cost
    is in the sharper levels); the scene's own ladder is prefiltered beside the shadows, and once
    both are in, the frame is the non-progressive renderer's bit for bit."""
    from warp_sg.renderer.environment_setup import PREVIEW_GAMMA_LAMBDA

    release = threading.Event()

    def slow_ssdf(*args, **kw):
        assert release.wait(120)
        return compute_ssdf(*args, **kw)

    full = Renderer(_sharp_scene(shadows=False))
    assert full.gamma.lambdas[-1] > PREVIEW_GAMMA_LAMBDA  # the scene needs the sharper levels
    r = Renderer(_sharp_scene(), progressive=True, ssdf_compute=slow_ssdf)
    assert r.gamma.lambdas[-1] <= PREVIEW_GAMMA_LAMBDA < r._gamma_reach * 2
    first = r.render()
    assert r._gamma_job is not None and r._gamma_job.wait(120)
    second = r.render()  # the scene's ladder installed, the shadows still held back
    assert np.array_equal(r.gamma.lambdas, full.gamma.lambdas)
    unshadowed = full.render()
    assert np.array_equal(second, unshadowed)
    # the preview: glossy reflections a little blurred (mean |difference| 0.18 % of the 234 pixels
    # that differ, measured); the sharper lobes read the blend towards the map's filtered texels
    on = np.abs(first - unshadowed).max(axis=2) > 0
    assert on.sum() > 50  # the short ladder is seen
    rel = np.abs(first - unshadowed)[on].sum() / unshadowed[on].sum()
    assert rel < 0.01, rel
    release.set()
    assert r.wait(120) and not r.shadows_pending and r.shadows_ready()
    assert np.array_equal(r.render(), Renderer(_sharp_scene()).render())
    assert r.timings["precompute_parts"]["env_prefilter_full"] > 0


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread priorities are Linux's")
def test_the_shadow_job_runs_below_the_rendering_threads_priority(cache_dir):
    """A progressive renderer's shadow job (and the threads it starts) run at nice + BACKGROUND_NICE
    (warp_sg.renderer.progressive.lower_thread_priority): where the cores are contended the frames
    get them first. The rendering thread's own priority is unchanged."""
    import os
    from concurrent.futures import ThreadPoolExecutor

    from warp_sg.renderer.progressive import BACKGROUND_NICE

    def nice_here():
        return os.getpriority(os.PRIO_PROCESS, threading.get_native_id())

    main_nice = nice_here()
    seen = {}

    def ssdf(*args, **kw):
        seen["job"] = nice_here()
        with ThreadPoolExecutor(1) as ex:  # a worker the job starts (the rays' pool) inherits it
            seen["worker"] = ex.submit(nice_here).result()
        return compute_ssdf(*args, **kw)

    r = Renderer(_scene(), progressive=True, ssdf_compute=ssdf)
    assert r.wait(120)
    want = min(main_nice + BACKGROUND_NICE, 19)
    assert seen == {"job": want, "worker": want}
    assert nice_here() == main_nice


def test_the_first_frames_ladder_is_every_other_level_and_matches_quadrature():
    """``preview_ladder``: a geometric ladder of ratio 2 with the scene ladder's levels up to
    PREVIEW_GAMMA_LAMBDA, its top kept; the table built on it against direct quadrature of eq. 35
    on a 128×64 procedural sky, beside the scene's √2 ladder up to the same top (measured: median
    0.33 % and worst 4.8 % against 0.11 % and 1.0 %: the λ interpolation over twice the step)."""
    import math

    from precompute.environment import prefilter as pf
    from precompute.environment import prefilter_numpy as pfn
    from warp_sg.renderer.environment_setup import PREVIEW_GAMMA_LAMBDA, preview_ladder
    from warp_sg.scene import sky as sk

    lams = pf.default_ladder(128, base_face=128)[0]
    pv = preview_ladder(lams)
    assert np.allclose(pv[1:] / pv[:-1], 2.0) and pv[-1] <= PREVIEW_GAMMA_LAMBDA < 2 * pv[-1]
    assert pv[-1] == lams[lams <= PREVIEW_GAMMA_LAMBDA][-1] and len(pv) == (len(lams[lams <= PREVIEW_GAMMA_LAMBDA]) + 1) // 2
    env = sk.procedural_sky(128, 64)
    b = pf.prefilter_environment(env, lambdas=pv, device="cpu", cache=False, progress=False)
    rng = np.random.default_rng(5)
    p = rng.normal(size=(40, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    lam = np.exp(rng.uniform(math.log(0.5), math.log(pv[-1]), len(p)))
    ref = np.array([pfn.gamma_reference(env, a, x) for a, x in zip(p, lam)])
    rel = np.abs(pfn.gamma_lookup_numpy(b, p, lam) - ref).max(1) / np.abs(ref).max(1)
    full = pf.prefilter_environment(env, lambdas=lams[lams <= pv[-1]], device="cpu", cache=False, progress=False)
    rel_full = np.abs(pfn.gamma_lookup_numpy(full, p, lam) - ref).max(1) / np.abs(ref).max(1)
    print(f"\n  preview ladder vs quadrature: median {np.median(rel):.2e}, max {rel.max():.2e}; "
          f"the scene's: {np.median(rel_full):.2e}, {rel_full.max():.2e}")
    assert np.median(rel) < 0.005 and rel.max() < 0.06
    assert np.median(rel) < 4.0 * np.median(rel_full) and rel.max() < 6.0 * rel_full.max()
