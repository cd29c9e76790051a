"""An animation: a Python loop of frames that changes lighting, material and camera each frame
without re-running any precompute (the SSDFs, the environment fit and the ΓL pyramid stay in the
``Renderer``; only rasterisation and shading run per frame).

    python examples/animate.py                       # 24 frames of examples/cook_torrance.toml
    python examples/animate.py --frames 8 --size 128 --out out/animate --device cuda

Per frame: the environment turns 360°/frames about +Y (the sun circles the ball), the roughness
``m`` goes 0.08 → 0.3 → 0.08, and the camera orbits slowly. Writes ``frame_000.png`` ... and
prints the per-frame timings (raster / shade).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

import warp_sg as ws
from warp_sg.renderer.renderer import Renderer

HERE = Path(__file__).resolve().parent


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=str(HERE / "cook_torrance.toml"))
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--size", type=int, default=None, help="square frame size (default: the scene's)")
    ap.add_argument("--out", default="out/animate")
    ap.add_argument("--device", default="cpu")
    args = ap.parse_args(argv)

    scene = ws.load_scene(args.scene)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    r = Renderer(scene, device=args.device, progress=True)  # precompute (cached on disk) happens once, here
    print(f"precompute {r.timings['precompute']:.2f} s")
    if args.size:
        r.set_camera(width=args.size, height=args.size)
    cam0 = np.asarray(scene.camera.origin, np.float64)
    target = np.asarray(scene.camera.target, np.float64)
    base_rot = scene.environment.rotation if scene.environment is not None else 0.0
    material = next(n for n, m in scene.materials.items() if "m" in m.params)
    for f in range(args.frames):
        t = f / max(args.frames, 1)
        if scene.environment is not None:
            r.set_environment_rotation(base_rot + 360.0 * t)
        r.set_material(material, m=0.08 + 0.22 * 0.5 * (1 - math.cos(2 * math.pi * t)))
        a = 0.5 * math.sin(2 * math.pi * t)  # orbit ±0.5 rad
        rel = cam0 - target
        c, s = math.cos(a), math.sin(a)
        r.set_camera(origin=tuple(target + [c * rel[0] + s * rel[2], rel[1], -s * rel[0] + c * rel[2]]))
        img = r.render()
        ws.save_image(out / f"frame_{f:03d}.png", img)
        print(f"frame {f:3d}: raster {r.timings['raster'] * 1e3:7.1f} ms, shade {r.timings['shade'] * 1e3:7.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
