r"""Diffuse models: Lambert and Oren–Nayar (lecture "Lambertian reflection", "Oren-Nayar model").

* Lambert: ``ρ = kd/π``.
* Oren–Nayar (qualitative model, pbrt form): ``ρ = kd/π (A + B max(0, cos(φi − φo)) sin α tan β)``,
  ``A = 1 − σ²/(2(σ² + 0.33))``, ``B = 0.45σ²/(σ² + 0.09)``, ``α = max(θi, θo)``, ``β = min(θi, θo)``.
  Evaluated without angles as ``sin α tan β cos(φi − φo) = (ix ox + iy oy) / max(cos θi, cos θo)``
  (exact identity; finite at the normal and at grazing).

Kernel side: Lambert has no hooks (``kd/π``, cosine sampling); Oren–Nayar's ``diffuse`` is the
same identity in float32, and a roughness texture sets σ, hence ``(A, B, σ)`` (``texel_param0``).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import numpy as np
import warp as wp

from ..base import BRDF, INV_PI, as_rgb, as_scalar, dirs, upper
from ..kernel.material_eval_wp import oren_nayar_params
from ..kernel.material_struct import Material
from ..params import KD, Param
from ..registry import Kernel, register


@wp.func
def oren_nayar_diffuse(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    """kd/π (A + B max(0, ix ox + iy oy)/max(cos θi, cos θo))."""
    dphi = wp.max(o[0] * i[0] + o[1] * i[1], 0.0)
    cmax = wp.max(wp.max(o[2], i[2]), 1.0e-12)
    return mat.kd * (INV_PI * (mat.params[0] + mat.params[1] * dphi / cmax))


@wp.func
def oren_nayar_texel_param0(mat: Material, p: wp.vec4, v: float) -> wp.vec4:
    """A σ texel: (A, B, σ) (``oren_nayar_params``)."""
    return oren_nayar_params(wp.max(v, 0.0))


@register
class Lambert(BRDF):
    """``ρ(o, i) = kd/π`` (energy conserving for kd ≤ 1)."""

    NAME = "lambert"
    CODE = 0
    PARAMS = {"kd": KD}
    KERNEL = Kernel()

    def __init__(self, kd=(0.8, 0.8, 0.8)):
        self.kd = as_rgb(kd, "kd")
        self.ks = np.zeros(3)


@register
class OrenNayar(BRDF):
    """Oren–Nayar rough diffuse; ``sigma`` is the facet-slope standard deviation in radians."""

    NAME = "oren_nayar"
    CODE = 1
    PARAMS = {"kd": KD, "sigma": Param("number", "Oren–Nayar roughness σ (radians)", lo=0, texture=True,
                                       slider=(0.0, 1.5), kernel=(0,))}  # (texel_param0: σ -> (A, B, σ))
    KERNEL = Kernel(diffuse=oren_nayar_diffuse, texel_param0=oren_nayar_texel_param0)

    def __init__(self, kd=(0.8, 0.8, 0.8), sigma=0.3):
        self.kd = as_rgb(kd, "kd")
        self.ks = np.zeros(3)
        self.sigma = as_scalar(sigma, "sigma", lo=0.0)
        s2 = self.sigma**2
        self.A = 1.0 - s2 / (2.0 * (s2 + 0.33))
        self.B = 0.45 * s2 / (s2 + 0.09)

    def diffuse(self, o, i):
        o, i = dirs(o, i)
        dphi = np.maximum(o[..., 0] * i[..., 0] + o[..., 1] * i[..., 1], 0.0)
        cmax = np.maximum(np.maximum(o[..., 2], i[..., 2]), 1e-12)
        f = self.A + self.B * dphi / cmax
        return np.where(upper(o, i)[..., None], self.kd * INV_PI * f[..., None], 0.0)

    def kernel_params(self):
        return (self.A, self.B, self.sigma, 0.0)
