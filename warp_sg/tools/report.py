r"""Error against run time: ``warp-sg report SCENE -o DIR`` / :func:`run_report`.

For one scene it measures how the knobs that trade accuracy for speed move the renderer along
the error/time plane, next to the Monte-Carlo reference's own error-vs-samples curve:

1. **Ground truth**: a high-sample :func:`warp_sg.groundtruth.reference` image (``truth_spp`` samples per
   pixel, spread over the k×k sub-pixel grid the truth resolves; seed 1). Its own noise (mean
   squared standard error) is reported as the noise floor.
2. **MC curve**: an independent progressive reference run (seed 2); after every power-of-two
   ``spp`` its error against the ground truth and its elapsed time are recorded.
3. **Knob sweeps**: each render-setting knob the scene exposes (:data:`KNOBS`: SG lobes per NDF,
   clamped-cosine lobes, environment SG lobes, ΓL resolution and λ ladder, SSDF resolution and PCA
   terms, supersampling ...) is varied alone from the scene's settings; for every value the
   precompute time and the per-frame time (median of warm frames) are measured separately, and
   the image error against the ground truth. The settings share one fresh cache: a precompute
   stage (refinement, SSDF rays, PCA, environment fit, ΓL) is built once for each distinct input
   and reused by every setting that does not change it; a row's precompute time is what it costs
   with an empty cache (its own builds as measured plus the measured build time of what it
   reused). Rows are written to ``report.csv`` as they finish.

Errors (:func:`warp_sg.groundtruth.region_error.image_errors`): relative MSE ``Σ(x − r)² / Σ r²`` on linear radiance, PSNR of the
tone-mapped (``tonemap_srgb``) images, and the max absolute error (linear); for the scene's own
settings also per region (object, lit floor, shadow, silhouette band) with relative MSE, bias and
the fraction of pixels off by more than 3× (:mod:`warp_sg.groundtruth.region_error`). Outputs in ``DIR``:
``report.csv``, ``report.md`` (summary + table + embedded plots), ``error_vs_time.png`` (log-log,
one curve per knob, the MC curve on the same axes), ``psnr_vs_time.png``, ``images.png`` (truth,
renderer, difference), ``report.json``.

``warp-sg report SCENE --animation JOB.toml -o DIR`` reports an animation instead: per frame of a
``warp-sg batch`` job file, the region biases and the moved objects' shadow centroid offset
against that frame's reference (:mod:`warp_sg.tools.report_animation`).
"""
from __future__ import annotations

import contextlib
import copy
import dataclasses
import os
import statistics
import time
from pathlib import Path

import numpy as np

from warp_sg.core.cache import content_key, fresh_cache, note_build, note_hit, record_builds
from warp_sg.core.device import add_device_argument, device_for
from warp_sg.core.errors import InputError
from warp_sg.core.files import output_folder
from warp_sg.groundtruth.region_error import image_errors
from warp_sg.scene.camera import with_resolution
from warp_sg.tools.report_outputs import write_outputs, write_rows_csv

# knob name -> (full sweep, quick sweep); only knobs present in the scene's render settings run.
KNOBS: dict[str, tuple[list, list]] = {
    "lobes": ([1, 2, 3, 4], [1, 3]),
    "ndf_lobes": ([1, 2, 3, 4], [1, 3]),
    "cosine_lobes": ([1, 2, 3, 4], [1, 3]),
    "env_peaks": ([0, 1, 4], [0, 1]),
    "env_lobes": ([2, 4, 6, 9, 12], [2, 6]),
    "env_sg_lobes": ([2, 4, 6, 9, 12], [2, 6]),
    "gamma_resolution": ([8, 16, 32, 64, 96], [8, 16]),
    "gamma_levels": ([4, 6, 8, 12], [4, 8]),
    "gamma_lambda_count": ([4, 6, 8, 12], [4, 8]),
    "ssdf_resolution": ([12, 16, 24, 32, 48], [16, 32]),
    "pca_terms": ([2, 4, 8, 16, 24], [4, 16]),
    "supersampling": ([1, 2, 3], [1, 2]),
    "antialias": ([1, 4, 6], [1, 4]),
}

#: samples per pixel of the ground truth (its noise floor is printed in the report; at the default
#: sweep's 6×6 grid that is 113 samples per sub-pixel)
DEFAULT_TRUTH_SPP = 4096



# --------------------------------------------------------------------------------------------
# errors
# --------------------------------------------------------------------------------------------
# --------------------------------------------------------------------------------------------
# scene plumbing (Scene / Renderer come from warp_sg.scene and warp_sg.renderer.renderer)
# --------------------------------------------------------------------------------------------
def _load(scene):
    if isinstance(scene, (str, os.PathLike)):
        from warp_sg.scene.loader import load_scene

        return load_scene(scene)
    return scene


def _settings(scene):
    return getattr(scene, "render", None) or getattr(scene, "settings", None)


def available_knobs(scene) -> dict[str, object]:
    """Knobs of :data:`KNOBS` that the scene's render settings expose, with their current values."""
    s = _settings(scene)
    out = {}
    if s is None:
        return out
    for k in KNOBS:
        v = s.get(k) if isinstance(s, dict) else getattr(s, k, None)
        if v is not None and not isinstance(v, bool):
            out[k] = v
    return out


def with_setting(scene, knob, value):
    """A copy of ``scene`` with render setting ``knob`` set to ``value``."""
    sc = copy.copy(scene)
    s = _settings(scene)
    if isinstance(s, dict):
        s2 = dict(s)
        s2[knob] = value
    elif dataclasses.is_dataclass(s):
        s2 = dataclasses.replace(s, **{knob: value})
    else:
        s2 = copy.copy(s)
        setattr(s2, knob, value)
    if hasattr(scene, "render") and not callable(scene.render):
        sc.render = s2
    else:
        sc.settings = s2
    return sc


def time_renderer(scene, device="cpu", frames=3, ledger=None, memo=None):
    """(image, precompute seconds, per-frame seconds) for ``scene`` with an empty cache.

    Uses ``warp_sg.renderer.renderer.Renderer`` (precompute once, then ``frames`` warm frames; median).
    With a ``ledger`` (:func:`warp_sg.core.cache.record_builds`, recording into the report's one cache)
    the precompute reuses what earlier settings built, and its time is the measured construction
    plus the build time of every entry it found (what an empty cache would have cost); ``memo``:
    the report's :class:`RawSSDFMemo`. The precompute stages run one after the other
    (``Renderer.overlap_precompute`` off), so that a setting's time is the sum of its stages'."""
    from warp_sg.renderer.renderer import Renderer

    def run():
        mark = ledger.mark() if ledger is not None else 0
        t0 = time.perf_counter()
        overlap, Renderer.overlap_precompute = Renderer.overlap_precompute, False  # stage times add up
        try:
            r = Renderer(scene, device=device, ssdf_compute=memo)
        finally:
            Renderer.overlap_precompute = overlap
        t_pre = time.perf_counter() - t0
        if ledger is not None:
            t_pre += ledger.hit_cost(mark)[0]
        img = np.asarray(r.render())  # first frame: compiles / uploads (not counted as a frame)
        times = []
        for _ in range(max(1, frames)):
            t1 = time.perf_counter()
            img = np.asarray(r.render())
            times.append(time.perf_counter() - t1)
        return img, t_pre, statistics.median(times)

    if ledger is not None:
        return run()
    with fresh_cache():
        return run()


class RawSSDFMemo:
    """The report's ``ssdf_compute``: the uncompressed SSDFs (rays and distance search,
    ``precompute.compute_ssdf``) of a mesh at a resolution are computed once, so settings that
    change only their compression (``pca_terms``) or nothing of them re-run PCA only. The same
    function with the same arguments: the same SSDFs. Computations and reuses are entered in the
    recording ledgers (:func:`warp_sg.core.cache.note_build`, kind ``ssdf_raw``) so the reused ones count
    at their build time."""

    def __init__(self):
        self._memo: dict = {}

    def __call__(self, vertices, triangles, normals, *, resolution, ray_resolution, device="cpu", progress=True):
        from precompute.visibility.ssdf import compute_ssdf

        key = content_key(np.asarray(vertices, np.float32), np.asarray(triangles, np.int32),
                          np.asarray(normals, np.float32), {"resolution": int(resolution),
                                                            "ray_resolution": int(ray_resolution)})
        if key in self._memo:
            note_hit("ssdf_raw", key)
            return self._memo[key]
        w0, c0 = time.perf_counter(), time.process_time()
        X = compute_ssdf(vertices, triangles, normals, resolution=resolution, ray_resolution=ray_resolution,
                         device=device, progress=progress)
        note_build("ssdf_raw", key, time.perf_counter() - w0, time.process_time() - c0)
        self._memo[key] = X
        return X


# --------------------------------------------------------------------------------------------
# the report
# --------------------------------------------------------------------------------------------
@dataclasses.dataclass
class Report:
    out_dir: Path
    rows: list  # dicts with report_outputs.CSV_FIELDS
    truth_spp: int
    noise_floor_rel_mse: float
    files: dict


def mc_curve(scene, truth, device="cpu", max_spp=64, seed=2, progress=True, per_sample: int = 1,
             max_depth: int | None = None):
    """Error-vs-time rows of a progressive reference run at every power of two up to ``max_spp``
    samples per sub-pixel of ``scene``; ``per_sample``: sub-pixels per pixel (the rows' ``spp``
    count samples per pixel); ``max_depth``: its paths' (default the full path tracer's)."""
    from warp_sg.groundtruth.reference import DEFAULT_MAX_DEPTH, render_reference

    rows = []

    def cb(spp, seconds, img, se):
        if spp & (spp - 1) == 0 or spp == max_spp:
            rows.append({"knob": "mc_reference", "value": spp * per_sample, "precompute_s": 0.0, "frame_s": seconds,
                         "total_s": seconds, "spp": spp * per_sample, **image_errors(img, truth)})

    render_reference(scene, spp=max_spp, device=device, progress=progress, seed=seed, callback=cb,
                     max_depth=DEFAULT_MAX_DEPTH if max_depth is None else max_depth)
    return rows


def run_report(scene, out_dir, device=None, quick=False, truth_spp=None, mc_max_spp=None, knobs=None,
               progress=True, frames=None, width=None, height=None, cluster=None, reuse=True,
               max_depth: int | None = None, truth: str = "reference") -> Report:
    """Run the sweep for ``scene`` (a Scene or a path) and write the report into ``out_dir``.

    ``reuse`` (default): the settings share one fresh cache, so each precompute stage is built
    once per distinct input and reused by the settings that do not change it (the uncompressed
    SSDFs too, :class:`RawSSDFMemo`); a row's ``precompute_s`` is its measured construction plus
    the build time of everything it reused, i.e. what it costs with an empty cache. ``reuse=False``:
    a fresh cache for every setting (the same rows, each precompute measured whole). ``report.csv``
    is rewritten after every row.

    ``cluster`` (a Dask cluster spec / Client, :mod:`warp_sg.distributed.rendering`): the ground truth's
    samples are split across its workers (same image bit for bit); ``None``: all local, no Dask.

    ``width``/``height`` override the camera's resolution (the reference's cost grows with it);
    ``device=None`` is the scene's ``[render] device``. ``max_depth``: the ground truth's paths
    (default the full path tracer; 2: direct light only, against the scene rendered with ``bounces
    = 0``: the paper's part alone, :func:`warp_sg.groundtruth.reference.matching_transport`).
    ``truth``: ``"reference"`` (our Monte-Carlo reference, which shares the BRDF code) or ``"mitsuba"``
    (Mitsuba 3 through the independent peer, :mod:`warp_sg.tools.mitsuba`: the BRDFs from their
    published formulas; its box filter needs no sub-pixel grid)."""
    from warp_sg.groundtruth.reference import DEFAULT_MAX_DEPTH, check_max_depth, matching_transport, render_reference

    max_depth = check_max_depth(DEFAULT_MAX_DEPTH if max_depth is None else max_depth, "--max-depth")
    scene = matching_transport(with_resolution(_load(scene), width, height), max_depth)
    device = device_for(device, scene)
    out = output_folder(out_dir)
    truth_spp = int(truth_spp or (64 if quick else DEFAULT_TRUTH_SPP))
    mc_max_spp = int(mc_max_spp or max(1, truth_spp // 8))
    frames = frames or (1 if quick else 3)

    avail = available_knobs(scene)
    if knobs is not None:
        avail = {k: v for k, v in avail.items() if k in knobs}
    sweep = [(k, v) for k, cur in avail.items() for v in (KNOBS[k][1] if quick else KNOBS[k][0])]
    # the ground truth resolves pixels at least as finely as any swept supersampling or
    # antialiasing grid, so those knobs' errors include their aliasing
    rs0 = _settings(scene)
    aa = [int(getattr(rs0, "antialias", 1))] + [int(v) for k, v in sweep if k == "antialias"]
    k_truth = max([int(rs0.supersampling)] + [int(v) for k, v in sweep if k == "supersampling"] + aa)
    truth_scene = scene if k_truth == _settings(scene).supersampling else with_setting(scene, "supersampling", k_truth)

    per = k_truth * k_truth  # the spp counts are per pixel, spread over the k×k sub-pixels
    sub_spp = max(1, truth_spp // per)
    if truth not in ("reference", "mitsuba"):
        raise InputError(f"must be 'reference' or 'mitsuba', got {truth!r}", where="--truth")
    t0 = time.perf_counter()
    label = None
    if truth == "mitsuba":
        from warp_sg.tools.mitsuba.render import mitsuba_reference

        truth = mitsuba_reference(scene, spp=truth_spp, max_depth=max_depth, seed=1)
        label = (f"Mitsuba 3 ({truth.variant}, the BRDFs from their published formulas: warp_sg.tools.mitsuba) "
                 f"with {truth.spp} samples per pixel, box filter, max_depth {max_depth}")
    elif cluster is not None:
        from warp_sg.distributed.rendering import render_reference_distributed

        truth = render_reference_distributed(truth_scene, spp=sub_spp, cluster=cluster, device=device,
                                             progress=progress, seed=1, max_depth=max_depth)
    else:
        truth = render_reference(truth_scene, spp=sub_spp, device=device, progress=progress, seed=1,
                                 max_depth=max_depth)
    truth_time = time.perf_counter() - t0
    floor = float(np.sum(truth.stderr.astype(np.float64) ** 2) / max(np.sum(truth.image.astype(np.float64) ** 2),
                                                                        1e-300))
    rows = mc_curve(truth_scene, truth.image, device, max(1, mc_max_spp // per), progress=progress, per_sample=per,
                    max_depth=max_depth)
    write_rows_csv(out, rows)
    base_img = None
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(sweep) + 1, desc="report sweep", unit="setting", leave=False)
    with contextlib.ExitStack() as stack:
        ledger = memo = None
        if reuse:  # one cache for the sweep: a setting rebuilds only what it changes
            stack.enter_context(fresh_cache())
            ledger = stack.enter_context(record_builds())
            memo = RawSSDFMemo()
        if bar is not None:
            stack.callback(bar.close)
        for knob, value in [("default", "scene")] + sweep:
            sc = scene if knob == "default" else with_setting(scene, knob, value)
            img, tp, tf = time_renderer(sc, device, frames, ledger=ledger, memo=memo)
            if knob == "default":
                base_img = img
            rows.append({"knob": knob, "value": value, "precompute_s": tp, "frame_s": tf, "total_s": tp + tf,
                         "spp": "", **image_errors(img, truth.image)})
            write_rows_csv(out, rows)  # each row as it finishes
            if bar is not None:
                bar.update(1)

    from warp_sg.groundtruth.region_error import region_errors, scene_regions

    regions = region_errors(base_img, truth.image, scene_regions(scene, device=device)) if base_img is not None else None
    files = write_outputs(out, rows, truth.image, base_img, sub_spp * per, floor, truth_time, scene, k_truth,
                          regions=regions, truth_label=label)
    return Report(out, rows, sub_spp * per, floor, files)


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def add_cli_arguments(p) -> None:
    p.add_argument("scene", help="scene file (TOML)")
    p.add_argument("-o", "--output", required=True, help="output folder")
    add_device_argument(p)
    p.add_argument("--quick", action="store_true", help="small sweep (smoke test)")
    p.add_argument("--truth-spp", type=int, default=None,
                   help=f"samples per pixel of the ground truth (default {DEFAULT_TRUTH_SPP}; --quick: 64)")
    p.add_argument("--width", type=int, default=None, help="override the camera width (keeps the aspect)")
    p.add_argument("--height", type=int, default=None, help="override the camera height")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--truth", choices=("reference", "mitsuba"), default="reference",
                   help="the ground truth: our Monte-Carlo reference, or Mitsuba 3 with the BRDFs written from their "
                        "published formulas (warp_sg.tools.mitsuba; independent of our BRDF code)")
    p.add_argument("--max-depth", type=int, default=None, metavar="N",
                   help="the ground truth's path segments (default: a full path tracer; 2: direct light only, "
                        "compared with the scene rendered with bounces = 0, the paper's part alone)")
    p.add_argument("--cluster", default=None, metavar="local:N|tcp://HOST:PORT",
                   help="split the ground truth's samples across a Dask cluster (docs/distributed.md)")
    p.add_argument("--animation", default=None, metavar="JOB.toml",
                   help="per-frame errors of an animation instead of the sweep: the frames of a `warp-sg batch` "
                        "job file (object transforms, camera, ...) against each frame's MC reference "
                        "(--truth-spp samples per pixel, default 1024; --quick: 64); writes animation.csv/.md")


def cli_main(args) -> int:
    if getattr(args, "max_depth", None) is not None:
        from warp_sg.groundtruth.reference import check_max_depth

        check_max_depth(args.max_depth, "--max-depth")
    if args.truth_spp is not None and args.truth_spp < 1:
        raise InputError(f"must be >= 1, got {args.truth_spp}", where="--truth-spp")
    for k in ("width", "height"):
        v = getattr(args, k)
        if v is not None and v < 1:
            raise InputError(f"must be >= 1, got {v}", where=f"--{k}")
    if getattr(args, "animation", None) is not None:
        from warp_sg.tools.report_animation import run_animation_report

        if args.cluster:
            raise InputError("an animation report renders its references on this machine", where="--cluster")
        rep = run_animation_report(args.scene, args.animation, args.output, device=args.device, spp=args.truth_spp,
                                   quick=args.quick, progress=not args.no_progress, width=args.width,
                                   height=args.height)
        print(f"animation report ({len(rep.rows)} frames) written to {rep.files['markdown']}")
        return 0
    rep = run_report(args.scene, args.output, device=args.device, quick=args.quick, truth_spp=args.truth_spp,
                     progress=not args.no_progress, width=args.width, height=args.height,
                     cluster=getattr(args, "cluster", None), max_depth=getattr(args, "max_depth", None),
                     truth=getattr(args, "truth", "reference"))
    print(f"report written to {rep.files['markdown']}")
    return 0


__all__ = ["run_report", "image_errors", "KNOBS", "available_knobs", "with_setting", "mc_curve", "Report",
           "add_cli_arguments", "cli_main"]
