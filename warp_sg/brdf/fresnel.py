r"""Fresnel reflectance (lecture "Fresnel reflectance"; paper eq. 14; Schlick 1994).

Each class evaluates ``F(c)`` for the cosine ``c`` between the incident direction and the
microfacet normal (``c = i·h``), returning RGB (..., 3):

* :class:`NoFresnel` — ``F = 1`` (kernel kind 0).
* :class:`Schlick` ``(f0)`` — ``F = f0 + (1 − f0)(1 − c)^5`` (kind 1, ``fresnel_a = f0``).
* :class:`Dielectric` ``(eta)`` — unpolarised dielectric, Cook–Torrance form of paper eq. 14:
  ``g = √(η² + c² − 1)``, ``F = (g−c)²/(2(g+c)²) · (1 + ((c(g+c) − 1)/(c(g−c) + 1))²)``;
  ``F = 1`` under total internal reflection (``g² < 0``) (kind 2, ``fresnel_a = η``).
* :class:`Conductor` ``(eta, k)`` — lecture's conductor formula:
  ``r∥² = ((η²+k²)c² − 2ηc + 1)/((η²+k²)c² + 2ηc + 1)``,
  ``r⊥² = ((η²+k²) − 2ηc + c²)/((η²+k²) + 2ηc + c²)``, ``F = (r∥² + r⊥²)/2``
  (kind 3, ``fresnel_a = η``, ``fresnel_b = k``).

Presets (lecture tables): conductors gold, silver, copper, steel; dielectrics vacuum, air, ice,
water, quartz, glass, sapphire, diamond.
"""
from __future__ import annotations

import numpy as np

from ..core.errors import InputError
from .base import as_rgb, suggest

CONDUCTORS = {
    "gold": (0.370, 2.820),
    "silver": (0.177, 3.638),
    "copper": (0.617, 2.630),
    "steel": (2.485, 3.433),
}
DIELECTRICS = {
    "vacuum": 1.0,
    "air": 1.00029,
    "ice": 1.31,
    "water": 1.333,
    "quartz": 1.46,
    "glass": 1.5,
    "sapphire": 1.77,
    "diamond": 2.42,
}
PRESETS = sorted(["none", *CONDUCTORS, *DIELECTRICS])


def _c(c):
    return np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)[..., None]


def fresnel_eq14(eta, c):
    """Paper eq. 14: ``g = √(η² + c² − 1)``, ``F = (g−c)²/(2(g+c)²) (1 + ((c(g+c)−1)/(c(g−c)+1))²)``,
    1 under total internal reflection (``g² ≤ 0``); ``c`` clipped to [0, 1]; broadcasts ``eta``
    against ``c``. The one numpy implementation (:class:`Dielectric`, ``brdf.models.measured``)."""
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    eta = np.asarray(eta, dtype=np.float64)
    g2 = eta * eta + c * c - 1.0
    g = np.sqrt(np.maximum(g2, 0.0))
    a = (g - c) ** 2 / np.maximum(2.0 * (g + c) ** 2, 1e-300)
    den = c * (g - c) + 1.0
    den = np.where(np.abs(den) < 1e-300, 1e-300, den)
    q = (c * (g + c) - 1.0) / den
    return np.where(g2 > 0, np.clip(a * (1.0 + q * q), 0.0, 1.0), 1.0)


def fresnel_normalised(eta, c):
    """``F(c)/F(1)`` of :func:`fresnel_eq14` (1 where ``F(1) = 0``, i.e. η = 1)."""
    f1 = fresnel_eq14(eta, 1.0)
    return np.where(f1 > 1e-12, fresnel_eq14(eta, c) / np.where(f1 > 1e-12, f1, 1.0), 1.0)


class NoFresnel:
    kind = 0

    def __call__(self, c):
        c = _c(c)
        return np.ones(c.shape[:-1] + (3,))

    def record(self):
        return 0, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)

    def __repr__(self):
        return "NoFresnel()"


class Schlick:
    kind = 1

    def __init__(self, f0, where="fresnel.schlick"):
        self.f0 = as_rgb(f0, where)
        if np.any(self.f0 > 1):
            raise InputError(f"must be in [0, 1], got {self.f0.tolist()}", where=where)

    def __call__(self, c):
        c = _c(c)
        return self.f0 + (1.0 - self.f0) * (1.0 - c) ** 5

    def record(self):
        return 1, tuple(self.f0), (0.0, 0.0, 0.0)

    def __repr__(self):
        return f"Schlick({self.f0.tolist()})"


class Dielectric:
    kind = 2

    def __init__(self, eta, where="fresnel.eta"):
        self.eta = as_rgb(eta, where)
        if np.any(self.eta <= 0):
            raise InputError(f"must be > 0, got {self.eta.tolist()}", where=where)

    def __call__(self, c):
        return fresnel_eq14(self.eta, _c(c))

    def record(self):
        return 2, tuple(self.eta), (0.0, 0.0, 0.0)

    def __repr__(self):
        return f"Dielectric({self.eta.tolist()})"


class Conductor:
    kind = 3

    def __init__(self, eta, k, where="fresnel"):
        self.eta = as_rgb(eta, f"{where}.eta")
        self.k = as_rgb(k, f"{where}.k")
        if np.any(self.eta <= 0):
            raise InputError(f"must be > 0, got {self.eta.tolist()}", where=f"{where}.eta")

    def __call__(self, c):
        c = _c(c)
        e, k = self.eta, self.k
        t = e * e + k * k
        c2 = c * c
        rpar = (t * c2 - 2 * e * c + 1) / (t * c2 + 2 * e * c + 1)
        rper = (t - 2 * e * c + c2) / (t + 2 * e * c + c2)
        return np.clip(0.5 * (rpar + rper), 0.0, 1.0)

    def record(self):
        return 3, tuple(self.eta), tuple(self.k)

    def __repr__(self):
        return f"Conductor({self.eta.tolist()}, {self.k.tolist()})"


def parse_fresnel(value, where="fresnel"):
    """Fresnel from a scene value: ``None``/"none", a preset name ("copper", "glass", ...),
    ``{"schlick": f0}``, ``{"eta": η}`` (dielectric) or ``{"eta": η, "k": k}`` (conductor);
    an existing Fresnel object is returned unchanged. Bad values raise InputError naming ``where``."""
    if value is None:
        return NoFresnel()
    if isinstance(value, (NoFresnel, Schlick, Dielectric, Conductor)):
        return value
    if isinstance(value, str):
        name = value.strip().lower()
        if name == "none":
            return NoFresnel()
        if name in CONDUCTORS:
            return Conductor(*CONDUCTORS[name], where=where)
        if name in DIELECTRICS:
            return Dielectric(DIELECTRICS[name], where=where)
        raise InputError(f"unknown Fresnel preset '{value}'{suggest(name, PRESETS)}; presets: {', '.join(PRESETS)}",
                         where=where)
    if isinstance(value, dict):
        keys = set(value)
        for key in keys:
            if key not in ("schlick", "eta", "k"):
                raise InputError(f"unknown key '{key}'{suggest(key, ['schlick', 'eta', 'k'])}", where=where)
        if keys == {"schlick"}:
            return Schlick(value["schlick"], where=f"{where}.schlick")
        if keys == {"eta"}:
            return Dielectric(value["eta"], where=f"{where}.eta")
        if keys == {"eta", "k"}:
            return Conductor(value["eta"], value["k"], where=where)
        raise InputError("use {schlick = f0}, {eta = η} or {eta = η, k = k}", where=where)
    raise InputError(f"expected a preset name or a table, got {value!r}", where=where)
