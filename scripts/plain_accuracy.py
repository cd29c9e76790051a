"""Accuracy on plain user inputs (issue 11): SG renderer vs the Monte-Carlo reference, per region.

    python scripts/plain_accuracy.py [--size 96] [--spp 256] [--cases sphere:sky:lambert,...]

Writes each case's scene into a temporary folder (2-triangle floor, icosphere/blob, sky EXR with a
sun or a point light) and prints the per-region table of :mod:`warp_sg.groundtruth.region_error`.
"""
from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np

import warp_sg as ws
from warp_sg.groundtruth.region_error import box_reference, format_region_table, region_errors, scene_regions
from warp_sg.scene.plain_scenes import write_plain_scene

DEFAULT = "sphere:sky:lambert,sphere:point:lambert,blob:sky:lambert,blob:sky:blinn_phong,sphere:sky:cook_torrance,sphere:point:ward"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--cases", default=DEFAULT)
    ap.add_argument("--render", default="", help="extra [render] keys, k=v,k=v")
    a = ap.parse_args()
    extra = {}
    for kv in filter(None, a.render.split(",")):
        k, v = kv.split("=")
        extra[k] = eval(v)
    for case in a.cases.split(","):
        obj, light, mat = case.split(":")
        with tempfile.TemporaryDirectory() as d:
            path = write_plain_scene(d, obj=obj, light=light, material=mat, size=a.size, render=extra or None)
            scene = ws.load_scene(path)
            t = time.perf_counter()
            r = ws.Renderer(scene, device="cpu")
            t_pre = time.perf_counter() - t
            img = r.render()
            img = r.render()
            t_frame = r.timings["frame"]
            ref, se = box_reference(ws.load_scene(path), spp=a.spp, return_stderr=True)
            regs = scene_regions(ws.load_scene(path))
            errs = region_errors(img, ref, regs, stderr=se)
            allm = float(np.sum((img - ref) ** 2) / np.sum(ref ** 2))
            print(f"\n## {case}  (image rel MSE {allm:.4f}; precompute {t_pre:.1f} s, frame {1000 * t_frame:.0f} ms)")
            print(format_region_table(errs))


if __name__ == "__main__":
    main()
