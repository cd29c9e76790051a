"""Make the photographs of the inverse-rendering example (``examples/fit_ball.toml``,
``examples/fit_views.toml``) into ``examples/assets/`` (committed; rerun to rebuild):

* ``fit_start_kd.exr``   the fit's starting base colour: 32 × 32 grey 0.5
* ``fit_view_N.exr``     four 64 × 64 linear frames of the true scene — the ball's base colour the
  tiles of ``assets/albedo.png``, its roughness α = 0.25, the sky of ``assets/sky.hdr`` — rendered
  by the SG renderer itself (direct light, as it shades)

Usage: ``python examples/make_fit_views.py``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

import warp_sg as ws
from warp_sg.scene.lights import EnvironmentLight
from warp_sg.scene.textures import Texture

HERE = Path(__file__).resolve().parent
VIEWS = [(0.0, 1.3, 3.0), (2.4, 1.3, 1.8), (-2.4, 1.3, 1.8), (0.0, 2.6, 1.8)]


def main() -> None:
    ws.save_image(HERE / "assets" / "fit_start_kd.exr", np.full((32, 32, 3), 0.5, np.float32), half=True)
    scene = ws.load_scene(HERE / "fit_ball.toml")
    scene.lights[0] = EnvironmentLight(file=HERE / "assets" / "sky.hdr")
    r = ws.Renderer(scene, device="cpu")
    r.set_material("ball", kd=Texture(path=HERE / "assets" / "albedo.png"), alpha=0.25)
    for i, o in enumerate(VIEWS):
        r.set_camera(origin=o)
        ws.save_image(HERE / "assets" / f"fit_view_{i}.exr", r.render(), half=True)


if __name__ == "__main__":
    main()
