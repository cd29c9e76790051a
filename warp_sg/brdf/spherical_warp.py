r"""Spherical warp of NDF lobes into BRDF-slice lobes (paper §4.3, eq. 15–22), numpy.

For a view ``o`` and an NDF lobe ``G(h; pD, λD, μD)``:

* ``pW = ψ(pD) = 2(o·pD) pD − o`` (eq. 17–18),
* ``λW = λD / τ(pD)`` with the warp's differential area ``τ(h) = 4|h·o|`` (eq. 19, 21),
* ``μW = μD`` (eq. 20), then ``ρ*s(i; o) ≈ Σ G(i; pW, λW, Mo(pW) μW)`` (eq. 22).

Grazing guard: ``|pD·o|`` is clamped to ``WARP_COS_EPS`` (λW ≤ λD/(4·1e-4)); a lobe whose axis
faces away from ``o`` (``pD·o ≤ 0``) or whose warped axis falls below the horizon gets zero
amplitude (Mo is zero there).
"""
from __future__ import annotations

import numpy as np

from ..core.errors import InputError

WARP_COS_EPS = 1e-4


def spherical_warp(pD, lD, mD, o):
    """Warp NDF lobe(s) ``(pD (...,3), λD (...), μD)`` for view ``o`` (...,3) -> ``(pW, λW, μW)``."""
    pD = np.asarray(pD, dtype=np.float64)
    o = np.asarray(o, dtype=np.float64)
    c = np.sum(pD * o, axis=-1)
    pW = 2.0 * c[..., None] * pD - o
    pW = pW / np.linalg.norm(pW, axis=-1, keepdims=True)
    lW = np.asarray(lD, dtype=np.float64) / (4.0 * np.maximum(np.abs(c), WARP_COS_EPS))
    return pW, lW, np.broadcast_to(np.asarray(mD, dtype=np.float64), np.shape(lW)).copy()


def slice_lobes_numpy(model, o, n_lobes=1, method="analytic"):
    """SG lobes of the specular slice ``ks ρs(o, ·)`` as a function of i (paper eq. 22).

    ``o`` (..., 3) unit, local frame. Returns ``(axes (..., K, 3), sharpness (..., K),
    amplitude (..., K, 3))`` — amplitudes include ``ks`` and ``Mo(o, pW)``. Phong: the NDF lobes
    rotated to the mirror direction, amplitude ``ks (n+2)/(2π) μ``; Lafortune: its lobes directly.
    Diffuse-only models return K = 0 lobes."""
    o = np.asarray(o, dtype=np.float64)
    if o.shape[-1:] != (3,):
        raise InputError(f"expected (..., 3), got shape {o.shape}", where="o")
    lead = o.shape[:-1]
    if not model.is_specular:
        return np.zeros(lead + (0, 3)), np.zeros(lead + (0,)), np.zeros(lead + (0, 3))
    ks = np.asarray(model.ks)
    if hasattr(model, "slice_sg"):  # a model with its own slice lobes (Lafortune)
        a, lam, amp = model.slice_sg(o)
        return a, np.array(lam), amp[..., None] * ks
    axes, lam, mu = model.ndf_sg(n_lobes, method)
    K = len(lam)
    O = np.broadcast_to(o[..., None, :], lead + (K, 3))
    if getattr(model, "slice_about_mirror", False):  # Phong
        r = O * np.array([-1.0, -1.0, 1.0])
        # rotate lobes (axis z for isotropic fits) to the mirror direction
        amp = ks * (model.n + 2.0) / (2.0 * np.pi) * mu[:, None]
        return r.copy(), np.broadcast_to(lam, lead + (K,)).copy(), np.broadcast_to(amp, lead + (K, 3)).copy()
    pW, lW, mW = spherical_warp(np.broadcast_to(axes, lead + (K, 3)), np.broadcast_to(lam, lead + (K,)),
                                np.broadcast_to(mu, lead + (K,)), O)
    c = np.sum(axes * O, axis=-1)
    ok = (c > 0) & (pW[..., 2] > 0) & (O[..., 2] > 0)
    pWs = np.where(ok[..., None], pW, np.array([0.0, 0.0, 1.0]))
    mo = model.mo(O, pWs)
    amp = np.where(ok[..., None], mo * mW[..., None] * ks, 0.0)
    return pW, lW, amp


def eval_slice(axes, lam, amp, i):
    """Evaluate an SG slice ``Σ G(i; axes, λ, amp)`` (..., 3) at directions ``i`` (..., 3)."""
    i = np.asarray(i, dtype=np.float64)
    d = i[..., None, :] - axes
    g = np.exp(-lam * 0.5 * np.sum(d * d, axis=-1))
    return np.sum(g[..., None] * amp, axis=-2)
