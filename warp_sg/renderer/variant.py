r"""Which shading-kernel variant a frame runs: the :class:`~warp_sg.shading.kernel.Features` of the
scene's content and the renderer's switches (a mixin of :class:`~warp_sg.renderer.renderer.Renderer`).

The kernel is specialised per feature set (:func:`warp_sg.shading.kernel.shade_kernel`): the
environment's diffuse and specular modes, local lights, specular materials, SSDF shadows (shown:
``Renderer.show_shadows``), textures and normal maps, the ``fh`` form, the per-vertex visibility
paths (``[render] visibility_sampling = "vertex"``), the material models, the material layers
(emission, occlusion, clear coat, vertex colours, cut-outs), an environment given as its SG mixture
(``Renderer.set_environment_mixture``), the adjoint (``Renderer(requires_grad=True)``) and light
that bounces (:mod:`warp_sg.renderer.interreflection`; not in the adjoint's frames).
"""
from __future__ import annotations

from dataclasses import replace

from warp_sg.scene.render_settings import uses_sigmoid
from warp_sg.shading import kernel as S


class VariantChoice:
    """The kernel variant of a ``Renderer``'s current state (:meth:`features`)."""

    def _vertex_sampled(self) -> bool:
        """Visibility of fixed directions sampled per vertex (``[render] visibility_sampling =
        "vertex"``) with shadows shown."""
        return self.scene.render.visibility_sampling == "vertex" and self.shadows and self.show_shadows

    def _env_visible_vertex(self) -> bool:
        """The diffuse environment term as the exact irradiance times the per-vertex visible fraction
        (``visibility_sampling = "vertex"`` with shadows shown; needs ρd = kd/π, no Oren–Nayar)."""
        return self.features().env_visible_vertex  # (gated by shading.Features)

    def final_features(self) -> S.Features:
        """The variant of the frames once the shadows are installed: :meth:`features` as it will be
        when a pending shadow precompute (``progressive``, or beside the environment setup) is done."""
        if self.shadows or getattr(self, "_job", None) is None:
            return self.features()
        self.shadows = True
        try:
            f = self.features()
        finally:
            self.shadows = False
        bounce = (self.scene.render.bounces > 0 and self.show_shadows and getattr(self, "show_bounces", True)
                  and not self.requires_grad)  # (the job's gather rows: light that bounces)
        return f if f.bounce == bounce else replace(f, bounce=bounce)

    def features(self) -> S.Features:
        return S.Features(
            env_diffuse=self.env_diffuse_mode,
            env_specular=(S.ENV_MIXTURE if self.env_mixture else self.env_specular_mode) if self.has_specular else S.ENV_NONE,
            lights=len(self.shading_lights) > 0,
            specular=self.has_specular,
            shadows=self.shadows and self.show_shadows,
            textures=self.has_textures,
            normal_maps=self.has_normal_maps,
            fh_sigmoid=uses_sigmoid(self.scene.render.fh),
            env_vis_vertex=self._vertex_sampled() and self.env_diffuse_mode == S.ENV_SG,
            light_vis_vertex=self._vertex_sampled() and len(self.shading_lights) > 0,
            env_visible_vertex=self._vertex_sampled(),
            models=self.material_table.models,
            emission=self.has_emission, occlusion=self.has_occlusion, coat=self.has_coat,
            vertex_colors=self.geometry.colors is not None, cutouts=self.cutouts is not None,
            moving=self.dynamic is not None and self.shadows and self.show_shadows,
            env_mixture=self.env_mixture and self.env_diffuse_mode == S.ENV_SG, grad=self.requires_grad,
            bounce=self._bounces_on() and not self.requires_grad,
        )


__all__ = ["VariantChoice"]
