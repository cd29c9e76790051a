r"""Shared machinery of the BRDF model classes (numpy, float64).

Every model is ``ρ(o, i) = kd/π + ks · ρs(o, i)`` in the local frame (z+ = normal, x = tangent),
with directions pointing away from the surface (docs/math.md "BRDF"). Specular models factor
``ρs(o, i) = Mo(o, i) · D(h)``, ``h = (o + i)/‖o + i‖`` (paper eq. 9), keep ``Mo`` analytic and fit
the NDF ``D`` by spherical Gaussians (supplement §2–3).

Numerical forms used by every model (float64 here, same forms in ``material_wp``):

* ``ln(h·n) = log1p(−(hx² + hy²)/(1 + hz))`` — no cancellation near the normal;
* ``θh = atan2(√(hx² + hy²), hz)`` instead of ``arccos(hz)``;
* ``tan²θh = (hx² + hy²)/hz²``.
"""
from __future__ import annotations

import numpy as np

from .helpers import (  # noqa: F401
    COS_EPS,
    INV_PI,
    as_rgb,
    as_roughness,
    as_scalar,
    dirs,
    half_vector,
    log_cos_theta,
    reflect_z,
    sin2_theta,
    suggest,
    theta_of,
    upper,
)


class BRDF:
    """Base class. A model (:mod:`warp_sg.brdf.registry`) sets ``NAME``, ``CODE``, ``PARAMS`` and
    ``KERNEL`` (its ``@wp.func`` functions) and implements ``diffuse`` and, for specular models, ``mo`` and
    ``ndf``.

    What the rest of the code asks of a model it reads from these class attributes, never from the
    model's code (:mod:`warp_sg.brdf.registry` collects them per code): ``is_specular`` (a specular
    lobe: the environment's specular term, its albedo table, the kernel variant's specular paths),
    ``ROUGHNESS`` (the name of its lobe-width parameter, or None) and ``ENERGY_NORMALISED`` (the energy check of
    :mod:`warp_sg.brdf.energy`)."""

    NAME = "base"
    #: the kernel code (``Material.model``), unique per registered model
    CODE = -1
    #: the scene-file parameters, ``{name: warp_sg.brdf.params.Param}`` (in constructor order)
    PARAMS: dict = {}
    #: the kernel side (:class:`warp_sg.brdf.registry.Kernel`), set by the model's module
    KERNEL = None
    #: a specular lobe (``ks ρs``); False: the diffuse part alone
    is_specular = False
    #: the name of the lobe-width parameter a texture may set per texel (a texturable number of
    #: ``PARAMS``, whose ``kernel`` says which kernel parameters a texel sets): the albedo table's
    #: second axis (:mod:`warp_sg.brdf.kernel.albedo`); None: none
    ROUGHNESS: str | None = None
    #: the specular lobe reflects at most all the light for ``ks = 1`` and ``F = 1`` (its
    #: normalisation), so ``kd + ks·F(0°) > 1`` is worth a warning (:mod:`warp_sg.brdf.energy`)
    ENERGY_NORMALISED = False

    kd = np.zeros(3)
    ks = np.zeros(3)

    # -- exact evaluation -------------------------------------------------------------------
    @property
    def diffuse_albedo(self):
        return self.kd

    def diffuse(self, o, i):
        """Diffuse part ``kd/π`` (Lambert), (..., 3); zero below the horizon."""
        o, i = dirs(o, i)
        up = upper(o, i)
        return np.where(up[..., None], self.kd * INV_PI, 0.0)

    def specular(self, o, i):
        """``ρs(o, i)`` without ``ks`` (..., 3); zero below the horizon."""
        o, i = dirs(o, i)
        if not self.is_specular:
            return np.zeros(o.shape[:-1] + (3,))
        h = half_vector(o, i)
        val = self.mo(o, i) * self.ndf(h)[..., None]
        return np.where(upper(o, i)[..., None], val, 0.0)

    def eval(self, o, i):
        """Exact BRDF ``kd/π + ks ρs(o, i)`` (..., 3) in the local frame; 0 below the horizon."""
        o, i = dirs(o, i)
        val = self.diffuse(o, i)
        if self.is_specular:
            val = val + self.ks * self.specular(o, i)
        return np.where(upper(o, i)[..., None], val, 0.0)

    # -- kernel record ------------------------------------------------------------------------
    def kernel_params(self):
        return (0.0, 0.0, 0.0, 0.0)

    def fresnel_record(self):
        f = getattr(self, "fresnel", None)
        if f is None:
            return 0, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)
        return f.record()

    def material_record(self):
        """Python values for the kernel-side ``Material`` struct (``material_wp``).

        ``lobe_start``, ``lobe_count``, ``table_index`` and ``data_offset`` are filled by
        ``pack_materials``.
        """
        kind, a, b = self.fresnel_record()
        return {
            "model": self.CODE,
            "kd": tuple(float(x) for x in self.kd),
            "ks": tuple(float(x) for x in self.ks),
            "params": tuple(float(x) for x in self.kernel_params()),
            "fresnel_kind": int(kind),
            "fresnel_a": tuple(float(x) for x in a),
            "fresnel_b": tuple(float(x) for x in b),
            "table_index": 0,
            "data_offset": 0,
        }

    def __repr__(self):
        args = ", ".join(f"{k}={getattr(self, k, None)!r}" for k in self.PARAMS)
        return f"{type(self).__name__}({args})"


class SpecularBRDF(BRDF):
    """A model with the factorisation ``ρs = Mo(o, i) · D(h)`` (paper eq. 9)."""

    is_specular = True
    #: number of NDF lobes a model asks for by itself (None: the caller's n_lobes)
    own_lobes: int | None = None

    def mo(self, o, i):  # pragma: no cover - abstract
        raise NotImplementedError

    def ndf(self, h):  # pragma: no cover - abstract
        raise NotImplementedError

    def ndf_sg(self, n_lobes=1, method="analytic"):
        """SG mixture of the NDF in the local frame: ``(axes (K,3), sharpness (K,), amplitude (K,))``."""
        from .fitting.fit import ndf_sg_for

        return ndf_sg_for(self, n_lobes, method)

    def table_lobes(self, n_lobes=1, method="analytic"):
        """The NDF lobes stored in the kernel's lobe table (``material_struct.material_lobes``):
        ``ndf_sg`` with the model's lobe count (:func:`warp_sg.brdf.fitting.fit.lobe_count`)."""
        from .fitting.fit import lobe_count

        return self.ndf_sg(lobe_count(self, n_lobes), method)
