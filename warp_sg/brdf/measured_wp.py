r"""Kernel-side measured (MERL) BRDF functions — PLACEHOLDER written by the BRDF helper so that
``material_wp`` compiles; the measured-BRDF helper owns this file and replaces it.

Signatures (contract with ``material_wp``):

* ``merl_eval(data, offset, o, i) -> vec3``: exact measured BRDF. Assumed layout here: MERL's
  three channel blocks of 90·90·180 values, already scaled, starting at ``offset``;
  nearest-bin lookup in (√θh, θd, φd) (lecture "RegularHalfangleBRDF").
* ``measured_mo(tables, index, eta, o, i) -> vec3``: Mo of the microfacet factorisation without
  ks. Placeholder: zero.
"""
from __future__ import annotations

import warp as wp

N_TH = wp.constant(90)
N_TD = wp.constant(90)
N_PD = wp.constant(180)


@wp.func
def merl_eval(data: wp.array(dtype=float), offset: int, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    if o[2] <= 0.0 or i[2] <= 0.0:
        return wp.vec3(0.0, 0.0, 0.0)
    h = wp.normalize(o + i)
    th = wp.acos(wp.clamp(h[2], -1.0, 1.0))
    ph = wp.atan2(h[1], h[0])
    # rotate i into the half-vector frame (Rusinkiewicz): rotate by -ph about z, then -th about y
    cp = wp.cos(-ph)
    sp = wp.sin(-ph)
    v = wp.vec3(i[0] * cp - i[1] * sp, i[0] * sp + i[1] * cp, i[2])
    ct = wp.cos(-th)
    st = wp.sin(-th)
    d = wp.vec3(v[0] * ct + v[2] * st, v[1], -v[0] * st + v[2] * ct)
    td = wp.acos(wp.clamp(d[2], -1.0, 1.0))
    pd = wp.atan2(d[1], d[0])
    if pd < 0.0:
        pd = pd + 3.14159265
    ith = wp.clamp(int(wp.sqrt(th / 1.5707963) * float(N_TH)), 0, N_TH - 1)
    itd = wp.clamp(int(td / 1.5707963 * float(N_TD)), 0, N_TD - 1)
    ipd = wp.clamp(int(pd / 3.14159265 * float(N_PD)), 0, N_PD - 1)
    idx = offset + ipd + N_PD * (itd + N_TD * ith)
    n = N_TH * N_TD * N_PD
    return wp.vec3(wp.max(data[idx], 0.0), wp.max(data[idx + n], 0.0), wp.max(data[idx + 2 * n], 0.0))


@wp.func
def measured_mo(tables: wp.array3d(dtype=float), index: int, eta: wp.vec3, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    return wp.vec3(0.0, 0.0, 0.0)
