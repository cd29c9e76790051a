r"""Importance sampling side of the kernel BRDF contract (:mod:`warp_sg.brdf.kernel.material_wp`, which
re-exports every name and documents each model's sampling): the building blocks of the models'
``sample`` / ``pdf`` hooks (cosine, cosine-power, Beckmann, Ashikhmin–Shirley, GGX visible-normal
and SG mixture directions with their densities). ``brdf_sample`` / ``brdf_pdf`` themselves switch
on the model and are generated from the registry (:mod:`~warp_sg.brdf.kernel.material_variants`).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func / struct annotations.
import warp as wp

from .material_eval_wp import (
    as_exponent_log,
    expm1_neg_f,
    from_axis,
    ggx_g1,
    ggx_ndf_peak1,
    log1p_f,
)
from .material_struct import INV_PI, PI, TWO_PI, Material


# ------------------------------------------------------------------------------------------------
# importance sampling of the specular part
# ------------------------------------------------------------------------------------------------
@wp.func
def cosine_dir(u: wp.vec2) -> wp.vec3:
    r = wp.sqrt(u[0])
    phi = TWO_PI * u[1]
    return wp.vec3(r * wp.cos(phi), r * wp.sin(phi), wp.sqrt(wp.max(1.0 - u[0], 0.0)))


@wp.func
def cosine_sample(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
    """The sampling of a diffuse-only model: cosine-distributed directions."""
    return cosine_dir(u)


@wp.func
def cosine_pdf(mat: Material, o: wp.vec3, i: wp.vec3) -> float:
    """The density of :func:`cosine_sample`: ``max(i_z, 0)/π``."""
    if i[2] <= 0.0:
        return 0.0
    return i[2] * INV_PI


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
def ggx_vndf_h(o: wp.vec3, ax: float, ay: float, u: wp.vec2) -> wp.vec3:
    """GGX visible normal for view o (oz > 0), Heitz 2018 listing 1 (ggx.py ``vndf_sample_h``)."""
    vh = wp.normalize(wp.vec3(ax * o[0], ay * o[1], o[2]))
    lensq = vh[0] * vh[0] + vh[1] * vh[1]
    t1 = wp.vec3(1.0, 0.0, 0.0)
    if lensq > 0.0:
        t1 = wp.vec3(-vh[1], vh[0], 0.0) / wp.sqrt(lensq)
    t2 = wp.cross(vh, t1)
    r = wp.sqrt(u[0])
    phi = TWO_PI * u[1]
    p1 = r * wp.cos(phi)
    p2 = r * wp.sin(phi)
    s = 0.5 * (1.0 + vh[2])
    p2 = (1.0 - s) * wp.sqrt(wp.max(1.0 - p1 * p1, 0.0)) + s * p2
    nh = p1 * t1 + p2 * t2 + wp.sqrt(wp.max(1.0 - p1 * p1 - p2 * p2, 0.0)) * vh
    return wp.normalize(wp.vec3(ax * nh[0], ay * nh[1], wp.max(nh[2], 1.0e-7)))


@wp.func
def ggx_pdf_i(o: wp.vec3, h: wp.vec3, ax: float, ay: float) -> float:
    """Density of the reflected visible-normal sample: ``G1(o) D(h)/(4 (n·o))``, D = D̂/(π αx αy)."""
    return ggx_g1(o, ax, ay) * ggx_ndf_peak1(h, ax, ay) / (4.0 * PI * ax * ay * o[2])


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
