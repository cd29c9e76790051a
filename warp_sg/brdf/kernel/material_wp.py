r"""Kernel-side BRDF contract (docs/architecture.md "BRDF contract"): the ``Material`` struct,
``pack_materials`` and the ``@wp.func``s used by the renderer and the Monte-Carlo reference.

All functions work in the local frame (z+ = normal, x = tangent), float32, unit vectors, and
mirror the numpy models of :mod:`warp_sg.brdf` (same formulas, same stable forms; see each
model's docstring for its equation and source):

* ``brdf_eval(mat, o, i)``     exact ``kd/π + ks ρs`` (Oren–Nayar diffuse; measured: ``merl_eval``);
* ``brdf_diffuse(mat, o, i)``  the diffuse part;
* ``brdf_mo(mat, o, i)``       ``ks ∘ Mo(o, i)`` of the factorisation ``ρs = Mo · D(h)`` (eq. 9);
* ``brdf_ndf(mat, h)``         ``D(h)`` (Phong: the lobe of the mirrored direction);
* ``brdf_sample(mat, o, u)`` / ``brdf_pdf(mat, o, i)``: importance sampling of the *specular*
  part (the caller mixes in cosine sampling for the diffuse part). Phong: cosine-power lobe about
  the mirror direction; Blinn–Phong: ``cos θh = u^{1/(n+2)}``; Cook–Torrance, Torrance–Sparrow,
  Ward (iso/aniso): Beckmann slope sampling (Walter et al. 2007; Ward 1992) with
  ``p(h) = exp(−(sx²/αx² + sy²/αy²))/(π αx αy cos³θh)``; Ashikhmin–Shirley: their quadrant
  sampling with ``p(h) = √((nu+1)(nv+1))/(2π) (n·h)^{nu cos²φ + nv sin²φ}``; Lafortune: one lobe
  chosen uniformly, cosine power about ``C∘o``; GGX: visible normals (Heitz 2018) with
  ``p(i) = G1(o) D(h)/(4 (n·o))`` (cosine samples for ``n·o ≤ 0``); measured: the NDF SG mixture
  (``1 − cos θ = −log1p(−u (1 − e^{−2λ}))/λ``). ``p(i) = p(h)/(4 |o·h|)`` for half-vector models;
  diffuse-only models return cosine samples. ``brdf_pdf`` returns the density of exactly what
  ``brdf_sample`` draws (directions below the horizon included).
* ``slice_lobe_count(mat)``, ``slice_lobe(mat, o, k) -> (axis, sharpness, amplitude vec3)``:
  SG lobe k of ``ks ρs(o, ·)``: spherical warp (paper eq. 17–22) of NDF lobe k times
  ``ks ∘ Mo(o, pW)``; Phong: the lobe about the mirror direction, amplitude ``ks (n+2)/(2π) μ``;
  Lafortune: ``G(i; C∘o/‖C∘o‖, n, ks ‖C∘o‖^n)``. ``slice_lobe(mat, lobe_axis, lobe_sharpness,
  lobe_amplitude, o, k)`` does the same with explicitly passed lobe tables.
* ``ndf_lobe(mat, k)``: NDF lobe k (local frame). With ``mat.analytic == 1`` it is computed from
  ``mat.params`` (so textured roughness works per pixel): single lobe ``λ = 2/m²`` (Cook–Torrance,
  Torrance–Sparrow), ``2/α²`` (Ward), ``n`` (Phong, Blinn–Phong, isotropic Ashikhmin–Shirley),
  or the anisotropic construction of supplement eq. 14 with ``mat.lobe_count`` lobes (GGX too), or
  for isotropic GGX the fits at roughness nodes stored in the lobe table, interpolated at the
  texel's α (``ggx_table_lobe``); otherwise it is read from the lobe table (GGX: sharpness rescaled
  by the curvature ratio ``(1/α² − 1)/(1/ᾱ² − 1)`` of the texel's α to the fitted ᾱ = ``p[2:4]``).

The ``Material`` struct carries the (shared) lobe tables and measured-data arrays as array
fields, so every function takes just ``mat``. Ashikhmin–Shirley and anisotropic Ward lobe axes are
in the local tangent frame (x = tangent).

Each model's own ``@wp.func`` functions live in its file in :mod:`warp_sg.brdf.models` (its
``KERNEL``, :class:`warp_sg.brdf.registry.Kernel`); the model code of a material is its class's
``CODE`` (``warp_sg.brdf.MODELS[name].CODE``).

Files: this module is the public entry (``from warp_sg.brdf import material_wp as M``) and
re-exports every name of :mod:`~warp_sg.brdf.kernel.material_struct` (the struct and packing),
:mod:`~warp_sg.brdf.kernel.material_eval_wp` (model-independent building blocks),
:mod:`~warp_sg.brdf.kernel.material_variants` (the functions that switch on ``mat.model``, generated from
the registry: the generic all-model ones here, and ``material_funcs(models)`` for kernels
specialised to a set of models) and :mod:`~warp_sg.brdf.kernel.material_sample_wp` (importance sampling
building blocks) — the same objects, so kernels may use either.
"""
from ..registry import constant_diffuse  # noqa: F401
from .material_eval_wp import (  # noqa: F401
    COS_MIN,
    above,
    aniso_axis,
    as_exponent_log,
    cos_pow,
    expm1_neg_f,
    fresnel_eval,
    from_axis,
    g_over_cos,
    ggx_extent,
    ggx_g1,
    ggx_g2_over_cos,
    ggx_lambda_cos,
    ggx_ndf_peak1,
    ggx_table_lobe,
    half_vec,
    lafortune_lobe,
    log1p_f,
    log_cos_theta,
    lum,
    oren_nayar_params,
    reflect_z,
    sin2_theta,
    warp_axis,
)
from .material_sample_wp import (  # noqa: F401
    as_h,
    as_pdf_h,
    beckmann_h,
    beckmann_pdf_h,
    cos_power_dir,
    cos_power_pdf,
    cosine_dir,
    cosine_pdf,
    cosine_sample,
    ggx_pdf_i,
    ggx_vndf_h,
    reflect_about,
    sg_lobe_weight,
    sg_mixture_pdf,
    sg_sample_dir,
)
from .material_struct import (  # noqa: F401
    FRESNEL_CONDUCTOR,
    FRESNEL_DIELECTRIC,
    FRESNEL_NONE,
    FRESNEL_SCHLICK,
    INV_PI,
    LN_EPS,
    PI,
    TWO_PI,
    WARP_COS_EPS,
    Material,
    MaterialTable,
    material_lobes,
    pack_materials,
)
from .material_variants import (  # noqa: F401
    ALL_MODELS,
    _aniso_lobe,
    all_models,
    brdf_diffuse,
    brdf_eval,
    brdf_mo,
    brdf_ndf,
    brdf_pdf,
    brdf_sample,
    brdf_specular,
    diffuse_at,
    material_funcs,
    mo_raw,
    ndf_lobe,
    shading_slice_lobe,
    slice_lobe,
    slice_lobe_count,
    texel_param0,
    variant_tag,
    warp_lobe,
)
from .measured_wp import fresnel_dielectric, measured_mo, merl_eval  # noqa: F401
