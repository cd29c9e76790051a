r"""BRDF models (local frame, z+ = normal), their NDF SG fits and the kernel-side material records.

``ρ(o, i) = kd/π + ks ρs(o, i)``, ``ρs = Mo(o, i) D(h)`` (docs/math.md "BRDF"; paper eq. 8–9).
Models are keyed in :data:`MODELS` by their scene-file names; :func:`make_model` validates the
parameter names (an unknown one raises :class:`~warp_sg.errors.InputError` naming the closest).
The kernel side (``Material`` struct, ``brdf_eval``, ``slice_lobe`` ...) is in
:mod:`warp_sg.brdf.material_wp` (imported on demand: it compiles Warp code).
"""
from __future__ import annotations

import importlib

from ..errors import InputError
from .ashikhmin_shirley import AshikhminShirley
from .base import BRDF, SpecularBRDF, suggest
from .energy import check_diffuse_albedo
from .ggx import GGX
from .fresnel import Conductor, Dielectric, NoFresnel, Schlick, parse_fresnel
from .lafortune import Lafortune
from .lambert import Lambert, OrenNayar
from .microfacet import CookTorrance, TorranceSparrow
from .phong import BlinnPhong, Phong
from .ward import Ward
from .warp import slice_lobes_numpy, spherical_warp


class _LazyMeasured:
    """Stands for ``warp_sg.brdf.measured.Measured`` until first use (keeps imports light)."""

    NAME = "measured"

    @staticmethod
    def _cls():
        return importlib.import_module("warp_sg.brdf.measured").Measured

    def __call__(self, *args, **kwargs):
        return self._cls()(*args, **kwargs)

    def __getattr__(self, name):
        return getattr(self._cls(), name)

    def __repr__(self):
        return "<lazy warp_sg.brdf.measured.Measured>"


MODELS = {
    "lambert": Lambert,
    "oren_nayar": OrenNayar,
    "phong": Phong,
    "blinn_phong": BlinnPhong,
    "cook_torrance": CookTorrance,
    "torrance_sparrow": TorranceSparrow,
    "ward": Ward,
    "ashikhmin_shirley": AshikhminShirley,
    "lafortune": Lafortune,
    "ggx": GGX,
    "measured": _LazyMeasured(),
}


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


def __getattr__(name):
    if name == "Measured":
        return importlib.import_module("warp_sg.brdf.measured").Measured
    if name == "material_wp":
        return importlib.import_module("warp_sg.brdf.material_wp")
    raise AttributeError(f"module 'warp_sg.brdf' has no attribute {name!r}")


__all__ = [
    "BRDF", "SpecularBRDF", "Lambert", "OrenNayar", "Phong", "BlinnPhong", "CookTorrance",
    "TorranceSparrow", "Ward", "AshikhminShirley", "Lafortune", "GGX", "Measured", "NoFresnel", "Schlick",
    "Dielectric", "Conductor", "parse_fresnel", "MODELS", "make_model", "spherical_warp",
    "slice_lobes_numpy",
]
