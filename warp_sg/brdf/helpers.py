"""Numeric helpers of the BRDF models (numpy, float64): parameter checks and direction algebra.

They sit below both the model classes (:mod:`warp_sg.brdf.base`) and the NDF fits
(:mod:`warp_sg.brdf.fitting.fit`), so neither imports the other's module for them. Forms (see
:mod:`warp_sg.brdf.base`): ``ln(h·n) = log1p(−(hx² + hy²)/(1 + hz))``, ``θh = atan2(√(hx² + hy²), hz)``.
"""
from __future__ import annotations

import numpy as np

from ..core.errors import InputError
from ..core.suggest import closest

INV_PI = 1.0 / np.pi
#: Smallest cosine used where a model divides by a cosine (grazing guard).
COS_EPS = 1e-6
#: Largest magnitude of a parameter: beyond it the float32 shading overflows (3.4e38) once the value
#: meets the lobes' amplitudes and the lights (the same bound as radiance, ``warp_sg.scene.envmap.MAX_RADIANCE``)
MAX_PARAM = 1e20


def suggest(name, options):
    c = closest(name, options, cutoff=0.0)  # however unlike: a BRDF name or parameter always gets one
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
    if np.any(np.abs(a) > MAX_PARAM):
        raise InputError(f"must be within ±{MAX_PARAM:g}, got {a.tolist()}", where=name)
    return a


def as_scalar(value, name, *, lo=None, lo_open=False, hi=None):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"expected a number, got {value!r}", where=name) from None
    if not np.isfinite(v):
        raise InputError("must be finite", where=name)
    if abs(v) > MAX_PARAM:
        raise InputError(f"must be within ±{MAX_PARAM:g}, got {v}", where=name)
    if lo is not None and (v < lo or (lo_open and v <= lo)):
        raise InputError(f"must be {'>' if lo_open else '>='} {lo}, got {v}", where=name)
    if hi is not None and v > hi:
        raise InputError(f"must be <= {hi}, got {v}", where=name)
    return v


def as_roughness(alpha, alpha_x, alpha_y, default: float, model: str) -> tuple[float, float]:
    """(αx, αy) from either ``alpha`` (isotropic) or both ``alpha_x`` and ``alpha_y``
    (anisotropic), ``default`` when none is given; each > 0. Raises InputError naming the key."""
    if alpha is not None and (alpha_x is not None or alpha_y is not None):
        raise InputError("give either alpha or alpha_x and alpha_y, not both", where="alpha")
    if alpha is None and (alpha_x is None) != (alpha_y is None):
        raise InputError(f"anisotropic {model} needs both alpha_x and alpha_y",
                         where="alpha_x" if alpha_x is None else "alpha_y")
    if alpha is None and alpha_x is None:
        alpha = default
    if alpha is not None:
        a = as_scalar(alpha, "alpha", lo=0.0, lo_open=True)
        return a, a
    return (as_scalar(alpha_x, "alpha_x", lo=0.0, lo_open=True),
            as_scalar(alpha_y, "alpha_y", lo=0.0, lo_open=True))


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


__all__ = ["INV_PI", "COS_EPS", "suggest", "as_rgb", "as_scalar", "dirs", "half_vector", "sin2_theta",
           "log_cos_theta", "theta_of", "reflect_z", "upper"]
