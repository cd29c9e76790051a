r"""Anisotropic Ashikhmin–Shirley specular model (supplement eq. 12–14; lecture "Ashikmin-Shirley model").

``ρs = √((nu+1)(nv+1)) (n·h)^{nu cos²φh + nv sin²φh} F(h·i) / (8π (h·i) max(n·i, n·o))``,
``Mo = √((nu+1)(nv+1)) F(h·i) / (8π (h·i) max(n·i, n·o))`` (eq. 12),
``D(h) = (n·h)^{nu cos²φh + nv sin²φh}`` (eq. 13), φh measured from the tangent x.

D is evaluated as ``exp((nu hx² + nv hy²) · ln(hz)/(hx² + hy²))`` with
``ln(hz)/(hx²+hy²) = log1p(−s²/(1+hz))/s²`` (limit ``−1/(1+hz)`` at s² → 0): finite everywhere.

SG mixture (eq. 14): N lobes (odd, parameter ``lobes``) spread along the wide axis (the tangent
direction with the smaller exponent), constant sharpness ``λi = max(nu, nv)``,
``θv = arccos(ε^{1/(n_min+1)})`` — the angle where D along the wide axis falls to ≈ ε (ε = 0.1;
the flattened supplement text prints the exponent as 1/(N+1), which contradicts its own
definition of θv, so we use the definition) — spacing ``θi = 2θv/(N+1)``, lobe k at angle
``(k − (N−1)/2) θi`` from the normal, amplitude ``μi = D(pi)``. Axes are in the local frame
(x = tangent), so they are not symmetric about z.
``fresnel``: anything :func:`parse_fresnel` accepts (default: none, F = 1).

Kernel side (float32, same forms): the analytic lobes, and their quadrant sampling with
``p(h) = √((nu+1)(nv+1))/(2π) (n·h)^{nu cos²φ + nv sin²φ}``.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import numpy as np
import warp as wp

from ...core.errors import InputError
from ...sg import EPSILON
from ..base import SpecularBRDF, as_rgb, as_scalar, dirs, half_vector
from ..fresnel import parse_fresnel
from ..kernel.material_eval_wp import aniso_axis, as_exponent_log, expm1_neg_f, fresnel_eval, half_vec
from ..kernel.material_sample_wp import as_h, as_pdf_h, reflect_about
from ..kernel.material_struct import LN_EPS, PI, Material
from ..params import FRESNEL, KD, KS, Param
from ..registry import Kernel, register


@wp.func
def ashikhmin_shirley_ndf(mat: Material, h: wp.vec3) -> float:
    return wp.exp(as_exponent_log(h, mat.params[0], mat.params[1]))


@wp.func
def ashikhmin_shirley_mo(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    p = mat.params
    h = half_vec(o, i)
    ih = wp.max(wp.dot(i, h), 1.0e-12)
    cmax = wp.max(wp.max(i[2], o[2]), 1.0e-12)
    val = wp.sqrt((p[0] + 1.0) * (p[1] + 1.0)) / (8.0 * PI * ih * cmax)
    return fresnel_eval(mat, ih) * val


@wp.func
def ashikhmin_shirley_lobe(mat: Material, k: int):
    """One lobe λ = n (isotropic), else the layout of supplement eq. 14 (sharpness max(nu, nv),
    θv = arccos(ε^{1/(nmin+1)}))."""
    p = mat.params
    if p[0] == p[1]:
        return wp.vec3(0.0, 0.0, 1.0), wp.max(p[0], 1.0e-6), 1.0
    nmin = wp.min(p[0], p[1])
    nmax = wp.max(p[0], p[1])
    # θv = arccos(ε^{1/(nmin+1)}) = 2 asin(√((1 − ε^{1/(nmin+1)})/2))
    omc = expm1_neg_f(-LN_EPS / (nmin + 1.0))
    theta_v = 2.0 * wp.asin(wp.sqrt(0.5 * omc))
    wide_x = int(0)
    if p[0] < p[1]:
        wide_x = 1
    axis = aniso_axis(mat.lobe_count, k, theta_v, wide_x)
    return axis, nmax, ashikhmin_shirley_ndf(mat, axis)


@wp.func
def ashikhmin_shirley_sample(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
    return reflect_about(o, as_h(mat.params[0], mat.params[1], u))


@wp.func
def ashikhmin_shirley_pdf_h(mat: Material, h: wp.vec3) -> float:
    return as_pdf_h(mat.params[0], mat.params[1], h)


def aniso_log_cos(h):
    """``(ln hz / (hx² + hy²), hx², hy²)`` with the stable limit at the normal."""
    hx2 = h[..., 0] ** 2
    hy2 = h[..., 1] ** 2
    s2 = hx2 + hy2
    hz = np.maximum(h[..., 2], 0.0)
    small = s2 < 1e-12
    s2s = np.where(small, 1.0, s2)
    with np.errstate(divide="ignore"):  # h on the horizon (hz = 0): ln 0 = −inf, so D = exp(n·L) = 0
        L = np.where(small, -1.0 / (1.0 + hz), np.log1p(-np.minimum(s2s / (1.0 + hz), 1.0)) / s2s)
    return L, hx2, hy2


@register
class AshikhminShirley(SpecularBRDF):
    NAME = "ashikhmin_shirley"
    CODE = 7
    ROUGHNESS = "nu"
    KERNEL = Kernel(ndf=ashikhmin_shirley_ndf, mo=ashikhmin_shirley_mo, analytic_lobe=ashikhmin_shirley_lobe,
                    sample=ashikhmin_shirley_sample, pdf_h=ashikhmin_shirley_pdf_h)
    PARAMS = {"kd": KD, "ks": KS,
              "nu": Param("number", "exponent along the tangent", lo=0, texture=True, slider=(1.0, 2000.0), kernel=(0,)),
              "nv": Param("number", "exponent along the bitangent", lo=0, texture=True, slider=(1.0, 2000.0), kernel=(1,)),
              "fresnel": FRESNEL,
              "lobes": Param("integer", "number of SG lobes (odd) along the longer axis", lo=1, odd=True)}

    def __init__(self, kd=(0.0, 0.0, 0.0), ks=(1.0, 1.0, 1.0), nu=100.0, nv=100.0, fresnel=None, lobes=7):
        self.kd = as_rgb(kd, "kd")
        self.ks = as_rgb(ks, "ks")
        self.nu = as_scalar(nu, "nu", lo=0.0)
        self.nv = as_scalar(nv, "nv", lo=0.0)
        try:
            n = int(lobes)
        except (TypeError, ValueError):
            raise InputError(f"expected an odd integer, got {lobes!r}", where="lobes") from None
        if n != lobes or n < 1 or n % 2 == 0:
            raise InputError(f"must be an odd integer >= 1, got {lobes!r}", where="lobes")
        self.lobes = n
        self.own_lobes = n if self.nu != self.nv else None
        self.fresnel = parse_fresnel(fresnel)

    @property
    def isotropic(self):
        return self.nu == self.nv

    def mo(self, o, i):
        o, i = dirs(o, i)
        h = half_vector(o, i)
        ih = np.maximum(np.sum(i * h, axis=-1), 1e-12)
        cmax = np.maximum(np.maximum(i[..., 2], o[..., 2]), 1e-12)
        val = np.sqrt((self.nu + 1) * (self.nv + 1)) / (8.0 * np.pi * ih * cmax)
        return self.fresnel(ih) * val[..., None]

    def ndf(self, h):
        h = np.asarray(h, dtype=np.float64)
        L, hx2, hy2 = aniso_log_cos(h)
        return np.where(h[..., 2] > 0, np.exp((self.nu * hx2 + self.nv * hy2) * L), 0.0)

    def ndf_analytic_lambda(self):
        return max(self.nu, self.nv, 1e-6)

    def aniso_layout(self):
        """``(λ, θv, wide_x)`` of the anisotropic layout (supplement eq. 14): ``max(nu, nv)``,
        ``θv = arccos(ε^{1/(nmin+1)})``, wide along x when the x exponent is smaller."""
        nmin, nmax = min(self.nu, self.nv), max(self.nu, self.nv)
        theta_v = np.arccos(EPSILON ** (1.0 / (nmin + 1.0)))
        return nmax, theta_v, self.nu < self.nv

    def kernel_params(self):
        return (self.nu, self.nv, 0.0, 0.0)
