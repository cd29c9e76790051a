"""Sampling routines of the Monte-Carlo reference: environment CDF, cones, MIS weights."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_sg.groundtruth import sampling as S
from warp_sg.scene import envmap as em


@wp.kernel
def _env_draw(env: S.EnvSampler, seed: int, dirs: wp.array(dtype=wp.vec3), est: wp.array(dtype=wp.vec3),
              pdf_out: wp.array(dtype=float)):
    tid = wp.tid()
    st = wp.rand_init(seed, tid)
    d = S.env_sample(env, wp.randf(st), wp.randf(st), wp.randf(st), wp.randf(st))
    p = S.env_pdf(env, d)
    dirs[tid] = d
    pdf_out[tid] = p
    est[tid] = S.env_radiance(env, d) / p


@wp.kernel
def _cone_draw(axis: wp.vec3, omc: float, seed: int, dirs: wp.array(dtype=wp.vec3), inside: wp.array(dtype=int)):
    tid = wp.tid()
    st = wp.rand_init(seed, tid)
    d = S.cone_sample(axis, omc, wp.randf(st), wp.randf(st))
    dirs[tid] = d
    inside[tid] = wp.where(S.in_cone(axis, omc * 1.0001 + 1.0e-7, d), 1, 0)


@wp.kernel
def _sphere_hit(c: wp.array(dtype=wp.vec3), r: wp.array(dtype=float), d: wp.array(dtype=wp.vec3),
                out: wp.array(dtype=float)):
    tid = wp.tid()
    out[tid] = S.sphere_hit_distance(c[tid], r[tid], d[tid])


@wp.kernel
def _mis(a: wp.array(dtype=float), b: wp.array(dtype=float), out: wp.array(dtype=float)):
    tid = wp.tid()
    out[tid] = S.power_heuristic(a[tid], b[tid])


def _random_env(rng, h=16, w=32):
    env = rng.gamma(0.5, 1.0, size=(h, w, 3))
    env[3, 5] = 200.0  # a sun
    env[10:, :] *= 0.01
    return env


def test_env_sampling_estimates_the_exact_integral_of_a_piecewise_constant_map(device):
    rng = np.random.default_rng(1)
    env = _random_env(rng)
    h, w, _ = env.shape
    exact = np.sum(env * em.row_solid_angles(h, w)[:, None, None], axis=(0, 1))
    sampler = S.make_env_sampler(env, 2.0, device)
    n = 200_000
    dirs = wp.empty(n, dtype=wp.vec3, device=device)
    est = wp.empty(n, dtype=wp.vec3, device=device)
    pdf = wp.empty(n, dtype=float, device=device)
    wp.launch(_env_draw, dim=n, inputs=[sampler, 7, dirs, est, pdf], device=device)
    e = est.numpy().astype(np.float64)
    mean = e.mean(0)
    se = e.std(0) / np.sqrt(n)
    assert np.all(np.abs(mean - 2.0 * exact) < 4 * se + 1e-4 * exact), (mean, 2 * exact, se)
    # the strategy is nearly proportional to luminance: tiny relative stderr
    assert np.all(se / mean < 0.02)
    # sampled texel frequencies follow the table probabilities
    _, _, _, tpdf = S.env_tables(env, 2.0)
    prob = tpdf * em.row_solid_angles(h, w)[:, None]
    r, c = em.dir_to_texel(dirs.numpy(), h, w)
    counts = np.bincount(r * w + c, minlength=h * w).reshape(h, w)
    expected = prob * n
    big = expected > 50
    z = (counts[big] - expected[big]) / np.sqrt(expected[big])
    assert np.mean(z ** 2) < 2.0
    # pdf returned at the sample equals the table's texel pdf (but for float32 ties on texel edges)
    agree = np.isclose(pdf.numpy(), tpdf[r, c], rtol=1e-5)
    assert agree.mean() > 1 - 1e-4


def test_env_tables_pdf_integrates_to_one_and_solid_angles_to_four_pi():
    rng = np.random.default_rng(2)
    env = _random_env(rng, 9, 20)
    _, marg, cond, tpdf = S.env_tables(env)
    om = em.row_solid_angles(9, 20)
    assert abs(om.sum() * 20 - 4 * np.pi) < 1e-12
    assert abs(np.sum(tpdf * om[:, None]) - 1.0) < 1e-12
    assert marg[0] == 0 and marg[-1] == 1 and np.all(np.diff(marg) > 0)
    assert np.all(np.diff(cond, axis=1) > 0)


def test_env_sampler_rejects_a_map_with_wrong_shape():
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        S.env_tables(np.zeros((4, 8, 4)))


@pytest.mark.parametrize("sin2", [1e-10, 1e-4, 0.25, 1.0])
def test_cone_samples_stay_in_the_cone_and_have_the_uniform_mean_cosine(device, sin2):
    omc = S.one_minus_cos_from_sin2(sin2)
    axis = np.array([0.3, -0.5, 0.8])
    axis /= np.linalg.norm(axis)
    n = 50_000
    dirs = wp.empty(n, dtype=wp.vec3, device=device)
    inside = wp.empty(n, dtype=int, device=device)
    wp.launch(_cone_draw, dim=n, inputs=[wp.vec3(*axis), float(omc), 3, dirs, inside], device=device)
    d = dirs.numpy().astype(np.float64)
    assert inside.numpy().all()
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-5)
    # E[1 - cos] = omc / 2 for a uniform cone
    one_minus_cos = 0.5 * np.sum((d - axis) ** 2, axis=1)
    m = one_minus_cos.mean()
    se = one_minus_cos.std() / np.sqrt(n)
    assert abs(m - omc / 2) < 5 * se + 1e-6 * omc + 2e-8


def test_one_minus_cos_is_accurate_for_tiny_cones():
    assert S.one_minus_cos_from_sin2(1e-12) == pytest.approx(5e-13, rel=1e-9)
    assert S.one_minus_cos_from_sin2(1.0) == pytest.approx(1.0)


def test_sphere_hit_distance_entry_exit_and_miss(device):
    c = np.array([[0, 0, 5], [0, 0, 5], [0, 0, 0.5], [0, 0, -5], [0, 0, 1e4]], np.float32)
    r = np.array([1.0, 1.0, 1.0, 1.0, 1e-2], np.float32)
    d = np.array([[0, 0, 1], [0, 1, 0], [0, 0, 1], [0, 0, 1], [0, 0, 1]], np.float32)
    out = wp.empty(5, dtype=float, device=device)
    wp.launch(_sphere_hit, dim=5, inputs=[wp.array(c, dtype=wp.vec3, device=device), wp.array(r, device=device),
                                          wp.array(d, dtype=wp.vec3, device=device), out], device=device)
    o = out.numpy()
    np.testing.assert_allclose(o, [4.0, -1.0, 1.5, -1.0, 1e4 - 1e-2], rtol=1e-6)


def test_power_heuristic_weights_sum_to_one_and_survive_huge_pdfs(device):
    rng = np.random.default_rng(0)
    a = np.concatenate([10.0 ** rng.uniform(-30, 30, 10_000), [0.0, 0.0, 1e38]]).astype(np.float32)
    b = np.concatenate([10.0 ** rng.uniform(-30, 30, 10_000), [0.0, 1.0, 1e38]]).astype(np.float32)
    wa = wp.empty(len(a), dtype=float, device=device)
    wb = wp.empty(len(a), dtype=float, device=device)
    A = wp.array(a, device=device)
    B = wp.array(b, device=device)
    wp.launch(_mis, dim=len(a), inputs=[A, B, wa], device=device)
    wp.launch(_mis, dim=len(a), inputs=[B, A, wb], device=device)
    s = wa.numpy() + wb.numpy()
    assert np.all(np.isfinite(s))
    np.testing.assert_allclose(s[:-3], 1.0, atol=1e-6)
    assert s[-3] == 0.0 and s[-2] == 1.0 and s[-1] == pytest.approx(1.0)
    ref = S.power_heuristic_np(a[:-3].astype(np.float64), b[:-3].astype(np.float64))
    np.testing.assert_allclose(wa.numpy()[:-3], ref, atol=1e-6)
