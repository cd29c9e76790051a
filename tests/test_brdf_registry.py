"""The BRDF registry (warp_sg.brdf.registry): a model is one class, and the kernel switch, the
packing, the fits and everything that asks what a model can do follow it.

Throw-away models defined in this file only are registered with new codes; nothing else in the
project is edited:

* a specular one, the energy-conserving Blinn–Phong ``ρs = (n+8)/(8π) (n·h)^n`` (Akenine-Möller
  et al., "Real-Time Rendering", normalised Blinn–Phong) with its kernel hooks: ``make_model``,
  ``pack_materials``, the generated ``brdf_eval`` / ``slice_lobe`` / ``brdf_sample`` /
  ``brdf_pdf`` (generic and specialised) must serve it, checked against the closed form written
  here in numpy;
* a diffuse one (``kd/π`` under another name) and an anisotropic one (Ward's kernel functions
  under another name and code, not energy-normalised): with the specular one they check that the
  albedo table (:mod:`warp_sg.brdf.kernel.albedo`), the energy check (:mod:`warp_sg.brdf.energy`)
  and the renderer's kernel variant read the models' declared capabilities (``is_specular``,
  ``ROUGHNESS``, ``ENERGY_NORMALISED``), not their codes.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import numpy as np
import pytest
import warp as wp

from warp_sg import brdf as B
from warp_sg.brdf import registry
from warp_sg.brdf.base import BRDF, SpecularBRDF, as_rgb, as_scalar, dirs, half_vector
from warp_sg.brdf.kernel import material_wp as M
from warp_sg.brdf.kernel.material_eval_wp import cos_pow, log_cos_theta
from warp_sg.brdf.kernel.material_sample_wp import reflect_about
from warp_sg.brdf.params import KD, KS, Param
from warp_sg.core.errors import InputError

TWO_PI = 2.0 * np.pi
EIGHT_PI = 8.0 * np.pi


@wp.func
def _nbp_ndf(mat: M.Material, h: wp.vec3) -> float:
    return cos_pow(h, mat.params[0])


@wp.func
def _nbp_mo(mat: M.Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    return wp.vec3(1.0, 1.0, 1.0) * ((mat.params[0] + 8.0) / EIGHT_PI)


@wp.func
def _nbp_lobe(mat: M.Material, k: int):
    return wp.vec3(0.0, 0.0, 1.0), wp.max(mat.params[0], 1.0e-6), 1.0


@wp.func
def _nbp_sample(mat: M.Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
    ct = wp.pow(wp.max(u[0], 1.0e-30), 1.0 / (mat.params[0] + 2.0))
    st = wp.sqrt(wp.max(1.0 - ct * ct, 0.0))
    phi = TWO_PI * u[1]
    return reflect_about(o, wp.vec3(st * wp.cos(phi), st * wp.sin(phi), ct))


@wp.func
def _nbp_pdf_h(mat: M.Material, h: wp.vec3) -> float:
    if h[2] <= 0.0:
        return 0.0
    return (mat.params[0] + 2.0) / TWO_PI * wp.exp((mat.params[0] + 1.0) * log_cos_theta(h))


def _free_code():
    return max(registry.BY_CODE) + 1


class NormalisedBlinnPhong(SpecularBRDF):
    NAME = "normalised_blinn_phong_test"
    PARAMS = {"kd": KD, "ks": KS, "n": Param("number", "exponent", lo=0, texture=True, kernel=(0,))}
    KERNEL = registry.Kernel(ndf=_nbp_ndf, mo=_nbp_mo, analytic_lobe=_nbp_lobe, sample=_nbp_sample, pdf_h=_nbp_pdf_h)
    ROUGHNESS = "n"
    ENERGY_NORMALISED = True

    def __init__(self, kd=(0.0, 0.0, 0.0), ks=(1.0, 1.0, 1.0), n=30.0):
        self.kd = as_rgb(kd, "kd")
        self.ks = as_rgb(ks, "ks")
        self.n = as_scalar(n, "n", lo=0.0)

    def mo(self, o, i):
        o, i = dirs(o, i)
        return np.full(o.shape[:-1] + (3,), (self.n + 8.0) / EIGHT_PI)

    def ndf(self, h):
        h = np.asarray(h, dtype=np.float64)
        return np.where(h[..., 2] > 0, np.maximum(h[..., 2], 0.0) ** self.n, 0.0)

    def ndf_analytic_lambda(self):
        return max(self.n, 1e-6)

    def kernel_params(self):
        return (self.n, 0.0, 0.0, 0.0)


@pytest.fixture
def new_model():
    NormalisedBlinnPhong.CODE = _free_code()
    registry.register(NormalisedBlinnPhong)
    try:
        yield NormalisedBlinnPhong
    finally:
        registry.unregister(NormalisedBlinnPhong)


def _closed_form(n, ks, kd, o, i):
    """ρ = kd/π + ks (n+8)/(8π) (n·h)^n, zero below the horizon (the published formula)."""
    h = half_vector(o, i)
    up = (o[..., 2] > 0) & (i[..., 2] > 0)
    val = kd / np.pi + ks * ((n + 8.0) / EIGHT_PI * np.maximum(h[..., 2], 0.0) ** n)[..., None]
    return np.where(up[..., None], val, 0.0)


def _pdf_closed_form(n, o, i):
    """p(i) = (n+2)/(2π) (n·h)^{n+1} / (4 o·h) of cos θh = u^{1/(n+2)} sampling."""
    h = half_vector(o, i)
    oh = np.sum(o * h, -1)
    ph = np.where(h[..., 2] > 0, (n + 2.0) / TWO_PI * np.maximum(h[..., 2], 0.0) ** (n + 1.0), 0.0)
    return np.where(oh > 0, ph / (4.0 * np.maximum(oh, 1e-6)), 0.0)


def _dirs(rng, k, upper=True):
    v = rng.normal(size=(k, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    if upper:
        v[:, 2] = np.abs(v[:, 2]) + 0.05
        v /= np.linalg.norm(v, axis=1, keepdims=True)
    return v


def _eval_kernel(F):
    @wp.kernel
    def k(mats: wp.array(dtype=M.Material), o_a: wp.array(dtype=wp.vec3), i_a: wp.array(dtype=wp.vec3),
          u_a: wp.array(dtype=wp.vec2), f: wp.array(dtype=wp.vec3), axis: wp.array(dtype=wp.vec3),
          lam: wp.array(dtype=float), amp: wp.array(dtype=wp.vec3), s: wp.array(dtype=wp.vec3),
          p: wp.array(dtype=float), count: wp.array(dtype=int)):
        t = wp.tid()
        mat = mats[0]
        o = o_a[t]
        f[t] = F.brdf_eval(mat, o, i_a[t])
        a, l, m = F.slice_lobe(mat, o, 0)
        axis[t] = a
        lam[t] = l
        amp[t] = m
        d = F.brdf_sample(mat, o, u_a[t])
        s[t] = d
        p[t] = F.brdf_pdf(mat, o, d)
        count[t] = F.slice_lobe_count(mat)

    return k


def _run(F, model, o, i, u):
    table = M.pack_materials([model], n_lobes=1, device="cpu")
    n = len(o)
    outs = [wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=float), wp.zeros(n, dtype=wp.vec3),
            wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=float), wp.zeros(n, dtype=int)]
    args = [table.materials] + [wp.array(x.astype(np.float32), dtype=t) for x, t in
                                ((o, wp.vec3), (i, wp.vec3), (u, wp.vec2))] + outs
    wp.launch(_eval_kernel(F), n, args, device="cpu")
    return table, [x.numpy() for x in outs]


def test_a_model_registered_in_one_place_is_served_by_the_generated_kernel_switch(new_model):
    code = new_model.CODE
    assert B.MODELS[new_model.NAME] is new_model and registry.model_of(code) is new_model
    model = B.make_model(new_model.NAME, kd=[0.1, 0.2, 0.3], ks=[0.5, 0.4, 0.3], n=40.0)
    with pytest.raises(InputError, match="unknown parameter 'm'"):
        B.make_model(new_model.NAME, m=0.2)
    rng = np.random.default_rng(3)
    o, i, u = _dirs(rng, 512), _dirs(rng, 512), rng.random((512, 2))
    ref = _closed_form(40.0, model.ks, model.kd, o, i)
    assert np.allclose(model.eval(o, i), ref, rtol=1e-12, atol=0)  # the numpy side, for the slice reference
    ra, rl, rm = B.slice_lobes_numpy(model, o, 1, "analytic")
    two = {registry.code_of("lambert"), registry.code_of("cook_torrance")}
    for F in (M.material_funcs({code}), M.material_funcs(two | {code}), M.material_funcs(registry.codes())):
        table, (f, axis, lam, amp, s, p, count) = _run(F, model, o, i, u)
        assert table.records[0]["model"] == code and table.records[0]["analytic"] == 1
        np.testing.assert_allclose(f, ref, rtol=2e-3, atol=1e-6 * ref.max())
        assert np.all(count == 1)
        np.testing.assert_allclose(lam, rl[:, 0], rtol=2e-3)
        np.testing.assert_allclose(amp, rm[:, 0], rtol=3e-3, atol=1e-6 * rm.max())
        ok = np.sum(rm[:, 0], -1) > 0
        np.testing.assert_allclose(axis[ok], ra[ok, 0], atol=2e-4)
        # the sample's density is the half-vector density of cos θh = u^{1/(n+2)}
        pref = _pdf_closed_form(40.0, o, s.astype(np.float64))
        np.testing.assert_allclose(p, pref, rtol=3e-3, atol=1e-6 * pref.max())


def test_the_registry_refuses_a_taken_name_or_code_and_a_model_without_kernel():
    class Clash(NormalisedBlinnPhong):
        NAME = "ggx"

    Clash.CODE = _free_code()
    with pytest.raises(ValueError, match="taken"):
        registry.register(Clash)

    class CodeClash(NormalisedBlinnPhong):
        NAME = "code_clash_test"
        CODE = B.MODELS["ward"].CODE

    with pytest.raises(ValueError, match="taken"):
        registry.register(CodeClash)

    class NoKernel(NormalisedBlinnPhong):
        NAME = "no_kernel_test"
        KERNEL = None

    NoKernel.CODE = _free_code()
    with pytest.raises(ValueError, match="KERNEL"):
        registry.register(NoKernel)
    assert "code_clash_test" not in B.MODELS and "no_kernel_test" not in B.MODELS


def test_the_registry_refuses_parameters_that_are_not_declared_params():
    from dataclasses import replace

    class TupleParams(NormalisedBlinnPhong):
        NAME = "tuple_params_test"
        PARAMS = ("kd", "ks", "n")  # names without their declarations

    class DanglingAlternative(NormalisedBlinnPhong):
        NAME = "dangling_alternative_test"
        PARAMS = {"kd": KD, "n_x": replace(KS, instead_of="n_iso")}

    for cls, words in ((TupleParams, "PARAMS must be a dict"), (DanglingAlternative, "instead of 'n_iso'")):
        cls.CODE = _free_code()
        with pytest.raises(ValueError, match=words):
            registry.register(cls)
        assert cls.NAME not in B.MODELS
    with pytest.raises(ValueError, match="kind"):
        Param("colour", "not a kind")


def test_every_shipped_model_declares_its_kernel_and_a_distinct_code():
    assert len({c.CODE for c in B.MODELS.values()}) == len(B.MODELS)
    for name, cls in B.MODELS.items():
        assert cls.NAME == name and registry.BY_CODE[cls.CODE] is cls
        hooks = cls.KERNEL.hooks()
        if cls.is_specular:  # a specular model must say how its lobe is evaluated and sampled
            assert "mo" in hooks and ("ndf" in hooks or "specular" in hooks), name
            assert "sample" in hooks and ("pdf" in hooks or "pdf_h" in hooks), name
    # Oren–Nayar's directional ρd is the only non-constant diffuse part
    assert registry.constant_diffuse([c.CODE for c in B.MODELS.values() if c.NAME != "oren_nayar"])
    assert not registry.constant_diffuse([B.MODELS["oren_nayar"].CODE])


# ---------------------------------------------------------------------------------------------
# capabilities: a diffuse, a specular and an anisotropic model that the rest of the code has never
# heard of, served by what they declare
# ---------------------------------------------------------------------------------------------
class FlatDiffuse(BRDF):
    """``kd/π`` under another name: no specular lobe, no width, no energy normalisation."""

    NAME = "flat_diffuse_test"
    PARAMS = {"kd": KD}
    KERNEL = registry.Kernel()

    def __init__(self, kd=(0.8, 0.8, 0.8)):
        self.kd = as_rgb(kd, "kd")
        self.ks = np.zeros(3)


class WardTwin(B.Ward):
    """Ward's functions (isotropic or anisotropic) under another name and code, declared not
    energy-normalised: its α map sets αx and αy (``ROUGHNESS = "alpha"`` and ``PARAMS`` inherited:
    ``alpha``'s ``Param.kernel`` is (0, 1))."""

    NAME = "ward_twin_test"
    ENERGY_NORMALISED = False


@pytest.fixture
def three_models():
    done = []
    try:
        for cls in (FlatDiffuse, NormalisedBlinnPhong, WardTwin):
            cls.CODE = _free_code()
            registry.register(cls)
            done.append(cls)
        yield FlatDiffuse, NormalisedBlinnPhong, WardTwin
    finally:
        for cls in done:
            registry.unregister(cls)


def test_capabilities_are_the_models_declarations(three_models):
    diffuse, specular, aniso = three_models
    assert diffuse.CODE not in registry.specular_codes() and {specular.CODE, aniso.CODE} <= registry.specular_codes()
    assert not registry.has_specular([B.Lambert.CODE, diffuse.CODE])
    assert registry.has_specular([diffuse.CODE, specular.CODE]) and registry.has_specular([aniso.CODE])
    assert registry.textured_lobe_codes() >= {specular.CODE, aniso.CODE}
    assert diffuse.CODE not in registry.textured_lobe_codes()
    assert registry.roughness_kernel(specular.CODE) == (0,) and registry.roughness_kernel(aniso.CODE) == (0, 1)
    assert registry.roughness_kernel(diffuse.CODE) == ()
    assert registry.constant_diffuse([diffuse.CODE])
    # the texture slots follow the parameters' declarations (warp_sg.shading.surface)
    from warp_sg.shading.surface import SLOT_KD, SLOT_KS, SLOT_P0, SLOT_P1, param_slots

    assert param_slots(specular.NAME, "n") == (SLOT_P0,) and param_slots(specular.NAME, "ks") == (SLOT_KS,)
    assert param_slots(aniso.NAME, "alpha") == (SLOT_P0, SLOT_P1) and param_slots(aniso.NAME, "alpha_y") == (SLOT_P1,)
    assert param_slots(diffuse.NAME, "kd") == (SLOT_KD,) and param_slots(diffuse.NAME, "n") == ()


def test_a_width_that_is_not_a_texturable_kernel_parameter_0_is_refused():
    class NoSuchWidth(NormalisedBlinnPhong):
        NAME = "no_such_width_test"
        ROUGHNESS = "m"

    class DiffuseWidth(FlatDiffuse):
        NAME = "diffuse_width_test"
        PARAMS = {"kd": KD, "s": Param("number", "width", lo=0, texture=True, kernel=(0,))}
        ROUGHNESS = "s"

    for cls, words in ((NoSuchWidth, "ROUGHNESS must name"), (DiffuseWidth, "needs a specular lobe")):
        cls.CODE = _free_code()
        with pytest.raises(ValueError, match=words):
            registry.register(cls)
        assert cls.NAME not in B.MODELS
    with pytest.raises(ValueError, match="kernel parameters"):
        Param("number", "a texturable number that sets no kernel parameter", texture=True)


def test_the_energy_check_reads_energy_normalised(three_models):
    from warp_sg.brdf.energy import energy_excess, normal_incidence_reflectance, normalised_models

    diffuse, specular, aniso = three_models
    assert specular.NAME in normalised_models() and aniso.NAME not in normalised_models()
    assert "ward" in normalised_models() and diffuse.NAME not in normalised_models()
    hot = B.make_model(specular.NAME, kd=[0.5] * 3, ks=[0.7] * 3, n=20.0)
    np.testing.assert_allclose(normal_incidence_reflectance(hot), 1.2)
    assert f"the '{specular.NAME}' material reflects more light" in energy_excess(hot)
    # the same numbers on Ward's lobe: a warning for Ward, none for its twin that does not declare it
    assert energy_excess(B.make_model("ward", kd=[0.5] * 3, ks=[0.7] * 3, alpha=0.2)) is not None
    assert energy_excess(B.make_model(aniso.NAME, kd=[0.5] * 3, ks=[0.7] * 3, alpha=0.2)) is None
    assert energy_excess(B.make_model(diffuse.NAME, kd=[0.9] * 3)) is None
    with pytest.raises(InputError, match="diffuse albedo above 1"):  # kd <= 1 for every model
        B.make_model(diffuse.NAME, kd=[1.5, 0.5, 0.5])


def test_the_albedo_table_follows_the_declared_capabilities(three_models):
    """One table of the three models and Ward: the diffuse model has none; the specular model's
    textured exponent runs the table over the texture's range (row q = the table of a material whose
    exponent is the q-th value); the anisotropic model's α map sets αx and αy (``Roughness.kernel``),
    and its anisotropic table is Ward's own."""
    from warp_sg.brdf.kernel import albedo
    from warp_sg.sg.irradiance import irradiance_table_array

    diffuse, specular, aniso = three_models
    lo, hi = 8.0, 200.0
    q = [float(np.exp(np.log(lo) + k / (albedo.NQ - 1) * np.log(hi / lo))) for k in range(albedo.NQ)]
    a_lo, a_hi = 0.05, 0.5
    qa = [float(np.exp(np.log(a_lo) + k / (albedo.NQ - 1) * np.log(a_hi / a_lo))) for k in range(albedo.NQ)]
    mats = [(B.make_model(diffuse.NAME, kd=[0.5] * 3), None),
            (B.make_model(specular.NAME, n=40.0), (lo, hi)),
            *[(B.make_model(specular.NAME, n=v), None) for v in (q[0], q[3], q[-1])],
            (B.make_model(aniso.NAME, alpha=0.2), (a_lo, a_hi)),
            *[(B.make_model(aniso.NAME, alpha=v), None) for v in (qa[0], qa[5])],
            (B.make_model(aniso.NAME, alpha_x=0.3, alpha_y=0.08), None),
            (B.make_model("ward", alpha_x=0.3, alpha_y=0.08), None)]
    table = M.pack_materials([m for m, _ in mats], n_lobes=1, device="cpu")
    kinds = albedo.layout(table.records, [r for _, r in mats])
    assert [k[0] for k in kinds] == [albedo.KIND_NONE, albedo.KIND_ISO] + [albedo.KIND_ISO] * 3 + [
        albedo.KIND_ISO] * 3 + [albedo.KIND_ANISO] * 2
    assert kinds[1][1] == albedo.NQ and kinds[5][1] == albedo.NQ and kinds[2][1] == 1
    out = albedo.attach(table, [r for _, r in mats], irradiance_table_array("cpu"), "cpu", samples=256).numpy()
    offs = [s.albedo_offset for s in table.structs]
    n = albedo.NMU

    def rows(i, k=0):
        return out[offs[i] + k * n: offs[i] + (k + 1) * n]

    assert table.structs[0].albedo_nq == 0
    assert np.abs(rows(1) - 1.0).max() > 1e-3  # a correction that is not 1 (so the rows below compare something)
    for k, i in ((0, 2), (3, 3), (albedo.NQ - 1, 4)):
        np.testing.assert_allclose(rows(1, k), rows(i), rtol=2e-3, err_msg=f"exponent row {k}")
    for k, i in ((0, 6), (5, 7)):
        np.testing.assert_allclose(rows(5, k), rows(i), rtol=2e-3, err_msg=f"alpha row {k}")
    np.testing.assert_array_equal(out[offs[8]: offs[8] + albedo.NQ * n], out[offs[9]: offs[9] + albedo.NQ * n])


def test_the_renderer_picks_its_kernel_variant_from_the_capabilities(three_models):
    """A scene of the diffuse model alone gets the variant without specular paths (no environment
    specular); one with the specular or the anisotropic model gets them, and its models' switch."""
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.scene.camera import Camera
    from warp_sg.scene.lights import PointLight
    from warp_sg.scene.model import Material, Scene, SceneObject
    from warp_sg.scene.render_settings import RenderSettings
    from warp_sg.shading import kernel as S

    diffuse, specular, aniso = three_models
    for cls, params, spec in ((diffuse, {"kd": [0.5] * 3}, False), (specular, {"n": 30.0}, True),
                              (aniso, {"alpha_x": 0.3, "alpha_y": 0.1}, True)):
        scene = Scene(camera=Camera(origin=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fov=30.0, width=8, height=8),
                      objects=[SceneObject(material="b", primitive="sphere", params={"radius": 0.5})],
                      materials={"b": Material(cls.NAME, params)}, lights=[PointLight(position=(1.0, 2.0, 2.0))],
                      render=RenderSettings(shadows=False))
        f = Renderer(scene, device="cpu").features()
        assert f.models == (cls.CODE,)
        assert f.specular is spec, cls.NAME
        assert (f.env_specular == S.ENV_NONE) if not spec else True
