"""Gradients of a frame (``Renderer(requires_grad=True)``, ``warp_sg.renderer.gradients``) against
central finite differences of the rendered image.

Each parameter is moved along a random direction ``V`` by ±h and ±h/4 and re-rendered; a pixel is
*smooth* for the check where the two central differences agree (the shading has kinks: table
interpolation in the irradiance of a lobe, the GGX lobe table's roughness nodes, the clamps of
visibility); the test asserts that most pixels are smooth and that ``Σ W·∂I/∂p·V`` over them equals
the adjoint's gradient (``backward(W)``) within 1e-3 relative. Finite differences run in float32
(the kernels' precision): steps of about 1e-3 of the value; the check allows the rounding of the
float32 images on top of the 1e-3 (three standard deviations of it, asserted to be under 1 %).

Held fixed, as the backward pass holds them (``gradients`` docstring): the per-vertex visibility
caches (a light's or a lobe's direction is moved in place, not through ``update_light``, which
would recompute them) and the energy-correction table (a Fresnel or anisotropic roughness is
written into the packed record in place); roughness through ``set_material`` keeps its table's
fixed range. The scene: an SG-mixture environment (``set_environment_mixture``), a directional
and a point light, shadows, an isotropic and an anisotropic GGX material, a textured one (base
colour, roughness, normal map), a Lambert floor; 32 × 24 pixels.
"""
from __future__ import annotations

import zlib

import numpy as np
import pytest
import warp as wp

from warp_sg.renderer.gradient_keys import RECORD_FIELDS, get_leaf, model_params, record_vector, set_leaf
from warp_sg.renderer.renderer import Renderer
from warp_sg.scene.camera import Camera
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight, PointLight
from warp_sg.scene.model import Material, Scene, SceneObject
from warp_sg.scene.render_settings import RenderSettings
from warp_sg.scene.textures import Texture
from warp_sg.shading.env_mixture import mixture_mean
from warp_sg.shading.visibility_terms import EnvSG

RNG = np.random.default_rng(7)
KD_TEX = (0.3 + 0.4 * RNG.random((8, 8, 3))).astype(np.float32)
A_TEX = (0.27 + 0.2 * RNG.random((8, 8, 1))).astype(np.float32)
N_TEX = np.concatenate([0.5 + 0.12 * RNG.standard_normal((8, 8, 2)), np.ones((8, 8, 1))], -1).astype(np.float32)
K = 6
AXES = RNG.standard_normal((K, 3))
AXES[:, 1] = np.abs(AXES[:, 1])
AXES /= np.linalg.norm(AXES, axis=1, keepdims=True)
LAM = 2.0 + 6.0 * RNG.random(K)
MU = 0.3 + RNG.random((K, 3))


def _scene() -> Scene:
    cam = Camera(origin=(0.0, 1.2, 3.0), target=(0.0, 0.3, 0.0), fov=40.0, width=32, height=24)
    sphere = lambda c, r: {"radius": r, "resolution": (12, 24), "center": c}  # noqa: E731
    objects = [SceneObject(material="ball", primitive="sphere", params=sphere((-0.45, 0.45, 0.0), 0.4)),
               SceneObject(material="tex", primitive="sphere", params=sphere((0.45, 0.4, 0.2), 0.35)),
               SceneObject(material="aniso", primitive="torus",
                           params={"major_radius": 0.3, "minor_radius": 0.12, "center": (0.0, 0.15, -0.6)}),
               SceneObject(material="floor", primitive="plane", params={"size": (3.0, 3.0), "resolution": (6, 6)})]
    mats = {"ball": Material("ggx", {"kd": [0.5, 0.4, 0.3], "ks": [0.9, 0.8, 0.7], "alpha": 0.33,
                                     "fresnel": {"schlick": 0.3}}),
            "tex": Material("ggx", {"ks": [1.0, 1.0, 1.0], "fresnel": {"schlick": 0.04}},
                            textures={"kd": Texture(data=KD_TEX), "alpha": Texture(data=A_TEX)},
                            normal_map=Texture(data=N_TEX)),
            "aniso": Material("ggx", {"kd": [0.2, 0.2, 0.2], "alpha_x": 0.21, "alpha_y": 0.44,
                                      "fresnel": {"schlick": 0.5}}),
            "floor": Material("lambert", {"kd": [0.5, 0.5, 0.5]})}
    lights = [EnvironmentLight(procedural="sky", options={"width": 64, "height": 32}),
              DirectionalLight(direction=(-0.4, 1.0, 0.3), intensity=(2.0, 2.0, 2.0), radius=0.05),
              PointLight(position=(1.0, 1.5, 1.0), intensity=(3.0, 3.0, 3.0), radius=0.05)]
    rs = RenderSettings(shadows=True, ssdf_resolution=16, pca_terms=8, visibility_budget=0, env_lobes=4, env_peaks=0,
                        antialias=1)
    return Scene(camera=cam, objects=objects, materials=mats, lights=lights, render=rs)


@pytest.fixture(scope="module")
def renderer():
    r = Renderer(_scene(), device="cpu", requires_grad=True)
    r.set_environment_mixture(AXES, LAM, MU)
    r.render()
    return r


def fd_check(r, apply, x0, key, h, smooth_min=0.85, tol=1e-3):
    """Central differences of the image along a random direction V of the value ``x0`` (``apply(x)``
    sets it; restored after) against the adjoint's gradient of ``key``; returns (grad, fd, smooth)."""
    x0 = np.asarray(x0, np.float64)
    v = np.random.default_rng(zlib.crc32(key.encode())).standard_normal(x0.shape)
    imgs = {}
    for s in (1.0, -1.0, 0.25, -0.25):
        apply(x0 + s * h * v)
        imgs[s] = r.render().astype(np.float64)
    apply(x0)
    base = r.render()
    d1 = (imgs[1.0] - imgs[-1.0]) / (2.0 * h)
    d2 = (imgs[0.25] - imgs[-0.25]) / (0.5 * h)
    noise = 4.0 * 1.2e-7 * (np.abs(base) + 1e-3) / (0.25 * h)  # float32 rounding of the finer difference
    smooth = np.abs(d1 - d2) <= np.maximum(2e-4 * np.abs(d1), noise)
    w = np.random.default_rng(1).standard_normal(base.shape) * smooth
    grads = r.backward(w)
    g = float(np.sum(np.asarray(grads[key], np.float64).reshape(v.shape) * v))
    fd = float(np.sum(w * d1))
    # the rounding of float32 images in Σ W·d1 (a few units in the last place of each pixel, /2h)
    moved = imgs[1.0] != imgs[-1.0]  # (a pixel the parameter does not reach renders the same, bit for bit)
    sigma = float(np.sqrt(np.sum((w * moved * 2.4e-7 * np.abs(base) / (2.0 * h)) ** 2)))
    assert smooth.mean() >= smooth_min, f"{key}: only {smooth.mean():.2f} of the pixels are smooth"
    assert sigma <= 0.01 * abs(fd), f"{key}: a step of {h} leaves the difference in the rounding"
    assert abs(g - fd) <= tol * abs(fd) + 3.0 * sigma, f"{key}: adjoint {g:.6e}, finite differences {fd:.6e}"
    return g, fd, smooth.mean()


def _set_param(r, name, key):
    def apply(x):
        m = r.scene.materials[name]
        head = key.split(".")[0]
        value = x.tolist() if x.ndim else float(x)
        new = set_leaf(dict(m.params), key, value)
        r.set_material(name, **{head: new[head]})
    return apply


def _set_record(r, name, key):
    """Write the packed record of the material with ``key`` set in place (its tables held)."""
    mi = r.geometry.material_names.index(name)
    m = r.scene.materials[name]
    params = model_params(m)

    def apply(x):
        vec = record_vector(m.model, set_leaf(params, key, x.tolist() if x.ndim else float(x)))
        s, o = r.material_table.structs[mi], 0
        for field, n in RECORD_FIELDS:
            old = getattr(s, field)
            setattr(s, field, type(old)(*[float(c) for c in vec[o:o + n]]))
            o += n
        r.material_table.rebuild()
    return apply


@pytest.mark.parametrize("name,key", [("ball", "kd"), ("ball", "ks"), ("ball", "alpha"), ("floor", "kd"),
                                      ("aniso", "kd")])
def test_material_parameter_gradients_match_finite_differences(renderer, name, key):
    x0 = renderer.scene.materials[name].params[key]
    fd_check(renderer, _set_param(renderer, name, key), x0, f"materials.{name}.{key}", 1e-3)


@pytest.mark.parametrize("name,key,h", [("ball", "fresnel.schlick", 1e-3), ("aniso", "fresnel.schlick", 1e-3),
                                        ("aniso", "alpha_x", 2e-4), ("aniso", "alpha_y", 2e-3)])
def test_fresnel_and_anisotropic_roughness_gradients_match_finite_differences(renderer, name, key, h):
    params = model_params(renderer.scene.materials[name])
    fd_check(renderer, _set_record(renderer, name, key), get_leaf(params, key), f"materials.{name}.{key}", h)


@pytest.mark.parametrize("key,data", [("kd", KD_TEX), ("alpha", A_TEX), ("normal_map", N_TEX)])
def test_texture_gradients_match_finite_differences(renderer, key, data):
    def apply(x):
        renderer.set_material("tex", **{key: Texture(data=x.astype(np.float32))})
    try:
        fd_check(renderer, apply, data, f"materials.tex.{key}", 1e-3)
    finally:
        renderer.set_material("tex", **{key: Texture(data=data)})


def test_light_intensity_gradients_match_finite_differences(renderer):
    for i, local in ((1, 0), (2, 1)):
        li = renderer.scene.local_lights[local]
        fd_check(renderer, lambda x: renderer.update_light(local, intensity=x.tolist()), li.intensity,
                 f"lights.{i}.intensity", 1e-3)


def _in_place(arr, row):
    """Set row ``row`` of a device array in place (the caches keyed on the scene's lights stay)."""
    base = arr.numpy().copy()

    def apply(x):
        a = base.copy()
        a[row] = x
        arr.assign(a)
    return apply, base[row].astype(np.float64)


def test_light_geometry_gradients_match_finite_differences_with_visibility_held(renderer):
    la = renderer.light_arrays
    d_apply, d0 = _in_place(la.vec, 0)
    fd_check(renderer, lambda x: d_apply(x / np.linalg.norm(x)), d0, "lights.1.direction", 1e-3, smooth_min=0.75)
    p_apply, p0 = _in_place(la.vec, 1)
    fd_check(renderer, p_apply, p0, "lights.2.position", 1e-3, smooth_min=0.75)
    # the directional light's angular radius (the point light's reaches a few penumbra pixels only)
    r_apply, r0 = _in_place(la.radius, 0)
    fd_check(renderer, r_apply, r0, "lights.1.radius", 3e-3, smooth_min=0.75)


def test_environment_mixture_gradients_match_finite_differences(renderer):
    fd_check(renderer, lambda x: renderer.set_environment_mixture(AXES, LAM, x), MU, "lights.0.mu", 1e-3)
    es = renderer._env_sg_arrays  # axes and sharpness in place: the lobes' per-vertex visibility held
    a0, l0 = es.axis.numpy().copy(), es.lam.numpy().copy()
    try:
        fd_check(renderer, lambda x: es.axis.assign((x / np.linalg.norm(x, axis=1, keepdims=True)).astype(np.float32)),
                 a0, "lights.0.axis", 1e-3, smooth_min=0.75)
        fd_check(renderer, lambda x: es.lam.assign(x.astype(np.float32)), l0, "lights.0.lambda", 1e-3, smooth_min=0.75)
    finally:
        es.axis.assign(a0)
        es.lam.assign(l0)


def test_gradients_are_zero_where_a_parameter_is_not_seen(renderer):
    """A weight on the background only: every gradient is zero (nothing leaks across pixels)."""
    img = renderer.render()
    tri = renderer._vb.tri_id.numpy()
    w = np.where((tri < 0)[..., None], 1.0, 0.0) * np.ones_like(img)
    g = renderer.backward(w)
    assert all(np.all(np.asarray(v) == 0.0) for v in g.values())


def test_the_adjoint_split_over_workers_sums_as_one_worker(renderer, monkeypatch):
    """The adjoint split over two workers' private sums equals one worker's (Warp's CPU atomics are
    plain adds: the split must lose nothing); a frame of 80 × 64 pixels, over the split's minimum."""
    import warp_sg.core.workers as workers

    cam = renderer.scene.camera
    renderer.set_camera(width=80, height=64)
    try:
        out = []
        for n in (2, 1):
            monkeypatch.setattr(workers, "cpu_workers", lambda *args, n=n, **kw: n)
            img = renderer.render()
            w = np.random.default_rng(3).standard_normal(img.shape)
            out.append(renderer.backward(w))
    finally:
        renderer.set_camera(width=cam.width, height=cam.height)
    for k in out[0]:
        np.testing.assert_allclose(np.asarray(out[0][k]), np.asarray(out[1][k]), rtol=1e-4, atol=1e-5, err_msg=k)


@wp.kernel
def _mixture_mean_kernel(env: EnvSG, p: wp.array(dtype=wp.vec3), lam: wp.array(dtype=float),
                         out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = mixture_mean(env, p[i], lam[i])


def test_mixture_mean_is_the_quadrature_of_the_lobes_product():
    """``env_mixture.mixture_mean`` (the specular lookup of an SG-mixture environment) against a
    float64 quadrature over the sphere of Σ_j μ_j G_j(i) G(i; p, λ) / ∫G."""
    es = EnvSG()
    es.count = K
    es.axis = wp.array(AXES.astype(np.float32), dtype=wp.vec3)
    es.lam = wp.array(LAM.astype(np.float32), dtype=float)
    es.mu = wp.array(MU.astype(np.float32), dtype=wp.vec3)
    p = RNG.standard_normal((5, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    lam = np.array([0.5, 3.0, 10.0, 40.0, 200.0])
    out = wp.zeros(5, dtype=wp.vec3)
    wp.launch(_mixture_mean_kernel, dim=5, inputs=[es, wp.array(p.astype(np.float32), dtype=wp.vec3),
                                wp.array(lam.astype(np.float32), dtype=float), out])
    # quadrature: a fine equal-area grid (z uniform, φ uniform)
    n = 1200
    z = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2.0 * np.pi
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    s = np.sqrt(1.0 - zz ** 2)
    d = np.stack([s * np.cos(pp), s * np.sin(pp), zz], -1).reshape(-1, 3)
    dw = 4.0 * np.pi / len(d)
    env = np.exp(LAM[None, :] * (d @ AXES.T - 1.0)) @ MU  # (N, 3)
    for i in range(5):
        g = np.exp(lam[i] * (d @ p[i] - 1.0))
        want = (g[:, None] * env).sum(0) * dw / (g.sum() * dw)
        np.testing.assert_allclose(out.numpy()[i], want, rtol=2e-3)
