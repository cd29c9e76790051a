r"""Per-frame error of an animation against the Monte-Carlo reference (issue 30):
``warp-sg report SCENE --animation JOB.toml -o DIR`` / :func:`run_animation_report`.

The frames are those of a ``warp-sg batch`` job file (:func:`warp_sg.distributed.batch.load_job`:
``[[frames]]``, ``[grid]``, ``[animate]``; camera, material, light, environment and
``objects.NAME`` transform changes; its ``scene`` must be SCENE, its ``output`` / ``cluster`` /
``exposure`` are the batch's own and are not used here), or, from Python, a list of variants
(:func:`warp_sg.distributed.rendering.normalize_variants`). One :class:`~warp_sg.renderer.renderer.Renderer`
renders every frame through its setters (``set_object_transform`` for moving objects: no
precompute per frame), after one warm-up frame. For each frame:

* the Monte-Carlo reference of the scene at that frame (``Renderer.scene`` follows every setter,
  the motion included: what ``warp-sg reference --transform`` renders), box-filtered over each pixel
  (:func:`warp_sg.groundtruth.region_error.box_reference`, ``spp`` samples per pixel over a
  ``supersample``² grid, seed ``seed``);
* the bias per region of :func:`~warp_sg.groundtruth.region_error.region_errors` over the masks of
  :func:`~warp_sg.groundtruth.region_error.scene_regions` at that frame: object, lit floor, shadow (and
  its ``leak``: its mean error as a fraction of the lit floor's), silhouette band; the image's
  relative MSE;
* the **shadow centroid offset**: ``|c_ours − c_ref|`` in pixels, where each centroid is
  :func:`~warp_sg.groundtruth.region_error.shadow_centroid` of the floor's darkening against the same
  frame with the moved objects (the dynamic objects the animation moves) taken away — translated
  100 scene diagonals behind the camera — in ours and in the reference respectively. Those two
  images are rendered once per distinct rest of the frame (usually once for the whole animation);
  empty when nothing moves;
* the frame time (the setters and ``render()``, seconds) and the reference's.

Outputs in ``DIR``, each rewritten atomically after every frame: ``animation.csv`` (the rows:
:data:`ANIMATION_FIELDS`), ``animation.md`` (the table, the worst frame per column), and at the
end ``animation.json``; the images in ``DIR/frames`` (float32 EXR): ``ours_NNN.exr``,
``reference_NNN.exr`` and the objects-away pair ``away_ours_K.exr`` / ``away_reference_K.exr`` of
the row's ``away`` index K.
"""
from __future__ import annotations

import copy
import csv
import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np

from warp_sg.core.errors import InputError
from warp_sg.core.files import atomic_output, output_folder
from warp_sg.scene.camera import with_resolution

#: the columns of ``animation.csv`` (biases as fractions, the centroid offset in pixels)
ANIMATION_FIELDS = ["frame", "object_bias", "lit_floor_bias", "shadow_bias", "shadow_leak", "silhouette_bias",
                    "rel_mse", "centroid_px", "away", "frame_s", "reference_s"]
#: samples per pixel of each frame's reference unless given (``--quick``: 64)
DEFAULT_ANIMATION_SPP = 1024
#: how far the moved objects are taken for the unoccluded images, in scene bounding-box diagonals
AWAY_DIAGONALS = 100.0


@dataclasses.dataclass
class AnimationReport:
    out_dir: Path
    rows: list
    files: dict


def animation_variants(scene, animation, scene_path=None) -> list[dict]:
    """Full-state variants of ``animation`` (a job file path, a :class:`~warp_sg.distributed.batch.Job`
    or a list of variant dicts) for ``scene``; a job whose ``scene`` is not ``scene_path`` (when
    given) is refused. Every variant is checked before any work."""
    from warp_sg.distributed.batch import Job, load_job
    from warp_sg.distributed.rendering import normalize_variants

    if isinstance(animation, (str, Path)):
        animation = load_job(animation)
    if isinstance(animation, Job):
        if scene_path is not None and Path(animation.scene).resolve() != Path(scene_path).resolve():
            raise InputError(f"the job renders '{animation.scene}', not the report's scene '{scene_path}'",
                             where=str(animation.path))
        animation = animation.variants
    variants = list(animation)
    if not variants:
        raise InputError("the animation has no frames", where="--animation")
    return normalize_variants(scene, variants)


def moved_objects(scene, variants) -> list:
    """The objects (as the variants name them) that the variants move."""
    return sorted({name for v in variants for name in v.get("objects", {})}, key=str)


def away_motion(scene) -> np.ndarray:
    """A translation that takes an object about :data:`AWAY_DIAGONALS` scene diagonals behind the
    camera (out of view, its shadow and its occlusion of the sky gone)."""
    g = scene.geometry()
    diag = float(np.linalg.norm(g.vertices.max(0) - g.vertices.min(0))) if len(g.vertices) else 1.0
    cam = scene.camera
    fwd = np.asarray(cam.target, np.float64) - np.asarray(cam.origin, np.float64)
    M = np.eye(4)
    M[:3, 3] = -AWAY_DIAGONALS * max(diag, 1e-6) * fwd / max(np.linalg.norm(fwd), 1e-30)
    return M


def frame_row(index: int, img, ref, regions: dict, centroids=None) -> dict:
    """The error columns of one frame: region biases, shadow leak and relative MSE of ``img``
    against ``ref`` over ``regions``; ``centroids``: ((row, col) ours, (row, col) reference) or None."""
    from warp_sg.groundtruth.region_error import image_errors, region_errors

    e = region_errors(img, ref, regions)
    row = {"frame": index, **{f"{k}_bias": e[k]["bias"] for k in ("object", "lit_floor", "shadow", "silhouette")},
           "shadow_leak": e["shadow"].get("leak", float("nan")), "rel_mse": image_errors(img, ref)["rel_mse"]}
    row["centroid_px"] = float("nan") if centroids is None else float(np.linalg.norm(centroids[0] - centroids[1]))
    return row


def _fmt(v, pct=False) -> str:
    if isinstance(v, float):
        if math.isnan(v):
            return "—"
        return f"{100 * v:+.2f} %" if pct else f"{v:.4g}"
    return str(v)


def markdown(rows, header: list[str]) -> str:
    """``animation.md``: the per-frame table and the worst frame of each error column."""
    cols = [("frame", "frame", False), ("object_bias", "object", True), ("lit_floor_bias", "lit floor", True),
            ("shadow_bias", "shadow", True), ("shadow_leak", "shadow leak (of lit)", True),
            ("silhouette_bias", "silhouette", True), ("rel_mse", "rel. MSE", False),
            ("centroid_px", "shadow centroid Δ (px)", False), ("frame_s", "frame (s)", False),
            ("reference_s", "reference (s)", False)]
    lines = header + ["| " + " | ".join(c[1] for c in cols) + " |", "|" + "---:|" * len(cols)]
    for r in rows:
        lines.append("| " + " | ".join(_fmt(r[k], pct) for k, _, pct in cols) + " |")
    worst = {}
    for k, _, _ in cols[1:8]:
        vals = [abs(r[k]) for r in rows if isinstance(r[k], float) and not math.isnan(r[k])]
        worst[k] = max(vals) if vals else float("nan")
    lines.append("| worst (magnitude) | " + " | ".join(
        "—" if math.isnan(worst[k]) else f"{100 * worst[k]:.2f} %" if pct else f"{worst[k]:.4g}"
        for k, _, pct in cols[1:8]) + " | | |")
    return "\n".join(lines) + "\n"


def write_animation_files(out: Path, rows, header: list[str]) -> dict:
    """``animation.csv`` and ``animation.md`` of the rows so far (each written atomically)."""
    out = Path(out)
    csv_path, md_path = out / "animation.csv", out / "animation.md"
    with atomic_output(csv_path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=ANIMATION_FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(r[k]) if isinstance(r.get(k), float) else r.get(k, "")) for k in ANIMATION_FIELDS})
    with atomic_output(md_path) as tmp:
        Path(tmp).write_text(markdown(rows, header))
    return {"csv": csv_path, "markdown": md_path}


def run_animation_report(scene, animation, out_dir, device=None, spp=None, supersample: int = 4, seed: int = 0,
                         progress: bool = True, width=None, height=None, quick: bool = False) -> AnimationReport:
    """Render every frame of ``animation`` with one Renderer and its Monte-Carlo reference, and
    write the per-frame rows into ``out_dir`` (module docstring). ``scene``: a Scene or a scene
    file (a Scene is copied, not changed); ``animation``: a job file, a Job or a list of variants;
    ``spp``: samples per pixel of each reference (default :data:`DEFAULT_ANIMATION_SPP`, ``quick``: 64)."""
    from warp_sg.core.device import device_for
    from warp_sg.core.image_io import save_image
    from warp_sg.distributed.rendering import apply_variant
    from warp_sg.groundtruth.region_error import box_reference, scene_regions, shadow_centroid
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.scene.loader import load_scene

    scene_path = scene if isinstance(scene, (str, Path)) else None
    # (a copy: the renderer's setters change its scene, the caller's stays as it was)
    scene = with_resolution(load_scene(scene) if scene_path is not None else copy.deepcopy(scene), width, height)
    variants = animation_variants(scene, animation, scene_path)
    spp = int(spp or (64 if quick else DEFAULT_ANIMATION_SPP))
    if spp < 1 or int(supersample) < 1:
        raise InputError(f"spp and supersample must be >= 1, got {spp} and {supersample}", where="animation report")
    out = output_folder(out_dir)
    frames = out / "frames"
    frames.mkdir(exist_ok=True)
    device = device_for(device, scene)
    moved = moved_objects(scene, variants)
    h, w = scene.camera.height, scene.camera.width
    header = ["# Animation against the Monte-Carlo reference", "",
              f"Scene: `{getattr(scene, 'path', None) or 'in memory'}`, {w}×{h} pixels, {len(variants)} frames; "
              f"each frame's reference {spp} samples per pixel ({supersample}×{supersample} box, seed {seed}). "
              f"Bias = mean(ours)/mean(reference) − 1 per region (worst channel); the shadow centroid Δ is "
              f"between ours and the reference, each against its own image with "
              f"{', '.join(map(str, moved)) or 'nothing'} taken away.", ""]
    r = Renderer(scene, device=device, progress=progress)
    r.render()  # the warm-up frame: compiles and uploads (not counted)
    away, away_keys, rows = away_motion(scene), {}, []
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(variants), desc="animation report", unit="frame", leave=False)
    try:
        for i, v in enumerate(variants):
            t0 = time.perf_counter()
            apply_variant(r, v)
            img = np.array(r.render(), np.float32)
            frame_s = time.perf_counter() - t0
            t0 = time.perf_counter()
            ref = box_reference(r.scene, spp=spp, supersample=supersample, device=device, seed=seed)
            reference_s = time.perf_counter() - t0
            regions = scene_regions(r.scene, device=device)
            centroids, k = None, ""
            if moved:
                rest = json.dumps({s: b for s, b in v.items() if s != "objects"}, sort_keys=True, default=str)
                if rest not in away_keys:  # the frame without the moved objects (the next variant puts them back)
                    for name in moved:
                        r.set_object_transform(name, away)
                    k = len(away_keys)
                    u = (np.array(r.render(), np.float32),
                         box_reference(r.scene, spp=spp, supersample=supersample, device=device, seed=seed))
                    save_image(frames / f"away_ours_{k:03d}.exr", u[0])
                    save_image(frames / f"away_reference_{k:03d}.exr", u[1])
                    away_keys[rest] = (k, u)
                k, (u_ours, u_ref) = away_keys[rest]
                floor = regions["lit_floor"] | regions["shadow"]
                centroids = (shadow_centroid(img, u_ours, floor), shadow_centroid(ref, u_ref, floor))
            save_image(frames / f"ours_{i:03d}.exr", img)
            save_image(frames / f"reference_{i:03d}.exr", ref)
            rows.append({**frame_row(i, img, ref, regions, centroids), "away": k, "frame_s": frame_s,
                         "reference_s": reference_s})
            files = write_animation_files(out, rows, header)  # each row as it finishes
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    meta = {"frames": len(variants), "width": int(w), "height": int(h), "spp": spp, "supersample": int(supersample),
            "seed": int(seed), "moved": [str(m) for m in moved], "rows": rows}
    with atomic_output(out / "animation.json") as tmp:
        Path(tmp).write_text(json.dumps(meta, indent=1, default=str))
    files["json"] = out / "animation.json"
    return AnimationReport(out, rows, files)


__all__ = ["ANIMATION_FIELDS", "DEFAULT_ANIMATION_SPP", "AnimationReport", "animation_variants", "moved_objects",
           "away_motion", "frame_row", "markdown", "write_animation_files", "run_animation_report"]
