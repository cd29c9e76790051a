r"""The material-model switch of the kernel BRDF contract, generated from the registry and
specialised per set of models.

Every ``@wp.func`` of :mod:`~warp_sg.brdf.kernel.material_wp` that depends on ``mat.model`` is built here
by :func:`material_funcs` for a set of model codes (``CODE`` of the classes in
:mod:`warp_sg.brdf.registry`). Each model declares its kernel functions in its own file
(:class:`~warp_sg.brdf.registry.Kernel`: ``ndf``, ``mo``, ``specular``, ``diffuse``, ``eval``,
``analytic_lobe``, ``table_lobe``, ``slice``, ``slice_of_lobe``, ``sample``, ``pdf``, ``pdf_h``,
``texel_param0``); a switch is a chain of small functions, one per model of the set that defines
the hook (``if mat.model == CODE: return hook(...)`` else the next one), ending in the hook's
default. A model outside the set has no link at all (its code is removed at compile time), so a
kernel built from ``material_funcs({Lambert.CODE})`` contains no microfacet, Lafortune or
measured code (fewer registers and less divergence on a GPU, less code per pixel on the CPU).
The all-model set :func:`all_models` gives the generic functions that
:mod:`~warp_sg.brdf.kernel.material_wp` re-exports (Monte-Carlo reference, sampling, tests), so the
generic and the specialised functions are the same source.

The model-independent parts (in the order a caller sees them):

* ``brdf_ndf`` (0 for ``h_z ≤ 0``), ``mo_raw`` / ``brdf_specular`` / ``brdf_diffuse`` (0 when
  ``o`` or ``i`` is below the horizon); ``brdf_specular`` defaults to ``mo_raw · brdf_ndf(h)``,
  ``brdf_eval`` to ``brdf_diffuse + ks ∘ brdf_specular``; ``brdf_mo = ks ∘ mo_raw``;
* ``ndf_lobe``: the model's ``analytic_lobe`` when ``mat.analytic == 1``, else its
  ``table_lobe`` (default: the table as stored);
* ``slice_lobe``: the model's ``slice``, else ``slice_of_lobe(ndf_lobe)`` (default: the
  spherical warp ``warp_lobe``, paper eq. 17–22); ``shading_slice_lobe`` is ``slice_lobe`` for
  models with their own slice and otherwise warps with ``Mo`` taken just above the horizon;
* ``brdf_sample`` (``u`` clamped to [0, 1)), ``brdf_pdf`` (default: ``pdf_h(h)/(4 max(o·h, 1e-6))``
  of the half vector; diffuse-only models: cosine sampling);
* ``texel_param0``: the parameters of a material whose first parameter comes from a texel.

A material whose model is not in the set gets every default: zero specular part, ``kd/π``
diffuse part — callers pass the set of every model a scene's material table holds
(``MaterialTable.models``). Functions of a set are cached (one build per distinct set and
process) and named ``<func>_m<codes>`` (generic set: the plain names), so the generated source of
a kernel shows which models it contains.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations; the
# functions are closures over the model set.
from typing import Any, NamedTuple

import warp as wp

from ...core.errors import InputError
from .. import models as _models  # noqa: F401  (registers every model)
from ..registry import BY_CODE, codes
from .material_eval_wp import above, aniso_axis, half_vec, warp_axis
from .material_sample_wp import cosine_pdf, cosine_sample, reflect_about
from .material_struct import INV_PI, Material

_CACHE: dict = {}


def all_models() -> frozenset:
    """Every registered model code."""
    return codes()


#: every model code registered when this module was imported (the generic functions' set)
ALL_MODELS = all_models()


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
    brdf_sample: Any
    brdf_pdf: Any
    texel_param0: Any


def variant_tag(models) -> str:
    """Name suffix of a model set: ``""`` for :data:`ALL_MODELS` (the generic functions), else
    ``"_m4"``, ``"_m0_10"``, … (a model registered later makes a new set, never the generic names)."""
    ms = frozenset(int(m) for m in models)
    return "" if ms == ALL_MODELS else "_m" + "_".join(str(m) for m in sorted(ms))


# ------------------------------------------------------------------------------------------------
# one link of a switch, per signature: ``if mat.model == code: return impl(...)`` else ``nxt(...)``
# ------------------------------------------------------------------------------------------------
def _link_h(name, code, impl, nxt):
    @wp.func(name=name)
    def link(mat: Material, h: wp.vec3) -> float:
        if mat.model == wp.static(code):
            return impl(mat, h)
        return nxt(mat, h)

    return link


def _link_oi(name, code, impl, nxt):
    @wp.func(name=name)
    def link(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        if mat.model == wp.static(code):
            return impl(mat, o, i)
        return nxt(mat, o, i)

    return link


def _link_oi_f(name, code, impl, nxt):
    @wp.func(name=name)
    def link(mat: Material, o: wp.vec3, i: wp.vec3) -> float:
        if mat.model == wp.static(code):
            return impl(mat, o, i)
        return nxt(mat, o, i)

    return link


def _link_k(name, code, impl, nxt):
    @wp.func(name=name)
    def link(mat: Material, k: int):
        if mat.model == wp.static(code):
            return impl(mat, k)
        return nxt(mat, k)

    return link


def _link_ok(name, code, impl, nxt):
    @wp.func(name=name)
    def link(mat: Material, o: wp.vec3, k: int):
        if mat.model == wp.static(code):
            return impl(mat, o, k)
        return nxt(mat, o, k)

    return link


def _link_lobe(name, code, impl, nxt):
    @wp.func(name=name)
    def link(mat: Material, o: wp.vec3, axis: wp.vec3, lam: float, mu: float):
        if mat.model == wp.static(code):
            return impl(mat, o, axis, lam, mu)
        return nxt(mat, o, axis, lam, mu)

    return link


def _link_u(name, code, impl, nxt):
    @wp.func(name=name)
    def link(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
        if mat.model == wp.static(code):
            return impl(mat, o, u)
        return nxt(mat, o, u)

    return link


def _link_pv(name, code, impl, nxt):
    @wp.func(name=name)
    def link(mat: Material, p: wp.vec4, v: float) -> wp.vec4:
        if mat.model == wp.static(code):
            return impl(mat, p, v)
        return nxt(mat, p, v)

    return link


def _hook(code: int, hook: str):
    """Model ``code``'s ``hook`` function, with the defaults of diffuse-only models (cosine sampling)."""
    cls = BY_CODE[code]
    f = getattr(cls.KERNEL, hook)
    if f is None and not cls.is_specular and hook in ("sample", "pdf"):
        f = cosine_sample if hook == "sample" else cosine_pdf
    return f


def _switch(hook: str, link, ms, tag: str, default):
    """The chain of ``link``s over the models of ``ms`` that define ``hook``, ending in ``default``."""
    f = default
    for code in sorted(ms, reverse=True):
        impl = _hook(code, hook)
        if impl is not None:
            f = link(f"{hook}_c{code}{tag}", code, impl, f)
    return f


def _mask(ms, keep) -> int:
    """Bit mask of the codes of ``ms`` whose class satisfies ``keep``."""
    return sum(1 << c for c in ms if keep(BY_CODE[c]))


def material_funcs(models=None) -> MaterialFuncs:
    """The model-switching ``@wp.func``s for the model codes ``models`` (any iterable of registered
    codes, default all; cached per set): ``brdf_ndf``, ``mo_raw``, ``brdf_mo``, ``brdf_specular``,
    ``brdf_diffuse``, ``brdf_eval``, ``ndf_lobe``, ``slice_lobe_count``, ``warp_lobe``,
    ``slice_lobe`` (with its explicit-table overload), the shading pair ``shading_slice_lobe``,
    ``diffuse_at``, the sampling pair ``brdf_sample``, ``brdf_pdf`` and ``texel_param0`` (a
    :class:`MaterialFuncs`, with ``models``, the sorted codes, and ``tag``, the name suffix)."""
    everything = all_models()
    ms = everything if models is None else frozenset(int(m) for m in models)
    if not ms or not ms <= everything:
        raise InputError(f"material model codes {sorted(ms)} are not a non-empty subset of the registered "
                         f"codes {sorted(everything)}", where="material_funcs")
    if ms in _CACHE:
        return _CACHE[ms]
    T = variant_tag(ms)
    ANY_SPECULAR = any(BY_CODE[c].is_specular for c in ms)
    SPECULAR = _mask(ms, lambda c: c.is_specular)  # models with a specular slice
    OWN_SLICE = _mask(ms, lambda c: c.KERNEL.slice is not None or c.KERNEL.slice_of_lobe is not None)

    # ---------------------------------------------------------------------------- the defaults
    @wp.func(name="ndf_none" + T)
    def ndf_none(mat: Material, h: wp.vec3) -> float:
        return 0.0

    @wp.func(name="mo_none" + T)
    def mo_none(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        return wp.vec3(0.0, 0.0, 0.0)

    ndf_of = _switch("ndf", _link_h, ms, T, ndf_none)
    mo_of = _switch("mo", _link_oi, ms, T, mo_none)

    @wp.func(name="brdf_ndf" + T)
    def brdf_ndf(mat: Material, h: wp.vec3) -> float:
        """D(h) of the factorisation ρs = Mo·D (peak 1). Measured: the NDF SG mixture of the table."""
        if h[2] <= 0.0:
            return 0.0
        return ndf_of(mat, h)

    @wp.func(name="mo_raw" + T)
    def mo_raw(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """Mo(o, i) without ks (zero if o or i is below the horizon)."""
        if o[2] <= 0.0 or i[2] <= 0.0:
            return wp.vec3(0.0, 0.0, 0.0)
        return mo_of(mat, o, i)

    @wp.func(name="brdf_mo" + T)
    def brdf_mo(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """ks ∘ Mo(o, i) (architecture contract: includes ks)."""
        return wp.cw_mul(mat.ks, mo_raw(mat, o, i))

    @wp.func(name="specular_of_halfway" + T)
    def specular_of_halfway(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """The default specular part: Mo(o, i) D(h) (a diffuse-only model: zero)."""
        if wp.static(SPECULAR != 0):
            if (wp.static(SPECULAR) >> mat.model) & 1 == 1:
                h = half_vec(o, i)
                return mo_raw(mat, o, i) * brdf_ndf(mat, h)
        return wp.vec3(0.0, 0.0, 0.0)

    specular_of = _switch("specular", _link_oi, ms, T, specular_of_halfway)

    @wp.func(name="brdf_specular" + T)
    def brdf_specular(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """ρs(o, i) without ks; zero below the horizon."""
        if o[2] <= 0.0 or i[2] <= 0.0:
            return wp.vec3(0.0, 0.0, 0.0)
        return specular_of(mat, o, i)

    @wp.func(name="diffuse_lambert" + T)
    def diffuse_lambert(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        return mat.kd * INV_PI

    diffuse_of = _switch("diffuse", _link_oi, ms, T, diffuse_lambert)

    @wp.func(name="brdf_diffuse" + T)
    def brdf_diffuse(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """kd/π, or the model's diffuse part (Oren–Nayar); zero below the horizon."""
        if o[2] <= 0.0 or i[2] <= 0.0:
            return wp.vec3(0.0, 0.0, 0.0)
        return diffuse_of(mat, o, i)

    @wp.func(name="eval_sum" + T)
    def eval_sum(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        f = brdf_diffuse(mat, o, i)
        if wp.static(ANY_SPECULAR):  # a specular model is in the set
            f += wp.cw_mul(mat.ks, brdf_specular(mat, o, i))
        return f

    eval_of = _switch("eval", _link_oi, ms, T, eval_sum)

    @wp.func(name="brdf_eval" + T)
    def brdf_eval(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
        """Exact BRDF kd/π + ks ∘ ρs(o, i) (measured: the tabulated data); zero below the horizon
        (each part is)."""
        return eval_of(mat, o, i)

    # -------------------------------------------------------------------------------- SG lobes
    @wp.func(name="aniso_lobe" + T)
    def _aniso_lobe(mat: Material, k: int, lam: float, theta_v: float, wide_x: int):
        """Lobe k of the anisotropic layout of supplement eq. 14 (n lobes spaced 2θv/(n + 1)
        along the wide axis), amplitude D at its axis."""
        axis = aniso_axis(mat.lobe_count, k, theta_v, wide_x)
        return axis, lam, brdf_ndf(mat, axis)

    @wp.func(name="table_as_stored" + T)
    def table_as_stored(mat: Material, k: int):
        j = mat.lobe_start + k
        return mat.lobe_axis[j], mat.lobe_sharpness[j], mat.lobe_amplitude[j]

    table_lobe_of = _switch("table_lobe", _link_k, ms, T, table_as_stored)
    analytic_lobe_of = _switch("analytic_lobe", _link_k, ms, T, table_lobe_of)

    @wp.func(name="ndf_lobe" + T)
    def ndf_lobe(mat: Material, k: int):
        """NDF SG lobe k (0 ≤ k < lobe_count): (axis, sharpness, amplitude) in the local frame."""
        if mat.analytic == 1:
            return analytic_lobe_of(mat, k)
        return table_lobe_of(mat, k)

    @wp.func(name="slice_lobe_count" + T)
    def slice_lobe_count(mat: Material) -> int:
        """Number of SG lobes of the specular slice (0 for diffuse-only models)."""
        if wp.static(SPECULAR != 0):
            if (wp.static(SPECULAR) >> mat.model) & 1 == 1:
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

    @wp.func(name="slice_warped" + T)
    def slice_warped(mat: Material, o: wp.vec3, axis: wp.vec3, lam: float, mu: float):
        return warp_lobe(mat, axis, lam, mu, o)

    slice_of_lobe_of = _switch("slice_of_lobe", _link_lobe, ms, T, slice_warped)

    @wp.func(name="slice_of_ndf_lobe" + T)
    def slice_of_ndf_lobe(mat: Material, o: wp.vec3, k: int):
        axis, lam, mu = ndf_lobe(mat, k)
        return slice_of_lobe_of(mat, o, axis, lam, mu)

    slice_of = _switch("slice", _link_ok, ms, T, slice_of_ndf_lobe)

    @wp.func(name="slice_lobe" + T)
    def slice_lobe(mat: Material, o: wp.vec3, k: int):
        """SG lobe k of the slice ks ρs(o, ·): (axis, sharpness, amplitude RGB)."""
        return slice_of(mat, o, k)

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
        the caller removes the rest). Models with their own slice (Phong, Lafortune) use it."""
        if wp.static(OWN_SLICE != 0):
            if (wp.static(OWN_SLICE) >> mat.model) & 1 == 1:
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

    # -------------------------------------------------------------------------------- sampling
    @wp.func(name="sample_normal" + T)
    def sample_normal(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
        return reflect_about(o, wp.vec3(0.0, 0.0, 1.0))

    sample_of = _switch("sample", _link_u, ms, T, sample_normal)

    @wp.func(name="brdf_sample" + T)
    def brdf_sample(mat: Material, o: wp.vec3, u_in: wp.vec2) -> wp.vec3:
        """A direction i drawn from the specular sampling density ``brdf_pdf(mat, o, ·)``."""
        u = wp.vec2(wp.clamp(u_in[0], 0.0, 0.99999994), wp.clamp(u_in[1], 0.0, 0.99999994))
        return sample_of(mat, o, u)

    @wp.func(name="pdf_h_none" + T)
    def pdf_h_none(mat: Material, h: wp.vec3) -> float:
        return 0.0

    pdf_h_of = _switch("pdf_h", _link_h, ms, T, pdf_h_none)

    @wp.func(name="pdf_of_halfway" + T)
    def pdf_of_halfway(mat: Material, o: wp.vec3, i: wp.vec3) -> float:
        """p(i) = p(h)/(4 |o·h|) of a half-vector sampling density ``pdf_h``."""
        hh = o + i
        l = wp.length(hh)
        if l <= 0.0:
            return 0.0
        h = hh / l
        oh = wp.dot(o, h)
        if oh <= 0.0:
            return 0.0
        ph = pdf_h_of(mat, h)
        return ph / (4.0 * wp.max(oh, 1.0e-6))

    pdf_of = _switch("pdf", _link_oi_f, ms, T, pdf_of_halfway)

    @wp.func(name="brdf_pdf" + T)
    def brdf_pdf(mat: Material, o: wp.vec3, i: wp.vec3) -> float:
        """Solid-angle density of ``brdf_sample(mat, o, ·)`` at i."""
        return pdf_of(mat, o, i)

    # -------------------------------------------------------------------------------- textures
    @wp.func(name="texel_param_clamped" + T)
    def texel_param_clamped(mat: Material, p: wp.vec4, v: float) -> wp.vec4:
        return wp.vec4(wp.max(v, 1.0e-4), p[1], p[2], p[3])

    texel_param0 = _switch("texel_param0", _link_pv, ms, T, texel_param_clamped)

    fs = MaterialFuncs(tuple(sorted(ms)), T, brdf_ndf, mo_raw, brdf_mo, brdf_specular, brdf_diffuse, brdf_eval,
                       _aniso_lobe, ndf_lobe, slice_lobe_count, warp_lobe, slice_lobe, shading_slice_lobe, diffuse_at,
                       brdf_sample, brdf_pdf, texel_param0)
    _CACHE[ms] = fs
    return fs


#: the generic (all-model) functions, re-exported by :mod:`~warp_sg.brdf.kernel.material_wp`
GENERIC = material_funcs(ALL_MODELS)
(_, _, brdf_ndf, mo_raw, brdf_mo, brdf_specular, brdf_diffuse, brdf_eval, _aniso_lobe, ndf_lobe, slice_lobe_count,
 warp_lobe, slice_lobe, shading_slice_lobe, diffuse_at, brdf_sample, brdf_pdf, texel_param0) = GENERIC
