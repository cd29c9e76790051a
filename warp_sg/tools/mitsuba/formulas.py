r"""The BRDF models of the scene format, written again from their published formulas for Mitsuba 3.

This module is the independent side of the accuracy checks: it never imports the renderer's BRDF
code (``warp_sg.brdf``); each model below is typed from its source, in Dr.Jit, so that the same code
runs in Mitsuba's ``scalar_rgb`` and ``llvm_ad_rgb`` variants. Directions are in the local
shading frame (z = normal, x = tangent): ``o`` towards the viewer (Mitsuba's ``si.wi``), ``i``
towards the light (Mitsuba's ``wo``), both pointing away from the surface. Each function returns
the BRDF ``f(o, i)`` (RGB, without the cosine), zero unless both directions are above the surface.

Sources (the scene-key reference, docs/scene-keys.md, names the parameters):

* Lambert ``kd/π``; Oren–Nayar, qualitative form (Oren & Nayar 1994; pbrt-v3 §8.4.2):
  ``kd/π (A + B max(0, cos(φi − φo)) sin α tan β)``, ``A = 1 − σ²/(2(σ² + 0.33))``,
  ``B = 0.45σ²/(σ² + 0.09)``, ``α = max(θi, θo)``, ``β = min(θi, θo)``.
* Phong (Lewis 1994 normalisation): ``kd/π + ks (n+2)/(2π) max(0, r·i)^n``, ``r`` the mirror of ``o``.
* Blinn–Phong (Wang et al. 2009 supplement eq. 7): ``kd/π + ks (n+2)/(2π) (n·h)^n``.
* Cook–Torrance (Cook & Torrance 1982, as in Wang et al. 2009 eq. 10–11):
  ``kd/π + ks F(i·h) G exp(−(θh/m)²) / (π (n·i)(n·o))``.
* Torrance–Sparrow with a Beckmann distribution (pbrt-v2 ``Microfacet``; Walter et al. 2007 eq. 25):
  ``kd/π + ks D_B G F(i·h) / (4 (n·i)(n·o))``, ``D_B = exp(−tan²θh/m²)/(π m² cos⁴θh)``.
* V-cavity shadowing of both (Torrance & Sparrow 1967; Blinn 1977):
  ``G = min(1, 2(n·h)(n·o)/(o·h), 2(n·h)(n·i)/(i·h))``.
* Ward (Ward 1992, eq. 5a): ``kd/π + ks exp(−tan²θh (cos²φh/αx² + sin²φh/αy²)) / (4π αx αy √((n·i)(n·o)))``.
* Ashikhmin–Shirley specular lobe (Ashikhmin & Shirley 2000, eq. 4):
  ``ks √((nu+1)(nv+1)) (n·h)^{nu cos²φh + nv sin²φh} F(h·i) / (8π (h·i) max(n·i, n·o))``, plus ``kd/π``.
* Lafortune (Lafortune et al. 1997): ``kd/π + ks Σj max(0, cx ox ix + cy oy iy + cz oz iz)^{nj}``.
* GGX / Trowbridge–Reitz (Walter et al. 2007 eq. 33; Heitz 2014 eq. 99, height-correlated Smith):
  ``kd/π + ks F(i·h) D(h) G2(o, i) / (4 (n·i)(n·o))`` with Mitsuba's own GGX ``D`` and ``G1``
  (``mi.MicrofacetDistribution``), ``Λ = 1/G1 − 1``, ``G2 = 1/(1 + Λ(o) + Λ(i))``.
* Fresnel: none (1); Schlick ``f0 + (1 − f0)(1 − c)⁵``; a dielectric of index η and a conductor
  (η, k) by Mitsuba's exact unpolarised ``mi.fresnel`` / ``mi.fresnel_conductor``.
"""
from __future__ import annotations

import math

INV_PI = 1.0 / math.pi


def _mods():
    import drjit as dr
    import mitsuba as mi

    return dr, mi


def rgb(mi, v):
    """A Mitsuba colour from a number or three numbers."""
    if isinstance(v, (int, float)):
        return mi.Color3f(float(v))
    v = [float(x) for x in v]
    return mi.Color3f(v[0], v[1], v[2]) if len(v) == 3 else mi.Color3f(v[0])


def fresnel(table, c):
    """``F(c)`` (RGB) of a scene file's ``fresnel`` value already resolved to a dict:
    ``{}`` (none), ``{"schlick": f0}``, ``{"eta": η}`` (dielectric) or ``{"eta": η, "k": k}`` (conductor)."""
    dr, mi = _mods()
    c = dr.clip(c, 0.0, 1.0)
    if not table:
        return mi.Color3f(1.0)
    if "schlick" in table:
        f0 = rgb(mi, table["schlick"])
        w = dr.square(dr.square(1.0 - c)) * (1.0 - c)
        return f0 + (1.0 - f0) * w
    eta = table["eta"]
    eta = [float(eta)] * 3 if isinstance(eta, (int, float)) else [float(x) for x in eta]
    if "k" in table:
        k = table["k"]
        k = [float(k)] * 3 if isinstance(k, (int, float)) else [float(x) for x in k]
        return mi.Color3f(*[mi.fresnel_conductor(c, mi.Complex2f(e, kk)) for e, kk in zip(eta, k)])
    return mi.Color3f(*[mi.fresnel(c, mi.Float(e))[0] for e in eta])


def _half(dr, mi, o, i):
    h = o + i
    n = dr.norm(h)
    return h / dr.maximum(n, 1e-20)


def _vcavity(dr, h, o, i):
    """``min(1, 2(n·h)(n·o)/(o·h), 2(n·h)(n·i)/(i·h))`` (o·h = i·h for the half vector)."""
    oh = dr.maximum(dr.dot(o, h), 1e-20)
    return dr.minimum(1.0, dr.minimum(2.0 * h.z * o.z / oh, 2.0 * h.z * i.z / oh))


def lambert(p, o, i):
    dr, mi = _mods()
    return rgb(mi, p.get("kd", 0.8)) * INV_PI


def oren_nayar(p, o, i):
    dr, mi = _mods()
    s2 = float(p.get("sigma", 0.3)) ** 2
    a = 1.0 - s2 / (2.0 * (s2 + 0.33))
    b = 0.45 * s2 / (s2 + 0.09)
    sin_i = dr.safe_sqrt(1.0 - dr.square(i.z))
    sin_o = dr.safe_sqrt(1.0 - dr.square(o.z))
    # cos(φi − φo) from the projected directions
    cphi = (i.x * o.x + i.y * o.y) / dr.maximum(sin_i * sin_o, 1e-20)
    cphi = dr.select((sin_i > 1e-6) & (sin_o > 1e-6), dr.maximum(cphi, 0.0), 0.0)
    # α = max(θi, θo) has the smaller cosine; β = min has the larger
    sin_alpha = dr.select(i.z < o.z, sin_i, sin_o)
    tan_beta = dr.select(i.z < o.z, sin_o / dr.maximum(o.z, 1e-20), sin_i / dr.maximum(i.z, 1e-20))
    return rgb(mi, p.get("kd", 0.8)) * INV_PI * (a + b * cphi * sin_alpha * tan_beta)


def _diffuse(mi, p):
    return rgb(mi, p.get("kd", 0.0)) * INV_PI


def phong(p, o, i):
    dr, mi = _mods()
    n = float(p.get("n", 50.0))
    r = mi.Vector3f(-o.x, -o.y, o.z)
    c = dr.maximum(dr.dot(r, i), 0.0)
    return _diffuse(mi, p) + rgb(mi, p.get("ks", 1.0)) * ((n + 2.0) / (2.0 * math.pi) * dr.power(c, n))


def blinn_phong(p, o, i):
    dr, mi = _mods()
    n = float(p.get("n", 50.0))
    h = _half(dr, mi, o, i)
    return _diffuse(mi, p) + rgb(mi, p.get("ks", 1.0)) * ((n + 2.0) / (2.0 * math.pi) *
                                                          dr.power(dr.maximum(h.z, 0.0), n))


def cook_torrance(p, o, i):
    dr, mi = _mods()
    m = float(p.get("m", 0.2))
    h = _half(dr, mi, o, i)
    th = dr.acos(dr.clip(h.z, -1.0, 1.0))
    d = dr.exp(-dr.square(th / m))
    g = _vcavity(dr, h, o, i)
    spec = fresnel(p.get("fresnel"), dr.dot(i, h)) * (g * d / (math.pi * dr.maximum(i.z * o.z, 1e-20)))
    return _diffuse(mi, p) + rgb(mi, p.get("ks", 1.0)) * spec


def torrance_sparrow(p, o, i):
    dr, mi = _mods()
    m = float(p.get("m", 0.2))
    h = _half(dr, mi, o, i)
    c2 = dr.square(dr.maximum(h.z, 1e-10))
    tan2 = (1.0 - c2) / c2
    d = dr.exp(-tan2 / (m * m)) / (math.pi * m * m * c2 * c2)
    g = _vcavity(dr, h, o, i)
    spec = fresnel(p.get("fresnel"), dr.dot(i, h)) * (d * g / (4.0 * dr.maximum(i.z * o.z, 1e-20)))
    return _diffuse(mi, p) + rgb(mi, p.get("ks", 1.0)) * spec


def _alphas(p, default):
    a = p.get("alpha")
    ax = float(p.get("alpha_x", a if a is not None else default))
    ay = float(p.get("alpha_y", a if a is not None else default))
    return ax, ay


def ward(p, o, i):
    dr, mi = _mods()
    ax, ay = _alphas(p, 0.2)
    h = _half(dr, mi, o, i)
    hz2 = dr.square(dr.maximum(h.z, 1e-10))
    e = -(dr.square(h.x / ax) + dr.square(h.y / ay)) / hz2
    spec = dr.exp(e) / (4.0 * math.pi * ax * ay * dr.sqrt(dr.maximum(i.z * o.z, 1e-24)))
    return _diffuse(mi, p) + rgb(mi, p.get("ks", 1.0)) * spec


def ashikhmin_shirley(p, o, i):
    dr, mi = _mods()
    nu, nv = float(p.get("nu", 100.0)), float(p.get("nv", 100.0))
    h = _half(dr, mi, o, i)
    s2 = dr.square(h.x) + dr.square(h.y)
    # exponent nu cos²φh + nv sin²φh; cos²φh = hx²/(hx² + hy²); at the normal any φ gives (n·h)^e = 1
    e = dr.select(s2 > 1e-20, (nu * dr.square(h.x) + nv * dr.square(h.y)) / dr.maximum(s2, 1e-20), 0.5 * (nu + nv))
    d = dr.power(dr.maximum(h.z, 1e-20), e)
    hi = dr.maximum(dr.dot(h, i), 1e-20)
    norm = math.sqrt((nu + 1.0) * (nv + 1.0)) / (8.0 * math.pi)
    spec = fresnel(p.get("fresnel"), hi) * (norm * d / (hi * dr.maximum(i.z, o.z)))
    return _diffuse(mi, p) + rgb(mi, p.get("ks", 1.0)) * spec


def lafortune(p, o, i):
    dr, mi = _mods()
    total = mi.Float(0.0)
    for lobe in p.get("lobes", [{"cx": -1.0, "cy": -1.0, "cz": 1.0, "n": 20.0}]):
        v = float(lobe["cx"]) * o.x * i.x + float(lobe["cy"]) * o.y * i.y + float(lobe["cz"]) * o.z * i.z
        total = total + dr.power(dr.maximum(v, 0.0), float(lobe["n"]))
    return _diffuse(mi, p) + rgb(mi, p.get("ks", 1.0)) * total


def ggx(p, o, i):
    dr, mi = _mods()
    ax, ay = _alphas(p, 0.3)
    dist = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, ax, ay, False)
    h = _half(dr, mi, o, i)
    d = dist.eval(h)
    lam_o = 1.0 / dr.maximum(dist.smith_g1(o, h), 1e-20) - 1.0
    lam_i = 1.0 / dr.maximum(dist.smith_g1(i, h), 1e-20) - 1.0
    g2 = 1.0 / (1.0 + lam_o + lam_i)
    spec = fresnel(p.get("fresnel"), dr.dot(i, h)) * (d * g2 / (4.0 * dr.maximum(i.z * o.z, 1e-20)))
    return _diffuse(mi, p) + rgb(mi, p.get("ks", 1.0)) * spec


#: scene-file model name → BRDF function
MODELS = {
    "lambert": lambert,
    "oren_nayar": oren_nayar,
    "phong": phong,
    "blinn_phong": blinn_phong,
    "cook_torrance": cook_torrance,
    "torrance_sparrow": torrance_sparrow,
    "ward": ward,
    "ashikhmin_shirley": ashikhmin_shirley,
    "lafortune": lafortune,
    "ggx": ggx,
}


def sampling_alphas(p) -> tuple[float, float] | None:
    """GGX roughness ``(αx, αy)`` of the half-vector distribution that importance-samples a model's
    specular lobe (None: diffuse only). Any positive density gives an unbiased estimate; this one only
    puts the samples where the lobe is (a cosine power n is about a GGX of α = √(2/(n + 2)))."""
    model = p["model"]
    if model in ("lambert", "oren_nayar"):
        return None
    if model in ("phong", "blinn_phong"):
        a = math.sqrt(2.0 / (float(p.get("n", 50.0)) + 2.0))
        return (a, a) if model == "blinn_phong" else (0.5 * a, 0.5 * a)
    if model in ("cook_torrance", "torrance_sparrow"):
        m = float(p.get("m", 0.2))
        return m, m
    if model in ("ward", "ggx"):
        return _alphas(p, 0.2 if model == "ward" else 0.3)
    if model == "ashikhmin_shirley":
        return (math.sqrt(2.0 / (float(p.get("nu", 100.0)) + 2.0)), math.sqrt(2.0 / (float(p.get("nv", 100.0)) + 2.0)))
    if model == "lafortune":
        n = min(float(lb["n"]) for lb in p.get("lobes", [{"n": 20.0}]))
        a = math.sqrt(2.0 / (n + 2.0))
        return a, a
    if model == "measured":
        return 0.3, 0.3
    raise KeyError(model)


__all__ = ["MODELS", "fresnel", "sampling_alphas", "rgb"]
