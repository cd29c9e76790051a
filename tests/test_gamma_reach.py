"""The ΓL ladder ends where the scene's sharpest lobe needs it (warp_sg.scene.lobe_extent)."""
from __future__ import annotations

import numpy as np

from warp_sg.groundtruth.region_error import image_errors
from warp_sg.renderer.renderer import Renderer
from warp_sg.scene.lobe_extent import MIN_REACH, gamma_reach, sharpest_ndf_lobe
from warp_sg.scene.model import Material
from warp_sg.scene.textures import Texture
from warp_sg.tools.bench import bench_scene


def _scene():
    sc = bench_scene(48, 36, quick=True, shadows=False)
    sc.render.gamma_resolution, sc.render.gamma_levels = 64, 0  # the default ladder
    return sc


def test_capped_ladder_renders_the_image_of_the_full_ladder(cache_dir):
    sc = _scene()
    r = Renderer(sc)
    from precompute.environment.prefilter import default_ladder

    full = default_ladder(r.env_residual.shape[0], base_face=64)[0]
    assert r._gamma_capped and len(r.gamma.lambdas) < len(full)
    capped = r.render()
    r._gamma_need, r.gamma, r._gamma_capped = 0.0, None, False  # the whole ladder
    r._ensure_gamma()
    assert len(r.gamma.lambdas) == len(full)
    whole = r.render()
    assert image_errors(capped, whole)["rel_mse"] < 1e-5


def test_a_textured_roughness_reaches_its_smoothest_texel():
    sc = _scene()
    base = sharpest_ndf_lobe(sc)
    # the Ward "satin" material with an alpha texture down to 0.05: far sharper than its mean
    alpha = np.full((8, 8), 0.3, np.float32)
    alpha[0, 0] = 0.05
    sc.materials["satin"] = Material(model="ward", params={"kd": [0.1, 0.2, 0.4], "ks": [0.4, 0.4, 0.4]},
                                     textures={"alpha": Texture(data=alpha)})
    lam = sharpest_ndf_lobe(sc)
    assert lam > 2.0 / 0.06 ** 2 > base  # Ward's single lobe λ = 2/α² at the smoothest texel
    assert gamma_reach(sc) >= max(lam, MIN_REACH)


def test_a_sharper_material_extends_the_ladder(cache_dir):
    r = Renderer(_scene())
    r.render()
    reach = r._gamma_reach
    r.set_material("satin", alpha=0.02)  # Ward λ = 5000: beyond the capped ladder
    r.render()
    assert r._gamma_reach > reach
