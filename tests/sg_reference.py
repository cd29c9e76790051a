"""High-accuracy float64 quadrature references for SG tests (shared by test_sg*.py).

Sharp lobes are integrated in the polar angle θ about the first axis, after doing the azimuthal
integral in closed form (``∫ e^{x cos φ} dφ = 2π I0(x)``, with the exponentially scaled ``ive``),
on sub-intervals placed around the product's peak with widths ∝ 1/√λ, so the quadrature
resolves lobes up to λ = 1e6.
"""
from __future__ import annotations

import numpy as np
from scipy import integrate, special


def _pieces(center, width, lo=0.0, hi=np.pi):
    pts = {lo, hi}
    for k in (-40, -12, -4, -1, 0, 1, 4, 12, 40):
        x = center + k * width
        if lo < x < hi:
            pts.add(x)
    return sorted(pts)


def ref_integral(lam):
    """∫_{S²} exp(λ (cos θ − 1)) dω = (2π/λ) ∫_0^{2λ} e^{−s} ds (substitution s = λ(1 − cos θ))."""
    lam = float(lam)
    top = 2.0 * lam
    pts = [0.0] + [x for x in (1.0, 5.0, 20.0, 60.0, 700.0) if x < top] + [top]
    tot = sum(integrate.quad(lambda s: np.exp(-s), a, b, epsabs=0, epsrel=1e-13, limit=200)[0]
              for a, b in zip(pts[:-1], pts[1:]))
    return 2.0 * np.pi / lam * tot


def ref_inner(l1, l2, gamma):
    """∫ G(v; p1, λ1, 1) G(v; p2, λ2, 1) dω with angle γ between the axes."""
    l1, l2, g = float(l1), float(l2), float(gamma)
    pm = np.array([l2 * np.sin(g), 0.0, l1 + l2 * np.cos(g)])
    d = np.linalg.norm(pm)
    theta_star = np.arctan2(pm[0], pm[2]) if d > 0 else 0.0
    width = 1.0 / np.sqrt(max(d, 1.0))

    def f(t):
        x = l2 * np.sin(t) * np.sin(g)
        e = -l1 * 2 * np.sin(0.5 * t) ** 2 - l2 * 2 * np.sin(0.5 * (t - g)) ** 2
        return 2 * np.pi * np.sin(t) * np.exp(e) * special.ive(0, x)

    pts = _pieces(theta_star, width)
    return sum(integrate.quad(f, a, b, epsabs=0, epsrel=1e-12, limit=400)[0] for a, b in zip(pts[:-1], pts[1:]))


def axes_at_angle(gamma, rot=None):
    p1 = np.array([0.0, 0.0, 1.0])
    p2 = np.array([np.sin(gamma), 0.0, np.cos(gamma)])
    if rot is not None:
        p1, p2 = rot @ p1, rot @ p2
    return p1, p2


def random_rotation(seed=0):
    from scipy.spatial.transform import Rotation

    return Rotation.random(random_state=seed).as_matrix()


LAMBDAS = [1e-4, 1e-2, 1.0, 10.0, 1e3, 1e6]
ANGLES = {"aligned": 0.0, "small": 1e-3, "oblique": 0.7, "orthogonal": np.pi / 2, "antipodal": np.pi}
