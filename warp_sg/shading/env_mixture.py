r"""An environment that *is* an SG mixture: the mean radiance under a lobe from the mixture's lobes.

The specular environment term (eq. 41, :mod:`warp_sg.shading.kernel`) reads the mean radiance of
the environment under the product lobe ``G(p, λ)`` of each slice lobe, ``L̄ = ΓL(p, λ)/∫G(λ)``
(eq. 35). For a map the prefiltered ΓL pyramid holds it
(``precompute.environment.prefilter_wp.gamma_mean``). For an environment given as the mixture
``L(i) = Σ_j μ_j G_j(i)`` (``Renderer.set_environment_mixture``: what inverse rendering
recovers) it is exact in closed form, the SG inner product (paper eq. 4)::

    L̄(p, λ) = Σ_j μ_j ∫ G(i; p, λ) G(i; p_j, λ_j) di / ∫G(λ)

a smooth function of every lobe's amplitude, axis and sharpness, so the kernel's adjoint
(:mod:`warp_sg.renderer.gradients`) differentiates the specular term with respect to the lighting.
The loop over lobes only accumulates (``+=``) and its sum is returned as it is: Warp's reverse pass
does not replay a dynamic loop before the statements after it, so nothing after the loop may use
what it summed (:mod:`warp_sg.shading.kernel_grad`).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import warp as wp

from warp_sg.sg.algebra_wp import sg_inner, sg_integral
from warp_sg.shading.visibility_terms import EnvSG


@wp.func
def mixture_mean(env: EnvSG, p: wp.vec3, lam: float) -> wp.vec3:
    """``L̄(p, λ) = Σ_j μ_j ∫G(p, λ) G_j / ∫G(λ)``: the mean radiance of the mixture under the
    lobe (p, λ) (module docstring)."""
    inv = 1.0 / sg_integral(wp.max(lam, 1.0e-6))
    acc = wp.vec3(0.0, 0.0, 0.0)
    for j in range(env.count):  # (only summed: what the loop adds is returned as it is)
        acc += env.mu[j] * (sg_inner(p, lam, env.axis[j], env.lam[j]) * inv)
    return acc


__all__ = ["mixture_mean"]
