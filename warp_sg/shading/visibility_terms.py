r"""The shading kernel's argument structs and its SSDF-visibility building blocks (``@wp.func``).

Structs: :class:`GeometryArrays` (the mesh on the device), :class:`Visibility` (per-vertex SSDFs,
occluder cones, the per-vertex light deficit) and :class:`EnvSG` (the environment's SG mixture in
world space, its exact irradiance table and per-vertex caches). Functions: the visible fraction of
an SG lobe at a point, ``vis_ratio(p, λ) = fh(θd(p), λ) / fh(θh(p), λ)`` (paper eq. 25–31, on the
SSDF value ``θd`` in direction ``p`` and the horizon angle ``θh``; ``fh`` tabulated or the paper's
sigmoid, :mod:`warp_sg.sg.fh`), with the lookup skipped where the occluder cone is clear
(``precompute.visibility.occluder_cone``); a light's visible fraction, its uniform disc cut by the
same boundary (``light_cap_visible``, ``light_fraction``, ``light_vis_ratio``); the lobe seen
through the visibility boundary
(``visible_lobe``); and the per-lobe constants of the environment mixture (``lobe_constants``).
The kernel variants that use them are :mod:`warp_sg.shading.kernel`'s.
"""
from __future__ import annotations

import warp as wp

from precompute.environment.irradiance import IrradianceTable
from precompute.visibility.occluder_cone import occluder_clearance
from precompute.visibility.ssdf_wp import SSDFPoint, ssdf_at
from warp_sg.brdf.kernel.material_wp import lum
from warp_sg.numeric.fastmath import fast_asin
from warp_sg.numeric.onb import frame_bitangent, frame_tangent
from warp_sg.sg import CLAMPED_COSINE_SHARPNESS
from warp_sg.sg.algebra_wp import FA_NUMERATOR, TWO_PI
from warp_sg.sg.fh import fh_ratio_table_pair, fh_theta_max_wp
from warp_sg.sg.irradiance import sg_irradiance_row, sg_power
from warp_sg.sg.ssdf_product import sg_visibility_scale_sigmoid

_HALF_PI_F = wp.constant(1.5707963267948966)
_INV_SQRT2 = wp.constant(0.7071067811865476)
_INV_SQRT_2PI = wp.constant(0.3989422804014327)
_CONE_UNKNOWN = wp.constant(3.9)  # occluder_cone.no_cones' α (4): the axis says nothing
#: sharpness of the eq. 40 clamped-cosine lobe: only used to place and size the product lobe
#: C* ⊗ G whose visibility / ΓL lookup stands for the cosine-weighted lobe
CC_LAM = wp.constant(CLAMPED_COSINE_SHARPNESS)


@wp.struct
class GeometryArrays:
    """World-space mesh attributes on the device (see ``warp_sg.scene.Geometry``)."""

    positions: wp.array(dtype=wp.vec3)
    normals: wp.array(dtype=wp.vec3)
    uvs: wp.array(dtype=wp.vec2)
    tangents: wp.array(dtype=wp.vec3)
    tris: wp.array(dtype=wp.vec3i)
    tri_material: wp.array(dtype=int)


@wp.struct
class Visibility:
    """PCA-compressed SSDFs (``precompute.SSDFData``) and the fh ratio table (``warp_sg.sg.fh``)."""

    mean: wp.array2d(dtype=float)
    basis: wp.array3d(dtype=float)
    weights: wp.array2d(dtype=float)
    normals: wp.array(dtype=wp.vec3)  # the per-vertex normals (frames) the SSDFs were computed in
    frame_t: wp.array(dtype=wp.vec3)  # (V,) their frames' tangent and bitangent where objects move
    frame_b: wp.array(dtype=wp.vec3)  # (warp_sg.renderer.dynamic_objects); length 1: the frames of the normals
    fh_table: wp.array2d(dtype=float)
    cones: wp.array(dtype=wp.vec4)  # per-vertex occluder cones (precompute.visibility.occluder_cone)
    cone_band: float  # their texel margin h: the width of the skip's blend
    #: (V, lights) per-vertex SSDF deficit θd − θh towards each light (``warp_sg.shading.vertex_visibility``),
    #: read by the variant with ``Features.light_vis_vertex``; a (1, 1) placeholder otherwise
    light_deficit: wp.array2d(dtype=float)


@wp.struct
class EnvSG:
    """Environment SG mixture (world-space axes, environment rotation applied), eq. 34 diffuse part."""

    count: int
    axis: wp.array(dtype=wp.vec3)
    lam: wp.array(dtype=float)
    mu: wp.array(dtype=wp.vec3)
    #: per lobe, the constants of its exact irradiance (``lobe_constants``): μ ∫G(λ) and its row
    #: in the irradiance table, so a pixel pays only the table lookup
    power: wp.array(dtype=wp.vec3)
    irr_row: wp.array(dtype=float)
    #: (V, count) visible fraction of C*(n_v) ⊗ G_j per vertex (``warp_sg.shading.vertex_visibility``),
    #: read by the variant with ``Features.env_vis_vertex``; a (1, 1) placeholder otherwise
    vis: wp.array2d(dtype=float)
    #: (V,) per vertex the visible fraction (RGB) of its diffuse environment irradiance
    #: (``warp_sg.shading.vertex_visibility.env_vertex_visible``), read by the variant with
    #: ``Features.env_visible_vertex``; a length-1 placeholder otherwise
    visible: wp.array(dtype=wp.vec3)
    #: (V,) the vertices' visible irradiance E ∘ F at unit scale, and (T,) 1 for triangles whose
    #: vertex normals are within 5° (``vertex_visibility.smooth_triangles``): those interpolate it
    irr_vertex: wp.array(dtype=wp.vec3)
    smooth: wp.array(dtype=wp.uint8)
    irr_scale: float  # the environment's scale (irr_vertex is at unit scale)
    #: the residual map at texel scale (64 × 128, unit scale), which the per-vertex quadrature of
    #: ``visible`` weighs the SSDF texels with; a 1×1 placeholder where unused
    radiance: wp.array2d(dtype=wp.vec3)
    #: the exact irradiance of the residual map (``precompute.environment.irradiance``): the magnitude of
    #: the diffuse term, of which the vertices' quadrature or the lobes give the visible fraction
    exact: IrradianceTable


# --------------------------------------------------------------------------------------------
# building blocks (@wp.func)
# --------------------------------------------------------------------------------------------
@wp.func
def vertex_light_pair(e: int, ids: wp.array(dtype=int), n_lights: int) -> wp.vec2i:
    """``(vertex, light)`` of entry ``e`` of a per-vertex, per-light table flattened row by row
    (``n_lights`` columns); ``ids``: the vertices of the rows (empty: row i is vertex i)."""
    v = e // n_lights
    j = e - v * n_lights
    if ids.shape[0] > 0:
        v = ids[v]
    return wp.vec2i(v, j)


@wp.func
def vertex_point(v: int, n: wp.vec3) -> SSDFPoint:
    """The SSDF lookup point of vertex ``v`` alone (weight 1, normal ``n``): a per-vertex cache's cone
    test and lookups."""
    q = SSDFPoint()
    q.i0 = v
    q.i1 = v
    q.i2 = v
    q.c0 = 1.0
    q.n0 = n
    return q


@wp.func
def vertex_frame(vis: Visibility, v: int, n: wp.vec3):
    """(t, b) of the frame vertex v's SSDF is stored in: the stored frame of a moving object's vertex
    (``Visibility.frame_t``, ``frame_b``), else the frame of its normal."""
    if vis.frame_t.shape[0] == vis.normals.shape[0]:
        return vis.frame_t[v], vis.frame_b[v]
    return frame_tangent(n), frame_bitangent(n)


@wp.func
def lookup_skip(fh_mode: int, vis: Visibility, q: SSDFPoint, p: wp.vec3, th_h: float, lam: float) -> float:
    """How far the SSDF lookup of lobe (p, λ) at point ``q`` may be skipped, ``s ∈ [0, 1]``
    (``precompute.visibility.occluder_cone.occluder_clearance``; 1: its visibility is exactly 1). Only with the
    tabulated fh, whose flat tail beyond θmax(λ) makes the skip exact; 0 with the sigmoid."""
    if fh_mode != 0:
        return 0.0
    return occluder_clearance(vis.cones, q, p, th_h, fh_theta_max_wp(lam), vis.cone_band)


@wp.func
def vis_ratio(shadows: int, fh_mode: int, vis: Visibility, q: SSDFPoint, p: wp.vec3, lam: float) -> float:
    """The visible fraction of a lobe (p, λ) relative to the unoccluded point:
    ``fh(θd(p), λ) / fh(θh(p), λ)`` with θd the SSDF of the shading point at world direction p
    (eq. 24, 30; each vertex's SSDF read in that vertex's own frame where the frames disagree,
    ``precompute.visibility.ssdf_wp.ssdf_eval_world``: no seam where the frame turns) and ``θh = asin(p·Ng)``
    the SSDF of an unoccluded point (its horizon). The unshadowed response (exact BRDF and cosine,
    or the exact SG irradiance) already accounts for the horizon, so the SSDF supplies only what
    the occluders take away. ``q``: the shading point (``ssdf_point``, once per pixel). 1 without
    shadows. With the table ``fh``, a lobe that clears the occluder cones of the point's vertices
    by ``min(θh, θmax(λ))`` is fully visible (``precompute.visibility.occluder_cone``): no SSDF lookup."""
    return _boundary_ratio(shadows, fh_mode, vis, q, p, lam, 0)


@wp.func
def vis_ratio_depth(shadows: int, fh_mode: int, vis: Visibility, q: SSDFPoint, p: wp.vec3, lam: float) -> wp.vec2:
    """:func:`vis_ratio` and the SSDF value θd(p) it read (``(ratio, θd)``; θd = π/2 where no
    lookup was needed: the lobe clears the occluders)."""
    if shadows == 0:
        return wp.vec2(1.0, _HALF_PI_F)
    th_h = fast_asin(wp.dot(p, q.ng))
    s = lookup_skip(fh_mode, vis, q, p, th_h, lam)
    if s >= 1.0:
        return wp.vec2(1.0, _HALF_PI_F)
    th = ssdf_at(vis.mean, vis.basis, vis.weights, q, p)
    r = fh_fraction(fh_mode, vis, th, th_h, lam)
    return wp.vec2(r + (1.0 - r) * s, th)


@wp.func
def _occluder_axis(vis: Visibility, q: SSDFPoint) -> wp.vec3:
    """The occluder-cone axes of the point's vertices (``precompute.visibility.occluder_cone``) weighted by
    the barycentrics, over the vertices that have occluders (zero vector: none; cones of unknown
    axis, ``no_cones``' α = 4, do not count)."""
    c = wp.vec3(0.0, 0.0, 0.0)
    k0 = vis.cones[q.i0]
    k1 = vis.cones[q.i1]
    k2 = vis.cones[q.i2]
    if k0[3] >= 0.0 and k0[3] < _CONE_UNKNOWN:
        c += wp.vec3(k0[0], k0[1], k0[2]) * (q.c0 + q.e0)
    if k1[3] >= 0.0 and k1[3] < _CONE_UNKNOWN:
        c += wp.vec3(k1[0], k1[1], k1[2]) * (q.c1 + q.e1)
    if k2[3] >= 0.0 and k2[3] < _CONE_UNKNOWN:
        c += wp.vec3(k2[0], k2[1], k2[2]) * (q.c2 + q.e2)
    return c


@wp.func
def visible_lobe(vis: Visibility, q: SSDFPoint, p: wp.vec3, lam: float, th: float):
    """``(p', λ')``: where the visible part of the lobe (p, λ) lies when the half-space model of
    eq. 25–31 cuts it θd = ``th`` from its axis, on the side away from the point's occluders (the
    vertices' occluder-cone axes). Along that direction the lobe is a Gaussian of σ = 1/√λ cut at
    −θd: its visible part has mean ``σ φ(t)/Φ(t)`` and variance ``σ² (1 − t m − m²)`` (t = θd/σ,
    m = φ(t)/Φ(t), the truncated normal), so the axis moves by that mean and the sharpness grows
    by the variance's inverse square root. The lobe's mean radiance is then read there
    (``gamma_mean``): a lobe that straddles the horizon of a floor sees the sky above it, not the
    average of the sky and the ground the floor hides. (p, λ) itself where nothing cuts it."""
    return cut_lobe(p, lam, th, _occluder_axis(vis, q))


@wp.func
def cut_lobe(p: wp.vec3, lam: float, th: float, c: wp.vec3):
    """:func:`visible_lobe` for an occluder in the direction ``c`` (any length; zero: none) whose
    SSDF at ``p`` is ``th``: the truncated-normal shift of the lobe's axis away from ``c`` and its
    sharpness (the moving objects' proxies use it with their own occluder,
    :mod:`warp_sg.shading.motion_wp`)."""
    sig = 1.0 / wp.sqrt(wp.max(lam, 1.0e-6))
    t = th / sig
    if t >= 3.0:  # the cut is 3σ away: the shift would be < 0.005 σ
        return p, lam
    away = p * wp.dot(p, c) - c  # tangent at p pointing away from the occluders
    if wp.length_sq(away) < 1.0e-12:
        return p, lam
    g = wp.normalize(away)
    tt = wp.max(t, -8.0)
    cdf = 0.5 * (1.0 + wp.erf(tt * _INV_SQRT2))
    pdf = _INV_SQRT_2PI * wp.exp(-0.5 * tt * tt)
    m = pdf / wp.max(cdf, 1.0e-12)
    if cdf < 1.0e-12:
        m = -tt  # the far tail: the visible part starts at the cut
    var = wp.clamp(1.0 - tt * m - m * m, 0.05, 1.0)
    shift = wp.min(sig * m, _HALF_PI_F)
    return wp.normalize(p * wp.cos(shift) + g * wp.sin(shift)), lam / wp.sqrt(var)


@wp.func
def fh_fraction(fh_mode: int, vis: Visibility, th: float, th_h: float, lam: float) -> float:
    """``fh(θd, λ) / fh(θh, λ)`` clamped to [0, 1] (eq. 30 over the unoccluded point's value).
    With the table, both angles at or beyond θmax(λ) read its flat tail: exactly 1, no lookup."""
    a = float(0.0)
    b = float(0.0)
    if fh_mode == 0:
        if wp.min(th, th_h) >= fh_theta_max_wp(lam):
            return 1.0
    if fh_mode == 1:
        a = sg_visibility_scale_sigmoid(th, lam)
        b = sg_visibility_scale_sigmoid(th_h, lam)
    else:
        a, b = fh_ratio_table_pair(vis.fh_table, th, th_h, lam)
    return wp.clamp(a / wp.max(b, 1.0e-8), 0.0, 1.0)


@wp.func
def light_cap_visible(th: float, lam: float) -> float:
    """The visible fraction of a uniform light disc (a spherical cap of angular radius α) whose
    centre lies ``th`` = θd from a visibility boundary great circle (visible side ``th > 0``):
    the area of cap ∩ hemisphere over the cap's, ``2[π − acos(sin θd / sin α) − cos α ·
    acos(−tan θd / tan α)] / (2π(1 − cos α))`` for |θd| < α (the intersection area of two spherical
    caps, of radii α and π/2, whose centres are π/2 − θd apart: the two-cap formula as in
    Tovchigrechko & Vakser, Protein Sci. 2001; checked against quadrature over the disc in
    ``tests/test_light_visibility.py``),
    1 at θd ≥ α and 0 at θd ≤ −α; for small α it is the flat disc's ``½ + (u√(1−u²) + asin u)/π``,
    u = θd/α. α is the light's own from its SG sharpness (``warp_sg.scene.lights.light_irradiance``:
    λ = fa⁻¹(2π sin²α), so sin α = √(fa(λ)/2π)). Evaluated in float64: the numerator is O(α²)
    out of O(1) terms."""
    sa = light_sin_radius(lam)
    return cap_visible(th, sa, wp.asin(sa))


@wp.func
def light_sin_radius(lam: float) -> float:
    """``sin α`` of a light of SG sharpness λ (:func:`light_cap_visible`)."""
    return wp.min(wp.sqrt(FA_NUMERATOR / (TWO_PI * wp.max(lam, 1.0e-30))), 1.0)


@wp.func
def cap_visible(th: float, sa: float, alpha: float) -> float:
    """:func:`light_cap_visible` of the light's ``sin α`` and ``α``."""
    if th >= alpha:
        return 1.0
    if th <= -alpha:
        return 0.0
    s64 = wp.float64(sa)
    c64 = wp.sqrt(wp.float64(1.0) - s64 * s64)
    t64 = wp.float64(th)
    u = wp.clamp(wp.sin(t64) / s64, wp.float64(-1.0), wp.float64(1.0))
    v = wp.clamp(-wp.tan(t64) * c64 / s64, wp.float64(-1.0), wp.float64(1.0))
    pi64 = wp.float64(3.141592653589793)
    a = wp.float64(2.0) * (pi64 - wp.acos(u) - c64 * wp.acos(v))
    omc = s64 * s64 / (wp.float64(1.0) + c64)  # 1 − cos α without cancellation
    return wp.clamp(float(a / (wp.float64(2.0) * pi64 * omc)), 0.0, 1.0)


@wp.func
def light_fraction(fh_mode: int, vis: Visibility, th: float, th_h: float, lam: float) -> float:
    """A light's visible fraction over that of the unoccluded point, ``g(θd)/g(θh)`` clamped to
    [0, 1], ``g`` = :func:`light_cap_visible` (the light is a uniform disc, as in the Monte-Carlo
    reference and ``docs/math.md``, not a Gaussian: the SG's fh has tails that reach ~1.5 α into
    the umbra and out into the lit side). With the paper's sigmoid (``fh_mode`` 1) its fh ratio,
    as for every lobe (:func:`fh_fraction`)."""
    if fh_mode == 1:
        return fh_fraction(fh_mode, vis, th, th_h, lam)
    sa = light_sin_radius(lam)  # (the light's radius once for both sides of the ratio)
    alpha = wp.asin(sa)
    return wp.clamp(cap_visible(th, sa, alpha) / wp.max(cap_visible(th_h, sa, alpha), 1.0e-8), 0.0, 1.0)


@wp.func
def light_vis_ratio(shadows: int, fh_mode: int, vis: Visibility, q: SSDFPoint, p: wp.vec3, lam: float) -> float:
    """:func:`vis_ratio` for a light (axis ``p``, sharpness ``λ``): the same SSDF lookup and skip,
    the visible fraction from :func:`light_fraction`."""
    return _boundary_ratio(shadows, fh_mode, vis, q, p, lam, 1)


@wp.func
def _boundary_ratio(shadows: int, fh_mode: int, vis: Visibility, q: SSDFPoint, p: wp.vec3, lam: float,
                    disc: int) -> float:
    """:func:`vis_ratio` (``disc`` 0: the lobe's fh ratio) and :func:`light_vis_ratio` (1: the
    light's disc, :func:`light_fraction`): one SSDF lookup, skipped where the occluder cones clear."""
    if shadows == 0:
        return 1.0
    th_h = fast_asin(wp.dot(p, q.ng))
    s = lookup_skip(fh_mode, vis, q, p, th_h, lam)
    if s >= 1.0:
        return 1.0
    th = ssdf_at(vis.mean, vis.basis, vis.weights, q, p)
    r = float(0.0)
    if disc != 0:
        r = light_fraction(fh_mode, vis, th, th_h, lam)
    else:
        r = fh_fraction(fh_mode, vis, th, th_h, lam)
    return r + (1.0 - r) * s


@wp.func
def visible_irradiance(exact: wp.vec3, lobes: wp.vec3, lobes_visible: wp.vec3) -> wp.vec3:
    """The diffuse environment term's irradiance with visibility: the lobes' visible irradiance
    ``Σ_j a_j V_j`` plus the part of the exact irradiance ``E(n)`` the lobes miss, ``E − Σ_j a_j``
    (either sign), seen with the lobes' mean visible fraction ``v̄ = lum(Σ a_j V_j)/lum(Σ a_j)``
    (1 where the lobes carry nothing). Unshadowed (all ``V_j = 1``) it is ``E(n)`` exactly; where the
    mixture is right (``Σ_j a_j = E``) it is eq. 39 unchanged (``precompute.environment.irradiance``)."""
    den = lum(lobes)
    vbar = float(1.0)
    if den > 1.0e-30:
        vbar = wp.clamp(lum(lobes_visible) / den, 0.0, 1.0)
    return lobes_visible + (exact - lobes) * vbar


@wp.kernel  # (with its adjoint: a requires_grad frame records it, warp_sg.renderer.gradients)
def _lobe_constants_kernel(irr: wp.array2d(dtype=float), lam: wp.array(dtype=float), mu: wp.array(dtype=wp.vec3),
                           power: wp.array(dtype=wp.vec3), row: wp.array(dtype=float)):
    j = wp.tid()
    power[j] = sg_power(lam[j], mu[j])
    row[j] = sg_irradiance_row(irr, lam[j])


def lobe_constants(es: EnvSG, irr, device, keep: bool = False) -> EnvSG:
    """Fill ``es.power`` (μ ∫G(λ)) and ``es.irr_row`` (the lobe's irradiance-table row) once per
    environment change: ``sg_irradiance(irr, n, p, λ, μ) = power · sg_irradiance_norm_at(irr, n·p,
    λ, irr_row)`` for every pixel. ``keep``: into the arrays ``es`` has (a change of μ only)."""
    n = int(es.lam.shape[0])
    if not keep:
        es.power = wp.zeros(n, dtype=wp.vec3, device=device)
        es.irr_row = wp.zeros(n, dtype=float, device=device)
    wp.launch(_lobe_constants_kernel, dim=n, inputs=[irr, es.lam, es.mu, es.power, es.irr_row], device=device)
    return es
