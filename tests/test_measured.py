"""Measured BRDFs: MERL tables written from known analytic BRDFs are read back and fitted, and the
fit recovers the parameters; the kernel side (merl_eval, measured_mo, slice lobes) matches numpy."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import warp_sg.brdf as B
from warp_sg.brdf import merl
from warp_sg.brdf.kernel import material_wp as M
from warp_sg.brdf.models.measured import (
    D_THETA,
    S_THETA,
    Measured,
    compress_shadowing,
    fit_ndf_sg,
    fit_ndf_sg_anisotropic,
    fresnel_eq14,
    fresnel_normalised,
)
from warp_sg.core.errors import InputError

ETA = 1.33
M_TRUE = 0.18
ALPHA_S = 0.6  # roughness of the Smith shadowing curve
KD = np.array([0.12, 0.06, 0.03])
KS = np.array([0.5, 0.6, 0.7])


def smith_g1(theta, alpha):
    """Smith G1 for Beckmann (rational approximation of Walter et al. 2007)."""
    a = 1.0 / np.maximum(alpha * np.tan(np.minimum(theta, np.pi / 2 - 1e-9)), 1e-12)
    return np.where(a < 1.6, (3.535 * a + 2.181 * a * a) / (1 + 2.276 * a + 2.577 * a * a), 1.0)


def separable_brdf(o, i):
    """kd/π + ks F(i·h)/F(1) S(θo) S(θi) exp(−(θh/m)²) / (π cos θo cos θi): exactly the model."""
    o = np.asarray(o, float)
    i = np.asarray(i, float)
    h = o + i
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    th = np.arctan2(np.hypot(h[..., 0], h[..., 1]), h[..., 2])
    to = np.arctan2(np.hypot(o[..., 0], o[..., 1]), o[..., 2])
    ti = np.arctan2(np.hypot(i[..., 0], i[..., 1]), i[..., 2])
    co = np.maximum(o[..., 2], 1e-9)
    ci = np.maximum(i[..., 2], 1e-9)
    spec = (fresnel_normalised(ETA, np.sum(i * h, -1)) * smith_g1(to, ALPHA_S) * smith_g1(ti, ALPHA_S)
            * np.exp(-(th / M_TRUE) ** 2) / (np.pi * co * ci))
    val = KD / np.pi + KS * spec[..., None]
    return np.where(((o[..., 2] > 0) & (i[..., 2] > 0))[..., None], val, 0.0)


@pytest.fixture(scope="module")
def sep_file(tmp_path_factory):
    p = tmp_path_factory.mktemp("merl") / "separable.binary"
    merl.write_merl(p, merl.tabulate(separable_brdf, below_horizon=-1.0 / 1500))
    return p


@pytest.fixture(scope="module")
def sep(sep_file):
    return B.make_model("measured", file=str(sep_file), lobes=1)


@pytest.fixture(scope="module")
def ct_measured():
    ct = B.CookTorrance(kd=(0.1, 0.05, 0.02), ks=(20.0, 25.0, 30.0), m=0.2, fresnel={"eta": ETA})
    return ct, Measured(table=merl.tabulate(ct), lobes=2, cache=False)


def test_fit_recovers_parameters_of_a_separable_microfacet_brdf(sep):
    np.testing.assert_allclose(sep.kd, KD, rtol=0.02, atol=2e-3)
    np.testing.assert_allclose(sep.ks, KS, rtol=0.02)
    # tabulated NDF and shadowing
    supported = sep.ndf_support > 1e-6 * sep.ndf_support.max()
    assert np.abs(sep.ndf_table - np.exp(-(D_THETA / M_TRUE) ** 2))[supported].max() < 0.02
    good = S_THETA < np.radians(80)
    assert np.abs(sep.shadowing - smith_g1(S_THETA, ALPHA_S))[good].max() < 0.02
    # one SG lobe: λ close to the nonlinear fit of exp(−(θ/m)²) (supplement Fig. 2), m recovered
    lam_ct = B.CookTorrance(m=M_TRUE).ndf_sg(1, "fit")[1][0]
    assert sep.lobe_sharpness[0] == pytest.approx(lam_ct, rel=0.03)
    assert sep.equivalent_m == pytest.approx(M_TRUE, rel=0.03)
    e = sep.errors()
    assert e["microfacet"] < 1e-3
    assert e["sg"] < 5e-3
    assert e["sg_pca"] < 5e-3


def test_cook_torrance_table_is_fitted_with_small_eq11_error(ct_measured):
    ct, meas = ct_measured
    F1 = fresnel_eq14(ETA, 1.0)
    np.testing.assert_allclose(meas.ks / F1, ct.ks, rtol=0.03)  # ks is relative to F(1)
    np.testing.assert_allclose(meas.kd, ct.kd, atol=0.01)
    assert meas.equivalent_m == pytest.approx(0.2, rel=0.05)
    e = meas.errors()
    assert e["microfacet"] < 0.01
    assert e["sg_pca"] < 0.01
    # two lobes: sorted by increasing sharpness and at least as good as one on the NDF table
    assert len(meas.lobe_sharpness) == 2 and np.all(np.diff(meas.lobe_sharpness) > 0)


def test_two_lobes_fit_a_two_scale_ndf_better_than_one():
    D = 0.7 * np.exp(-300 * (1 - np.cos(D_THETA))) + 0.3 * np.exp(-20 * (1 - np.cos(D_THETA)))
    w = 2 * np.pi * np.sin(D_THETA) * np.gradient(D_THETA)
    res = []
    for k in (1, 2):
        ax, lam, mu = fit_ndf_sg(D_THETA, D, w, k)
        approx = (mu * np.exp(-lam * (1 - np.cos(D_THETA))[:, None])).sum(-1)
        res.append(np.sum(w * (D - approx) ** 2) / np.sum(w * D * D))
    assert res[1] < 1e-8 < res[0]
    np.testing.assert_allclose(lam, [20, 300], rtol=1e-3)
    np.testing.assert_allclose(mu, [0.3, 0.7], rtol=1e-3)


def test_anisotropic_ndf_is_fitted_by_lbfgsb_lobes():
    ward = B.Ward(alpha_x=0.1, alpha_y=0.3)
    ax, lam, mu = fit_ndf_sg_anisotropic(ward.ndf, 5)
    h = np.random.default_rng(0).normal(size=(4000, 3))
    h[:, 2] = np.abs(h[:, 2]) * 6
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    D = ward.ndf(h)
    approx = (mu * np.exp(-lam * (1 - h @ ax.T))).sum(-1)
    ax1, lam1, mu1 = fit_ndf_sg_anisotropic(ward.ndf, 1)
    approx1 = (mu1 * np.exp(-lam1 * (1 - h @ ax1.T))).sum(-1)
    e5 = np.sum((D - approx) ** 2) / np.sum(D * D)
    e1 = np.sum((D - approx1) ** 2) / np.sum(D * D)
    assert e5 < 0.02 and e5 < 0.3 * e1
    # lobes spread along the wide (y) axis
    assert np.ptp(ax[:, 1]) > 5 * np.ptp(ax[:, 0])


def test_shadowing_pca_compresses_90_to_8_dimensions():
    S = smith_g1(S_THETA, 0.35)
    coeffs, rec = compress_shadowing(S, 8)
    assert coeffs.shape == (8,)
    assert np.abs(rec - S).max() < 5e-3
    _, rec2 = compress_shadowing(S, 2)
    assert np.abs(rec2 - S).max() > np.abs(rec - S).max()


def test_fit_is_cached_by_content(sep_file, cache_dir):
    a = Measured(file=sep_file, lobes=1)
    files = list(cache_dir.rglob("*.npz"))
    assert len(files) == 1
    b = Measured(file=sep_file, lobes=1)
    np.testing.assert_array_equal(a.lobe_sharpness, b.lobe_sharpness)
    assert len(list(cache_dir.rglob("*.npz"))) == 1
    c = Measured(file=sep_file, lobes=2)  # the SG fit is redone, the microfacet fit is reused
    assert len(list(cache_dir.rglob("*.npz"))) == 1 and len(c.lobe_sharpness) == 2
    np.testing.assert_array_equal(a.shadowing, c.shadowing)


def test_make_model_validates_measured_parameters(sep_file, tmp_path):
    with pytest.raises(InputError, match="lobes"):
        B.make_model("measured", file=str(sep_file), lobes=0)
    with pytest.raises(InputError, match="did you mean"):
        B.make_model("measured", file=str(sep_file), lobse=1)
    with pytest.raises(InputError, match="not found"):
        B.make_model("measured", file=str(tmp_path / "missing.binary"))


@wp.kernel
def _measured_kernel(mats: wp.array(dtype=M.Material), o: wp.array(dtype=wp.vec3), i: wp.array(dtype=wp.vec3),
                     ev: wp.array(dtype=wp.vec3), mo: wp.array(dtype=wp.vec3), ndf: wp.array(dtype=float),
                     axis: wp.array(dtype=wp.vec3), lam: wp.array(dtype=float), amp: wp.array(dtype=wp.vec3)):
    t = wp.tid()
    mat = mats[0]
    ev[t] = M.brdf_eval(mat, o[t], i[t])
    mo[t] = M.brdf_mo(mat, o[t], i[t])
    ndf[t] = M.brdf_ndf(mat, wp.normalize(o[t] + i[t]))
    a, l, m = M.slice_lobe(mat, o[t], 0)
    axis[t] = a
    lam[t] = l
    amp[t] = m


def test_kernel_material_matches_numpy_model(device, sep):
    table = M.pack_materials([sep], device=device)
    rng = np.random.default_rng(1)
    n = 2000
    v = rng.normal(size=(2, n, 3))
    v[..., 2] = np.abs(v[..., 2]) + 0.1
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    o, i = v
    arrs = [wp.zeros(n, dtype=t, device=device) for t in (wp.vec3, wp.vec3, float, wp.vec3, float, wp.vec3)]
    wp.launch(_measured_kernel, n, inputs=[table.materials, wp.array(o.astype(np.float32), dtype=wp.vec3, device=device),
                                           wp.array(i.astype(np.float32), dtype=wp.vec3, device=device), *arrs],
              device=device)
    ev, mo, ndf, axis, lam, amp = (a.numpy() for a in arrs)
    same = merl.merl_index(o, i) == merl.merl_index(o.astype(np.float32).astype(float), i.astype(np.float32).astype(float))
    ref = sep.eval(o, i)
    close = np.isclose(ev, ref, rtol=1e-4, atol=1e-6).all(-1)
    assert close[same].mean() > 0.99
    np.testing.assert_allclose(mo, sep.ks * sep.mo(o, i), rtol=2e-3, atol=1e-6)
    np.testing.assert_allclose(ndf, sep.ndf(B.base.half_vector(o, i)), rtol=1e-3, atol=1e-6)
    ax_np, lam_np, amp_np = B.slice_lobes_numpy(sep, o, 1, "fit")
    np.testing.assert_allclose(lam, lam_np[:, 0], rtol=1e-3)
    np.testing.assert_allclose(amp, amp_np[:, 0], rtol=3e-3, atol=1e-6)
    np.testing.assert_allclose(axis, ax_np[:, 0], atol=1e-4)
