"""The interactive viewer (``warp-sg preview``), headless: an off-screen plotter whose widgets and
mouse/keyboard events are driven programmatically through VTK's own event machinery.

References are independent of the viewer: a second ``Renderer`` built from the scene file with
the pose / the material change / the shadows setting given directly, the geometric shadow of the
sphere (projection of its centre from the light onto the floor), and Blinn-Phong's half-maximum
angle θ½ = acos(2^(-1/n)) of the highlight. One shared viewer (module scope) keeps the cost low.
"""
from __future__ import annotations

import numpy as np
import pytest

import warp_sg as ws
from warp_sg.core.image_io import read_exr, tonemap_srgb

SIZE = 96
SCENE = f"""
[camera]
origin = [0.0, 2.2, 3.0]
target = [0.0, 0.3, 0.0]
fov = 40.0
width = {SIZE}
height = {SIZE}

[[objects]]
primitive = "sphere"
center = [0.0, 0.5, 0.0]
radius = 0.4
resolution = [16, 32]
material = "shiny"

[[objects]]
primitive = "plane"
size = [4.0, 4.0]
resolution = [24, 24]
material = "floor"

[materials.shiny]
model = "blinn_phong"
kd = [0.1, 0.1, 0.3]
ks = [0.6, 0.6, 0.6]
n = 20.0

[materials.floor]
model = "lambert"
kd = [0.7, 0.7, 0.7]

[[lights]]
type = "point"
position = [0.8, 2.0, 0.6]
radius = 0.05
intensity = [4.0, 4.0, 4.0]

[render]
shadows = true
ssdf_resolution = 12
pca_terms = 8
visibility_budget = 3000
"""
_COUNTS = [{}]  # the fixture's precompute call counter
SPHERE_C, SPHERE_R = np.array([0.0, 0.5, 0.0]), 0.4
PRECOMPUTE = [("precompute", "ssdf_for_mesh"), ("precompute", "prefilter_environment"),
              ("precompute.visibility.refine", "refine_cached"), ("precompute.environment.sg_fit", "fit_environment_sgs"),
              ("precompute.environment.peaks", "extract_peaks")]


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """(viewer, scene path, precompute call counter); the counter spies on every precompute entry
    point from the moment the viewer is built."""
    import importlib

    from warp_sg.tools.preview import open_viewer

    folder = tmp_path_factory.mktemp("viewer")
    path = folder / "scene.toml"
    path.write_text(SCENE)
    v = open_viewer(ws.load_scene(path), off_screen=True, progress=False, screenshot_dir=folder)
    v.plotter.iren.interactor.Initialize()  # so that it delivers events off-screen
    calls = {}
    _COUNTS[0] = calls
    mp = pytest.MonkeyPatch()
    for mod, name in PRECOMPUTE:
        m = importlib.import_module(mod)
        orig = getattr(m, name)

        def spy(*a, _orig=orig, _name=name, **k):
            calls[_name] = calls.get(_name, 0) + 1
            return _orig(*a, **k)

        mp.setattr(m, name, spy)
    v.ssdf0 = v.renderer.ssdf
    v.precompute_s = v.renderer.timings["precompute"]
    yield v, path, calls
    mp.undo()
    v.close()


def _no_precompute(v, calls):
    assert calls == {}, f"precompute ran during an interaction: {calls}"
    assert v.renderer.ssdf is v.ssdf0 and v.renderer.timings["precompute"] == v.precompute_s


def _reference(path, pose=None, shadows=True, **materials):
    """A fresh renderer of the scene file (pose: origin, target, up, fov). Its own precompute is
    not counted as the viewer's."""
    from warp_sg.renderer.renderer import Renderer

    calls = _COUNTS[0]
    before = dict(calls)
    try:
        return _fresh_renderer(Renderer, path, pose, shadows, materials)
    finally:
        calls.clear()
        calls.update(before)


def _fresh_renderer(Renderer, path, pose, shadows, materials):

    sc = ws.load_scene(path)
    sc.render.shadows = shadows
    if pose is not None:
        o, t, u, f = pose
        sc.camera = ws.scene.Camera(origin=o, target=t, up=u, fov=f, width=SIZE, height=SIZE)
    r = Renderer(sc)
    for name, params in materials.items():
        r.set_material(name, **params)
    return r


def _material_mask(r, name):
    vb = r.rasterize(1)
    tid = vb.tri_id.numpy()
    mi = r.geometry.material_names.index(name)
    return (tid >= 0) & (r.geometry.tri_material[np.maximum(tid, 0)] == mi)


def _silhouette_pixels(r):
    """Pixels with a 4-neighbour that sees another material or the background (1× buffer)."""
    tid = r.rasterize(1).tri_id.numpy()
    m = np.where(tid >= 0, r.geometry.tri_material[np.maximum(tid, 0)], -1)
    p = np.pad(m, 1, mode="edge")
    return ((p[1:-1, :-2] != m) | (p[1:-1, 2:] != m) | (p[:-2, 1:-1] != m) | (p[2:, 1:-1] != m))


def _drag(widget, set_value):
    """What a mouse drag does to a VTK widget: Start, move (value changes), End."""
    widget.InvokeEvent("StartInteractionEvent")
    set_value()
    widget.InvokeEvent("InteractionEvent")
    widget.InvokeEvent("EndInteractionEvent")


def _checkbox(v, name, state):
    w = v.editor.checkboxes[name]
    w.GetRepresentation().SetState(int(state))
    w.InvokeEvent("StateChangedEvent")


# Events go through VTK's interactor (initialised off-screen by the fixture) to its observers:
# the interactor style, the widgets, pyvista's key and click handlers and the viewer's.
def _key(v, key):
    it = v.plotter.iren.interactor
    it.SetKeySym(key)
    it.SetKeyCode(key)
    it.KeyPressEvent()
    it.CharEvent()


def _mouse(v, event, x, y):
    it = v.plotter.iren.interactor
    it.SetEventPosition(int(x), int(y))
    getattr(it, event)()


def _click(v, x, y):
    _mouse(v, "LeftButtonPressEvent", x, y)
    _mouse(v, "LeftButtonReleaseEvent", x, y)


def test_frame_is_the_renderers_image_of_the_pyvista_camera_pose_and_orbiting_renders_coarse_then_full(setup):
    v, path, calls = setup
    vp = v.viewport
    pose = ((1.4, 1.2, 2.4), (0.1, 0.4, 0.0), (0.0, 1.0, 0.0), 33.0)
    assert not np.allclose(pose[0], ws.load_scene(path).camera.origin)
    vp.set_pose(*pose[:3], fov=pose[3])
    vp.draw()
    ref = _reference(path, pose).render()
    np.testing.assert_allclose(v.image, ref, rtol=1e-5, atol=1e-6)
    # what is on the texture: the tone-mapped frame, bottom row first
    shown = np.asarray(vp._vimg.point_data["rgb"]).reshape(SIZE, SIZE, 3)[::-1]
    expect = (tonemap_srgb(ref) * 255 + 0.5).astype(np.uint8)
    assert np.abs(shown.astype(int) - expect).max() <= 1
    # a mouse drag: coarse frames while dragging, the full frame after the release
    vp.budget_s = 1e-9  # coarse frames whatever this machine's speed (the divisor adapts to it)
    _mouse(v, "LeftButtonPressEvent", 48, 48)
    _mouse(v, "MouseMoveEvent", 60, 50)  # the style orbits and renders: StartEvent -> a coarse frame
    assert vp.interacting and vp.last["coarse"] == 8 and vp.last["width"] == SIZE // 8
    # the button held still: the rest timer (delivered by the interactor to its style) brings the
    # full frame of the same pose — the style must not repeat the last mouse delta on it
    vp.rest_ms = 0
    pose_before, frames = vp.pose(), vp.frames
    v.plotter.iren.interactor.InvokeEvent("TimerEvent")
    assert vp.pose() == pose_before and vp.interacting
    assert vp.frames == frames + 1 and vp.last["coarse"] == 1 and vp.last["width"] == SIZE
    _mouse(v, "LeftButtonReleaseEvent", 60, 50)
    assert not vp.interacting and vp.last["coarse"] == 1 and vp.frames == frames + 1  # already full
    vp.rest_ms = 200
    vp.budget_s = 0.05
    o, t, u, f, _, _ = vp.pose()
    assert not np.allclose(o, pose[0])  # the drag orbited the camera
    np.testing.assert_allclose(v.image, _reference(path, (o, t, u, f)).render(), rtol=1e-5, atol=1e-6)
    # 'r' goes back to the scene camera
    _key(v, "r")
    sc = ws.load_scene(path)
    np.testing.assert_allclose(vp.pose()[0], sc.camera.origin, atol=1e-9)
    np.testing.assert_allclose(v.image, _reference(path).render(), rtol=1e-5, atol=1e-6)
    _no_precompute(v, calls)


def _highlight_area(img, mask):
    """Pixels of ``mask`` above half of the largest luminance there (specular-only image)."""
    lum = img.mean(2)[mask]
    return int(np.count_nonzero(lum > 0.5 * lum.max()))


def test_clicking_the_sphere_selects_its_material_and_the_roughness_slider_narrows_the_highlight(setup):
    v, path, calls = setup
    vp, ed = v.viewport, v.editor
    vp.reset_view()
    r = v.renderer
    sphere = _material_mask(r, "shiny")
    floor = _material_mask(r, "floor")
    assert floor[SIZE - 5, SIZE // 2] and not sphere[SIZE - 5, SIZE // 2]
    _click(v, SIZE // 2, 4)  # display y points up: the bottom row's floor (the widgets are at the sides)
    assert ed.material == "floor" and "material.n" not in ed.sliders
    cy, cx = (int(round(c)) for c in np.argwhere(sphere).mean(0))
    _click(v, cx, SIZE - 1 - cy)
    assert ed.material == "shiny" and "material.n" in ed.sliders
    _checkbox(v, "diffuse", False)  # the highlight alone
    areas = {}
    for n in (20.0, 200.0):
        _drag(ed.sliders["material.n"], lambda n=n: ed.sliders["material.n"].GetRepresentation().SetValue(n))
        assert vp.last["coarse"] == 1
        areas[n] = _highlight_area(v.image, sphere)
    assert v.renderer.scene.materials["shiny"].params["n"] == 200.0
    # Blinn-Phong: cos^n θh = 1/2 at θh ≈ sqrt(2 ln 2 / n), so the half-max area scales as 1/n:
    # 10x from n = 20 to 200; the pixel grid and the curved surface leave at least 3x
    assert areas[200.0] >= 1 and areas[20.0] > 3 * areas[200.0], areas
    # diffuse off = every kd zeroed, rendered by a fresh renderer
    ref = _reference(path, shiny={"n": 200.0, "kd": [0.0, 0.0, 0.0]}, floor={"kd": [0.0, 0.0, 0.0]}).render()
    np.testing.assert_allclose(v.image, ref, rtol=1e-5, atol=1e-6)
    _checkbox(v, "diffuse", True)
    _checkbox(v, "specular", False)
    ref = _reference(path, shiny={"n": 200.0, "ks": [0.0, 0.0, 0.0]}).render()
    np.testing.assert_allclose(v.image, ref, rtol=1e-5, atol=1e-6)
    _checkbox(v, "specular", True)
    _drag(ed.sliders["material.n"], lambda: ed.sliders["material.n"].GetRepresentation().SetValue(20.0))
    assert ed.latency and all(e["seconds"] > 0 for e in ed.latency)
    _no_precompute(v, calls)


def _geometric_shadow(cam, light):
    """Pixels whose floor point (y = 0) cannot see the light's centre past the sphere (ray cast)."""
    d = np.asarray(cam.ray_directions(), np.float64).reshape(cam.height, cam.width, 3)
    o = np.asarray(cam.origin, np.float64)
    p = o + d * (-o[1] / np.where(d[..., 1] < 0, d[..., 1], -1e-30))[..., None]
    seg = np.asarray(light, np.float64) - p
    t = np.clip(np.sum((SPHERE_C - p) * seg, -1) / np.sum(seg * seg, -1), 0.0, 1.0)
    return np.linalg.norm(p + seg * t[..., None] - SPHERE_C, axis=-1) < SPHERE_R


def test_moving_the_light_handle_moves_the_shadow_and_the_shadows_toggle_removes_it(setup):
    v, path, calls = setup
    vp, ed = v.viewport, v.editor
    vp.reset_view()
    r = v.renderer
    floor = _material_mask(r, "floor") & ~_material_mask(r, "shiny")
    cam = r.scene.camera
    noshadow = _reference(path, shadows=False)
    masks = []
    for light in ((0.8, 2.0, -0.8), (-0.8, 2.0, -0.8)):  # shadows in front of the sphere
        _drag(ed.spheres[0], lambda light=light: ed.spheres[0].SetCenter(*light))
        np.testing.assert_allclose(r.scene.local_lights[0].position, light)
        lit = v.image.copy()
        _checkbox(v, "shadows", False)
        noshadow.update_light(0, position=light)
        unshadowed = noshadow.render()
        # = the file with shadows off, which skips the visibility refinement of the mesh: the
        # normals interpolated over other triangles differ by ~1e-4; at the silhouettes the
        # antialiasing shades once per triangle a pixel's sub-pixels see (warp_sg.renderer.antialias), so
        # there the two tessellations differ by up to a few percent
        sil = _silhouette_pixels(r)
        np.testing.assert_allclose(v.image[~sil], unshadowed[~sil], rtol=2e-3, atol=1e-4)
        np.testing.assert_allclose(v.image[sil], unshadowed[sil], rtol=5e-2, atol=1e-3)
        _checkbox(v, "shadows", True)
        np.testing.assert_allclose(v.image, lit, rtol=1e-6, atol=1e-7)
        shadow = floor & (lit.mean(2) < 0.5 * unshadowed.mean(2))
        expect = floor & _geometric_shadow(cam, light)
        # the SSDF (12² map, 8 PCA terms) rounds off the shadow's far tip: most of the geometric
        # shadow, hardly anything outside it
        overlap = (shadow & expect).sum() / (shadow | expect).sum()
        inside = (shadow & expect).sum() / shadow.sum()
        assert expect.sum() > 30 and overlap > 0.6 and inside > 0.9, (overlap, inside)
        masks.append((shadow, expect))
    (s0, e0), (s1, e1) = masks

    def iou(a, b):
        return (a & b).sum() / (a | b).sum()

    # each shadow matches its own light's geometric shadow, not the other one's
    assert iou(s0, e1) < iou(s0, e0) - 0.2 and iou(s1, e0) < iou(s1, e1) - 0.2
    x0, x1 = (np.argwhere(m)[:, 1].mean() for m in (s0, s1))
    assert x1 - x0 > 10  # the light went to -x, its shadow to +x
    _no_precompute(v, calls)


def test_the_bounces_toggle_shows_the_direct_light_alone_and_back(setup):
    import copy

    from warp_sg.renderer.renderer import Renderer

    v, path, calls = setup
    with_bounces = v.image.copy()
    _checkbox(v, "bounces", False)
    before = dict(calls)  # (the fresh renderer's own precompute is not the viewer's)
    sc = copy.deepcopy(v.renderer.scene)  # the viewer's scene as the earlier tests left it
    sc.render.bounces = 0
    direct = Renderer(sc, precomputed=v.renderer.precomputed()).render()  # (the same refined mesh and SSDFs)
    calls.clear()
    calls.update(before)
    np.testing.assert_allclose(v.image, direct, rtol=1e-5, atol=1e-6)
    assert v.image.sum() < with_bounces.sum()  # the floor's and the sphere's light on each other gone
    _checkbox(v, "bounces", True)
    np.testing.assert_array_equal(v.image, with_bounces)
    _no_precompute(v, calls)


def test_keys_write_an_exr_and_png_screenshot_and_print_timings(setup, capsys):
    v, path, calls = setup
    vp = v.viewport
    vp.reset_view()
    _key(v, "s")
    _key(v, "t")
    out = capsys.readouterr().out
    assert "precompute" in out and "last frame" in out
    exr, png = sorted(p for p in v.editor.screenshot_dir.iterdir() if p.stem.endswith("_001"))
    np.testing.assert_allclose(read_exr(exr), v.image, rtol=1e-6)
    from PIL import Image

    shot = np.asarray(Image.open(png).convert("RGB")).astype(int)
    assert np.abs(shot - (tonemap_srgb(v.image) * 255 + 0.5).astype(int)).max() <= 1
    assert not [p for p in v.editor.screenshot_dir.iterdir() if p.name.startswith(".")]  # atomic: no temporaries
    _no_precompute(v, calls)


def test_dragging_a_dynamic_objects_handle_moves_it_and_the_o_key_turns_it(tmp_path):
    """A dynamic sphere's handle dragged 0.6 along +x: the frame is that of a fresh renderer with
    the object moved by set_object_transform; 'o' turns it 15° about the vertical (its texture-free
    sphere looks the same: its transform is checked), all without precompute."""
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.tools.preview import open_viewer

    path = tmp_path / "scene.toml"
    path.write_text(SCENE.replace('material = "shiny"', 'material = "shiny"\ndynamic = true', 1))
    v = open_viewer(ws.load_scene(path), off_screen=True, progress=False, screenshot_dir=tmp_path)
    try:
        v.plotter.iren.interactor.Initialize()
        h = v.editor.objects
        assert h.objects == [0] and len(h.widgets) == 1
        c0 = h.rest_centre[0].copy()
        ssdf = v.renderer.ssdf
        _drag(h.widgets[0], lambda: h.widgets[0].SetCenter(*(c0 + [0.6, 0.0, 0.0])))
        M = np.asarray(v.renderer.scene.objects[0].motion)
        np.testing.assert_allclose(M[:3, 3], [0.6, 0.0, 0.0], atol=1e-6)
        fresh = Renderer(ws.load_scene(path))
        fresh.set_camera(**{k: getattr(v.renderer.scene.camera, k) for k in ("origin", "target", "up", "fov",
                                                                           "width", "height")})
        fresh.set_object_transform(0, M)
        np.testing.assert_allclose(v.image, fresh.render(), rtol=1e-5, atol=1e-6)
        _key(v, "o")
        R = np.asarray(v.renderer.scene.objects[0].motion)[:3, :3]
        np.testing.assert_allclose(R[[0, 0, 2, 2], [0, 2, 0, 2]], np.array([1, 1, -1, 1]) * np.array(
            [np.cos(np.radians(15)), np.sin(np.radians(15)), np.sin(np.radians(15)), np.cos(np.radians(15))]), atol=1e-9)
        assert v.renderer.ssdf is ssdf  # no precompute
    finally:
        v.close()


@pytest.mark.parametrize("model,given,sliders", [
    ("ward", {"alpha": 0.1}, ["kd", "ks", "alpha"]),
    ("ward", {}, ["kd", "ks", "alpha"]),
    ("ward", {"alpha_x": 0.1, "alpha_y": 0.3}, ["kd", "ks", "alpha_x", "alpha_y"]),
    ("ward", {"alpha_y": 0.3}, ["kd", "ks", "alpha_x", "alpha_y"]),
    ("ggx", {"alpha": 0.5}, ["kd", "ks", "alpha"]),
    ("cook_torrance", {"m": 0.2}, ["kd", "ks", "m"]),
    ("ashikhmin_shirley", {}, ["kd", "ks", "nu", "nv"]),
    ("oren_nayar", {}, ["kd", "sigma"]),
    ("lafortune", {}, ["kd", "ks"]),
    ("measured", {"file": "x.binary"}, []),
])
def test_the_sliders_are_the_declared_parameters_of_the_model_the_material_uses(model, given, sliders):
    """A slider per parameter with a declared range; of ``alpha`` and the pair given instead of it,
    the ones the material sets (no display needed)."""
    from warp_sg.brdf import MODELS
    from warp_sg.tools.viewer_widgets import slider_params

    assert slider_params(MODELS[model].PARAMS, given) == sliders
