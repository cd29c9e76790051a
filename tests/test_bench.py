"""``warp-sg bench``: the quick run produces every section with the documented columns."""
from __future__ import annotations

import math

import pytest

from warp_sg.tools.bench import SECTIONS, run_bench
from warp_sg.tools.spp_curve import spp_for_error


def test_spp_for_error_interpolates_log_log_and_extrapolates_like_one_over_spp():
    curve = [(1, 1.0, 0.1), (2, 0.5, 0.2), (4, 0.25, 0.4)]
    spp, t = spp_for_error(curve, 0.5)
    assert spp == pytest.approx(2.0) and t == pytest.approx(0.2)
    spp, t = spp_for_error(curve, 0.025)
    assert spp == pytest.approx(40.0) and t == pytest.approx(4.0)
    assert spp_for_error(curve, 2.0)[0] == 1


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """One quick run of every section (a fresh cache), and what it printed."""
    import os

    old = os.environ.get("WARP_SG_CACHE_DIR")
    os.environ["WARP_SG_CACHE_DIR"] = str(tmp_path_factory.mktemp("bench-cache"))
    try:
        printed = []
        res = run_bench(device="cpu", quick=True, print_fn=printed.append)
    finally:
        if old is None:
            os.environ.pop("WARP_SG_CACHE_DIR", None)
        else:
            os.environ["WARP_SG_CACHE_DIR"] = old
    return res, printed


def _close(a, b):
    return a == pytest.approx(b, rel=1e-9)


def test_quick_bench_prints_every_section_with_its_columns(quick):
    res, printed = quick
    assert list(res.sections) == list(SECTIONS)
    assert len(printed) == len(SECTIONS) and all(p.startswith("### ") for p in printed)
    for name, rows in res.sections.items():
        assert rows, name
        assert all("case" in r for r in rows), name
        assert not any(str(r.get("note", "")).startswith("failed") for r in rows), (name, rows)
    md = res.to_markdown()
    assert md.count("### ") == len(SECTIONS)
    # one table line per row, plus the header and the rule
    assert sum(ln.startswith("| ") for ln in md.splitlines()) == sum(len(r) + 1 for r in res.sections.values())


def test_visibility_ratios_are_the_quotients_of_their_timings_and_the_buffers_agree(quick):
    """The speed-ups are the ray cast's times over the raster's (with the BVH build added for
    the dynamic-scene column), the case names the mesh and image it measured, and the two
    visibility buffers agree on almost every pixel (the ray cast checks the raster)."""
    for r in quick[0].sections["visibility: rasterizer vs ray casting"]:
        assert _close(r["speedup_pool"], r["raycast_pool_s"] / r["raster_s"])
        assert _close(r["speedup_1launch"], r["raycast_1launch_s"] / r["raster_s"])
        assert _close(r["speedup_with_bvh_build"], (r["raycast_pool_s"] + r["bvh_build_s"]) / r["raster_s"])
        assert r["case"] == f"{r['triangles'] / 1e6:.2f}M tris {r['width']}x{r['height']}"
        assert 0.99 <= r["tri_id_agreement"] <= 1.0


def test_shading_rows_are_ratios_to_the_full_scene_and_each_frame_contains_its_shading(quick):
    shading = quick[0].sections["shading cost by scene feature"]
    cases = [r["case"] for r in shading]
    assert cases[:5] == ["full scene", "no environment", "no local lights", "diffuse-only materials", "shadows off"]
    assert cases[-2:] == ["precompute, empty cache", "precompute, warm cache (skipped)"]
    frames = shading[:-2]
    assert frames[0]["shade_ratio"] == 1.0
    for r in frames:
        assert _close(r["shade_ratio"], r["shade_s"] / frames[0]["shade_s"]), r["case"]
        assert 0 < r["shade_s"] <= r["frame_s"], r["case"]  # the frame's time includes its shading
    cold, warm = shading[-2], shading[-1]
    assert _close(warm["speedup"], cold["precompute_s"] / warm["precompute_s"])


def test_precompute_rows_count_the_bench_meshes_vertices(quick):
    """Each row names the vertex count of the ``warp_sg.tools.bench_precompute`` mesh it timed, and its ratio and
    per-vertex cost are its total over the first row's and over that count."""
    import re

    from warp_sg.tools import bench_precompute as pb

    pre = quick[0].sections["precompute cost"]
    assert len(pre) == 2  # the quick targets: 150 and 600 floor vertices
    for r, target in zip(pre, (150, 600)):
        n = int(re.match(r"(\d+) vertices", r["case"]).group(1))
        assert n == len(pb.bench_mesh(target)[0])
        assert _close(r["ratio"], r["total_s"] / pre[0]["total_s"])
        assert _close(r["ms_per_vertex"], 1e3 * r["total_s"] / n)


def test_equal_error_rows_share_the_renderers_error_and_are_net_of_the_truths_noise(quick):
    """Per scene four rows: the SG frame (ratio 1), precompute + frame (the same error, more time),
    the MC reference at the renderer's error, the truth's noise floor; the net error is the raw
    error less the floor, and every ratio is a time over the frame's."""
    import re

    eq = quick[0].sections["equal error: SG renderer vs Monte-Carlo reference"]
    labels = ["bench scene", "plain inputs", "plain inputs, point light"]
    assert len(eq) == 4 * len(labels)
    for k, label in enumerate(labels):
        frame, total, mc, truth = eq[4 * k:4 * k + 4]
        assert frame["case"] == f"{label}: SG renderer (frame)" and frame["ratio"] == 1.0
        assert total["case"] == f"{label}: SG renderer (precompute + frame)"
        assert re.fullmatch(rf"{re.escape(label)}: MC reference at equal error \(\S+ spp\)", mc["case"])
        assert re.fullmatch(rf"{re.escape(label)}: ground truth \(\d+ spp\) noise floor", truth["case"])
        assert frame["rel_mse"] == total["rel_mse"] == mc["rel_mse"] and math.isfinite(frame["rel_mse"])
        assert _close(frame["rel_mse_net"], max(frame["rel_mse"] - truth["rel_mse"], 1e-30))
        assert frame["rel_mse_net"] == total["rel_mse_net"] == mc["rel_mse_net"]
        assert total["seconds"] > frame["seconds"]  # the precompute's time is added to the frame's
        for r in (total, mc, truth):
            assert _close(r["ratio"], r["seconds"] / frame["seconds"]), r["case"]


def test_mitsuba_rows_or_one_line_saying_why_not(quick):
    from warp_sg.tools.peer_mitsuba import mitsuba_status

    res = quick[0]
    mit = res.sections["equal error: SG renderer vs Mitsuba 3"]
    eq = res.sections["equal error: SG renderer vs Monte-Carlo reference"]
    if mitsuba_status("cpu")[0]:  # the optional [compare] extra is installed
        assert [r["case"] for r in mit] == ["bench scene, Lambert materials", "plain inputs",
                                            "plain inputs, point light", "setup"]
        for r in mit[:3]:
            if "mitsuba_s" in r:
                assert _close(r["mitsuba_ratio"], r["mitsuba_s"] / r["frame_s"])
                assert _close(r["mc_ratio"], r["mc_s"] / r["frame_s"])
        # the same SG frame as the Monte-Carlo section (one measurement per run), a less noisy truth
        assert mit[1]["frame_s"] == eq[4]["seconds"] and mit[1]["truth_floor"] < eq[7]["rel_mse"]
    else:
        assert len(mit) == 1 and mit[0]["note"].startswith("skipped: ") and "[compare]" in mit[0]["note"]


def test_frame_scaling_groups_hold_one_variable_fixed_and_count_the_rendered_triangles(quick):
    sc = quick[0].sections["frame scaling: pixels and triangles"]
    assert [r["grows with"] for r in sc] == ["pixels", "pixels", "triangles", "triangles"]
    by_pixels, by_tris = sc[:2], sc[2:]
    assert by_pixels[0]["triangles"] == by_pixels[1]["triangles"] and by_pixels[0]["pixels"] != by_pixels[1]["pixels"]
    assert by_tris[0]["pixels"] == by_tris[1]["pixels"] and by_tris[0]["triangles"] < by_tris[1]["triangles"]
    for group in (by_pixels, by_tris):
        for r in group:
            assert r["case"] == f"{r['triangles']} triangles, {r['pixels']}"
            assert _close(r["ratio"], r["new view s"] / group[0]["new view s"])
            assert _close(r["fps (new view)"], 1.0 / r["new view s"])
            assert 0 < r["raster s (new view)"] <= r["new view s"]  # the new view's raster is part of its frame


def test_ray_budget_rows_are_relative_to_a_ray_per_texel(quick):
    budget = quick[0].sections["SSDF error vs ray budget"]
    full, adaptive = budget[0], budget[1]
    assert full["case"].endswith("full (a ray per texel)") and full["ray_ratio"] == 1.0
    assert full["rays_per_vertex"] == 64 * 64 and full["err_vs_full_rad"] == 0.0
    for r in budget:
        assert _close(r["ray_ratio"], r["rays_per_vertex"] / full["rays_per_vertex"]), r["case"]
    assert adaptive["ray_ratio"] < 0.5 and adaptive["err_vs_full_rad"] < 1e-3
    assert adaptive["err_vs_256_rad"] <= 1.02 * full["err_vs_256_rad"] + 1e-5


def test_first_image_comes_before_the_shadowed_frame(quick):
    first = quick[0].sections["time to first image"]
    row = first[0]
    assert row["case"].startswith("generated textured helmet")
    assert 0 < row["first_frame_s"] <= row["shadows_s"]  # one progressive run: the first frame, then shadows
    assert 0 < row["warm_s"] and 0 < row["cold_cpu_s"] and row["vertices"] > 0


def test_moved_frames_are_compared_with_static_frames_of_the_same_run(quick):
    """"objects that move": per scene a re-shaded frame, a camera-nudged one, a moved one whose
    ratios are the quotients of those timings, and a cold renderer over the moved frame."""
    rows = quick[0].sections["objects that move"]
    reshade, nudged, moved, cold = rows[:4]
    assert reshade["case"].endswith("static frame, shaded again") and moved["case"].endswith("set_object_transform")
    assert _close(moved["vs_reshade"], moved["frame_s"] / reshade["frame_s"])
    assert _close(moved["vs_nudged"], moved["frame_s"] / nudged["frame_s"])
    assert _close(cold["cold_over_moved"], cold["frame_s"] / moved["frame_s"])
    assert 0 < moved["raster_s"] < moved["frame_s"] and moved["motion_s"] > 0
    assert rows[-1]["case"] == "setup" and "load average" in rows[-1]["note"]


def test_first_run_rows_come_from_fresh_processes_first_frame_before_final(quick):
    """"first run": a fresh process per run (its CPU seconds include the imports), the progressive
    first frame before the final one in both runs, and the compile columns of Warp's own records."""
    row = quick[0].sections["first run"][0]
    assert row["case"].startswith("generated textured helmet")
    assert 0 < row["first_frame_s"] <= row["final_s"] and 0 < row["first_frame_compiled_s"] <= row["final_compiled_s"]
    assert row["cpu_s"] > 0 and row["cpu_compiled_s"] > 0
    assert row["modules"] >= 0 and row["compile_s"] >= 0 and (row["modules"] > 0) == (row["compile_s"] > 0)
