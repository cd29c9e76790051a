"""Kernel-side BRDF (material_wp) against the numpy models: brdf_eval, brdf_mo, slice_lobe,
and the sampling pair brdf_sample/brdf_pdf (pdf integrates to ≤ 1 and matches the histogram)."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import warp_sg.brdf as B
from warp_sg.brdf.kernel import material_wp as M


def all_models():
    return [
        B.Lambert(kd=[0.2, 0.5, 0.8]),
        B.OrenNayar(kd=[0.7, 0.6, 0.5], sigma=0.4),
        B.Phong(kd=0.1, ks=[0.5, 0.6, 0.7], n=30),
        B.BlinnPhong(kd=0.2, ks=0.5, n=80),
        B.CookTorrance(kd=0.1, ks=1.0, m=0.25, fresnel="copper"),
        B.CookTorrance(ks=1.0, m=0.08, fresnel={"schlick": 0.04}),
        B.TorranceSparrow(kd=0.05, ks=[0.9, 0.8, 0.7], m=0.3, fresnel={"eta": 1.5}),
        B.Ward(kd=0.1, ks=0.6, alpha=0.2),
        B.Ward(ks=0.6, alpha_x=0.1, alpha_y=0.35),
        B.AshikhminShirley(kd=0.1, ks=0.8, nu=50, nv=500, fresnel={"eta": [0.2, 0.9, 1.1], "k": [3.0, 2.5, 2.0]}, lobes=5),
        B.AshikhminShirley(ks=0.8, nu=300, nv=40, fresnel="gold"),
        B.Lafortune(kd=0.2, ks=0.7, lobes=[{"cx": -1, "cy": -1, "cz": 1, "n": 15},
                                           {"cx": 0.6, "cy": 0.6, "cz": 0.8, "n": 4}]),
    ]


@wp.kernel
def _eval_kernel(mats: wp.array(dtype=M.Material), mid: wp.array(dtype=int), o: wp.array(dtype=wp.vec3),
                 i: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3), mo: wp.array(dtype=wp.vec3)):
    t = wp.tid()
    mat = mats[mid[t]]
    out[t] = M.brdf_eval(mat, o[t], i[t])
    mo[t] = M.brdf_mo(mat, o[t], i[t])


@wp.kernel
def _slice_kernel(mats: wp.array(dtype=M.Material), mid: int, o: wp.array(dtype=wp.vec3),
                  axis: wp.array2d(dtype=wp.vec3), lam: wp.array2d(dtype=float), amp: wp.array2d(dtype=wp.vec3)):
    t = wp.tid()
    mat = mats[mid]
    for k in range(M.slice_lobe_count(mat)):
        a, l, m = M.slice_lobe(mat, o[t], k)
        axis[t, k] = a
        lam[t, k] = l
        amp[t, k] = m


@wp.kernel
def _sample_kernel(mats: wp.array(dtype=M.Material), mid: int, o: wp.vec3, u: wp.array(dtype=wp.vec2),
                   out: wp.array(dtype=wp.vec3), pdf: wp.array(dtype=float)):
    t = wp.tid()
    mat = mats[mid]
    d = M.brdf_sample(mat, o, u[t])
    out[t] = d
    pdf[t] = M.brdf_pdf(mat, o, d)


def random_dirs(rng, n, upper=True):
    v = rng.normal(size=(n, 3))
    if upper:
        v[:, 2] = np.abs(v[:, 2]) + 1e-3
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_kernel_brdf_eval_matches_numpy_for_every_model(device):
    models = all_models()
    table = M.pack_materials(models, 1, device)
    rng = np.random.default_rng(1)
    n = 400
    o = random_dirs(rng, n)
    i = random_dirs(rng, n)
    # half of the pairs near the specular configuration, where the lobes live
    i[: n // 2] = o[: n // 2] * [-1, -1, 1] + 0.05 * rng.normal(size=(n // 2, 3))
    i[: n // 2, 2] = np.abs(i[: n // 2, 2])
    i /= np.linalg.norm(i, axis=1, keepdims=True)
    for k, model in enumerate(models):
        mid = wp.array(np.full(n, k, np.int32), dtype=int, device=device)
        out = wp.zeros(n, dtype=wp.vec3, device=device)
        mo = wp.zeros(n, dtype=wp.vec3, device=device)
        wp.launch(_eval_kernel, n, inputs=[table.materials, mid, wp.array(o.astype(np.float32), dtype=wp.vec3, device=device),
                                           wp.array(i.astype(np.float32), dtype=wp.vec3, device=device), out, mo], device=device)
        # compare at the float32-rounded directions
        o32 = o.astype(np.float32).astype(np.float64)
        i32 = i.astype(np.float32).astype(np.float64)
        ref = model.eval(o32, i32)
        got = out.numpy()
        assert np.all(np.isfinite(got))
        scale = np.max(np.abs(ref)) + 1e-30
        np.testing.assert_allclose(got, ref, rtol=2e-3, atol=2e-4 * scale, err_msg=type(model).__name__)
        if model.is_specular and model.NAME not in ("lafortune",):
            mref = model.ks * model.mo(o32, i32)
            np.testing.assert_allclose(mo.numpy(), mref, rtol=2e-3, atol=1e-5 * (np.max(mref) + 1e-30),
                                       err_msg=type(model).__name__)


@pytest.mark.parametrize("method, n_lobes", [("analytic", 1), ("fit", 1), ("analytic", 2)])
def test_kernel_slice_lobes_match_numpy(method, n_lobes):
    device = "cpu"
    models = [m for m in all_models() if m.is_specular]
    if method == "fit" or n_lobes > 1:  # keep the L-BFGS-B anisotropic fits small
        models = [m for m in models if not getattr(m, "own_lobes", None) and m.NAME != "ward"] + [
            B.AshikhminShirley(ks=0.8, nu=30, nv=300, fresnel="gold", lobes=3)]
    table = M.pack_materials(models, n_lobes, device, method=method)
    rng = np.random.default_rng(2)
    n = 64
    o = random_dirs(rng, n)
    for k, model in enumerate(models):
        K = table.records[k]["lobe_count"]
        axis = wp.zeros((n, K), dtype=wp.vec3)
        lam = wp.zeros((n, K), dtype=float)
        amp = wp.zeros((n, K), dtype=wp.vec3)
        wp.launch(_slice_kernel, n, inputs=[table.materials, k, wp.array(o.astype(np.float32), dtype=wp.vec3), axis, lam, amp])
        ra, rl, rm = B.slice_lobes_numpy(model, o.astype(np.float32).astype(np.float64), n_lobes, method)
        assert ra.shape[-2] == K
        ok = np.sum(rm, -1) > 0
        np.testing.assert_allclose(lam.numpy(), rl, rtol=2e-3, err_msg=type(model).__name__)
        np.testing.assert_allclose(amp.numpy(), rm, rtol=3e-3, atol=1e-6 * np.max(rm), err_msg=type(model).__name__)
        np.testing.assert_allclose(axis.numpy()[ok], ra[ok], atol=2e-4, err_msg=type(model).__name__)


@pytest.mark.parametrize("index", [2, 3, 4, 6, 7, 8, 9, 10, 11])
def test_kernel_sampling_pdf_is_a_density_matching_the_samples(index):
    """E[1/pdf · 1{upper}] over samples = upper-hemisphere measure of the support ≤ 2π, and
    ∫ pdf dω over the sphere (quadrature) ≤ 1 with equality up to the lost below-horizon mass."""
    models = all_models()
    table = M.pack_materials(models, 1, "cpu")
    o = np.array([0.4, 0.2, 0.0])
    o[2] = np.sqrt(1 - 0.2)
    n = 20000
    rng = np.random.default_rng(3)
    u = rng.random((n, 2)).astype(np.float32)
    out = wp.zeros(n, dtype=wp.vec3)
    pdf = wp.zeros(n, dtype=float)
    wp.launch(_sample_kernel, n, inputs=[table.materials, index, wp.vec3(*o), wp.array(u, dtype=wp.vec2), out, pdf])
    d = out.numpy()
    p = pdf.numpy()
    assert np.all(np.isfinite(d)) and np.all(np.isfinite(p))
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-4)
    assert np.all(p[np.linalg.norm(d, axis=1) > 0] >= 0)
    # importance-sampled specular albedo agrees with brute-force quadrature of the same integral
    model = models[index]
    t = (np.arange(500) + 0.5) / 500 * np.pi / 2
    ph = (np.arange(1000) + 0.5) / 1000 * 2 * np.pi
    T, P = np.meshgrid(t, ph, indexing="ij")
    I = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
    w = np.sin(T) * (np.pi / 2 / 500) * (2 * np.pi / 1000)
    spec_only = np.sum(model.ks[1] * model.specular(o, I)[..., 1] * I[..., 2] * w)
    good = p > 0
    fs = model.ks[1] * model.specular(o, d.astype(np.float64))[:, 1] * np.maximum(d[:, 2], 0)
    est_s = np.sum(fs[good] / p[good]) / n
    assert est_s == pytest.approx(spec_only, rel=0.01), (est_s, spec_only)


@wp.kernel
def _finite_kernel(mats: wp.array(dtype=M.Material), dirs: wp.array(dtype=wp.vec3), u: wp.array(dtype=wp.vec2),
                   out: wp.array3d(dtype=float)):
    a, b, c = wp.tid()
    mat = mats[a]
    o = dirs[b]
    i = dirs[c]
    f = M.brdf_eval(mat, o, i)
    mo = M.brdf_mo(mat, o, i)
    s = float(0.0)
    for k in range(M.slice_lobe_count(mat)):
        ax, l, m = M.slice_lobe(mat, o, k)
        s += ax[0] + ax[1] + ax[2] + l + m[0] + m[1] + m[2]
    d = M.brdf_sample(mat, o, u[c])
    p = M.brdf_pdf(mat, o, d) + M.brdf_pdf(mat, o, i)
    out[a, b, c] = f[0] + f[1] + f[2] + mo[0] + mo[1] + mo[2] + s + d[0] + d[1] + d[2] + p


def test_kernel_functions_stay_finite_at_grazing_and_extreme_roughness():
    models = [
        B.CookTorrance(ks=1, m=1e-4, fresnel="copper"), B.CookTorrance(ks=1, m=3.0, fresnel={"eta": 1.5}),
        B.TorranceSparrow(ks=1, m=1e-4), B.Ward(ks=1, alpha=1e-4), B.Ward(ks=1, alpha_x=1e-3, alpha_y=0.8),
        B.BlinnPhong(ks=1, n=1e7), B.Phong(ks=1, n=1e7), B.Phong(ks=1, n=0.0),
        B.AshikhminShirley(ks=1, nu=1e6, nv=1.0, fresnel={"schlick": 0.04}), B.AshikhminShirley(ks=1, nu=0, nv=0),
        B.OrenNayar(kd=1, sigma=0.0), B.Lafortune(lobes=[{"cx": -1, "cy": -1, "cz": 1, "n": 1e4}]),
    ]
    table = M.pack_materials(models, 1, "cpu")
    g = np.array([0.0, 1e-7, 1e-4, 0.2])
    th = np.pi / 2 - g
    base = np.stack([np.sin(th), 0 * th, np.cos(th)], -1)
    dirs = np.concatenate([base, base * [-1, 1, 1], base[:, [1, 0, 2]], [[0, 0, 1.0], [0.6, 0, 0.8]]])
    u = np.array([[0, 0], [0.999999, 0.999999], [0.5, 0.25], [1e-7, 0.5]] * 4 + [[0.3, 0.3], [0.7, 0.1]], np.float32)
    out = wp.zeros((len(models), len(dirs), len(dirs)), dtype=float)
    wp.launch(_finite_kernel, out.shape, inputs=[table.materials, wp.array(dirs.astype(np.float32), dtype=wp.vec3),
                                                 wp.array(u, dtype=wp.vec2), out])
    v = out.numpy()
    bad = np.argwhere(~np.isfinite(v))
    assert len(bad) == 0, [(type(models[a]).__name__, dirs[b], dirs[c]) for a, b, c in bad[:5]]
