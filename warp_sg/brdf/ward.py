r"""Ward model, isotropic and anisotropic (lecture "Ward model"; supplement eq. 4–6).

``ρs = exp(−tan²θh (cos²φh/αx² + sin²φh/αy²)) / (4π αx αy √((n·i)(n·o)))``; isotropic:
``αx = αy = α``. Factorised as ``Mo = 1/(4π αx αy √((n·i)(n·o)))`` (eq. 5) and
``D(h) = exp(−(hx²/αx² + hy²/αy²)/hz²)`` (eq. 6; ``tan²θh cos²φh = hx²/hz²``), whose isotropic
single-lobe SG is ``λ = 2/α², μ = 1``. Anisotropic NDFs get N lobes (odd) spread along the wider
axis, built like Ashikhmin–Shirley (supplement eq. 14): sharpness ``2/min(α)²``, the extent
``θv`` where D falls to ε = 0.1 along the wide axis (``tan θv = max(α) √(−ln ε)``),
``θi = 2θv/(N+1)``, amplitudes ``D(pi)``.
The ``√((n·i)(n·o))`` factor is clamped at 1e-12 (finite at grazing).
"""
from __future__ import annotations

import numpy as np

from .base import SpecularBRDF, as_rgb, as_roughness, dirs


class Ward(SpecularBRDF):
    NAME = "ward"
    MODEL_ID = 6
    PARAMS = ("kd", "ks", "alpha", "alpha_x", "alpha_y")

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

    def kernel_params(self):
        return (self.alpha_x, self.alpha_y, 0.0, 0.0)
