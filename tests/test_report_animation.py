"""``warp-sg report SCENE --animation JOB.toml`` (:mod:`warp_sg.tools.report_animation`): its rows are
the region errors and shadow centroids of the frames it wrote, recomputed here from the scene at
each pose; its reference is the reference of the scene moved there; its frames are those of a
fresh renderer moved the same way; a bad job file is one line and exit status 2."""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest

import warp_sg as ws
from warp_sg.core.image_io import load_image
from warp_sg.groundtruth.region_error import box_reference, region_errors, scene_regions, shadow_centroid
from warp_sg.numeric.rigid_motion import motion_from_fields
from warp_sg.renderer.dynamic_objects import scene_with_transforms
from warp_sg.scene.plain_scenes import write_plain_scene
from warp_sg.tools.cli import main

SMALL = {"ssdf_resolution": 16, "pca_terms": 16, "visibility_budget": 4000}
POSES = [{"translate": [-0.6, 0.0, 0.2]}, {"translate": [0.5, 0.0, -0.3], "rotate": [0.0, 0.0, -40.0],
                                          "pivot": [0.0, 0.5, 0.0]}]


def _job(folder, poses, scene="scene.toml", extra=""):
    text = [f'scene = "{scene}"', 'output = "frames/f_{index:03d}.png"', extra]
    for p in poses:
        text.append("[[frames]]")
        text.append("objects.object = { " + ", ".join(f"{k} = {v}" for k, v in p.items()) + " }")
    path = folder / "job.toml"
    path.write_text("\n".join(text) + "\n")
    return path


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    folder = tmp_path_factory.mktemp("anim")
    scene = write_plain_scene(folder, size=32, dynamic=True, render=SMALL)
    out = folder / "report"
    rc = main(["report", str(scene), "--animation", str(_job(folder, POSES)), "-o", str(out), "--truth-spp", "64",
               "--no-progress"])
    assert rc == 0
    with open(out / "animation.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return scene, out, rows


def test_animation_report_writes_one_finite_row_per_frame(report):
    _, out, rows = report
    assert [int(r["frame"]) for r in rows] == [0, 1]
    for r in rows:
        for k in ("object_bias", "lit_floor_bias", "shadow_bias", "silhouette_bias", "centroid_px", "frame_s",
                  "reference_s"):
            assert math.isfinite(float(r[k])), (k, r[k])
    md = (out / "animation.md").read_text()
    assert md.count("\n| 0 |") == 1 and md.count("\n| 1 |") == 1 and "worst" in md


def test_animation_rows_are_the_region_errors_of_the_scene_at_each_pose(report):
    """Recomputed from the written images and the scene moved by the job's fields (not the
    renderer's own state): the masks, biases and centroid offsets equal the rows; the reference
    is the reference of the moved scene bit for bit; the frame is a fresh renderer's moved the
    same way; the objects-away images show no object."""
    scene_path, out, rows = report
    base = ws.load_scene(scene_path)
    fresh = ws.Renderer(ws.load_scene(scene_path))
    for i, (pose, row) in enumerate(zip(POSES, rows)):
        M = motion_from_fields(pose)
        at = scene_with_transforms(base, {"object": M})
        img = load_image(out / "frames" / f"ours_{i:03d}.exr")
        ref = load_image(out / "frames" / f"reference_{i:03d}.exr")
        assert np.array_equal(ref, box_reference(at, spp=64, supersample=4, seed=0))
        fresh.set_object_transform("object", M)
        assert np.array_equal(img, fresh.render())
        reg = scene_regions(at)
        e = region_errors(img, ref, reg)
        for k in ("object", "lit_floor", "shadow", "silhouette"):
            assert float(row[f"{k}_bias"]) == pytest.approx(e[k]["bias"], rel=1e-12, abs=1e-15)
        assert float(row["shadow_leak"]) == pytest.approx(e["shadow"]["leak"], rel=1e-12, abs=1e-15)
        k = int(row["away"])
        u_ours = load_image(out / "frames" / f"away_ours_{k:03d}.exr")
        u_ref = load_image(out / "frames" / f"away_reference_{k:03d}.exr")
        floor = reg["lit_floor"] | reg["shadow"]
        dc = np.linalg.norm(shadow_centroid(img, u_ours, floor) - shadow_centroid(ref, u_ref, floor))
        assert float(row["centroid_px"]) == pytest.approx(dc, rel=1e-12, abs=1e-15)
    assert {r["away"] for r in rows} == {"0"}  # the rest of the frame is the same: one objects-away pair
    from warp_sg.tools.report_animation import away_motion

    gone = scene_with_transforms(base, {"object": away_motion(base)})
    assert not scene_regions(gone)["object"].any()


def test_animation_report_of_a_scene_object_leaves_it_as_it_was(tmp_path):
    """From Python, with a list of variants: the scene given is not moved by the report's renderer
    (its objects-away pose was the last one set)."""
    from warp_sg.tools.report_animation import run_animation_report

    sc = ws.load_scene(write_plain_scene(tmp_path, size=8, dynamic=True, render=SMALL))
    rep = run_animation_report(sc, [{"objects": {"object": {"translate": [0.3, 0.0, 0.0]}}}], tmp_path / "r", spp=4,
                               progress=False)
    assert len(rep.rows) == 1 and rep.rows[0]["away"] == 0
    assert sc.objects[0].motion is None


@pytest.mark.parametrize("case, message", [
    ("static", "not dynamic"),
    ("scene", "not the report's scene"),
    ("toml", "not valid TOML"),
    ("field", "unknown object field"),
])
def test_bad_animation_job_is_one_line_and_exit_2(tmp_path, capsys, case, message):
    scene = write_plain_scene(tmp_path, size=8, dynamic=True, render=SMALL)
    if case == "static":
        job = _job(tmp_path, POSES)
        job.write_text(job.read_text().replace("objects.object", "objects.floor"))
    elif case == "scene":
        (tmp_path / "other.toml").write_text(scene.read_text())
        job = _job(tmp_path, POSES, scene="other.toml")
    elif case == "toml":
        job = _job(tmp_path, POSES, extra="frames = [")
    else:
        job = _job(tmp_path, [{"spin": 3.0}])
    out = tmp_path / "report"
    rc = main(["report", str(scene), "--animation", str(job), "-o", str(out), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and message in err[0], err
    assert not out.exists()  # checked before any work
