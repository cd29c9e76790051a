r"""The material-model switch of the kernel BRDF contract, specialised per set of models.

Every ``@wp.func`` of :mod:`~warp_sg.brdf.material_wp` that branches on ``mat.model`` is built
here by :func:`material_funcs` for a set of model codes (``MODEL_*`` of
:mod:`~warp_sg.brdf.material_struct`): the branch of a model outside the set is removed at compile
time (``wp.static``), so a kernel built from ``material_funcs({MODEL_LAMBERT})`` contains no
microfacet, Lafortune or measured code at all (fewer registers and less divergence on a GPU, less
code per pixel on the CPU). The formulas are written once, in the factory's body; the all-model
set :data:`ALL_MODELS` gives the generic functions that :mod:`~warp_sg.brdf.material_wp`
re-exports (Monte-Carlo reference, sampling, tests), so the generic and the specialised functions
are the same source. Each model's equation is documented in its numpy model (:mod:`warp_sg.brdf`)
and in :mod:`~warp_sg.brdf.material_wp`.

A material whose model is not in the set falls through every branch: zero specular part, ``kd/π``
diffuse part — callers pass the set of every model a scene's material table holds
(``MaterialTable.models``). Functions of a set are cached (one build per distinct set and process) and
named ``<func>_m<ids>`` (generic set: the plain names), so the generated source of a kernel shows
which models it contains.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations; the
# functions are closures over the model set.
from typing import Any, NamedTuple

import warp as wp

from ..errors import InputError
from ..fastmath import fast_atan2
from .material_eval_wp import (_aniso_overlap, above, as_exponent_log, cos_pow, expm1_neg_f, fresnel_eval, g_over_cos,
                               ggx_extent, ggx_g2_over_cos, ggx_ndf_peak1, ggx_table_lobe, half_vec, lafortune_lobe,
                               log1p_f, reflect_z, sin2_theta, warp_axis)
from .material_struct import INV_PI, LN_EPS, PI, TWO_PI, Material
from .measured_wp import measured_mo, merl_eval

#: every model code (MODEL_LAMBERT = 0 … MODEL_GGX = 10)
ALL_MODELS = frozenset(range(11))

_CACHE: dict = {}


class MaterialFuncs(NamedTuple):
    """The ``@wp.func``s of one model set (:func:`material_funcs`)."""

    models: tuple  # the sorted model codes
    tag: str       # the name suffix of the functions (``variant_tag``)
    brdf_ndf: Any
    mo_raw: Any
    brdf_mo: Any
    brdf_specular: Any
    brdf_diffuse: Any
    brdf_eval: Any
    aniso_lobe: Any
    ndf_lobe: Any
    slice_lobe_count: Any
    warp_lobe: Any
    slice_lobe: Any
    shading_slice_lobe: Any
    diffuse_at: Any


def variant_tag(models) -> str:
    """Name suffix of a model set: ``""`` for :data:`ALL_MODELS`, else ``"_m4"``, ``"_m0_10"``, …"""
    ms = frozenset(int(m) for m in models)
    return "" if ms == ALL_MODELS else "_m" + "_".join(str(m) for m in sorted(ms))


def material_funcs(models=ALL_MODELS) -> MaterialFuncs:
    """The model-switching ``@wp.func``s for the model codes ``models`` (any iterable of ints in
    ``ALL_MODELS``; cached per set): ``brdf_ndf``, ``mo_raw``, ``brdf_mo``, ``brdf_specular``,
    ``brdf_diffuse``, ``brdf_eval``, ``ndf_lobe``, ``slice_lobe_count``, ``warp_lobe``,
    ``slice_lobe`` (with its explicit-table overload), and the shading pair ``shading_slice_lobe``,
    ``diffuse_at`` (a :class:`MaterialFuncs`, with ``models``, the sorted codes, and ``tag``, the
    name suffix)."""
    ms = frozenset(int(m) for m in models)
    if not ms or not ms <= ALL_MODELS:
        raise InputError(f"material model codes {sorted(ms)} are not a non-empty subset of 0..10",
                         where="material_funcs")
    if ms in _CACHE:
        return _CACHE[ms]
    H = tuple(m in ms for m in range(11))  # H[m]: model m's branches are compiled in
    T = variant_tag(ms)

    @wp.func(name="brdf_ndf" + T)
    def brdf_ndf(mat: Material, h: wp.vec3) -> float:
        """D(h) of the factorisation ρs = Mo·D (peak 1). Measured: the NDF SG mixture of the table."""
        m = mat.model
        p = mat.params
        if h[2] <= 0.0:
            return 0.0
        if wp.static(H[2] or H[3]):
            if m == 2 or m == 3:
                return cos_pow(h, p[0])
        if wp.static(H[4]):
            if m == 4:
                t = fast_atan2(wp.sqrt(sin2_theta(h)), h[2]) / p[0]  # the angle of h (2e-6 rad)
                return wp.exp(-t * t)
        if wp.static(H[5]):
            if m == 5:
                return wp.exp(-sin2_theta(h) / (h[2] * h[2]) / (p[0] * p[0]))
        if wp.static(H[6]):
            if m == 6:
                e = (h[0] * h[0] / (p[0] * p[0]) + h[1] * h[1] / (p[1] * p[1])) / (h[2] * h[2])
                return wp.exp(-e)
        if wp.static(H[7]):
            if m == 7:
                return wp.exp(as_exponent_log(h, p[0], p[1]))
        if wp.static(H[10]):
            if m == 10:
                return ggx_ndf_peak1(h, p[0], p[1])
        if wp.static(H[9]):
            if m == 9:
                d = float(0.0)
                for k in range(mat.lobe_count):
                    j = mat.lobe_start + k
                    a = mat.lobe_axis[j]
                    dd = h - a
                    d += mat.lobe_amplitude[j] * wp.exp(-mat.lobe_sharpness[j] * 0.5 * wp.dot(dd, dd))
                return d
        return 0.0

    @wp.func(name="mo_raw" + T)
    def mo_raw(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """Mo(o, i) without ks (zero if o or i is below the horizon)."""
        if o[2] <= 0.0 or i[2] <= 0.0:
            return wp.vec3(0.0, 0.0, 0.0)
        m = mat.model
        p = mat.params
        one = wp.vec3(1.0, 1.0, 1.0)
        if wp.static(H[2] or H[3]):
            if m == 2 or m == 3:
                return one * ((p[0] + 2.0) / TWO_PI)
        if wp.static(H[4] or H[5]):
            if m == 4 or m == 5:
                h = half_vec(o, i)
                val = g_over_cos(o, i, h) * INV_PI
                if m == 5:
                    hz = wp.max(h[2], 1.0e-6)
                    hz2 = hz * hz
                    val = val / (4.0 * p[0] * p[0] * hz2 * hz2)
                return fresnel_eval(mat, wp.dot(i, h)) * val
        if wp.static(H[6]):
            if m == 6:
                c = wp.sqrt(wp.max(o[2] * i[2], 1.0e-12))
                return one * (1.0 / (4.0 * PI * p[0] * p[1] * c))
        if wp.static(H[7]):
            if m == 7:
                h = half_vec(o, i)
                ih = wp.max(wp.dot(i, h), 1.0e-12)
                cmax = wp.max(wp.max(i[2], o[2]), 1.0e-12)
                val = wp.sqrt((p[0] + 1.0) * (p[1] + 1.0)) / (8.0 * PI * ih * cmax)
                return fresnel_eval(mat, ih) * val
        if wp.static(H[10]):
            if m == 10:
                h = half_vec(o, i)
                val = ggx_g2_over_cos(o, i, p[0], p[1]) / (4.0 * PI * p[0] * p[1])
                return fresnel_eval(mat, wp.dot(i, h)) * val
        if wp.static(H[8]):
            if m == 8:
                return one
        if wp.static(H[9]):
            if m == 9:
                return measured_mo(mat.mo_tables, mat.table_index, mat.fresnel_a, o, i)
        return wp.vec3(0.0, 0.0, 0.0)

    @wp.func(name="brdf_mo" + T)
    def brdf_mo(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """ks ∘ Mo(o, i) (architecture contract: includes ks)."""
        return wp.cw_mul(mat.ks, mo_raw(mat, o, i))

    @wp.func(name="brdf_specular" + T)
    def brdf_specular(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """ρs(o, i) without ks; zero below the horizon."""
        if o[2] <= 0.0 or i[2] <= 0.0:
            return wp.vec3(0.0, 0.0, 0.0)
        m = mat.model
        if m <= 1:
            return wp.vec3(0.0, 0.0, 0.0)
        if wp.static(H[2]):
            if m == 2:
                r = reflect_z(o)
                d = r - i
                omd = 0.5 * wp.dot(d, d)
                if omd >= 1.0:
                    return wp.vec3(0.0, 0.0, 0.0)
                lobe = wp.exp(mat.params[0] * log1p_f(-omd))
                return wp.vec3(1.0, 1.0, 1.0) * ((mat.params[0] + 2.0) / TWO_PI * lobe)
        if wp.static(H[8]):
            if m == 8:
                s = float(0.0)
                for k in range(mat.lobe_count):
                    s += lafortune_lobe(mat, mat.lobe_start + k, o, i)
                return wp.vec3(s, s, s)
        h = half_vec(o, i)
        return mo_raw(mat, o, i) * brdf_ndf(mat, h)

    @wp.func(name="brdf_diffuse" + T)
    def brdf_diffuse(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """kd/π, or Oren–Nayar kd/π (A + B max(0, ix ox + iy oy)/max(cos θi, cos θo))."""
        if o[2] <= 0.0 or i[2] <= 0.0:
            return wp.vec3(0.0, 0.0, 0.0)
        if wp.static(H[1]):
            if mat.model == 1:
                dphi = wp.max(o[0] * i[0] + o[1] * i[1], 0.0)
                cmax = wp.max(wp.max(o[2], i[2]), 1.0e-12)
                return mat.kd * (INV_PI * (mat.params[0] + mat.params[1] * dphi / cmax))
        return mat.kd * INV_PI

    @wp.func(name="brdf_eval" + T)
    def brdf_eval(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """Exact BRDF kd/π + ks ∘ ρs(o, i) (measured: the tabulated data); zero below the horizon
        (each part is)."""
        if wp.static(H[9]):
            if mat.model == 9:
                if o[2] <= 0.0 or i[2] <= 0.0:
                    return wp.vec3(0.0, 0.0, 0.0)
                return merl_eval(mat.merl_data, mat.data_offset, o, i)
        f = brdf_diffuse(mat, o, i)
        if wp.static(any(H[2:])):  # a specular model is in the set
            f += wp.cw_mul(mat.ks, brdf_specular(mat, o, i))
        return f

    # -------------------------------------------------------------------------------- SG lobes
    @wp.func(name="aniso_lobe" + T)
    def _aniso_lobe(mat: Material, k: int, lam: float, theta_v: float, wide_x: int):
        """Lobe k of the anisotropic layout of supplement eq. 14 (n lobes spaced 2θv/(n + 1)
        along the wide axis), amplitude D at its axis."""
        n = mat.lobe_count
        theta_i = 2.0 * theta_v / float(n + 1)
        a = (float(k) - 0.5 * float(n - 1)) * theta_i
        axis = wp.vec3(0.0, wp.sin(a), wp.cos(a))
        if wide_x == 1:
            axis = wp.vec3(wp.sin(a), 0.0, wp.cos(a))
        return axis, lam, brdf_ndf(mat, axis)

    @wp.func(name="ndf_lobe" + T)
    def ndf_lobe(mat: Material, k: int):
        """NDF SG lobe k (0 ≤ k < lobe_count): (axis, sharpness, amplitude) in the local frame."""
        p = mat.params
        m = mat.model
        if mat.analytic == 1:
            z = wp.vec3(0.0, 0.0, 1.0)
            if wp.static(H[2] or H[3]):
                if m == 2 or m == 3:
                    return z, wp.max(p[0], 1.0e-6), 1.0
            if wp.static(H[4] or H[5]):
                if m == 4 or m == 5:
                    return z, 2.0 / (p[0] * p[0]), 1.0
            if wp.static(H[6]):
                if m == 6:
                    if p[0] == p[1]:
                        return z, 2.0 / (p[0] * p[0]), 1.0
                    amin = wp.min(p[0], p[1])
                    amax = wp.max(p[0], p[1])
                    wide_x = int(0)
                    if p[0] > p[1]:
                        wide_x = 1
                    return _aniso_lobe(mat, k, 2.0 / (amin * amin), wp.atan(amax * wp.sqrt(-LN_EPS)), wide_x)
            if wp.static(H[7]):
                if m == 7:
                    if p[0] == p[1]:
                        return z, wp.max(p[0], 1.0e-6), 1.0
                    nmin = wp.min(p[0], p[1])
                    nmax = wp.max(p[0], p[1])
                    # θv = arccos(ε^{1/(nmin+1)}) = 2 asin(√((1 − ε^{1/(nmin+1)})/2))
                    omc = expm1_neg_f(-LN_EPS / (nmin + 1.0))
                    theta_v = 2.0 * wp.asin(wp.sqrt(0.5 * omc))
                    wide_x = int(0)
                    if p[0] < p[1]:
                        wide_x = 1
                    return _aniso_lobe(mat, k, nmax, theta_v, wide_x)
            if wp.static(H[10]):
                if m == 10:
                    if p[2] == p[3]:  # isotropic material: the node table (any per-texel α)
                        lam_t, mu_t = ggx_table_lobe(mat, k, wp.sqrt(p[0] * p[1]))
                        return z, lam_t, mu_t
                    wide_x = int(0)
                    if p[0] > p[1]:
                        wide_x = 1
                    amin = wp.min(p[0], p[1])
                    lam_g = 2.0 / (amin * amin)
                    theta_g = ggx_extent(wp.max(p[0], p[1]))
                    ax_g, l_g, mu_g = _aniso_lobe(mat, k, lam_g, theta_g, wide_x)
                    return ax_g, l_g, mu_g / _aniso_overlap(mat.lobe_count, k, lam_g, theta_g)
        j = mat.lobe_start + k
        lam = mat.lobe_sharpness[j]
        if wp.static(H[10]):
            if m == 10:
                # GGX fits scale with the NDF's curvature 1/α² − 1 (D̂ = 1 − 2(1/α² − 1)θ² + …):
                # fitted for (αx, αy) = (p[2], p[3]); a textured α rescales the sharpness (factor 1
                # when untextured)
                c_fit = wp.max(1.0 / (p[2] * p[3]) - 1.0, 1.0e-6)
                c_tex = wp.max(1.0 / (p[0] * p[1]) - 1.0, 1.0e-6)
                lam = lam * c_tex / c_fit
        return mat.lobe_axis[j], lam, mat.lobe_amplitude[j]

    @wp.func(name="slice_lobe_count" + T)
    def slice_lobe_count(mat: Material) -> int:
        """Number of SG lobes of the specular slice (0 for diffuse-only models)."""
        if wp.static(any(H[2:])):
            if mat.model >= 2:
                return mat.lobe_count
        return 0

    @wp.func(name="warp_lobe" + T)
    def warp_lobe(mat: Material, pD: wp.vec3, lam: float, mu: float, o: wp.vec3):
        """Spherical warp (eq. 17–22): (pW, λD/(4|pD·o|), ks ∘ Mo(o, pW) μ)."""
        pW, lamW, c = warp_axis(pD, lam, o)
        amp = wp.vec3(0.0, 0.0, 0.0)
        if c > 0.0 and pW[2] > 0.0 and o[2] > 0.0:
            amp = brdf_mo(mat, o, pW) * mu
        return pW, lamW, amp

    @wp.func(name="slice_lobe" + T)
    def slice_lobe(mat: Material, o: wp.vec3, k: int):
        """SG lobe k of the slice ks ρs(o, ·): (axis, sharpness, amplitude RGB)."""
        m = mat.model
        if wp.static(H[8]):
            if m == 8:
                j = mat.lobe_start + k
                c = mat.lobe_axis[j]
                v = wp.cw_mul(c, o)
                nv = wp.length(v)
                n = wp.max(mat.lobe_sharpness[j], 1.0e-6)
                if nv <= 0.0:
                    return wp.vec3(0.0, 0.0, 1.0), n, wp.vec3(0.0, 0.0, 0.0)
                amp = mat.lobe_amplitude[j] * wp.exp(wp.min(mat.lobe_sharpness[j] * wp.log(nv), 80.0))
                return v / nv, n, mat.ks * amp
        axis, lam, mu = ndf_lobe(mat, k)
        if wp.static(H[2]):
            if m == 2:
                return reflect_z(o), lam, mat.ks * ((mat.params[0] + 2.0) / TWO_PI * mu)
        return warp_lobe(mat, axis, lam, mu, o)

    @wp.func(name="slice_lobe" + T)
    def slice_lobe(mat: Material, lobe_axis: wp.array(dtype=wp.vec3), lobe_sharpness: wp.array(dtype=float),  # noqa: F811
                   lobe_amplitude: wp.array(dtype=float), o: wp.vec3, k: int):
        """Overload with explicitly passed lobe tables (architecture.md signature)."""
        mm = mat
        mm.lobe_axis = lobe_axis
        mm.lobe_sharpness = lobe_sharpness
        mm.lobe_amplitude = lobe_amplitude
        return slice_lobe(mm, o, k)

    # -------------------------------------------------------------------------------- shading
    @wp.func(name="shading_slice_lobe" + T)
    def shading_slice_lobe(mat: Material, o: wp.vec3, k: int):
        """SG lobe k of the slice ks ρs(o, ·) (spherical warp, eq. 17–22) for shading: as
        ``slice_lobe``, but ``Mo`` is taken at the warped axis lifted to just above the horizon
        (``above``) instead of dropping the whole lobe once its axis dips below it (at grazing
        views half of such a lobe is still above the horizon; the cosine weight ``e(n·pW, λW)`` of
        the caller removes the rest)."""
        if wp.static(H[2] or H[8]):
            m = mat.model
            if m == 2 or m == 8:
                return slice_lobe(mat, o, k)
        axis, lam, mu = ndf_lobe(mat, k)
        pW, lamW, c = warp_axis(axis, lam, o)
        amp = wp.vec3(0.0, 0.0, 0.0)
        if c > 0.0:
            amp = brdf_mo(mat, o, above(pW)) * mu
        return pW, lamW, amp

    @wp.func(name="diffuse_at" + T)
    def diffuse_at(mat: Material, o_l: wp.vec3, p_l: wp.vec3) -> wp.vec3:
        """ρd(o, i) evaluated at a product lobe's axis (kd/π exactly for Lambert)."""
        return brdf_diffuse(mat, o_l, above(p_l))

    fs = MaterialFuncs(tuple(sorted(ms)), T, brdf_ndf, mo_raw, brdf_mo, brdf_specular, brdf_diffuse, brdf_eval,
                       _aniso_lobe, ndf_lobe, slice_lobe_count, warp_lobe, slice_lobe, shading_slice_lobe, diffuse_at)
    _CACHE[ms] = fs
    return fs


#: the generic (all-model) functions, re-exported by :mod:`~warp_sg.brdf.material_wp`
GENERIC = material_funcs(ALL_MODELS)
(_, _, brdf_ndf, mo_raw, brdf_mo, brdf_specular, brdf_diffuse, brdf_eval, _aniso_lobe, ndf_lobe, slice_lobe_count,
 warp_lobe, slice_lobe, shading_slice_lobe, diffuse_at) = GENERIC
