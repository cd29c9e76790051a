"""warp_sg.core.image_io: EXR/PNG round trips, sRGB values, atomic writes, clear errors."""
from __future__ import annotations

import os

import numpy as np
import pytest

from warp_sg.core.errors import ImageError, InputError
from warp_sg.core.image_io import linear_to_srgb, load_image, save_image, srgb_to_linear, tonemap_srgb


def _img(h=7, w=5, c=3, seed=0):
    rng = np.random.default_rng(seed)
    return (rng.random((h, w, c)) * 10.0).astype(np.float32)


def test_exr_round_trip_is_bit_exact(tmp_path):
    img = _img()
    img[0, 0] = [1e-30, 3.4e38, 0.0]
    p = save_image(tmp_path / "a.exr", img)
    back = load_image(p)
    assert back.dtype == np.float32 and back.shape == img.shape
    assert np.array_equal(back, img)


def test_exr_half_round_trip_matches_float16(tmp_path):
    img = _img()
    back = load_image(save_image(tmp_path / "h.exr", img, half=True))
    assert np.array_equal(back, img.astype(np.float16).astype(np.float32))


def test_exr_grey_and_rgba_channels(tmp_path):
    g = _img(c=1)
    assert np.array_equal(load_image(save_image(tmp_path / "g.exr", g[..., 0])), g)
    rgba = _img(c=4)
    assert np.array_equal(load_image(save_image(tmp_path / "r.exr", rgba)), rgba)
    assert load_image(tmp_path / "r.exr", channels=3).shape == (7, 5, 3)
    assert np.array_equal(load_image(tmp_path / "g.exr", channels=3)[..., 2], g[..., 0])


def test_srgb_transfer_functions_match_iec_61966_values():
    x = np.array([0.0, 0.0031308, 0.18, 0.5, 1.0], np.float32)
    expect = np.array([0.0, 0.04045, 0.4613561, 0.7353570, 1.0], np.float32)
    assert np.allclose(linear_to_srgb(x), expect, atol=2e-6)
    assert np.allclose(srgb_to_linear(expect), x, atol=2e-6)


def test_png_stores_tonemapped_srgb_codes(tmp_path):
    from PIL import Image

    img = np.array([[[0.0, 0.18, 0.5], [1.0, 4.0, np.nan]]], np.float32)
    save_image(tmp_path / "a.png", img)
    codes = np.asarray(Image.open(tmp_path / "a.png"))
    assert codes.tolist() == [[[0, 118, 188], [255, 255, 0]]]
    # exposure +1 stop doubles the linear value before encoding: 0.18 -> 0.36 -> code 161
    save_image(tmp_path / "b.png", img, exposure=1.0)
    assert np.asarray(Image.open(tmp_path / "b.png"))[0, 0, 1] == round(255 * float(linear_to_srgb(0.36)))
    assert np.allclose(tonemap_srgb(img, 1.0)[0, 0, 1], linear_to_srgb(0.36))


def test_png_load_decodes_srgb_unless_linear(tmp_path):
    img = np.array([[[0.0, 0.18, 0.5]]], np.float32)
    p = save_image(tmp_path / "a.png", img)
    lin = load_image(p)
    assert np.allclose(lin, img, atol=3e-3)  # 8-bit quantisation only
    raw = load_image(p, linear=True)
    assert np.allclose(raw * 255.0, [[[0, 118, 188]]])


def test_png_16bit_grey_is_scaled(tmp_path):
    from PIL import Image

    a = np.array([[0, 65535], [32768, 1000]], np.uint16)
    Image.fromarray(a).save(tmp_path / "g16.png")
    back = load_image(tmp_path / "g16.png", linear=True)
    assert back.shape == (2, 2, 1)
    assert np.allclose(back[..., 0], a / 65535.0, atol=1e-7)


def test_write_is_atomic_and_leaves_nothing_on_error(tmp_path, monkeypatch):
    import warp_sg.core.image_io as io_mod

    target = tmp_path / "keep.exr"
    save_image(target, np.ones((2, 2, 3), np.float32))
    before = target.read_bytes()

    def boom(tmp, a, half):
        with open(tmp, "wb") as f:
            f.write(b"partial")
        raise RuntimeError("disk full")

    monkeypatch.setattr(io_mod, "_write_exr", boom)
    with pytest.raises(ImageError, match="keep.exr"):
        save_image(target, np.zeros((2, 2, 3), np.float32))
    assert target.read_bytes() == before  # old file untouched
    assert sorted(os.listdir(tmp_path)) == ["keep.exr"]  # no temporary left


def test_non_writable_folder_is_an_image_error(unprivileged):
    # as root (how CI runs) the write is attempted by the unprivileged user 'nobody': root may write anywhere
    ro = unprivileged.dir / "ro"
    ro.mkdir()
    ro.chmod(0o555)  # r-xr-xr-x: nobody may write here but root
    body = f"""
        try:
            save_image({str(ro / "out.png")!r}, np.zeros((2, 2, 3)))
        except ImageError as e:
            print("ImageError:", e)
            sys.exit(3)
        """
    setup = """
        import logging
        import numpy as np
        from PIL import Image, PngImagePlugin
        from warp_sg.core.errors import ImageError
        from warp_sg.core.image_io import save_image
        """
    r = unprivileged.run(setup, body)
    assert r.returncode == 3, (r.stdout, r.stderr)
    assert "out.png" in r.stdout and "permission denied" in r.stdout.lower(), r.stdout
    assert os.listdir(ro) == []  # no temporary left behind


def test_bad_paths_and_arrays_raise_image_errors(tmp_path):
    with pytest.raises(ImageError, match=r"x\.bmp.*unknown image extension|unknown image extension"):
        save_image(tmp_path / "x.bmp", np.zeros((2, 2, 3)))
    with pytest.raises(ImageError, match="does not exist"):
        save_image(tmp_path / "missing" / "x.exr", np.zeros((2, 2, 3)))
    (tmp_path / "adir.exr").mkdir()
    with pytest.raises(ImageError, match=r"adir\.exr.*is a folder"):
        save_image(tmp_path / "adir.exr", np.zeros((2, 2, 3)))
    with pytest.raises(ImageError, match="shape"):
        save_image(tmp_path / "x.exr", np.zeros((2, 2, 2)))
    assert issubclass(ImageError, InputError)


def test_unreadable_and_wrong_channel_files_name_the_file(tmp_path):
    with pytest.raises(ImageError, match="nope.png"):
        load_image(tmp_path / "nope.png")
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png at all")
    with pytest.raises(ImageError, match="bad.png"):
        load_image(bad)
    badexr = tmp_path / "bad.exr"
    badexr.write_bytes(b"\x76\x2f\x31\x01garbage")
    with pytest.raises(ImageError, match="bad.exr"):
        load_image(badexr)
    import OpenEXR

    z = np.zeros((2, 2), np.float32)
    with OpenEXR.File({"type": OpenEXR.scanlineimage}, {"Z": z, "U": z}) as f:
        f.write(str(tmp_path / "depth.exr"))
    with pytest.raises(ImageError, match=r"depth.exr.*\[U, Z\].*R, G, B"):
        load_image(tmp_path / "depth.exr")
    g = save_image(tmp_path / "g.exr", np.zeros((2, 2)))
    with pytest.raises(ImageError, match="1 channel"):
        load_image(g, channels=4)


def test_permission_denied_on_temp_file_is_an_image_error(tmp_path, monkeypatch):
    import warp_sg.core.files as atomic_mod

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(atomic_mod.tempfile, "mkstemp", denied)
    with pytest.raises(ImageError, match=r"out.exr.*cannot write to folder.*Permission denied"):
        save_image(tmp_path / "out.exr", np.zeros((2, 2, 3)))
    assert os.listdir(tmp_path) == []


def test_saved_files_get_normal_permissions_not_mkstemp_0600(tmp_path):
    out = save_image(tmp_path / "p.png", np.ones((2, 2, 3)))
    mask = os.umask(0)
    os.umask(mask)
    assert os.stat(out).st_mode & 0o777 == 0o666 & ~mask
