r"""GGX (Trowbridge–Reitz) microfacet model, isotropic and anisotropic, with height-correlated Smith
masking-shadowing and visible-normal sampling.

Sources: Walter et al. 2007 ("Microfacet models for refraction through rough surfaces", eq. 33–34),
Heitz 2014 ("Understanding the masking-shadowing function in microfacet-based BRDFs", eq. 43, 72,
86 and §5.3), Heitz 2018 ("Sampling the GGX distribution of visible normals", listing 1).
Local frame: z+ = normal, x = tangent (``alpha_x`` along the tangent, as Ashikhmin–Shirley's ``nu``).

* NDF: ``D(h) = 1/(π αx αy q²)``, ``q = hx²/αx² + hy²/αy² + hz²`` (hz > 0);
  ``∫ D(h) (n·h) dω_h = 1``.
* Smith: ``Λ(v) = (−1 + √(1 + (αx² vx² + αy² vy²)/vz²))/2``, ``G1(v) = 1/(1 + Λ(v))``,
  height-correlated ``G2(o, i) = 1/(1 + Λ(o) + Λ(i))`` (Heitz 2014 eq. 99).
* BRDF: ``ρs = F(i·h) D(h) G2(o, i) / (4 (n·i)(n·o))``.

Factorisation ``ρs = Mo(o, i) · D̂(h)`` (paper eq. 9): the NDF with peak 1,
``D̂(h) = π αx αy D(h) = 1/q²``, and ``Mo = F(i·h) G2 / (4π αx αy (n·i)(n·o))``. ``G2/((n·i)(n·o))``
is evaluated as ``1/((n·i)(n·o) + (n·i) L(o) + (n·o) L(i))`` with
``L(v) = vz Λ(v) = a²/(2(√(vz² + a²) + vz))``, ``a² = αx² vx² + αy² vy²`` (no cancellation, finite
at grazing unless both directions are grazing).

SG fits of ``D̂`` (:mod:`warp_sg.brdf.fitting.fit`): ``D̂ = 1/(cos²θ + sin²θ/α²)² = 1 − 2(1/α² − 1)θ² + …``
(Taylor single lobe ``λ = 4/α² − 4``, ``μ = 1``: :meth:`GGX.ndf_analytic_lambda`). Isotropic
K-lobe fits (K = 1..4; non-negative amplitudes, a θ grid that covers the long tail ``D̂ ≈ (α/θ)⁴``
out to ``25α``) are shipped at 39 roughness nodes (``fitting/ggx_lobe_table.py``, made by
``scripts/ggx_lobe_table.py``) and interpolated in α (:func:`table_lobes`) — in the kernel too, so
a textured α gets fitted lobes per texel. Other counts (or ``method="fit"``) fit the constant α
directly. Anisotropic: the Ashikhmin–Shirley N-lobe layout (supplement eq. 14) with extent ``θv``
where ``D̂`` along the wide axis falls to ε = 0.1, the common sharpness ``2/min(α)²`` — half the
Taylor value, so the wider lobes follow GGX's heavy tails — and amplitudes ``D̂(pk)`` divided by
the lobes' overlap at pk (:func:`warp_sg.brdf.fitting.fit.aniso_lobes`), so that more lobes do not
overshoot (supplement eq. 11 error of (αx, αy) = (0.3, 0.06) for N = 5, 7, 9, 15: 0.18, 0.048,
0.027, 0.029; with ``4/α² − 4`` and plain ``D̂(pk)``: 0.45, 0.28, 0.15, 0.077; docs/ggx.md).
``lobes``: NDF lobes (default :data:`DEFAULT_LOBES` isotropic, :data:`DEFAULT_ANISO_LOBES`
anisotropic; odd when anisotropic).

Sampling (Heitz 2018): the visible-normal density ``D_o(h) = G1(o) max(0, o·h) D(h)/(n·o)``,
``i = 2(o·h)h − o``, so ``pdf(i) = G1(o) D(h)/(4 (n·o))``.
``fresnel``: anything :func:`parse_fresnel` accepts (default: none, F = 1).

Kernel side (float32, same forms): ``D̂``, the height-correlated ``G2/((n·i)(n·o))``, the
isotropic node table interpolated at the texel's α (``ggx_table_lobe``), the anisotropic layout
with overlap-normalised amplitudes, fitted lobes rescaled by the curvature ratio of a textured α,
and visible-normal sampling (cosine samples for ``n·o ≤ 0``).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
from dataclasses import replace

import numpy as np
import warp as wp

from ...core.errors import InputError
from ..base import SpecularBRDF, as_rgb, as_roughness, dirs, half_vector
from ..fresnel import parse_fresnel
from ..kernel.material_eval_wp import (
    _aniso_overlap,
    aniso_axis,
    fresnel_eval,
    ggx_extent,
    ggx_g2_over_cos,
    ggx_ndf_peak1,
    ggx_table_lobe,
    half_vec,
)
from ..kernel.material_sample_wp import cosine_dir, ggx_pdf_i, ggx_vndf_h, reflect_about
from ..kernel.material_struct import INV_PI, PI, Material
from ..params import ALPHA_X, ALPHA_Y, FRESNEL, KD, KS, Param
from ..registry import Kernel, register

#: default number of NDF lobes (isotropic; see docs/ggx.md for the error against lobe count)
DEFAULT_LOBES = 3
#: default number of NDF lobes for anisotropic GGX (the Ashikhmin–Shirley layout needs odd N)
DEFAULT_ANISO_LOBES = 9
#: ε of the anisotropic extent θv (supplement eq. 14)
from ...sg import EPSILON  # noqa: E402

#: the isotropic multi-lobe fit covers θ ∈ [0, min(π/2, FIT_EXTENT α)]
FIT_EXTENT = 25.0
#: roughness nodes of the shipped isotropic fits (fitting/ggx_lobe_table.py): α = TABLE_A0 + TABLE_STEP·n
TABLE_A0 = 0.025
TABLE_STEP = 0.025
TABLE_N = 39
#: lobe counts the table holds
TABLE_LOBES = (1, 2, 3, 4)
#: smallest sharpness of a table lobe (D̂ is flat at α = 1)
MIN_LAMBDA = 1e-3


def _curvature(alpha):
    """``1/α² − 1``: ``D̂ = 1 − 2(1/α² − 1)θ² + …`` — the sharpness scale of the fits."""
    return 1.0 / (alpha * alpha) - 1.0


def node_fit(alpha, k):
    """The K-lobe least-squares fit at one table node: ``(λ/(1/α² − 1), μ)`` (``fit`` method)."""
    from ..fitting.fit import ndf_sg_for

    _, lam, mu = ndf_sg_for(GGX(alpha=alpha, lobes=k), k, "fit")
    return lam / _curvature(alpha), mu


def table_lobes(alpha, k):
    """Isotropic K-lobe SG fit of ``D̂`` at any α from the node table: normalised sharpness and
    amplitudes interpolated linearly in α between the two nearest nodes (α clamped to the node
    range), ``λ = max(λ_norm · (1/α'² − 1), MIN_LAMBDA)`` with ``α' = min(α, 1)``. Below the
    first node the normalised fit is that of the first node (the NDF is a function of tan θ/α
    there); above the last the lobes flatten with the curvature, to constant ones at α = 1. Interpolated fits stay
    within ~2× of a fresh fit's error (docs/ggx.md).
    Returns ``(λ (K,), μ (K,))``; the kernel does the same (``material_eval_wp.ggx_table_lobe``)."""
    from ..fitting.ggx_lobe_table import LAMBDA_NORM, MU

    ln_t, mu_t = np.asarray(LAMBDA_NORM[k]), np.asarray(MU[k])
    a1 = TABLE_A0 + TABLE_STEP * (TABLE_N - 1)
    t = (min(max(alpha, TABLE_A0), a1) - TABLE_A0) / TABLE_STEP
    j = min(int(t), TABLE_N - 2)
    f = t - j
    ln = (1.0 - f) * ln_t[j] + f * ln_t[j + 1]
    mu = (1.0 - f) * mu_t[j] + f * mu_t[j + 1]
    return np.maximum(ln * _curvature(min(alpha, 1.0)), MIN_LAMBDA), mu


def smith_lambda_cos(v, ax, ay):
    """``L(v) = vz Λ(v) = a²/(2(√(vz² + a²) + vz))``, ``a² = αx² vx² + αy² vy²`` (vz ≥ 0)."""
    vz = np.maximum(v[..., 2], 0.0)
    a2 = (ax * v[..., 0]) ** 2 + (ay * v[..., 1]) ** 2
    den = 2.0 * (np.sqrt(vz * vz + a2) + vz)
    return np.where(den > 0, a2 / np.where(den > 0, den, 1.0), 0.0)


def smith_g1(v, ax, ay):
    """``G1(v) = 1/(1 + Λ(v)) = vz/(vz + L(v))`` (0 at and below the horizon)."""
    vz = np.maximum(v[..., 2], 0.0)
    den = vz + smith_lambda_cos(v, ax, ay)
    return np.where(vz > 0, vz / np.where(den > 0, den, 1.0), 0.0)


def smith_g2(o, i, ax, ay):
    """Height-correlated ``G2(o, i) = 1/(1 + Λ(o) + Λ(i))`` (Heitz 2014 eq. 99)."""
    co = np.maximum(o[..., 2], 0.0)
    ci = np.maximum(i[..., 2], 0.0)
    den = co * ci + ci * smith_lambda_cos(o, ax, ay) + co * smith_lambda_cos(i, ax, ay)
    return np.where((co > 0) & (ci > 0), co * ci / np.where(den > 0, den, 1.0), 0.0)


def g2_over_cos(o, i, ax, ay):
    """``G2(o, i)/((n·i)(n·o)) = 1/((n·i)(n·o) + (n·i)L(o) + (n·o)L(i))``, clamped like ``g_over_cos``."""
    co = np.maximum(o[..., 2], 1e-12)
    ci = np.maximum(i[..., 2], 1e-12)
    den = co * ci + ci * smith_lambda_cos(o, ax, ay) + co * smith_lambda_cos(i, ax, ay)
    return 1.0 / den


def vndf_sample_h(o, u, ax, ay):
    """Heitz 2018 listing 1: a microfacet normal drawn from ``D_o(h)`` for view o (oz > 0), u in [0,1)²."""
    o = np.asarray(o, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    vh = np.stack(np.broadcast_arrays(ax * o[..., 0], ay * o[..., 1], o[..., 2]), -1)
    vh = vh / np.linalg.norm(vh, axis=-1, keepdims=True)
    lensq = vh[..., 0] ** 2 + vh[..., 1] ** 2
    inv = np.where(lensq > 0, 1.0 / np.sqrt(np.where(lensq > 0, lensq, 1.0)), 0.0)
    t1 = np.stack([np.where(lensq > 0, -vh[..., 1] * inv, 1.0), np.where(lensq > 0, vh[..., 0] * inv, 0.0),
                   np.zeros_like(lensq)], -1)
    t2 = np.cross(vh, t1)
    r = np.sqrt(u[..., 0])
    phi = 2.0 * np.pi * u[..., 1]
    p1 = r * np.cos(phi)
    p2 = r * np.sin(phi)
    s = 0.5 * (1.0 + vh[..., 2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - p1 * p1, 0.0)) + s * p2
    nh = (p1[..., None] * t1 + p2[..., None] * t2
          + np.sqrt(np.maximum(1.0 - p1 * p1 - p2 * p2, 0.0))[..., None] * vh)
    ne = np.stack([ax * nh[..., 0], ay * nh[..., 1], np.maximum(nh[..., 2], 0.0)], -1)
    return ne / np.linalg.norm(ne, axis=-1, keepdims=True)


def _lobe_count(lobes, anisotropic):
    if lobes is None:
        return DEFAULT_ANISO_LOBES if anisotropic else DEFAULT_LOBES
    try:
        n = int(lobes)
    except (TypeError, ValueError):
        raise InputError(f"expected an integer, got {lobes!r}", where="lobes") from None
    if n != lobes or n < 1:
        raise InputError(f"must be an integer >= 1, got {lobes!r}", where="lobes")
    if anisotropic and n % 2 == 0:
        raise InputError(f"anisotropic GGX needs an odd lobe count, got {lobes!r}", where="lobes")
    return n


@wp.func
def ggx_ndf(mat: Material, h: wp.vec3) -> float:
    return ggx_ndf_peak1(h, mat.params[0], mat.params[1])


@wp.func
def ggx_mo(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    p = mat.params
    h = half_vec(o, i)
    val = ggx_g2_over_cos(o, i, p[0], p[1]) / (4.0 * PI * p[0] * p[1])
    return fresnel_eval(mat, wp.dot(i, h)) * val


@wp.func
def ggx_lobe(mat: Material, k: int):
    """Isotropic material: the node table at the texel's α; anisotropic: the layout of supplement
    eq. 14 with sharpness 2/min(α)², extent ``ggx_extent`` and overlap-normalised amplitudes."""
    p = mat.params
    if p[2] == p[3]:  # isotropic material: the node table (any per-texel α)
        lam_t, mu_t = ggx_table_lobe(mat, k, wp.sqrt(p[0] * p[1]))
        return wp.vec3(0.0, 0.0, 1.0), lam_t, mu_t
    wide_x = int(0)
    if p[0] > p[1]:
        wide_x = 1
    amin = wp.min(p[0], p[1])
    lam_g = 2.0 / (amin * amin)
    theta_g = ggx_extent(wp.max(p[0], p[1]))
    ax_g = aniso_axis(mat.lobe_count, k, theta_g, wide_x)
    mu_g = ggx_ndf(mat, ax_g)
    return ax_g, lam_g, mu_g / _aniso_overlap(mat.lobe_count, k, lam_g, theta_g)


@wp.func
def ggx_fitted_lobe(mat: Material, k: int):
    """A fitted lobe of the table: GGX fits scale with the NDF's curvature 1/α² − 1
    (D̂ = 1 − 2(1/α² − 1)θ² + …): fitted for (αx, αy) = (p[2], p[3]); a textured α rescales the
    sharpness (factor 1 when untextured)."""
    p = mat.params
    j = mat.lobe_start + k
    lam = mat.lobe_sharpness[j]
    c_fit = wp.max(1.0 / (p[2] * p[3]) - 1.0, 1.0e-6)
    c_tex = wp.max(1.0 / (p[0] * p[1]) - 1.0, 1.0e-6)
    lam = lam * c_tex / c_fit
    return mat.lobe_axis[j], lam, mat.lobe_amplitude[j]


@wp.func
def ggx_sample(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
    """Visible normals (Heitz 2018); cosine samples for n·o ≤ 0."""
    if o[2] <= 0.0:
        return cosine_dir(u)
    return reflect_about(o, ggx_vndf_h(o, mat.params[0], mat.params[1], u))


@wp.func
def ggx_pdf(mat: Material, o: wp.vec3, i: wp.vec3) -> float:
    """The density of :func:`ggx_sample`: ``G1(o) D(h)/(4 (n·o))`` (cosine for n·o ≤ 0)."""
    if o[2] <= 0.0:
        if i[2] <= 0.0:
            return 0.0
        return i[2] * INV_PI
    hh = o + i
    ln = wp.length(hh)
    if ln <= 0.0:
        return 0.0
    h = hh / ln
    if wp.dot(o, h) <= 0.0:
        return 0.0
    return ggx_pdf_i(o, h, mat.params[0], mat.params[1])


@register
class GGX(SpecularBRDF):
    NAME = "ggx"
    CODE = 10
    ROUGHNESS = "alpha"  # (glTF's roughness map; it sets αx = αy: its Param.kernel)
    ENERGY_NORMALISED = True  # with Smith masking
    KERNEL = Kernel(ndf=ggx_ndf, mo=ggx_mo, analytic_lobe=ggx_lobe, table_lobe=ggx_fitted_lobe, sample=ggx_sample,
                    pdf=ggx_pdf)
    PARAMS = {"kd": KD, "ks": KS,
              "alpha": Param("number", "isotropic roughness α (glTF: roughness²; default 0.3)", lo=0, lo_open=True,
                             texture=True, slider=(0.01, 1.0), kernel=(0, 1)),
              "alpha_x": replace(ALPHA_X, slider=(0.01, 1.0)), "alpha_y": replace(ALPHA_Y, slider=(0.01, 1.0)),
              "fresnel": FRESNEL,
              "lobes": Param("integer", "number of NDF SG lobes (default 3 isotropic, 9 anisotropic; odd when "
                             "anisotropic)", lo=1)}

    def __init__(self, kd=(0.0, 0.0, 0.0), ks=(1.0, 1.0, 1.0), alpha=None, alpha_x=None, alpha_y=None,
                 fresnel=None, lobes=None):
        self.kd = as_rgb(kd, "kd")
        self.ks = as_rgb(ks, "ks")
        self.alpha_x, self.alpha_y = as_roughness(alpha, alpha_x, alpha_y, 0.3, "GGX")
        self.alpha = self.alpha_x if self.isotropic else None
        self.fresnel = parse_fresnel(fresnel)
        self.lobes = _lobe_count(lobes, not self.isotropic)
        self.own_lobes = self.lobes

    #: D̂ is log-convex in u = 1 − cos θ: its multi-lobe fits use non-negative amplitudes
    ndf_log_convex = True
    #: anisotropic layout: amplitudes divided by the lobes' overlap (fit.aniso_lobes)
    aniso_normalised = True

    @property
    def isotropic(self):
        return self.alpha_x == self.alpha_y

    # -- the distribution and its masking ---------------------------------------------------
    def ndf(self, h):
        """``D̂(h) = 1/q²`` (peak 1), ``q = hx²/αx² + hy²/αy² + hz²``; 0 below the horizon."""
        h = np.asarray(h, dtype=np.float64)
        q = h[..., 0] ** 2 / self.alpha_x**2 + h[..., 1] ** 2 / self.alpha_y**2 + h[..., 2] ** 2
        return np.where(h[..., 2] > 0, 1.0 / np.maximum(q, 1e-300) ** 2, 0.0)

    def D(self, h):
        """The normalised GGX NDF ``D(h) = D̂(h)/(π αx αy)`` (``∫ D (n·h) dω = 1``)."""
        return self.ndf(h) / (np.pi * self.alpha_x * self.alpha_y)

    def g1(self, v):
        return smith_g1(np.asarray(v, dtype=np.float64), self.alpha_x, self.alpha_y)

    def g2(self, o, i):
        o, i = dirs(o, i)
        return smith_g2(o, i, self.alpha_x, self.alpha_y)

    def mo(self, o, i):
        o, i = dirs(o, i)
        h = half_vector(o, i)
        ih = np.sum(i * h, axis=-1)
        val = g2_over_cos(o, i, self.alpha_x, self.alpha_y) / (4.0 * np.pi * self.alpha_x * self.alpha_y)
        return self.fresnel(ih) * val[..., None]

    # -- importance sampling -------------------------------------------------------------------
    def sample(self, o, u):
        """Directions i from the visible-normal density (Heitz 2018); (..., 3). May lie below the
        horizon (the BRDF is zero there); ``pdf`` is their solid-angle density. A view below the
        horizon gets cosine-distributed directions (as the kernel's ``brdf_sample``)."""
        o, u = np.asarray(o, dtype=np.float64), np.asarray(u, dtype=np.float64)
        o, _ = np.broadcast_arrays(o, np.empty(u.shape[:-1] + (3,)))
        h = vndf_sample_h(np.where(o[..., 2:] > 0, o, [0.0, 0.0, 1.0]), u, self.alpha_x, self.alpha_y)
        i = 2.0 * np.sum(o * h, axis=-1, keepdims=True) * h - o
        r, phi = np.sqrt(u[..., 0]), 2.0 * np.pi * u[..., 1]
        cosine = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1.0 - u[..., 0], 0.0))], -1)
        return np.where(o[..., 2:] > 0, i, cosine)

    def pdf(self, o, i):
        """Solid-angle density of :meth:`sample`: ``G1(o) D(h) / (4 (n·o))`` where ``o·h > 0``
        (``max(n·i, 0)/π`` for a view below the horizon)."""
        o, i = dirs(o, i)
        h = half_vector(o, i)
        oh = np.sum(o * h, axis=-1)
        co = o[..., 2]
        val = self.g1(o) * self.D(h) / (4.0 * np.where(co > 0, co, 1.0))
        val = np.where((oh > 0) & (h[..., 2] > 0), val, 0.0)
        return np.where(co > 0, val, np.maximum(i[..., 2], 0.0) / np.pi)

    # -- SG fits -------------------------------------------------------------------------------
    def ndf_sg(self, n_lobes=1, method="analytic"):
        """NDF SG lobes. Isotropic with ``method="analytic"`` and ``lobes`` in :data:`TABLE_LOBES`:
        :func:`table_lobes` (the kernel computes the same from the per-texel α); otherwise the
        fits and constructions of :mod:`warp_sg.brdf.fitting.fit` (``self.lobes`` lobes)."""
        if self.isotropic and method == "analytic" and self.lobes in TABLE_LOBES:
            lam, mu = table_lobes(self.alpha_x, self.lobes)
            return np.tile([0.0, 0.0, 1.0], (self.lobes, 1)), lam, mu
        return super().ndf_sg(n_lobes, method)

    def kernel_lobe_table(self, method):
        """``(normalised λ (TABLE_N·K,), μ (TABLE_N·K,))`` node-major, when the kernel builds the
        lobes from the table (isotropic, ``analytic``, K in :data:`TABLE_LOBES`), else None."""
        if not (self.isotropic and method == "analytic" and self.lobes in TABLE_LOBES):
            return None
        from ..fitting.ggx_lobe_table import LAMBDA_NORM, MU

        return np.asarray(LAMBDA_NORM[self.lobes]).reshape(-1), np.asarray(MU[self.lobes]).reshape(-1)

    def ndf_analytic_lambda(self):
        a = min(self.alpha_x, self.alpha_y)
        return max(4.0 / (a * a) - 4.0, 1e-3)

    def aniso_layout(self):
        """``(λ, θv, wide_x)`` of the anisotropic layout (supplement eq. 14)."""
        return self.aniso_lambda(), self.aniso_extent(), self.alpha_x > self.alpha_y

    def aniso_lambda(self):
        """Common sharpness of the anisotropic N-lobe layout: ``2/min(αx, αy)²``."""
        return 2.0 / min(self.alpha_x, self.alpha_y) ** 2

    def ndf_fit_extent(self):
        """θ range of the isotropic multi-lobe fit (the long tail)."""
        return min(np.pi / 2, FIT_EXTENT * self.alpha_x)

    def aniso_extent(self):
        """``θv`` where ``D̂`` along the wide axis falls to ε: ``(1 + t²/α²)/(1 + t²) = ε^{−1/2}``,
        ``t² = (E − 1)/(1/α² − E)``, ``E = ε^{−1/2}`` (capped at 80° where D̂ stays above ε)."""
        a = max(self.alpha_x, self.alpha_y)
        E = EPSILON ** -0.5
        den = 1.0 / (a * a) - E
        cap = np.radians(80.0)
        if den <= 0:
            return cap
        return float(min(np.arctan(np.sqrt((E - 1.0) / den)), cap))

    def kernel_params(self):
        # params[2:4]: the (αx, αy) stored fitted lobes are for; a textured α (params[0:2] per
        # texel) rescales their sharpness by (1/α² − 1) (material_eval_wp.ndf_lobe)
        return (self.alpha_x, self.alpha_y, self.alpha_x, self.alpha_y)


__all__ = ["GGX", "DEFAULT_LOBES", "DEFAULT_ANISO_LOBES", "table_lobes", "node_fit", "smith_g1", "smith_g2", "smith_lambda_cos",
           "g2_over_cos", "vndf_sample_h"]
