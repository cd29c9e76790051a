r"""Kernel-side BRDF contract (docs/architecture.md "BRDF contract"): the ``Material`` struct,
``pack_materials`` and the ``@wp.func``s used by the renderer and the Monte-Carlo reference.

All functions work in the local frame (z+ = normal, x = tangent), float32, unit vectors, and
mirror the numpy models of :mod:`warp_sg.brdf` (same formulas, same stable forms; see each
model's docstring for its equation and source):

* ``brdf_eval(mat, o, i)``     exact ``kd/π + ks ρs`` (Oren–Nayar diffuse; measured: ``merl_eval``);
* ``brdf_diffuse(mat, o, i)``  the diffuse part;
* ``brdf_mo(mat, o, i)``       ``ks ∘ Mo(o, i)`` of the factorisation ``ρs = Mo · D(h)`` (eq. 9);
* ``brdf_ndf(mat, h)``         ``D(h)`` (Phong: the lobe of the mirrored direction);
* ``brdf_sample(mat, o, u)`` / ``brdf_pdf(mat, o, i)``: importance sampling of the *specular*
  part (the caller mixes in cosine sampling for the diffuse part). Phong: cosine-power lobe about
  the mirror direction; Blinn–Phong: ``cos θh = u^{1/(n+2)}``; Cook–Torrance, Torrance–Sparrow,
  Ward (iso/aniso): Beckmann slope sampling (Walter et al. 2007; Ward 1992) with
  ``p(h) = exp(−(sx²/αx² + sy²/αy²))/(π αx αy cos³θh)``; Ashikhmin–Shirley: their quadrant
  sampling with ``p(h) = √((nu+1)(nv+1))/(2π) (n·h)^{nu cos²φ + nv sin²φ}``; Lafortune: one lobe
  chosen uniformly, cosine power about ``C∘o``; measured: the NDF SG mixture
  (``1 − cos θ = −log1p(−u (1 − e^{−2λ}))/λ``). ``p(i) = p(h)/(4 |o·h|)`` for half-vector models;
  diffuse-only models return cosine samples. ``brdf_pdf`` returns the density of exactly what
  ``brdf_sample`` draws (directions below the horizon included).
* ``slice_lobe_count(mat)``, ``slice_lobe(mat, o, k) -> (axis, sharpness, amplitude vec3)``:
  SG lobe k of ``ks ρs(o, ·)``: spherical warp (paper eq. 17–22) of NDF lobe k times
  ``ks ∘ Mo(o, pW)``; Phong: the lobe about the mirror direction, amplitude ``ks (n+2)/(2π) μ``;
  Lafortune: ``G(i; C∘o/‖C∘o‖, n, ks ‖C∘o‖^n)``. ``slice_lobe(mat, lobe_axis, lobe_sharpness,
  lobe_amplitude, o, k)`` does the same with explicitly passed lobe tables.
* ``ndf_lobe(mat, k)``: NDF lobe k (local frame). With ``mat.analytic == 1`` it is computed from
  ``mat.params`` (so textured roughness works per pixel): single lobe ``λ = 2/m²`` (Cook–Torrance,
  Torrance–Sparrow), ``2/α²`` (Ward), ``n`` (Phong, Blinn–Phong, isotropic Ashikhmin–Shirley),
  or the anisotropic construction of supplement eq. 14 with ``mat.lobe_count`` lobes; otherwise it
  is read from the lobe table.

The ``Material`` struct carries the (shared) lobe tables and measured-data arrays as array
fields, so every function takes just ``mat``. Ashikhmin–Shirley and anisotropic Ward lobe axes are
in the local tangent frame (x = tangent).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..errors import InputError
from ..frames import frame_bitangent, frame_tangent
from .fit import is_anisotropic as _is_anisotropic
from .fit import lobe_count as _lobe_count
from .measured_wp import fresnel_dielectric, measured_mo, merl_eval

MODEL_LAMBERT = wp.constant(0)
MODEL_OREN_NAYAR = wp.constant(1)
MODEL_PHONG = wp.constant(2)
MODEL_BLINN_PHONG = wp.constant(3)
MODEL_COOK_TORRANCE = wp.constant(4)
MODEL_TORRANCE_SPARROW = wp.constant(5)
MODEL_WARD = wp.constant(6)
MODEL_ASHIKHMIN_SHIRLEY = wp.constant(7)
MODEL_LAFORTUNE = wp.constant(8)
MODEL_MEASURED = wp.constant(9)

FRESNEL_NONE = wp.constant(0)
FRESNEL_SCHLICK = wp.constant(1)
FRESNEL_DIELECTRIC = wp.constant(2)
FRESNEL_CONDUCTOR = wp.constant(3)

PI = wp.constant(3.141592653589793)
INV_PI = wp.constant(0.3183098861837907)
TWO_PI = wp.constant(6.283185307179586)
#: ln ε of the anisotropic construction (ε = 0.1, supplement eq. 14)
LN_EPS = wp.constant(-2.302585092994046)
#: grazing guard of the spherical warp (|pD·o| ≥ 1e-4)
WARP_COS_EPS = wp.constant(1.0e-4)

#: analytic in-kernel lobes are supported for these models
_ANALYTIC = {2, 3, 4, 5, 6, 7}


@wp.struct
class Material:
    model: int
    kd: wp.vec3
    ks: wp.vec3
    params: wp.vec4
    fresnel_kind: int
    fresnel_a: wp.vec3
    fresnel_b: wp.vec3
    lobe_start: int
    lobe_count: int
    table_index: int
    data_offset: int
    analytic: int
    lobe_axis: wp.array(dtype=wp.vec3)
    lobe_sharpness: wp.array(dtype=float)
    lobe_amplitude: wp.array(dtype=float)
    merl_data: wp.array(dtype=float)
    mo_tables: wp.array3d(dtype=float)


# ------------------------------------------------------------------------------------------------
# small building blocks
# ------------------------------------------------------------------------------------------------
@wp.func
def log1p_f(x: float) -> float:
    """log(1 + x) for x > −1, series below |x| < 1e-4."""
    if wp.abs(x) < 1.0e-4:
        return x * (1.0 - x * (0.5 - x / 3.0))
    return wp.log(1.0 + x)


@wp.func
def expm1_neg_f(x: float) -> float:
    """1 − e^{−x} for x ≥ 0."""
    if x < 1.0e-3:
        return x * (1.0 - 0.5 * x * (1.0 - x / 3.0))
    return 1.0 - wp.exp(-x)


@wp.func
def sin2_theta(v: wp.vec3) -> float:
    return v[0] * v[0] + v[1] * v[1]


@wp.func
def log_cos_theta(h: wp.vec3) -> float:
    """ln(h_z) = log1p(−(hx²+hy²)/(1+hz)); −1e30 at/below the horizon."""
    hz = h[2]
    if hz <= 0.0:
        return -1.0e30
    return log1p_f(-wp.min(sin2_theta(h) / (1.0 + hz), 0.99999994))


@wp.func
def cos_pow(v: wp.vec3, n: float) -> float:
    """max(0, v_z)^n."""
    if v[2] <= 0.0:
        return 0.0
    return wp.exp(n * log_cos_theta(v))


@wp.func
def half_vec(o: wp.vec3, i: wp.vec3) -> wp.vec3:
    h = o + i
    l = wp.length(h)
    if l > 0.0:
        return h / l
    return wp.vec3(0.0, 0.0, 1.0)


@wp.func
def reflect_z(o: wp.vec3) -> wp.vec3:
    return wp.vec3(-o[0], -o[1], o[2])


@wp.func
def from_axis(a: wp.vec3, x: float, y: float, z: float) -> wp.vec3:
    return x * frame_tangent(a) + y * frame_bitangent(a) + z * a


@wp.func
def lum(c: wp.vec3) -> float:
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]


@wp.func
def fresnel_eval(mat: Material, c_in: float) -> wp.vec3:
    """Fresnel reflectance (fresnel.py): none, Schlick(f0), dielectric(η) eq. 14, conductor(η, k)."""
    c = wp.clamp(c_in, 0.0, 1.0)
    kind = mat.fresnel_kind
    if kind == 1:
        f0 = mat.fresnel_a
        q = 1.0 - c
        q2 = q * q
        return f0 + (wp.vec3(1.0, 1.0, 1.0) - f0) * (q2 * q2 * q)
    if kind == 2:
        eta = mat.fresnel_a
        return wp.vec3(fresnel_dielectric(eta[0], c), fresnel_dielectric(eta[1], c), fresnel_dielectric(eta[2], c))
    if kind == 3:
        out = wp.vec3(1.0, 1.0, 1.0)
        c2 = c * c
        for ch in range(3):
            e = mat.fresnel_a[ch]
            k = mat.fresnel_b[ch]
            t = e * e + k * k
            rpar = (t * c2 - 2.0 * e * c + 1.0) / (t * c2 + 2.0 * e * c + 1.0)
            rper = (t - 2.0 * e * c + c2) / (t + 2.0 * e * c + c2)
            out[ch] = wp.clamp(0.5 * (rpar + rper), 0.0, 1.0)
        return out
    return wp.vec3(1.0, 1.0, 1.0)


@wp.func
def g_over_cos(o: wp.vec3, i: wp.vec3, h: wp.vec3) -> float:
    """V-cavity G(o, i)/((n·i)(n·o)), finite at grazing (microfacet.py)."""
    ci = wp.max(i[2], 1.0e-12)
    co = wp.max(o[2], 1.0e-12)
    hz = wp.max(h[2], 0.0)
    oh = wp.max(wp.dot(o, h), 1.0e-12)
    return wp.min(1.0 / (ci * co), wp.min(2.0 * hz / (oh * ci), 2.0 * hz / (oh * co)))


@wp.func
def as_exponent_log(h: wp.vec3, nu: float, nv: float) -> float:
    """(nu hx² + nv hy²) · ln(hz)/(hx² + hy²): the log of the Ashikhmin–Shirley NDF."""
    hz = h[2]
    if hz <= 0.0:
        return -1.0e30
    hx2 = h[0] * h[0]
    hy2 = h[1] * h[1]
    s2 = hx2 + hy2
    L = -1.0 / (1.0 + hz)
    if s2 > 1.0e-20:
        L = log1p_f(-wp.min(s2 / (1.0 + hz), 0.99999994)) / s2
    return (nu * hx2 + nv * hy2) * L


# ------------------------------------------------------------------------------------------------
# NDF and Mo
# ------------------------------------------------------------------------------------------------
@wp.func
def brdf_ndf(mat: Material, h: wp.vec3) -> float:
    """D(h) of the factorisation ρs = Mo·D (peak 1). Measured: the NDF SG mixture of the table."""
    m = mat.model
    p = mat.params
    if h[2] <= 0.0:
        return 0.0
    if m == 2 or m == 3:
        return cos_pow(h, p[0])
    if m == 4:
        t = wp.atan2(wp.sqrt(sin2_theta(h)), h[2]) / p[0]
        return wp.exp(-t * t)
    if m == 5:
        return wp.exp(-sin2_theta(h) / (h[2] * h[2]) / (p[0] * p[0]))
    if m == 6:
        e = (h[0] * h[0] / (p[0] * p[0]) + h[1] * h[1] / (p[1] * p[1])) / (h[2] * h[2])
        return wp.exp(-e)
    if m == 7:
        return wp.exp(as_exponent_log(h, p[0], p[1]))
    if m == 9:
        d = float(0.0)
        for k in range(mat.lobe_count):
            j = mat.lobe_start + k
            a = mat.lobe_axis[j]
            dd = h - a
            d += mat.lobe_amplitude[j] * wp.exp(-mat.lobe_sharpness[j] * 0.5 * wp.dot(dd, dd))
        return d
    return 0.0


@wp.func
def mo_raw(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    """Mo(o, i) without ks (zero if o or i is below the horizon)."""
    if o[2] <= 0.0 or i[2] <= 0.0:
        return wp.vec3(0.0, 0.0, 0.0)
    m = mat.model
    p = mat.params
    one = wp.vec3(1.0, 1.0, 1.0)
    if m == 2 or m == 3:
        return one * ((p[0] + 2.0) / TWO_PI)
    if m == 4 or m == 5:
        h = half_vec(o, i)
        val = g_over_cos(o, i, h) * INV_PI
        if m == 5:
            hz = wp.max(h[2], 1.0e-6)
            hz2 = hz * hz
            val = val / (4.0 * p[0] * p[0] * hz2 * hz2)
        return fresnel_eval(mat, wp.dot(i, h)) * val
    if m == 6:
        c = wp.sqrt(wp.max(o[2] * i[2], 1.0e-12))
        return one * (1.0 / (4.0 * PI * p[0] * p[1] * c))
    if m == 7:
        h = half_vec(o, i)
        ih = wp.max(wp.dot(i, h), 1.0e-12)
        cmax = wp.max(wp.max(i[2], o[2]), 1.0e-12)
        val = wp.sqrt((p[0] + 1.0) * (p[1] + 1.0)) / (8.0 * PI * ih * cmax)
        return fresnel_eval(mat, ih) * val
    if m == 8:
        return one
    if m == 9:
        return measured_mo(mat.mo_tables, mat.table_index, mat.fresnel_a, o, i)
    return wp.vec3(0.0, 0.0, 0.0)


@wp.func
def brdf_mo(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    """ks ∘ Mo(o, i) (architecture contract: includes ks)."""
    return wp.cw_mul(mat.ks, mo_raw(mat, o, i))


@wp.func
def lafortune_lobe(mat: Material, j: int, o: wp.vec3, i: wp.vec3) -> float:
    c = mat.lobe_axis[j]
    d = c[0] * o[0] * i[0] + c[1] * o[1] * i[1] + c[2] * o[2] * i[2]
    if d <= 0.0:
        return 0.0
    return mat.lobe_amplitude[j] * wp.exp(wp.min(mat.lobe_sharpness[j] * wp.log(d), 80.0))


@wp.func
def brdf_specular(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    """ρs(o, i) without ks; zero below the horizon."""
    if o[2] <= 0.0 or i[2] <= 0.0:
        return wp.vec3(0.0, 0.0, 0.0)
    m = mat.model
    if m <= 1:
        return wp.vec3(0.0, 0.0, 0.0)
    if m == 2:
        r = reflect_z(o)
        d = r - i
        omd = 0.5 * wp.dot(d, d)
        if omd >= 1.0:
            return wp.vec3(0.0, 0.0, 0.0)
        lobe = wp.exp(mat.params[0] * log1p_f(-omd))
        return wp.vec3(1.0, 1.0, 1.0) * ((mat.params[0] + 2.0) / TWO_PI * lobe)
    if m == 8:
        s = float(0.0)
        for k in range(mat.lobe_count):
            s += lafortune_lobe(mat, mat.lobe_start + k, o, i)
        return wp.vec3(s, s, s)
    h = half_vec(o, i)
    return mo_raw(mat, o, i) * brdf_ndf(mat, h)


@wp.func
def oren_nayar_params(sigma: float) -> wp.vec4:
    """``params`` of an Oren–Nayar material for roughness σ (radians): (A, B, σ, 0) (lambert.py)."""
    s2 = sigma * sigma
    return wp.vec4(1.0 - s2 / (2.0 * (s2 + 0.33)), 0.45 * s2 / (s2 + 0.09), sigma, 0.0)


@wp.func
def brdf_diffuse(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    """kd/π, or Oren–Nayar kd/π (A + B max(0, ix ox + iy oy)/max(cos θi, cos θo))."""
    if o[2] <= 0.0 or i[2] <= 0.0:
        return wp.vec3(0.0, 0.0, 0.0)
    if mat.model == 1:
        dphi = wp.max(o[0] * i[0] + o[1] * i[1], 0.0)
        cmax = wp.max(wp.max(o[2], i[2]), 1.0e-12)
        return mat.kd * (INV_PI * (mat.params[0] + mat.params[1] * dphi / cmax))
    return mat.kd * INV_PI


@wp.func
def brdf_eval(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    """Exact BRDF kd/π + ks ∘ ρs(o, i) (measured: the tabulated data); zero below the horizon."""
    if o[2] <= 0.0 or i[2] <= 0.0:
        return wp.vec3(0.0, 0.0, 0.0)
    if mat.model == 9:
        return merl_eval(mat.merl_data, mat.data_offset, o, i)
    return brdf_diffuse(mat, o, i) + wp.cw_mul(mat.ks, brdf_specular(mat, o, i))


# ------------------------------------------------------------------------------------------------
# SG lobes: NDF lobes and the warped slice
# ------------------------------------------------------------------------------------------------
@wp.func
def _aniso_lobe(mat: Material, k: int, lam: float, theta_v: float, wide_x: int):
    n = mat.lobe_count
    theta_i = 2.0 * theta_v / float(n + 1)
    a = (float(k) - 0.5 * float(n - 1)) * theta_i
    axis = wp.vec3(0.0, wp.sin(a), wp.cos(a))
    if wide_x == 1:
        axis = wp.vec3(wp.sin(a), 0.0, wp.cos(a))
    return axis, lam, brdf_ndf(mat, axis)


@wp.func
def ndf_lobe(mat: Material, k: int):
    """NDF SG lobe k (0 ≤ k < lobe_count): (axis, sharpness, amplitude) in the local frame."""
    p = mat.params
    m = mat.model
    if mat.analytic == 1:
        z = wp.vec3(0.0, 0.0, 1.0)
        if m == 2 or m == 3:
            return z, wp.max(p[0], 1.0e-6), 1.0
        if m == 4 or m == 5:
            return z, 2.0 / (p[0] * p[0]), 1.0
        if m == 6:
            if p[0] == p[1]:
                return z, 2.0 / (p[0] * p[0]), 1.0
            amin = wp.min(p[0], p[1])
            amax = wp.max(p[0], p[1])
            wide_x = int(0)
            if p[0] > p[1]:
                wide_x = 1
            return _aniso_lobe(mat, k, 2.0 / (amin * amin), wp.atan(amax * wp.sqrt(-LN_EPS)), wide_x)
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
    j = mat.lobe_start + k
    return mat.lobe_axis[j], mat.lobe_sharpness[j], mat.lobe_amplitude[j]


@wp.func
def slice_lobe_count(mat: Material) -> int:
    """Number of SG lobes of the specular slice (0 for diffuse-only models)."""
    if mat.model <= 1:
        return 0
    return mat.lobe_count


@wp.func
def warp_axis(pD: wp.vec3, lam: float, o: wp.vec3):
    """Spherical warp of an NDF lobe's axis and sharpness (eq. 17–22): (pW = reflection of o about
    pD, λW = λD/(4|pD·o|), pD·o); the grazing limit pD·o → 0 is guarded by WARP_COS_EPS."""
    c = wp.dot(pD, o)
    pW = 2.0 * c * pD - o
    l = wp.length(pW)
    if l > 0.0:
        pW = pW / l
    return pW, lam / (4.0 * wp.max(wp.abs(c), WARP_COS_EPS)), c


@wp.func
def warp_lobe(mat: Material, pD: wp.vec3, lam: float, mu: float, o: wp.vec3):
    """Spherical warp (eq. 17–22): (pW, λD/(4|pD·o|), ks ∘ Mo(o, pW) μ)."""
    pW, lamW, c = warp_axis(pD, lam, o)
    amp = wp.vec3(0.0, 0.0, 0.0)
    if c > 0.0 and pW[2] > 0.0 and o[2] > 0.0:
        amp = brdf_mo(mat, o, pW) * mu
    return pW, lamW, amp


@wp.func
def slice_lobe(mat: Material, o: wp.vec3, k: int):
    """SG lobe k of the slice ks ρs(o, ·): (axis, sharpness, amplitude RGB)."""
    m = mat.model
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
    if m == 2:
        return reflect_z(o), lam, mat.ks * ((mat.params[0] + 2.0) / TWO_PI * mu)
    return warp_lobe(mat, axis, lam, mu, o)


@wp.func
def slice_lobe(mat: Material, lobe_axis: wp.array(dtype=wp.vec3), lobe_sharpness: wp.array(dtype=float),
               lobe_amplitude: wp.array(dtype=float), o: wp.vec3, k: int):
    """Overload with explicitly passed lobe tables (architecture.md signature)."""
    mm = mat
    mm.lobe_axis = lobe_axis
    mm.lobe_sharpness = lobe_sharpness
    mm.lobe_amplitude = lobe_amplitude
    return slice_lobe(mm, o, k)


# ------------------------------------------------------------------------------------------------
# importance sampling of the specular part
# ------------------------------------------------------------------------------------------------
@wp.func
def cosine_dir(u: wp.vec2) -> wp.vec3:
    r = wp.sqrt(u[0])
    phi = TWO_PI * u[1]
    return wp.vec3(r * wp.cos(phi), r * wp.sin(phi), wp.sqrt(wp.max(1.0 - u[0], 0.0)))


@wp.func
def cos_power_dir(a: wp.vec3, n: float, u: wp.vec2) -> wp.vec3:
    """Direction with density (n+1)/(2π) cos^n about a."""
    ct = wp.pow(wp.max(u[0], 1.0e-30), 1.0 / (n + 1.0))
    st = wp.sqrt(wp.max(1.0 - ct * ct, 0.0))
    phi = TWO_PI * u[1]
    return from_axis(a, st * wp.cos(phi), st * wp.sin(phi), ct)


@wp.func
def cos_power_pdf(a: wp.vec3, n: float, v: wp.vec3) -> float:
    c = wp.dot(a, v)
    if c <= 0.0:
        return 0.0
    d = a - v
    return (n + 1.0) / TWO_PI * wp.exp(n * log1p_f(-wp.min(0.5 * wp.dot(d, d), 0.99999994)))


@wp.func
def reflect_about(o: wp.vec3, h: wp.vec3) -> wp.vec3:
    return 2.0 * wp.dot(o, h) * h - o


@wp.func
def beckmann_alphas(mat: Material) -> wp.vec2:
    m = mat.model
    if m == 6:
        return wp.vec2(mat.params[0], mat.params[1])
    return wp.vec2(mat.params[0], mat.params[0])


@wp.func
def beckmann_h(ax: float, ay: float, u: wp.vec2) -> wp.vec3:
    r = wp.sqrt(-wp.log(wp.max(1.0 - u[0], 1.0e-30)))
    phi = TWO_PI * u[1]
    sx = ax * r * wp.cos(phi)
    sy = ay * r * wp.sin(phi)
    return wp.normalize(wp.vec3(sx, sy, 1.0))


@wp.func
def beckmann_pdf_h(ax: float, ay: float, h: wp.vec3) -> float:
    hz = h[2]
    if hz <= 0.0:
        return 0.0
    e = (h[0] * h[0] / (ax * ax) + h[1] * h[1] / (ay * ay)) / (hz * hz)
    if e > 80.0:
        return 0.0
    return wp.exp(-e) / (PI * ax * ay * wp.max(hz * hz * hz, 1.0e-30))


@wp.func
def as_h(nu: float, nv: float, u: wp.vec2) -> wp.vec3:
    q = wp.min(int(u[0] * 4.0), 3)
    uu = u[0] * 4.0 - float(q)
    phi = wp.atan(wp.sqrt((nu + 1.0) / (nv + 1.0)) * wp.tan(0.5 * PI * wp.min(uu, 0.9999999)))
    if q == 1:
        phi = PI - phi
    elif q == 2:
        phi = PI + phi
    elif q == 3:
        phi = TWO_PI - phi
    cp = wp.cos(phi)
    sp = wp.sin(phi)
    e = nu * cp * cp + nv * sp * sp
    ct = wp.pow(wp.max(1.0 - u[1], 1.0e-30), 1.0 / (e + 1.0))
    st = wp.sqrt(wp.max(1.0 - ct * ct, 0.0))
    return wp.vec3(st * cp, st * sp, ct)


@wp.func
def as_pdf_h(nu: float, nv: float, h: wp.vec3) -> float:
    if h[2] <= 0.0:
        return 0.0
    return wp.sqrt((nu + 1.0) * (nv + 1.0)) / TWO_PI * wp.exp(as_exponent_log(h, nu, nv))


@wp.func
def sg_lobe_weight(mat: Material, j: int) -> float:
    lam = mat.lobe_sharpness[j]
    return mat.lobe_amplitude[j] * TWO_PI * expm1_neg_f(2.0 * lam) / lam


@wp.func
def sg_sample_dir(a: wp.vec3, lam: float, u: wp.vec2) -> wp.vec3:
    omc = wp.min(-log1p_f(-u[0] * expm1_neg_f(2.0 * lam)) / lam, 2.0)
    ct = 1.0 - omc
    st = wp.sqrt(wp.max(omc * (2.0 - omc), 0.0))
    phi = TWO_PI * u[1]
    return from_axis(a, st * wp.cos(phi), st * wp.sin(phi), ct)


@wp.func
def sg_mixture_pdf(mat: Material, h: wp.vec3) -> float:
    num = float(0.0)
    den = float(0.0)
    for k in range(mat.lobe_count):
        j = mat.lobe_start + k
        w = sg_lobe_weight(mat, j)
        den += w
        d = h - mat.lobe_axis[j]
        num += mat.lobe_amplitude[j] * wp.exp(-mat.lobe_sharpness[j] * 0.5 * wp.dot(d, d))
    if den <= 0.0:
        return 0.0
    return num / den


@wp.func
def brdf_sample(mat: Material, o: wp.vec3, u_in: wp.vec2) -> wp.vec3:
    """A direction i drawn from the specular sampling density ``brdf_pdf(mat, o, ·)``."""
    m = mat.model
    u = wp.vec2(wp.clamp(u_in[0], 0.0, 0.99999994), wp.clamp(u_in[1], 0.0, 0.99999994))
    if m <= 1:
        return cosine_dir(u)
    if m == 2:
        return cos_power_dir(reflect_z(o), mat.params[0], u)
    if m == 8:
        nl = wp.max(mat.lobe_count, 1)
        q = wp.min(int(u[0] * float(nl)), nl - 1)
        uu = wp.vec2(u[0] * float(nl) - float(q), u[1])
        j = mat.lobe_start + q
        v = wp.cw_mul(mat.lobe_axis[j], o)
        if wp.length(v) <= 0.0:
            return cosine_dir(uu)
        return cos_power_dir(wp.normalize(v), mat.lobe_sharpness[j], uu)
    h = wp.vec3(0.0, 0.0, 1.0)
    if m == 3:
        ct = wp.pow(wp.max(u[0], 1.0e-30), 1.0 / (mat.params[0] + 2.0))
        st = wp.sqrt(wp.max(1.0 - ct * ct, 0.0))
        phi = TWO_PI * u[1]
        h = wp.vec3(st * wp.cos(phi), st * wp.sin(phi), ct)
    elif m == 4 or m == 5 or m == 6:
        al = beckmann_alphas(mat)
        h = beckmann_h(al[0], al[1], u)
    elif m == 7:
        h = as_h(mat.params[0], mat.params[1], u)
    elif m == 9:
        total = float(0.0)
        for k in range(mat.lobe_count):
            total += sg_lobe_weight(mat, mat.lobe_start + k)
        if total <= 0.0:
            return cosine_dir(u)
        t = u[0] * total
        chosen = mat.lobe_start
        acc = float(0.0)
        lo = float(0.0)
        found = int(0)
        for k in range(mat.lobe_count):
            w = sg_lobe_weight(mat, mat.lobe_start + k)
            if found == 0 and (t < acc + w or k == mat.lobe_count - 1):
                chosen = mat.lobe_start + k
                lo = acc
                found = 1
            acc += w
        wsel = sg_lobe_weight(mat, chosen)
        uu = wp.vec2(wp.clamp((t - lo) / wp.max(wsel, 1.0e-30), 0.0, 0.99999994), u[1])
        h = sg_sample_dir(mat.lobe_axis[chosen], mat.lobe_sharpness[chosen], uu)
    return reflect_about(o, h)


@wp.func
def brdf_pdf(mat: Material, o: wp.vec3, i: wp.vec3) -> float:
    """Solid-angle density of ``brdf_sample(mat, o, ·)`` at i."""
    m = mat.model
    if m <= 1:
        if i[2] <= 0.0:
            return 0.0
        return i[2] * INV_PI
    if m == 2:
        return cos_power_pdf(reflect_z(o), mat.params[0], i)
    if m == 8:
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
    hh = o + i
    l = wp.length(hh)
    if l <= 0.0:
        return 0.0
    h = hh / l
    oh = wp.dot(o, h)
    if oh <= 0.0:
        return 0.0
    ph = float(0.0)
    if m == 3:
        if h[2] > 0.0:
            ph = (mat.params[0] + 2.0) / TWO_PI * wp.exp((mat.params[0] + 1.0) * log_cos_theta(h))
    elif m == 4 or m == 5 or m == 6:
        al = beckmann_alphas(mat)
        ph = beckmann_pdf_h(al[0], al[1], h)
    elif m == 7:
        ph = as_pdf_h(mat.params[0], mat.params[1], h)
    elif m == 9:
        ph = sg_mixture_pdf(mat, h)
    return ph / (4.0 * wp.max(oh, 1.0e-6))


# ------------------------------------------------------------------------------------------------
# packing
# ------------------------------------------------------------------------------------------------
class MaterialTable:
    """Kernel-side materials: ``materials`` (wp.array(Material)) plus the shared tables
    ``lobe_axis``, ``lobe_sharpness``, ``lobe_amplitude``, ``merl_data``, ``mo_tables`` (also
    referenced from every Material) and ``records`` (the python dicts)."""

    def __init__(self, materials, lobe_axis, lobe_sharpness, lobe_amplitude, merl_data, mo_tables, records, device):
        self.materials = materials
        self.lobe_axis = lobe_axis
        self.lobe_sharpness = lobe_sharpness
        self.lobe_amplitude = lobe_amplitude
        self.merl_data = merl_data
        self.mo_tables = mo_tables
        self.records = records
        self.device = device

    def __len__(self):
        return len(self.records)


def material_lobes(model, n_lobes=1, method="analytic"):
    """NDF lobes stored in the table for ``model``: (axes (K,3), sharpness (K,), amplitude (K,))."""
    if not model.is_specular:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0)
    if model.MODEL_ID == 8:
        return model.C.copy(), np.maximum(model.N, 0.0), np.ones(len(model.N))
    if model.MODEL_ID == 9:
        return model.ndf_sg(getattr(model, "lobes", n_lobes) or n_lobes, "fit")
    return model.ndf_sg(_lobe_count(model, n_lobes), method)


def pack_materials(models, n_lobes=1, device="cpu", method="analytic"):
    """Pack BRDF models into a :class:`MaterialTable` on ``device``.

    ``n_lobes``: NDF lobes per isotropic model (an int, or one per model); models with their own
    count (Ashikhmin–Shirley ``lobes``, measured ``lobes``, Lafortune) keep theirs. ``method``:
    "analytic" (in-kernel lobes from the parameters, textured parameters allowed) or "fit"
    (nonlinear fits stored in the table)."""
    from ..device import resolve_device

    device = resolve_device(device)
    models = list(models)
    if method not in ("analytic", "fit"):
        raise InputError(f"unknown fit method '{method}' (use analytic or fit)", where="method")
    if isinstance(n_lobes, (list, tuple, np.ndarray)):
        if len(n_lobes) != len(models):
            raise InputError(f"expected {len(models)} lobe counts, got {len(n_lobes)}", where="n_lobes")
        counts = [int(n) for n in n_lobes]
    else:
        counts = [int(n_lobes)] * len(models)
    for n in counts:
        if n < 1:
            raise InputError(f"must be >= 1, got {n}", where="n_lobes")
    axes_all, lam_all, amp_all, merl_parts, mo_parts, records = [], [], [], [], [], []
    start = 0
    merl_off = 0
    for model, n in zip(models, counts):
        rec = dict(model.material_record())
        ax, lam, amp = material_lobes(model, n, method)
        ax = np.asarray(ax, np.float64).reshape(-1, 3)
        rec["lobe_start"] = start
        rec["lobe_count"] = len(lam)
        # in-kernel lobes only where they equal the numpy analytic construction: one isotropic
        # lobe, or the anisotropic construction (multi-lobe isotropic "analytic" falls back to fits)
        aniso = _is_anisotropic(model)
        rec["analytic"] = 1 if (method == "analytic" and rec["model"] in _ANALYTIC
                                and (aniso or len(lam) == 1)) else 0
        start += len(lam)
        axes_all.append(ax)
        lam_all.append(np.asarray(lam, np.float64).reshape(-1))
        amp_all.append(np.asarray(amp, np.float64).reshape(-1))
        if hasattr(model, "merl_table"):
            data = np.asarray(model.merl_table(), np.float32).reshape(-1)
            rec["data_offset"] = merl_off
            merl_parts.append(data)
            merl_off += len(data)
        if hasattr(model, "mo_table"):
            tab = np.asarray(model.mo_table(), np.float32)
            if tab.ndim != 2:
                raise InputError(f"mo_table() must be 2-D, got shape {tab.shape}", where="measured")
            rec["table_index"] = len(mo_parts)
            mo_parts.append(tab)
        records.append(rec)

    def cat(parts, shape):
        return np.concatenate(parts) if parts and sum(len(p) for p in parts) else np.zeros(shape)

    lobe_axis = wp.array(cat(axes_all, (1, 3)).astype(np.float32), dtype=wp.vec3, device=device)
    lobe_sharp = wp.array(cat(lam_all, (1,)).astype(np.float32), dtype=float, device=device)
    lobe_amp = wp.array(cat(amp_all, (1,)).astype(np.float32), dtype=float, device=device)
    merl = wp.array(np.concatenate(merl_parts) if merl_parts else np.zeros(1, np.float32), dtype=float, device=device)
    if mo_parts:
        shapes = {p.shape for p in mo_parts}
        if len(shapes) != 1:
            raise InputError(f"all mo_table() shapes must agree, got {sorted(shapes)}", where="measured")
        mo = wp.array(np.stack(mo_parts), dtype=float, device=device)
    else:
        mo = wp.zeros((1, 1, 1), dtype=float, device=device)

    structs = []
    for rec in records:
        s = Material()
        s.model = int(rec["model"])
        s.kd = wp.vec3(*rec["kd"])
        s.ks = wp.vec3(*rec["ks"])
        s.params = wp.vec4(*rec["params"])
        s.fresnel_kind = int(rec["fresnel_kind"])
        s.fresnel_a = wp.vec3(*rec["fresnel_a"])
        s.fresnel_b = wp.vec3(*rec["fresnel_b"])
        s.lobe_start = int(rec["lobe_start"])
        s.lobe_count = int(rec["lobe_count"])
        s.table_index = int(rec.get("table_index", 0))
        s.data_offset = int(rec.get("data_offset", 0))
        s.analytic = int(rec["analytic"])
        s.lobe_axis = lobe_axis
        s.lobe_sharpness = lobe_sharp
        s.lobe_amplitude = lobe_amp
        s.merl_data = merl
        s.mo_tables = mo
        structs.append(s)
    if structs:
        mats = wp.array(structs, dtype=Material, device=device)
    else:
        mats = wp.empty(0, dtype=Material, device=device)
    return MaterialTable(mats, lobe_axis, lobe_sharp, lobe_amp, merl, mo, records, device)
