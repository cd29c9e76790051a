"""Objects that move (docs/rendering.md "Objects that move"): two short image sequences rendered
from one precompute each, by ``Renderer.set_object_transform``.

    python examples/rolling.py                          # 12 frames of each, 256², into out/rolling
    python examples/rolling.py --frames 6 --size 128 --reference 256

* ``ball``: ``examples/rolling.toml`` — a ball (``dynamic = true``) rolls 2.4 m across a floor of
  two triangles under the procedural sun-sky, without slipping (it turns by distance/radius about
  the axis up × direction), drifting a little sideways.
* ``turntable``: the Stanford bunny (the USD file that ships with warp-lang, 12 200 triangles, read
  by :mod:`warp_sg.scene.importers.usd`; needs ``pip install warp-sg[usd]``) turns once on a turntable,
  on the same floor under the sky EXR with a sun of :mod:`warp_sg.scene.plain_scenes`, scaled to
  0.97 m and set on the floor; its self-shadows (ears, head, haunch) turn with it.

Writes ``ball_000.png`` ..., ``turntable_000.png`` ... and prints each frame's time next to a
static frame's. ``--reference SPP``: also the Monte-Carlo reference of the middle frame of each
sequence at its pose (``ws.reference(r.scene)``) and the per-region bias.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import warp_sg as ws
from warp_sg.core.image_io import save_image
from warp_sg.numeric.rigid_motion import motion_about, rolling, rotation_about
from warp_sg.scene.plain_scenes import write_plain_scene

HERE = Path(__file__).resolve().parent


def ball_poses(n: int):
    """The rolling ball: x from −1.2 to 1.2, z drifting by 0.3 (the motion after its own transform)."""
    for x in np.linspace(-1.2, 1.2, n):
        M = rolling(x)
        M[2, 3] += 0.3 * (x + 1.2) / 2.4
        yield M


def turntable_poses(n: int):
    """The bunny turned once about the vertical axis through its centre (0, 0.5, 0)."""
    for a in np.linspace(0.0, 360.0, n, endpoint=False):
        yield motion_about(rotation_about([0.0, 1.0, 0.0], a), [0.0, 0.5, 0.0])


def sequence(name, scene, poses, out: Path, size: int, ref_spp: int, device: str) -> list[Path]:
    scene.camera = type(scene.camera)(**{**{k: getattr(scene.camera, k) for k in
                                             ("origin", "target", "up", "fov", "near", "far")},
                                          "width": size, "height": size})
    r = ws.Renderer(scene, device=device, progress=True)
    obj = next(i for i, ob in enumerate(scene.objects) if ob.dynamic)
    r.render()
    t = time.perf_counter()
    r.set_camera(fov=scene.camera.fov + 1e-4)  # a static frame: raster and shade again
    r.render()
    static = time.perf_counter() - t
    print(f"{name}: precompute {r.timings['precompute']:.1f} s, static frame {1e3 * static:.0f} ms")
    paths, poses = [], list(poses)
    for f, M in enumerate(poses):
        r.set_object_transform(obj, M)
        t = time.perf_counter()
        img = r.render()
        dt = time.perf_counter() - t
        p = out / f"{name}_{f:03d}.png"
        save_image(p, img)
        paths.append(p)
        print(f"  frame {f:3d}: {1e3 * dt:6.0f} ms  (motion {1e3 * r.timings.get('motion', 0.0):.1f} ms)")
    if ref_spp:
        from warp_sg.groundtruth.region_error import box_reference, format_region_table, region_errors, scene_regions

        r.set_object_transform(obj, poses[len(poses) // 2])
        img = r.render()
        ref = box_reference(r.scene, spp=ref_spp, supersample=4, device=device)  # the scene at this pose
        save_image(out / f"{name}_reference.png", ref)
        print(format_region_table(region_errors(img, ref, scene_regions(r.scene, device=device))))
    return paths


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--out", default="out/rolling")
    ap.add_argument("--reference", type=int, default=0, metavar="SPP", help="also the middle frame's MC reference")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--only", choices=("ball", "turntable"), default=None)
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.only in (None, "ball"):
        sequence("ball", ws.load_scene(HERE / "rolling.toml"), ball_poses(args.frames), out, args.size,
                 args.reference, args.device)
    if args.only in (None, "turntable"):
        with tempfile.TemporaryDirectory() as tmp:
            scene = ws.load_scene(write_plain_scene(tmp, obj="bunny", light="sky", size=args.size, dynamic=True))
            sequence("turntable", scene, turntable_poses(args.frames), out, args.size, args.reference, args.device)
    return 0


if __name__ == "__main__":
    sys.exit(main())
