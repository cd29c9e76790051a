r"""Kernel-side measured (MERL) BRDF functions, used by :mod:`warp_sg.brdf.kernel.material_wp`.

* ``merl_eval(data, offset, o, i) -> vec3`` — the exact measured BRDF by table lookup, the same
  indexing as the MERL reference code (``BRDFRead.cpp``, Matusik et al. 2003) and pbrt's
  ``RegularHalfangleBRDF`` (lecture "Regular halfangle format"):

  - half vector ``h = (o+i)/‖o+i‖``, ``θh = atan2(√(hx²+hy²), hz)``, ``φh = atan2(hy, hx)``;
  - difference vector ``d = Ry(−θh) Rz(−φh) i`` (Rusinkiewicz), i.e. ``d = (i·x̂h, i·ŷh, i·h)`` with
    ``x̂h = (cos φh cos θh, sin φh cos θh, −sin θh)``, ``ŷh = (−sin φh, cos φh, 0)``;
    ``θd = atan2(√(dx²+dy²), dz)``, ``φd = atan2(dy, dx)`` folded to ``[0, π)`` by reciprocity;
  - indices ``ih = ⌊√(θh/(π/2)) · 90⌋``, ``id = ⌊θd/(π/2) · 90⌋``, ``ip = ⌊φd/π · 180⌋`` (each clamped),
    cell ``ip + 180 (id + 90 ih)``; the three channel blocks (R, G, B) of ``90·90·180`` values follow
    each other from ``data[offset]`` and are already scaled (1/1500, 1.15/1500, 1.66/1500) by
    :meth:`warp_sg.brdf.models.measured.Measured.merl_table`.

  θ's use ``atan2`` rather than ``acos`` because in float32 ``acos(hz)`` near the normal is off by
  ~3e-4 rad, which is more than one √θh bin.

* ``measured_mo(tables, index, eta, o, i) -> vec3`` — ``Mo`` of the fitted microfacet model (paper
  eq. 13) without ``ks``::

      Mo(o, i) = F(|i·h|) / F(1) · S(θo) S(θi) / (π cos θo cos θi)

  with the Fresnel factor of paper eq. 14 (Cook & Torrance 1981) for the relative index of
  refraction ``eta`` (per channel), normalised by its value at normal incidence so that ``ks`` is
  the specular scale at normal incidence; ``S(θo) S(θi)`` is read by bilinear interpolation from
  ``tables[index]``, an ``(n, n)`` table over ``θo`` (rows) and ``θi`` (columns) on the nodes
  ``θ_a = a/(n−1) · π/2`` (built from the PCA-compressed shadowing, see ``Measured.mo_table``).
  The full specular term is then ``ρs = ks ∘ Mo · D(h)``, ``D`` the SG mixture fitted to the NDF.
"""
from __future__ import annotations

import warp as wp

N_TH = wp.constant(90)
N_TD = wp.constant(90)
N_PD = wp.constant(180)
HALF_PI_F = wp.constant(1.5707963267948966)
PI_F = wp.constant(3.141592653589793)
#: smallest cosine in the 1/(π cos θo cos θi) normalisation (grazing guard)
MO_COS_EPS = wp.constant(1.0e-3)


@wp.func
def merl_index(o: wp.vec3, i: wp.vec3) -> int:
    """Cell index (within one channel block) of the MERL table for the direction pair (o, i)."""
    hs = o + i
    hl = wp.length(hs)
    if hl <= 0.0:
        return 0
    h = hs / hl
    r = wp.sqrt(h[0] * h[0] + h[1] * h[1])
    th = wp.atan2(r, h[2])
    cp = float(1.0)
    sp = float(0.0)
    if r > 1.0e-12:
        cp = h[0] / r
        sp = h[1] / r
    ct = h[2]
    st = r
    dx = i[0] * cp * ct + i[1] * sp * ct - i[2] * st
    dy = -i[0] * sp + i[1] * cp
    dz = wp.dot(i, h)
    td = wp.atan2(wp.sqrt(dx * dx + dy * dy), dz)
    pd = wp.atan2(dy, dx)
    if pd < 0.0:
        pd = pd + PI_F
    ith = wp.clamp(int(wp.sqrt(wp.max(th, 0.0) / HALF_PI_F) * float(N_TH)), 0, N_TH - 1)
    itd = wp.clamp(int(td / HALF_PI_F * float(N_TD)), 0, N_TD - 1)
    ipd = wp.clamp(int(pd / PI_F * float(N_PD)), 0, N_PD - 1)
    return ipd + N_PD * (itd + N_TD * ith)


@wp.func
def merl_eval(data: wp.array(dtype=float), offset: int, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    """Exact measured BRDF (RGB) at (o, i), local frame; zero below the horizon (module docstring)."""
    if o[2] <= 0.0 or i[2] <= 0.0:
        return wp.vec3(0.0, 0.0, 0.0)
    idx = offset + merl_index(o, i)
    n = N_TH * N_TD * N_PD
    return wp.vec3(wp.max(data[idx], 0.0), wp.max(data[idx + n], 0.0), wp.max(data[idx + 2 * n], 0.0))


@wp.func
def fresnel_dielectric(eta: float, c_in: float) -> float:
    """Paper eq. 14: ``g = √(η² + c² − 1)``, ``F = (g−c)²/(2(g+c)²) (1 + ((c(g+c)−1)/(c(g−c)+1))²)``;
    1 under total internal reflection."""
    c = wp.clamp(c_in, 0.0, 1.0)
    g2 = eta * eta + c * c - 1.0
    if g2 <= 0.0:
        return 1.0
    g = wp.sqrt(g2)
    a = (g - c) * (g - c) / wp.max(2.0 * (g + c) * (g + c), 1.0e-30)
    num = c * (g + c) - 1.0
    den = c * (g - c) + 1.0
    if wp.abs(den) < 1.0e-30:
        den = 1.0e-30
    q = num / den
    return wp.clamp(a * (1.0 + q * q), 0.0, 1.0)


@wp.func
def shadow_bilinear(tables: wp.array3d(dtype=float), index: int, theta_o: float, theta_i: float) -> float:
    """Bilinear lookup of ``tables[index]`` at (θo, θi), nodes ``a/(n−1) · π/2``."""
    n = tables.shape[1]
    m = tables.shape[2]
    uo = wp.clamp(theta_o / HALF_PI_F, 0.0, 1.0) * float(n - 1)
    ui = wp.clamp(theta_i / HALF_PI_F, 0.0, 1.0) * float(m - 1)
    a0 = wp.min(int(uo), n - 2)
    b0 = wp.min(int(ui), m - 2)
    if n < 2:
        a0 = 0
    if m < 2:
        b0 = 0
    a1 = wp.min(a0 + 1, n - 1)
    b1 = wp.min(b0 + 1, m - 1)
    fa = wp.clamp(uo - float(a0), 0.0, 1.0)
    fb = wp.clamp(ui - float(b0), 0.0, 1.0)
    v00 = tables[index, a0, b0]
    v01 = tables[index, a0, b1]
    v10 = tables[index, a1, b0]
    v11 = tables[index, a1, b1]
    return (1.0 - fa) * ((1.0 - fb) * v00 + fb * v01) + fa * ((1.0 - fb) * v10 + fb * v11)


@wp.func
def measured_mo(tables: wp.array3d(dtype=float), index: int, eta: wp.vec3, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    """``Mo(o, i) = F(|i·h|)/F(1) · S(θo)S(θi)/(π cos θo cos θi)`` without ks (module docstring)."""
    if o[2] <= 0.0 or i[2] <= 0.0:
        return wp.vec3(0.0, 0.0, 0.0)
    hs = o + i
    hl = wp.length(hs)
    if hl <= 0.0:
        return wp.vec3(0.0, 0.0, 0.0)
    h = hs / hl
    c = wp.abs(wp.dot(i, h))
    to = wp.atan2(wp.sqrt(o[0] * o[0] + o[1] * o[1]), o[2])
    ti = wp.atan2(wp.sqrt(i[0] * i[0] + i[1] * i[1]), i[2])
    s = shadow_bilinear(tables, index, to, ti)
    norm = s / (PI_F * wp.max(o[2], MO_COS_EPS) * wp.max(i[2], MO_COS_EPS))
    out = wp.vec3(0.0, 0.0, 0.0)
    for ch in range(3):
        e = eta[ch]
        f1 = fresnel_dielectric(e, 1.0)
        if f1 <= 1.0e-12:
            out[ch] = norm
        else:
            out[ch] = fresnel_dielectric(e, c) / f1 * norm
    return out
