r"""What a material carries beside its BRDF: emission, ambient occlusion, alpha cut-outs and a clear
coat (glTF 2.0 §3.9 and KHR_materials_clearcoat / KHR_materials_emissive_strength; issue 27).

A :class:`MaterialLayers` record hangs off a scene :class:`~warp_sg.scene.Material` (``layers``);
the renderer (:mod:`warp_sg.shading.kernel`, :mod:`warp_sg.shading.surface_layers`) and the Monte-Carlo reference
(:mod:`warp_sg.groundtruth.reference_wp`) read the same record, so both shade the same surface::

    L(o) = a(o) · [Lbase(o) + Le] + Lcoat(o)
    a(o) = 1 − c · F(n_c·o),   F(x) = 0.04 + 0.96 (1 − x)⁵     (Schlick, coat index 1.5)

* ``emission`` Le (linear RGB radiance, glTF ``emissiveFactor × KHR_materials_emissive_strength``)
  times ``emission_map`` (RGB, linear): radiance the surface sends towards the viewer. It lights
  nothing else (as in glTF viewers; the renderer's light transport is direct lighting).
* ``occlusion_map`` (first channel, strength already applied: ``1 + s·(occ − 1)``): multiplies the
  **environment's diffuse term** only, as glTF viewers apply ambient occlusion — the SG mixture's
  diffuse term and the diffuse response to the environment's sharp peaks (its sun), not the
  specular terms and not local (point, directional) lights.
* ``alpha_cutoff`` (None: opaque): the surface is a hole where ``alpha · alpha_map · vertex alpha
  < alpha_cutoff`` (glTF ``alphaMode = "MASK"``): camera rays, shadow rays and the SSDF precompute's
  rays pass through (:mod:`warp_sg.shading.cutout`).
* ``clearcoat`` c (× ``clearcoat_map`` R) and ``clearcoat_alpha`` α_c (``clearcoat_map`` G, when
  given): a second, colourless GGX lobe ``c · ρ_GGX(α_c, F0 = 0.04)`` in the coat's frame (the
  interpolated normal, or ``clearcoat_normal_map``), and the attenuation ``a(o)`` of everything
  under it — the view-dependent form glTF viewers use (three.js, Filament) in place of the
  specification's ``1 − c F(v·h)`` inside the integral.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_sg.scene.textures import Texture

#: F0 of the coat (index of refraction 1.5, KHR_materials_clearcoat)
COAT_F0 = 0.04


@dataclass
class MaterialLayers:
    """Emission, occlusion, alpha cut-out and clear coat of a material (module docstring)."""

    emission: tuple = (0.0, 0.0, 0.0)
    emission_map: Texture | None = None
    occlusion_map: Texture | None = None
    alpha_cutoff: float | None = None
    alpha: float = 1.0
    alpha_map: Texture | None = None
    clearcoat: float = 0.0
    clearcoat_alpha: float = 0.01
    clearcoat_map: Texture | None = None
    clearcoat_normal_map: Texture | None = None

    @property
    def emissive(self) -> bool:
        return bool(np.any(np.asarray(self.emission, np.float64) > 0))

    @property
    def cut_out(self) -> bool:
        return self.alpha_cutoff is not None

    @property
    def coated(self) -> bool:
        return self.clearcoat > 0 or self.clearcoat_map is not None

    def coat_model(self):
        """The coat lobe as a ``ggx`` model: ``ks = c``, ``α = α_c``, Schlick F0 = 0.04, no diffuse."""
        from warp_sg.brdf import make_model

        return make_model("ggx", kd=[0.0, 0.0, 0.0], ks=[float(self.clearcoat)] * 3, alpha=float(self.clearcoat_alpha),
                          fresnel={"schlick": COAT_F0})

    def maps(self) -> dict:
        """{slot name: Texture} of the maps that are set."""
        names = ("emission_map", "occlusion_map", "alpha_map", "clearcoat_map", "clearcoat_normal_map")
        return {n: getattr(self, n) for n in names if getattr(self, n) is not None}


__all__ = ["MaterialLayers", "COAT_F0"]
