r"""Kernel side of moving objects: the occluder proxies (:mod:`precompute.visibility.proxies`) read per pixel.

A receiver of object ``o`` sees the proxies of every other object ``j`` for which the pair is not
already in the precomputed SSDFs, i.e. where ``o`` or ``j`` is dynamic
(:mod:`precompute.visibility.ssdf_groups`: the static objects shadow each other in their maps, a dynamic
object only itself). Per shading point ``P`` (normal ``n``):

* **SSDF** (:func:`proxy_theta`): ``θp(d) = min_j θ_j(d)`` with a sphere's ``∠(d, a) − α``
  (:mod:`precompute.visibility.proxies`) and a flat object's :func:`polygon_theta`, the angle from
  ``d`` to its outline on the sphere of directions (its edges are great-circle arcs; negative where
  the ray hits it) — not the infinite plane it lies in, whose ``asin(σ d·m)`` hides the environment
  past a floor's edge from a glossy object's grazing lobes; the lobe's visibility is ``min(V_own,
  fh(θp, λ)/fh(θh, λ))`` (:func:`proxy_ratio`), i.e. ``fh(min(θd, θp))/fh(θh)``: the SSDF of the
  union of occluders, ``min``, before the SSDF × SG product (eq. 30) — used for the specular
  lobes (and the diffuse lobes of the per-pixel path); a light's fraction is the uniform disc's
  at ``min(θd, θp)`` instead (:func:`proxy_light_ratio`), as the maps' own for lights. A specular lobe's mean radiance is
  read on its visible part (:func:`moving_lobe`): cut by the maps' occluders as in a static scene
  (``visible_lobe``), or, where a proxy cuts more, moved away from that proxy (``cut_lobe``, the
  same truncated-normal shift) — before, a glossy moving ball on a floor averaged the sky with
  the ground the floor hides and was 9 % dark (``examples/rolling.toml``, against the
  Monte-Carlo reference; now −0.2 %).
* **Diffuse environment** (:func:`proxy_diffuse`): the visible fraction ``F`` of the irradiance is
  multiplied by ``Π_j (1 − O_j/E(n))`` over the objects (occlusions combined as independent, Ren
  et al. 2006's product of visibilities). An object with an occlusion field
  (:mod:`precompute.visibility.occlusion_field`: a curved object other than one sphere) is seen as
  the cap of the first moment ``M`` of what it hides from ``P``, looked up in the object's frame
  (``Proxies.field_inv``: ``(sRρ)⁻¹`` of its current motion, about its moved centre ``blobs[k]``): axis
  ``a = R M/|M|``, ``π sin²α = |M|`` — ``Ω⊥ = n·M`` exactly where the object is above the receiver's
  horizon; any other object as its one diffuse sphere (``precompute.visibility.proxies.diffuse_sphere``:
  ``a`` towards its centre, ``sin α = r/dist``). A cap's occluded irradiance is ``O = L(a) · Ω⊥(θ, α)``: the
  residual map's radiance at the cap's axis times the cap's cosine-weighted solid angle, exact
  also where the cap straddles the horizon (Snyder 1996, "Area light sources for real-time
  graphics", in the form of Lagarde & de Rousiers 2014, "Moving Frostbite to PBR", eq. 18)::

      Ω⊥ = π sin²α cos θ                                          (cos²θ > sin²α, above)
      Ω⊥ = (cos θ acos y − x sin θ √(1 − y²)) sin²α + atan(sin θ √(1 − y²)/x)   (straddling)
      x = √(1/sin²α − 1),  y = −x cos θ / sin θ

  A plane's is the irradiance of the residual map behind it, ``E_m(n)`` (a second irradiance
  table of the map masked to ``d·m < 0``, ``Proxies.behind``), times the share of the half-space's
  cosine-weighted solid angle ``π(1 − σ n·m)/2`` that the flat object's outline covers (Lambert's
  formula on the outline clipped to the receiver's horizon, :func:`polygon_cosine_solid_angle`):
  a finite floor leaves the ground near the horizon visible.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import warp as wp

from precompute.environment.irradiance import IrradianceTable, irradiance_unscaled
from precompute.visibility.occlusion_field import field_moments
from warp_sg.numeric.fastmath import fast_asin
from warp_sg.scene.envmap import env_lookup
from warp_sg.sg.fh import fh_ratio_table_pair, fh_theta_max_wp
from warp_sg.sg.ssdf_product import sg_visibility_scale_sigmoid
from warp_sg.shading.visibility_terms import (
    SSDFPoint,
    Visibility,
    cut_lobe,
    light_fraction,
    light_sin_radius,
    visible_lobe,
)

_HALF_PI = wp.constant(1.5707963267948966)
_FAR = wp.constant(4.0)  # an SSDF beyond any angle: no proxy


@wp.struct
class Proxies:
    """The proxies of a scene with moving objects, in the current pose (world space)."""

    active: int  # 0: a static scene (the funcs return "nothing occludes")
    tri_object: wp.array(dtype=int)  # (T,) the object of each triangle
    dynamic: wp.array(dtype=int)  # (objects,) 1 for a dynamic object
    spheres: wp.array(dtype=wp.vec4)  # (K,) centre, radius, grouped by object
    sphere_owner: wp.array(dtype=int)  # (K,) object; -1: none (placeholder)
    bounds: wp.array(dtype=wp.vec4)  # (objects,) a sphere around each object's spheres (radius < 0: none)
    sphere_start: wp.array(dtype=int)  # (objects,) its first sphere
    sphere_count: wp.array(dtype=int)  # (objects,) and how many
    blobs: wp.array(dtype=wp.vec4)  # (objects,) the one sphere the diffuse term sees (proxies.diffuse_sphere)
    blob_owner: wp.array(dtype=int)  # (objects,) object; -1: none (a plane, or no such object)
    #: the occlusion fields (precompute.visibility.occlusion_field), RINGS vec4 per cell, one object after the other
    field: wp.array(dtype=wp.vec4)
    field_ring: wp.array(dtype=wp.vec2)  # their cells' first rings r_in and ln r_in (occlusion_field.cell_axes)
    field_axis: wp.array(dtype=wp.vec4)  # their cells' −ω and rings' scale
    field_cell: wp.array(dtype=int)  # (objects,) the object's first cell; -1: none (its blob instead)
    field_inv: wp.array(dtype=wp.mat33)  # (objects,) (sRρ)⁻¹: world offsets from blobs[k]'s centre → field frame
    planes: wp.array(dtype=wp.vec4)  # (L,) unit normal m, offset h (m·x + h = 0)
    disks: wp.array(dtype=wp.vec4)  # (L,) the plane's bounding disk: centre, radius
    plane_owner: wp.array(dtype=int)  # (L,) object; -1: none
    outline: wp.array(dtype=wp.vec3)  # the planes' outlines (convex polygons), one after the other
    outline_start: wp.array(dtype=int)  # (L,) first vertex of plane i's outline
    outline_count: wp.array(dtype=int)  # (L,) its vertex count
    #: irradiance (unit scale) of the residual map behind the plane normal ``behind_axis`` (d·m < 0)
    behind: IrradianceTable
    behind_axis: wp.vec3


@wp.func
def _pair(px: Proxies, recv: int, owner: int) -> int:
    """1 where the proxy of object ``owner`` occludes receivers of object ``recv``."""
    if owner < 0 or owner == recv:
        return 0
    if px.dynamic[owner] != 0 or px.dynamic[recv] != 0:
        return 1
    return 0


@wp.func
def _plane_side(px: Proxies, i: int, P: wp.vec3) -> float:
    """σ = ±1, the side of plane i that ``P`` is on, or 0 where ``P`` does not project inside its disk."""
    pl = px.planes[i]
    m = wp.vec3(pl[0], pl[1], pl[2])
    sd = wp.dot(m, P) + pl[3]
    dk = px.disks[i]
    if wp.length(P - m * sd - wp.vec3(dk[0], dk[1], dk[2])) > dk[3]:
        return 0.0
    return wp.where(sd >= 0.0, 1.0, -1.0)


@wp.func
def _sphere_theta(s: wp.vec4, P: wp.vec3, d: wp.vec3) -> float:
    """A sphere's SSDF seen from P at direction d: ∠(d, a) − α (−π/2 inside it)."""
    v = wp.vec3(s[0], s[1], s[2]) - P
    dist = wp.length(v)
    if dist <= s[3]:
        return -_HALF_PI
    return wp.acos(wp.clamp(wp.dot(d, v) / dist, -1.0, 1.0)) - wp.asin(s[3] / dist)


@wp.func
def _arc_distance(a: wp.vec3, b: wp.vec3, d: wp.vec3) -> float:
    """The angle from unit ``d`` to the great-circle arc from unit ``a`` to unit ``b`` (the shorter
    one): ``asin |d·u|`` (``u`` the arc's pole) where ``d`` projects inside the arc, else the angle
    to the nearer end."""
    c = wp.cross(a, b)
    s = wp.length(c)
    if s > 1.0e-9:
        u = c / s
        du = wp.dot(d, u)
        q = d - u * du
        if wp.length(q) > 1.0e-9 and wp.dot(wp.cross(a, q), u) >= 0.0 and wp.dot(wp.cross(q, b), u) >= 0.0:
            return fast_asin(wp.min(wp.abs(du), 1.0))
    return wp.acos(wp.clamp(wp.max(wp.dot(d, a), wp.dot(d, b)), -1.0, 1.0))


@wp.func
def polygon_theta(verts: wp.array(dtype=wp.vec3), start: int, count: int, m: wp.vec3, h: float, P: wp.vec3,
                  d: wp.vec3) -> float:
    """The SSDF (eq. 23) at unit direction ``d`` of a flat convex polygon (its vertices in order, in
    the plane ``m·x + h = 0``) seen from ``P``: the angle from ``d`` to the polygon's outline on the
    sphere of directions (its edges project to great-circle arcs), negative where the ray ``P + t d``
    hits the polygon. A floor's outline instead of the infinite plane it lies in: directions that
    pass its edge see the environment beyond it (the ground of the map near the horizon)."""
    dist = float(_FAR)
    sgn = int(0)
    hit = int(1)
    md = wp.dot(m, d)
    t = float(-1.0)
    if wp.abs(md) > 1.0e-12:
        t = -(wp.dot(m, P) + h) / md
    if t <= 0.0:
        hit = 0
    X = P + d * wp.max(t, 0.0)
    for k in range(count):
        va = verts[start + k]
        vb = verts[start + (k + 1) % count]
        dist = wp.min(dist, _arc_distance(wp.normalize(va - P), wp.normalize(vb - P), d))
        side = wp.dot(wp.cross(vb - va, X - va), m)  # the hit point against edge k, in the plane
        if hit != 0:
            sk = wp.where(side >= 0.0, 1, -1)
            if sgn == 0:
                sgn = sk
            elif sk != sgn:
                hit = 0
    if hit != 0:
        return -dist
    return dist


@wp.func
def proxy_theta_axis(px: Proxies, tri: int, P: wp.vec3, d: wp.vec3, reach: float):
    """``(θp, c)``: the SSDF at unit direction ``d`` of the proxies that occlude the point ``P`` of
    triangle ``tri`` (module docstring), where it is below ``reach`` (an object whose bounding
    sphere is ``reach`` or more from ``d`` is skipped), 4 (beyond any angle) where none is; and the
    direction towards the proxy that gives it (a sphere's centre, a plane's side), zero for none."""
    th = float(_FAR)
    c = wp.vec3(0.0, 0.0, 0.0)
    recv = px.tri_object[tri]
    for k in range(px.bounds.shape[0]):
        b = px.bounds[k]
        if b[3] > 0.0 and _pair(px, recv, k) != 0:
            if _sphere_theta(b, P, d) < reach:
                s0 = px.sphere_start[k]
                for i in range(s0, s0 + px.sphere_count[k]):
                    si = px.spheres[i]
                    ti = _sphere_theta(si, P, d)
                    if ti < th:
                        th = ti
                        c = wp.vec3(si[0], si[1], si[2]) - P
    for i in range(px.planes.shape[0]):
        if _pair(px, recv, px.plane_owner[i]) != 0:
            pl = px.planes[i]
            m = wp.vec3(pl[0], pl[1], pl[2])
            towards = m * wp.where(wp.dot(m, P) + pl[3] >= 0.0, -1.0, 1.0)
            ti = float(_FAR)
            if px.outline_count[i] >= 3:  # the flat object's outline (polygon_theta)
                ti = polygon_theta(px.outline, px.outline_start[i], px.outline_count[i], m, pl[3], P, d)
            else:
                sg = _plane_side(px, i, P)
                if sg != 0.0:  # no outline: the plane it lies in, where P projects inside its disk
                    ti = fast_asin(wp.clamp(sg * wp.dot(d, m), -1.0, 1.0))
            if ti < th:
                th = ti
                c = towards
    return th, c


@wp.func
def proxy_theta(px: Proxies, tri: int, P: wp.vec3, d: wp.vec3, reach: float) -> float:
    """``θp`` of :func:`proxy_theta_axis`."""
    th, c = proxy_theta_axis(px, tri, P, d, reach)
    return th


@wp.func
def proxy_cut(fh_mode: int, table: wp.array2d(dtype=float), px: Proxies, tri: int, P: wp.vec3, ng: wp.vec3,
              d: wp.vec3, lam: float):
    """``(r, θp, c)``: ``r = fh(θp, λ)/fh(θh, λ)`` clamped to [0, 1], the visible fraction of the lobe
    (d, λ) the proxies leave (1 in a static scene, or where they clear the lobe by θmax(λ)), with
    the SSDF θp and the direction c towards the proxy of :func:`proxy_theta_axis`."""
    if px.active == 0:
        return 1.0, float(_FAR), wp.vec3(0.0, 0.0, 0.0)
    tmax = fh_theta_max_wp(lam)
    th, c = proxy_theta_axis(px, tri, P, d, tmax)
    if th >= tmax:
        return 1.0, th, c
    th_h = fast_asin(wp.clamp(wp.dot(d, ng), -1.0, 1.0))
    a = float(0.0)
    b = float(0.0)
    if fh_mode == 1:
        a = sg_visibility_scale_sigmoid(th, lam)
        b = sg_visibility_scale_sigmoid(th_h, lam)
    else:
        a, b = fh_ratio_table_pair(table, th, th_h, lam)
    return wp.clamp(a / wp.max(b, 1.0e-8), 0.0, 1.0), th, c


@wp.func
def proxy_ratio(fh_mode: int, table: wp.array2d(dtype=float), px: Proxies, tri: int, P: wp.vec3, ng: wp.vec3,
                d: wp.vec3, lam: float) -> float:
    """The visible fraction ``r`` of :func:`proxy_cut`."""
    r, th, c = proxy_cut(fh_mode, table, px, tri, P, ng, d, lam)
    return r


@wp.func
def proxy_light_ratio(fh_mode: int, vis: Visibility, px: Proxies, tri: int, P: wp.vec3, ng: wp.vec3, d: wp.vec3,
                      lam: float) -> float:
    """A light's (axis ``d``, SG sharpness λ) visible fraction that the proxies leave: the uniform
    disc's, :func:`~warp_sg.shading.visibility_terms.light_fraction` of the proxies' SSDF θp — as
    the maps' own for lights, so that a moving object's shadow has the umbra and penumbra a ray
    cast finds, not the SG's tails (1 where the proxies clear the disc's radius α)."""
    if px.active == 0:
        return 1.0
    reach = float(0.0)
    if fh_mode == 1:
        reach = fh_theta_max_wp(lam)
    else:
        reach = wp.asin(light_sin_radius(lam))
    th = proxy_theta(px, tri, P, d, reach)
    if th >= reach:
        return 1.0
    return light_fraction(fh_mode, vis, th, fast_asin(wp.clamp(wp.dot(d, ng), -1.0, 1.0)), lam)


@wp.func
def moving_lobe(fh_mode: int, vis: Visibility, q: SSDFPoint, px: Proxies, tri: int, P: wp.vec3, ng: wp.vec3,
                p: wp.vec3, lam: float, vd: wp.vec2):
    """``(V, p', λ')`` of a specular lobe (p, λ) in a scene with moving objects: the smaller of the
    maps' visible fraction (``vd = vis_ratio_depth(...)``: fraction, θd) and the proxies'
    (:func:`proxy_cut`), and the lobe's visible part cut by the occluder that gives it
    (:func:`~warp_sg.shading.visibility_terms.visible_lobe` for the maps,
    :func:`~warp_sg.shading.visibility_terms.cut_lobe` towards the proxy), where its mean radiance is read: a
    glossy lobe that straddles a floor's horizon sees the sky above it, not the ground the floor hides."""
    r, th, c = proxy_cut(fh_mode, vis.fh_table, px, tri, P, ng, p, lam)
    if r < vd[0]:
        pc, lc = cut_lobe(p, lam, th, c)
        return r, pc, lc
    if vd[0] < 1.0:
        pv, lv = visible_lobe(vis, q, p, lam, vd[1])
        return vd[0], pv, lv
    return vd[0], p, lam


@wp.func
def cap_cosine_solid_angle(cos_t: float, sin2: float) -> float:
    """``Ω⊥``: ∫ max(n·d, 0) dd over a cap of half-angle α (``sin2 = sin²α``) whose axis makes the
    angle θ (``cos_t``) with n (module docstring; Snyder 1996)."""
    s2 = wp.clamp(sin2, 0.0, 0.9999)
    if cos_t * cos_t > s2:
        return wp.pi * s2 * wp.max(cos_t, 0.0)
    sin_t = wp.max(wp.sqrt(wp.max(1.0 - cos_t * cos_t, 0.0)), 1.0e-6)
    x = wp.sqrt(1.0 / s2 - 1.0)
    y = wp.clamp(-x * cos_t / sin_t, -1.0, 1.0)
    sty = sin_t * wp.sqrt(wp.max(1.0 - y * y, 0.0))
    return wp.max((cos_t * wp.acos(y) - x * sty) * s2 + wp.atan(sty / x), 0.0)


@wp.func
def _edge_term(a: wp.vec3, b: wp.vec3, n: wp.vec3) -> float:
    """θ_e (n·u_e) of the edge from direction a to b (u_e the unit normal of their great circle)."""
    c = wp.cross(wp.normalize(a), wp.normalize(b))
    s = wp.length(c)
    if s < 1.0e-9:
        return 0.0
    return wp.atan2(s, wp.dot(wp.normalize(a), wp.normalize(b))) * wp.dot(c / s, n)


@wp.func
def polygon_cosine_solid_angle(verts: wp.array(dtype=wp.vec3), start: int, count: int, P: wp.vec3,
                               n: wp.vec3) -> float:
    """``∫ max(n·d, 0) dd`` over the directions from ``P`` to a convex polygon: Lambert's formula
    ``½ |Σ_e θ_e (n·u_e)|`` over the polygon clipped to the half-space ``n·(x − P) ≥ 0`` (the
    clipped part's closing edge lies in that plane)."""
    total = float(0.0)
    exit_p = wp.vec3(0.0, 0.0, 0.0)
    entry_p = wp.vec3(0.0, 0.0, 0.0)
    n_cut = int(0)
    for k in range(count):
        a = verts[start + k] - P
        b = verts[start + (k + 1) % count] - P
        da = wp.dot(a, n)
        db = wp.dot(b, n)
        if da >= 0.0 and db >= 0.0:
            total += _edge_term(a, b, n)
        elif da >= 0.0:  # leaves the half-space
            exit_p = a + (b - a) * (da / (da - db))
            total += _edge_term(a, exit_p, n)
            n_cut += 1
        elif db >= 0.0:  # enters it
            entry_p = a + (b - a) * (da / (da - db))
            total += _edge_term(entry_p, b, n)
            n_cut += 1
    if n_cut == 2:
        total += _edge_term(exit_p, entry_p, n)
    return 0.5 * wp.abs(total)


@wp.func
def proxy_diffuse(px: Proxies, tri: int, P: wp.vec3, n: wp.vec3, radiance: wp.array2d(dtype=wp.vec3),
                  exact: IrradianceTable) -> wp.vec3:
    """Per channel ``Π_j (1 − O_j/E(n))``: the fraction of the diffuse environment irradiance at
    ``P`` (normal ``n``) that the proxies leave (module docstring; 1 in a static scene)."""
    f = wp.vec3(1.0, 1.0, 1.0)
    if px.active == 0:
        return f
    recv = px.tri_object[tri]
    E = irradiance_unscaled(exact, n)
    for i in range(px.blobs.shape[0]):
        if _pair(px, recv, px.blob_owner[i]) != 0:
            s = px.blobs[i]
            v = wp.vec3(s[0], s[1], s[2]) - P
            dist = wp.max(wp.length(v), 1.0e-12)
            a = v / dist
            sin2 = (s[3] / dist) * (s[3] / dist)
            cell = px.field_cell[i]
            if cell >= 0:  # the object's occlusion field: the cap of its first moment M, π sin²α = |M|
                A = px.field_inv[i]
                mo = field_moments(px.field, px.field_ring, px.field_axis, cell, A * (-v))
                mv = wp.vec3(mo[0], mo[1], mo[2])
                sin2 = wp.length(mv) / wp.pi
                a = wp.normalize(wp.transpose(A) * mv)  # R M (Aᵀ = R/(sρ))
            om = float(0.0)
            if sin2 > 1.0e-12:
                om = cap_cosine_solid_angle(wp.dot(n, a), sin2)
            if om > 0.0:
                L = env_lookup(radiance, exact.to_env, a)
                for c in range(3):
                    f[c] = f[c] * (1.0 - wp.clamp(L[c] * om / wp.max(E[c], 1.0e-12), 0.0, 1.0))
    for i in range(px.planes.shape[0]):
        if _pair(px, recv, px.plane_owner[i]) != 0:
            pl = px.planes[i]
            m = wp.vec3(pl[0], pl[1], pl[2])
            sg = _plane_side(px, i, P)
            if sg != 0.0 and wp.abs(wp.dot(m, px.behind_axis)) > 0.9999:
                B = irradiance_unscaled(px.behind, n)  # behind +behind_axis
                if sg * wp.dot(m, px.behind_axis) < 0.0:
                    B = E - B  # the point is on the other side: the other half is hidden
                # the half-space's radiance, on the part the outline covers: Ω⊥(outline)/Ω⊥(half-space)
                half = 0.5 * wp.pi * (1.0 - sg * wp.dot(n, m))
                cover = float(0.0)
                if half > 1.0e-6:
                    cover = wp.clamp(polygon_cosine_solid_angle(px.outline, px.outline_start[i], px.outline_count[i],
                                                                P, n) / half, 0.0, 1.0)
                for c in range(3):
                    f[c] = f[c] * (1.0 - cover * wp.clamp(B[c] / wp.max(E[c], 1.0e-12), 0.0, 1.0))
    return f




def no_proxies(device) -> Proxies:
    """The argument of a static scene's kernel: ``active = 0``, placeholder arrays."""
    from precompute.environment.irradiance import placeholder_table

    px = Proxies()
    px.active = 0
    px.tri_object = px.dynamic = px.sphere_owner = px.plane_owner = px.blob_owner = wp.full(1, -1, dtype=int,
                                                                                           device=device)
    px.spheres = px.planes = px.disks = px.blobs = px.bounds = px.field = wp.zeros(1, dtype=wp.vec4, device=device)
    px.field_ring = wp.ones(1, dtype=wp.vec2, device=device)
    px.field_axis = wp.zeros(1, dtype=wp.vec4, device=device)
    px.field_cell = wp.full(1, -1, dtype=int, device=device)
    px.field_inv = wp.zeros(1, dtype=wp.mat33, device=device)
    px.sphere_start = px.sphere_count = wp.zeros(1, dtype=int, device=device)
    px.outline = wp.zeros(1, dtype=wp.vec3, device=device)
    px.outline_start = px.outline_count = wp.zeros(1, dtype=int, device=device)
    px.behind = placeholder_table(device)
    px.behind_axis = wp.vec3(0.0, 0.0, 0.0)
    return px


__all__ = ["Proxies", "proxy_theta", "proxy_theta_axis", "proxy_cut", "moving_lobe", "polygon_theta", "proxy_ratio",
           "proxy_light_ratio", "proxy_diffuse", "cap_cosine_solid_angle", "polygon_cosine_solid_angle",
           "no_proxies"]
