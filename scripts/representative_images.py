"""Images with and without SSDFs at representative vertices (docs/precompute.md, "Representative vertices").

    python scripts/representative_images.py ASSET [--budget 20000] [--size 512 384] [--out DIR] [--reference SPP]
    python scripts/representative_images.py ferrari.glb --size 256 192 --own A/own.exr --reference-file A/reference.exr
    python scripts/representative_images.py helmet --budget 5000   # the generated helmet, forced to use them

Renders the asset's scene twice in one process, every vertex with its own ray-cast SSDF
(``ssdf_for_mesh(representatives=0)``) and with at most ``--budget`` representatives
(:mod:`precompute.visibility.representatives`), and prints the errors of the second against the
first, image-wide and per region (:mod:`warp_sg.groundtruth.region_error`), with each render's
precompute CPU seconds. ``--reference SPP``: also both against the Monte-Carlo reference
(``box_reference``, SPP paths per pixel; the relative MSEs are corrected for its noise, its
per-pixel standard error saved beside it as ``reference_stderr.npy``); ``--reference-file EXR``: an
earlier run's reference (and its ``reference_stderr.npy``). The floor of the regions is the object
named ``floor`` or ``ground`` (the ground plane an asset scene adds; ``--floor`` other names). Uses
``WARP_SG_CACHE_DIR`` as it is (a second run reuses
the SSDFs; ``--own EXR`` takes the first image from an earlier run). Writes ``own.exr``, ``reps.exr`` (and ``reference.exr``) to ``--out``.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("asset")
    ap.add_argument("--budget", type=int, default=20000)
    ap.add_argument("--size", type=int, nargs=2, default=(512, 384))
    ap.add_argument("--out", default=None)
    ap.add_argument("--reference", type=int, default=0, metavar="SPP")
    ap.add_argument("--json", default=None)
    ap.add_argument("--reference-file", default=None, metavar="EXR", help="an earlier run's reference.exr")
    ap.add_argument("--floor", nargs="+", default=["floor", "ground"], help="names of the floor object")
    ap.add_argument("--name", default="reps", help="name of the representatives' image (NAME.exr)")
    ap.add_argument("--angle", type=float, default=None, help="rep_max_angle (default the module's)")
    ap.add_argument("--own", default=None, metavar="EXR",
                    help="an earlier run's own.exr (the same asset and size): not rendered again")
    a = ap.parse_args(argv)
    out = Path(a.out or tempfile.mkdtemp(prefix="wsg-reps-"))
    out.mkdir(parents=True, exist_ok=True)
    from warp_sg.core.device import resolve_device

    resolve_device("cpu")
    import numpy as np

    import precompute
    import precompute.visibility.ssdf as S
    from warp_sg.core.image_io import load_image, save_image
    from warp_sg.groundtruth.region_error import image_errors, region_errors, scene_regions
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.scene.importers.asset import asset_scene

    asset = a.asset
    if asset == "helmet":
        from warp_sg.tools.bench_assets import textured_helmet

        asset = str(textured_helmet(out / "helmet.glb"))
    scene, _ = asset_scene(asset, width=a.size[0], height=a.size[1])
    imgs, info = {}, {}
    runs = (("own", 0), (a.name, a.budget))
    if a.own:
        imgs["own"] = load_image(a.own)[..., :3]
        runs = runs[1:]
    plain = S.ssdf_for_mesh
    for name, budget in runs:
        def forced(*args, _b=budget, **kw):  # the renderer passes [render] visibility_budget: this budget instead
            kw["representatives"] = _b
            if a.angle is not None:
                kw["rep_max_angle"] = a.angle
            return plain(*args, **kw)

        precompute.ssdf_for_mesh = forced  # (what the renderer calls; the refinement keeps the scene's budget)
        w0, c0 = time.perf_counter(), time.process_time()
        r = Renderer(scene, device="cpu")
        img = r.render()
        info[name] = {"wall_s": time.perf_counter() - w0, "cpu_s": time.process_time() - c0,
                      "ssdf_vertices": int(len(r.geometry.vertices)),
                      "representatives": int(len(set(r.ssdf.representative.tolist()))) if r.ssdf is not None and
                      len(r.ssdf.representative) else 0}
        imgs[name] = img
        save_image(out / f"{name}.exr", img)
        print(name, info[name], flush=True)
    regions = scene_regions(scene, floor=a.floor)
    res = {"asset": Path(asset).name, "size": list(a.size), "budget": a.budget, "runs": info,
           f"{a.name}_vs_own": {"image": image_errors(imgs[a.name], imgs["own"]),
                                "regions": region_errors(imgs[a.name], imgs["own"], regions)}}
    ref = se = None
    if a.reference_file:
        ref = load_image(a.reference_file)[..., :3]
        sef = Path(a.reference_file).with_name("reference_stderr.npy")
        se = np.load(sef) if sef.exists() else None
    elif a.reference:
        from warp_sg.groundtruth.region_error import box_reference

        w0, c0 = time.perf_counter(), time.process_time()
        ref, se = box_reference(scene, spp=a.reference, return_stderr=True)
        res["reference"] = {"spp": a.reference, "wall_s": time.perf_counter() - w0, "cpu_s": time.process_time() - c0}
        save_image(out / "reference.exr", ref)
        np.save(out / "reference_stderr.npy", np.asarray(se, np.float32))
    if ref is not None:
        for name in imgs:
            res[f"{name}_vs_reference"] = {"image": image_errors(imgs[name], ref),
                                           "regions": region_errors(imgs[name], ref, regions, stderr=se)}
    print(json.dumps(res, indent=1, default=float))
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
