"""Error-against-run-time report: metrics, and a tiny end-to-end run (shape and trends)."""
from __future__ import annotations

import csv
import math
import os

import numpy as np
import pytest

from warp_sg.groundtruth.region_error import image_errors
from warp_sg.tools.report import KNOBS, available_knobs, run_report, with_setting
from warp_sg.tools.report_outputs import markdown_table


def test_image_errors_are_zero_for_identical_images_and_exact_for_a_known_offset():
    rng = np.random.default_rng(0)
    ref = rng.uniform(0.1, 0.5, (6, 5, 3)).astype(np.float32)
    e = image_errors(ref, ref)
    assert e["rel_mse"] == 0 and e["max_err"] == 0 and math.isinf(e["psnr_db"])
    img = ref + np.float32(0.01)
    e = image_errors(img, ref)
    np.testing.assert_allclose(e["rel_mse"], 1e-4 * ref.size / np.sum(ref.astype(np.float64) ** 2), rtol=1e-4)
    np.testing.assert_allclose(e["max_err"], 0.01, rtol=1e-4)
    assert 30 < e["psnr_db"] < 60


def test_image_errors_reject_mismatched_shapes():
    from warp_sg.core.errors import InputError

    with pytest.raises(InputError, match="shape"):
        image_errors(np.zeros((2, 2, 3)), np.zeros((3, 2, 3)))


def test_knobs_come_from_the_scene_render_settings_and_copies_leave_the_scene_alone():
    from warp_sg.tools.bench import bench_scene

    sc = bench_scene(8, 6)
    knobs = available_knobs(sc)
    assert {"lobes", "supersampling", "env_lobes", "pca_terms", "ssdf_resolution"} <= set(knobs)
    assert set(knobs) <= set(KNOBS)
    sc2 = with_setting(sc, "lobes", 3)
    assert sc2.render.lobes == 3 and sc.render.lobes == knobs["lobes"]


def test_markdown_table_has_one_row_per_measurement():
    rows = [{"knob": "lobes", "value": v, "precompute_s": 0.1, "frame_s": 0.01 * v, "rel_mse": 1e-2 / v,
             "psnr_db": 30.0 + v, "max_err": 0.5} for v in (1, 2, 3)]
    t = markdown_table(rows).strip().splitlines()
    assert len(t) == 2 + 3 and t[2].startswith("| lobes | 1 |")


def test_tiny_report_writes_csv_markdown_plots_with_decreasing_mc_error(tmp_path, cache_dir):
    from warp_sg.tools.bench import bench_scene

    sc = bench_scene(12, 9, quick=True)
    rep = run_report(sc, tmp_path / "rep", quick=True, truth_spp=1024, mc_max_spp=128,
                     knobs=["lobes", "supersampling"], progress=False)  # per pixel; 4×4 sub-pixels
    umask = os.umask(0)
    os.umask(umask)
    for key in ("csv", "markdown", "plot", "plot_psnr", "images", "json"):
        assert rep.files[key].is_file() and rep.files[key].stat().st_size > 0, key
        assert rep.files[key].stat().st_mode & 0o777 == 0o666 & ~umask, key  # written by atomic_output
    assert not [f for f in rep.files["csv"].parent.iterdir() if f.name.startswith(".")]  # no temporaries left
    with open(rep.files["csv"]) as f:
        rows = list(csv.DictReader(f))
    kinds = [r["knob"] for r in rows]
    assert kinds.count("mc_reference") == 4  # spp 1, 2, 4, 8 per sub-pixel
    assert kinds.count("default") == 1
    assert kinds.count("lobes") == len(KNOBS["lobes"][1]) and kinds.count("supersampling") == len(KNOBS["supersampling"][1])
    for r in rows:
        for k in ("frame_s", "rel_mse", "psnr_db", "max_err"):
            assert math.isfinite(float(r[k])) or r[k] == "inf", (k, r)
    mc = [r for r in rep.rows if r["knob"] == "mc_reference"]
    assert [r["spp"] for r in mc] == [16, 32, 64, 128] and rep.truth_spp == 1024
    assert mc[-1]["rel_mse"] < mc[0]["rel_mse"] / 2  # MC error falls like 1/spp
    assert mc[-1]["psnr_db"] > mc[0]["psnr_db"]
    assert all(b["total_s"] >= a["total_s"] for a, b in zip(mc, mc[1:]))  # progressive: time grows
    ss = sorted((r for r in rep.rows if r["knob"] == "supersampling"), key=lambda r: r["value"])
    assert [r["value"] for r in ss] == sorted(KNOBS["supersampling"][1]) and all(r["frame_s"] > 0 for r in ss)
    assert rep.noise_floor_rel_mse < mc[-1]["rel_mse"]
    md = rep.files["markdown"].read_text()
    assert "error_vs_time.png" in md and "| knob |" in md
    assert "## Error by region" in md and "| lit_floor |" in md and "| silhouette |" in md


def test_region_errors_give_bias_per_channel_and_count_pixels_off_by_three_times():
    from warp_sg.groundtruth.region_error import region_errors

    ref = np.ones((4, 5, 3))
    img = ref * np.array([1.1, 1.0, 0.7])  # +10 %, 0, −30 %
    img[0, 0] = 5.0  # one pixel off by 5×
    m = np.zeros((4, 5), bool)
    m[0] = True  # 5 pixels
    e = region_errors(img, ref, {"object": m})["object"]
    assert e["pixels"] == 5
    np.testing.assert_allclose(e["bias_rgb"], [(4 * 1.1 + 5) / 5 - 1, (4 + 5) / 5 - 1, (4 * 0.7 + 5) / 5 - 1])
    assert e["bias"] == pytest.approx(0.88)  # the worst channel (red)
    assert e["off3"] == pytest.approx(1 / 5)
    np.testing.assert_allclose(e["rel_mse"], np.sum((img[m] - 1) ** 2) / 15)


def test_scene_regions_take_the_floor_by_name():
    """A plane named "ground" under a sphere lit from above: by default no floor (its pixels are
    ``object``); named as the floor, those pixels split into a lit floor and the sphere's shadow
    (a directional light 45° off the vertical: the shadow beside the sphere, seen from above)."""
    from warp_sg.groundtruth.region_error import scene_regions
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import DirectionalLight
    from warp_sg.scene.model import Material, Scene, SceneObject

    cam = Camera(origin=(0.0, 3.0, 0.01), target=(0.0, 0.0, 0.0), fov=50.0, width=32, height=32)
    objs = [SceneObject(material="m", primitive="sphere", params={"radius": 0.3, "center": (0.0, 0.8, 0.0)}),
            SceneObject(material="m", primitive="plane", name="ground", params={"size": (8.0, 8.0)})]
    sc = Scene(camera=cam, objects=objs, materials={"m": Material("lambert", {"kd": [0.5, 0.5, 0.5]})},
               lights=[DirectionalLight(direction=(1.0, 1.0, 0.0), radius=0.01, intensity=(1.0, 1.0, 1.0))])
    plain, named = scene_regions(sc), scene_regions(sc, floor=("Ground",))
    assert not plain["lit_floor"].any() and not plain["shadow"].any()
    assert np.array_equal(plain["object"], named["object"] | named["lit_floor"] | named["shadow"])
    assert named["lit_floor"].sum() > named["shadow"].sum() > 0
    assert named["object"].sum() > 0 and not (named["shadow"] & named["object"]).any()
    assert np.array_equal(plain["silhouette"], named["silhouette"])


def test_reused_precompute_gives_the_rows_of_a_fresh_cache_per_setting(tmp_path, cache_dir):
    """The sweep's settings share one cache (each stage built once per distinct input): the
    images, hence the error columns, are those of the slow path that rebuilds everything per
    setting, and every row still counts a whole precompute (what it reused at its build time)."""
    from warp_sg.core.cache import record_builds
    from warp_sg.tools.bench import bench_scene

    sc = bench_scene(12, 9, quick=True)
    knobs = ["ssdf_resolution", "pca_terms", "env_lobes", "lobes"]
    kw = dict(quick=True, truth_spp=256, mc_max_spp=32, knobs=knobs, progress=False, frames=1)
    with record_builds() as ledger:
        fast = run_report(sc, tmp_path / "fast", **kw).rows
    slow = run_report(sc, tmp_path / "slow", reuse=False, **kw).rows
    assert [(r["knob"], r["value"]) for r in fast] == [(r["knob"], r["value"]) for r in slow]
    for a, b in zip(fast, slow):
        for k in ("rel_mse", "psnr_db", "max_err"):
            assert a[k] == b[k], (a["knob"], a["value"], k)
    sweep = [r for r in fast if r["knob"] != "mc_reference"]
    assert all(r["precompute_s"] > 0 for r in sweep)
    # one SSDF build per SSDF resolution, PCA per term count; one environment fit per lobe count
    builds = [k for k, _, built in ledger.events if built]
    # default (16², 8 terms) also stands for ssdf_resolution 16; then 32², 4 terms, 16 terms
    assert builds.count("ssdf") == 4
    assert builds.count("ssdf_raw") == 2  # rays and distance search at 16² and 32² only
    assert builds.count("env_sg_fit") == 3  # 4 (default), 2 and 6 lobes


def test_a_report_against_mitsuba_takes_its_truth_from_the_independent_peer(tmp_path, cache_dir):
    """``truth="mitsuba"``: the ground truth is Mitsuba 3 through warp_sg.tools.mitsuba; the scene's own
    setting is then close to it (a Lambert sphere under a point light, direct light) and the report
    names its truth."""
    pytest.importorskip("mitsuba")
    import warp_sg as ws
    from warp_sg.scene.plain_scenes import write_plain_scene

    sc = ws.load_scene(write_plain_scene(tmp_path / "s", obj="sphere", light="point", material="lambert", size=16))
    rep = run_report(sc, tmp_path / "rep", quick=True, truth_spp=256, mc_max_spp=8, knobs=["antialias"],
                     progress=False, max_depth=2, truth="mitsuba")
    default = [r for r in rep.rows if r["knob"] == "default"][0]
    assert default["rel_mse"] < 0.02, default
    md = rep.files["markdown"].read_text()
    assert "Ground truth: Mitsuba 3" in md
    with pytest.raises(ws.InputError, match="--truth"):
        run_report(sc, tmp_path / "rep2", quick=True, truth="ours", progress=False)
