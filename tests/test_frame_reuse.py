"""What a frame does not redo (issue 13): the visibility buffer is reused while the camera stays,
the static geometry is rasterised from its device arrays without revalidation, and environment
lobes that carry no energy are left out — each checked against a renderer built from scratch.

Every test that edits a renderer gets its own (``renderer``): the precompute runs once for the module
(``precomputed``) and each fresh ``Renderer`` of the same scene reads it from the on-disk cache, so a
test sees the state it set up itself, in any order."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import raster
from warp_sg.renderer.renderer import Renderer
from warp_sg.scene.camera import Camera
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight
from warp_sg.scene.model import Material, Scene, SceneObject
from warp_sg.scene.render_settings import RenderSettings


def _scene(kd=(0.6, 0.5, 0.4), origin=(0.0, 1.2, 3.0)):
    cam = Camera(origin=origin, target=(0.0, 0.3, 0.0), fov=40.0, width=40, height=32)
    objects = [SceneObject(material="ball", primitive="sphere", params={"radius": 0.4, "resolution": (12, 24),
                                                                         "center": (0.0, 0.45, 0.0)}),
               SceneObject(material="floor", primitive="plane", params={"size": (3.0, 3.0), "resolution": (6, 6)})]
    mats = {"ball": Material("blinn_phong", {"kd": list(kd), "ks": [0.3, 0.3, 0.3], "n": 30.0}),
            "floor": Material("lambert", {"kd": [0.5, 0.5, 0.5]})}
    env = EnvironmentLight(procedural="constant", options={"radiance": [0.3, 0.35, 0.4], "width": 32, "height": 16})
    lights = [env, DirectionalLight(direction=(-0.4, -1.0, -0.3), intensity=(2.0, 2.0, 2.0))]
    rs = RenderSettings(shadows=True, ssdf_resolution=16, pca_terms=8, visibility_budget=0, env_lobes=2,
                        antialias=2)
    return Scene(camera=cam, objects=objects, materials=mats, lights=lights, render=rs)


@pytest.fixture(scope="module")
def precomputed():
    """The scene's precompute (shadows), once: it lands in the on-disk cache the renderers below read."""
    Renderer(_scene(), device="cpu")


@pytest.fixture
def renderer(precomputed):
    """A renderer of its own for each test (from the cached precompute), one frame rendered."""
    r = Renderer(_scene(), device="cpu")
    r.render()
    return r


def test_material_edit_reshades_the_same_visibility_buffer_and_equals_a_fresh_render(renderer):
    renderer.set_material("ball", kd=[0.1, 0.7, 0.2])
    img = renderer.render()
    assert renderer.timings["raster_reused"] is True
    fresh = Renderer(_scene(kd=(0.1, 0.7, 0.2)), device="cpu").render()
    np.testing.assert_array_equal(img, fresh)


def test_camera_change_rasterises_again_and_equals_a_fresh_render(renderer):
    renderer.set_camera(origin=(0.8, 1.0, 2.8))
    img = renderer.render()
    assert renderer.timings["raster_reused"] is False
    fresh = Renderer(_scene(origin=(0.8, 1.0, 2.8)), device="cpu").render()
    np.testing.assert_array_equal(img, fresh)
    renderer.render()
    assert renderer.timings["raster_reused"] is True


def test_trusted_device_geometry_rasterises_like_the_validated_numpy_path(renderer):
    g, ga, cam = renderer.geometry, renderer.geo_arrays, renderer.scene.camera
    a = raster.rasterize(g.vertices, g.triangles, cam, device="cpu", supersample=2)
    b = raster.rasterize(ga.positions, ga.tris, cam, device="cpu", supersample=2, validate=False)
    np.testing.assert_array_equal(a.tri_id.numpy(), b.tri_id.numpy())
    np.testing.assert_array_equal(a.bary.numpy(), b.bary.numpy())
    assert (a.tri_id.numpy() >= 0).mean() > 0.3


def test_environment_lobes_without_energy_are_left_out():
    """The rule the frames' environment arrays keep their lobes by: a lobe whose amplitude the fit set
    to 0 (or to next to nothing against the others) is left out; one is kept when none carries any."""
    from warp_sg.renderer.environment_setup import lobes_with_energy

    lam = np.array([2.0, 5.0, 8.0, 40.0])
    mu = np.array([[0.3, 0.2, 0.1], [0.0, 0.0, 0.0], [1e-9, 0.0, 0.0], [0.0, 0.0, 0.05]])
    assert lobes_with_energy(lam, mu).tolist() == [True, False, False, True]
    assert lobes_with_energy(lam[:2], np.zeros((2, 3))).tolist() == [True, False]


def test_background_kernel_matches_the_camera_rays_and_the_numpy_environment_lookup():
    from warp_sg.scene.envmap import env_lookup_numpy, rotation_y
    from warp_sg.shading.background import background_image, background_params

    rng = np.random.default_rng(5)
    env = rng.uniform(0.0, 2.0, (16, 32, 3)).astype(np.float32)
    cam = Camera(origin=(0.3, 1.0, 2.5), target=(0.0, 0.2, 0.0), fov=55.0, width=23, height=17)
    R = rotation_y(40.0)
    import warp as wp

    bg = background_params(cam, 3, wp.array(env, dtype=wp.vec3, device="cpu"), R, 1.5, "cpu")
    got = background_image(bg, "cpu").numpy()
    want = env_lookup_numpy(env, cam.ray_directions(supersample=3), rotation=R) * 1.5
    np.testing.assert_allclose(got, want, rtol=2e-4, atol=2e-5)
    # masked by a visibility buffer: the lookup only where it sees no object, 0 elsewhere
    tri = rng.integers(-1, 2, got.shape[:2]).astype(np.int32)
    masked = background_image(bg, "cpu", wp.array(tri, dtype=int, device="cpu")).numpy()
    np.testing.assert_allclose(masked[tri < 0], want[tri < 0], rtol=2e-4, atol=2e-5)
    assert (masked[tri >= 0] == 0).all()


def test_a_bad_material_edit_raises_and_leaves_the_material_and_the_image_as_they_were(renderer):
    from warp_sg.core.errors import SceneError

    before = renderer.render()
    params = dict(renderer.scene.materials["ball"].params)
    for bad in ({"n": -5.0}, {"model": "no_such_model"}, {"kd": [0.2, 0.3]}):
        with pytest.raises(SceneError, match="ball"):
            renderer.set_material("ball", **bad)
        assert renderer.scene.materials["ball"].model == "blinn_phong"
        assert renderer.scene.materials["ball"].params == params
    np.testing.assert_array_equal(renderer.render(), before)


def test_a_new_view_overwrites_the_old_buffer_and_equals_a_fresh_rasterisation(renderer):
    ga, cam = renderer.geo_arrays, renderer.scene.camera
    old = raster.rasterize(ga.positions, ga.tris, cam, device="cpu", supersample=2, validate=False)
    ptr = old.tri_id.ptr
    moved = replace(cam, origin=(0.6, 1.1, 2.9))
    a = raster.rasterize(ga.positions, ga.tris, moved, device="cpu", supersample=2, validate=False, reuse=old)
    b = raster.rasterize(ga.positions, ga.tris, moved, device="cpu", supersample=2, validate=False)
    assert a.tri_id.ptr == ptr  # the same memory, rewritten
    np.testing.assert_array_equal(a.tri_id.numpy(), b.tri_id.numpy())
    np.testing.assert_array_equal(a.bary.numpy(), b.bary.numpy())
    np.testing.assert_array_equal(a.depth.numpy(), b.depth.numpy())
    # a buffer of another size is not reused
    c = raster.rasterize(ga.positions, ga.tris, moved, device="cpu", supersample=1, validate=False, reuse=a)
    assert c.tri_id.ptr != a.tri_id.ptr and c.tri_id.shape == (cam.height, cam.width)


@pytest.mark.parametrize("render", [{"antialias": 2}, {"supersampling": 2, "antialias": 1}])
def test_the_background_of_a_new_view_and_of_a_reshade_are_the_same(render):
    """A new view reads the environment along the camera rays inside the shading kernel; a re-shade
    (same camera) builds the background image once (``background_image``, checked against numpy
    above) and reads it: the frames are bit-identical, under a sky that varies with direction."""
    scene = replace(_scene(), lights=[EnvironmentLight(procedural="sky", options={"width": 64, "height": 32})])
    scene = replace(scene, render=replace(scene.render, **render))
    r = Renderer(scene, device="cpu")
    new_view = r.render()
    assert r.timings["raster_reused"] is False and r.timings["background"] == "rays"
    r.set_material("floor", kd=[0.5, 0.5, 0.5])
    reshade = r.render()
    assert r.timings["raster_reused"] is True and r.timings["background"] == "image"
    np.testing.assert_array_equal(new_view, reshade)
    sky = new_view[0].sum(-1)  # the top row sees only the sky
    assert sky.std() > 1e-3 * sky.mean()
