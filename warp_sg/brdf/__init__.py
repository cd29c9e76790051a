r"""BRDF models (local frame, z+ = normal), their NDF SG fits and the kernel-side material records.

``ρ(o, i) = kd/π + ks ρs(o, i)``, ``ρs = Mo(o, i) D(h)`` (docs/math.md "BRDF"; paper eq. 8–9).
Models are keyed in :data:`MODELS` by their scene-file names, in one registry
(:mod:`warp_sg.brdf.registry`: each model is one class in :mod:`warp_sg.brdf.models` that declares
its name, kernel code, parameters, fit hooks and kernel ``@wp.func`` functions); :func:`make_model`
validates the parameter names (an unknown one raises :class:`~warp_sg.core.errors.InputError` naming
the closest). The kernel side (``Material`` struct, ``brdf_eval``, ``slice_lobe`` ..., generated
from the registry) is in :mod:`warp_sg.brdf.kernel.material_wp`.
"""
from __future__ import annotations

from ..core.errors import InputError
from . import models  # noqa: F401  (imports and registers every model)
from .base import BRDF, SpecularBRDF, suggest
from .energy import check_diffuse_albedo
from .fresnel import Conductor, Dielectric, NoFresnel, Schlick, parse_fresnel
from .models.ashikhmin_shirley import AshikhminShirley
from .models.ggx import GGX
from .models.lafortune import Lafortune
from .models.lambert import Lambert, OrenNayar
from .models.measured import Measured
from .models.microfacet import CookTorrance, TorranceSparrow
from .models.phong import BlinnPhong, Phong
from .models.ward import Ward
from .registry import MODELS
from .spherical_warp import slice_lobes_numpy, spherical_warp


def make_model(name, **params):
    """Build the model called ``name`` (a key of :data:`MODELS`) from scene-file parameters."""
    if name not in MODELS:
        raise InputError(f"unknown BRDF model '{name}'{suggest(name, MODELS)}; models: {', '.join(MODELS)}",
                         where="model")
    cls = MODELS[name]
    allowed = tuple(cls.PARAMS)
    for key in params:
        if key not in allowed:
            raise InputError(f"unknown parameter '{key}' for model '{name}'{suggest(key, allowed)}; "
                             f"parameters: {', '.join(allowed)}", where=key)
    model = cls(**params)
    check_diffuse_albedo(model)
    return model


__all__ = [
    "BRDF", "SpecularBRDF", "Lambert", "OrenNayar", "Phong", "BlinnPhong", "CookTorrance",
    "TorranceSparrow", "Ward", "AshikhminShirley", "Lafortune", "GGX", "Measured", "NoFresnel", "Schlick",
    "Dielectric", "Conductor", "parse_fresnel", "MODELS", "make_model", "spherical_warp",
    "slice_lobes_numpy",
]
