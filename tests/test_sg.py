"""warp_sg.sg (numpy) against float64 quadrature, λ in 1e-4..1e6, aligned / small-angle /
orthogonal / antipodal axes, float64 (rel. 1e-5) and float32 (rel. 1e-3 where representable)."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from sg_reference import ANGLES, LAMBDAS, axes_at_angle, random_rotation, ref_inner, ref_integral

from warp_sg import sg

TOL = {np.float64: 1e-5, np.float32: 1e-3}
TINY = {np.float64: 1e-290, np.float32: 1e-30}
ROT = random_rotation(7)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_integral_matches_quadrature_for_all_sharpness(dtype):
    lam = np.array(LAMBDAS, dtype)
    got = sg.integral(lam, 2.0)
    assert got.dtype == dtype
    ref = np.array([2.0 * ref_integral(float(x)) for x in lam.astype(np.float64)])
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, ref, rtol=TOL[dtype])


def _inner_cases():
    return list(itertools.product(LAMBDAS, LAMBDAS[::2], ANGLES.items()))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_inner_product_matches_quadrature(dtype):
    ref = []
    p1s, p2s, l1s, l2s = [], [], [], []
    for l1, l2, (_, g) in _inner_cases():
        p1, p2 = axes_at_angle(g, ROT)
        p1s.append(p1)
        p2s.append(p2)
        l1s.append(l1)
        l2s.append(l2)
        ref.append(ref_inner(l1, l2, g))
    p1 = np.array(p1s, dtype)
    p2 = np.array(p2s, dtype)
    l1 = np.array(l1s, dtype)
    l2 = np.array(l2s, dtype)
    val = sg.inner_product(p1, l1, 1.0, p2, l2, 1.0)
    assert val.dtype == dtype
    assert np.all(np.isfinite(val))
    assert np.all(val >= 0)
    ref = np.array(ref)
    # the reference sees the float-rounded axes only through γ; rounding of the axes moves the
    # result by λ·δ(1−cos γ) relative: compare where that is below tolerance
    eps = np.finfo(dtype).eps
    sens = 2 * l1 * l2 / (l1 + l2) * np.sin(np.array([g for _, _, (_, g) in _inner_cases()])) * 4 * eps
    rep = (ref > TINY[dtype]) & (sens < 0.1 * TOL[dtype])
    assert rep.sum() > 0.6 * len(ref)
    np.testing.assert_allclose(val[rep], ref[rep], rtol=TOL[dtype])
    # where unrepresentable the result underflows to (near) zero, never garbage
    assert np.all(val[ref < TINY[dtype]] < 10 * TINY[dtype])


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_vector_product_equals_pointwise_product(dtype):
    rng = np.random.default_rng(0)
    for l1, l2, (name, g) in itertools.product(LAMBDAS, LAMBDAS, ANGLES.items()):
        p1, p2 = axes_at_angle(g, ROT)
        p1 = p1.astype(dtype)
        p2 = p2.astype(dtype)
        axis, lam, amp = sg.product(p1, dtype(l1), dtype(0.5), p2, dtype(l2), dtype(3.0))
        assert np.isfinite(axis).all() and np.isfinite(lam) and np.isfinite(amp)
        assert lam > 0 and amp >= 0
        np.testing.assert_allclose(np.linalg.norm(axis), 1.0, rtol=1e-6 if dtype == np.float64 else 1e-6 * 10)
        # test points: the product peak and points ~1/√λ around it, plus random directions
        w = 1.0 / np.sqrt(max(float(lam), 1.0))
        v = axis.astype(np.float64) + w * rng.normal(size=(8, 3))
        v = np.concatenate([v, rng.normal(size=(4, 3))])
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        v = v.astype(dtype)
        v64 = v.astype(np.float64)
        ref = 1.5 * np.exp(-l1 * sg.one_minus_dot(v64, p1.astype(np.float64))
                           - l2 * sg.one_minus_dot(v64, p2.astype(np.float64)))
        got = sg.evaluate(v, axis, lam, amp).astype(np.float64)
        assert np.all(np.isfinite(got))
        rep = ref > TINY[dtype] * 1e3
        # float32: λ·|δ(1 − v·p)| with |δ| ~ eps·θ bounds what is representable
        if dtype == np.float32:
            theta = np.sqrt(2 * sg.one_minus_dot(v64, axis.astype(np.float64)))
            rep &= (max(l1, l2) * theta * 2e-7 + float(lam) * theta * 2e-7) < 3e-4
        np.testing.assert_allclose(got[rep], ref[rep], rtol=TOL[dtype], err_msg=f"{l1} {l2} {name}")


def test_antipodal_equal_lobes_give_constant_product():
    p = np.array([0.0, 0.0, 1.0])
    axis, lam, amp = sg.product(p, 3.0, 1.0, -p, 3.0, 1.0)
    v = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, 0.6, 0.8]])
    np.testing.assert_allclose(sg.evaluate(v, axis, lam, amp), np.exp(-6.0), rtol=1e-12)


def test_evaluate_is_exact_and_finite_near_the_axis():
    p = np.array([0.0, 0.0, 1.0])
    th = np.array([0.0, 1e-8, 1e-4, 0.5, np.pi])
    v = np.stack([np.sin(th), 0 * th, np.cos(th)], -1)
    for lam in LAMBDAS:
        ref = np.exp(-lam * 2 * np.sin(th / 2) ** 2)
        np.testing.assert_allclose(sg.evaluate(v, p, lam), ref, rtol=1e-12, atol=1e-300)
        got32 = sg.evaluate(v.astype(np.float32), p.astype(np.float32), np.float32(lam))
        assert got32.dtype == np.float32 and np.all(np.isfinite(got32))


def test_rgb_amplitudes_broadcast():
    p = np.array([0.0, 0.0, 1.0])
    mu = np.array([1.0, 2.0, 3.0])
    assert sg.integral(2.0, mu).shape == (3,)
    np.testing.assert_allclose(sg.integral(2.0, mu), mu * ref_integral(2.0), rtol=1e-10)
    assert sg.inner_product(p, 1.0, mu, p, 2.0, 1.0).shape == (3,)
    a, l, m = sg.product(p, 1.0, mu, p, 2.0, 2.0)
    np.testing.assert_allclose(m, 2 * mu)


def test_rotate_and_effective_area_round_trip():
    R = random_rotation(3)
    p = np.array([0.3, -0.2, 0.9])
    p /= np.linalg.norm(p)
    np.testing.assert_allclose(sg.rotate(R, p), R @ p)
    lam = np.array([3.0, 10.0, 1e4])
    np.testing.assert_allclose(sg.fa_inv(sg.fa(lam)), lam)
    # fa(λ): the solid angle where G ≥ ε (exact: 2π(−ln ε)/λ for λ ≥ −ln ε/2)
    eps = 0.1
    exact = 2 * np.pi * (-np.log(eps)) / lam
    np.testing.assert_allclose(sg.fa(lam), exact)
