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
"""
from __future__ import annotations

import numpy as np

from .base import SpecularBRDF, as_rgb, as_scalar, dirs, log_cos_theta


def _cos_pow(v, n):
    """``max(0, v_z)^n`` via ``exp(n ln v_z)`` (stable near the axis)."""
    vz = v[..., 2]
    with np.errstate(divide="ignore"):
        return np.where(vz > 0, np.exp(n * log_cos_theta(v)), 0.0)


class _CosinePower(SpecularBRDF):
    """Shared by Phong and Blinn–Phong: parameters (kd, ks, n), ``Mo = (n+2)/(2π)``, analytic SG
    sharpness ``λ = n`` and the kernel parameters."""

    PARAMS = ("kd", "ks", "n")

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


class BlinnPhong(_CosinePower):
    NAME = "blinn_phong"
    MODEL_ID = 3


class Phong(_CosinePower):
    NAME = "phong"
    MODEL_ID = 2

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
