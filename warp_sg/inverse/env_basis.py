r"""The environment a fit recovers: a fixed basis of spherical Gaussians with free RGB amplitudes.

``L(i) = Σ_j μ_j exp(λ (i·p_j − 1))`` over ``K`` axes ``p_j`` spread evenly over the sphere (a
Fibonacci lattice, :func:`basis_axes`) with one sharpness ``λ`` set by their spacing: neighbouring
lobes cross at half their peak when ``λ (1 − cos s) = ln 2``, ``s = √(4π/K)`` the mean spacing
(:func:`basis_sharpness`). With axes and sharpness fixed, the per-vertex visible fraction of each
lobe is computed once (``Renderer.set_environment_mixture`` changes only μ afterwards) and the
image is linear in μ: the renderer's gradient of μ (``lights.INDEX.mu``) is exact, shadows included.

* :func:`project_map` — the amplitudes that best reproduce a map (least squares with μ ≥ 0 over
  the map's texels weighted by solid angle, ``scipy.optimize.lsq_linear``): the fit's start from
  the scene's own environment, and the "low-resolution map through the fit" of the gradient (the
  projection is linear in the map, so ``∂loss/∂map = Pᵀ ∂loss/∂μ``).
* :func:`basis_map` — the mixture evaluated on an equirectangular map (the fitted environment
  written as EXR; the renderer's map pipeline renders it like any other map).
"""
from __future__ import annotations

import numpy as np

from warp_sg.scene.envmap import row_solid_angles, uv_to_dir

#: default number of lobes of a fitted environment (spacing ≈ 25°)
DEFAULT_LOBES = 64
#: size of the equirectangular map a fitted environment is written as
MAP_SIZE = (64, 128)


def basis_axes(k: int) -> np.ndarray:
    """(K, 3) unit vectors of a Fibonacci lattice on the sphere (even to within a few percent)."""
    i = np.arange(k) + 0.5
    z = 1.0 - 2.0 * i / k
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    return np.stack([r * np.cos(phi), z, r * np.sin(phi)], -1)  # y up, as the maps


def basis_sharpness(k: int) -> float:
    """λ at which lobes one mean spacing ``s = √(4π/K)`` apart cross at half their peak."""
    s = np.sqrt(4.0 * np.pi / k)
    return float(np.log(2.0) / (1.0 - np.cos(s)))


def _design(axes: np.ndarray, lam, h: int, w: int):
    """(texel directions' basis values (H·W, K), solid angles (H·W,)) of an H × W map."""
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    d = uv_to_dir(u[None, :], v[:, None]).reshape(-1, 3)
    lam = np.broadcast_to(np.asarray(lam, np.float64), (len(axes),))
    a = np.exp(lam[None, :] * (d @ axes.T - 1.0))
    om = np.repeat(row_solid_angles(h, w), w)
    return a, om


def box_map(radiance: np.ndarray, h: int, w: int) -> np.ndarray:
    """The map averaged over the texels of an (at most) h × w grid, weighted by solid angle
    (float64; a map smaller than the grid is kept as it is)."""
    env = np.asarray(radiance, np.float64)
    H, W = env.shape[:2]
    h, w = min(h, H), min(w, W)
    om = np.repeat(row_solid_angles(H, W)[:, None], W, axis=1)
    cell = ((np.arange(H) * h // H)[:, None] * w + (np.arange(W) * w // W)[None, :]).ravel()
    den = np.bincount(cell, weights=om.ravel(), minlength=h * w)
    out = np.stack([np.bincount(cell, weights=(env[..., c] * om).ravel(), minlength=h * w) for c in range(3)], -1)
    return (out / den[:, None]).reshape(h, w, 3)


def project_map(radiance: np.ndarray, axes: np.ndarray, lam, size=(32, 64)) -> np.ndarray:
    """(K, 3) amplitudes μ ≥ 0 minimising ``Σ_t Ω_t |Σ_j μ_j G_j(d_t) − L_t|²`` over the map's texels
    (the map box-filtered to ``size`` first)."""
    from scipy.optimize import lsq_linear

    m = box_map(radiance, *size)
    h, w = m.shape[:2]
    m = m.reshape(-1, 3)
    a, om = _design(axes, lam, h, w)
    sw = np.sqrt(om)[:, None]
    return np.stack([lsq_linear(a * sw, m[:, c] * sw[:, 0], bounds=(0.0, np.inf)).x for c in range(3)], -1)


def basis_map(axes: np.ndarray, lam, mu: np.ndarray, size=MAP_SIZE) -> np.ndarray:
    """(H, W, 3) float32: the mixture at the texel centres of an equirectangular map."""
    h, w = size
    a, _ = _design(axes, lam, h, w)
    return (a @ np.asarray(mu, np.float64)).reshape(h, w, 3).astype(np.float32)


__all__ = ["DEFAULT_LOBES", "MAP_SIZE", "basis_axes", "basis_sharpness", "project_map", "basis_map"]
