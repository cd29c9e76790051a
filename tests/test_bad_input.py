"""Bad input: every case gives exit status 2 (CLI) or a typed exception (API) with one clear line
naming the file / field / element at fault — never a traceback, never a partial output file,
never a corrupt cache.

CLI cases call ``warp_sg.tools.cli.main(argv)`` in-process (faster than a subprocess); one case runs the
real ``warp-sg`` executable to check the installed entry point. The property tests at the end
(hypothesis) generate malformed scenes, meshes, glTF files and maps and judge every answer.
"""
from __future__ import annotations

import contextlib
import math
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
import tomllib
from conftest import BALL_ON_FLOOR, assert_clean_failure, run_cli, write_scene
from conftest import replace_once as replace
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import warp_sg as ws
from warp_sg.core.errors import ImageError, InputError, MeshError, SceneError

#: the ball's lines in the shared scene (what a mesh object replaces)
BALL = 'primitive = "sphere"\ncenter = [0.0, 0.5, 0.0]\nradius = 0.5\nresolution = [8, 16]'


# ------------------------------------------------------------------------------------------------
# scene files through the API: typed exceptions naming file / table / key / element
# ------------------------------------------------------------------------------------------------
SCENE_CASES = [
    # id, old, new, exception type, words the message must contain
    ("unknown-top-key", "[camera]", "[camra]", SceneError, ["camra", "camera"]),
    ("unknown-camera-key", "fov = 40.0", "fvo = 40.0", SceneError, ["fvo", "fov"]),
    ("unknown-material-param", "m = 0.2", "rougness = 0.2", InputError, ["rougness"]),
    ("unknown-model", 'model = "cook_torrance"', 'model = "cook_torrence"', InputError, ["cook_torrence", "cook_torrance"]),
    ("undefined-material", 'material = "copper"', 'material = "coper"', SceneError, ["coper", "copper"]),
    ("negative-roughness", "m = 0.2", "m = -0.2", InputError, ["m", "-0.2"]),
    ("negative-kd", "kd = [0.8, 0.8, 0.8]", "kd = [0.6, -0.6, 0.6]", InputError, ["kd"]),
    ("kd-wrong-length", "kd = [0.8, 0.8, 0.8]", "kd = [0.6, 0.6]", InputError, ["kd"]),
    ("fov-wrong-type", "fov = 40.0", 'fov = "wide"', SceneError, ["fov"]),
    ("zero-width", "width = 16", "width = 0", SceneError, ["width"]),
    ("unknown-light-type", 'type = "point"', 'type = "pointy"', SceneError, ["pointy"]),
    ("negative-light-radius", "radius = 0.1", "radius = -0.1", InputError, ["radius"]),
    ("unknown-render-key", "shadows = false", "shadowz = false", SceneError, ["shadowz", "shadows"]),
    ("render-lobes-zero", "shadows = false", "lobes = 0", SceneError, ["lobes"]),
    ("unknown-primitive", 'primitive = "sphere"', 'primitive = "sphear"', InputError, ["sphear"]),
    ("camera-origin-equals-target", "origin = [0.0, 1.0, 4.0]", "origin = [0.0, 0.5, 0.0]", SceneError, ["origin"]),
    ("malformed-toml", "fov = 40.0", "fov = = 40.0", SceneError, ["toml"]),
    ("missing-mesh-file", BALL,
     'mesh = "nothere.ply"', SceneError, ["nothere.ply"]),
    ("missing-env-file", '[[lights]]\ntype = "point"\nposition = [2.0, 3.0, 2.0]\nradius = 0.1\n'
     'intensity = [20.0, 20.0, 20.0]', '[[lights]]\ntype = "environment"\nfile = "sky_missing.exr"',
     InputError, ["sky_missing.exr"]),
    ("missing-texture", "kd = [0.8, 0.8, 0.8]", 'kd = "albedo_missing.png"', InputError, ["albedo_missing.png"]),
]


@pytest.mark.parametrize("case", SCENE_CASES, ids=[c[0] for c in SCENE_CASES])
def test_bad_scene_file_raises_a_typed_error_naming_the_culprit(tmp_path, case):
    _, old, new, exc, words = case
    p = write_scene(tmp_path, replace(old, new))
    with pytest.raises(exc) as ei:
        sc = ws.load_scene(p)
        sc.geometry()  # meshes are read when geometry is built
        for m in sc.materials.values():
            m.brdf  # noqa: B018 - builds the model (validates parameters)
    msg = str(ei.value)
    for w in words:
        assert w.lower() in msg.lower(), msg
    assert "\n" not in msg.strip()


def test_scene_file_not_found_names_the_path(tmp_path):
    with pytest.raises(SceneError, match="nope.toml"):
        ws.load_scene(tmp_path / "nope.toml")


def _mesh_scene(tmp_path, mesh_name, mesh_bytes):
    (tmp_path / mesh_name).write_bytes(mesh_bytes)
    return write_scene(tmp_path, replace(BALL,
                                         f'mesh = "{mesh_name}"'))


PLY_OOB = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
           b"element face 2\nproperty list uchar int vertex_indices\nend_header\n"
           b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 7\n")

MESH_CASES = [
    ("corrupt-ply", "bad.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 99\nend_header\n\x00\x01", ["bad.ply"]),
    ("garbage-obj", "bad.obj", b"\x00\xff\xfe garbage \x00" * 10, ["bad.obj"]),
    ("nan-vertex", "nan.obj", b"v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", ["nan", "vertex"]),
    ("index-out-of-range-obj", "oob.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n", ["oob.obj", "out of"]),
    ("index-out-of-range-ply", "oob.ply", PLY_OOB, ["triangle 1", "vertex", "range"]),
    ("zero-area-only", "flat.obj", b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", ["zero area"]),
    ("empty-file", "empty.obj", b"", ["empty.obj"]),
]


@pytest.mark.parametrize("case", MESH_CASES, ids=[c[0] for c in MESH_CASES])
def test_bad_mesh_raises_mesh_or_scene_error_naming_the_file_or_element(tmp_path, case):
    _, name, data, words = case
    p = _mesh_scene(tmp_path, name, data)
    with pytest.raises(InputError) as ei:
        ws.load_scene(p).geometry()
    msg = str(ei.value)
    assert isinstance(ei.value, (MeshError, SceneError))
    for w in words:
        assert w.lower() in msg.lower(), msg


def test_nan_vertices_through_the_python_api_name_the_object_and_vertex():
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import DirectionalLight
    from warp_sg.scene.model import Scene, SceneObject

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [np.nan, 1, 1]], float)
    t = np.array([[0, 1, 2], [1, 2, 3]])
    sc = Scene(camera=Camera(width=4, height=4), objects=[SceneObject(material="a", vertices=v, triangles=t, name="blob")],
               materials={"a": ws.brdf.Lambert()}, lights=[DirectionalLight(direction=(0, 1, 0))])
    with pytest.raises(MeshError) as ei:
        sc.geometry()
    assert "blob" in str(ei.value) and "3" in str(ei.value)


def test_unreadable_texture_names_the_file(tmp_path):
    (tmp_path / "tex.png").write_bytes(b"\x89PNG\r\n\x1a\n this is not a png")
    p = write_scene(tmp_path, replace("kd = [0.8, 0.8, 0.8]", 'kd = "tex.png"'))
    with pytest.raises(InputError, match="tex.png"):
        sc = ws.load_scene(p)
        for m in sc.materials.values():
            m.brdf  # noqa: B018


def _write_exr(path, channels: dict):
    import OpenEXR

    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(hdr, {k: np.ascontiguousarray(v, np.float32) for k, v in channels.items()}) as f:
        f.write(str(path))


def test_environment_exr_with_wrong_channels_names_file_and_channels(tmp_path):
    _write_exr(tmp_path / "sky.exr", {"Z": np.ones((8, 16))})
    p = write_scene(tmp_path, BALL_ON_FLOOR + '\n[[lights]]\ntype = "environment"\nfile = "sky.exr"\n')
    with pytest.raises(ImageError) as ei:
        sc = ws.load_scene(p)
        sc.environment.radiance()
    assert "sky.exr" in str(ei.value) and "Z" in str(ei.value)


def test_environment_file_that_is_not_exr_names_the_file(tmp_path):
    (tmp_path / "sky.exr").write_bytes(b"not an exr at all")
    p = write_scene(tmp_path, BALL_ON_FLOOR + '\n[[lights]]\ntype = "environment"\nfile = "sky.exr"\n')
    with pytest.raises(ImageError, match="sky.exr"):
        ws.load_scene(p).environment.radiance()


def test_two_environment_lights_are_rejected(tmp_path):
    env = '\n[[lights]]\ntype = "environment"\nprocedural = "sky"\n'
    with pytest.raises(SceneError, match="environment"):
        ws.load_scene(write_scene(tmp_path, BALL_ON_FLOOR + env + env))


def test_reference_rejects_zero_spp_with_an_input_error(tmp_path):
    sc = ws.load_scene(write_scene(tmp_path))
    with pytest.raises(InputError, match="spp"):
        ws.reference(sc, spp=0, progress=False)


def test_unknown_device_is_an_input_error(tmp_path):
    sc = ws.load_scene(write_scene(tmp_path))
    with pytest.raises(InputError, match="device"):
        ws.reference(sc, spp=1, device="tpu", progress=False)


def test_report_into_a_non_writable_folder_is_an_input_error(tmp_path):
    from warp_sg.tools.report import run_report

    target = tmp_path / "file_not_dir"
    target.write_text("x")
    with pytest.raises(InputError, match="file_not_dir"):
        run_report(write_scene(tmp_path), target / "sub", quick=True, progress=False)


# ------------------------------------------------------------------------------------------------
# the CLI: exit status 2, one line, no traceback, no partial output
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("case", SCENE_CASES[:8] + SCENE_CASES[16:18], ids=[c[0] for c in SCENE_CASES[:8] + SCENE_CASES[16:18]])
@pytest.mark.parametrize("command", ["render", "reference"])
def test_cli_bad_scene_exits_2_with_one_line_and_no_output_file(tmp_path, capsys, case, command):
    _, old, new, _, words = case
    p = write_scene(tmp_path, replace(old, new))
    out = tmp_path / "out.exr"
    extra = ["--spp", "1"] if command == "reference" else []
    rc, _, err = run_cli([command, p, "-o", out, *extra], capsys)
    assert_clean_failure(rc, err, *words[:1])
    assert not out.exists()
    assert not any(f.name.startswith(".out") or f.name.startswith("out") for f in tmp_path.iterdir())


def test_cli_bad_mesh_exits_2_naming_the_element(tmp_path, capsys):
    p = _mesh_scene(tmp_path, "oob.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n")
    rc, _, err = run_cli(["render", p, "-o", tmp_path / "o.png"], capsys)
    assert_clean_failure(rc, err, "range")
    assert not (tmp_path / "o.png").exists()


def test_cli_missing_scene_file_exits_2(tmp_path, capsys):
    rc, _, err = run_cli(["reference", tmp_path / "none.toml", "-o", tmp_path / "o.exr"], capsys)
    assert_clean_failure(rc, err, "none.toml")


def test_cli_zero_spp_exits_2(tmp_path, capsys):
    rc, _, err = run_cli(["reference", write_scene(tmp_path), "-o", tmp_path / "o.exr", "--spp", "0"], capsys)
    assert_clean_failure(rc, err, "spp")
    assert not (tmp_path / "o.exr").exists()


def test_cli_zero_max_depth_exits_2_naming_the_option(tmp_path, capsys):
    rc, _, err = run_cli(["reference", write_scene(tmp_path), "-o", tmp_path / "o.exr", "--spp", "1",
                          "--max-depth", "0"], capsys)
    assert_clean_failure(rc, err, "--max-depth")
    assert not (tmp_path / "o.exr").exists()


def test_cli_reference_max_depth_two_is_the_direct_light_image(tmp_path, capsys):
    # the CLI's reference at --max-depth 2 is ws.reference's direct-only image, bit for bit
    import warp_sg as ws
    from warp_sg.core.image_io import load_image

    scene = write_scene(tmp_path)
    rc, _, err = run_cli(["reference", scene, "-o", tmp_path / "d.exr", "--spp", "2", "--max-depth", "2",
                          "--no-progress"], capsys)
    assert rc == 0, err
    want = ws.reference(ws.load_scene(scene), spp=2, progress=False, max_depth=2)
    np.testing.assert_array_equal(load_image(tmp_path / "d.exr"), want)


def test_cli_bad_scene_into_a_missing_folder_exits_2_and_creates_no_folder(tmp_path, capsys):
    # missing output folders are created, but only once the image exists
    out = tmp_path / "no" / "such" / "dir" / "o.exr"
    p = write_scene(tmp_path, replace("fov = 40.0", "fvo = 40.0"))
    rc, _, err = run_cli(["reference", p, "-o", out, "--spp", "1"], capsys)
    assert_clean_failure(rc, err, "fvo")
    assert not (tmp_path / "no").exists()


def test_cli_output_in_a_read_only_folder_exits_2(unprivileged):
    # as root (how CI runs) the CLI runs as the unprivileged user 'nobody': root may write anywhere
    scene = write_scene(unprivileged.dir)
    ro = unprivileged.dir / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    argv = ["reference", str(scene), "-o", str(ro / "o.exr"), "--spp", "1"]
    setup = "import warp_sg.core.files, warp_sg.tools.cli, warp_sg.core.image_io, warp_sg.groundtruth.reference, warp_sg.scene"
    r = unprivileged.run(setup, f"sys.exit(warp_sg.tools.cli.main({argv!r}))")
    msg = assert_clean_failure(r.returncode, r.stderr, "o.exr", "writable")
    assert msg.startswith("warp-sg: error:")
    assert list(ro.iterdir()) == []


@pytest.mark.parametrize("command", ["render", "reference"])
def test_cli_output_under_a_regular_file_exits_2_and_writes_nothing(tmp_path, capsys, command):
    # the output's folder cannot exist (nor be created): one of its parents is a regular file
    f = tmp_path / "afile"
    f.write_text("x")
    extra = ["--spp", "1"] if command == "reference" else []
    rc, _, err = run_cli([command, write_scene(tmp_path), "-o", f / "sub" / "o.exr", *extra], capsys)
    assert_clean_failure(rc, err, "o.exr", "afile")
    assert f.read_text() == "x" and sorted(x.name for x in tmp_path.iterdir()) == ["afile", "scene.toml"]


def test_cli_output_path_that_is_a_folder_exits_2(tmp_path, capsys):
    d = tmp_path / "adir.exr"
    d.mkdir()
    rc, _, err = run_cli(["reference", write_scene(tmp_path), "-o", d, "--spp", "1"], capsys)
    assert_clean_failure(rc, err, "adir.exr")


def test_cli_unknown_output_format_exits_2(tmp_path, capsys):
    out = tmp_path / "o.bmpx"
    rc, _, err = run_cli(["reference", write_scene(tmp_path), "-o", out, "--spp", "1"], capsys)
    assert_clean_failure(rc, err, "o.bmpx")
    assert not out.exists()


def test_cli_cuda_device_without_cuda_exits_2(tmp_path, capsys):
    from warp_sg.core.device import cuda_available

    if cuda_available():
        pytest.skip("this machine has CUDA")
    rc, _, err = run_cli(["reference", write_scene(tmp_path), "-o", tmp_path / "o.exr", "--device", "cuda"], capsys)
    assert_clean_failure(rc, err, "cuda")


def test_cli_unknown_option_exits_2(tmp_path, capsys):
    rc, _, err = run_cli(["reference", write_scene(tmp_path), "-o", tmp_path / "o.exr", "--spps", "4"], capsys)
    assert rc == 2 and "Traceback" not in err and "--spps" in err


def test_cli_report_into_a_file_exits_2(tmp_path, capsys):
    f = tmp_path / "afile"
    f.write_text("x")
    rc, _, err = run_cli(["report", write_scene(tmp_path), "-o", f / "rep", "--quick"], capsys)
    assert_clean_failure(rc, err, "afile")


def test_installed_entry_point_exits_2_without_traceback(tmp_path):
    exe = shutil.which("warp-sg")
    cmd = [exe] if exe else [sys.executable, "-m", "warp_sg.tools.cli"]
    p = write_scene(tmp_path, replace("m = 0.2", "rougness = 0.2"))
    r = subprocess.run([*cmd, "reference", str(p), "-o", str(tmp_path / "o.exr"), "--spp", "1"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and "rougness" in r.stderr
    assert not (tmp_path / "o.exr").exists()


# ------------------------------------------------------------------------------------------------
# the precompute cache: interruption and corruption never leave a bad entry
# ------------------------------------------------------------------------------------------------
def test_interrupted_precompute_leaves_no_cache_entry_and_the_next_run_rebuilds(cache_dir):
    from warp_sg.core import cache

    key = cache.content_key("bad-input-test", np.arange(5))

    def interrupted():
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        cache.load_or_build("test_kind", key, interrupted)
    files = list(Path(cache_dir).rglob("*")) if Path(cache_dir).exists() else []
    assert not [f for f in files if f.is_file()], files  # no entry and no temporary left behind
    out = cache.load_or_build("test_kind", key, lambda: {"x": np.arange(3.0)})
    np.testing.assert_array_equal(out["x"], [0, 1, 2])


def test_corrupt_cache_entry_is_rebuilt_not_trusted(cache_dir):
    from warp_sg.core import cache

    key = cache.content_key("bad-input-test-2")
    cache.load_or_build("test_kind", key, lambda: {"x": np.ones(4)})
    (entry,) = [f for f in Path(cache_dir).rglob("*") if f.is_file()]
    data = bytearray(entry.read_bytes())
    i = bytes(data).find(np.ones(4).tobytes())  # a byte of the stored array
    data[i + 4] ^= 0xFF
    entry.write_bytes(bytes(data))
    with pytest.warns(Warning):
        out = cache.load_or_build("test_kind", key, lambda: {"x": np.full(4, 2.0)})
    np.testing.assert_array_equal(out["x"], 2.0)
    again = cache.load_or_build("test_kind", key, lambda: {"x": np.full(4, 3.0)})
    np.testing.assert_array_equal(again["x"], 2.0)  # the rebuilt entry is valid and reused


def test_truncated_cache_entry_is_rebuilt(cache_dir):
    from warp_sg.core import cache

    key = cache.content_key("bad-input-test-3")
    cache.load_or_build("test_kind", key, lambda: {"x": np.ones(100)})
    (entry,) = [f for f in Path(cache_dir).rglob("*") if f.is_file()]
    entry.write_bytes(entry.read_bytes()[:50])
    with pytest.warns(Warning):
        out = cache.load_or_build("test_kind", key, lambda: {"x": np.zeros(100)})
    assert out["x"].sum() == 0


def test_renderer_interrupted_during_precompute_leaves_a_clean_cache(tmp_path, cache_dir, monkeypatch):
    """Ctrl-C inside the SSDF precompute: nothing half-written in the cache; the next run rebuilds
    and renders the same image as an uninterrupted run."""
    import precompute.visibility.ssdf as pss
    from warp_sg.renderer.renderer import Renderer

    # small SSDFs on the scene's own vertices: what is checked is the cache, not the shadows
    text = replace("shadows = false", "shadows = true\nvisibility_budget = 0\nssdf_resolution = 16\npca_terms = 8")
    sc = ws.load_scene(write_scene(tmp_path, text))
    real = pss.compute_ssdf

    def interrupted(*a, **k):
        real(*a, **k)  # do the work, then get interrupted before the result is stored
        raise KeyboardInterrupt

    monkeypatch.setattr(pss, "compute_ssdf", interrupted)
    with pytest.raises(KeyboardInterrupt):
        Renderer(sc)
    leftovers = [f for f in Path(cache_dir).rglob("*") if f.is_file() and "ssdf" in str(f)]
    assert leftovers == []
    monkeypatch.setattr(pss, "compute_ssdf", real)
    img = Renderer(ws.load_scene(write_scene(tmp_path, text))).render()
    assert np.all(np.isfinite(img))
    again = Renderer(ws.load_scene(write_scene(tmp_path, text))).render()  # from the cache now
    np.testing.assert_array_equal(img, again)


# ------------------------------------------------------------------------------------------------
# glTF assets (issue 31): broken files are one line naming the element, never a traceback, and a
# texture that cannot be read is an error, not an untextured image
# ------------------------------------------------------------------------------------------------
QUAD_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
QUAD_F = np.array([[0, 1, 2], [0, 2, 3]])


def write_gltf(folder, name="asset.gltf", *, faces=None, vertices=None, texture=False, edit=None):
    """A one-quad glTF (``.gltf`` + ``.bin`` files, a 4×4 PNG base colour with ``texture``) written by
    trimesh; ``faces`` / ``vertices`` replace the index / position buffers as written, ``edit(header)``
    changes the JSON."""
    import json

    import trimesh
    from PIL import Image
    from trimesh.visual import TextureVisuals
    from trimesh.visual.material import PBRMaterial

    vis = None
    if texture:
        mat = PBRMaterial(name="paint", baseColorTexture=Image.fromarray(np.full((4, 4, 3), 200, np.uint8)),
                          metallicFactor=0.0, roughnessFactor=0.5)
        vis = TextureVisuals(uv=QUAD_V[:, :2], material=mat)
    s = trimesh.Scene()
    s.add_geometry(trimesh.Trimesh(QUAD_V.copy(), QUAD_F.copy(), visual=vis, process=False), node_name="quad")
    files = s.export(file_type="gltf")
    header = json.loads(files.pop("model.gltf"))
    for fname, data in files.items():
        (folder / fname).write_bytes(data)
    acc = header["accessors"]
    prim = header["meshes"][0]["primitives"][0]
    for arr, key, dtype in ((faces, prim["indices"], np.uint32), (vertices, prim["attributes"]["POSITION"], np.float32)):
        if arr is None:
            continue
        a = np.asarray(arr, dtype)
        view = header["bufferViews"][acc[key]["bufferView"]]
        uri = header["buffers"][view["buffer"]]["uri"]
        (folder / uri).write_bytes(a.tobytes())
        view["byteLength"] = header["buffers"][view["buffer"]]["byteLength"] = a.nbytes
        if dtype == np.uint32:  # indices: a flat list
            acc[key].update(count=int(a.size), max=[int(a.max())], min=[int(a.min())])
        else:
            acc[key].update(count=len(a), max=np.nanmax(a, 0).tolist(), min=np.nanmin(a, 0).tolist())
    if edit is not None:
        edit(header)
    path = folder / name
    path.write_text(json.dumps(header))
    return path


def _gltf_argv(how, path, tmp_path):
    """``render`` of a glTF as an asset, or as ``mesh = "..."`` in a TOML scene."""
    out = tmp_path / "o.png"
    if how == "asset":
        return ["render", path, "-o", out, "--width", 16, "--height", 12, "--no-progress"], out
    scene = write_scene(tmp_path, replace(BALL + '\nmaterial = "copper"',
                                          f'mesh = "{path.name}"'))
    return ["render", scene, "-o", out, "--no-progress"], out


@pytest.mark.parametrize("how", ["asset", "toml"])
def test_gltf_with_an_out_of_range_index_exits_2_naming_node_and_triangle(tmp_path, capsys, how):
    # before: trimesh's vertex normals raised IndexError outside the guarded load (traceback, exit 1)
    path = write_gltf(tmp_path, faces=[[0, 1, 2], [0, 2, 9]])
    argv, out = _gltf_argv(how, path, tmp_path)
    rc, _, err = run_cli(argv, capsys)
    assert_clean_failure(rc, err, "asset.gltf", "node 'quad'", "triangle 1", "out of range")
    assert not out.exists()


@pytest.mark.parametrize("how", ["asset", "toml"])
def test_gltf_with_a_nan_position_names_the_vertex_not_the_camera(tmp_path, capsys, how):
    # before: the asset's bounds were NaN and the message blamed camera.origin
    v = QUAD_V.copy()
    v[2, 0] = np.nan
    argv, out = _gltf_argv(how, write_gltf(tmp_path, vertices=v), tmp_path)
    rc, _, err = run_cli(argv, capsys)
    msg = assert_clean_failure(rc, err, "asset.gltf", "vertex 2", "non-finite")
    assert "camera" not in msg
    assert not out.exists()


@pytest.mark.parametrize("damage", ["missing", "corrupt"])
def test_gltf_texture_that_cannot_be_read_is_an_error_naming_material_and_image(tmp_path, capsys, damage):
    # before: trimesh dropped the image, the run exited 0 and the image came out untextured
    path = write_gltf(tmp_path, texture=True)
    import json

    h = json.loads(path.read_text())
    h["images"][0] = {"uri": "paint.png"}
    path.write_text(json.dumps(h))
    if damage == "corrupt":
        (tmp_path / "paint.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 40)
    rc, _, err = run_cli(["render", path, "-o", tmp_path / "o.png", "--width", 16, "--height", 12], capsys)
    assert_clean_failure(rc, err, "asset.gltf", "material 'paint'", "baseColorTexture", "paint.png",
                         "not found" if damage == "missing" else "cannot be read")
    assert not (tmp_path / "o.png").exists()


def test_gltf_texture_that_reads_is_still_rendered(tmp_path):
    # the check above does not refuse good files: the texture's 200/255 sRGB reaches kd
    from warp_sg.scene.importers.gltf import gltf_object_parts
    from warp_sg.scene.textures import srgb_to_linear

    _, specs = gltf_object_parts(write_gltf(tmp_path, texture=True), "a")
    (spec,) = specs.values()
    np.testing.assert_allclose(spec["textures"]["kd"].data[..., :3], srgb_to_linear(np.float64(200 / 255)), rtol=1e-5)


GLTF_DANGLING = [
    # id, edit of the header, words of the message
    ("indices", lambda h: h["meshes"][0]["primitives"][0].update(indices=7), ["meshes[0].primitives[0].indices = 7", "accessors"]),
    ("position", lambda h: h["meshes"][0]["primitives"][0]["attributes"].update(POSITION=-1), ["POSITION = -1"]),
    ("material", lambda h: h["meshes"][0]["primitives"][0].update(material=3), ["material = 3", "0 materials"]),
    ("node-mesh", lambda h: h["nodes"][0].update(mesh=5), ["nodes[0].mesh = 5", "meshes"]),
    ("scene-node", lambda h: h["scenes"][0].update(nodes=[0, 4]), ["scenes[0].nodes[1] = 4", "nodes"]),
    ("buffer", lambda h: h["bufferViews"][0].update(buffer=9), ["bufferViews[0].buffer = 9", "buffers"]),
    ("view-type", lambda h: h["accessors"][0].update(bufferView="zero"), ["bufferView = 'zero'"]),
    ("node-cycle", lambda h: h["nodes"].extend([{"children": [2]}, {"children": [1]}]), ["cycle", "node 1"]),
    ("own-child", lambda h: h["nodes"][0].update(children=[0]), ["own child", "node 0"]),
    ("meshopt", lambda h: h.update(extensionsRequired=["EXT_meshopt_compression"]), ["EXT_meshopt_compression", "cannot decode"]),
]


@pytest.mark.parametrize("case", GLTF_DANGLING, ids=[c[0] for c in GLTF_DANGLING])
def test_gltf_with_a_dangling_reference_exits_2_naming_the_json_element(tmp_path, capsys, case):
    _, edit, words = case
    path = write_gltf(tmp_path, edit=edit)
    rc, _, err = run_cli(["render", path, "-o", tmp_path / "o.png", "--width", 16, "--height", 12], capsys)
    assert_clean_failure(rc, err, "asset.gltf", *words)
    assert not (tmp_path / "o.png").exists()


# ------------------------------------------------------------------------------------------------
# environment maps that are not 2:1 (issue 31, defect 2): refused with their size, and the SG fit's
# working map is bounded whatever the shape (before: a 2×20000 map ran > 300 s in the O(N²) blur)
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape", [(2, 20000), (20000, 2), (64, 64 * 5)])
def test_environment_map_far_from_2_to_1_exits_2_naming_its_size(tmp_path, capsys, shape):
    h, w = shape
    _write_exr(tmp_path / "sky.exr", {c: np.ones((h, w)) for c in "RGB"})
    p = write_scene(tmp_path, BALL_ON_FLOOR + '\n[[lights]]\ntype = "environment"\nfile = "sky.exr"\n')
    rc, _, err = run_cli(["render", p, "-o", tmp_path / "o.png", "--no-progress"], capsys)
    assert_clean_failure(rc, err, "sky.exr", f"{w}×{h}")
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("options", [{"width": 2, "height": 20000}, {"width": 40000, "height": 2}])
@pytest.mark.parametrize("procedural", ["sky", "constant"])
def test_procedural_environment_of_a_bad_shape_is_refused_before_it_is_built(options, procedural):
    from warp_sg.scene.lights import EnvironmentLight

    with pytest.raises(ImageError, match=f"{options['width']}×{options['height']}"):
        EnvironmentLight(procedural=procedural, options=options).base_radiance()


@pytest.mark.parametrize("shape", [(2, 20000), (20000, 2), (37, 211), (1001, 2003), (8, 16)])
def test_sg_fit_working_map_is_bounded_and_keeps_the_energy_whatever_the_shape(shape):
    # the energy Σ L Ω is an integral of the piecewise-constant map: every resampling must keep it
    from precompute.environment.sg_fit import _working_map
    from warp_sg.scene.envmap import texel_solid_angles

    rows = 32
    env = np.random.default_rng(1).random(shape + (3,))
    work = _working_map(env, rows)
    assert work.shape[0] <= 2 * rows and work.shape[1] <= 4 * rows
    e_in = (env * texel_solid_angles(*shape)[..., None]).sum((0, 1))
    e_out = (work * texel_solid_angles(*work.shape[:2])[..., None]).sum((0, 1))
    np.testing.assert_allclose(e_out, e_in, rtol=1e-12)


def test_area_resampling_of_a_divisible_map_is_the_box_mip():
    # the exact solid-angle average over 2×2 blocks is what downsample_envmap computes in closed form
    from precompute.environment.sg_fit import _area_resample
    from warp_sg.scene.envmap import downsample_envmap

    env = np.random.default_rng(2).random((64, 128, 3))
    np.testing.assert_allclose(_area_resample(env, 32, 64), downsample_envmap(env, 2), rtol=1e-12, atol=1e-14)


# ------------------------------------------------------------------------------------------------
# exposure and radiance that are not finite (issue 31, defect 4 and 8): before, `render --exposure
# inf` wrote an EXR of inf/NaN pixels and `--exposure nan` a black PNG, both with exit 0
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("value", ["inf", "nan", "-inf"])
@pytest.mark.parametrize("suffix", [".exr", ".png"])
def test_render_exposure_that_is_not_finite_exits_2_and_writes_nothing(tmp_path, capsys, value, suffix):
    out = tmp_path / f"o{suffix}"
    rc, _, err = run_cli(["render", write_scene(tmp_path), "-o", out, f"--exposure={value}"], capsys)
    assert_clean_failure(rc, err, "--exposure", value)
    assert not out.exists()


def test_render_exposure_that_overflows_float32_exits_2_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "o.exr"
    rc, _, err = run_cli(["render", write_scene(tmp_path), "-o", out, "--exposure", "200", "--no-progress"], capsys)
    assert_clean_failure(rc, err, "--exposure 200", "not finite")
    assert not out.exists() and "RuntimeWarning" not in err


def test_environment_radiance_that_overflows_float32_is_refused_naming_the_texel(tmp_path, capsys):
    # before: an environment at 3e38 rendered inf pixels with exit 0
    _write_exr(tmp_path / "sky.exr", {c: np.full((8, 16), 3e38) for c in "RGB"})
    p = write_scene(tmp_path, BALL_ON_FLOOR + '\n[[lights]]\ntype = "environment"\nfile = "sky.exr"\n')
    rc, _, err = run_cli(["render", p, "-o", tmp_path / "o.exr", "--no-progress"], capsys)
    assert_clean_failure(rc, err, "sky.exr", "radiance above 1e+20", "row 0, column 0")
    assert not (tmp_path / "o.exr").exists()


def test_finite_exposure_still_scales_the_image(tmp_path, capsys):
    # the checks above refuse only what is not finite: +1 stop doubles every pixel
    from warp_sg.core.image_io import load_image

    p = write_scene(tmp_path)
    assert run_cli(["render", p, "-o", tmp_path / "a.exr", "--no-progress"], capsys)[0] == 0
    assert run_cli(["render", p, "-o", tmp_path / "b.exr", "--no-progress", "--exposure", "1"], capsys)[0] == 0
    np.testing.assert_allclose(load_image(tmp_path / "b.exr"), 2 * load_image(tmp_path / "a.exr"), rtol=1e-6)


# ------------------------------------------------------------------------------------------------
# inside-out meshes (issue 31, defect 5): before, a closed mesh with inverted winding and normals
# rendered about 10× too dark without a word
# ------------------------------------------------------------------------------------------------
def _sphere(path, *, invert=False):
    """An icosphere (radius 0.4 about (0, 0.4, 0)) written as PLY or OBJ; ``invert``: winding and
    normals reversed (inside out)."""
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    m.vertices += [0.0, 0.4, 0.0]
    if invert:
        m.invert()
    path.write_bytes(m.export(file_type="ply", vertex_normal=True) if path.suffix == ".ply"
                     else m.export(file_type="obj", include_normals=False).encode())
    return path


def _render_mesh_scene(tmp_path, capsys, mesh_name):
    from warp_sg.core.image_io import load_image

    p = write_scene(tmp_path, replace(BALL,
                                      f'mesh = "{mesh_name}"'), name=f"{mesh_name}.toml")
    out = tmp_path / f"{mesh_name}.exr"
    rc, _, err = run_cli(["render", p, "-o", out, "--no-progress", "--width", 32, "--height", 24], capsys)
    assert rc == 0, err
    return load_image(out), [ln for ln in err.splitlines() if "warning" in ln]


@pytest.mark.parametrize("name", ["inv.ply", "inv.obj"])
def test_inside_out_closed_mesh_is_flipped_with_one_warning_and_renders_like_the_right_one(tmp_path, capsys, name):
    # the reference is the same sphere written the right way round (before: ~10x darker, no word)
    good, good_warn = _render_mesh_scene(tmp_path, capsys, _sphere(tmp_path / "good.ply").name)
    assert good_warn == []
    img, warn = _render_mesh_scene(tmp_path, capsys, _sphere(tmp_path / name, invert=True).name)
    assert len(warn) == 1 and warn[0].startswith("warp-sg: warning:") and name in warn[0], warn
    assert "inside out" in warn[0]
    np.testing.assert_allclose(img, good, atol=2e-3 * float(good.max()))


def test_closed_mesh_with_inward_normals_gets_them_flipped_with_one_warning():
    import trimesh

    from warp_sg.core.errors import InputWarning
    from warp_sg.scene.geometry import object_mesh
    from warp_sg.scene.model import SceneObject

    m = trimesh.creation.icosphere(subdivisions=2)
    ob = SceneObject(material="a", vertices=m.vertices, triangles=m.faces, normals=-m.vertex_normals, name="ball")
    with pytest.warns(InputWarning, match=r"\(ball\): the closed mesh's normals point inwards") as rec:
        out = object_mesh(ob, 0, None)
    assert len(rec) == 1
    np.testing.assert_allclose(out.normals, m.vertex_normals, atol=1e-6)  # outward: the sphere's own normals
    np.testing.assert_array_equal(out.triangles, m.faces)


def test_signed_volume_and_closedness_match_closed_forms():
    import trimesh

    from warp_sg.core.meshcheck import closed_and_oriented, signed_volume, weld_ids

    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    assert signed_volume(v, f) == pytest.approx(6.0) and signed_volume(v, f[:, ::-1]) == pytest.approx(-6.0)
    assert closed_and_oriented(f, weld_ids(v))
    assert not closed_and_oriented(f[1:], weld_ids(v))  # a hole
    one_flipped = f.copy()
    one_flipped[0] = one_flipped[0, ::-1]
    assert not closed_and_oriented(one_flipped, weld_ids(v))
    # split vertices (a seam exported twice) are welded back by position
    vs = np.concatenate([v, v])
    assert closed_and_oriented(np.concatenate([f[:6], f[6:] + len(v)]), weld_ids(vs))


def test_open_mesh_keeps_its_orientation_without_a_warning():
    import warnings

    from warp_sg.scene.geometry import orient_outward

    v = QUAD_V.astype(np.float32)
    t = QUAD_F[:, ::-1].copy()  # facing -z: an open mesh has no inside, nothing to decide
    n = np.tile([0.0, 0.0, 1.0], (4, 1)).astype(np.float32)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        t2, n2 = orient_outward(v, t, np.ones(2, bool), n, "quad")
    np.testing.assert_array_equal(t2, t)
    np.testing.assert_array_equal(n2, n)


# ------------------------------------------------------------------------------------------------
# messages that blamed the wrong thing or said too little (issue 31, defects 6 and 7)
# ------------------------------------------------------------------------------------------------
def test_view_nan_names_the_view_and_the_nan_not_the_other_angle(tmp_path, capsys):
    mesh = _sphere(tmp_path / "s.ply")
    rc, _, err = run_cli(["render", mesh, "--view", "nan", "20", "-o", tmp_path / "o.png"], capsys)
    msg = assert_clean_failure(rc, err, "--view", "nan")
    assert "20" not in msg and "range" not in msg


def test_view_angles_that_are_not_finite_are_named_by_the_api():
    from warp_sg.scene.importers.asset import frame_camera

    with pytest.raises(InputError, match="azimuth must be a finite"):
        frame_camera([0, 0, 0], [1, 1, 1], view=(float("nan"), 20.0))
    with pytest.raises(InputError, match="elevation must be a finite"):
        frame_camera([0, 0, 0], [1, 1, 1], view=(30.0, float("inf")))


def test_zero_based_obj_face_index_names_the_line_not_zero_area(tmp_path, capsys):
    (tmp_path / "tri0.obj").write_text("# made by hand\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    rc, _, err = run_cli(["render", tmp_path / "tri0.obj", "-o", tmp_path / "o.png"], capsys)
    msg = assert_clean_failure(rc, err, "tri0.obj", "line 5", "index 0", "start at 1")
    assert "zero area" not in msg


def test_draco_asset_is_decoded_or_refused_naming_the_extension():
    # before: trimesh's placeholder zeros gave "every triangle has zero area" on one of its parts
    path = Path(__file__).resolve().parents[2] / "shared" / "assets" / "ferrari.glb"
    if not path.exists():
        pytest.skip("../shared/assets is not here")
    from warp_sg.scene.importers.gltf import load_gltf

    try:
        asset = load_gltf(path, images=False)
    except MeshError as e:
        assert "KHR_draco_mesh_compression" in str(e) and "zero area" not in str(e)
    else:  # a Draco decoder is installed: the triangles are real
        lo, hi = asset.bounds()
        assert np.all(hi - lo > 0)


def test_zero_scale_names_the_file_and_the_object(tmp_path):
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import DirectionalLight
    from warp_sg.scene.model import Scene, SceneObject, Transform

    ob = SceneObject(material="a", vertices=QUAD_V, triangles=QUAD_F, name="blob", transform=Transform(scale=(1, 0, 1)))
    sc = Scene(camera=Camera(width=4, height=4), objects=[ob], materials={"a": ws.brdf.Lambert()},
               lights=[DirectionalLight(direction=(0, 1, 0))])
    with pytest.raises(SceneError, match=r"\[\[objects\]\] #1 \(blob\): transform is singular"):
        sc.geometry()
    p = write_scene(tmp_path, replace('material = "floor"', 'material = "floor"\nscale = [1.0, 1e-40, 1.0]'))
    with pytest.raises(SceneError, match=r"scene.toml: \[\[objects\]\] #2 \(plane\): transform is singular"):
        ws.load_scene(p).geometry()


def test_folder_given_as_scene_or_mesh_is_called_a_folder(tmp_path, capsys):
    (tmp_path / "adir.toml").mkdir()
    rc, _, err = run_cli(["render", tmp_path / "adir.toml", "-o", tmp_path / "o.png"], capsys)
    assert_clean_failure(rc, err, "adir.toml", "is a folder")
    (tmp_path / "meshes").mkdir()
    p = write_scene(tmp_path, replace(BALL, 'mesh = "meshes"'))
    rc, _, err = run_cli(["render", p, "-o", tmp_path / "o.png"], capsys)
    assert_clean_failure(rc, err, "meshes", "is a folder")
    rc, _, err = run_cli(["render", tmp_path / "meshes", "-o", tmp_path / "o.png"], capsys)
    assert_clean_failure(rc, err, "meshes", "is a folder")


def test_unknown_mesh_extension_names_the_format(tmp_path, capsys):
    (tmp_path / "cloud.xyz").write_text("0 0 0\n1 0 0\n0 1 0\n")
    rc, _, err = run_cli(["render", tmp_path / "cloud.xyz", "-o", tmp_path / "o.png"], capsys)
    msg = assert_clean_failure(rc, err, "cloud.xyz", "'.xyz' is not supported", ".obj")
    assert "no triangles" not in msg


@pytest.mark.parametrize("command", ["reference", "report"])
def test_asset_given_to_a_scene_command_says_it_needs_a_scene_file(tmp_path, capsys, command):
    mesh = _sphere(tmp_path / "s.ply")
    extra = ["--spp", "1"] if command == "reference" else ["--quick"]
    rc, _, err = run_cli([command, mesh, "-o", tmp_path / ("o.exr" if command == "reference" else "rep"), *extra], capsys)
    msg = assert_clean_failure(rc, err, "s.ply", "not a scene file", "--print-scene")
    assert "TOML" not in msg and "utf-8" not in msg


def test_scene_file_with_a_utf8_byte_order_mark_loads_as_without_it(tmp_path):
    plain = ws.load_scene(write_scene(tmp_path))
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + BALL_ON_FLOOR.encode())
    sc = ws.load_scene(bom)
    assert sc.camera == plain.camera and list(sc.materials) == list(plain.materials)


# ------------------------------------------------------------------------------------------------
# warnings are ours (issue 31, defect 8): one line, never numpy's or trimesh's multi-line warnings
# ------------------------------------------------------------------------------------------------
def test_black_environment_fits_without_runtime_warnings(tmp_path, capsys, cache_dir):
    from warp_sg.core.image_io import load_image

    _write_exr(tmp_path / "black.exr", {c: np.zeros((16, 32)) for c in "RGB"})
    p = write_scene(tmp_path, BALL_ON_FLOOR + '\n[[lights]]\ntype = "environment"\nfile = "black.exr"\n')
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        from precompute.environment.sg_fit import fit_environment_sgs

        fit = fit_environment_sgs(np.zeros((16, 32, 3), np.float32), 8, cache=False, cosine="exact")
    assert np.all(fit.amplitude == 0) and fit.info["radiance_rel_rms"] == 0.0
    rc, _, err = run_cli(["render", p, "-o", tmp_path / "o.exr", "--no-progress"], capsys)
    assert rc == 0 and "Warning" not in err and "warning" not in err, err
    assert np.all(np.isfinite(load_image(tmp_path / "o.exr")))


def test_huge_coordinates_are_refused_naming_the_vertex_without_a_warning(tmp_path, capsys):
    # before: trimesh's vertex welding cast 1e30 to int64 (a RuntimeWarning) and the image was wrong
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=1)
    m.vertices *= 1e30
    (tmp_path / "big.ply").write_bytes(m.export(file_type="ply"))
    rc, _, err = run_cli(["render", tmp_path / "big.ply", "-o", tmp_path / "o.png"], capsys)
    assert_clean_failure(rc, err, "big.ply", "vertex 0", "beyond ±1e+12")
    assert "Warning" not in err


def test_tiny_object_is_refused_naming_its_size(tmp_path, capsys):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=1)
    m.vertices *= 1e-8
    (tmp_path / "tiny.ply").write_bytes(m.export(file_type="ply"))
    rc, _, err = run_cli(["render", tmp_path / "tiny.ply", "-o", tmp_path / "o.png"], capsys)
    assert_clean_failure(rc, err, "tiny.ply", "across", "at least 1e-05")


def test_cli_prints_a_library_warning_as_one_line(tmp_path, capsys, monkeypatch):
    # any warning that still reaches the CLI (here one raised by numpy's own machinery) is one line
    import warnings

    import warp_sg.tools.cli as cli

    def noisy(args):
        warnings.warn_explicit("Palette images with Transparency expressed in bytes should be converted\nto RGBA",
                               UserWarning, "/x/PIL/Image.py", 7)
        return 0

    monkeypatch.setattr(cli, "schema_main", noisy)
    rc, _, err = run_cli(["schema"], capsys)
    assert rc == 0 and err.strip() == ("warp-sg: warning: PIL: Palette images with Transparency expressed in bytes "
                                       "should be converted (UserWarning)")


def test_numpy_floating_point_notes_are_kept_from_the_user(tmp_path, capsys, monkeypatch):
    # (issue 51) numpy's "overflow encountered in multiply" and friends: the results are checked
    # where they matter; before, each reached the user as an extra line
    import warnings

    import warp_sg.tools.cli as cli

    def noisy(args):
        warnings.warn_explicit("overflow encountered in multiply", RuntimeWarning, "/x/numpy/_core/umath.py", 7)
        warnings.warn_explicit("invalid value encountered in divide", RuntimeWarning, "/x/warp_sg/scene/envmap.py", 9)
        return 0

    monkeypatch.setattr(cli, "schema_main", noisy)
    rc, _, err = run_cli(["schema"], capsys)
    assert rc == 0 and err.strip() == ""


# ------------------------------------------------------------------------------------------------
# energy conservation (issue 31, defect 9): kd > 1 is an error; kd + ks·F(0°) > 1 for the
# normalised models is one warning line (docs/rendering.md, "Energy conservation")
# ------------------------------------------------------------------------------------------------
def test_diffuse_albedo_above_one_is_an_error_naming_kd(tmp_path, capsys):
    p = write_scene(tmp_path, replace("kd = [0.8, 0.8, 0.8]", "kd = [5.0, 5.0, 5.0]"))
    rc, _, err = run_cli(["render", p, "-o", tmp_path / "o.png"], capsys)
    assert_clean_failure(rc, err, "[materials.floor]", "'kd'", "<= 1", "5.0")
    assert not (tmp_path / "o.png").exists()
    with pytest.raises(InputError, match="kd"):
        ws.scene.Material.from_brdf(ws.brdf.Lambert(kd=1.5))


def test_kd_texture_above_one_is_an_error(tmp_path):
    from warp_sg.core.image_io import save_image

    save_image(tmp_path / "albedo.exr", np.full((4, 4, 3), 0.8, np.float32))
    p = write_scene(tmp_path, replace("kd = [0.8, 0.8, 0.8]", 'kd = { texture = "albedo.exr", scale = 2.0 }'))
    with pytest.raises(SceneError, match=r"\[materials.floor\] key 'kd': texture values reach 1.6 > 1"):
        ws.load_scene(p)


def test_normalised_model_reflecting_more_than_it_receives_warns_once(tmp_path, capsys):
    text = replace('model = "cook_torrance"\nkd = [0.0, 0.0, 0.0]\nks = [1.0, 1.0, 1.0]\nm = 0.2\nfresnel = "copper"',
                   'model = "phong"\nkd = [0.8, 0.6, 0.6]\nks = [0.5, 0.5, 0.5]\nn = 30')
    rc, _, err = run_cli(["render", write_scene(tmp_path, text), "-o", tmp_path / "o.png"], capsys)
    warn = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 0 and len(warn) == 1, err
    assert "[materials.copper]" in warn[0] and "kd + ks = [1.3, 1.1, 1.1] > 1" in warn[0]


def test_energy_check_uses_the_fresnel_at_normal_incidence():
    # GGX under Schlick F0 = 0.04 with kd = 0.9, ks = 1: R0 = 0.94 (fine); F0 = 0.2: R0 = 1.1 (warned)
    from warp_sg.brdf.energy import energy_excess, normal_incidence_reflectance

    ok = ws.brdf.make_model("ggx", kd=0.9, ks=1.0, alpha=0.2, fresnel={"schlick": 0.04})
    np.testing.assert_allclose(normal_incidence_reflectance(ok), 0.94)
    assert energy_excess(ok) is None
    hot = ws.brdf.make_model("ggx", kd=0.9, ks=1.0, alpha=0.2, fresnel={"schlick": 0.2})
    assert "kd + ks·F(0°) = [1.1, 1.1, 1.1]" in energy_excess(hot)
    # cook_torrance's ks is no albedo (its D peaks at 1: the gold example has ks = 10)
    assert energy_excess(ws.brdf.make_model("cook_torrance", kd=0.5, ks=10.0, m=0.2)) is None


def test_examples_load_without_warnings():
    import warnings

    root = Path(__file__).resolve().parents[1] / "examples"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for f in sorted(root.glob("*.toml")):
            if not f.name.endswith(("_job.toml", "_views.toml")):  # (batch job files, fit photographs)
                ws.load_scene(f)


# ------------------------------------------------------------------------------------------------
# the watchdog (issue 31): sizes over a step's bound are refused up front, naming the size
# ------------------------------------------------------------------------------------------------
def _png_header(path, w, h):
    """A PNG whose header says ``w × h`` (and whose pixel data is a stub): what a reader sees first."""
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(b"\x00" * 16)) + chunk(b"IEND", b""))
    return path


@pytest.mark.parametrize("w,h", [(40000, 25000), (12000, 12000)])
def test_texture_over_the_texel_bound_is_refused_from_its_header(tmp_path, capsys, w, h):
    # 1e9 texels: over Pillow's own limit too (it raised DecompressionBombError, a traceback);
    # 144 M: within Pillow's but over ours
    _png_header(tmp_path / "big.png", w, h)
    p = write_scene(tmp_path, replace("kd = [0.8, 0.8, 0.8]", 'kd = "big.png"'))
    rc, _, err = run_cli(["render", p, "-o", tmp_path / "o.png"], capsys)
    assert_clean_failure(rc, err, "big.png", f"{w * h:,} texels", "134,217,728")


def test_environment_over_the_texel_bound_is_refused_unread_and_16k_by_8k_is_not(tmp_path):
    from warp_sg.scene.envmap import load_envmap
    from warp_sg.scene.lights import EnvironmentLight

    for w, h, refused in ((65536, 32768, True), (16384, 8192, False)):
        f = tmp_path / f"sky{w}.hdr"
        f.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w) + b"\x02\x02" * 8)
        with pytest.raises(ImageError) as ei:
            load_envmap(f)
        if refused:
            assert f"{w}×{h} texels" in str(ei.value) and "at most 134,217,728" in str(ei.value)
        else:  # past the watchdog: the stub pixels fail to decode
            assert "cannot read Radiance HDR" in str(ei.value)
    with pytest.raises(ImageError, match="32768×16384 texels"):
        EnvironmentLight(procedural="sky", options={"width": 32768, "height": 16384}).base_radiance()


def test_million_triangle_mesh_is_within_the_bound():
    from warp_sg.scene.geometry import object_mesh
    from warp_sg.scene.model import SceneObject

    n = 708  # a 708 × 708 grid: 1,000,000 triangles
    x, y = np.meshgrid(np.arange(n + 1, dtype=np.float32), np.arange(n + 1, dtype=np.float32))
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size, np.float32)], 1) / n
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    t = np.concatenate([np.stack([i, i + 1, i + n + 2], 1), np.stack([i, i + n + 2, i + n + 1], 1)])
    assert len(t) > 1_000_000
    m = object_mesh(SceneObject(material="a", vertices=v, triangles=t, name="grid"), 0, None)
    assert len(m.triangles) == len(t)


def test_scene_over_the_triangle_bound_is_refused_naming_the_count(monkeypatch):
    import warp_sg.scene.geometry as geo
    from warp_sg.scene.model import SceneObject

    monkeypatch.setattr(geo, "MAX_TRIANGLES", 1)  # the bound's check, on a mesh of 2 triangles
    with pytest.raises(MeshError, match="the mesh is too large: 2 triangles; at most 1 triangles"):
        geo.object_mesh(SceneObject(material="a", vertices=QUAD_V, triangles=QUAD_F, name="quad"), 0, None)


@pytest.mark.parametrize("render,camera,words", [
    ("shadows = true\nvisibility_budget = 10000000", "", ["SSDF precompute", "10,000,000 vertices", "32²"]),
    ("shadows = false", "16000 16000", ["the frame", "16000×16000 pixels"]),
    ("shadows = false", "20000 6", ["[camera]", "width 20000", "16384 per axis"]),
    ("shadows = false\ngamma_levels = 64\ngamma_resolution = 1024", "", ["ΓL prefilter", "64 levels", "1024"]),
])
def test_precompute_over_its_bound_is_refused_before_any_work(tmp_path, render, camera, words):
    from warp_sg.renderer.renderer import Renderer

    text = replace("shadows = false", render)
    if camera:
        w, h = camera.split()
        text = text.replace("width = 16\nheight = 12", f"width = {w}\nheight = {h}")
    # a 4096 × 2048 map: fine lobes up to gamma_resolution's faces (a constant map is quick to make)
    text += ('\n[[lights]]\ntype = "environment"\nprocedural = "constant"\n'
             'options = { radiance = 1.0, width = 4096, height = 2048 }\n')
    sc = ws.load_scene(write_scene(tmp_path, text))
    with pytest.raises(SceneError) as ei:
        Renderer(sc)
    for w in words:
        assert w in str(ei.value), str(ei.value)


# ------------------------------------------------------------------------------------------------
# property tests (issue 31): whatever malformed scene, mesh, glTF or map hypothesis makes, the CLI
# answers with exit 2 and one line naming the culprit, or with a finite, non-negative image; never
# a traceback, a hang past a size-proportional limit, or a partial file. Bounded for CI: tiny
# images, no shadows, few examples, derandomized (the same examples every run), no deadline (the
# first render compiles kernels) but a time limit per example from the input's size.
# ------------------------------------------------------------------------------------------------
def property_settings(n):
    """``n`` derandomized examples; ``WARP_SG_PROPERTY_EXAMPLES=N`` runs N random ones instead (a
    deeper search by hand)."""
    import os

    deep = int(os.environ.get("WARP_SG_PROPERTY_EXAMPLES", "0"))
    return settings(max_examples=deep or n, deadline=None, derandomize=not deep, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


class Hang(Exception):
    """An example that did not answer within its time limit."""


@contextlib.contextmanager
def time_limit(seconds):
    def stop(signum, frame):
        raise Hang(f"no answer within {seconds:.0f} s")

    old = signal.signal(signal.SIGALRM, stop)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def assert_answer(argv, folder, out, needles, capsys, limit):
    """Run ``warp-sg argv`` under ``limit`` seconds and judge the answer (section docstring)."""
    from warp_sg.core.image_io import load_image

    before = set(folder.iterdir())
    with time_limit(limit):
        rc, _, err = run_cli(argv, capsys)
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if rc == 2:
        msg = lines[-1]
        assert "error:" in msg and len(msg) < 500, err
        assert any(n.lower() in msg.lower() for n in needles), f"{msg!r} names none of {needles}"
        assert not out.exists() and set(folder.iterdir()) == before, "a failed run left a file"
        assert all(ln.startswith("warp-sg: warning:") for ln in lines[:-1]) or "usage:" in err, err
        return msg
    assert rc == 0, err
    assert all(ln.startswith("warp-sg: warning:") for ln in lines), err  # one line each, ours
    assert set(folder.iterdir()) == before | {out}, "temporary files left behind"
    img = load_image(out)
    assert np.all(np.isfinite(img)) and img.min() >= -1e-6 * max(1.0, float(img.max())), (img.min(), img.max())
    return None


def _toml(v) -> str:
    """A TOML literal of ``v`` (non-finite floats included: ``nan``, ``inf``)."""
    import json

    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml(x)}" for k, x in v.items()) + " }"
    return "[" + ", ".join(_toml(x) for x in v) + "]"


BASE_DOC = tomllib.loads(BALL_ON_FLOOR)  # (the shared scene, tests/conftest.py)


def doc_text(doc) -> str:
    out = []

    def table(head, d):
        out.append(f"\n{head}\n" + "".join(f"{k} = {_toml(v)}\n" for k, v in d.items()))

    table("[camera]", doc["camera"])
    for ob in doc["objects"]:
        table("[[objects]]", ob)
    for name, m in doc["materials"].items():
        table(f"[materials.{name}]", m)
    for li in doc["lights"]:
        table("[[lights]]", li)
    table("[render]", doc["render"])
    return "".join(out)


#: (section, entry, key, the table's name in messages) a mutation may hit
TOML_KEYS = [("camera", None, k, "[camera]") for k in ("origin", "target", "up", "fov", "width", "height", "near", "far")] + \
    [("objects", 0, k, "[[objects]] #1") for k in ("center", "radius", "resolution", "scale", "translate", "rotate",
                                                    "material", "primitive")] + \
    [("objects", 1, k, "[[objects]] #2") for k in ("size", "resolution", "center")] + \
    [("materials", "copper", k, "[materials.copper]") for k in ("kd", "ks", "m", "fresnel")] + \
    [("materials", "floor", "kd", "[materials.floor]")] + \
    [("lights", 0, k, "[[lights]] #1") for k in ("position", "radius", "intensity", "type")] + \
    [("render", None, k, "[render]") for k in ("supersampling", "antialias", "lobes", "shadows", "fh", "background",
                                               "visibility_sampling", "ssdf_resolution")]

_SCALARS = st.one_of(st.integers(-3, 3), st.integers(-2**62, 2**62), st.floats(allow_nan=True, allow_infinity=True),
                     st.floats(-10, 10), st.text(alphabet="abc.-_ 0", max_size=5), st.booleans())
TOML_VALUES = st.one_of(_SCALARS, st.lists(_SCALARS, max_size=4), st.lists(st.floats(-5, 5), min_size=3, max_size=3),
                        st.dictionaries(st.sampled_from(["texture", "scale", "a"]), _SCALARS, max_size=2),
                        st.just("__delete__"))


@property_settings(40)
@given(mutations=st.lists(st.tuples(st.sampled_from(TOML_KEYS), TOML_VALUES), min_size=1, max_size=2))
def test_property_malformed_toml_values_get_exit_2_naming_the_key_or_a_finite_image(capsys, cache_dir, mutations):
    import copy

    doc = copy.deepcopy(BASE_DOC)
    needles = []
    for (section, entry, key, label), value in mutations:
        table = doc[section] if entry is None else doc[section][entry]
        if value == "__delete__":
            table.pop(key, None)
        else:
            table[key] = value
        needles += [key, label]
    folder = Path(tempfile.mkdtemp())
    scene = folder / "scene.toml"
    scene.write_text(doc_text(doc))
    out = folder / "out.exr"
    assert_answer(["render", scene, "-o", out, "--no-progress"], folder, out, needles + ["scene.toml"], capsys,
                  limit=120)


@st.composite
def raw_meshes(draw):
    """(vertices, faces) with NaN / infinite / huge coordinates, degenerate, out-of-range and
    reversed faces now and then."""
    n = draw(st.integers(3, 9))
    coord = st.one_of(st.floats(-2, 2), st.sampled_from([0.0, 1.0, math.nan, math.inf, -1e30, 1e-9]))
    sane = draw(st.booleans())
    c = st.floats(-2, 2) if sane else coord
    v = draw(st.lists(st.tuples(c, c, c), min_size=n, max_size=n))
    idx = st.integers(0, n - 1) if sane else st.integers(-2, n + 1)
    f = draw(st.lists(st.tuples(idx, idx, idx), min_size=1, max_size=10))
    if draw(st.booleans()):
        f = [t[::-1] for t in f]
    return np.array(v, float), np.array(f, int)


def write_mesh(path, v, f):
    """OBJ (1-based indices, as written) or ASCII PLY of raw arrays, whatever they hold."""
    if path.suffix == ".obj":
        lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    else:
        lines = ["ply", "format ascii 1.0", f"element vertex {len(v)}", "property float x", "property float y",
                 "property float z", f"element face {len(f)}", "property list uchar int vertex_indices",
                 "end_header"] + [f"{x!r} {y!r} {z!r}" for x, y, z in v] + [f"3 {a} {b} {c}" for a, b, c in f]
    path.write_text("\n".join(lines) + "\n")


@property_settings(14)
@given(mesh=raw_meshes(), suffix=st.sampled_from([".obj", ".ply"]))
def test_property_broken_meshes_get_exit_2_naming_the_file_or_a_finite_image(capsys, cache_dir, mesh, suffix):
    folder = Path(tempfile.mkdtemp())
    path = folder / f"mesh{suffix}"
    write_mesh(path, *mesh)
    out = folder / "out.exr"
    argv = ["render", path, "-o", out, "--width", 8, "--height", 6, "--no-shadows", "--no-progress"]
    assert_answer(argv, folder, out, [path.name], capsys, limit=120 + 0.01 * mesh[1].size)


#: places in a glTF's JSON that hold references, counts and transforms
GLTF_FIELDS = [("meshes", 0, "primitives", 0, "indices"), ("meshes", 0, "primitives", 0, "attributes", "POSITION"),
               ("meshes", 0, "primitives", 0, "material"), ("meshes", 0, "primitives", 0, "mode"),
               ("nodes", 0, "mesh"), ("nodes", 0, "children"), ("nodes", 0, "matrix"), ("nodes", 0, "scale"),
               ("scenes", 0, "nodes"), ("scene",), ("accessors", 0, "bufferView"), ("accessors", 0, "count"),
               ("accessors", 0, "componentType"), ("accessors", 1, "type"), ("accessors", 1, "byteOffset"),
               ("bufferViews", 0, "buffer"), ("bufferViews", 0, "byteLength"), ("bufferViews", 1, "byteOffset"),
               ("buffers", 0, "uri"), ("buffers", 1, "byteLength"), ("materials",), ("textures",)]
GLTF_VALUES = st.one_of(st.integers(-3, 12), st.just("__delete__"), st.text(alphabet="ab0", max_size=3),
                        st.lists(st.integers(-2, 4), max_size=3), st.floats(allow_nan=True, allow_infinity=True),
                        st.lists(st.floats(-2, 2), min_size=16, max_size=16), st.just([{"children": [0]}]))


def _set(h, path, value):
    d = h
    for p in path[:-1]:
        if isinstance(d, list):
            if not (isinstance(p, int) and p < len(d)):
                return
        elif p not in d:
            d[p] = {} if not isinstance(p, int) else []
        d = d[p]
        if not isinstance(d, (dict, list)):
            return
    if isinstance(d, dict):
        if value == "__delete__":
            d.pop(path[-1], None)
        else:
            d[path[-1]] = value


@property_settings(16)
@given(edits=st.lists(st.tuples(st.sampled_from(GLTF_FIELDS), GLTF_VALUES), min_size=1, max_size=3))
def test_property_gltf_with_dangling_references_gets_exit_2_naming_the_file_or_a_finite_image(capsys, cache_dir,
                                                                                               edits):
    folder = Path(tempfile.mkdtemp())

    def edit(h):
        for path, value in edits:
            _set(h, path, value)

    path = write_gltf(folder, edit=edit)
    out = folder / "out.exr"
    argv = ["render", path, "-o", out, "--width", 8, "--height", 6, "--no-shadows", "--no-progress"]
    assert_answer(argv, folder, out, [path.name], capsys, limit=120)


@st.composite
def odd_maps(draw):
    """An (H, W, 3) map of an odd size, mostly one value with a few special texels."""
    h, w = draw(st.integers(1, 20)), draw(st.integers(1, 48))
    base = draw(st.sampled_from([0.0, 1e-30, 0.5, 3.0, 1e6]))
    a = np.full((h, w, 3), base, np.float32)
    for r, c, ch, val in draw(st.lists(st.tuples(st.integers(0, h - 1), st.integers(0, w - 1), st.integers(0, 2),
                                                 st.sampled_from([math.nan, math.inf, -1.0, 1e25, 0.0, 50.0])),
                                       max_size=3)):
        a[r, c, ch] = val
    return a


@property_settings(14)
@given(env=odd_maps(), use=st.sampled_from(["environment", "texture"]))
def test_property_odd_maps_get_exit_2_naming_the_file_or_a_finite_image(capsys, cache_dir, env, use):
    import copy

    folder = Path(tempfile.mkdtemp())
    _write_exr(folder / "map.exr", {c: env[..., i] for i, c in enumerate("RGB")})
    doc = copy.deepcopy(BASE_DOC)
    doc["materials"]["copper"] = {"model": "lambert", "kd": [0.5, 0.5, 0.5]}  # diffuse only: no ΓL prefilter
    if use == "environment":
        doc["lights"].append({"type": "environment", "file": "map.exr"})
    else:
        doc["materials"]["floor"]["kd"] = "map.exr"
    scene = folder / "scene.toml"
    scene.write_text(doc_text(doc))
    out = folder / "out.exr"
    assert_answer(["render", scene, "-o", out, "--no-progress"], folder, out, ["map.exr", "[materials.floor]"], capsys,
                  limit=120 + 1e-3 * env.size)


@pytest.mark.parametrize("old,new,words", [
    ("intensity = [20.0, 20.0, 20.0]", "intensity = [20.0, 1e300, 20.0]", ["[[lights]] #1", "intensity", "<= 1e+20"]),
    ('type = "point"\nposition = [2.0, 3.0, 2.0]\nradius = 0.1\nintensity = [20.0, 20.0, 20.0]',
     'type = "environment"\nprocedural = "sky"\nscale = 1e30', ["[[lights]] #1", "scale", "<= 1e+20"]),
    ("ks = [1.0, 1.0, 1.0]", "ks = [1.0, 1e300, 1.0]", ["[materials.copper]", "'ks'", "±1e+20"]),
])
def test_light_or_material_value_that_overflows_float32_is_refused_naming_it(tmp_path, capsys, old, new, words):
    # before: a finite 1e300 became inf in float32 and the image was inf (or, now, refused unnamed)
    rc, _, err = run_cli(["render", write_scene(tmp_path, replace(old, new)), "-o", tmp_path / "o.exr"], capsys)
    assert_clean_failure(rc, err, *words)
    assert not (tmp_path / "o.exr").exists()


def test_closed_room_around_the_camera_keeps_its_inward_faces(tmp_path):
    # a room seen from inside faces inwards by design: no flip, no warning (winding number of the eye: 1)
    import warnings

    import trimesh

    from warp_sg.core.meshcheck import winding_number
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import PointLight
    from warp_sg.scene.model import Scene, SceneObject

    room = trimesh.creation.box(extents=(4.0, 4.0, 4.0))
    room.invert()
    assert winding_number(room.vertices, room.faces, [0, 0, 0]) == pytest.approx(-1.0)
    assert winding_number(room.vertices, room.faces, [5, 0, 0]) == pytest.approx(0.0, abs=1e-9)
    sc = Scene(camera=Camera(origin=(0.0, 0.0, 1.0), target=(0.0, 0.0, -1.0), width=4, height=4),
               objects=[SceneObject(material="a", vertices=room.vertices, triangles=room.faces, name="room")],
               materials={"a": ws.brdf.Lambert()}, lights=[PointLight(position=(0, 1, 0), radius=0.1)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        g = sc.geometry()
    np.testing.assert_array_equal(g.triangles, room.faces)
