"""The SG mixture fit's analytic Jacobian (precompute.environment.sg_design / varpro) against finite
differences of its residual (scipy's ``approx_derivative``, central differences), and its amplitude
solve against scipy's NNLS on the full system."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import nnls
from scipy.optimize._numdiff import approx_derivative

from precompute.environment.sg_design import LobeDesign, exact_norm_grad
from precompute.environment.sg_fit import _fibonacci_normals, irradiance_reference
from precompute.environment.varpro import Projection, solve_nonnegative
from warp_sg.scene import envmap as em
from warp_sg.scene import sky as sk
from warp_sg.sg import cosine_lobes as CC
from warp_sg.sg import irradiance as irr
from warp_sg.sg.irradiance import sg_irradiance_norm_np

K = 5


@pytest.fixture(scope="module")
def sky_rows():
    env = sk.procedural_sky(64, 32).astype(np.float64)
    h, w = env.shape[:2]
    d = em.texel_directions(h, w).reshape(-1, 3)
    om = em.texel_solid_angles(h, w).reshape(-1)
    normals = _fibonacci_normals(64)
    B = np.concatenate([np.sqrt(om)[:, None] * env.reshape(-1, 3), 0.7 * irradiance_reference(env, normals)])
    return d, om, normals, B


def _random_params(rng):
    return np.concatenate([rng.normal(size=(K, 3)), rng.uniform(math.log(0.1), math.log(300.0), (K, 1))], 1).ravel()


def _columns_agree(J, J_fd):
    """Per column: relative error ≤ 1e-5, or (a column the solve does not move: a lobe with no
    amplitude) within the finite differences' noise, 1e-7 of the largest column. (Column norms,
    not elements: the exact irradiance is a bilinear table lookup, whose slope jumps at cell
    edges, and a difference step that straddles one is off there.)"""
    err = np.linalg.norm(J - J_fd, axis=0)
    ref = np.linalg.norm(J_fd, axis=0)
    return np.all(err <= 1e-5 * ref + 1e-7 * ref.max()), float((err / np.maximum(ref, 1e-300))[ref > 1e-6 * ref.max()].max())


@pytest.mark.parametrize("cosine", ["exact", None, CC.LOBES[2]], ids=["exact", "eq40", "two_lobe_cosine"])
def test_projected_residual_jacobian_matches_finite_differences(sky_rows, cosine):
    d, om, normals, B = sky_rows
    design = LobeDesign([(d, np.sqrt(om), "radiance"), (normals, np.full(len(normals), 0.7), "irradiance")], cosine)
    proj = Projection(design.evaluate, design.derivative, B, np.repeat(np.arange(K), 4))
    rng = np.random.default_rng(7)
    for _ in range(3):
        x = _random_params(rng)
        J = proj.jacobian(x)
        J_fd = approx_derivative(proj.residual, x, method="3-point", rel_step=1e-6)
        ok, worst = _columns_agree(J, J_fd)
        assert ok, f"worst column relative error {worst:.2e}"
        assert worst < 1e-5
        # the design's own derivative: ∂A[:, k]/∂x_{4k+i}
        A, state = design.evaluate(x)
        dA_fd = approx_derivative(lambda y: design.evaluate(y)[0].ravel(), x, method="3-point",
                                  rel_step=1e-6).reshape(A.shape[0], K, 4 * K)
        dA_fd = dA_fd[:, np.repeat(np.arange(K), 4), np.arange(4 * K)]
        ok, worst = _columns_agree(design.derivative(state), dA_fd)
        assert ok and worst < 1e-5, f"worst column relative error of ∂A/∂x {worst:.2e}"


def test_jacobian_of_a_black_map_is_zero(sky_rows):
    d, om, normals, _ = sky_rows
    design = LobeDesign([(d, np.sqrt(om), "radiance"), (normals, np.ones(len(normals)), "irradiance")], "exact")
    proj = Projection(design.evaluate, design.derivative, np.zeros((len(d) + len(normals), 3)),
                      np.repeat(np.arange(K), 4))
    x = _random_params(np.random.default_rng(1))
    assert np.all(proj.residual(x) == 0.0) and np.all(proj.jacobian(x) == 0.0)


def test_exact_irradiance_gradient_matches_finite_differences_on_every_branch():
    """Table cells (λ ≤ 1e3), the sharp-lobe form (λ > 1e3) and lobes clear of the horizon,
    against central differences of the renderer's values. The table's bilinear interpolant has
    slope jumps on its cell edges (and the value jumps where a branch switches): points within a
    step of one are left out (a few)."""
    rng = np.random.default_rng(3)
    c = rng.uniform(-0.999, 0.999, 4000)
    lam = 10.0 ** rng.uniform(-1.5, 3.7, 4000)
    e = sg_irradiance_norm_np(c, lam)
    de_dc, de_dl = exact_norm_grad(c, lam, e)
    h = 1e-6
    fd_c = (sg_irradiance_norm_np(c + h, lam) - sg_irradiance_norm_np(c - h, lam)) / (2 * h)
    fd_l = (sg_irradiance_norm_np(c, lam * (1 + h)) - sg_irradiance_norm_np(c, lam * (1 - h))) / (2 * h * lam)

    def near(v, step):  # within two steps of an integer (a cell edge)
        return np.abs(v - np.round(v)) < 2 * step

    x = (c + 1) / 2 * (irr.IRR_N_C - 1)
    r = (np.log10(lam) - irr.IRR_LOG10_LAM_MIN) * irr.IRR_ROWS_PER_DECADE
    rim = lam * (1 - np.sqrt(1 - c * c)) - irr.ABOVE_HORIZON  # the clear-of-horizon switch at 0
    switch = (np.abs(rim) < 4 * h * lam) | (np.abs(lam - irr.IRR_LAM_SWITCH) < 4 * h * lam)
    skip_c = near(x, h * (irr.IRR_N_C - 1) / 2) | switch
    skip_l = near(r, h * irr.IRR_ROWS_PER_DECADE / np.log(10)) | switch
    assert skip_c.mean() < 0.01 and skip_l.mean() < 0.01
    # tolerance: 1e-5 relative, and the differences' rounding (≈ 1e-16 / h in e) as a floor
    bad_c = ~skip_c & (np.abs(de_dc - fd_c) > 1e-5 * np.abs(fd_c) + 1e-8)
    bad_l = ~skip_l & (np.abs(de_dl - fd_l) * lam > 1e-5 * np.abs(fd_l) * lam + 1e-8)
    assert not bad_c.any() and not bad_l.any(), (np.flatnonzero(bad_c)[:5], np.flatnonzero(bad_l)[:5])
    assert (lam > 1e3).sum() > 300 and (lam < irr.ABOVE_HORIZON).sum() > 300  # every branch is sampled
    assert (rim > 0).sum() > 300


def test_amplitudes_on_the_triangular_factor_are_the_nnls_solution():
    rng = np.random.default_rng(5)
    A = rng.normal(size=(300, 8))
    A[:, 3] = A[:, 2] + 1e-3 * rng.normal(size=300)  # nearly collinear columns
    B = rng.normal(size=(300, 3)) + A @ rng.uniform(-1, 1, (8, 3))
    mu, _, _ = solve_nonnegative(A, B)
    for c in range(3):
        ref = nnls(A, B[:, c])[0]
        assert np.all(mu[:, c] >= 0)
        assert np.linalg.norm(A @ mu[:, c] - B[:, c]) <= np.linalg.norm(A @ ref - B[:, c]) * (1 + 1e-10)
        assert np.allclose(mu[:, c], ref, atol=1e-8)
