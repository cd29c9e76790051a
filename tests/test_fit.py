"""``warp-sg fit`` / ``ws.fit`` (``warp_sg.inverse``): parameters recovered from photographs.

The photographs are frames of the same scene with known parameters, rendered by the plain
renderer (its map environment, adaptive antialiasing): a ball whose base colour is a texture and
whose roughness is a number, a Lambert floor of known albedo (it fixes the scale that an unknown
environment and an unknown albedo otherwise share), a sky the fit's SG basis can hold (a map of
16 lobes) and a directional light.
The fit (L-BFGS-B) starts from a grey texture, α = 0.5 and a constant environment and recovers
α and the texels the views see; the fitted scene renders with ``warp-sg render`` as it is, close to the
photographs. A fit stopped at its checkpoint and started again ends where an uninterrupted one
does. Bad input is one line and exit status 2, before any work and with no output.
"""
from __future__ import annotations

import numpy as np
import pytest

import warp_sg as ws
from warp_sg.core.errors import InputError
from warp_sg.inverse.env_basis import basis_axes, basis_map, basis_sharpness
from warp_sg.tools import cli

ALPHA = 0.25
KD_TEX = np.clip(0.25 + 0.5 * np.random.default_rng(3).random((8, 8, 3)), 0, 1).astype(np.float32)
VIEWS = [(0.0, 1.3, 3.0), (2.4, 1.3, 1.8), (-2.4, 1.3, 1.8), (0.0, 2.6, 1.8)]
SIZE = 56


def _scene_text(kd_tex: str, alpha: float, sky: bool) -> str:
    env = ('file = "sky.exr"' if sky else 'procedural = "constant"\noptions = { radiance = [1.0, 1.0, 1.0] }')
    return f"""
[camera]
origin = [0.0, 1.3, 3.0]
target = [0.0, 0.4, 0.0]
fov = 32.0
width = {SIZE}
height = {SIZE}

[[objects]]
primitive = "sphere"
center = [0.0, 0.45, 0.0]
radius = 0.45
resolution = [16, 32]
material = "ball"

[[objects]]
primitive = "plane"
size = [4.0, 4.0]
resolution = [6, 6]
material = "floor"

[materials.ball]
model = "ggx"
kd = {{ texture = "{kd_tex}" }}
ks = [1.0, 1.0, 1.0]
alpha = {alpha}
fresnel = {{ schlick = 0.3 }}
normal_map = "flat.exr"

[materials.floor]
model = "lambert"
kd = [0.5, 0.5, 0.5]

[[lights]]
type = "environment"
{env}

[[lights]]
type = "directional"
direction = [-0.5, 1.0, 0.4]
intensity = [4.0, 4.0, 4.0]
radius = 0.05

[render]
shadows = true
ssdf_resolution = 16
pca_terms = 8
visibility_budget = 0
env_peaks = 0
bounces = 0  # the fit differentiates the direct light (no bounces in its frames): the photographs too
"""


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    """The folder: the true scene, the photographs and their views file, the start scene."""
    d = tmp_path_factory.mktemp("fit")
    ws.save_image(d / "flat.exr", np.broadcast_to(np.array([0.5, 0.5, 1.0], np.float32), (4, 4, 3)).copy())
    ws.save_image(d / "kd_true.exr", KD_TEX)
    # the true sky: one the fit's 16-lobe basis holds (a bright lobe above, a dim blue sky around)
    axes = basis_axes(16)
    mu = np.where((axes[:, 1] > 0.5)[:, None], [2.0, 1.8, 1.5], [0.15, 0.2, 0.3])
    ws.save_image(d / "sky.exr", basis_map(axes, basis_sharpness(16), mu))
    ws.save_image(d / "kd_start.exr", np.full((8, 8, 3), 0.5, np.float32))
    (d / "true.toml").write_text(_scene_text("kd_true.exr", ALPHA, sky=True))
    (d / "start.toml").write_text(_scene_text("kd_start.exr", 0.5, sky=False))
    r = ws.Renderer(ws.load_scene(d / "true.toml"), device="cpu")
    lines = []
    for i, o in enumerate(VIEWS):
        r.set_camera(origin=o)
        ws.save_image(d / f"v{i}.exr", r.render())
        lines.append(f'[[views]]\norigin = {list(o)}\ntarget = [0.0, 0.4, 0.0]\nfov = 32.0\nwidth = {SIZE}\n'
                     f'height = {SIZE}\nimage = "v{i}.exr"\n')
    (d / "views.toml").write_text("\n".join(lines))
    return d


FREE = ["materials.ball.kd", "materials.ball.alpha", "lights.0"]


@pytest.fixture(scope="module")
def fitted(problem):
    return ws.fit(problem / "start.toml", problem / "views.toml", FREE, problem / "out" / "fitted.toml",
                  iterations=50, env_lobes=16, progress=False)


def test_fit_recovers_the_roughness_the_texture_and_the_light(problem, fitted):
    assert fitted.losses[-1] < fitted.losses[0] / 50.0
    assert abs(float(fitted.values["materials.ball.alpha"]) - ALPHA) < 0.04
    # the texels the views see (the nearest texel of each pixel of the ball, four pixels at least)
    seen = _seen_texels(problem) >= 4
    kd, true = fitted.values["materials.ball.kd"][seen], KD_TEX[seen]
    assert seen.sum() >= 16
    assert np.abs(kd.mean(axis=0) - true.mean(axis=0)).max() < 0.04
    assert np.corrcoef(kd.ravel(), true.ravel())[0, 1] > 0.6


def _seen_texels(problem) -> np.ndarray:
    """(8, 8) how many pixels of the views see each texel of the ball's texture (nearest texel)."""
    r = ws.Renderer(ws.load_scene(problem / "true.toml"), device="cpu")
    g = r.geometry
    ball = g.material_names.index("ball")
    count = np.zeros((8, 8), int)
    for o in VIEWS:
        r.set_camera(origin=o)
        vb = r.rasterize(1)
        tri, bary = vb.tri_id.numpy().ravel(), vb.bary.numpy().reshape(-1, 2)
        keep = tri >= 0
        keep[keep] = g.tri_material[tri[keep]] == ball
        t, b = g.triangles[tri[keep]], bary[keep]
        uv = g.uvs[t[:, 0]] * (1 - b[:, :1] - b[:, 1:]) + g.uvs[t[:, 1]] * b[:, :1] + g.uvs[t[:, 2]] * b[:, 1:]
        x = np.floor(uv[:, 0] * 8).astype(int) % 8
        y = np.floor((1.0 - uv[:, 1]) * 8).astype(int) % 8
        np.add.at(count, (y, x), 1)
    return count


def test_the_fitted_scene_renders_with_warp_sg_render_close_to_the_photographs(problem, fitted):
    out = fitted.scene
    text = out.read_text()
    assert "fitted_env.exr" in text and "fitted_ball_kd.exr" in text
    assert (out.parent / "fitted_loss.png").stat().st_size > 0
    assert cli.main(["render", str(out), "-o", str(out.parent / "render.exr")]) == 0
    img = ws.load_image(out.parent / "render.exr")
    photo = ws.load_image(problem / "v0.exr")
    r = ws.Renderer(ws.load_scene(out), device="cpu")
    tri = r.rasterize(1).tri_id.numpy()
    m = tri >= 0
    rel = np.sqrt(np.mean((img[m] - photo[m]) ** 2)) / np.sqrt(np.mean(photo[m] ** 2))
    assert rel < 0.1


def test_a_fit_stopped_at_its_checkpoint_ends_where_an_uninterrupted_fit_does(problem):
    kw = dict(env_lobes=16, progress=False, checkpoint_every=5, optimizer="adam")  # (Adam's state is checkpointed)
    a = ws.fit(problem / "start.toml", problem / "views.toml", FREE, problem / "a" / "f.toml", iterations=10, **kw)
    ws.fit(problem / "start.toml", problem / "views.toml", FREE, problem / "b" / "f.toml", iterations=5, **kw)
    b = ws.fit(problem / "start.toml", problem / "views.toml", FREE, problem / "b" / "f.toml", iterations=10, **kw)
    assert a.started_at == 0 and b.started_at == 5
    for k in a.values:
        np.testing.assert_allclose(a.values[k], b.values[k], rtol=1e-6, err_msg=k)
    np.testing.assert_allclose(a.losses, b.losses, rtol=1e-6)


def _run(args, capsys):
    rc = cli.main(args)
    return rc, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("case,message", [
    ("size", f"is {SIZE}x{SIZE} pixels, its camera 32x{SIZE}"),
    ("key", "has no parameter 'kdd'"),
    ("nan", "not a finite radiance"),
    ("light", "the scene has 2 [[lights]] tables"),
])
def test_bad_input_is_one_line_and_exit_status_2_with_no_output(problem, tmp_path, capsys, case, message):
    views = (problem / "views.toml").read_text().replace('image = "v', f'image = "{problem}/v')
    free = ["materials.ball.kdd"] if case == "key" else ["lights.5"] if case == "light" else ["materials.ball.alpha"]
    if case == "size":
        views = views.replace(f"width = {SIZE}", "width = 32", 1)
    if case == "nan":
        img = ws.load_image(problem / "v0.exr")
        img[3, 5, 1] = np.nan
        ws.save_image(tmp_path / "nan.exr", img)
        views = views.replace(f'"{problem}/v0.exr"', f'"{tmp_path}/nan.exr"')
    (tmp_path / "views.toml").write_text(views)
    args = ["fit", str(problem / "start.toml"), str(tmp_path / "views.toml"), "-o", str(tmp_path / "o" / "f.toml")]
    for f in free:
        args += ["--free", f]
    rc, err = _run(args, capsys)
    assert rc == 2 and len(err) == 1 and message in err[0], err
    assert not (tmp_path / "o" / "f.toml").exists()


def test_fit_refuses_an_output_that_is_not_a_scene_file(problem, tmp_path):
    with pytest.raises(InputError, match="toml"):
        ws.fit(problem / "start.toml", problem / "views.toml", ["materials.ball.alpha"], tmp_path / "f.exr")
