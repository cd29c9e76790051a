"""Exact BRDF models: reciprocity, non-negativity, energy conservation (albedo ≤ 1 by quadrature)
for the normalised models, Fresnel formulas, finiteness at grazing angles and near-zero roughness,
parameter validation (InputError naming the parameter, closest-name suggestions)."""
from __future__ import annotations

import numpy as np
import pytest

import warp_sg.brdf as B
from warp_sg.brdf.fresnel import Conductor, Dielectric, Schlick, parse_fresnel
from warp_sg.core.errors import InputError


def models():
    return {
        "lambert": B.Lambert(kd=[0.2, 0.5, 0.9]),
        "oren_nayar": B.OrenNayar(kd=[0.9, 0.5, 0.2], sigma=0.5),
        "phong": B.Phong(kd=0.1, ks=0.8, n=20),
        "blinn_phong": B.BlinnPhong(kd=0.1, ks=0.8, n=60),
        "cook_torrance": B.CookTorrance(kd=0.1, ks=1.0, m=0.2, fresnel="gold"),
        "torrance_sparrow": B.TorranceSparrow(kd=0.1, ks=0.8, m=0.3, fresnel={"eta": 1.5}),
        "ward": B.Ward(kd=0.1, ks=0.5, alpha=0.15),
        "ward_aniso": B.Ward(kd=0.1, ks=0.5, alpha_x=0.08, alpha_y=0.3),
        "ashikhmin_shirley": B.AshikhminShirley(kd=0.1, ks=0.8, nu=20, nv=400, fresnel={"schlick": 0.05}),
        "lafortune": B.Lafortune(kd=0.2, ks=0.5, lobes=[{"cx": -1, "cy": -1, "cz": 1, "n": 12},
                                                        {"cx": 0.8, "cy": 0.8, "cz": 0.9, "n": 3}]),
    }


def rand_dirs(rng, n):
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.mark.parametrize("name", list(models()))
def test_reciprocity_and_non_negativity(name):
    m = models()[name]
    rng = np.random.default_rng(0)
    o, i = rand_dirs(rng, 3000), rand_dirs(rng, 3000)
    i[:1000] = o[:1000] * [-1, -1, 1] + 0.1 * rng.normal(size=(1000, 3))  # near the mirror direction
    i[:1000, 2] = np.abs(i[:1000, 2])
    i /= np.linalg.norm(i, axis=1, keepdims=True)
    f, g = m.eval(o, i), m.eval(i, o)
    assert f.shape == (3000, 3)
    assert np.all(np.isfinite(f)) and np.all(f >= 0)
    np.testing.assert_allclose(f, g, rtol=1e-10, atol=1e-14)
    # zero below the horizon
    ib = i * [1, 1, -1]
    assert np.all(m.eval(o, ib) == 0) and np.all(m.eval(ib, o) == 0)


def albedo(model, theta_o, n_t=160, n_p=160):
    """∫ ρ(o, i) cos θi dωi by Gauss–Legendre in cos θi × midpoint in φ (vectorised)."""
    o = np.array([np.sin(theta_o), 0.0, np.cos(theta_o)])
    x, wx = np.polynomial.legendre.leggauss(n_t)
    c, wc = 0.5 * (x + 1), 0.5 * wx
    ph = (np.arange(n_p) + 0.5) / n_p * 2 * np.pi
    C, P = np.meshgrid(c, ph, indexing="ij")
    S = np.sqrt(1 - C**2)
    I = np.stack([S * np.cos(P), S * np.sin(P), C], -1)
    return np.sum(model.eval(o, I) * (C * wc[:, None] * 2 * np.pi / n_p)[..., None], axis=(0, 1))


def test_lambert_albedo_is_kd():
    np.testing.assert_allclose(albedo(B.Lambert(kd=[0.2, 0.5, 0.9]), 0.7, 16, 16), [0.2, 0.5, 0.9], rtol=1e-9)


@pytest.mark.parametrize("model", [
    B.OrenNayar(kd=1.0, sigma=1.0),
    B.Phong(ks=1.0, n=1.0),
    B.Phong(ks=1.0, n=40.0),
    B.TorranceSparrow(ks=1.0, m=0.2),
    B.TorranceSparrow(ks=1.0, m=0.7),
    B.AshikhminShirley(ks=1.0, nu=10, nv=100, fresnel={"schlick": 1.0}),
    B.Ward(ks=1.0, alpha=0.2),
], ids=lambda m: repr(m)[:40])
def test_normalised_models_conserve_energy(model):
    for t in (0.0, 0.8, 1.5):
        a = albedo(model, t)
        assert np.all(a <= 1.0 + 2e-3), (t, a)
        assert np.all(a > 0)


def test_phong_normal_incidence_albedo_is_one_and_blinn_phong_supplement_normalisation():
    assert albedo(B.Phong(ks=1.0, n=30), 0.0)[0] == pytest.approx(1.0, rel=1e-3)
    # supplement eq. 7 normalisation: BP albedo at normal incidence → 4 for large n (documented)
    a = albedo(B.BlinnPhong(ks=1.0, n=2000), 0.0, n_t=1024, n_p=8)[0]
    assert a == pytest.approx(4.0, rel=0.01)


def test_fresnel_formulas():
    c = np.linspace(0, 1, 11)
    # normal incidence closed forms
    assert Dielectric(1.5)(1.0)[0] == pytest.approx(0.04, rel=1e-9)
    e, k = 0.617, 2.630
    assert Conductor(e, k)(1.0)[0] == pytest.approx(((e - 1) ** 2 + k**2) / ((e + 1) ** 2 + k**2), rel=1e-9)
    # Cook–Torrance form (eq. 14) equals the textbook r∥, r⊥ form for dielectrics
    eta = 1.33
    ci = c[1:]
    st = np.sqrt(1 - ci**2) / eta
    ct = np.sqrt(1 - st**2)
    rpar = (eta * ci - ct) / (eta * ci + ct)
    rper = (ci - eta * ct) / (ci + eta * ct)
    np.testing.assert_allclose(Dielectric(eta)(ci)[:, 0], 0.5 * (rpar**2 + rper**2), rtol=1e-9)
    # k → 0: the lecture's conductor formula (an approximation) agrees with the dielectric at
    # normal incidence and stays within a few percent (absolute) elsewhere
    np.testing.assert_allclose(Conductor(1.5, 0.0)(1.0), Dielectric(1.5)(1.0), rtol=1e-12)
    assert np.max(np.abs(Conductor(1.5, 0.0)(ci) - Dielectric(1.5)(ci))) < 0.1
    # grazing: F → 1
    for f in (Dielectric(1.5), Conductor(0.2, 3.0), Schlick(0.04)):
        np.testing.assert_allclose(f(0.0), 1.0, atol=1e-12)
    # total internal reflection (η < 1) is 1, everything in [0, 1]
    assert np.all(Dielectric(0.7)(0.1) == 1.0)
    for name in ("gold", "silver", "copper", "steel", "glass", "water", "diamond"):
        v = parse_fresnel(name)(c)
        assert np.all((v >= 0) & (v <= 1))


@pytest.mark.parametrize("value, where", [
    ("coper", "copper"), ({"schlik": 0.04}, "schlick"), ({"eta": -1.0}, "fresnel.eta"),
    ({"schlick": 2.0}, "fresnel.schlick"), (3, "fresnel"), ({"eta": [1, 2]}, "fresnel.eta"),
])
def test_parse_fresnel_rejects_bad_input(value, where):
    with pytest.raises(InputError, match=where):
        parse_fresnel(value)


def test_make_model_validates_names_and_values():
    m = B.make_model("cook_torrance", kd=[0.1, 0.1, 0.1], ks=1.0, m=0.2, fresnel="copper")
    assert isinstance(m, B.CookTorrance)
    with pytest.raises(InputError, match="did you mean 'roughness'|did you mean 'm'"):
        B.make_model("cook_torrance", mm=0.2)
    with pytest.raises(InputError, match="did you mean 'blinn_phong'"):
        B.make_model("blinn_phon", n=10)
    with pytest.raises(InputError, match="m"):
        B.make_model("cook_torrance", m=-0.1)
    with pytest.raises(InputError, match="alpha"):
        B.make_model("ward", alpha=-1.0)
    with pytest.raises(InputError, match="kd"):
        B.make_model("lambert", kd=[0.1, 0.2])
    with pytest.raises(InputError, match="lobes"):
        B.make_model("ashikhmin_shirley", nu=10, nv=100, lobes=4)
    with pytest.raises(InputError, match=r"lobes\[0\]"):
        B.make_model("lafortune", lobes=[{"cx": 1, "cy": 1, "cz": 1}])
    with pytest.raises(InputError, match="sigma"):
        B.make_model("oren_nayar", sigma=-0.1)
    assert set(B.MODELS) == {"lambert", "phong", "blinn_phong", "cook_torrance", "torrance_sparrow", "ward",
                             "ashikhmin_shirley", "oren_nayar", "lafortune", "measured", "ggx"}


@pytest.mark.parametrize("model", [
    B.CookTorrance(ks=1, m=1e-4, fresnel="copper"), B.TorranceSparrow(ks=1, m=1e-4), B.Ward(ks=1, alpha=1e-4),
    B.Ward(ks=1, alpha_x=1e-4, alpha_y=0.5), B.BlinnPhong(ks=1, n=1e7), B.Phong(ks=1, n=1e7),
    B.AshikhminShirley(ks=1, nu=1e7, nv=10), B.OrenNayar(kd=1, sigma=0.0), B.CookTorrance(ks=1, m=3.0),
], ids=lambda m: repr(m)[:40])
def test_grazing_and_near_zero_roughness_stay_finite(model):
    g = [0.0, 1e-9, 1e-4, 0.3, 1.0]
    th = np.pi / 2 - np.array(g)
    o = np.stack([np.sin(th), 0 * th, np.cos(th)], -1)
    dirs = np.concatenate([o, o * [-1, 1, 1], o[:, [1, 0, 2]], [[0, 0, 1.0]]])
    O, I = np.broadcast_arrays(dirs[:, None], dirs[None])
    v = model.eval(O, I)
    assert np.all(np.isfinite(v)) and np.all(v >= 0)
    if model.is_specular:
        for n, meth in ((1, "analytic"),):
            a, l, mu = model.ndf_sg(n, meth)
            assert np.all(np.isfinite(a)) and np.all(np.isfinite(l)) and np.all(np.isfinite(mu))
        sl = B.slice_lobes_numpy(model, dirs)
        for x in sl:
            assert np.all(np.isfinite(x))
