r"""Lafortune generalized cosine lobes (lecture "Lafortune model").

``ρ(o, i) = kd/π + ks Σ_j max(0, cx,j ox ix + cy,j oy iy + cz,j oz iz)^{n_j}``
(``C = (−1, −1, 1)`` is a Phong lobe around the mirror direction, ``(1, 1, 1)`` retro-reflection,
``(−1, −1, 0.5)`` off-specular). Reciprocal by construction. No normalisation: the lobe
coefficients C carry the magnitude.

BRDF slice for a view o (no warp needed): with ``v_j = C_j ∘ o`` (component-wise),
``max(0, v_j·i)^{n} = ‖v_j‖^{n} max(0, a_j·i)^{n} ≈ ‖v_j‖^{n} G(i; a_j, n_j, 1)``,
``a_j = v_j/‖v_j‖`` (cosine power ≈ SG of sharpness n, supplement eq. 9).

Kernel side: the lobe table holds ``C_j`` (axis field, not normalised) and ``n_j``; the slice is
the lobes above; sampling picks one lobe uniformly and draws a cosine power about ``C_j ∘ o``.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import numpy as np
import warp as wp

from ...core.errors import InputError
from ..base import SpecularBRDF, as_rgb, as_scalar, dirs, suggest, upper
from ..kernel.material_eval_wp import lafortune_lobe
from ..kernel.material_sample_wp import cos_power_dir, cos_power_pdf, cosine_dir
from ..kernel.material_struct import INV_PI, Material
from ..params import KD, KS, Param
from ..registry import Kernel, register


@wp.func
def lafortune_mo(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    return wp.vec3(1.0, 1.0, 1.0)


@wp.func
def lafortune_specular(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    s = float(0.0)
    for k in range(mat.lobe_count):
        s += lafortune_lobe(mat, mat.lobe_start + k, o, i)
    return wp.vec3(s, s, s)


@wp.func
def lafortune_slice(mat: Material, o: wp.vec3, k: int):
    """``G(i; C∘o/‖C∘o‖, n, ks ‖C∘o‖^n)``."""
    j = mat.lobe_start + k
    c = mat.lobe_axis[j]
    v = wp.cw_mul(c, o)
    nv = wp.length(v)
    n = wp.max(mat.lobe_sharpness[j], 1.0e-6)
    if nv <= 0.0:
        return wp.vec3(0.0, 0.0, 1.0), n, wp.vec3(0.0, 0.0, 0.0)
    amp = mat.lobe_amplitude[j] * wp.exp(wp.min(mat.lobe_sharpness[j] * wp.log(nv), 80.0))
    return v / nv, n, mat.ks * amp


@wp.func
def lafortune_sample(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
    nl = wp.max(mat.lobe_count, 1)
    q = wp.min(int(u[0] * float(nl)), nl - 1)
    uu = wp.vec2(u[0] * float(nl) - float(q), u[1])
    j = mat.lobe_start + q
    v = wp.cw_mul(mat.lobe_axis[j], o)
    if wp.length(v) <= 0.0:
        return cosine_dir(uu)
    return cos_power_dir(wp.normalize(v), mat.lobe_sharpness[j], uu)


@wp.func
def lafortune_pdf(mat: Material, o: wp.vec3, i: wp.vec3) -> float:
    nl = wp.max(mat.lobe_count, 1)
    s = float(0.0)
    for k in range(mat.lobe_count):
        j = mat.lobe_start + k
        v = wp.cw_mul(mat.lobe_axis[j], o)
        if wp.length(v) <= 0.0:
            s += wp.max(i[2], 0.0) * INV_PI
        else:
            s += cos_power_pdf(wp.normalize(v), mat.lobe_sharpness[j], i)
    return s / float(nl)

LOBE_KEYS = ("cx", "cy", "cz", "n")


@register
class Lafortune(SpecularBRDF):
    NAME = "lafortune"
    CODE = 8
    KERNEL = Kernel(mo=lafortune_mo, specular=lafortune_specular, slice=lafortune_slice, sample=lafortune_sample,
                    pdf=lafortune_pdf)
    PARAMS = {"kd": KD, "ks": KS, "lobes": Param("lafortune_lobes", "lobes: a list of {cx, cy, cz, n} tables")}

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

    @property
    def own_lobes(self):
        """One lobe table entry per lobe, whatever count is asked for."""
        return len(self.N)

    def table_lobes(self, n_lobes=1, method="analytic"):
        """The kernel's table: axis field ``C_j``, sharpness ``max(n_j, 0)``, amplitude 1."""
        return self.C.copy(), np.maximum(self.N, 0.0), np.ones(len(self.N))

    def ndf_sg(self, n_lobes=1, method="analytic"):
        """Lafortune lobes as stored in the kernel table: axis = C_j (not normalised), sharpness n_j."""
        return self.C.copy(), np.maximum(self.N, 1e-6), np.ones(len(self.N))
