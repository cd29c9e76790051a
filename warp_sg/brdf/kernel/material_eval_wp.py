r"""Evaluation side of the kernel BRDF contract (:mod:`warp_sg.brdf.kernel.material_wp`, which re-exports
every name and documents the contract): the model-independent building blocks of ``brdf_eval``,
``brdf_mo``, ``brdf_ndf`` and the SG lobes of the specular slice (half vector, Fresnel, shadowing
terms, GGX and Ashikhmin–Shirley pieces, the Lafortune lobe, the GGX node table, the spherical
warp of an axis ``warp_axis``, the horizon lift ``above``). The functions that switch on
``mat.model`` are built from these in :mod:`~warp_sg.brdf.kernel.material_variants`, once per set of
models. Local frame, z+ = normal, x = tangent.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func / struct annotations.
import warp as wp

from ...core.image_io import LUMINANCE
from ...numeric.onb import frame_bitangent, frame_tangent
from .material_struct import LN_EPS, WARP_COS_EPS, Material
from .measured_wp import fresnel_dielectric


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


#: the luminance weights (:data:`warp_sg.core.image_io.LUMINANCE`) as kernel constants
LUM_R, LUM_G, LUM_B = (wp.constant(float(w)) for w in LUMINANCE)


@wp.func
def lum(c: wp.vec3) -> float:
    return LUM_R * c[0] + LUM_G * c[1] + LUM_B * c[2]


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


@wp.func
def ggx_lambda_cos(v: wp.vec3, ax: float, ay: float) -> float:
    """GGX ``L(v) = vz Λ(v) = a²/(2(√(vz² + a²) + vz))``, ``a² = αx² vx² + αy² vy²`` (ggx.py)."""
    vz = wp.max(v[2], 0.0)
    a2 = ax * ax * v[0] * v[0] + ay * ay * v[1] * v[1]
    den = 2.0 * (wp.sqrt(vz * vz + a2) + vz)
    if den <= 0.0:
        return 0.0
    return a2 / den


@wp.func
def ggx_g1(v: wp.vec3, ax: float, ay: float) -> float:
    """GGX Smith ``G1(v) = vz/(vz + L(v))`` (0 at and below the horizon)."""
    vz = v[2]
    if vz <= 0.0:
        return 0.0
    return vz / (vz + ggx_lambda_cos(v, ax, ay))


@wp.func
def ggx_g2_over_cos(o: wp.vec3, i: wp.vec3, ax: float, ay: float) -> float:
    """Height-correlated ``G2/((n·i)(n·o)) = 1/((n·i)(n·o) + (n·i)L(o) + (n·o)L(i))`` (ggx.py)."""
    co = wp.max(o[2], 1.0e-12)
    ci = wp.max(i[2], 1.0e-12)
    return 1.0 / (co * ci + ci * ggx_lambda_cos(o, ax, ay) + co * ggx_lambda_cos(i, ax, ay))


@wp.func
def ggx_ndf_peak1(h: wp.vec3, ax: float, ay: float) -> float:
    """GGX ``D̂(h) = 1/q²``, ``q = hx²/αx² + hy²/αy² + hz²`` (peak 1; 0 below the horizon)."""
    if h[2] <= 0.0:
        return 0.0
    q = h[0] * h[0] / (ax * ax) + h[1] * h[1] / (ay * ay) + h[2] * h[2]
    return 1.0 / (q * q)


@wp.func
def ggx_extent(a: float) -> float:
    """``θv`` of anisotropic GGX: ``tan²θv = (E − 1)/(1/α² − E)``, ``E = ε^{−1/2}``, capped at 80°."""
    E = wp.exp(-0.5 * LN_EPS)
    den = 1.0 / (a * a) - E
    cap = 1.3962634015954636
    if den <= 0.0:
        return cap
    return wp.min(wp.atan(wp.sqrt((E - 1.0) / den)), cap)


#: smallest cosine of the (clamped) view / lobe directions in the shading frame (``above``)
COS_MIN = wp.constant(1.0e-3)


@wp.func
def above(v: wp.vec3) -> wp.vec3:
    """v with its z clamped to ≥ COS_MIN (renormalised): keeps grazing directions shadeable."""
    if v[2] >= COS_MIN:
        return v
    xy = wp.sqrt(wp.max(v[0] * v[0] + v[1] * v[1], 1.0e-30))
    s = wp.sqrt(1.0 - COS_MIN * COS_MIN) / xy
    return wp.vec3(v[0] * s, v[1] * s, COS_MIN)


# ------------------------------------------------------------------------------------------------
# Lafortune lobe and Oren–Nayar parameters
# ------------------------------------------------------------------------------------------------
@wp.func
def lafortune_lobe(mat: Material, j: int, o: wp.vec3, i: wp.vec3) -> float:
    c = mat.lobe_axis[j]
    d = c[0] * o[0] * i[0] + c[1] * o[1] * i[1] + c[2] * o[2] * i[2]
    if d <= 0.0:
        return 0.0
    return mat.lobe_amplitude[j] * wp.exp(wp.min(mat.lobe_sharpness[j] * wp.log(d), 80.0))


@wp.func
def oren_nayar_params(sigma: float) -> wp.vec4:
    """``params`` of an Oren–Nayar material for roughness σ (radians): (A, B, σ, 0) (lambert.py)."""
    s2 = sigma * sigma
    return wp.vec4(1.0 - s2 / (2.0 * (s2 + 0.33)), 0.45 * s2 / (s2 + 0.09), sigma, 0.0)


# ------------------------------------------------------------------------------------------------
# SG lobes: GGX node table, anisotropic overlap, spherical warp of an axis
# ------------------------------------------------------------------------------------------------
#: GGX roughness nodes of the shipped fits (ggx.py TABLE_A0, TABLE_STEP, TABLE_N; MIN_LAMBDA)
GGX_TABLE_A0 = wp.constant(0.025)
GGX_TABLE_STEP = wp.constant(0.025)
GGX_TABLE_N = wp.constant(39)
GGX_MIN_LAMBDA = wp.constant(1.0e-3)


@wp.func
def ggx_table_lobe(mat: Material, k: int, alpha: float):
    """Isotropic GGX lobe k at roughness α from the node table stored at ``lobe_start``
    (node-major, ``lobe_count`` lobes a node): normalised sharpness and amplitude interpolated
    linearly in α, ``λ = max(λ_norm (1/α'² − 1), MIN_LAMBDA)``, ``α' = min(α, 1)``
    (ggx.py ``table_lobes``). Returns (sharpness, amplitude)."""
    a1 = GGX_TABLE_A0 + GGX_TABLE_STEP * float(GGX_TABLE_N - 1)
    t = (wp.clamp(alpha, GGX_TABLE_A0, a1) - GGX_TABLE_A0) / GGX_TABLE_STEP
    j = wp.min(int(t), GGX_TABLE_N - 2)
    f = t - float(j)
    n = mat.lobe_count
    i0 = mat.lobe_start + j * n + k
    i1 = i0 + n
    ln = (1.0 - f) * mat.lobe_sharpness[i0] + f * mat.lobe_sharpness[i1]
    mu = (1.0 - f) * mat.lobe_amplitude[i0] + f * mat.lobe_amplitude[i1]
    am = wp.min(alpha, 1.0)
    return wp.max(ln * (1.0 / (am * am) - 1.0), GGX_MIN_LAMBDA), mu


@wp.func
def aniso_axis(n: int, k: int, theta_v: float, wide_x: int) -> wp.vec3:
    """Axis of lobe k of the anisotropic layout of supplement eq. 14: n lobes spaced 2θv/(n + 1)
    along the wide axis (x if ``wide_x`` else y)."""
    theta_i = 2.0 * theta_v / float(n + 1)
    a = (float(k) - 0.5 * float(n - 1)) * theta_i
    axis = wp.vec3(0.0, wp.sin(a), wp.cos(a))
    if wide_x == 1:
        axis = wp.vec3(wp.sin(a), 0.0, wp.cos(a))
    return axis


@wp.func
def _aniso_overlap(n: int, k: int, lam: float, theta_v: float) -> float:
    """Σ_j e^{−λ(1 − cos((k − j)θi))}, θi = 2θv/(n + 1): the overlap of the layout's lobes at lobe k
    (GGX divides its amplitudes by it; fit.aniso_lobes)."""
    theta_i = 2.0 * theta_v / float(n + 1)
    s = float(0.0)
    for j in range(n):
        d = float(k - j) * theta_i
        sd = wp.sin(0.5 * d)
        s += wp.exp(-lam * 2.0 * sd * sd)
    return s


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
