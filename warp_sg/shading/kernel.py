r"""Per-pixel deferred shading over the visibility buffer (paper §7, eq. 36–43).

One kernel launch shades every sample of a visibility buffer once (deferred shading: the cost never depends on
overdraw). Per sample, with ``x`` the surface point, ``o`` the view direction, ``Ng`` the interpolated vertex normal
(the frame of the precomputed visibility), ``(Ts, Bs, Ns)`` the shading frame (tangent frame rotated by the
normal/tangent maps), ``e(c, λ)`` the exact normalised irradiance of an SG (``warp_sg.sg.irradiance``) and
``vis_ratio(p, λ) = fh(θd(p), λ)/fh(θh(p), λ)`` the SSDF's visible fraction of a lobe over an unoccluded point's::

    R(o) = Rlights + Rd + Rs                                                        (eq. 36)

Local lights (point, spherical, directional; environment peaks such as a sun), eq. 42–43 made exact where it is cheap —
one BRDF evaluation at the light's direction l::

    Rlights += ρ(o, l) E e(n·l, λ_l) g_α(θd(l))/g_α(θh(l))

with ``g_α`` the visible fraction of the light's uniform disc (angular radius α) cut by the SSDF's boundary ``θd`` from
its centre (``visibility_terms.light_cap_visible``; the paper's SG ``fh`` ratio with ``fh = "sigmoid"``). With
``Features.light_vis_vertex`` the SSDF towards the light is ``θd = θh + Σ_k b_k D[i_k, j]``, the per-vertex deficit
cache of ``warp_sg.shading.vertex_visibility``, and no lookup is made.

Environment, diffuse — eq. 39, with the magnitude exact: ``E(n)`` is the irradiance of the map
(``precompute.environment.irradiance``, a cube-map table of its cosine-weighted integral) and only the visible fraction
is approximated::

    Rd += ρd E(Ns) Σ_k b_k F[i_k]                                 (Features.env_visible_vertex)

(on triangles whose vertex normals agree within 5°, and without normal maps, the vertices' own ``E ∘ F`` interpolated:
no table lookup, within ≈ 0.1 %.)

``F`` the per-vertex visible fraction by quadrature of the vertex's SSDF weighted by the map
(``warp_sg.shading.vertex_visibility``; the default with ``visibility_sampling = "vertex"`` and ρd = kd/π). Otherwise
(per-pixel visibility, or Oren–Nayar's directional ρd) the mixture's lobes give it::

    Rd += ρd(o, p_G) μ_j ∫G_j e(Ns·p_j, λ_j) vis_ratio(p_G, λ_G) + ρd (E − Σ_j a_j) v̄,   G = C* ⊗ L*_j

(``a_j`` the lobes' unshadowed irradiance, ``v̄`` their mean visible fraction; with ``Features.env_vis_vertex`` the
lobes' visibility is the per-vertex cache ``Σ_k b_k V[i_k, j]``.) Without shadows it is ``ρd E(Ns)``, one table lookup.

Environment, specular — eq. 41, for each slice lobe G_k of ks ρs(o, ·) (spherical warp of the NDF lobes, eq. 17–22,
``shading_slice_lobe``)::

    Rs += c(o) Σ_k μ_k ∫G_k e(Ns·p_k, λ_k) · ΓL(p, λ)/∫G(λ) (eq. 35) · vis_ratio(p, λ),   (p, λ) = C* ⊗ G_k

``c(o) = A(o)/A*(o)`` is the material's tabulated ratio of the exact BRDF's directional albedo to the slice lobes'
(``warp_sg.brdf.kernel.albedo``): the warp's energy error, up to ±20 %, removed.

The clamped-cosine SG ``C*`` (eq. 40) only places and sizes the product lobe whose visibility and mean radiance stand
for the cosine-weighted lobe; the cosine itself is exact. The diffuse BRDF ``ρd(o, i)`` (kd/π, or Oren-Nayar) is
evaluated at the product lobe's axis. ``θd(p)`` is the SSDF of the surface point (eq. 24, per-vertex PCA weights,
``precompute.visibility.ssdf_wp.ssdf_eval_world``); with shadows off (or a scene that cannot shadow itself)
``vis_ratio`` is 1.

Normal and tangent maps (§7): a per-pixel rotation of the tangent frame, the minimal rotation taking ``Ng`` to the
mapped normal (Rodrigues; equivalent to the paper's quaternion map), then a rotation about it to the mapped tangent. The
BRDF and its slice are built in the rotated frame (with ``o' = ℜ o``); visibility stays in the vertex frame.

An environment given as its SG mixture (``Features.env_mixture``: ``Renderer.set_environment_mixture``, what inverse
rendering recovers) is shaded by its lobes alone: the diffuse lobe sum above without the exact table's rest, and ``L̄``
in eq. 41 the lobes' closed form (:mod:`warp_sg.shading.env_mixture`).

Layers (:mod:`warp_sg.shading.surface_layers`): ``a(o)·(R + Le) + Rcoat``, the coat's GGX lobe shaded like the
specular terms in its frame; occlusion on the environment's diffuse term; cut-outs' holes seen through.
Moving objects (``Features.moving``, :mod:`warp_sg.shading.motion_wp`): each visibility is capped by the proxies' own.
Light that bounces (``Features.bounce``, :mod:`warp_sg.shading.bounce`): the vertices' indirect light, diffuse and per slice lobe.

Kernel variants: the kernel is specialised by scene content (``Features``): environment diffuse (SG mixture | none),
environment specular (ΓL | none), lights, specular materials, shadows (SSDF), textures, normal/tangent maps, the
material layers (emission, occlusion, coat, vertex colours, cut-outs), the fh method and the set of material models (the
BRDF functions, ``shading_slice_lobe`` and ``diffuse_at`` come from ``material_funcs`` of
``brdf.kernel.material_variants``, built for just those models). Variants are created once per feature tuple and cached
(``shade_kernel``); code a scene does not need is removed at compile time with ``wp.static``. The kernel is 1-D over
row-major samples with an index offset ``base`` and ``per`` samples per thread (:data:`PIXELS_PER_THREAD` on the CPU, 1
on CUDA), so on the CPU disjoint ranges run on a small thread pool (``raster.parallel.launch``; Warp runs one CPU launch
on one core). ``Features.grad``: the same kernel with its adjoint and one pixel per thread
(:mod:`warp_sg.shading.kernel_grad`); its loops over lights and lobes are functions that return their sums, for every
variant.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations at definition
# time and the kernel variants are closures.
from dataclasses import dataclass

import warp as wp

from precompute.environment.irradiance import env_irradiance
from precompute.visibility.ssdf_wp import SSDFPoint, ssdf_point_framed
from warp_sg.brdf.kernel.albedo import albedo_correction
from warp_sg.brdf.kernel.material_wp import ALL_MODELS, Material, above, constant_diffuse, material_funcs
from warp_sg.numeric.fastmath import fast_asin
from warp_sg.numeric.onb import local_to_world, world_to_local
from warp_sg.scene.lights import LightArrays, light_irradiance
from warp_sg.sg.algebra_wp import sg_integral, sg_product_lobe
from warp_sg.sg.irradiance import sg_irradiance_norm, sg_irradiance_norm_at
from warp_sg.shading.background import Background, background_along, background_at
from warp_sg.shading.bounce import Indirect, indirect_irradiance, indirect_specular_func, lobe_mean_radiance
from warp_sg.shading.cutout import Cutouts, see_behind
from warp_sg.shading.env_mixture import mixture_mean
from warp_sg.shading.motion_wp import Proxies, moving_lobe, proxy_diffuse, proxy_light_ratio, proxy_ratio
from warp_sg.shading.surface import MaterialTextures, apply_shading_maps, tangent_in_plane, textured_material
from warp_sg.shading.surface_layers import Layers, coat_setup, emission_at, occlusion_at, vertex_coloured
from warp_sg.shading.visibility_terms import (
    CC_LAM,
    EnvSG,
    GeometryArrays,
    Visibility,
    light_fraction,
    light_vis_ratio,
    vis_ratio,
    vis_ratio_depth,
    visible_irradiance,
    visible_lobe,
)

ENV_NONE, ENV_SG, ENV_PREFILTERED, ENV_MIXTURE = 0, 1, 2, 3


# --------------------------------------------------------------------------------------------
# kernel variants
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Features:
    """What a scene needs; one compiled kernel per distinct value."""

    env_diffuse: int = ENV_NONE   # ENV_NONE | ENV_SG (the environment's SG mixture)
    #: ENV_NONE | ENV_PREFILTERED (the ΓL pyramid) | ENV_MIXTURE (the SG mixture's lobes, ``env_mixture``)
    env_specular: int = ENV_NONE
    lights: bool = False
    specular: bool = False
    shadows: bool = False
    textures: bool = False
    normal_maps: bool = False
    fh_sigmoid: bool = False
    #: environment-diffuse visibility interpolated from the per-vertex cache ``EnvSG.vis``
    #: (``warp_sg.shading.vertex_visibility``) instead of one SSDF lookup per lobe per pixel
    env_vis_vertex: bool = False
    #: lights' SSDF deficit interpolated from the per-vertex cache ``Visibility.light_deficit``
    light_vis_vertex: bool = False
    #: the diffuse environment term as the exact irradiance times the visible fraction interpolated
    #: from ``EnvSG.visible`` (per-vertex quadrature of the SSDF; needs ρd = kd/π)
    env_visible_vertex: bool = False
    #: sorted material model codes of the scene (``MaterialTable.models``); the material
    #: functions are specialised to them (``material_funcs``); default: every model
    models: tuple = tuple(sorted(ALL_MODELS))
    #: a material's layers (:mod:`warp_sg.shading.surface_layers`, :mod:`warp_sg.shading.cutout`), each compiled in
    #: only where a scene has it
    emission: bool = False
    occlusion: bool = False
    coat: bool = False
    vertex_colors: bool = False
    cutouts: bool = False
    moving: bool = False  # dynamic objects: their occluder proxies per pixel (warp_sg.shading.motion_wp)
    #: the environment *is* its SG mixture (``Renderer.set_environment_mixture``): diffuse from the
    #: lobes alone (no exact-irradiance table), specular from the lobes (``env_specular = ENV_MIXTURE``)
    env_mixture: bool = False
    #: the kernel is compiled with its adjoint (``Renderer(requires_grad=True)``, :mod:`warp_sg.renderer.gradients`)
    grad: bool = False
    bounce: bool = False  # light that bounces (warp_sg.shading.bounce); not with grad (the direct light's)

    def __post_init__(self):
        object.__setattr__(self, "models", tuple(sorted({int(m) for m in self.models})))
        if self.env_mixture:  # (the per-vertex visible fraction weighs the map, which the mixture replaces)
            object.__setattr__(self, "env_visible_vertex", False)
        # the per-vertex visibility gating, decided once here (the renderer's caches and the kernel read it)
        evis = bool(self.env_visible_vertex and self.shadows) and env_visible_vertex_ok(self.env_diffuse, self.models)
        object.__setattr__(self, "env_visible_vertex", evis)
        object.__setattr__(self, "env_vis_vertex", bool(self.env_vis_vertex and self.shadows) and not evis)
        object.__setattr__(self, "light_vis_vertex", bool(self.light_vis_vertex and self.shadows))


_KERNELS: dict = {}

#: pixels one CPU thread shades (``raster.parallel.launch(per_thread=...)``): Warp copies the
#: kernel's struct arguments (geometry, materials, lights, environment, ΓL, SSDF: ~4 KB) at every
#: thread's entry, ~26 ns — more than a background pixel costs. 16 pixels share one entry
#: (measured on the frame-scaling scene: shading CPU time −23 %). CUDA shades one per thread.
PIXELS_PER_THREAD = 16


def env_visible_vertex_ok(env_diffuse: int, models) -> bool:
    """Whether the diffuse environment term can be the exact irradiance times the per-vertex visible
    fraction (``EnvSG.visible``): an SG environment and ρd = kd/π (``brdf.registry.constant_diffuse``)."""
    return int(env_diffuse) == ENV_SG and constant_diffuse(models)


def _gamma_parts():
    """(struct type, @wp.func gamma_mean(struct, p, lam) -> vec3: ΓL/∫G) of the prefiltered ΓL pyramid."""
    from precompute.environment import prefilter_wp as P

    return P.GammaTable, P.gamma_mean


def shade_kernel_ready(f: Features, device) -> bool:
    """Whether the kernel of feature set ``f`` is built and its module loaded on ``device``."""
    from raster.parallel import is_loaded

    return f in _KERNELS and is_loaded(_KERNELS[f], device)


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
    VVIS, LVIS, EVIS = bool(f.env_vis_vertex), bool(f.light_vis_vertex), bool(f.env_visible_vertex)  # Features gates
    RHO_D_CONST = constant_diffuse(f.models)  # no Oren–Nayar: ρd = kd/π, whatever the directions
    # per-pixel SSDF reads outside the specular loop (lights without the deficit cache, diffuse
    # lobes without the visibility cache): the SSDF point is built for every pixel
    Q_EARLY = SHADOWS == 1 and ((LIGHTS and not LVIS) or (ENV_D == 1 and not VVIS and not EVIS))
    MF = material_funcs(f.models)  # the material switch reduced to the scene's models
    brdf_eval, diffuse_at, slice_lobe_count = MF.brdf_eval, MF.diffuse_at, MF.slice_lobe_count
    shading_slice_lobe = MF.shading_slice_lobe
    indirect_specular = indirect_specular_func(MF)  # (the slice lobes' indirect light without ΓL's loop)
    USE_GAMMA = ENV_S == ENV_PREFILTERED
    MIX = bool(f.env_mixture)
    BOUNCE = bool(f.bounce and not f.grad)  # (the gradient variant differentiates the direct light)
    EMIT, OCC, COAT, VCOL, CUT, MOVING = (bool(f.emission), bool(f.occlusion), bool(f.coat),
                                          bool(f.vertex_colors), bool(f.cutouts), bool(f.moving))
    brdf_diffuse = MF.brdf_diffuse
    if USE_GAMMA:
        GammaT, gamma_mean = _gamma_parts()
    else:  # the mixture's own lobes (ENV_MIXTURE: the EnvSG passed again), or a placeholder
        GammaT, gamma_mean = EnvSG, mixture_mean
    key = "shade_" + "_".join(str(int(v)) for v in (ENV_D, ENV_S, LIGHTS, SPEC, SHADOWS, TEX, NMAP, FH, VVIS, LVIS,
                                                      EVIS, EMIT, OCC, COAT, VCOL, CUT, MOVING, MIX, f.grad, BOUNCE)) + MF.tag

    # Each loop over lights or lobes is a function that returns its sums: Warp's reverse pass
    # replays a function's forward body whole but not a dynamic loop's, so a value summed in a loop
    # is only used after the loop by the caller (the gradient variant, warp_sg.shading.kernel_grad).
    @wp.func(name=key + "_lights")
    def lights_sum(lights: LightArrays, irr: wp.array2d(dtype=float), vis: Visibility, px: Proxies, lay: Layers,
                   mat: Material, cm: Material, has_coat: bool, o_l: wp.vec3, oc_l: wp.vec3, P: wp.vec3, ng: wp.vec3,
                   ts: wp.vec3, bs: wp.vec3, ns: wp.vec3, ts_c: wp.vec3, bs_c: wp.vec3, ns_c: wp.vec3, q: SSDFPoint,
                   t: int, i0: int, i1: int, i2: int, b0: float, b1: float, b2: float, occ: float):
        """(the lights' colour, the coat's): exact BRDF × irradiance × the light's SG cosine e(n·l, λ);
        the SSDF (and the moving objects' proxies) supply only the occluded fraction."""
        col = wp.vec3(0.0, 0.0, 0.0)
        ccol = wp.vec3(0.0, 0.0, 0.0)
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
                        vr = light_fraction(FH, vis, th_h + dd, th_h, ll)
                else:
                    vr = light_vis_ratio(SHADOWS, FH, vis, q, la, ll)
                if wp.static(MOVING): vr = wp.min(vr, proxy_light_ratio(FH, vis, px, t, P, ng, la, ll))  # noqa: E701
                if e > 0.0:
                    f = brdf_eval(mat, o_l, above(li))
                    if wp.static(OCC):  # the environment's peaks: occlusion on their diffuse part
                        if j >= lay.n_local:
                            f = f - brdf_diffuse(mat, o_l, above(li)) * (1.0 - occ)
                    col += wp.cw_mul(f, E) * (e * vr)
                if wp.static(COAT):
                    if ec > 0.0:
                        ccol += wp.cw_mul(brdf_eval(cm, oc_l, above(lc)), E) * (ec * vr)
        return col, ccol

    @wp.func(name=key + "_env_lobes")
    def env_lobes_sum(env: EnvSG, irr: wp.array2d(dtype=float), vis: Visibility, px: Proxies, mat: Material,
                      o_l: wp.vec3, P: wp.vec3, ng: wp.vec3, ts: wp.vec3, bs: wp.vec3, ns: wp.vec3, q: SSDFPoint,
                      t: int, i0: int, i1: int, i2: int, b0: float, b1: float, b2: float):
        """(Σ_j a_j ρd(p_G) V_j, Σ_j a_j, Σ_j a_j V_j) over the mixture's lobes (eq. 39)."""
        cd = wp.vec3(0.0, 0.0, 0.0)
        unocc = wp.vec3(0.0, 0.0, 0.0)
        seen = wp.vec3(0.0, 0.0, 0.0)
        for j in range(env.count):
            ax = env.axis[j]
            E = env.power[j] * sg_irradiance_norm_at(irr, wp.dot(ns, ax), env.lam[j], env.irr_row[j])
            if wp.length_sq(E) > 0.0:
                vr = float(1.0)
                pe, le = sg_product_lobe(ns, CC_LAM, ax, env.lam[j])
                if wp.static(VVIS):  # the per-vertex cache, interpolated
                    vr = b0 * env.vis[i0, j] + b1 * env.vis[i1, j] + b2 * env.vis[i2, j]
                else:
                    vr = vis_ratio(SHADOWS, FH, vis, q, pe, le)
                if wp.static(MOVING): vr = wp.min(vr, proxy_ratio(FH, vis.fh_table, px, t, P, ng, pe, le))  # noqa: E701
                unocc += E
                seen += E * vr
                cd += wp.cw_mul(E, diffuse_at(mat, o_l, world_to_local(pe, ts, bs, ns))) * vr
        return cd, unocc, seen

    @wp.func(name=key + "_specular")
    def specular_sum(mat: Material, o_l: wp.vec3, ts: wp.vec3, bs: wp.vec3, ns: wp.vec3, n: int,
                     irr: wp.array2d(dtype=float), vis: Visibility, q: SSDFPoint, px: Proxies, gamma: GammaT,
                     t: int, P: wp.vec3, ng: wp.vec3, ind: Indirect, iv: wp.vec3i, bw: wp.vec3,
                     bounce: int) -> wp.vec3:
        """Σ_k [μ_k ∫G_k e(n·pW, λW)] · L̄ · V over the first ``n`` slice lobes of the material in the
        frame (ts, bs, ns) (eq. 41; the module docstring), with ``bounce`` + the indirect light where the SSDF cuts."""
        spec = wp.vec3(0.0, 0.0, 0.0)
        for k in range(n):
            pw_l, lw, mw = shading_slice_lobe(mat, o_l, k)
            if wp.length_sq(mw) > 0.0:
                e = sg_irradiance_norm(irr, pw_l[2], lw) * sg_integral(lw)
                if e > 0.0:
                    pa, lam = sg_product_lobe(ns, CC_LAM, local_to_world(pw_l, ts, bs, ns), lw)
                    vd = vis_ratio_depth(SHADOWS, FH, vis, q, pa, lam)
                    pv = pa
                    lv = lam
                    vr = vd[0]
                    if wp.static(MOVING):  # the maps' and the proxies' cut, the smaller
                        vr, pv, lv = moving_lobe(FH, vis, q, px, t, P, ng, pa, lam, vd)
                    else:
                        if vd[0] < 1.0:  # the mean radiance of the lobe's visible part
                            pv, lv = visible_lobe(vis, q, pa, lam, vd[1])
                    spec += wp.cw_mul(mw, gamma_mean(gamma, pv, lv)) * (e * vr)  # L̄ = ΓL(p, λ)/∫G(λ)
                    if wp.static(BOUNCE):  # the indirect light where the SSDF cuts the lobe (shading.bounce)
                        if bounce != 0 and vr < 1.0: spec += wp.cw_mul(mw, lobe_mean_radiance(ind, iv[0], iv[1], iv[2], bw[0], bw[1], bw[2], ns, pa, lam)) * e  # noqa: E701,E501
        return spec

    def shade(base: int, per: int, tri_id: wp.array2d(dtype=int), bary: wp.array2d(dtype=wp.vec2), background: wp.array2d(dtype=wp.vec3),
              rays: Background, use_rays: int, cam: wp.vec3, geo: GeometryArrays, mats: wp.array(dtype=Material), tex: MaterialTextures,
              irr: wp.array2d(dtype=float), lights: LightArrays, env: EnvSG, gamma: GammaT, vis: Visibility, px: Proxies,
              lay: Layers, cut: Cutouts, mesh: wp.uint64, env_bg: Background, ind: Indirect, out: wp.array2d(dtype=wp.vec3)):
        W = tri_id.shape[1]
        p0 = base + wp.tid() * per  # the thread's first row-major pixel index
        ny = p0 // W  # (row, column) of the next pixel: one division per thread, then steps
        nx = p0 - ny * W
        for s in range(per):  # noqa: B007  per pixels per thread on the CPU (raster.parallel.launch), 1 on CUDA
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
                hit, t, b0, b1, b2, dv = see_behind(mesh, cut, geo.positions, cam, t, b0, b1, b2)
                if not hit:
                    out[y, x] = background_along(env_bg, dv)
                    continue
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
            ns_c, ts_c, bs_c, oc_l = ng, tg, bs, o_l
            if wp.static(COAT):
                has_coat, cm, ns_c, ts_c, bs_c, oc_l, atten = coat_setup(mats, lay, tex, mi, uv, o, ng, tg)
            ccol = wp.vec3(0.0, 0.0, 0.0)
            occ = float(1.0)
            if wp.static(OCC):
                occ = occlusion_at(tex, mi, uv)
            # the point's SSDF frames, once for every light and lobe that reads the SSDF: at once when
            # lights or diffuse lobes read it per pixel, else only where a specular lobe does
            q = SSDFPoint()
            q.ng = ng
            if wp.static(Q_EARLY):
                q = ssdf_point_framed(vis.normals, vis.frame_t, vis.frame_b, i0, i1, i2, b0, b1, b2, ng)

            col = wp.vec3(0.0, 0.0, 0.0)
            has_kd = wp.length_sq(mat.kd) > 0.0

            # ---------------- local lights (eq. 42–43, exact where it is cheap) ----------------
            # exact BRDF × irradiance × the light's SG cosine e(n·l, λ); the SSDF (and the moving
            # objects' proxies) supply only the occluded fraction (vis_ratio, proxy_ratio)
            if wp.static(LIGHTS):
                lc, lcc = lights_sum(lights, irr, vis, px, lay, mat, cm, has_coat, o_l, oc_l, P, ng, ts, bs, ns,
                                     ts_c, bs_c, ns_c, q, t, i0, i1, i2, b0, b1, b2, occ)
                col += lc
                ccol += lcc

            # ---------------- environment, diffuse (eq. 39) ----------------
            # ρd E(n) times its visible fraction: per vertex by quadrature of the SSDF (EVIS, the
            # default), else from the mixture's lobes and the part of E(n) they miss (module docstring)
            cd = wp.vec3(0.0, 0.0, 0.0)  # the environment's diffuse term (times the occlusion)
            if wp.static(ENV_D == 1 and SHADOWS == 0 and RHO_D_CONST and not MIX):
                if has_kd:  # nothing occludes: ρd E(n), no lobe
                    cd += wp.cw_mul(env_irradiance(env.exact, ns), diffuse_at(mat, o_l, wp.vec3(0.0, 0.0, 1.0)))
            if wp.static(ENV_D == 1 and EVIS):
                if has_kd:  # ρd E(n) F, F the vertices' visible fractions interpolated
                    rho_d = diffuse_at(mat, o_l, wp.vec3(0.0, 0.0, 1.0))
                    if not wp.static(NMAP) and env.smooth[t] != wp.uint8(0):  # E ∘ F of the vertices
                        dv = b0 * env.irr_vertex[i0] + b1 * env.irr_vertex[i1] + b2 * env.irr_vertex[i2]
                        cd += wp.cw_mul(dv, rho_d) * env.irr_scale
                    else:
                        fv = b0 * env.visible[i0] + b1 * env.visible[i1] + b2 * env.visible[i2]
                        cd += wp.cw_mul(wp.cw_mul(env_irradiance(env.exact, ns), fv), rho_d)
                    if wp.static(MOVING): cd = wp.cw_mul(cd, proxy_diffuse(px, t, P, ns, env.radiance, env.exact))  # noqa: E701
            if wp.static(ENV_D == 1 and (MIX or not (SHADOWS == 0 and RHO_D_CONST)) and not EVIS):
                if has_kd:
                    rho_d = diffuse_at(mat, o_l, wp.vec3(0.0, 0.0, 1.0))  # ρd at the normal
                    # Σ_j a_j ρd(p_G) V_j, and the exact irradiance's part the lobes miss (E − Σ_j a_j)
                    # with ρd at the normal and the lobes' mean visible fraction (visible_irradiance)
                    cl, unocc, seen = env_lobes_sum(env, irr, vis, px, mat, o_l, P, ng, ts, bs, ns, q, t,
                                                    i0, i1, i2, b0, b1, b2)
                    cd += cl
                    if wp.static(not MIX):  # (the mixture alone: no part missed)
                        rest = visible_irradiance(env_irradiance(env.exact, ns), unocc, seen) - seen
                        cd += wp.cw_mul(rest, rho_d)
            col += cd * occ
            if wp.static(BOUNCE):  # light that bounces: the vertices' indirect irradiance (shading.bounce)
                if has_kd: col += wp.cw_mul(indirect_irradiance(ind, i0, i1, i2, b0, b1, b2), diffuse_at(mat, o_l, wp.vec3(0.0, 0.0, 1.0)))  # noqa: E701
                if wp.static(SPEC and ENV_S < 2):  # (with the environment's loop: read there)
                    col += indirect_specular(mat, o_l, ts, bs, ns, irr, ind, wp.vec3i(i0, i1, i2), wp.vec3(b0, b1, b2))

            # ---------------- environment, specular (eq. 41) ----------------
            # per slice lobe G_k: [μ_k ∫G_k e(n·pW, λW)] · L̄, the lobe's exact cosine-weighted mass times
            # the mean radiance L̄ = ΓL(p, λ)/∫G(λ) over (p, λ) = C* ⊗ G_k (eq. 35; module docstring)
            if wp.static(SPEC and ENV_S >= 2):
                nspec = slice_lobe_count(mat)
                ncoat = int(0)
                if wp.static(COAT):
                    if has_coat:
                        ncoat = slice_lobe_count(cm)
                if wp.static(SHADOWS == 1 and not Q_EARLY):
                    if nspec > 0 or ncoat > 0:
                        q = ssdf_point_framed(vis.normals, vis.frame_t, vis.frame_b, i0, i1, i2, b0, b1, b2, ng)
                iv, bw = wp.vec3i(i0, i1, i2), wp.vec3(b0, b1, b2)
                spec = specular_sum(mat, o_l, ts, bs, ns, nspec, irr, vis, q, px, gamma, t, P, ng, ind, iv, bw, 1)
                if nspec > 0:  # the slice's energy made the BRDF's: A(o)/A*(o) (brdf.kernel.albedo)
                    col += wp.cw_mul(spec, albedo_correction(mat, o_l))
                if wp.static(COAT):  # the coat's lobes, the same way in the coat's frame
                    cspec = specular_sum(cm, oc_l, ts_c, bs_c, ns_c, ncoat, irr, vis, q, px, gamma, t, P, ng, ind, iv, bw, 0)
                    ccol += wp.cw_mul(cspec, albedo_correction(cm, oc_l))  # (zero without a coat)
            if wp.static(EMIT):
                col += emission_at(lay, tex, mi, uv)
            if wp.static(COAT):
                col = col * atten + ccol
            out[y, x] = wp.vec3(wp.max(col[0], 0.0), wp.max(col[1], 0.0), wp.max(col[2], 0.0))

    shade.__name__ = key
    shade.__qualname__ = key
    if f.grad:  # one pixel per thread, with its adjoint (warp_sg.shading.kernel_grad)
        from warp_sg.shading.kernel_grad import grad_kernel

        k = grad_kernel(shade, key)
    else:
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


__all__ = ["Features", "shade_kernel", "shade_kernel_ready", "resolve_box", "GeometryArrays", "MaterialTextures", "Visibility",
           "EnvSG", "ENV_NONE", "ENV_SG", "ENV_PREFILTERED", "ENV_MIXTURE"]
