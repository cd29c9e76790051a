r"""Shared machinery of the BRDF model classes (numpy, float64).

Every model is ``ρ(o, i) = kd/π + ks · ρs(o, i)`` in the local frame (z+ = normal, x = tangent),
with directions pointing away from the surface (DESIGN.md "BRDF"). Specular models factor
``ρs(o, i) = Mo(o, i) · D(h)``, ``h = (o + i)/‖o + i‖`` (paper eq. 9), keep ``Mo`` analytic and fit
the NDF ``D`` by spherical Gaussians (supplement §2–3).

Numerical forms used by every model (float64 here, same forms in ``material_wp``):

* ``ln(h·n) = log1p(−(hx² + hy²)/(1 + hz))`` — no cancellation near the normal;
* ``θh = atan2(√(hx² + hy²), hz)`` instead of ``arccos(hz)``;
* ``tan²θh = (hx² + hy²)/hz²``.
"""
from __future__ import annotations

import difflib

import numpy as np

from ..errors import InputError

INV_PI = 1.0 / np.pi
#: Smallest cosine used where a model divides by a cosine (grazing guard).
COS_EPS = 1e-6


def closest(name, options):
    m = difflib.get_close_matches(str(name), list(options), n=1, cutoff=0.0)
    return m[0] if m else None


def suggest(name, options):
    c = closest(name, options)
    return f" (did you mean '{c}'?)" if c else ""


def as_rgb(value, name, *, nonneg=True):
    """A number or 3 numbers -> float64 (3,) array; raises InputError naming ``name``."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"expected a number or 3 numbers (RGB), got {value!r}", where=name) from None
    if a.ndim == 0:
        a = np.full(3, float(a))
    if a.shape != (3,):
        raise InputError(f"expected a number or 3 numbers (RGB), got shape {a.shape}", where=name)
    if not np.all(np.isfinite(a)):
        raise InputError("must be finite", where=name)
    if nonneg and np.any(a < 0):
        raise InputError(f"must be >= 0, got {a.tolist()}", where=name)
    return a


def as_scalar(value, name, *, lo=None, lo_open=False, hi=None):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"expected a number, got {value!r}", where=name) from None
    if not np.isfinite(v):
        raise InputError("must be finite", where=name)
    if lo is not None and (v < lo or (lo_open and v <= lo)):
        raise InputError(f"must be {'>' if lo_open else '>='} {lo}, got {v}", where=name)
    if hi is not None and v > hi:
        raise InputError(f"must be <= {hi}, got {v}", where=name)
    return v


def dirs(*vs):
    """Broadcast direction arrays to float64 (..., 3)."""
    out = [np.asarray(v, dtype=np.float64) for v in vs]
    for v in out:
        if v.shape[-1:] != (3,):
            raise InputError(f"directions must have a trailing axis of size 3, got shape {v.shape}", where="direction")
    return np.broadcast_arrays(*out)


def half_vector(o, i):
    h = o + i
    n = np.linalg.norm(h, axis=-1, keepdims=True)
    return h / np.where(n > 0, n, 1.0)


def sin2_theta(v):
    return v[..., 0] ** 2 + v[..., 1] ** 2


def log_cos_theta(h):
    """``ln(h_z)`` computed as ``log1p(−(hx²+hy²)/(1+hz))`` (accurate near the normal)."""
    hz = np.maximum(h[..., 2], 0.0)
    return np.log1p(-np.minimum(sin2_theta(h) / (1.0 + hz), 1.0))


def theta_of(h):
    return np.arctan2(np.sqrt(sin2_theta(h)), h[..., 2])


def reflect_z(o):
    """Mirror direction of ``o`` about the normal: ``2 (n·o) n − o`` = (−ox, −oy, oz)."""
    return o * np.array([-1.0, -1.0, 1.0])


def upper(o, i):
    return (o[..., 2] > 0) & (i[..., 2] > 0)


class BRDF:
    """Base class. Subclasses set ``NAME``, ``MODEL_ID``, ``PARAMS`` and implement ``diffuse`` and,
    for specular models, ``mo`` and ``ndf``."""

    NAME = "base"
    MODEL_ID = -1
    PARAMS: tuple[str, ...] = ()
    is_specular = False

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
            "model": self.MODEL_ID,
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
        from .fit import ndf_sg_for

        return ndf_sg_for(self, n_lobes, method)
