"""warp_sg.sg.algebra_wp (@wp.func twins, float32) against float64 quadrature and the numpy module:
finite everywhere, rel. error ≤ 1e-3 where representable in float32, λ in 1e-4..1e6."""
from __future__ import annotations

import itertools

import numpy as np
import warp as wp
from sg_reference import ANGLES, LAMBDAS, axes_at_angle, random_rotation, ref_inner, ref_integral

from warp_sg import sg
from warp_sg.sg import algebra_wp as S

ROT = random_rotation(11)


@wp.kernel
def _sg_kernel(p1: wp.array(dtype=wp.vec3), l1: wp.array(dtype=float), p2: wp.array(dtype=wp.vec3),
               l2: wp.array(dtype=float), v: wp.array(dtype=wp.vec3),
               integ: wp.array(dtype=float), inner: wp.array(dtype=float), prod_axis: wp.array(dtype=wp.vec3),
               prod_sharp: wp.array(dtype=float), prod_scale: wp.array(dtype=float), ev: wp.array(dtype=float),
               fa: wp.array(dtype=float)):
    t = wp.tid()
    integ[t] = S.sg_integral(l1[t])
    inner[t] = S.sg_inner(p1[t], l1[t], p2[t], l2[t])
    a, s, sc = S.sg_product(p1[t], l1[t], p2[t], l2[t])
    prod_axis[t] = a
    prod_sharp[t] = s
    prod_scale[t] = sc
    ev[t] = S.sg_eval(v[t], a, s) * sc
    fa[t] = S.sg_fa_inv(l1[t])


def _run(p1, l1, p2, l2, v, device):
    n = len(l1)
    f = lambda a, dt=float: wp.array(np.asarray(a, np.float32), dtype=dt, device=device)  # noqa: E731
    outs = [wp.zeros(n, dtype=float, device=device), wp.zeros(n, dtype=float, device=device),
            wp.zeros(n, dtype=wp.vec3, device=device), wp.zeros(n, dtype=float, device=device),
            wp.zeros(n, dtype=float, device=device), wp.zeros(n, dtype=float, device=device),
            wp.zeros(n, dtype=float, device=device)]
    wp.launch(_sg_kernel, n, inputs=[f(p1, wp.vec3), f(l1), f(p2, wp.vec3), f(l2), f(v, wp.vec3), *outs], device=device)
    return [o.numpy() for o in outs]


def _cases():
    p1s, p2s, l1s, l2s, gs = [], [], [], [], []
    for l1, l2, (_, g) in itertools.product(LAMBDAS, LAMBDAS, ANGLES.items()):
        p1, p2 = axes_at_angle(g, ROT)
        p1s.append(p1)
        p2s.append(p2)
        l1s.append(l1)
        l2s.append(l2)
        gs.append(g)
    return np.array(p1s), np.array(l1s), np.array(p2s), np.array(l2s), np.array(gs)


def test_sg_wp_matches_quadrature_in_float32(device):
    p1, l1, p2, l2, g = _cases()
    rng = np.random.default_rng(5)
    # evaluation points near each product's peak
    a64, s64, _ = sg.product(p1, l1, 1.0, p2, l2, 1.0)
    v = a64 + rng.normal(size=a64.shape) / np.sqrt(np.maximum(s64, 1.0))[:, None]
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    integ, inner, pa, ps, psc, ev, fa = _run(p1, l1, p2, l2, v, device)
    for arr in (integ, inner, pa, ps, psc, ev, fa):
        assert np.all(np.isfinite(arr))
    # integral
    ref_int = np.array([ref_integral(x) for x in l1])
    np.testing.assert_allclose(integ, ref_int, rtol=1e-3)
    np.testing.assert_allclose(fa, sg.fa_inv(l1.astype(np.float32).astype(np.float64)), rtol=1e-6)
    # inner product (quadrature), where representable and not limited by float32 axis rounding
    ref_in = np.array([ref_inner(a, b, c) for a, b, c in zip(l1, l2, g)])
    sens = 2 * l1 * l2 / (l1 + l2) * np.sin(g) * 4 * 6e-8
    rep = (ref_in > 1e-30) & (sens < 1e-4)
    assert rep.sum() > 0.6 * len(rep)
    np.testing.assert_allclose(inner[rep], ref_in[rep], rtol=1e-3)
    assert np.all(inner[ref_in < 1e-30] < 1e-29)
    # product: evaluated at points around the peak equals G1·G2 there
    p1f, p2f, vf = (x.astype(np.float32).astype(np.float64) for x in (p1, p2, v))
    l1f, l2f = l1.astype(np.float32).astype(np.float64), l2.astype(np.float32).astype(np.float64)
    ref_ev = np.exp(-l1f * sg.one_minus_dot(vf, p1f) - l2f * sg.one_minus_dot(vf, p2f))
    theta = np.sqrt(2 * sg.one_minus_dot(vf, a64))
    rep = (ref_ev > 1e-30) & ((np.maximum(l1, l2) + s64) * theta * 2e-7 < 3e-4)
    assert rep.sum() > 0.5 * len(rep)
    np.testing.assert_allclose(ev[rep], ref_ev[rep], rtol=1e-3)
    np.testing.assert_allclose(np.linalg.norm(pa, axis=1), 1.0, atol=1e-5)
    assert np.all(ps > 0) and np.all(psc <= 1.0) and np.all(psc >= 0)


def test_sg_wp_agrees_with_numpy_float64(device):
    p1, l1, p2, l2, g = _cases()
    rng = np.random.default_rng(6)
    v = rng.normal(size=p1.shape)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    integ, inner, pa, ps, psc, ev, fa = _run(p1, l1, p2, l2, v, device)
    p1f, p2f = p1.astype(np.float32).astype(np.float64), p2.astype(np.float32).astype(np.float64)
    ref_inner_np = sg.inner_product(p1f, l1, 1.0, p2f, l2, 1.0)
    rep = (ref_inner_np > 1e-30) & (2 * l1 * l2 / (l1 + l2) * np.sin(g) * 4 * 6e-8 < 1e-4)
    np.testing.assert_allclose(inner[rep], ref_inner_np[rep], rtol=1e-3)
    a, s, m = sg.product(p1f, l1, 1.0, p2f, l2, 1.0)
    ok = (m > 1e-30) & (s > 1e-3)
    np.testing.assert_allclose(ps[ok], s[ok], rtol=1e-3)
    np.testing.assert_allclose(psc[ok], m[ok], rtol=1e-3)
