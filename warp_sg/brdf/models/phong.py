r"""Phong and Blinn–Phong, normalised by ``(n+2)/(2π)`` (lecture "Specular shading"; supplement eq. 7–9).

* Phong: ``ρs(o, i) = (n+2)/(2π) · max(0, r·i)^n`` with the mirror direction ``r = 2(n·o)n − o``.
  Its lobe lives around ``r`` (not a half-vector model): ``Mo = (n+2)/(2π)`` and the "NDF" is the
  lobe ``D(v) = max(0, v_z)^n`` of the reflected direction ``v = R_o⁻¹ i`` (``v_z = r·i``); the
  BRDF slice is its SG ``G(i; r, λ, μ)`` directly (no warp).
* Blinn–Phong: ``ρs(o, i) = (n+2)/(2π) · (n·h)^n`` (supplement eq. 7), ``Mo = (n+2)/(2π)`` (eq. 8),
  ``D(h) = (n·h)^n ≈ exp(−n(1 − n·h))`` (eq. 9): analytic SG ``λ = n, μ = 1``.
  Note: with this (supplement) normalisation Blinn–Phong is not energy conserving for large n
  (its albedo tends to 4 at normal incidence as n → ∞; the energy-conserving factor would be
  (n+8)/(8π)); ``ks`` must absorb it.

Kernel side (float32, same forms): ``D = max(0, v_z)^n`` (``cos_pow``), ``Mo = (n+2)/(2π)``; analytic
lobe ``λ = max(n, 1e-6)``. Phong's slice is the NDF lobe moved to the mirror direction with
amplitude ``ks (n+2)/(2π) μ`` (no warp) and its sampling a cosine-power lobe about the mirror
direction; Blinn–Phong samples ``cos θh = u^{1/(n+2)}``, ``p(h) = (n+2)/(2π) (n·h)^{n+1}``.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import numpy as np
import warp as wp

from ..base import SpecularBRDF, as_rgb, as_scalar, dirs, log_cos_theta
from ..kernel.material_eval_wp import cos_pow, log1p_f, reflect_z
from ..kernel.material_eval_wp import log_cos_theta as log_cos_theta_f
from ..kernel.material_sample_wp import cos_power_dir, cos_power_pdf, reflect_about
from ..kernel.material_struct import TWO_PI, Material
from ..params import KD, KS, Param
from ..registry import Kernel, register


@wp.func
def cosine_power_ndf(mat: Material, h: wp.vec3) -> float:
    return cos_pow(h, mat.params[0])


@wp.func
def cosine_power_mo(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    return wp.vec3(1.0, 1.0, 1.0) * ((mat.params[0] + 2.0) / TWO_PI)


@wp.func
def cosine_power_lobe(mat: Material, k: int):
    return wp.vec3(0.0, 0.0, 1.0), wp.max(mat.params[0], 1.0e-6), 1.0


@wp.func
def phong_specular(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    """(n+2)/(2π) (r·i)^n with ln(r·i) = log1p(−‖r − i‖²/2)."""
    r = reflect_z(o)
    d = r - i
    omd = 0.5 * wp.dot(d, d)
    if omd >= 1.0:
        return wp.vec3(0.0, 0.0, 0.0)
    lobe = wp.exp(mat.params[0] * log1p_f(-omd))
    return wp.vec3(1.0, 1.0, 1.0) * ((mat.params[0] + 2.0) / TWO_PI * lobe)


@wp.func
def phong_slice_of_lobe(mat: Material, o: wp.vec3, axis: wp.vec3, lam: float, mu: float):
    return reflect_z(o), lam, mat.ks * ((mat.params[0] + 2.0) / TWO_PI * mu)


@wp.func
def phong_sample(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
    return cos_power_dir(reflect_z(o), mat.params[0], u)


@wp.func
def phong_pdf(mat: Material, o: wp.vec3, i: wp.vec3) -> float:
    return cos_power_pdf(reflect_z(o), mat.params[0], i)


@wp.func
def blinn_phong_sample(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
    ct = wp.pow(wp.max(u[0], 1.0e-30), 1.0 / (mat.params[0] + 2.0))
    st = wp.sqrt(wp.max(1.0 - ct * ct, 0.0))
    phi = TWO_PI * u[1]
    h = wp.vec3(st * wp.cos(phi), st * wp.sin(phi), ct)
    return reflect_about(o, h)


@wp.func
def blinn_phong_pdf_h(mat: Material, h: wp.vec3) -> float:
    ph = float(0.0)
    if h[2] > 0.0:
        ph = (mat.params[0] + 2.0) / TWO_PI * wp.exp((mat.params[0] + 1.0) * log_cos_theta_f(h))
    return ph


def _cos_pow(v, n):
    """``max(0, v_z)^n`` via ``exp(n ln v_z)`` (stable near the axis)."""
    vz = v[..., 2]
    with np.errstate(divide="ignore"):
        return np.where(vz > 0, np.exp(n * log_cos_theta(v)), 0.0)


class _CosinePower(SpecularBRDF):
    """Shared by Phong and Blinn–Phong: parameters (kd, ks, n), ``Mo = (n+2)/(2π)``, analytic SG
    sharpness ``λ = n`` and the kernel parameters."""

    PARAMS = {"kd": KD, "ks": KS, "n": Param("number", "Phong exponent", lo=0, texture=True, slider=(1.0, 1000.0),
                                             kernel=(0,))}
    ROUGHNESS = "n"

    def __init__(self, kd=(0.0, 0.0, 0.0), ks=(1.0, 1.0, 1.0), n=50.0):
        self.kd = as_rgb(kd, "kd")
        self.ks = as_rgb(ks, "ks")
        self.n = as_scalar(n, "n", lo=0.0)

    def mo(self, o, i):
        o, i = dirs(o, i)
        return np.full(o.shape[:-1] + (3,), (self.n + 2.0) / (2.0 * np.pi))

    def ndf(self, v):
        """``max(0, v_z)^n``: of the half vector (Blinn–Phong) or of the direction expressed in the
        mirror frame, ``v_z = r·i`` (Phong)."""
        return _cos_pow(np.asarray(v, dtype=np.float64), self.n)

    def ndf_analytic_lambda(self):
        return max(self.n, 1e-6)

    def kernel_params(self):
        return (self.n, 0.0, 0.0, 0.0)


@register
class BlinnPhong(_CosinePower):
    NAME = "blinn_phong"
    CODE = 3
    KERNEL = Kernel(ndf=cosine_power_ndf, mo=cosine_power_mo, analytic_lobe=cosine_power_lobe,
                    sample=blinn_phong_sample, pdf_h=blinn_phong_pdf_h)


@register
class Phong(_CosinePower):
    NAME = "phong"
    CODE = 2
    ENERGY_NORMALISED = True  # (n+2)/2π
    KERNEL = Kernel(ndf=cosine_power_ndf, mo=cosine_power_mo, analytic_lobe=cosine_power_lobe, specular=phong_specular,
                    slice_of_lobe=phong_slice_of_lobe, sample=phong_sample, pdf=phong_pdf)
    #: the numpy slice (``spherical_warp.slice_lobes_numpy``): the NDF lobes moved to the mirror direction
    slice_about_mirror = True

    def specular(self, o, i):
        o, i = dirs(o, i)
        r = o * np.array([-1.0, -1.0, 1.0])
        c = np.sum(r * i, axis=-1)
        # (r·i)^n = exp(n ln c), with ln c = log1p(−‖r − i‖²/2)
        d = r - i
        omd = 0.5 * np.sum(d * d, axis=-1)
        with np.errstate(divide="ignore"):
            lobe = np.where(c > 0, np.exp(self.n * np.log1p(-np.minimum(omd, 1.0))), 0.0)
        val = (self.n + 2.0) / (2.0 * np.pi) * lobe
        up = (o[..., 2] > 0) & (i[..., 2] > 0)
        return np.where(up[..., None], val[..., None] * np.ones(3), 0.0)
