"""Texture loading (PNG sRGB/linear, scale/offset) and bilinear wrapping lookups (numpy vs kernel)."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp
from PIL import Image

from warp_sg.core.errors import ImageError
from warp_sg.scene.textures import Texture, TextureAtlas, build_atlas, sample_bilinear_np, srgb_to_linear, tex_sample


@wp.kernel
def _sample(atlas: TextureAtlas, t: int, uv: wp.array(dtype=wp.vec2), out: wp.array(dtype=wp.vec4)):
    i = wp.tid()
    out[i] = tex_sample(atlas, t, uv[i])


def test_png_colour_textures_are_srgb_decoded_and_data_textures_are_linear(tmp_path):
    a = np.zeros((2, 2, 3), np.uint8)
    a[0, 0] = (255, 128, 0)
    Image.fromarray(a).save(tmp_path / "t.png")
    tex = Texture(path=tmp_path / "t.png", scale=2.0, offset=0.1)
    lin = tex.rgba(colour=False)
    col = tex.rgba(colour=True)
    np.testing.assert_allclose(lin[0, 0, :3], 0.1 + 2.0 * np.array([1.0, 128 / 255, 0.0]), rtol=1e-6)
    np.testing.assert_allclose(col[0, 0, :3], 0.1 + 2.0 * srgb_to_linear(np.array([1.0, 128 / 255, 0.0])), rtol=1e-6)
    assert col[0, 0, 1] == pytest.approx(0.1 + 2.0 * 0.2158605, rel=1e-5)
    np.testing.assert_allclose(tex.raw()[0, 0, :3], [1.0, 128 / 255, 0.0])
    np.testing.assert_allclose(lin[..., 3], 1.0)


def test_uv_origin_is_bottom_left_and_lookups_wrap(device):
    img = np.zeros((2, 2, 4), np.float32)
    img[0, 0, 0] = 1.0  # top-left texel: u ∈ [0, ½), v ∈ [½, 1]
    img[1, 1, 1] = 1.0  # bottom-right texel
    atlas = build_atlas([np.ones((3, 3, 4), np.float32), img], device)
    uv = np.array([[0.25, 0.75], [0.75, 0.25], [1.25, 0.75], [0.5, 0.5], [-0.75, -0.25]], np.float32)
    out = wp.zeros(len(uv), dtype=wp.vec4, device=device)
    wp.launch(_sample, dim=len(uv), inputs=[atlas, 1, wp.array(uv, dtype=wp.vec2, device=device), out], device=device)
    got = out.numpy()
    np.testing.assert_allclose(got[0], [1, 0, 0, 0], atol=1e-6)
    np.testing.assert_allclose(got[1], [0, 1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(got[2], got[0], atol=1e-6)  # wraps in u
    np.testing.assert_allclose(got[3], [0.25, 0.25, 0, 0], atol=1e-6)  # centre: average of 4 texels
    np.testing.assert_allclose(got[4], got[0], atol=1e-6)  # wraps for negative uv: (0.25, 0.75)
    np.testing.assert_allclose(got, sample_bilinear_np(img, uv), atol=1e-6)


def test_random_lookups_match_numpy(device):
    rng = np.random.default_rng(0)
    img = rng.random((5, 7, 4)).astype(np.float32)
    atlas = build_atlas([img], device)
    uv = rng.uniform(-2, 2, (200, 2)).astype(np.float32)
    out = wp.zeros(len(uv), dtype=wp.vec4, device=device)
    wp.launch(_sample, dim=len(uv), inputs=[atlas, 0, wp.array(uv, dtype=wp.vec2, device=device), out], device=device)
    np.testing.assert_allclose(out.numpy(), sample_bilinear_np(img, uv), atol=1e-5)


def test_missing_or_corrupt_texture_raises_image_error_naming_the_file(tmp_path):
    with pytest.raises(ImageError, match="gone.png"):
        Texture(path=tmp_path / "gone.png").rgba()
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(ImageError, match="bad.png"):
        Texture(path=tmp_path / "bad.png").rgba()
