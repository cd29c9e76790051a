"""Shading kernels specialised per set of material models (``brdf.kernel.material_variants``).

* the specialised BRDF functions against the numpy models (independent reference: the closed
  forms of ``warp_sg.brdf`` and its numpy slice lobes), one kernel per model family;
* a renderer picks the variant of its scene's models (also after ``set_material(model=...)``),
  and renders the same image as the generic all-model kernel, for every model family and for a
  scene mixing two models;
* the generated source of a one-model variant holds no other model's code.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import warp as wp

import warp_sg.brdf as B
from warp_sg.brdf.kernel import material_wp as M
from warp_sg.brdf.kernel.material_variants import ALL_MODELS, material_funcs
from warp_sg.brdf.registry import code_of, codes
from warp_sg.core.errors import InputError
from warp_sg.renderer.renderer import Renderer
from warp_sg.scene.camera import Camera
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight
from warp_sg.scene.model import Scene, SceneObject
from warp_sg.scene.render_settings import RenderSettings
from warp_sg.shading import kernel as S

#: one material per model family: (model name, parameters, model code)
FAMILIES = [
    ("lambert", {"kd": [0.6, 0.5, 0.4]}, 0),
    ("oren_nayar", {"kd": [0.7, 0.6, 0.5], "sigma": 0.5}, 1),
    ("phong", {"kd": 0.1, "ks": [0.5, 0.6, 0.7], "n": 30.0}, 2),
    ("blinn_phong", {"kd": 0.2, "ks": 0.5, "n": 80.0}, 3),
    ("cook_torrance", {"kd": 0.1, "ks": 3.0, "m": 0.25, "fresnel": "copper"}, 4),
    ("torrance_sparrow", {"kd": 0.05, "ks": [0.9, 0.8, 0.7], "m": 0.3, "fresnel": {"eta": 1.5}}, 5),
    ("ward", {"kd": 0.1, "ks": 0.6, "alpha_x": 0.1, "alpha_y": 0.35}, 6),
    ("ashikhmin_shirley", {"kd": 0.1, "ks": 0.8, "nu": 50.0, "nv": 500.0, "fresnel": "gold", "lobes": 3}, 7),
    ("lafortune", {"kd": 0.2, "ks": 0.7, "lobes": [{"cx": -1, "cy": -1, "cz": 1, "n": 15},
                                                   {"cx": 0.6, "cy": 0.6, "cz": 0.8, "n": 4}]}, 8),
    ("ggx", {"kd": 0.05, "ks": 0.9, "alpha": 0.2, "fresnel": {"schlick": 0.9}}, 10),
]


# ---------------------------------------------------------------------------------------------
# the specialised functions against the numpy models
# ---------------------------------------------------------------------------------------------
_PROBES: dict = {}


def probe_kernel(models):
    """A kernel evaluating brdf_eval, brdf_mo and the slice lobes with ``material_funcs(models)``."""
    key = tuple(sorted(models))
    if key in _PROBES:
        return _PROBES[key]
    F = material_funcs(key)
    brdf_eval, brdf_mo, slice_lobe, slice_lobe_count = F.brdf_eval, F.brdf_mo, F.slice_lobe, F.slice_lobe_count

    def probe(mats: wp.array(dtype=M.Material), mid: int, o: wp.array(dtype=wp.vec3), i: wp.array(dtype=wp.vec3),
              f: wp.array(dtype=wp.vec3), mo: wp.array(dtype=wp.vec3), axis: wp.array2d(dtype=wp.vec3),
              lam: wp.array2d(dtype=float), amp: wp.array2d(dtype=wp.vec3)):
        t = wp.tid()
        mat = mats[mid]
        f[t] = brdf_eval(mat, o[t], i[t])
        mo[t] = brdf_mo(mat, o[t], i[t])
        for k in range(slice_lobe_count(mat)):
            a, l, m = slice_lobe(mat, o[t], k)
            axis[t, k] = a
            lam[t, k] = l
            amp[t, k] = m

    probe.__name__ = probe.__qualname__ = "probe" + F.tag
    k = wp.kernel(probe, enable_backward=False, module="unique")
    _PROBES[key] = k
    return k


def _dirs(rng, n):
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 1e-3
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.mark.parametrize("codes", [(0, 1), (2, 3), (4, 5, 6), (7, 8), (10,)], ids=lambda c: "m" + "_".join(map(str, c)))
def test_specialised_brdf_functions_match_the_numpy_models(codes):
    models = [B.make_model(name, **p) for name, p, c in FAMILIES if c in codes]
    table = M.pack_materials(models, 1, "cpu")
    assert {r["model"] for r in table.records} == set(codes)
    rng = np.random.default_rng(7)
    n = 128
    o = _dirs(rng, n)
    i = _dirs(rng, n)
    i[: n // 2] = o[: n // 2] * [-1, -1, 1] + 0.05 * rng.normal(size=(n // 2, 3))  # near the lobes
    i[: n // 2, 2] = np.abs(i[: n // 2, 2])
    i /= np.linalg.norm(i, axis=1, keepdims=True)
    o32, i32 = o.astype(np.float32), i.astype(np.float32)
    for k, model in enumerate(models):
        K = max(table.records[k]["lobe_count"], 1)
        f, mo = wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=wp.vec3)
        axis, lam, amp = wp.zeros((n, K), dtype=wp.vec3), wp.zeros((n, K), dtype=float), wp.zeros((n, K), dtype=wp.vec3)
        wp.launch(probe_kernel(codes), n, inputs=[table.materials, k, wp.array(o32, dtype=wp.vec3),
                                                  wp.array(i32, dtype=wp.vec3), f, mo, axis, lam, amp])
        name = type(model).__name__
        ref = model.eval(o32.astype(np.float64), i32.astype(np.float64))
        np.testing.assert_allclose(f.numpy(), ref, rtol=2e-3, atol=2e-4 * np.abs(ref).max(), err_msg=name)
        if not model.is_specular:
            continue
        if model.NAME != "lafortune":
            mref = model.ks * model.mo(o32.astype(np.float64), i32.astype(np.float64))
            np.testing.assert_allclose(mo.numpy(), mref, rtol=2e-3, atol=1e-5 * mref.max(), err_msg=name)
        ra, rl, rm = B.slice_lobes_numpy(model, o32.astype(np.float64), 1, "analytic")
        np.testing.assert_allclose(lam.numpy(), rl, rtol=2e-3, err_msg=name)
        np.testing.assert_allclose(amp.numpy(), rm, rtol=3e-3, atol=1e-6 * rm.max(), err_msg=name)
        ok = np.sum(rm, -1) > 0
        np.testing.assert_allclose(axis.numpy()[ok], ra[ok], atol=2e-4, err_msg=name)


def test_material_funcs_reject_unknown_model_codes():
    with pytest.raises(InputError, match="material model codes"):
        material_funcs({code_of("blinn_phong"), max(codes()) + 1})
    with pytest.raises(InputError, match="material model codes"):
        material_funcs(())
    lam, ct = code_of("lambert"), code_of("cook_torrance")
    assert material_funcs([ct, lam]) is material_funcs((lam, ct))  # cached per set


# ---------------------------------------------------------------------------------------------
# renderer: the scene's variant, same image as the generic kernel
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def renderer():
    """Two spheres ("a", "b") under a directional light and a small procedural sky (SG diffuse and
    prefiltered specular environment; no shadows: no precompute). Per-pixel sampling: the per-vertex
    diffuse environment sum needs ρd = kd/π, which the generic kernel (with Oren–Nayar) cannot
    assume, so it would differ by its interpolation (tests/test_env_irradiance_vertex.py)."""
    cam = Camera(origin=(0.0, 0.0, 3.5), target=(0.0, 0.0, 0.0), fov=40.0, width=24, height=24)
    sphere = {"radius": 0.45, "resolution": (16, 32)}
    scene = Scene(camera=cam,
                  objects=[SceneObject(material="a", primitive="sphere", params={**sphere, "center": (-0.5, 0.0, 0.0)}),
                           SceneObject(material="b", primitive="sphere", params={**sphere, "center": (0.5, 0.0, 0.0)})],
                  materials={"a": B.Lambert(kd=0.5), "b": B.Lambert(kd=0.5)},
                  lights=[DirectionalLight(direction=(0.3, 0.5, 1.0), radius=0.1, intensity=2.0),
                          EnvironmentLight(procedural="sky", options={"width": 32, "height": 16})],
                  render=RenderSettings(shadows=False, env_lobes=4, supersampling=1, antialias=1, background=False,
                                        visibility_sampling="pixel"))
    return Renderer(scene)


def generic_render(r, monkeypatch):
    """The same frame shaded by the generic all-model kernel."""
    f = r.features()
    with monkeypatch.context() as mp:
        mp.setattr(r, "features", lambda: dataclasses.replace(f, models=tuple(sorted(ALL_MODELS))))
        return r.render()


@pytest.mark.parametrize("name, params, code", FAMILIES, ids=[f[0] for f in FAMILIES])
def test_one_model_scene_renders_like_the_generic_kernel(renderer, monkeypatch, name, params, code):
    r = renderer
    for m in ("a", "b"):
        r.set_material(m, model=name, **params)
    f = r.features()
    assert f.models == (code,)
    assert S.shade_kernel(f).key.endswith(f"_m{code}")
    img = r.render()
    ref = generic_render(r, monkeypatch)
    assert img.max() > 0.05  # lit
    np.testing.assert_allclose(img, ref, rtol=1e-5, atol=1e-6)


def test_two_model_scene_gets_both_models(renderer, monkeypatch):
    r = renderer
    r.set_material("a", model="lambert", kd=[0.6, 0.5, 0.4])
    r.set_material("b", model="cook_torrance", kd=0.1, ks=3.0, m=0.25, fresnel="copper")
    f = r.features()
    assert f.models == (0, 4)
    assert S.shade_kernel(f).key.endswith("_m0_4")
    img = r.render()
    np.testing.assert_allclose(img, generic_render(r, monkeypatch), rtol=1e-5, atol=1e-6)
    # and the Cook–Torrance sphere is not shaded as the Lambert one would be: its model's code is there
    r.set_material("b", model="lambert", kd=0.1)
    lambert_b = r.render()
    right = np.zeros(img.shape[:2], bool)
    right[:, img.shape[1] // 2:] = True
    assert np.abs(img - lambert_b)[right].max() > 0.05
    np.testing.assert_allclose(img[~right], lambert_b[~right], rtol=1e-5, atol=1e-6)


# ---------------------------------------------------------------------------------------------
# what a variant contains
# ---------------------------------------------------------------------------------------------
def kernel_source(kernel) -> str:
    """The C++ source Warp generated for the kernel's module on the CPU (kernel cache)."""
    m = kernel.module
    m.load("cpu")
    found = sorted(Path(wp.config.kernel_cache_dir).glob(f"wp_{m.name}_*/*.cpp"), key=lambda p: p.stat().st_mtime)
    assert found, m.name
    return found[-1].read_text()


def test_one_model_variant_holds_no_other_models_code():
    full = dict(env_diffuse=S.ENV_SG, env_specular=S.ENV_PREFILTERED, lights=True, specular=True)
    generic = kernel_source(S.shade_kernel(S.Features(**full)))
    lam = kernel_source(S.shade_kernel(S.Features(**full, models=(code_of("lambert"),))))
    ct = kernel_source(S.shade_kernel(S.Features(**full, models=(code_of("cook_torrance"),))))
    other = ["merl_eval", "measured_mo", "lafortune_lobe", "ggx_", "as_exponent_log", "ggx_table_lobe"]
    for s in other + ["fresnel_eval", "g_over_cos"]:
        assert s in generic, s  # the generic kernel has every model (the check can fail)
        assert s not in lam, s
    for s in other:
        assert s not in ct, s
    assert "fresnel_eval" in ct and "g_over_cos" in ct
    assert len(lam) < len(ct) < len(generic)
