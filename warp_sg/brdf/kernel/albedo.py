r"""Energy of the SG specular slice against the exact BRDF: a per-material correction of the
environment's specular term.

The environment's specular term (eq. 41, ``warp_sg.shading.kernel``) is a sum over the SG lobes of the
warped BRDF slice (eq. 17–22). The warp takes ``Mo`` (Fresnel, shadowing, the 1/(n·i)(n·o)
factors) at each lobe's axis and warps every lobe isotropically, so the slice's total energy is off
by a view-dependent factor that more NDF lobes cannot remove: in a white furnace (constant
environment) a gold GGX sphere is 11 % dark at normal view and 6 % bright at grazing for α = 0.2,
19 % dark / 12 % bright for α = 0.5; Cook–Torrance (m = 0.25) −8 % / +11 %, Blinn–Phong (n = 50)
+3 % / −22 %, anisotropic GGX (0.3, 0.08) −11 % / −25 %. Under a real sky that is the bias of every
glossy object.

The cure is cheap and exact where it can be: the directional albedo of the specular term

    A(o) = ∫ ρs(o, i) (n·i) di                      (exact BRDF, ``brdf_specular``, F included)
    A*(o) = Σ_k μ_k ∫G_k e(n·p_k, λ_k)              (the slice lobes the shading kernel uses)

is tabulated per material over the view, and the shading kernel multiplies the environment's
specular sum by ``c(o) = A(o)/A*(o)`` (RGB; clamped to [1/4, 4]). In a white furnace the term is
then exact whatever the model; under a sky the slice keeps its shape (where the highlight is) and
gets the BRDF's energy. Lights do not need it: they evaluate the exact BRDF.

Table per material (``Material.albedo``, one shared array): ``NQ × NMU`` entries, ``NMU`` = 32
view angles θ_o from 0 to 89.9° (uniform in √(1 − cos θ_o)), and a second axis ``q`` of ``NQ``
entries:

* ``kind`` 0 — none (a diffuse model): ``c = 1``;
* ``kind`` 1 — isotropic: ``NQ = 1``, or, when the first parameter is textured (a glTF roughness
  map), ``NQ = 8`` values of it log-spaced over the texture's range ``[q0, q1]`` (the kernel
  interpolates at the texel's value);
* ``kind`` 2 — anisotropic (Ashikhmin–Shirley, Ward and GGX with two roughnesses): ``NQ = 8``
  view azimuths φ_o ∈ [0, π/2] relative to the tangent (the models are symmetric in ±x, ±y).

``A(o)`` is a quasi-Monte-Carlo estimate with the model's own importance sampling
(``brdf_sample``/``brdf_pdf``, as the Monte-Carlo reference; 2048 Hammersley points per entry: the
weights ρs cos/pdf are smooth, the estimate is within ~0.3 %), ``A*(o)`` the exact sum of the
lobes. Both are computed by one Warp kernel per model set (:func:`albedo_kernel`), so they use
the renderer's own functions.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import math

import numpy as np
import warp as wp

from ...sg.algebra_wp import sg_integral
from ...sg.irradiance import sg_irradiance_norm
from ..registry import roughness_kernel, specular_codes, textured_lobe_codes
from .material_struct import Material
from .material_variants import material_funcs

NMU = 32
NQ = 8
SAMPLES = 2048
THETA_MAX = 0.999 * 0.5 * math.pi
#: the table's view axis: s = √(1 − cos θ_o), uniform from 0 to S_MAX (θ_o from 0 to 89.9°; ≈ θ/√2
#: near the normal, finite slope at grazing, and one square root per pixel instead of an acos)
S_MAX = math.sqrt(1.0 - math.cos(THETA_MAX))
C_MIN, C_MAX = 0.25, 4.0
KIND_NONE, KIND_ISO, KIND_ANISO = 0, 1, 2
_S_MAX = wp.constant(S_MAX)
_C_MIN = wp.constant(C_MIN)
_C_MAX = wp.constant(C_MAX)
_HALF_PI = wp.constant(0.5 * math.pi)


@wp.func
def _radical_inverse(i: int) -> float:
    """Van der Corput radical inverse in base 2 of i (the Hammersley sequence's second coordinate)."""
    n = i
    f = float(0.5)
    r = float(0.0)
    while n > 0:
        if n % 2 == 1:
            r += f
        n = n // 2
        f *= 0.5
    return r


@wp.func
def _q_value(log_q0: float, inv_span: float, q: int, nq: int) -> float:
    """The q-th of ``nq`` values log-spaced from q0 (``ln q0``) over ``ln(q1/q0) = 1/inv_span``
    (q0 itself when nq = 1)."""
    if nq <= 1:
        return wp.exp(log_q0)
    return wp.exp(log_q0 + float(q) / (float(nq - 1) * inv_span))


_KERNELS: dict = {}


def albedo_kernel(models):
    """The table kernel for the model codes ``models`` (one thread per entry; cached per set)."""
    key = tuple(sorted(int(m) for m in models))
    if key in _KERNELS:
        return _KERNELS[key]
    MF = material_funcs(key)
    brdf_specular, shading_slice_lobe, slice_lobe_count = MF.brdf_specular, MF.shading_slice_lobe, MF.slice_lobe_count
    brdf_sample, brdf_pdf = MF.brdf_sample, MF.brdf_pdf  # (the set's own: a model registered after the import too)
    # the models whose textured width sets kernel parameter 1 too (its ``Param.kernel``: an isotropic
    # α map sets αx = αy, as ``textured_material`` does), as bits of the model code
    PAIRED = sum(1 << c for c in key if 1 in roughness_kernel(c))

    def albedo(mats: wp.array(dtype=Material), entry_mat: wp.array(dtype=int), entry_q: wp.array(dtype=int),
               entry_mu: wp.array(dtype=int), irr: wp.array2d(dtype=float), samples: int,
               out: wp.array(dtype=wp.vec3)):
        e = wp.tid()
        m = mats[entry_mat[e]]
        q = entry_q[e]
        sv = _S_MAX * float(entry_mu[e]) / float(NMU - 1)
        ct = 1.0 - sv * sv
        phi = float(0.0)
        if m.albedo_kind == KIND_ANISO:
            phi = _HALF_PI * float(q) / float(NQ - 1)
        elif m.albedo_kind == KIND_ISO and m.albedo_nq > 1:  # a textured width: the q-th value of its range
            v = _q_value(m.albedo_q0, m.albedo_q1, q, m.albedo_nq)
            p1 = m.params[1]
            if ((wp.static(PAIRED) >> m.model) & 1) == 1 and m.params[1] == m.params[0]:  # αx = αy = the texel's
                p1 = v
            m.params = wp.vec4(v, p1, m.params[2], m.params[3])
        m.ks = wp.vec3(1.0, 1.0, 1.0)
        st = wp.sqrt(wp.max(1.0 - ct * ct, 0.0))
        o = wp.vec3(st * wp.cos(phi), st * wp.sin(phi), ct)
        exact = wp.vec3(0.0, 0.0, 0.0)
        for s in range(samples):
            u = wp.vec2((float(s) + 0.5) / float(samples), _radical_inverse(s))
            i = brdf_sample(m, o, u)
            if i[2] > 0.0:
                p = brdf_pdf(m, o, i)
                if p > 0.0:
                    exact += brdf_specular(m, o, i) * (i[2] / p)
        exact = exact / float(samples)
        sg = wp.vec3(0.0, 0.0, 0.0)
        for k in range(slice_lobe_count(m)):
            pw, lw, mw = shading_slice_lobe(m, o, k)
            sg += mw * (sg_irradiance_norm(irr, pw[2], lw) * sg_integral(lw))
        c = wp.vec3(1.0, 1.0, 1.0)
        for ch in range(3):
            if sg[ch] > 0.0 and exact[ch] > 0.0:
                c[ch] = wp.clamp(exact[ch] / sg[ch], _C_MIN, _C_MAX)
        out[e] = c

    name = "albedo" + MF.tag
    albedo.__name__ = name
    albedo.__qualname__ = name
    k = wp.kernel(albedo, enable_backward=False, module="unique")
    _KERNELS[key] = k
    return k


def layout(records, p0_ranges):
    """Per material ``(kind, nq, q0, q1)`` from its packed record (``model``, ``params``,
    ``anisotropic``) and the range of its textured first parameter (``None``: constant)."""
    specular, textured = specular_codes(), textured_lobe_codes()
    out = []
    for rec, rng in zip(records, p0_ranges):
        m = int(rec["model"])
        if m not in specular:
            out.append((KIND_NONE, 0, 1.0, 1.0))
        elif rec.get("anisotropic"):
            out.append((KIND_ANISO, NQ, 1.0, 1.0))
        elif rng is not None and m in textured and rng[1] > rng[0] > 0:
            out.append((KIND_ISO, NQ, float(rng[0]), float(rng[1])))
        else:  # one entry at the material's own first parameter (the kernel sets it back unchanged)
            p0 = float(rec["params"][0])
            out.append((KIND_ISO, 1, p0, p0))
    return out


def attach(table, p0_ranges, irr, device, samples: int = SAMPLES):
    """Fill the albedo fields of every material of ``table`` (a packed ``MaterialTable``): the
    layout (module docstring) from its records and ``p0_ranges`` (per material the range of its
    textured first parameter, or ``None``), the correction entries computed by
    :func:`albedo_kernel`, and ``table.materials`` rebuilt with them. Returns the entries."""
    meta, off = [], 0
    em, eq, eu = [], [], []
    for i, (kind, nq, q0, q1) in enumerate(layout(table.records, p0_ranges)):
        meta.append((kind, nq, q0, q1, off))
        em += [i] * (nq * NMU)
        eq += [q for q in range(nq) for _ in range(NMU)]
        eu += list(range(NMU)) * nq
        off += nq * NMU
    out = wp.ones(max(off, 1), dtype=wp.vec3, device=device)
    for s, (kind, nq, q0, q1, o) in zip(table.structs, meta):
        # the struct holds ln q0 and 1/ln(q1/q0) (one log per pixel for a textured parameter)
        span = math.log(q1 / q0) if q1 > q0 > 0 else 0.0
        s.albedo_kind, s.albedo_nq, s.albedo_offset = kind, nq, o
        s.albedo_q0, s.albedo_q1 = math.log(max(q0, 1e-30)), (1.0 / span if span > 0 else 0.0)
        s.albedo = out
    table.rebuild()
    if off > 0:
        k = albedo_kernel(table.models)
        args = [wp.array(np.asarray(a, np.int32), dtype=int, device=device) for a in (em, eq, eu)]
        wp.launch(k, dim=off, inputs=[table.materials, *args, irr, int(samples), out], device=device)
    return out


@wp.func
def albedo_correction(mat: Material, o: wp.vec3) -> wp.vec3:
    """``c(o) = A(o)/A*(o)`` of the material at local view ``o`` (bilinear in √(1 − cos θ_o) and q;
    1 for a material without a table)."""
    if mat.albedo_nq <= 0:
        return wp.vec3(1.0, 1.0, 1.0)
    x = wp.clamp(wp.sqrt(wp.max(1.0 - o[2], 0.0)) / _S_MAX, 0.0, 1.0) * float(NMU - 1)
    x0 = wp.min(int(x), NMU - 2)
    fx = x - float(x0)
    nq = mat.albedo_nq
    y = float(0.0)
    if mat.albedo_kind == KIND_ANISO:
        y = wp.atan2(wp.abs(o[1]), wp.abs(o[0])) / _HALF_PI * float(NQ - 1)
    elif nq > 1:  # log-spaced values of a textured first parameter: albedo_q0 = ln q0, q1 = 1/ln(q1/q0)
        y = wp.clamp((wp.log(wp.max(mat.params[0], 1.0e-6)) - mat.albedo_q0) * mat.albedo_q1, 0.0, 1.0) * float(nq - 1)
    y0 = wp.min(int(y), wp.max(nq - 2, 0))
    fy = wp.clamp(y - float(y0), 0.0, 1.0)
    y1 = wp.min(y0 + 1, nq - 1)
    b = mat.albedo_offset
    a0 = mat.albedo[b + y0 * NMU + x0] * (1.0 - fx) + mat.albedo[b + y0 * NMU + x0 + 1] * fx
    a1 = mat.albedo[b + y1 * NMU + x0] * (1.0 - fx) + mat.albedo[b + y1 * NMU + x0 + 1] * fx
    return a0 * (1.0 - fy) + a1 * fy


__all__ = ["albedo_correction", "albedo_kernel", "attach", "layout", "NMU", "NQ", "SAMPLES",
           "KIND_NONE", "KIND_ISO", "KIND_ANISO"]
