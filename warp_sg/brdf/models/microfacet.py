r"""Microfacet models with the V-cavity shadowing term (lecture "Torrance-Sparrow model",
"Geometry attenuation factor"; paper eq. 10–12; supplement eq. 1–3).

V-cavity shadowing/masking: ``G(o, i) = min(1, 2(n·h)(n·o)/(o·h), 2(n·h)(n·i)/(i·h))``.
It is evaluated together with the ``1/((n·i)(n·o))`` factor as
``G/((n·i)(n·o)) = min(1/((n·i)(n·o)), 2(n·h)/((o·h)(n·i)), 2(n·h)/((o·h)(n·o)))``,
which stays finite at grazing angles.

* :class:`CookTorrance` (paper eq. 10–11, supplement eq. 1–3):
  ``ρs = F(i·h) G / (π (n·i)(n·o)) · exp(−(θh/m)²)``, ``Mo = F G/(π (n·i)(n·o))``,
  ``D(h) = exp(−(θh/m)²) ≈ G(h; n, 2/m², 1)`` (paper eq. 12).
* :class:`TorranceSparrow` (lecture, pbrt ``Microfacet``): ``ρs = D_B(h) G F(i·h) / (4 (n·i)(n·o))``
  with the normalised Beckmann distribution ``D_B = exp(−tan²θh/m²)/(π m² cos⁴θh)``
  (``∫ D_B cos θh dω = 1``). Factorised as ``D(h) = exp(−tan²θh/m²)`` (peak 1; analytic SG
  ``λ = 2/m²``, ``μ = 1``) and ``Mo = F G/(4π m² (n·i)(n·o) cos⁴θh)``. Energy conserving.

``fresnel`` is anything :func:`warp_sg.brdf.fresnel.parse_fresnel` accepts (default: none, F = 1).

Kernel side (float32, same forms): analytic lobe ``λ = 2/m²``; both sample the Beckmann slope
distribution (Walter et al. 2007) with ``p(h) = exp(−tan²θh/m²)/(π m² cos³θh)``.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import numpy as np
import warp as wp

from ...numeric.fastmath import fast_atan2
from ..base import SpecularBRDF, as_rgb, as_scalar, dirs, half_vector, sin2_theta, theta_of
from ..fresnel import parse_fresnel
from ..kernel.material_eval_wp import fresnel_eval, half_vec
from ..kernel.material_eval_wp import g_over_cos as g_over_cos_f
from ..kernel.material_eval_wp import sin2_theta as sin2_theta_f
from ..kernel.material_sample_wp import beckmann_h, beckmann_pdf_h, reflect_about
from ..kernel.material_struct import INV_PI, Material
from ..params import FRESNEL, KD, KS, Param
from ..registry import Kernel, register


@wp.func
def cook_torrance_ndf(mat: Material, h: wp.vec3) -> float:
    t = fast_atan2(wp.sqrt(sin2_theta_f(h)), h[2]) / mat.params[0]  # the angle of h (2e-6 rad)
    return wp.exp(-t * t)


@wp.func
def cook_torrance_mo(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    h = half_vec(o, i)
    val = g_over_cos_f(o, i, h) * INV_PI
    return fresnel_eval(mat, wp.dot(i, h)) * val


@wp.func
def torrance_sparrow_ndf(mat: Material, h: wp.vec3) -> float:
    p = mat.params
    return wp.exp(-sin2_theta_f(h) / (h[2] * h[2]) / (p[0] * p[0]))


@wp.func
def torrance_sparrow_mo(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    p = mat.params
    h = half_vec(o, i)
    val = g_over_cos_f(o, i, h) * INV_PI
    hz = wp.max(h[2], 1.0e-6)
    hz2 = hz * hz
    val = val / (4.0 * p[0] * p[0] * hz2 * hz2)
    return fresnel_eval(mat, wp.dot(i, h)) * val


@wp.func
def microfacet_lobe(mat: Material, k: int):
    p = mat.params
    return wp.vec3(0.0, 0.0, 1.0), 2.0 / (p[0] * p[0]), 1.0


@wp.func
def beckmann_sample(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
    return reflect_about(o, beckmann_h(mat.params[0], mat.params[0], u))


@wp.func
def beckmann_pdf(mat: Material, h: wp.vec3) -> float:
    return beckmann_pdf_h(mat.params[0], mat.params[0], h)


def g_over_cos(o, i, h):
    """``G(o, i)/((n·i)(n·o))`` for the V-cavity model, finite at grazing."""
    ci = np.maximum(i[..., 2], 1e-12)
    co = np.maximum(o[..., 2], 1e-12)
    hz = np.maximum(h[..., 2], 0.0)
    oh = np.maximum(np.sum(o * h, axis=-1), 1e-12)
    return np.minimum(1.0 / (ci * co), np.minimum(2.0 * hz / (oh * ci), 2.0 * hz / (oh * co)))


def vcavity_g(o, i, h):
    """The V-cavity ``G(o, i)`` itself (lecture)."""
    hz = h[..., 2]
    oh = np.maximum(np.sum(o * h, axis=-1), 1e-300)
    ih = np.maximum(np.sum(i * h, axis=-1), 1e-300)
    return np.minimum(1.0, np.minimum(2 * hz * o[..., 2] / oh, 2 * hz * i[..., 2] / ih))


class _Microfacet(SpecularBRDF):
    PARAMS = {"kd": KD, "ks": KS, "m": Param("number", "roughness m (Beckmann slope RMS)", lo=0, lo_open=True,
                                             texture=True, slider=(0.02, 1.0), kernel=(0,)), "fresnel": FRESNEL}
    ROUGHNESS = "m"

    def __init__(self, kd=(0.0, 0.0, 0.0), ks=(1.0, 1.0, 1.0), m=0.2, fresnel=None):
        self.kd = as_rgb(kd, "kd")
        self.ks = as_rgb(ks, "ks")
        self.m = as_scalar(m, "m", lo=0.0, lo_open=True)
        self.fresnel = parse_fresnel(fresnel)

    def ndf_analytic_lambda(self):
        return 2.0 / self.m**2

    def kernel_params(self):
        return (self.m, 0.0, 0.0, 0.0)


@register
class CookTorrance(_Microfacet):
    NAME = "cook_torrance"
    CODE = 4
    KERNEL = Kernel(ndf=cook_torrance_ndf, mo=cook_torrance_mo, analytic_lobe=microfacet_lobe, sample=beckmann_sample,
                    pdf_h=beckmann_pdf)

    def mo(self, o, i):
        o, i = dirs(o, i)
        h = half_vector(o, i)
        ih = np.sum(i * h, axis=-1)
        return self.fresnel(ih) * (g_over_cos(o, i, h) / np.pi)[..., None]

    def ndf(self, h):
        h = np.asarray(h, dtype=np.float64)
        t = theta_of(h) / self.m
        return np.where(h[..., 2] > 0, np.exp(-t * t), 0.0)


@register
class TorranceSparrow(_Microfacet):
    NAME = "torrance_sparrow"
    CODE = 5
    ENERGY_NORMALISED = True  # the normalised Beckmann distribution
    KERNEL = Kernel(ndf=torrance_sparrow_ndf, mo=torrance_sparrow_mo, analytic_lobe=microfacet_lobe,
                    sample=beckmann_sample, pdf_h=beckmann_pdf)

    def mo(self, o, i):
        o, i = dirs(o, i)
        h = half_vector(o, i)
        ih = np.sum(i * h, axis=-1)
        hz4 = np.maximum(h[..., 2], 1e-12) ** 4
        val = g_over_cos(o, i, h) / (4.0 * np.pi * self.m**2 * hz4)
        return self.fresnel(ih) * val[..., None]

    def ndf(self, h):
        h = np.asarray(h, dtype=np.float64)
        hz = h[..., 2]
        t2 = sin2_theta(h) / np.maximum(hz * hz, 1e-300) / self.m**2
        return np.where(hz > 0, np.exp(-t2), 0.0)
