r"""Lafortune generalized cosine lobes (lecture "Lafortune model").

``ρ(o, i) = kd/π + ks Σ_j max(0, cx,j ox ix + cy,j oy iy + cz,j oz iz)^{n_j}``
(``C = (−1, −1, 1)`` is a Phong lobe around the mirror direction, ``(1, 1, 1)`` retro-reflection,
``(−1, −1, 0.5)`` off-specular). Reciprocal by construction. No normalisation: the lobe
coefficients C carry the magnitude.

BRDF slice for a view o (no warp needed): with ``v_j = C_j ∘ o`` (component-wise),
``max(0, v_j·i)^{n} = ‖v_j‖^{n} max(0, a_j·i)^{n} ≈ ‖v_j‖^{n} G(i; a_j, n_j, 1)``,
``a_j = v_j/‖v_j‖`` (cosine power ≈ SG of sharpness n, supplement eq. 9).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .base import SpecularBRDF, as_rgb, as_scalar, dirs, suggest, upper

LOBE_KEYS = ("cx", "cy", "cz", "n")


class Lafortune(SpecularBRDF):
    NAME = "lafortune"
    MODEL_ID = 8
    PARAMS = ("kd", "ks", "lobes")

    def __init__(self, kd=(0.0, 0.0, 0.0), ks=(1.0, 1.0, 1.0), lobes=({"cx": -1.0, "cy": -1.0, "cz": 1.0, "n": 20.0},)):
        self.kd = as_rgb(kd, "kd")
        self.ks = as_rgb(ks, "ks")
        if isinstance(lobes, dict) or not hasattr(lobes, "__len__") or len(lobes) == 0:
            raise InputError("expected a non-empty list of {cx, cy, cz, n} tables", where="lobes")
        c, n = [], []
        for j, lobe in enumerate(lobes):
            where = f"lobes[{j}]"
            if not isinstance(lobe, dict):
                raise InputError("expected a table {cx, cy, cz, n}", where=where)
            for k in lobe:
                if k not in LOBE_KEYS:
                    raise InputError(f"unknown key '{k}'{suggest(k, LOBE_KEYS)}", where=where)
            for k in LOBE_KEYS:
                if k not in lobe:
                    raise InputError(f"missing key '{k}'", where=where)
            c.append([as_scalar(lobe[k], f"{where}.{k}") for k in ("cx", "cy", "cz")])
            n.append(as_scalar(lobe["n"], f"{where}.n", lo=0.0))
        self.C = np.array(c)
        self.N = np.array(n)
        self.lobes = [dict(cx=a[0], cy=a[1], cz=a[2], n=b) for a, b in zip(self.C, self.N)]

    def specular(self, o, i):
        o, i = dirs(o, i)
        v = o[..., None, :] * self.C  # (..., J, 3)
        d = np.sum(v * i[..., None, :], axis=-1)
        with np.errstate(divide="ignore"):
            val = np.where(d > 0, np.exp(self.N * np.log(np.maximum(d, 1e-300))), 0.0).sum(-1)
        return np.where(upper(o, i)[..., None], val[..., None] * np.ones(3), 0.0)

    def mo(self, o, i):
        o, i = dirs(o, i)
        return np.ones(o.shape[:-1] + (3,))

    def slice_sg(self, o):
        """Lobes of ``ρs(o, ·)`` (without ks): axes (..., J, 3), sharpness (J,), amplitude (..., J)."""
        o = np.asarray(o, dtype=np.float64)
        v = o[..., None, :] * self.C
        nv = np.linalg.norm(v, axis=-1)
        a = v / np.where(nv > 0, nv, 1.0)[..., None]
        with np.errstate(divide="ignore"):
            amp = np.where(nv > 0, np.exp(np.minimum(self.N * np.log(np.maximum(nv, 1e-300)), 80.0)), 0.0)
        return a, np.broadcast_to(np.maximum(self.N, 1e-6), amp.shape), amp

    def ndf_sg(self, n_lobes=1, method="analytic"):
        """Lafortune lobes as stored in the kernel table: axis = C_j (not normalised), sharpness n_j."""
        return self.C.copy(), np.maximum(self.N, 1e-6), np.ones(len(self.N))
