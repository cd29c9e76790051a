"""Equal error against Mitsuba 3 at full frame size (issue 13's 512² target), with a Mitsuba truth.

    python scripts/equal_error_large.py [--size 512] [--truth-spp 4096] [--scenes plain,point,bench]

`warp-sg bench`'s Mitsuba section measures at 96×72 against our own MC truth (8192 spp): at 512²
that truth takes hours on a 2-core CPU. Here the truth is Mitsuba's own (``truth_spp`` samples in
4 batches, its noise floor Σσ²/Σr² from the batch spread), which agrees with our MC reference
within noise on these Lambert scenes (``tests/test_peer_mitsuba.py``). Then, in one run:

* our frame: a warm ``Renderer.render()`` after a camera nudge (median of 3), antialias 4;
* our error: relative MSE against the truth, net of the truth's floor;
* Mitsuba's curve: 1, 2, 4, … spp (median of 3 timed renders each, after a warm-up) until its
  net error is below ours; the time at our error by log-log interpolation (``bench.spp_for_error``).

Prints a markdown table. Requires the optional ``[compare]`` extra (``warp_sg.tools.peer_mitsuba``).
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np


def scenes(size: int, which):
    from warp_sg.scene.loader import load_scene
    from warp_sg.scene.plain_scenes import write_plain_scene
    from warp_sg.tools.bench import bench_scene

    out = []
    with tempfile.TemporaryDirectory() as d:
        for key, light in (("plain", "sky"), ("point", "point")):
            if key in which:
                sc = load_scene(write_plain_scene(os.path.join(d, key), obj="sphere", light=light, material="lambert",
                                                  size=size))
                if sc.environment is not None:
                    sc.environment.base_radiance()  # read the EXR before the folder goes
                sc.geometry()
                out.append((f"plain inputs, {'sun-sky EXR' if light == 'sky' else 'one spherical point light'}", sc))
    if "bench" in which:
        out.append(("bench scene, Lambert materials", bench_scene(int(size * 4 / 3), size, diffuse_only=True)))
    return out


def measure(label, scene, truth_spp, seed=5):
    from warp_sg.groundtruth.region_error import image_errors
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.tools import peer_mitsuba as pm
    from warp_sg.tools.bench import _frames, _net_of_floor
    from warp_sg.tools.spp_curve import spp_for_error

    t = time.perf_counter()
    truth, se = pm.mitsuba_mean(pm.mitsuba_scene(scene), spp=max(1, truth_spp // 4), batches=4, seed=seed)
    t_truth = time.perf_counter() - t
    floor = float(np.sum(se.astype(np.float64) ** 2) / max(np.sum(truth.astype(np.float64) ** 2), 1e-300))
    r = Renderer(scene, device="cpu")
    img = r.render()
    _, frame = _frames(r, 3)
    err = image_errors(img, truth)["rel_mse"]
    curve = pm.mitsuba_curve(scene, truth, seed=seed + 1, repeats=3, stop_below=err, max_spp=4096)
    m_spp, m_t = spp_for_error(_net_of_floor(curve, floor), max(err - floor, 1e-30))
    h, w = img.shape[:2]
    return {"case": label, "size": f"{w}×{h}", "triangles": len(r.geometry.triangles), "rel_mse": err,
            "floor": floor, "frame_s": frame, "mitsuba_spp": m_spp, "mitsuba_s": m_t, "ratio": m_t / frame,
            "truth_s": t_truth}


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--truth-spp", type=int, default=4096)
    ap.add_argument("--scenes", default="plain,point,bench")
    a = ap.parse_args(argv)
    import warp as wp

    from warp_sg.tools import peer_mitsuba as pm

    wp.config.quiet = True
    ok, status = pm.mitsuba_status("cpu")
    if not ok:
        print(f"skipped: {status}")
        return 0
    print(f"{status}; load average at start {os.getloadavg()[0]:.2f}\n")
    print("| scene | size | our rel. MSE | truth floor | our frame s | Mitsuba spp at our error | Mitsuba s | ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for label, sc in scenes(a.size, a.scenes.split(",")):
        r = measure(label, sc, a.truth_spp)
        print(f"| {r['case']} | {r['size']} | {r['rel_mse']:.2e} | {r['floor']:.1e} | {r['frame_s']:.3f} | "
              f"{r['mitsuba_spp']:.1f} | {r['mitsuba_s']:.3f} | {r['ratio']:.1f}× |", flush=True)
    print(f"\nload average at end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
