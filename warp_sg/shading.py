r"""Per-pixel deferred shading over the visibility buffer (paper §7, eq. 36–43).

One kernel launch shades every sample of a visibility buffer once (deferred shading: the cost
never depends on overdraw). Per sample, with ``x`` the surface point, ``o`` the view direction,
``Ng`` the interpolated vertex normal (the frame of the precomputed visibility), ``(Ts, Bs, Ns)``
the shading frame (tangent frame rotated by the normal/tangent maps), ``e(c, λ)`` the exact
normalised irradiance of an SG (``warp_sg.sg_irradiance``) and ``vis_ratio(p, λ) =
fh(θd(p), λ)/fh(θh(p), λ)`` the SSDF's visible fraction of a lobe over an unoccluded point's::

    R(o) = Rlights + Rd + Rs                                                        (eq. 36)

Local lights (point, spherical, directional; environment peaks such as a sun), eq. 42–43 made
exact where it is cheap — one BRDF evaluation at the light's direction l::

    Rlights += ρ(o, l) E e(n·l, λ_l) vis_ratio(l, λ_l)

(with ``Features.light_vis_vertex`` the SSDF towards the light is ``θd = θh + Σ_k b_k D[i_k, j]``,
the per-vertex deficit cache of ``warp_sg.vertex_visibility``, and no lookup is made.)

Environment, diffuse — eq. 39 with the exact irradiance of each SG ``L*_j`` of the mixture::

    Rd += ρd(o, p_G) μ_j ∫G_j e(Ns·p_j, λ_j) vis_ratio(p_G, λ_G),   G = C* ⊗ L*_j (eq. 5, 40)

(with ``Features.env_vis_vertex`` the visibility factor is ``Σ_k b_k V[i_k, j]``, the per-vertex
cache of ``warp_sg.vertex_visibility``: the lobe axes are fixed in world space. With
``Features.env_irradiance_vertex`` and ρd = kd/π the whole sum, which depends on the point and its
normal only, is taken per vertex and interpolated, ``ρd Σ_k b_k D[i_k]``, on the triangles whose
check at their edge midpoints and centroid found that within 0.5 % of the per-pixel sum.)

Environment, specular — eq. 41, for each slice lobe G_k of ks ρs(o, ·) (spherical warp of the
NDF lobes, eq. 17–22, ``shading_slice_lobe``)::

    Rs += μ_k ∫G_k e(Ns·p_k, λ_k) · ΓL(p, λ)/∫G(λ) (eq. 35) · vis_ratio(p, λ),   (p, λ) = C* ⊗ G_k

The clamped-cosine SG ``C*`` (eq. 40) only places and sizes the product lobe whose visibility
and mean radiance stand for the cosine-weighted lobe; the cosine itself is exact. The diffuse BRDF
``ρd(o, i)`` (kd/π, or Oren-Nayar) is evaluated at the product lobe's axis. ``θd(p)`` is the SSDF
of the surface point (eq. 24, per-vertex PCA weights, ``precompute.ssdf_wp.ssdf_eval_world``);
with shadows off (or a scene that cannot shadow itself) ``vis_ratio`` is 1.

Normal and tangent maps (§7): a per-pixel rotation of the tangent frame, the minimal rotation
taking ``Ng`` to the mapped normal (Rodrigues; equivalent to the paper's quaternion map), then a
rotation about it to the mapped tangent. The BRDF and its slice are built in the rotated frame
(with ``o' = ℜ o``); visibility stays in the vertex frame.

A material's layers (:mod:`warp_sg.surface_layers`, glTF): the final radiance is
``a(o)·(R + Le) + Rcoat`` with ``Le`` the emission, ``a(o) = 1 − c·F(n_c·o)`` and ``Rcoat`` the clear
coat's GGX lobe shaded like the specular term above (lights: its BRDF at l; environment: its slice
lobes' ΓL) in its own frame; an occlusion map multiplies the environment's diffuse term (the SG
mixture and the diffuse response to the environment's peaks, lights ``≥ Layers.n_local``); vertex
colours scale kd and ks. With alpha cut-outs a camera ray that meets a hole continues behind it
(``warp_sg.cutout.first_opaque_hit`` in a ``wp.Mesh`` of the geometry), the background where it
leaves the scene.

Kernel variants: the kernel is specialised by scene content (``Features``): environment diffuse
(SG mixture | none), environment specular (ΓL | none), lights, specular materials, shadows
(SSDF), textures, normal/tangent maps, the material layers (emission, occlusion, coat, vertex colours,
cut-outs), the fh method and the set of material models (the BRDF
functions, ``shading_slice_lobe`` and ``diffuse_at`` come from ``material_funcs`` of
``brdf.material_variants``, built for just those models). Variants are created once per feature
tuple and cached (``shade_kernel``); code a scene does not need is removed at compile time with
``wp.static``. The kernel is 1-D over row-major samples with an index offset ``base`` and ``per``
samples per thread (:data:`PIXELS_PER_THREAD` on the CPU, 1 on CUDA), so on the CPU disjoint
ranges run on a small thread pool (``raster.parallel.launch``; Warp runs one CPU launch on one
core).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations at definition
# time and the kernel variants are closures.
from dataclasses import dataclass

import warp as wp

from .background import Background, background_along, background_at
from .cutout import Cutouts, first_opaque_hit, is_hole
from .brdf.material_wp import ALL_MODELS, Material, above, material_funcs
from .fastmath import fast_asin
from .fh import fh_ratio_table_pair, fh_theta_max_wp
from .frames import local_to_world, world_to_local
from .lights import LightArrays, light_irradiance
from .sg import CLAMPED_COSINE_SHARPNESS
from .sg_irradiance import sg_irradiance_norm, sg_irradiance_norm_at, sg_irradiance_row, sg_power
from .sg_wp import sg_integral, sg_product_lobe
from .surface import (  # noqa: F401  (re-exported: slot constants, MaterialTextures)
    N_SLOTS, SLOT_COAT, SLOT_COAT_NORMAL, SLOT_EMISSION, SLOT_KD, SLOT_KS, SLOT_NORMAL, SLOT_OCCLUSION, SLOT_P0,
    SLOT_P1, SLOT_TANGENT, MaterialTextures, apply_shading_maps, tangent_in_plane, textured_material,
)
from .ssdf_product import sg_visibility_scale_sigmoid
from .surface_layers import Layers, coat_at, coat_attenuation, coat_frame, emission_at, occlusion_at, vertex_coloured


from precompute.occluder_cone import occluder_clearance  # noqa: E402
from precompute.ssdf_wp import SSDFPoint, ssdf_at, ssdf_point  # noqa: E402

ENV_NONE, ENV_SG, ENV_PREFILTERED = 0, 1, 2
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
    """PCA-compressed SSDFs (``precompute.SSDFData``) and the fh ratio table (``warp_sg.fh``)."""

    mean: wp.array2d(dtype=float)
    basis: wp.array3d(dtype=float)
    weights: wp.array2d(dtype=float)
    normals: wp.array(dtype=wp.vec3)  # the per-vertex normals (frames) the SSDFs were computed in
    fh_table: wp.array2d(dtype=float)
    cones: wp.array(dtype=wp.vec4)  # per-vertex occluder cones (precompute.occluder_cone)
    cone_band: float  # their texel margin h: the width of the skip's blend
    #: (V, lights) per-vertex SSDF deficit θd − θh towards each light (``warp_sg.vertex_visibility``),
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
    #: (V, count) visible fraction of C*(n_v) ⊗ G_j per vertex (``warp_sg.vertex_visibility``),
    #: read by the variant with ``Features.env_vis_vertex``; a (1, 1) placeholder otherwise
    vis: wp.array2d(dtype=float)
    #: (V,) the diffuse environment term per vertex without ρd at unit environment scale,
    #: Σ_j μ_j ∫G_j e(n_v·p_j, λ_j) V[v, j],
    #: and (T,) per triangle 1 where interpolating it is within tolerance of the per-pixel sum
    #: (``warp_sg.vertex_visibility.env_vertex_irradiance``), read by the variant with
    #: ``Features.env_irradiance_vertex``; length-1 placeholders otherwise
    irr_vertex: wp.array(dtype=wp.vec3)
    gouraud: wp.array(dtype=wp.uint8)
    irr_scale: float  # the environment scale (irr_vertex is built at unit scale)


# --------------------------------------------------------------------------------------------
# building blocks (@wp.func)
# --------------------------------------------------------------------------------------------
@wp.func
def lookup_skip(fh_mode: int, vis: Visibility, q: SSDFPoint, p: wp.vec3, th_h: float, lam: float) -> float:
    """How far the SSDF lookup of lobe (p, λ) at point ``q`` may be skipped, ``s ∈ [0, 1]``
    (``precompute.occluder_cone.occluder_clearance``; 1: its visibility is exactly 1). Only with the
    tabulated fh, whose flat tail beyond θmax(λ) makes the skip exact; 0 with the sigmoid."""
    if fh_mode != 0:
        return 0.0
    return occluder_clearance(vis.cones, q, p, th_h, fh_theta_max_wp(lam), vis.cone_band)


@wp.func
def vis_ratio(shadows: int, fh_mode: int, vis: Visibility, q: SSDFPoint, p: wp.vec3, lam: float) -> float:
    """The visible fraction of a lobe (p, λ) relative to the unoccluded point:
    ``fh(θd(p), λ) / fh(θh(p), λ)`` with θd the SSDF of the shading point at world direction p
    (eq. 24, 30; each vertex's SSDF read in that vertex's own frame where the frames disagree,
    ``precompute.ssdf_wp.ssdf_eval_world``: no seam where the frame turns) and ``θh = asin(p·Ng)``
    the SSDF of an unoccluded point (its horizon). The unshadowed response (exact BRDF and cosine,
    or the exact SG irradiance) already accounts for the horizon, so the SSDF supplies only what
    the occluders take away. ``q``: the shading point (``ssdf_point``, once per pixel). 1 without
    shadows. With the table ``fh``, a lobe that clears the occluder cones of the point's vertices
    by ``min(θh, θmax(λ))`` is fully visible (``precompute.occluder_cone``): no SSDF lookup."""
    if shadows == 0:
        return 1.0
    th_h = fast_asin(wp.dot(p, q.ng))
    s = lookup_skip(fh_mode, vis, q, p, th_h, lam)
    if s >= 1.0:
        return 1.0
    th = ssdf_at(vis.mean, vis.basis, vis.weights, q, p)
    r = fh_fraction(fh_mode, vis, th, th_h, lam)
    return r + (1.0 - r) * s


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
def env_diffuse_sum(irr: wp.array2d(dtype=float), env: EnvSG, use_vis: int, n: wp.vec3, i0: int, i1: int, i2: int,
                    b0: float, b1: float, b2: float) -> wp.vec3:
    """``Σ_j μ_j ∫G_j e(n·p_j, λ_j) Σ_k b_k V[i_k, j]``: the diffuse environment sum (eq. 39)
    without ρd at normal ``n`` (visibility interpolated from ``env.vis`` when ``use_vis``) — what
    the shading kernel adds per pixel with ρd = kd/π and the per-vertex visibility, and what
    ``warp_sg.vertex_visibility`` evaluates at the vertices and checks the interpolation against."""
    acc = wp.vec3(0.0, 0.0, 0.0)
    for j in range(env.count):
        vr = float(1.0)
        if use_vis != 0:
            vr = b0 * env.vis[i0, j] + b1 * env.vis[i1, j] + b2 * env.vis[i2, j]
        acc += env.power[j] * (sg_irradiance_norm_at(irr, wp.dot(n, env.axis[j]), env.lam[j], env.irr_row[j]) * vr)
    return acc


@wp.kernel(enable_backward=False)
def _lobe_constants_kernel(irr: wp.array2d(dtype=float), lam: wp.array(dtype=float), mu: wp.array(dtype=wp.vec3),
                           power: wp.array(dtype=wp.vec3), row: wp.array(dtype=float)):
    j = wp.tid()
    power[j] = sg_power(lam[j], mu[j])
    row[j] = sg_irradiance_row(irr, lam[j])


def lobe_constants(es: EnvSG, irr, device) -> EnvSG:
    """Fill ``es.power`` (μ ∫G(λ)) and ``es.irr_row`` (the lobe's irradiance-table row) once per
    environment change: ``sg_irradiance(irr, n, p, λ, μ) = power · sg_irradiance_norm_at(irr, n·p,
    λ, irr_row)`` for every pixel."""
    n = int(es.lam.shape[0])
    es.power = wp.zeros(n, dtype=wp.vec3, device=device)
    es.irr_row = wp.zeros(n, dtype=float, device=device)
    wp.launch(_lobe_constants_kernel, dim=n, inputs=[irr, es.lam, es.mu, es.power, es.irr_row], device=device)
    return es


# --------------------------------------------------------------------------------------------
# kernel variants
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Features:
    """What a scene needs; one compiled kernel per distinct value."""

    env_diffuse: int = ENV_NONE   # ENV_NONE | ENV_SG (the environment's SG mixture)
    env_specular: int = ENV_NONE  # ENV_NONE | ENV_PREFILTERED (the ΓL pyramid)
    lights: bool = False
    specular: bool = False
    shadows: bool = False
    textures: bool = False
    normal_maps: bool = False
    fh_sigmoid: bool = False
    #: environment-diffuse visibility interpolated from the per-vertex cache ``EnvSG.vis``
    #: (``warp_sg.vertex_visibility``) instead of one SSDF lookup per lobe per pixel
    env_vis_vertex: bool = False
    #: lights' SSDF deficit interpolated from the per-vertex cache ``Visibility.light_deficit``
    light_vis_vertex: bool = False
    #: the whole diffuse environment term interpolated from ``EnvSG.irr_vertex`` on the triangles
    #: where ``EnvSG.gouraud`` says that is within tolerance (needs ρd = kd/π and no normal maps)
    env_irradiance_vertex: bool = False
    #: sorted material model codes of the scene (``MaterialTable.models``); the material
    #: functions are specialised to them (``material_funcs``); default: every model
    models: tuple = tuple(sorted(ALL_MODELS))
    #: a material's layers (:mod:`warp_sg.surface_layers`), each compiled in only where a scene has it:
    #: emission, occlusion of the environment's diffuse term, a clear coat, vertex colours, and
    #: alpha cut-outs (camera rays continue through holes, :mod:`warp_sg.cutout`)
    emission: bool = False
    occlusion: bool = False
    coat: bool = False
    vertex_colors: bool = False
    cutouts: bool = False

    def __post_init__(self):
        object.__setattr__(self, "models", tuple(sorted({int(m) for m in self.models})))


_KERNELS: dict = {}

#: pixels one CPU thread shades (``raster.parallel.launch(per_thread=...)``): Warp copies the
#: kernel's struct arguments (geometry, materials, lights, environment, ΓL, SSDF: ~4 KB) at every
#: thread's entry, ~26 ns — more than a background pixel costs. 16 pixels share one entry
#: (measured on the frame-scaling scene: shading CPU time −23 %). CUDA shades one per thread.
PIXELS_PER_THREAD = 16


def diffuse_sum_per_vertex_ok(env_diffuse: int, models, normal_maps: bool) -> bool:
    """Whether the whole diffuse environment term can be taken from per-vertex values
    (``EnvSG.irr_vertex``): an SG environment, ρd = kd/π whatever the directions (no Oren–Nayar,
    model 1) and the interpolated normal as the shading normal (no normal maps). The renderer asks
    this before building the cache; the kernel variant before reading it."""
    return int(env_diffuse) == ENV_SG and 1 not in tuple(models) and not normal_maps


def _gamma_parts():
    """(struct type, @wp.func gamma_mean(struct, p, lam) -> vec3: ΓL/∫G) of the prefiltered ΓL pyramid."""
    from precompute import prefilter as P

    return P.GammaTable, P.gamma_mean


def shade_kernel(f: Features):
    """The shading kernel for feature set ``f`` (compiled once per process and cached)."""
    if f in _KERNELS:
        return _KERNELS[f]
    ENV_D = int(f.env_diffuse)
    ENV_S = int(f.env_specular)
    LIGHTS = bool(f.lights)
    SPEC = bool(f.specular)
    SHADOWS = 1 if f.shadows else 0
    TEX = bool(f.textures)
    NMAP = bool(f.normal_maps)
    FH = 1 if f.fh_sigmoid else 0
    VVIS = bool(f.env_vis_vertex) and SHADOWS == 1
    LVIS = bool(f.light_vis_vertex) and SHADOWS == 1
    RHO_D_CONST = 1 not in f.models  # no Oren–Nayar: ρd = kd/π, whatever the directions
    EVTX = bool(f.env_irradiance_vertex) and diffuse_sum_per_vertex_ok(f.env_diffuse, f.models, f.normal_maps)
    # per-pixel SSDF reads outside the specular loop (lights without the deficit cache, diffuse
    # lobes without the visibility cache): the SSDF point is built for every pixel
    Q_EARLY = SHADOWS == 1 and ((LIGHTS and not LVIS) or (ENV_D == 1 and not VVIS))
    MF = material_funcs(f.models)  # the material switch reduced to the scene's models
    brdf_eval, diffuse_at, slice_lobe_count = MF.brdf_eval, MF.diffuse_at, MF.slice_lobe_count
    shading_slice_lobe = MF.shading_slice_lobe
    USE_GAMMA = ENV_S == ENV_PREFILTERED
    EMIT, OCC, COAT, VCOL, CUT = (bool(f.emission), bool(f.occlusion), bool(f.coat), bool(f.vertex_colors),
                                  bool(f.cutouts))
    brdf_diffuse = MF.brdf_diffuse
    if USE_GAMMA:
        GammaT, gamma_mean = _gamma_parts()
    else:
        GammaT, gamma_mean = EnvSG, None  # placeholder type (unused argument)

    def shade(base: int, per: int, tri_id: wp.array2d(dtype=int), bary: wp.array2d(dtype=wp.vec2), background: wp.array2d(dtype=wp.vec3),
              rays: Background, use_rays: int, cam: wp.vec3, geo: GeometryArrays, mats: wp.array(dtype=Material), tex: MaterialTextures,
              irr: wp.array2d(dtype=float), lights: LightArrays, env: EnvSG, gamma: GammaT, vis: Visibility,
              lay: Layers, cut: Cutouts, mesh: wp.uint64, env_bg: Background, out: wp.array2d(dtype=wp.vec3)):
        W = tri_id.shape[1]
        p0 = base + wp.tid() * per  # the thread's first row-major pixel index
        ny = p0 // W  # (row, column) of the next pixel: one division per thread, then steps
        nx = p0 - ny * W
        for s in range(per):  # per pixels per thread on the CPU (raster.parallel.launch), 1 on CUDA
            if ny >= tri_id.shape[0]:
                break
            y = ny
            x = nx
            nx += 1
            if nx == W:
                nx = 0
                ny += 1
            t = tri_id[y, x]
            if t < 0:  # the environment along the (sub)pixel's ray, or what the caller gathered
                if use_rays != 0:
                    out[y, x] = background_at(rays, y, x)
                else:
                    out[y, x] = background[y, x]
                continue
            bc = bary[y, x]
            b1 = bc[0]
            b2 = bc[1]
            b0 = 1.0 - b1 - b2
            if wp.static(CUT):  # alpha cut-out: the camera ray goes on behind the hole
                if is_hole(cut, t, b0, b1, b2):
                    tr = geo.tris[t]
                    ph = geo.positions[tr[0]] * b0 + geo.positions[tr[1]] * b1 + geo.positions[tr[2]] * b2
                    dv = wp.normalize(ph - cam)
                    hit, sh, face, hu, hv, hn = first_opaque_hit(mesh, cut, ph + dv * cut.step, dv, 1.0e30)
                    if not hit:
                        out[y, x] = background_along(env_bg, dv)
                        continue
                    t = face
                    b0 = hu
                    b1 = hv
                    b2 = 1.0 - hu - hv
            tri = geo.tris[t]
            i0 = tri[0]
            i1 = tri[1]
            i2 = tri[2]
            P = geo.positions[i0] * b0 + geo.positions[i1] * b1 + geo.positions[i2] * b2
            ng = wp.normalize(geo.normals[i0] * b0 + geo.normals[i1] * b1 + geo.normals[i2] * b2)
            o = wp.normalize(cam - P)

            mi = geo.tri_material[t]
            mat = mats[mi]
            uv = wp.vec2(0.0, 0.0)
            if wp.static(TEX or NMAP or EMIT or OCC or COAT):
                uv = geo.uvs[i0] * b0 + geo.uvs[i1] * b1 + geo.uvs[i2] * b2
            if wp.static(TEX):
                mat = textured_material(mat, tex, mi, uv)
            if wp.static(VCOL):
                mat = vertex_coloured(mat, lay, i0, i1, i2, b0, b1, b2)

            # shading frame: mesh tangent made orthogonal to the normal, then normal/tangent maps
            tg = tangent_in_plane(geo.tangents[i0] * b0 + geo.tangents[i1] * b1 + geo.tangents[i2] * b2, ng)
            ts = tg
            ns = ng
            if wp.static(NMAP):
                ns, ts = apply_shading_maps(tex, mi, uv, ng, ts)
            bs = wp.cross(ns, ts)
            o_l = above(world_to_local(o, ts, bs, ns))
            # the clear coat: its lobe in its own frame, and what it lets through, a(o)
            has_coat = False
            cm = mat
            atten = float(1.0)
            ns_c = ng
            ts_c = tg
            bs_c = bs
            oc_l = o_l
            if wp.static(COAT):
                has_coat, cm = coat_at(mats, lay, tex, mi, uv)
                if has_coat:
                    ns_c, ts_c = coat_frame(tex, mi, uv, ng, tg)
                    bs_c = wp.cross(ns_c, ts_c)
                    oc_l = above(world_to_local(o, ts_c, bs_c, ns_c))
                    atten = coat_attenuation(cm.ks[0], oc_l[2])
            ccol = wp.vec3(0.0, 0.0, 0.0)
            occ = float(1.0)
            if wp.static(OCC):
                occ = occlusion_at(tex, mi, uv)
            # the point's SSDF frames, once for every light and lobe that reads the SSDF: at once when
            # lights or diffuse lobes read it per pixel, else only where a specular lobe does
            q = SSDFPoint()
            q.ng = ng
            if wp.static(Q_EARLY):
                q = ssdf_point(vis.normals, i0, i1, i2, b0, b1, b2, ng)

            col = wp.vec3(0.0, 0.0, 0.0)
            has_kd = wp.length_sq(mat.kd) > 0.0

            # ---------------- local lights (eq. 42–43, exact where it is cheap) ----------------
            # The unshadowed response to a point / spherical / directional light is the exact BRDF at
            # the light's direction times its irradiance, weighted by the exact cosine of the light's
            # SG over the hemisphere e(n·l, λ) (→ max(n·l, 0) for small lights; smooth at the horizon
            # for large ones). The SSDF supplies only the occluded fraction (vis_ratio).
            if wp.static(LIGHTS):
                for j in range(lights.count):
                    la, ll, E = light_irradiance(lights, j, P)
                    li = world_to_local(la, ts, bs, ns)
                    e = sg_irradiance_norm(irr, li[2], ll)
                    ec = float(0.0)
                    lc = li
                    if wp.static(COAT):
                        if has_coat:
                            lc = world_to_local(la, ts_c, bs_c, ns_c)
                            ec = sg_irradiance_norm(irr, lc[2], ll)
                    if e > 0.0 or ec > 0.0:
                        vr = float(1.0)
                        if wp.static(LVIS):  # θd = θh + the vertices' interpolated deficit (per-vertex cache)
                            dd = (b0 * vis.light_deficit[i0, j] + b1 * vis.light_deficit[i1, j]
                                  + b2 * vis.light_deficit[i2, j])
                            if dd < 0.0:
                                th_h = fast_asin(wp.dot(la, q.ng))
                                vr = fh_fraction(FH, vis, th_h + dd, th_h, ll)
                        else:
                            vr = vis_ratio(SHADOWS, FH, vis, q, la, ll)
                        if e > 0.0:
                            f = brdf_eval(mat, o_l, above(li))
                            if wp.static(OCC):  # the environment's peaks: occlusion on their diffuse part
                                if j >= lay.n_local:
                                    f = f - brdf_diffuse(mat, o_l, above(li)) * (1.0 - occ)
                            col += wp.cw_mul(f, E) * (e * vr)
                        if wp.static(COAT):
                            if ec > 0.0:
                                ccol += wp.cw_mul(brdf_eval(cm, oc_l, above(lc)), E) * (ec * vr)

            # ---------------- environment, diffuse (eq. 39) ----------------
            # Σ_j ρd μ_j ∫G_j e(n·p_j, λ_j): the exact irradiance of each SG of the environment's
            # mixture (sg_irradiance: within 2 % for every λ, where eq. 40's single clamped-cosine lobe
            # is 17 % low at 54°), times the visible fraction of the product lobe C* ⊗ G_j.
            cd = wp.vec3(0.0, 0.0, 0.0)  # the environment's diffuse term (times the occlusion)
            if wp.static(ENV_D == 1):
                if has_kd:
                    rho_d = diffuse_at(mat, o_l, wp.vec3(0.0, 0.0, 1.0))  # ρd itself where it is constant
                    nj = env.count
                    if wp.static(EVTX):  # the per-vertex sum, where the triangle's check allows it
                        if env.gouraud[t] != wp.uint8(0):
                            dsum = b0 * env.irr_vertex[i0] + b1 * env.irr_vertex[i1] + b2 * env.irr_vertex[i2]
                            cd += wp.cw_mul(dsum, rho_d) * env.irr_scale
                            nj = 0
                    if wp.static(VVIS and RHO_D_CONST):  # no product lobe needed: the cache × kd/π
                        if nj > 0:
                            cd += wp.cw_mul(env_diffuse_sum(irr, env, 1, ns, i0, i1, i2, b0, b1, b2), rho_d)
                    else:
                        for j in range(nj):
                            ax = env.axis[j]
                            E = env.power[j] * sg_irradiance_norm_at(irr, wp.dot(ns, ax), env.lam[j], env.irr_row[j])
                            if wp.length_sq(E) > 0.0:
                                vr = float(1.0)
                                pe, le = sg_product_lobe(ns, CC_LAM, ax, env.lam[j])
                                if wp.static(VVIS):  # the per-vertex cache, interpolated
                                    vr = b0 * env.vis[i0, j] + b1 * env.vis[i1, j] + b2 * env.vis[i2, j]
                                else:
                                    vr = vis_ratio(SHADOWS, FH, vis, q, pe, le)
                                cd += wp.cw_mul(E, diffuse_at(mat, o_l, world_to_local(pe, ts, bs, ns))) * vr
            col += cd * occ

            # ---------------- environment, specular (eq. 41) ----------------
            # For each slice lobe G_k (axis pW, λW, amplitude μ_k ∝ Mo): ∫ G_k(i) max(n·i, 0) L(i) di ≈
            # [μ_k ∫G_k e(n·pW, λW)] · L̄, the lobe's exact cosine-weighted mass times the mean radiance
            # L̄ = ΓL(p, λ)/∫G(λ) over the cosine-weighted lobe (p, λ) = C* ⊗ G_k (eq. 35). Exact for a
            # constant environment and for sharp lobes, and bounded at grazing views, where the
            # paper's C* ⊗ ρ*_k (0.14 of its peak at the horizon times Mo ∝ 1/(n·i)) grows as 1/(n·o).
            if wp.static(SPEC and ENV_S == 2):
                nspec = slice_lobe_count(mat)
                ncoat = int(0)
                if wp.static(COAT):
                    if has_coat:
                        ncoat = slice_lobe_count(cm)
                if wp.static(SHADOWS == 1 and not Q_EARLY):
                    if nspec > 0 or ncoat > 0:
                        q = ssdf_point(vis.normals, i0, i1, i2, b0, b1, b2, ng)
                for k in range(nspec):
                    pw_l, lw, mw = shading_slice_lobe(mat, o_l, k)
                    if wp.length_sq(mw) > 0.0:
                        e = sg_irradiance_norm(irr, pw_l[2], lw) * sg_integral(lw)
                        if e > 0.0:
                            pw = local_to_world(pw_l, ts, bs, ns)
                            pa, lam = sg_product_lobe(ns, CC_LAM, pw, lw)
                            g = gamma_mean(gamma, pa, lam)  # L̄ = ΓL(p, λ)/∫G(λ)
                            vr = vis_ratio(SHADOWS, FH, vis, q, pa, lam)
                            col += wp.cw_mul(mw, g) * (e * vr)
                if wp.static(COAT):
                    for k in range(ncoat):  # the coat's lobes, the same way in the coat's frame
                        pw_l, lw, mw = shading_slice_lobe(cm, oc_l, k)
                        if wp.length_sq(mw) > 0.0:
                            e = sg_irradiance_norm(irr, pw_l[2], lw) * sg_integral(lw)
                            if e > 0.0:
                                pw = local_to_world(pw_l, ts_c, bs_c, ns_c)
                                pa, lam = sg_product_lobe(ns_c, CC_LAM, pw, lw)
                                g = gamma_mean(gamma, pa, lam)
                                vr = vis_ratio(SHADOWS, FH, vis, q, pa, lam)
                                ccol += wp.cw_mul(mw, g) * (e * vr)
            if wp.static(EMIT):
                col += emission_at(lay, tex, mi, uv)
            if wp.static(COAT):
                col = col * atten + ccol
            out[y, x] = wp.vec3(wp.max(col[0], 0.0), wp.max(col[1], 0.0), wp.max(col[2], 0.0))

    key = "shade_" + "_".join(str(int(v)) for v in (ENV_D, ENV_S, LIGHTS, SPEC, SHADOWS, TEX, NMAP, FH, VVIS, LVIS,
                                                      EVTX, EMIT, OCC, COAT, VCOL, CUT)) + MF.tag
    shade.__name__ = key
    shade.__qualname__ = key
    k = wp.kernel(shade, enable_backward=False, module="unique")
    _KERNELS[f] = k
    return k


@wp.kernel(enable_backward=False)
def resolve_box(src: wp.array2d(dtype=wp.vec3), k: int, out: wp.array2d(dtype=wp.vec3)):
    """Box-filter k×k blocks of the supersampled image (supersampling resolve)."""
    y, x = wp.tid()
    acc = wp.vec3(0.0, 0.0, 0.0)
    for dy in range(k):
        for dx in range(k):
            acc += src[y * k + dy, x * k + dx]
    out[y, x] = acc / float(k * k)


__all__ = ["Features", "shade_kernel", "resolve_box", "GeometryArrays", "MaterialTextures", "Visibility", "EnvSG",
           "SLOT_KD", "SLOT_KS", "SLOT_P0", "SLOT_P1", "SLOT_NORMAL", "SLOT_TANGENT", "SLOT_EMISSION", "SLOT_OCCLUSION",
           "SLOT_COAT", "SLOT_COAT_NORMAL", "N_SLOTS",
           "ENV_NONE", "ENV_SG", "ENV_PREFILTERED"]
