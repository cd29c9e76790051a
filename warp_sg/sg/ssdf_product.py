r"""Products of an SG with SSDF visibility (paper §5.3, eq. 25–31).

Given the SSDF value ``θd = V^d(p)`` at the SG axis ``p`` (:mod:`precompute.visibility.ssdf_wp`), visibility near
``p`` is replaced by a hemisphere whose boundary passes ``θd`` away from ``p``; then

* inner product (eq. 30):  ``⟨G(·; p, λ, μ), V⟩ ≈ μ · fh(θd, λ)``  →  :func:`sg_visibility_inner`
  returns ``fh(θd, λ)`` (unit amplitude, i.e. ``⟨G, V⟩/μ``);
* vector product (eq. 31): ``G ⊗ V ≈ G(·; p, λ, μ · fh(θd, λ)/fh(π/2, λ))``  →
  :func:`sg_visibility_scale` returns the amplitude factor ``fh(θd, λ)/fh(π/2, λ)`` ∈ [0, 1].

``fh`` is defined and evaluated in :mod:`warp_sg.sg.fh`; the default is the exact tabulated ratio
(bilinear, max abs error ≈ 3e-4), which is far more accurate than the paper's sigmoid (appendix
eq. 47–48, errors up to ≈ 0.5; kept as ``*_sigmoid`` variants). Kernel-side, the table is passed
explicitly: ``table = warp_sg.sg.fh.fh_table_array(device)`` (a ``wp.array2d(dtype=float)``), e.g.::

    s = sg_visibility_scale(table, theta_d, lam)    # amplitude factor of G ⊗ V
    v = sg_visibility_inner(table, theta_d, lam)    # ∫ G(i; p, λ, 1) V(i) di
"""
from __future__ import annotations

import warp as wp

from warp_sg.sg.fh import (
    fh_hemisphere,
    fh_hemisphere_wp,
    fh_ratio_sigmoid,
    fh_ratio_sigmoid_np,
    fh_ratio_table,
    fh_ratio_table_np,
)


def sg_visibility_scale_np(theta_d, lam, method: str = "table"):
    """numpy: ``fh(θd, λ)/fh(π/2, λ)`` (eq. 31 amplitude factor). ``method``: "table" | "sigmoid"."""
    if method == "sigmoid":
        return fh_ratio_sigmoid_np(theta_d, lam)
    if method != "table":
        raise ValueError(f"unknown fh method {method!r} (table, sigmoid)")
    return fh_ratio_table_np(theta_d, lam)


def sg_visibility_inner_np(theta_d, lam, method: str = "table"):
    """numpy: ``fh(θd, λ) ≈ ⟨G(·; p, λ, 1), V⟩`` (eq. 30)."""
    return sg_visibility_scale_np(theta_d, lam, method) * fh_hemisphere(lam)


@wp.func
def sg_visibility_scale(table: wp.array2d(dtype=float), theta_d: float, lam: float) -> float:
    """fh(θd, λ)/fh(π/2, λ): amplitude factor of the SG ⊗ visibility vector product (eq. 31)."""
    return fh_ratio_table(table, theta_d, lam)


@wp.func
def sg_visibility_inner(table: wp.array2d(dtype=float), theta_d: float, lam: float) -> float:
    """fh(θd, λ) ≈ ∫ G(i; p, λ, 1) V(i) di (eq. 30), unit amplitude."""
    return fh_ratio_table(table, theta_d, lam) * fh_hemisphere_wp(lam)


@wp.func
def sg_visibility_scale_sigmoid(theta_d: float, lam: float) -> float:
    """Paper appendix variant of :func:`sg_visibility_scale` (sigmoid, no table)."""
    return fh_ratio_sigmoid(theta_d, lam)


@wp.func
def sg_visibility_inner_sigmoid(theta_d: float, lam: float) -> float:
    """Paper appendix variant of :func:`sg_visibility_inner` (sigmoid, no table)."""
    return fh_ratio_sigmoid(theta_d, lam) * fh_hemisphere_wp(lam)

