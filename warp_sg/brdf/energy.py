r"""Energy conservation: how much of the light it receives a material may reflect.

* **Every model, an error.** The Lambert term alone reflects ``kd`` of the incident light
  (``∫ kd/π cos θ dω = kd``), so ``kd > 1`` in any channel is refused (:func:`check_diffuse_albedo`,
  an :class:`~warp_sg.core.errors.InputError` naming ``kd``). Such a value is a mistake of units
  (0–255, per cent): ``kd = 5`` makes a surface brighter than the light falling on it.
* **Normalised models, a warning.** For the models whose specular lobe is normalised (they declare
  ``ENERGY_NORMALISED``, :func:`~warp_sg.brdf.registry.energy_normalised`: with ``ks = 1`` and
  ``F = 1`` the lobe reflects at most all the light — Phong's ``(n+2)/2π``, the normalised Beckmann
  of Torrance–Sparrow, Ward, GGX with Smith masking)
  the reflectance at normal incidence is at most ``R₀ = kd + ks · F(0°)`` per channel
  (``F(0°)`` = 1 without a Fresnel term). :func:`energy_excess` says so when ``R₀ > 1``; the scene
  loader turns it into one ``InputWarning`` line for the values a scene file states. It is not an
  error: the renderer and the Monte-Carlo reference agree on such a material (the image is the
  right image of what was asked), and sums a little over 1 are common in assets (a white glTF
  dielectric has ``kd = 1``, ``F0 = 0.04``; glTF's own BRDF weights the diffuse term by
  ``1 − F``, which this model does not).

The other models are not checked beyond ``kd``: ``cook_torrance`` (its ``D`` peaks at 1, so ``ks``
is not an albedo: the gold example has ``ks = 10``), ``blinn_phong`` (the supplement's
normalisation: albedo up to 4), ``lafortune``, ``ashikhmin_shirley`` and ``measured``.
"""
from __future__ import annotations

import numpy as np

from ..core.errors import InputError
from .registry import MODELS, energy_normalised


def normalised_models() -> tuple:
    """The names of the registered models whose specular lobe reflects at most all the light for
    ``ks = 1``, ``F = 1`` (``ENERGY_NORMALISED``)."""
    return tuple(name for name, cls in MODELS.items() if energy_normalised(cls))


def check_diffuse_albedo(model) -> None:
    """Refuse a model whose diffuse albedo ``kd`` exceeds 1 in a channel (module docstring)."""
    kd = np.asarray(getattr(model, "kd", np.zeros(3)), np.float64)
    if np.any(kd > 1.0):
        raise InputError(f"must be <= 1, got {kd.tolist()}: a diffuse albedo above 1 reflects more light than the "
                         f"surface receives (colours are 0-1, not 0-255 or per cent)", where="kd")


def normal_incidence_reflectance(model) -> np.ndarray | None:
    """``R₀ = kd + ks · F(0°)`` (RGB) of a model that declares ``ENERGY_NORMALISED``, else None."""
    if not energy_normalised(model):
        return None
    f = getattr(model, "fresnel", None)
    f0 = np.ones(3) if f is None else np.asarray(f(np.ones(1)), np.float64).reshape(-1, 3)[0]
    return np.asarray(model.kd, np.float64) + np.asarray(model.ks, np.float64) * f0


def energy_excess(model) -> str | None:
    """One line when an ``ENERGY_NORMALISED`` model reflects more than it receives at normal incidence
    (``R₀ > 1`` in a channel), else None."""
    r0 = normal_incidence_reflectance(model)
    if r0 is None or not np.any(r0 > 1.0 + 1e-9):
        return None
    term = "kd + ks" if getattr(model, "fresnel", None) is None or type(model.fresnel).__name__ == "NoFresnel" \
        else "kd + ks·F(0°)"
    return (f"{term} = {np.round(r0, 4).tolist()} > 1: the '{model.NAME}' material reflects more light than it "
            f"receives at normal incidence (energy is not conserved)")


__all__ = ["normalised_models", "check_diffuse_albedo", "normal_incidence_reflectance", "energy_excess"]
