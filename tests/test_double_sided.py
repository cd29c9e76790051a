"""glTF's ``doubleSided`` (glTF 2.0 §3.9.5): a single-sided material's back faces are culled for
camera rays, in the raster and in the Monte-Carlo reference, whatever the object's closedness.

The case that matters is a surface stored twice, as two coincident shells facing opposite ways
(the shared Ferrari's body): the eye must see the shell that faces it and never the inward twin,
so the twin-shell quad must render exactly as its front shell alone (an independent scene: one
shell, nothing to cull), and a single shell seen from behind not at all."""
from __future__ import annotations

import numpy as np
import pytest
from gltf_files import GltfWriter, quad

from warp_sg.groundtruth.reference import reference
from warp_sg.renderer.renderer import Renderer
from warp_sg.scene.camera import Camera
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight
from warp_sg.scene.model import Scene, SceneObject
from warp_sg.scene.render_settings import RenderSettings

LIGHTS = [DirectionalLight(direction=(0.3, 1.0, 0.4), radius=0.1, intensity=(2.0, 2.0, 2.0)),
          EnvironmentLight(procedural="constant", options={"radiance": [0.4, 0.45, 0.5]})]
ABOVE = dict(origin=(0.0, 1.3, 1.5), target=(0.0, 0.3, 0.0), fov=40.0, width=32, height=24)
MATERIAL = {"name": "paint", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.1, 1.0], "metallicFactor": 0.0,
                                                      "roughnessFactor": 0.5}}


def shells_file(path, shells: str, double_sided: bool = False):
    """A 1.2-wide quad at y = 0.3 in one primitive: ``shells`` "front" (facing +Y), "back"
    (the same points wound the other way, normals −Y) or "twin" (both, coincident)."""
    P, idx, N, uv = quad(1.2, 0.3, 4)
    parts = {"front": (P, idx, N), "back": (P, idx[:, ::-1], -N)}
    chosen = [parts["front"], parts["back"]] if shells == "twin" else [parts[shells]]
    pos = np.concatenate([c[0] for c in chosen])
    tri = np.concatenate([c[1] + len(P) * i for i, c in enumerate(chosen)])
    nrm = np.concatenate([c[2] for c in chosen])
    w = GltfWriter()
    m = w.material(dict(MATERIAL, doubleSided=double_sided))
    w.mesh(pos, tri, nrm, None, material=m, name="body")
    return w.glb(path)


def scene_of(path, **cam):
    return Scene(camera=Camera(**{**ABOVE, **cam}), objects=[SceneObject(material=None, mesh=path, name="car")],
                 lights=list(LIGHTS), render=RenderSettings(shadows=False))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("shells")
    return {k: shells_file(d / f"{k}.glb", k) for k in ("front", "back", "twin")}


def test_the_glTF_default_is_single_sided_and_doubleSided_true_keeps_both_sides(tmp_path, files):
    assert Scene(camera=Camera(**ABOVE), objects=[SceneObject(material=None, mesh=files["twin"])],
                 lights=list(LIGHTS)).geometry().one_sided.tolist() == [True]
    both = shells_file(tmp_path / "both.glb", "twin", double_sided=True)
    assert Scene(camera=Camera(**ABOVE), objects=[SceneObject(material=None, mesh=both)],
                 lights=list(LIGHTS)).geometry().one_sided is None


def test_a_twin_shell_quad_renders_as_its_front_shell_alone(files):
    twin, front = Renderer(scene_of(files["twin"])).render(), Renderer(scene_of(files["front"])).render()
    assert (twin.sum(-1) > 0).mean() > 0.3  # the quad fills much of the frame
    np.testing.assert_allclose(twin, front, atol=1e-5)
    # seen from below, the other shell: the back shell alone
    below = dict(origin=(0.0, -0.9, 1.5))
    np.testing.assert_allclose(Renderer(scene_of(files["twin"], **below)).render(),
                               Renderer(scene_of(files["back"], **below)).render(), atol=1e-5)


def test_a_single_sided_shell_seen_from_behind_is_not_drawn(files):
    r = Renderer(scene_of(files["front"], origin=(0.0, -0.9, 1.5)))
    assert (r.rasterize(1).tri_id.numpy() < 0).all()


def test_the_reference_sees_the_twin_shell_quad_as_its_front_shell_alone(files):
    twin = reference(scene_of(files["twin"]), spp=8, progress=False, seed=3)
    front = reference(scene_of(files["front"]), spp=8, progress=False, seed=3)
    assert (front.sum(-1) > 0).mean() > 0.3
    np.testing.assert_allclose(twin, front, atol=1e-4)
