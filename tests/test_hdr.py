"""Radiance .hdr (RGBE) environment maps and images (issue 15), read and written through OpenCV.

The files are written here with OpenCV itself; the round trip is held to RGBE's precision: one
shared 8-bit exponent per pixel, so every channel is stored to within ``max(R, G, B) · 2⁻⁷``
(mantissa step 2^(e−8) with max < 2^e, i.e. at most max/128).
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from warp_sg.core.errors import ImageError
from warp_sg.core.image_io import load_image, save_image
from warp_sg.scene.envmap import load_envmap
from warp_sg.scene.lights import EnvironmentLight
from warp_sg.scene.loader import load_scene
from warp_sg.tools.cli import main


def radiance(h=16, w=32, seed=0):
    """Colours over six decades (1e-3 .. 1e3), as skies have."""
    rng = np.random.default_rng(seed)
    return (10.0 ** rng.uniform(-3, 3, (h, w, 1)) * rng.uniform(0.05, 1.0, (h, w, 3))).astype(np.float32)


def write_cv2(path, rgb):
    assert cv2.imwrite(str(path), np.ascontiguousarray(rgb[..., ::-1]))
    return path


def within_rgbe(got, want):
    peak = want.max(axis=2, keepdims=True)
    assert np.all(np.abs(got - want) <= peak / 128 + 1e-30)
    # the brightest channel itself is stored to 1 %
    i = want.argmax(axis=2)[..., None]
    np.testing.assert_allclose(np.take_along_axis(got, i, 2), np.take_along_axis(want, i, 2), rtol=0.01)


def test_envmap_reads_radiance_written_by_opencv_within_rgbe_precision(tmp_path):
    a = radiance()
    env = load_envmap(write_cv2(tmp_path / "sky.hdr", a))
    assert env.shape == a.shape and env.dtype == np.float32
    within_rgbe(env, a)
    within_rgbe(load_envmap(tmp_path / "sky.hdr", scale=2.0) / 2.0, a)


def test_channel_order_is_rgb(tmp_path):
    a = np.zeros((4, 8, 3), np.float32)
    a[..., 0] = 3.0  # pure red
    env = load_envmap(write_cv2(tmp_path / "red.hdr", a))
    np.testing.assert_allclose(env[..., 0], 3.0, rtol=0.01)
    assert np.all(env[..., 1:] == 0)


def test_save_image_writes_hdr_that_load_image_and_opencv_read_back(tmp_path):
    a = radiance(seed=1)
    p = save_image(tmp_path / "img.hdr", a)
    within_rgbe(load_image(p), a)
    within_rgbe(cv2.imread(str(p), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)[..., ::-1], a)


def test_environment_light_and_toml_scene_take_an_hdr_file(tmp_path):
    a = radiance(seed=2)
    write_cv2(tmp_path / "sky.hdr", a)
    within_rgbe(EnvironmentLight(file=tmp_path / "sky.hdr").base_radiance(), a)
    (tmp_path / "s.toml").write_text(
        '[camera]\n[[objects]]\nprimitive = "sphere"\nmaterial = "m"\n[materials.m]\nmodel = "lambert"\n'
        '[[lights]]\ntype = "environment"\nfile = "sky.hdr"\n')
    within_rgbe(load_scene(tmp_path / "s.toml").environment.base_radiance(), a)


@pytest.mark.parametrize("kind", ["truncated", "garbage", "empty"])
def test_bad_hdr_is_an_image_error_naming_the_file_and_exit_2(tmp_path, capsys, kind):
    good = write_cv2(tmp_path / "good.hdr", radiance(64, 128)).read_bytes()
    data = {"truncated": good[: len(good) // 2], "garbage": b"#?RADIANCE\nnot really\n", "empty": b""}[kind]
    bad = tmp_path / f"{kind}.hdr"
    bad.write_bytes(data)
    with pytest.raises(ImageError, match=f"{kind}.hdr"):
        load_envmap(bad)
    with pytest.raises(ImageError, match=f"{kind}.hdr"):
        load_image(bad)
    mesh = tmp_path / "box.ply"
    import trimesh

    trimesh.creation.box().export(mesh)
    out = tmp_path / "out.png"
    rc = main(["render", str(mesh), "--env", str(bad), "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and f"{kind}.hdr" in err[0] and not out.exists()


def test_exr_environment_maps_still_load(tmp_path):
    a = radiance(seed=3)
    save_image(tmp_path / "sky.exr", a)
    np.testing.assert_array_equal(load_envmap(tmp_path / "sky.exr"), a)
