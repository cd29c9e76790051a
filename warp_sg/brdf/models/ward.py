r"""Ward model, isotropic and anisotropic (lecture "Ward model"; supplement eq. 4–6).

``ρs = exp(−tan²θh (cos²φh/αx² + sin²φh/αy²)) / (4π αx αy √((n·i)(n·o)))``; isotropic:
``αx = αy = α``. Factorised as ``Mo = 1/(4π αx αy √((n·i)(n·o)))`` (eq. 5) and
``D(h) = exp(−(hx²/αx² + hy²/αy²)/hz²)`` (eq. 6; ``tan²θh cos²φh = hx²/hz²``), whose isotropic
single-lobe SG is ``λ = 2/α², μ = 1``. Anisotropic NDFs get N lobes (odd) spread along the wider
axis, built like Ashikhmin–Shirley (supplement eq. 14): sharpness ``2/min(α)²``, the extent
``θv`` where D falls to ε = 0.1 along the wide axis (``tan θv = max(α) √(−ln ε)``),
``θi = 2θv/(N+1)``, amplitudes ``D(pi)``.
The ``√((n·i)(n·o))`` factor is clamped at 1e-12 (finite at grazing).

Kernel side (float32, same forms): the analytic lobes (one isotropic lobe, or the anisotropic
layout) and Beckmann slope sampling (Ward 1992) with
``p(h) = exp(−(hx²/αx² + hy²/αy²)/hz²)/(π αx αy cos³θh)``.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import numpy as np
import warp as wp

from ...sg import EPSILON
from ..base import SpecularBRDF, as_rgb, as_roughness, dirs
from ..kernel.material_eval_wp import aniso_axis
from ..kernel.material_sample_wp import beckmann_h, beckmann_pdf_h, reflect_about
from ..kernel.material_struct import LN_EPS, PI, Material
from ..params import ALPHA_X, ALPHA_Y, KD, KS, Param
from ..registry import Kernel, register


@wp.func
def ward_ndf(mat: Material, h: wp.vec3) -> float:
    p = mat.params
    e = (h[0] * h[0] / (p[0] * p[0]) + h[1] * h[1] / (p[1] * p[1])) / (h[2] * h[2])
    return wp.exp(-e)


@wp.func
def ward_mo(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    p = mat.params
    c = wp.sqrt(wp.max(o[2] * i[2], 1.0e-12))
    return wp.vec3(1.0, 1.0, 1.0) * (1.0 / (4.0 * PI * p[0] * p[1] * c))


@wp.func
def ward_lobe(mat: Material, k: int):
    """One lobe 2/α² (isotropic), else the layout of supplement eq. 14 (sharpness 2/min(α)²,
    tan θv = max(α) √(−ln ε))."""
    p = mat.params
    if p[0] == p[1]:
        return wp.vec3(0.0, 0.0, 1.0), 2.0 / (p[0] * p[0]), 1.0
    amin = wp.min(p[0], p[1])
    amax = wp.max(p[0], p[1])
    wide_x = int(0)
    if p[0] > p[1]:
        wide_x = 1
    axis = aniso_axis(mat.lobe_count, k, wp.atan(amax * wp.sqrt(-LN_EPS)), wide_x)
    return axis, 2.0 / (amin * amin), ward_ndf(mat, axis)


@wp.func
def ward_sample(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
    return reflect_about(o, beckmann_h(mat.params[0], mat.params[1], u))


@wp.func
def ward_pdf_h(mat: Material, h: wp.vec3) -> float:
    return beckmann_pdf_h(mat.params[0], mat.params[1], h)


@register
class Ward(SpecularBRDF):
    NAME = "ward"
    CODE = 6
    ROUGHNESS = "alpha"  # (an α map sets αx = αy: its Param.kernel)
    ENERGY_NORMALISED = True
    KERNEL = Kernel(ndf=ward_ndf, mo=ward_mo, analytic_lobe=ward_lobe, sample=ward_sample, pdf_h=ward_pdf_h)
    PARAMS = {"kd": KD, "ks": KS, "alpha": Param("number", "isotropic roughness α", lo=0, lo_open=True, texture=True,
                                                 slider=(0.02, 0.8), kernel=(0, 1)),
              "alpha_x": ALPHA_X, "alpha_y": ALPHA_Y}

    def __init__(self, kd=(0.0, 0.0, 0.0), ks=(1.0, 1.0, 1.0), alpha=None, alpha_x=None, alpha_y=None):
        self.kd = as_rgb(kd, "kd")
        self.ks = as_rgb(ks, "ks")
        self.alpha_x, self.alpha_y = as_roughness(alpha, alpha_x, alpha_y, 0.15, "Ward")
        self.alpha = self.alpha_x if self.isotropic else None

    @property
    def isotropic(self):
        return self.alpha_x == self.alpha_y

    def mo(self, o, i):
        o, i = dirs(o, i)
        c = np.sqrt(np.maximum(o[..., 2] * i[..., 2], 1e-12))
        val = 1.0 / (4.0 * np.pi * self.alpha_x * self.alpha_y * c)
        return np.broadcast_to(val[..., None], val.shape + (3,)).copy()

    def ndf(self, h):
        h = np.asarray(h, dtype=np.float64)
        hz = h[..., 2]
        e = (h[..., 0] ** 2 / self.alpha_x**2 + h[..., 1] ** 2 / self.alpha_y**2) / np.maximum(hz * hz, 1e-300)
        return np.where(hz > 0, np.exp(-e), 0.0)

    def ndf_analytic_lambda(self):
        return 2.0 / min(self.alpha_x, self.alpha_y) ** 2

    def aniso_layout(self):
        """``(λ, θv, wide_x)`` of the anisotropic layout (supplement eq. 14): ``2/min(α)²``,
        ``tan θv = max(α) √(−ln ε)``, wide along x when ``αx > αy``."""
        amin, amax = min(self.alpha_x, self.alpha_y), max(self.alpha_x, self.alpha_y)
        theta_v = np.arctan(amax * np.sqrt(-np.log(EPSILON)))
        return 2.0 / amin**2, theta_v, self.alpha_x > self.alpha_y

    def kernel_params(self):
        return (self.alpha_x, self.alpha_y, 0.0, 0.0)
