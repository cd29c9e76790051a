r"""``warp-sg bench`` / :func:`run_bench`: the performance ratios of the project, measured in one run.

Sections (each a list of rows; ratios are relative to the first row of the section, and only the
ratios are meant to carry over between machines):

1. **visibility** — the tile rasterizer against ``wp.Mesh`` ray casting for primary visibility
   (``warp_sg.tools.bench_raster.run_bench``).
2. **shading** — per-frame cost of the SG renderer on the bench scene by scene feature, which
   shows what the kernel specialisation saves: full scene (environment + local lights + specular
   materials + SSDF shadows) vs no environment, no local lights, diffuse-only materials, shadows
   off; plus the precompute with an empty cache vs a warm cache (precompute skipped).
3. **precompute** — SSDF + PCA time by mesh size (``warp_sg.tools.bench_precompute.run_bench``; its document
   outputs go to a temporary folder).
4. **equal error** — the SG renderer against our Monte-Carlo reference: the renderer's relative
   MSE against a high-sample reference, the samples per pixel the reference needs to reach the
   same error (log-log interpolation between powers of two) and the time ratio; on the bench
   scene and on a plain-input scene (2-triangle floor, sun-sky EXR).
5. **frame scaling** — warm frame time by pixel count and by triangle count, full shading
   (:mod:`warp_sg.tools.bench_scaling`).
6. **equal error vs Mitsuba 3** — on the scenes Mitsuba renders with its own plugins; and **every
   model** — the accuracy matrix's sphere per BRDF model at 512², Mitsuba through the independent
   peer, Mitsuba's time to our error from its measured per-sample variance
   (:mod:`warp_sg.tools.bench_matrix`).
7. **SSDF error vs ray budget** — adaptive visibility rays against a ray per texel
   (:mod:`warp_sg.tools.bench_first_image`).
8. **time to first image** — cold first image (final and progressive) and warm frame of the
   generated textured helmet and the shared assets, and Mitsuba's at equal error
   (:mod:`warp_sg.tools.bench_first_image`).
9. **objects that move** — a frame after ``set_object_transform`` against a static frame and
   against a new ``Renderer`` with a cold cache (:mod:`warp_sg.tools.bench_motion`).
10. **light that bounces** — warm and edit frames with ``[render] bounces`` against without, the
    cold precompute with the gather against without, the gather's bytes per reference
    (:mod:`warp_sg.tools.bench_bounce`).
11. **inverse rendering: relighting** — ``ws.fit`` of the environment and the base-colour and
    roughness textures from path-traced photographs under one environment, relit under another
    from novel views: relighting PSNR, albedo PSNR, roughness error, fit time; Mitsuba 3's ``prb``
    at equal wall time where installed (:mod:`warp_sg.tools.bench_inverse`; full size:
    ``scripts/inverse_bench.py``).

The bench scene (:func:`bench_scene`) is a Torrance-Sparrow sphere, a Ward torus and a Lambert
floor under the procedural sky with one point light and one directional light.
"""
from __future__ import annotations

import math
import statistics
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from warp_sg.core.device import add_device_argument, device_for
from warp_sg.core.errors import InputError
from warp_sg.tools.spp_curve import spp_for_error


@dataclass
class BenchResult:
    sections: dict = field(default_factory=dict)  # name -> list of row dicts
    device: str = "cpu"
    quick: bool = False
    seconds: float = 0.0

    def to_markdown(self) -> str:
        out = []
        for name, rows in self.sections.items():
            out.append(f"### {name}\n")
            if not rows:
                out.append("(no rows)\n")
                continue
            keys = list(dict.fromkeys(k for r in rows for k in r))
            out.append("| " + " | ".join(keys) + " |")
            out.append("|" + "---|" * len(keys))
            for r in rows:
                out.append("| " + " | ".join(_fmt(r.get(k, "")) for k in keys) + " |")
            out.append("")
        return "\n".join(out)


def _fmt(v):
    if isinstance(v, float):
        if math.isnan(v):
            return "n/a"
        return f"{v:.4g}"
    return str(v)


# --------------------------------------------------------------------------------------------
# scene
# --------------------------------------------------------------------------------------------
def bench_scene(width=160, height=120, *, env=True, lights=True, diffuse_only=False, shadows=True, supersampling=1,
                quick=False):
    """The bench scene (see the module docstring), with features switched off on request.

    ``quick``: coarse tessellation and small precompute settings (tests, smoke runs)."""
    from warp_sg import brdf as B
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import DirectionalLight, EnvironmentLight, PointLight
    from warp_sg.scene.model import Scene, SceneObject
    from warp_sg.scene.render_settings import RenderSettings

    cam = Camera(origin=(0.0, 1.6, 4.2), target=(0.0, 0.45, 0.0), up=(0.0, 1.0, 0.0), fov=38.0, width=int(width),
                 height=int(height))
    if diffuse_only:
        mats = {"metal": B.Lambert(kd=[0.6, 0.3, 0.2]), "satin": B.Lambert(kd=[0.2, 0.4, 0.6]),
                "floor": B.Lambert(kd=[0.6, 0.6, 0.6])}
    else:
        mats = {"metal": B.TorranceSparrow(kd=[0.15, 0.05, 0.03], ks=[0.9, 0.6, 0.4], m=0.25),
                "satin": B.Ward(kd=[0.1, 0.2, 0.4], ks=[0.4, 0.4, 0.4], alpha=0.15),
                "floor": B.Lambert(kd=[0.6, 0.6, 0.6])}
    res = ({"sphere": (8, 16), "torus": (16, 8), "plane": (4, 4)} if quick else
           {"sphere": (32, 64), "torus": (64, 32), "plane": (32, 32)})
    objs = [SceneObject(material="metal", primitive="sphere",
                        params={"center": (-0.6, 0.5, 0.0), "radius": 0.5, "resolution": res["sphere"]}),
            SceneObject(material="satin", primitive="torus",
                        params={"center": (0.75, 0.25, 0.2), "major_radius": 0.45, "minor_radius": 0.2,
                                "resolution": res["torus"]}),
            SceneObject(material="floor", primitive="plane",
                        params={"center": (0.0, 0.0, 0.0), "size": (5.0, 5.0), "resolution": res["plane"]})]
    ls = []
    if env:
        ls.append(EnvironmentLight(procedural="sky"))
    if lights:
        ls.append(PointLight(position=(1.5, 2.5, 1.5), radius=0.15, intensity=(6.0, 6.0, 5.0)))
        ls.append(DirectionalLight(direction=(-0.4, 1.0, 0.3), radius=0.05, intensity=(1.0, 0.9, 0.8)))
    if not ls:
        ls.append(DirectionalLight(direction=(0.0, 1.0, 0.0), radius=0.05, intensity=(1.0, 1.0, 1.0)))
    rs = RenderSettings(shadows=shadows, supersampling=supersampling)
    if quick:
        rs = RenderSettings(shadows=shadows, supersampling=supersampling, ssdf_resolution=16, pca_terms=8,
                            gamma_resolution=16, gamma_levels=4, env_lobes=4, visibility_budget=1500)
    return Scene(camera=cam, objects=objs, materials=mats, lights=ls, render=rs)


# --------------------------------------------------------------------------------------------
# sections
# --------------------------------------------------------------------------------------------
def _frames(renderer, n):
    renderer.render()  # warm-up (compiles the variant)
    shade, frame = [], []
    for _ in range(n):
        renderer.render()
        shade.append(renderer.timings.get("shade", float("nan")))
        frame.append(renderer.timings.get("frame", float("nan")))
    return statistics.median(shade), statistics.median(frame)


def shading_section(device="cpu", quick=False, frames=None):
    from warp_sg.core.cache import fresh_cache
    from warp_sg.renderer.renderer import Renderer

    w, h = (48, 36) if quick else (320, 240)
    n = frames or (1 if quick else 5)
    cases = [("full scene", {}), ("no environment", {"env": False}), ("no local lights", {"lights": False}),
             ("diffuse-only materials", {"diffuse_only": True}), ("shadows off", {"shadows": False}),
             # visibility_sampling = "pixel": one SSDF lookup per lobe and light per pixel, and the
             # diffuse environment sum per pixel
             ("visibility per pixel (no per-vertex caches)", {"render": {"visibility_sampling": "pixel"}})]
    rows = []
    base = None
    with fresh_cache():
        for name, kw in cases:
            kw = dict(kw)
            settings = kw.pop("render", {})
            scene = bench_scene(w, h, quick=quick, **kw)
            for k, v in settings.items():
                setattr(scene.render, k, v)
            r = Renderer(scene, device=device)
            shade, frame = _frames(r, n)
            if base is None:
                base = shade
            rows.append({"case": name, "shade_s": shade, "frame_s": frame, "shade_ratio": shade / base,
                         "precompute_s": r.timings.get("precompute", float("nan"))})
        # precompute: cold (empty cache) vs warm (cache hit: precompute skipped)
    with fresh_cache():
        t0 = time.perf_counter()
        Renderer(bench_scene(w, h, quick=quick), device=device)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        Renderer(bench_scene(w, h, quick=quick), device=device)
        warm = time.perf_counter() - t0
    rows.append({"case": "precompute, empty cache", "precompute_s": cold, "shade_ratio": float("nan")})
    rows.append({"case": "precompute, warm cache (skipped)", "precompute_s": warm,
                 "shade_ratio": float("nan"), "speedup": cold / max(warm, 1e-9)})
    return rows


def visibility_section(device="cpu", quick=False):
    try:
        from warp_sg.tools import bench_raster as rb
    except Exception as e:  # noqa: BLE001 - report, don't crash the other sections
        return [{"case": "rasterizer vs ray casting", "note": f"warp_sg.tools.bench_raster unavailable ({type(e).__name__}: {e})"}]
    res = rb.run_bench(device=device, quick=quick)
    return _rows_from(res, "visibility")


def precompute_section(device="cpu", quick=False, cluster=None):
    """SSDF + PCA precompute time (``precompute.ssdf_for_mesh``, empty cache) by mesh size, on the
    plane-and-box meshes of ``warp_sg.tools.bench_precompute`` (whose ``run_bench`` has the detailed study with
    the product error: docs/precompute.md). With ``cluster`` (``--cluster``), one more row: the
    largest mesh with its SSDFs computed on the Dask cluster (:mod:`warp_sg.distributed.precompute`)."""
    from warp_sg.core.cache import fresh_cache

    try:
        import precompute
        from warp_sg.tools import bench_precompute as pb
    except Exception as e:  # noqa: BLE001
        return [{"case": "precompute", "note": f"warp_sg.tools.bench_precompute unavailable ({type(e).__name__}: {e})"}]
    targets, res, terms = ((150, 600), 16, 8) if quick else ((1000, 4000, 16000), 32, 16)
    V, F, N = pb.bench_mesh(targets[0])
    with fresh_cache():  # compile outside the timings
        precompute.ssdf_for_mesh(V, F, N, resolution=res, pca_terms=terms, device=device, progress=False)
    rows = []
    base = None
    for target in targets:
        V, F, N = pb.bench_mesh(target)
        with fresh_cache():
            t0 = time.perf_counter()
            precompute.ssdf_for_mesh(V, F, N, resolution=res, pca_terms=terms, device=device, progress=False)
            t = time.perf_counter() - t0
        base = base or t
        rows.append({"case": f"{len(V)} vertices (SSDF {res}², {terms} PCA terms)", "total_s": t,
                     "ratio": t / base, "ms_per_vertex": 1e3 * t / len(V)})
    if cluster is not None:
        from warp_sg.distributed.cluster import connect
        from warp_sg.distributed.precompute import DaskSSDF

        with connect(cluster) as client:
            n_workers = len(client.scheduler_info().get("workers", {}))
            compute = DaskSSDF(client)
            with fresh_cache():  # workers compile / load their kernels outside the timing
                precompute.ssdf_for_mesh(*pb.bench_mesh(targets[0]), resolution=res, pca_terms=terms, device=device,
                                         progress=False, compute=compute)
            with fresh_cache():
                t0 = time.perf_counter()
                precompute.ssdf_for_mesh(V, F, N, resolution=res, pca_terms=terms, device=device, progress=False,
                                         compute=compute)
                t = time.perf_counter() - t0
        rows.append({"case": f"{len(V)} vertices on Dask ({n_workers} workers)", "total_s": t, "ratio": t / base,
                     "ms_per_vertex": 1e3 * t / len(V)})
    return rows


def _rows_from(res, name):
    """Normalise another module's bench result (list of dicts | dict | text) into rows."""
    if isinstance(res, list) and all(isinstance(r, dict) for r in res):
        return res
    if isinstance(res, dict):
        for k in ("rows", "table", "results"):
            if isinstance(res.get(k), list):
                return _rows_from(res[k], name)
        return [{"case": k, "value": v} for k, v in res.items() if isinstance(v, (int, float, str))]
    return [{"case": name, "value": str(res)}]


#: per run: the SG renderer's measurements and the truths, shared by the equal-error sections
_CASES: dict = {}


def _cached(key, make):
    if key not in _CASES:
        _CASES[key] = make()
    return _CASES[key]


#: the ground truths' path segments (``run_bench(max_depth=...)``): the full path tracer's by default;
#: 2 compares the scenes rendered with ``bounces = 0`` with direct light only (the paper's part)
_MAX_DEPTH = [None]


def _depth() -> int:
    from warp_sg.groundtruth.reference import DEFAULT_MAX_DEPTH

    return DEFAULT_MAX_DEPTH if _MAX_DEPTH[0] is None else int(_MAX_DEPTH[0])


def _equal_error_case(scene, label, device, quick, truth_spp, progress, seed) -> dict:
    """Truth, the SG renderer's error and frame time, and our MC error curve of one scene (the
    renderer's measurement cached per run under ``label``, the truth and curve per ``truth_spp``).
    The renderer's image is antialiased (``antialias`` a×a coverage): the truth and the MC curve
    are then box-filtered the same way (a×a sub-pixels, ``spp`` counted per pixel), as a path
    tracer's jittered pixels would be. ``floor``: the truth's own noise, Σσ²/Σr², which every
    error measured against it contains in expectation."""
    import copy

    from warp_sg.core.cache import fresh_cache
    from warp_sg.groundtruth.reference import matching_transport, render_reference
    from warp_sg.groundtruth.region_error import image_errors
    from warp_sg.renderer.renderer import Renderer

    scene = matching_transport(scene, _depth())

    def measure():
        with fresh_cache():
            r = Renderer(scene, device=device)
            pre = r.timings.get("precompute", float("nan"))
            img = r.render()
            _, frame = _frames(r, 1 if quick else 3)
        return img, pre, frame

    def truth_and_curve():
        rs = scene.render
        k = rs.supersampling if rs.supersampling > 1 else max(1, rs.antialias)
        ref_scene = copy.deepcopy(scene)
        ref_scene.render.supersampling = k
        per = k * k  # samples per pixel for one sample per sub-pixel
        truth = render_reference(ref_scene, spp=max(1, truth_spp // per), device=device, progress=progress,
                                 seed=seed, max_depth=_depth())
        curve = []

        def cb(spp, seconds, im, se):
            if spp & (spp - 1) == 0:
                curve.append((spp * per, image_errors(im, truth.image)["rel_mse"], seconds))

        render_reference(ref_scene, spp=max(1, truth_spp // (8 * per)), device=device, progress=progress,
                         seed=seed + 1, callback=cb, max_depth=_depth())
        floor = float(np.sum(truth.stderr.astype(np.float64) ** 2) /
                      max(np.sum(truth.image.astype(np.float64) ** 2), 1e-300))
        return truth, curve, floor

    img, pre, frame = _cached(("sg", label, device, quick), measure)
    truth, curve, floor = _cached(("truth", label, device, quick, truth_spp), truth_and_curve)
    return dict(scene=scene, truth=truth, err=image_errors(img, truth.image), pre=pre, frame=frame, curve=curve,
                floor=floor)


def _equal_error_rows(scene, label, device, quick, truth_spp, progress, seed):
    """Rows of one scene (:func:`_equal_error_case`). Errors are compared net of the truth's noise
    floor (``rel_mse_net``), as in the Mitsuba section: with a 1024-spp truth the floor is of the
    order of the renderer's own error."""
    c = _equal_error_case(scene, label, device, quick, truth_spp, progress, seed)
    err, frame, pre, truth = c["err"], c["frame"], c["pre"], c["truth"]
    # every error against the truth contains the truth's own noise (floor): compare net of it
    net = max(err["rel_mse"] - c["floor"], 1e-30)
    spp, t_mc = spp_for_error(_net_of_floor(c["curve"], c["floor"]), net)
    return [
        {"case": f"{label}: SG renderer (frame)", "rel_mse": err["rel_mse"], "rel_mse_net": net,
         "psnr_db": err["psnr_db"], "seconds": frame, "ratio": 1.0},
        {"case": f"{label}: SG renderer (precompute + frame)", "rel_mse": err["rel_mse"], "rel_mse_net": net,
         "seconds": pre + frame, "ratio": (pre + frame) / frame},
        {"case": f"{label}: MC reference at equal error ({spp:.3g} spp)", "rel_mse": err["rel_mse"],
         "rel_mse_net": net, "seconds": t_mc, "ratio": t_mc / frame},
        {"case": f"{label}: ground truth ({truth_spp} spp) noise floor", "rel_mse": c["floor"],
         "seconds": truth.seconds, "ratio": truth.seconds / frame},
    ]


def _equal_error_scenes(quick, mitsuba=False):
    """(label, scene, seed) of the equal-error cases: the bench scene (with Lambert materials
    for Mitsuba, which has none of its glossy models: ``warp_sg.tools.peer_mitsuba``) and a plain-input
    scene (a sphere on a floor of two triangles under a sky EXR whose sun holds half the
    irradiance: ``warp_sg.scene.plain_scenes``; its files are read at load), and the same sphere and
    floor lit by one spherical point light only (the exact-light path; issue 13's
    "1 spp-equivalent" case)."""
    from warp_sg.scene.loader import load_scene
    from warp_sg.scene.plain_scenes import write_plain_scene

    w, h = (24, 18) if quick else (96, 72)
    out = [("bench scene, Lambert materials", bench_scene(w, h, quick=quick, diffuse_only=True), 31) if mitsuba else
           ("bench scene", bench_scene(w, h, quick=quick), 11)]
    with tempfile.TemporaryDirectory() as d:
        plain = load_scene(write_plain_scene(d, obj="sphere", light="sky", material="lambert", size=h))
        plain.environment.base_radiance()  # read the EXR before the folder goes
        plain.geometry()
        point = load_scene(write_plain_scene(d, obj="sphere", light="point", material="lambert", size=h))
        point.geometry()
    if quick:
        for sc in (plain, point):
            sc.render.visibility_budget, sc.render.ssdf_resolution, sc.render.pca_terms = 1500, 16, 8
    return out + [("plain inputs", plain, 21), ("plain inputs, point light", point, 41)]


def equal_error_section(device="cpu", quick=False, truth_spp=None, progress=False):
    """Equal error against our MC reference on the bench scene and on a plain-input scene
    (:func:`_equal_error_scenes`); ratios are MC time at the renderer's error over its frame time."""
    truth_spp = truth_spp or (32 if quick else 1024)
    rows = []
    for label, scene, seed in _equal_error_scenes(quick):
        rows += _equal_error_rows(scene, label, device, quick, truth_spp, progress, seed)
    return rows


def _net_of_floor(curve, floor):
    """An error curve [(spp, rel_mse, s)] against a noisy truth, less the truth's noise floor."""
    return [(spp, max(e - floor, 1e-30), t) for spp, e, t in curve]


def _lazy(module: str, name: str):
    """The section ``name`` of ``warp_sg.tools.<module>``, imported when it runs."""
    def run(**kw):
        import importlib

        return getattr(importlib.import_module(f"warp_sg.tools.{module}"), name)(**kw)

    return run


SECTIONS = {
    "visibility: rasterizer vs ray casting": visibility_section,
    "shading cost by scene feature": shading_section,
    "precompute cost": precompute_section,
    "equal error: SG renderer vs Monte-Carlo reference": equal_error_section,
    "frame scaling: pixels and triangles": _lazy("bench_scaling", "scaling_section"),
    "equal error: SG renderer vs Mitsuba 3": _lazy("bench_mitsuba", "mitsuba_section"),
    "equal error vs Mitsuba 3: every model (accuracy matrix)": _lazy("bench_matrix", "matrix_equal_error_section"),
    "SSDF error vs ray budget": _lazy("bench_first_image", "ray_budget_section"),
    "time to first image": _lazy("bench_first_image", "first_image_section"),
    "first run": _lazy("bench_first_image", "first_run_section"),
    "objects that move": _lazy("bench_motion", "motion_section"),
    "light that bounces": _lazy("bench_bounce", "bounce_section"),
    "inverse rendering: relighting": _lazy("bench_inverse", "inverse_section"),
}


def run_bench(device="cpu", quick=False, sections=None, print_fn=print, cluster=None,
              max_depth: int | None = None) -> BenchResult:
    """Run every section (or those named in ``sections``) and print the tables; returns them.
    ``cluster``: also time the SSDF precompute on this Dask cluster (precompute section).
    ``max_depth``: the equal-error sections' ground truths (default the full path tracer; 2: direct
    light only, against the scenes rendered with ``bounces = 0``)."""
    from warp_sg.core.device import resolve_device
    from warp_sg.core.suggest import did_you_mean

    for s in sections or ():
        if not any(s in name for name in SECTIONS):
            words = {w for name in SECTIONS for w in name.replace(":", " ").split()}
            raise InputError(f"no section's name contains {s!r}{did_you_mean(s, words)} (`warp-sg bench "
                             f"--help` lists the {len(SECTIONS)} sections)", where="--section")
    from warp_sg.groundtruth.reference import check_max_depth

    if max_depth is not None:
        check_max_depth(max_depth, "--max-depth")
    _MAX_DEPTH[0] = max_depth
    device = resolve_device(device)
    t0 = time.perf_counter()
    res = BenchResult(device=device, quick=quick)
    _CASES.clear()
    for name, fn in SECTIONS.items():
        if sections is not None and not any(s in name for s in sections):
            continue
        try:
            rows = fn(device=device, quick=quick, **({"cluster": cluster} if cluster is not None and
                                                     fn is precompute_section else {}))
        except InputError:
            raise
        except Exception as e:  # noqa: BLE001 - one broken section must not hide the others
            rows = [{"case": name, "note": f"failed: {type(e).__name__}: {e}"}]
        res.sections[name] = rows
        if print_fn is not None:
            print_fn(BenchResult({name: rows}).to_markdown())
    res.seconds = time.perf_counter() - t0
    return res


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def add_cli_arguments(p) -> None:
    add_device_argument(p, scene=False)
    p.add_argument("--quick", action="store_true", help="tiny sizes (smoke test)")
    p.add_argument("--section", action="append", default=None,
                   help="run only sections whose name contains this (repeatable); sections: "
                        + "; ".join(SECTIONS))
    p.add_argument("-o", "--output", default=None, help="also write the tables (markdown) to this file")
    p.add_argument("--cluster", default=None, metavar="local:N|tcp://HOST:PORT",
                   help="also time the SSDF precompute on a Dask cluster (docs/distributed.md)")
    p.add_argument("--max-depth", type=int, default=None, metavar="N",
                   help="the equal-error ground truths' path segments (default: a full path tracer; 2: direct "
                        "light only, compared with the scenes rendered with bounces = 0)")


def cli_main(args) -> int:
    out = None
    if args.output:
        out = Path(args.output)
        if out.is_dir() or not out.parent.is_dir():
            raise InputError("cannot write the bench tables here", where=str(out))
    res = run_bench(device=device_for(args.device), quick=args.quick, sections=args.section,
                    cluster=getattr(args, "cluster", None), max_depth=getattr(args, "max_depth", None))
    print(f"bench finished in {res.seconds:.1f} s on {res.device}")
    if out is not None:
        from warp_sg.core.files import atomic_output

        with atomic_output(out) as tmp:
            Path(tmp).write_text(res.to_markdown())
    return 0


__all__ = ["run_bench", "BenchResult", "bench_scene", "spp_for_error", "add_cli_arguments", "cli_main",
           "SECTIONS"]
