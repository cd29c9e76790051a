"""The warp-sg command line: render writes images, bad input exits 2 with one line and no output."""
from __future__ import annotations

import pytest

from warp_sg.tools.cli import main

SCENE = """
[camera]
origin = [0.0, 0.0, 3.0]
target = [0.0, 0.0, 0.0]
fov = 30.0
width = 12
height = 10

[[objects]]
primitive = "sphere"
radius = 0.6
resolution = [8, 16]
material = "red"

[materials.red]
model = "lambert"
kd = [0.8, 0.1, 0.1]

[[lights]]
type = "directional"
direction = [0.0, 0.0, 1.0]
radius = 0.05
intensity = [2.0, 2.0, 2.0]

[render]
shadows = false
"""


def run(argv, capsys):
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:
        rc = e.code
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture
def scene_file(tmp_path):
    p = tmp_path / "scene.toml"
    p.write_text(SCENE)
    return p


def test_render_writes_exr_and_png_with_the_scene_size(scene_file, tmp_path, capsys):
    from warp_sg.core.image_io import load_image

    rc, out, err = run(["render", scene_file, "-o", tmp_path / "a.exr", "--timings", "--no-progress"], capsys)
    assert rc == 0, err
    img = load_image(tmp_path / "a.exr")
    assert img.shape == (10, 12, 3)
    centre = img[5, 6]
    assert centre[0] > 5 * centre[1]  # a red sphere, lit from the camera
    assert "shade" in out
    rc, _, err = run(["render", scene_file, "-o", tmp_path / "b.png", "--spp", "2", "--exposure", "1",
                      "--width", "6", "--height", "5"], capsys)
    assert rc == 0, err
    png = load_image(tmp_path / "b.png")
    assert png.shape[:2] == (5, 6)
    # missing output folders are created (the README's `-o out/cook_torrance.png` on a fresh clone)
    rc, _, err = run(["render", scene_file, "-o", tmp_path / "new" / "dir" / "c.png"], capsys)
    assert rc == 0, err
    assert (tmp_path / "new" / "dir" / "c.png").is_file()


@pytest.mark.parametrize("edit,needle", [
    (("fov = 30.0", "fvo = 30.0"), "did you mean 'fov'"),
    (('kd = [0.8, 0.1, 0.1]', 'kd = "missing.png"'), "missing.png"),
    (("radius = 0.6", "radius = -0.6"), "radius"),
])
def test_bad_scene_exits_2_with_one_line_and_no_output_file(tmp_path, capsys, edit, needle):
    p = tmp_path / "scene.toml"
    p.write_text(SCENE.replace(*edit))
    out = tmp_path / "out.png"
    rc, _, err = run(["render", p, "-o", out], capsys)
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warp-sg: error: ") and needle in lines[0]
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == [p]
    rc, _, err = run(["render", p, "-o", tmp_path / "sub" / "out.png"], capsys)
    assert rc == 2 and not (tmp_path / "sub").exists()  # no folder created for a failed render


@pytest.mark.parametrize("target,needle", [("afile/o.exr", "is not a folder"), ("o.bmp", "unknown image format"),
                                           ("adir.png", "is a folder")])
def test_unusable_output_path_exits_2_before_rendering(scene_file, tmp_path, capsys, target, needle):
    (tmp_path / "adir.png").mkdir()
    (tmp_path / "afile").write_text("x")
    rc, _, err = run(["render", scene_file, "-o", tmp_path / target], capsys)
    assert rc == 2 and needle in err and len(err.strip().splitlines()) == 1


def test_help_and_usage_errors(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for cmd in ("render", "preview", "reference", "report", "bench"):
        assert cmd in out
    rc, _, err = run(["render"], capsys)
    assert rc == 2 and "scene" in err
    rc, _, err = run(["render", "x.toml", "-o", "y.png", "--spp", "0"], capsys)
    assert rc == 2 and "--supersampling" in err
    rc, _, err = run(["render", "x.toml", "-o", "y.png", "--spp", "17"], capsys)  # the [render] key's range
    assert rc == 2 and "--supersampling" in err and "must be in [1, 16], got 17" in err


def test_missing_scene_file_and_bad_device_exit_2(scene_file, tmp_path, capsys):
    rc, _, err = run(["render", tmp_path / "none.toml", "-o", tmp_path / "o.png"], capsys)
    assert rc == 2 and "none.toml" in err
    rc, _, err = run(["render", scene_file, "-o", tmp_path / "o.png", "--device", "tpu"], capsys)
    assert rc == 2 and "tpu" in err and not (tmp_path / "o.png").exists()


def test_external_subcommands_take_their_arguments_from_their_modules(capsys):
    for cmd in ("reference", "report", "bench"):
        with pytest.raises(SystemExit) as e:
            main([cmd, "--help"])
        assert e.value.code == 0
        assert "usage: warp-sg " + cmd in capsys.readouterr().out


def test_a_missing_external_module_makes_its_subcommand_exit_2(monkeypatch, capsys):
    import builtins

    real_import = builtins.__import__

    def fake_import(name, *args, **kwargs):
        if name == "warp_sg.tools.bench":
            raise ImportError("no module named warp_sg.tools.bench")
        return real_import(name, *args, **kwargs)

    import importlib

    monkeypatch.setattr(importlib, "import_module",
                        lambda name, *a: fake_import(name) if name == "warp_sg.tools.bench" else real_import(name, fromlist=["x"]))
    rc, _, err = run(["bench"], capsys)
    assert rc == 2 and "bench" in err and "not available" in err


def test_reference_creates_missing_output_folders_and_leaves_nothing_when_it_fails(scene_file, tmp_path, capsys):
    from warp_sg.core.image_io import load_image

    out = tmp_path / "out" / "ref" / "x.exr"
    err_out = tmp_path / "out" / "se" / "x_se.exr"
    rc, _, err = run(["reference", scene_file, "-o", out, "--stderr", err_out, "--spp", "2", "--no-progress"], capsys)
    assert rc == 0, err
    assert load_image(out).shape == (10, 12, 3) and load_image(err_out).shape == (10, 12, 3)
    # a failed run (bad device) creates no folder and no file
    rc, _, err = run(["reference", scene_file, "-o", tmp_path / "gone" / "x.exr", "--device", "tpu", "--spp", "1"],
                     capsys)
    assert rc == 2 and "tpu" in err and not (tmp_path / "gone").exists()


def test_device_default_is_the_scenes_render_device_in_every_subcommand(scene_file, tmp_path, capsys):
    import argparse

    from warp_sg.core.device import device_for
    from warp_sg.scene.loader import load_scene
    from warp_sg.tools.cli import build_parser

    for cmd in ("render", "preview", "reference", "report", "bench"):
        parser = build_parser(cmd)
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[cmd]
        dev = next(a for a in sub._actions if "--device" in a.option_strings)
        assert dev.default is None, cmd
        assert "default: " in dev.help and ("[render] device" in dev.help), (cmd, dev.help)
    sc = load_scene(scene_file)
    assert device_for(None, sc) == "cpu" and device_for("auto", sc) == "auto"
    sc.render.device = "cuda"
    assert device_for(None, sc) == "cuda" and device_for(None) == "cpu"
    # the scene's [render] device is what render and reference use without --device
    p = tmp_path / "tpu.toml"
    p.write_text(scene_file.read_text().replace("shadows = false", 'shadows = false\ndevice = "tpu"'))
    for cmd in ("render", "reference"):
        rc, _, err = run([cmd, p, "-o", tmp_path / f"{cmd}.png", "--spp", "1"], capsys)
        assert rc == 2 and "tpu" in err, (cmd, err)
        assert not (tmp_path / f"{cmd}.png").exists()
