"""precompute.environment.prefilter: ΓL(p, λ) = ∫ G(i; p, λ, 1) L(i) di (paper eq. 35) against direct quadrature."""
from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from precompute.environment import cubemap
from precompute.environment import prefilter as pf
from precompute.environment import prefilter_numpy as pfn
from precompute.environment.prefilter_wp import GammaTable, gamma_lookup, gamma_mean
from warp_sg import sg
from warp_sg.scene import envmap as em
from warp_sg.scene import sky as sk

SUN = np.array([0.45, 0.55, -0.70]) / np.linalg.norm([0.45, 0.55, -0.70])


@wp.kernel
def _lookup_kernel(tab: GammaTable, p: wp.array(dtype=wp.vec3), lam: wp.array(dtype=float),
                   out: wp.array(dtype=wp.vec3), mean: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = gamma_lookup(tab, p[i], lam[i])
    mean[i] = gamma_mean(tab, p[i], lam[i])


@wp.kernel
def _face_kernel(d: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3), back: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    f = cubemap.cube_face_of(d[i])
    out[i] = f
    back[i] = wp.normalize(cubemap.cube_dir(int(f[0]), f[1], f[2]))


def _lookup_wp(pre, p, lam, device, rotation=None, scale=1.0, mean=False):
    """``gamma_lookup`` (ΓL) of the table on ``device``, or with ``mean`` its ``gamma_mean`` (ΓL/∫G)."""
    out = wp.zeros(len(p), dtype=wp.vec3, device=device)
    avg = wp.zeros(len(p), dtype=wp.vec3, device=device)
    wp.launch(_lookup_kernel, dim=len(p), device=device,
              inputs=[pre.table(rotation=rotation, scale=scale, device=device),
                      wp.array(np.asarray(p, np.float32), dtype=wp.vec3, device=device),
                      wp.array(np.asarray(lam, np.float32), dtype=float, device=device), out, avg])
    return (avg if mean else out).numpy().astype(np.float64)


def _unit(rng, n):
    p = rng.normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def sky():
    return sk.procedural_sky(64, 32)


@pytest.fixture(scope="module")
def pre(sky):
    return pf.prefilter_environment(sky, device="cpu", cache=False, progress=False)


def test_cube_faces_round_trip_numpy_and_warp(device):
    rng = np.random.default_rng(0)
    d = _unit(rng, 400)
    f, a, b = cubemap.cube_face_of_numpy(d)
    assert np.all((np.abs(a) <= 1) & (np.abs(b) <= 1))
    back = cubemap.cube_dir_numpy(f, a, b)
    assert np.allclose(back / np.linalg.norm(back, axis=1, keepdims=True), d, atol=1e-12)
    out = wp.zeros(400, dtype=wp.vec3, device=device)
    bk = wp.zeros(400, dtype=wp.vec3, device=device)
    wp.launch(_face_kernel, dim=400, inputs=[wp.array(d.astype(np.float32), dtype=wp.vec3, device=device), out, bk],
              device=device)
    o = out.numpy()
    assert np.array_equal(o[:, 0].astype(int), f)
    assert np.allclose(o[:, 1:], np.stack([a, b], 1), atol=1e-5)
    assert np.allclose(bk.numpy(), d, atol=1e-5)


def test_matches_direct_quadrature_for_random_p_and_lambda(sky, pre):
    rng = np.random.default_rng(1)
    near_sun = SUN + 0.1 * rng.normal(size=(50, 3))
    p = np.concatenate([_unit(rng, 150), near_sun / np.linalg.norm(near_sun, axis=1, keepdims=True)])
    lam = np.exp(rng.uniform(math.log(0.1), math.log(1e4), len(p)))
    ref = np.array([pfn.gamma_reference(sky, a, b) for a, b in zip(p, lam)])
    got = pfn.gamma_lookup_numpy(pre, p, lam)
    rel = np.abs(got - ref).max(1) / np.abs(ref).max(1)
    print("\nλ range        n   median   p95     max   (relative error of ΓL vs quadrature, 64×32 sky)")
    for lo, hi in [(0.1, 1), (1, 10), (10, 100), (100, 1e3), (1e3, 1e4)]:
        m = (lam >= lo) & (lam < hi)
        print(f"[{lo:g}, {hi:g})".ljust(14), f"{m.sum():3d}  {np.median(rel[m]):.4f}  {np.percentile(rel[m], 95):.4f}"
              f"  {rel[m].max():.4f}")
    assert np.median(rel) < 0.005
    assert np.percentile(rel, 95) < 0.02
    assert rel.max() < 0.05


def test_constant_map_gives_exactly_L_times_sg_integral(device):
    L = np.array([0.7, 1.3, 2.0], np.float32)
    env = np.broadcast_to(L, (16, 32, 3)).copy()
    pre = pf.prefilter_environment(env, device=device, cache=False, progress=False)
    rng = np.random.default_rng(2)
    p = np.concatenate([_unit(rng, 200), [[0, 1, 0], [0, -1, 0], [1, 0, 0]]])
    lam = np.exp(rng.uniform(math.log(1e-3), math.log(1e5), len(p)))
    expect = sg.integral(lam)[:, None] * L
    assert np.allclose(pfn.gamma_lookup_numpy(pre, p, lam), expect, rtol=2e-6)
    assert np.allclose(_lookup_wp(pre, p, lam, device), expect, rtol=2e-5)
    # the mean radiance under any lobe of a constant map is the constant
    assert np.allclose(_lookup_wp(pre, p, lam, device, mean=True), np.broadcast_to(L, (len(p), 3)), rtol=2e-5)


def test_broad_lobes_tend_to_the_sphere_integral(sky, pre):
    total = np.einsum("hwc,hw->c", sky.astype(np.float64), em.texel_solid_angles(32, 64))
    p = _unit(np.random.default_rng(3), 20)
    g = pfn.gamma_lookup_numpy(pre, p, np.full(20, 1e-5))
    assert np.allclose(g, total, rtol=1e-4)  # ΓL(p, λ→0) = ∫ L
    # λ = 0.1 (below the ladder's λ0 = 0.5): the quadratic extension still matches quadrature
    ref = np.array([pfn.gamma_reference(sky, a, 0.1) for a in p])
    assert np.allclose(pfn.gamma_lookup_numpy(pre, p, 0.1), ref, rtol=2e-3)


def test_warp_lookup_matches_numpy_twin_with_rotation_and_scale(pre, device):
    rng = np.random.default_rng(4)
    p = _unit(rng, 300)
    lam = np.exp(rng.uniform(math.log(0.05), math.log(3e4), 300))
    R = em.rotation_matrix((0.3, 1.0, -0.2), 70.0)
    got = _lookup_wp(pre, p, lam, device, rotation=R, scale=2.5)
    want = pfn.gamma_lookup_numpy(pre, p, lam, rotation=R, scale=2.5)
    rel = np.abs(got - want).max(1) / np.abs(want).max(1)
    assert np.percentile(rel, 99) < 1e-4 and rel.max() < 2e-3  # float32, texel-boundary rounding
    mean = _lookup_wp(pre, p, lam, device, rotation=R, scale=2.5, mean=True)  # ΓL/∫G
    rel = np.abs(mean * sg.integral(lam)[:, None] - want).max(1) / np.abs(want).max(1)
    assert np.percentile(rel, 99) < 1e-4 and rel.max() < 2e-3
    # rotating the environment by R equals looking up Rᵀ p in the unrotated table
    assert np.allclose(want, 2.5 * pfn.gamma_lookup_numpy(pre, p @ R, lam), rtol=1e-9)


def test_build_on_each_device_matches_quadrature(device):
    """The table built on ``device`` (the CPU, and CUDA when present) against direct quadrature of
    eq. 35; on CUDA also texel for texel against the CPU build."""
    env = sk.procedural_sky(32, 16)
    b = pf.prefilter_environment(env, device=device, cache=False, progress=False)
    rng = np.random.default_rng(7)
    near = SUN + 0.1 * rng.normal(size=(8, 3))
    p = np.concatenate([_unit(rng, 12), near / np.linalg.norm(near, axis=1, keepdims=True), [SUN]])
    lam = np.exp(rng.uniform(math.log(0.3), math.log(3e3), len(p)))
    ref = np.array([pfn.gamma_reference(env, a, x) for a, x in zip(p, lam)])
    rel = np.abs(pfn.gamma_lookup_numpy(b, p, lam) - ref).max(1) / np.abs(ref).max(1)
    assert np.median(rel) < 0.005 and rel.max() < 0.05, rel
    if device != "cpu":
        a = pf.prefilter_environment(env, device="cpu", cache=False, progress=False)
        assert np.allclose(a.texels, b.texels, rtol=1e-4, atol=1e-6)


def test_tables_are_the_same_built_on_one_thread_or_on_several(sky, pre, monkeypatch):
    """Every level's texels are cut into chunks that one pool of threads runs: one thread, three
    threads and the default build give the same table bit for bit (and the default one matches
    quadrature, above)."""
    for n in ("1", "3"):
        monkeypatch.setenv("WARP_SG_THREADS", n)
        b = pf.prefilter_environment(sky, device="cpu", cache=False, progress=False)
        assert np.array_equal(b.texels, pre.texels) and np.array_equal(b.level_offsets, pre.level_offsets), n


def test_table_is_cached_by_map_content(cache_dir):
    env = sk.procedural_sky(16, 8)
    a = pf.prefilter_environment(env, device="cpu", progress=False)
    files = list((cache_dir / "env_prefilter").glob("*.npz"))
    assert len(files) == 1
    b = pf.prefilter_environment(env, device="cpu", progress=False)
    assert np.array_equal(a.texels, b.texels) and len(list((cache_dir / "env_prefilter").glob("*.npz"))) == 1
    env2 = env.copy()
    env2[3, 4] += 1.0
    pf.prefilter_environment(env2, device="cpu", progress=False)
    assert len(list((cache_dir / "env_prefilter").glob("*.npz"))) == 2


def test_poles_cube_edges_and_corners_match_quadrature(sky, pre):
    dirs = np.array([[0, 1, 0], [0, -1, 0], [0.02, 1, 0.01], [0.03, -1, -0.02], [1, 1, 0], [1, 1, 1],
                     [-1, 1, -1], [1, 0, 1], [0, 0.001, -1]], float)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    worst = 0.0
    for lam in [0.3, 3.0, 30.0, 300.0, 3000.0, 30000.0]:
        ref = np.array([pfn.gamma_reference(sky, d, lam) for d in dirs])
        got = pfn.gamma_lookup_numpy(pre, dirs, np.full(len(dirs), lam))
        worst = max(worst, float((np.abs(got - ref).max(1) / np.abs(ref).max(1)).max()))
    assert worst < 0.015
