"""One rule for the camera and the lights: a record built in Python (``Camera``, ``PointLight``,
``DirectionalLight``, ``EnvironmentLight``) is checked by the scene file's table model
(``warp_sg.scene.camera.CameraTable``, ``warp_sg.scene.light_tables``), so the same bad value is
refused with the same words in a file and in Python, and a value the file accepts is accepted."""
from __future__ import annotations

import numpy as np
import pytest

import warp_sg as ws
from warp_sg.core.errors import InputError, SceneError
from warp_sg.scene.camera import Camera
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight, PointLight
from warp_sg.scene.loader import load_scene

SCENE = """
[camera]
origin = [0.0, 1.0, 4.0]
target = [0.0, 0.5, 0.0]
{camera}

[[objects]]
primitive = "sphere"
material = "a"

[materials.a]
model = "lambert"

{lights}
"""
POINT = '[[lights]]\ntype = "point"\nposition = [2.0, 3.0, 2.0]\n'


def _camera(toml=""):
    """The [camera] lines: width 16, height 12 unless ``toml`` sets them, then ``toml``."""
    keep = [line for line in ("width = 16", "height = 12") if line.split()[0] + " =" not in toml]
    return "\n".join(keep + [toml])


def _load(tmp_path, text):
    p = tmp_path / "scene.toml"
    p.write_text(text)
    return load_scene(p)


@pytest.mark.parametrize("toml,kwargs,message", [
    ("fov = 179.5", dict(fov=179.5), "[camera] key 'fov' must be <= 179.0, got 179.5"),
    ("fov = 0.0", dict(fov=0.0), "[camera] key 'fov' must be > 0, got 0.0"),
    ("width = 0", dict(width=0), "[camera] key 'width' must be >= 1, got 0"),
    ("height = 2.5", dict(height=2.5), "[camera] key 'height' must be an integer, got 2.5"),
    ("near = -1.0", dict(near=-1.0), "[camera] key 'near' must be > 0, got -1.0"),
    ("near = 5.0\nfar = 2.0", dict(near=5.0, far=2.0), "[camera] key 'near' must be less than far = 2.0, got 5.0"),
    ('up = [0.0, 1.0, "x"]', dict(up=(0.0, 1.0, "x")), "[camera] key 'up' must be a list of 3 numbers, "
                                                         "got [0.0, 1.0, 'x']"),
    ("up = [0.0, -0.5, -4.0]", dict(up=(0.0, -0.5, -4.0)), "[camera] up is parallel to the viewing direction (or zero)"),
])
def test_a_camera_built_in_python_is_refused_in_the_scene_files_words(tmp_path, toml, kwargs, message):
    with pytest.raises(SceneError) as from_file:
        _load(tmp_path, SCENE.format(camera=_camera(toml), lights=POINT))
    assert str(from_file.value) == f"scene.toml: {message}"
    base = dict(origin=(0.0, 1.0, 4.0), target=(0.0, 0.5, 0.0), width=16, height=12)
    with pytest.raises(SceneError) as from_python:
        Camera(**{**base, **kwargs})
    assert str(from_python.value) == message
    assert isinstance(from_python.value, InputError)  # what raster.rasterize's callers catch


_P = '[[lights]]\ntype = "point"\n'
_D = '[[lights]]\ntype = "directional"\n'
_E = '[[lights]]\ntype = "environment"\n'
LIGHT_CASES = [  # (the light's table in a file, the record, its arguments in Python, the words after the label)
    (_P + "position = [2.0, 3.0, 2.0]\nradius = -0.1", PointLight, dict(position=(2.0, 3.0, 2.0), radius=-0.1),
     "key 'radius' must be >= 0, got -0.1"),
    (_P + "position = [2.0, 3.0, 2.0]\nintensity = [1.0, 2e20, 1.0]", PointLight,
     dict(position=(2.0, 3.0, 2.0), intensity=np.array([1.0, 2e20, 1.0])),
     "key 'intensity' must be <= 1e+20, got [1.0, 2e+20, 1.0]"),
    (_P + "position = [1.0, nan, 0.0]", PointLight, dict(position=np.array([1.0, np.nan, 0.0])),
     "key 'position' must be finite, got [1.0, nan, 0.0]"),
    (_D + "direction = [0.0, 0.0, 0.0]", DirectionalLight, dict(direction=(0, 0, 0)),
     "key 'direction' must be a non-zero vector"),
    (_D + "direction = [0.0, 1.0, 0.0]\nradius = 2.0", DirectionalLight, dict(direction=(0, 1, 0), radius=2.0),
     "key 'radius' must be <= 1.5707963267948966, got 2.0"),
    (_E + 'procedural = "sky"\nscale = -1.0', EnvironmentLight, dict(procedural="sky", scale=-1.0),
     "key 'scale' must be >= 0, got -1.0"),
    (_E + 'procedural = "skies"', EnvironmentLight, dict(procedural="skies"),
     "key 'procedural' must be 'sky' or 'constant', got 'skies'"),
    (_E + 'procedural = "sky"\noptions = {sun_intensty = 3.0}', EnvironmentLight,
     dict(procedural="sky", options={"sun_intensty": 3.0}),
     "key 'options.sun_intensty' unknown — did you mean 'sun_intensity'?"),
    (_E + 'procedural = "constant"\noptions = {radiance = -1.0}', EnvironmentLight,
     dict(procedural="constant", options={"radiance": -1.0}), "key 'options.radiance' must be >= 0, got -1.0"),
    (_E + 'procedural = "sky"\nrotation = "north"', EnvironmentLight, dict(procedural="sky", rotation="north"),
     "key 'rotation' must be a number, got 'north'"),
    (_E, EnvironmentLight, dict(), "give exactly one of 'file' or 'procedural'"),
]
LABELS = {PointLight: "point light", DirectionalLight: "directional light", EnvironmentLight: "environment light"}


@pytest.mark.parametrize("toml,record,kwargs,message", LIGHT_CASES, ids=[c[3][:40] for c in LIGHT_CASES])
def test_a_light_built_in_python_is_refused_in_the_scene_files_words(tmp_path, toml, record, kwargs, message):
    with pytest.raises(SceneError) as from_file:
        _load(tmp_path, SCENE.format(camera=_camera(), lights=toml))
    assert str(from_file.value) == f"scene.toml: [[lights]] #1 {message}"
    with pytest.raises(SceneError) as from_python:
        record(**kwargs)
    assert str(from_python.value) == f"[[lights]] ({LABELS[record]}) {message}"


def test_records_built_in_python_keep_numpy_values_and_the_files_defaults(tmp_path):
    cam = Camera(origin=np.array([0.0, 1.0, 4.0]), target=np.zeros(3, np.float32), fov=np.float32(35.0),
                 width=np.int64(32), height=np.int32(24))
    assert cam.origin == (0.0, 1.0, 4.0) and cam.width == 32 and isinstance(cam.width, int)
    assert cam.fov == 35.0 and cam.target == (0.0, 0.0, 0.0)
    d = DirectionalLight(np.array([0.0, 2.0, 0.0]), intensity=np.float64(3.0))
    np.testing.assert_array_equal(d.direction, [0.0, 1.0, 0.0])  # unit
    np.testing.assert_array_equal(d.intensity, [3.0, 3.0, 3.0])
    # a light with every default equals the file's light with every default
    sc = _load(tmp_path, SCENE.format(camera=_camera(), lights=POINT + '[[lights]]\ntype = "directional"\ndirection = [0.0, 1.0, 0.0]\n'
                                      '[[lights]]\ntype = "environment"\nprocedural = "sky"\n'))
    p, dl, env = sc.local_lights[0], sc.local_lights[1], sc.environment
    q = PointLight((2.0, 3.0, 2.0))
    assert p.radius == q.radius == 0.1 and np.array_equal(p.intensity, q.intensity)
    assert dl.radius == DirectionalLight((0, 1, 0)).radius == 0.02
    e = EnvironmentLight(procedural="sky")
    assert (env.scale, env.rotation) == (e.scale, e.rotation) == (1.0, 0.0)
    with pytest.raises(SceneError, match=r"give exactly one of 'file', 'procedural' or data"):
        EnvironmentLight(procedural="sky", data=np.ones((4, 8, 3)))


def test_a_refused_environment_change_leaves_the_renderer_as_it_was():
    sc = ws.scene.Scene(camera=Camera(width=8, height=8), objects=[ws.scene.SceneObject(material="a", primitive="sphere")],
                        materials={"a": ws.scene.Material("lambert")},
                        lights=[EnvironmentLight(procedural="constant", options={"radiance": 0.5})],
                        render=ws.scene.RenderSettings(shadows=False, antialias=1))
    r = ws.Renderer(sc)
    first = r.render().copy()
    with pytest.raises(SceneError, match=r"^\[\[lights\]\] \(environment light\) key 'scale' must be >= 0, got -2.0$"):
        r.set_environment_scale(-2.0)
    with pytest.raises(SceneError, match="key 'rotation' must be finite"):
        r.set_environment_rotation(float("inf"))
    assert (r.env_light.scale, r.env_light.rotation) == (1.0, 0.0)
    np.testing.assert_array_equal(r.render(), first)
    r.set_environment_scale(2.0)
    np.testing.assert_allclose(r.render(), 2.0 * first, rtol=1e-5, atol=1e-7)  # radiance is linear in the scale
