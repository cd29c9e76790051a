"""Render the accuracy matrix's references with Mitsuba 3 (warp_sg.groundtruth.accuracy_matrix).

    python scripts/mitsuba_refs.py [--spp 4096] [--only NAME ...] [--variant llvm_ad_rgb] [--max-depth 2]

Each case's scene is written to a temporary folder, translated by warp_sg.tools.mitsuba.scene_dict
(materials and lights from the scene file's own words, BRDFs from their published formulas) and
rendered in ``--batches`` independent batches; the mean image, its per-pixel standard error (from the
spread of the batch means) and the per-region masks (warp_sg.groundtruth.region_error.scene_regions)
go to tests/data/mitsuba/NAME.npz (float16), and manifest.json records the case, the Mitsuba version,
variant, spp, max_depth and the seconds taken. ``llvm_ad_rgb`` (needs a system libLLVM, e.g.
Debian's libllvm19) is ~50x faster than ``scalar_rgb`` for these plugin BSDFs; both give the same answer.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from tqdm import tqdm

from warp_sg.groundtruth import accuracy_matrix as AM


def render_reference(case, folder, spp: int, batches: int, variant: str, max_depth: int = 2, seed: int = 0):
    from warp_sg.groundtruth.region_error import scene_regions
    from warp_sg.tools.mitsuba.render import mitsuba_reference

    scene, _ = AM.load_case(case, folder)
    ref = mitsuba_reference(scene, spp, max_depth=max_depth, batches=batches, seed=seed, variant=variant)
    return ref.image, ref.stderr, scene_regions(scene), ref.spp


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--batches", type=int, default=8)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--max-depth", type=int, default=None, help="override every case's own depth (2: direct light)")
    ap.add_argument("--only", nargs="*", help="case names (default: every case)")
    ap.add_argument("--missing", action="store_true", help="only cases without a stored reference")
    a = ap.parse_args(argv)
    import mitsuba as mi

    cases = [AM.BY_NAME[n] for n in a.only] if a.only else list(AM.CASES)
    if a.missing:
        cases = [c for c in cases if not AM.reference_path(c).is_file()]
    man_path = AM.REFERENCES / "manifest.json"
    manifest = json.loads(man_path.read_text()) if man_path.is_file() else {}
    with tempfile.TemporaryDirectory() as tmp:
        for case in tqdm(cases, desc="mitsuba references", unit="scene"):
            if AM.needs_shared(case) and AM.shared_assets() is None:
                print(f"skipped {case.name}: shared/assets is absent", file=sys.stderr)
                continue
            t0 = time.perf_counter()
            depth = case.depth if a.max_depth is None else a.max_depth
            mean, se, masks, spp = render_reference(case, Path(tmp) / case.name, a.spp, a.batches, a.variant, depth)
            AM.save_reference(case, mean, se, masks, spp)
            manifest[case.name] = {"object": case.obj, "light": case.light, "material": AM.MATERIALS[case.material],
                                   "pose": case.pose, "size": case.size, "mitsuba": mi.__version__,
                                   "variant": a.variant, "spp": spp, "max_depth": depth,
                                   "seconds": round(time.perf_counter() - t0, 1),
                                   "pixels": {r: int(m.sum()) for r, m in masks.items()}}
            man_path.write_text(json.dumps(dict(sorted(manifest.items())), indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
