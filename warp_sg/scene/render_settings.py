"""The ``[render]`` table, once: :class:`RenderSettings` (the record the renderer and the Monte-Carlo
reference read, with the defaults) and :func:`render_table`, its pydantic model — every key's rule
(:data:`RENDER_INT_RANGES`, :data:`RENDER_CHOICES`, else the type of its default) and meaning
(:data:`RENDER_DOC`). The model is the one check of the table: the TOML loader validates
``[render]`` with it (as part of :class:`warp_sg.scene.schema.SceneFile`), a scene built in Python
with :meth:`RenderSettings.validate` (``Scene`` and ``Renderer`` call it), and ``warp-sg schema``
(``docs/scene.schema.json``) shows its rules and meanings, so all three say the same.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from functools import cache

#: the integer keys and their ranges [lo, hi]
RENDER_INT_RANGES = {"supersampling": (1, 16), "antialias": (1, 8), "lobes": (1, 16), "env_lobes": (1, 64),
                     "env_peaks": (0, 16), "visibility_budget": (0, 10_000_000),
                     "moving_visibility_budget": (0, 10_000_000), "pca_terms": (1, 256), "bounces": (0, 64),
                     "ssdf_resolution": (4, 1024), "gamma_levels": (0, 64), "gamma_resolution": (4, 1024)}
#: the string keys with a fixed set of choices
RENDER_CHOICES = {"fh": ("table", "sigmoid"), "visibility_sampling": ("vertex", "pixel")}


def uses_sigmoid(fh: str) -> bool:
    """The one reading of the ``fh`` choice (``[render] fh``, :data:`RENDER_CHOICES`): True when the
    kernels use the paper's sigmoid (``warp_sg.sg.fh.fh_ratio_sigmoid``), False for the exact table."""
    if fh not in RENDER_CHOICES["fh"]:
        raise ValueError(f"fh must be one of {', '.join(RENDER_CHOICES['fh'])}, got {fh!r}")
    return fh == "sigmoid"


#: what every key means
RENDER_DOC = {
    "shadows": "SSDF soft shadows, eq. 23–31 (off: visibility 1, no SSDF precompute)",
    "supersampling": "k: raster and shade at k·H × k·W, box-resolved",
    "antialias": "a: coverage at a×a sub-pixels, shading edge-adaptive: interior pixels once, edge pixels once "
                 "per triangle they see, weighted by coverage, contrasting pixels at every sub-pixel "
                 "(1 = off; used when supersampling = 1)",
    "lobes": "SG lobes of the NDF of isotropic models (anisotropic Ashikhmin-Shirley uses its own 'lobes')",
    "env_lobes": "SG lobes of the environment for the diffuse term (eq. 39; < 10 in the paper)",
    "env_peaks": "at most this many sharp environment peaks (a sun) separated from the map and shaded as "
                 "directional lights (precompute.environment.peaks; 0 = off)",
    "visibility_budget": "with shadows: refine the mesh where visibility changes, up to this many vertices "
                         "(precompute.refine_for_visibility); a mesh with more casts its SSDF rays at this many "
                         "representative vertices (precompute.visibility.representatives); 0 = the mesh as "
                         "given, every vertex its own SSDF",
    "moving_visibility_budget": "with shadows and objects that move: the refinement adds at most this many "
                                "vertices to each dynamic object (within visibility_budget; the uniform "
                                "pre-split aside): each moving vertex costs every frame it moves, so 0, the "
                                "default, keeps a dynamic object's own vertices",
    "pca_terms": "SSDF PCA terms (NV)",
    "ssdf_resolution": "SSDF map resolution",
    "gamma_levels": "λ levels of the ΓL pyramid (0 = default ladder: λ0 = 0.5 growing by √2 up to the map's "
                    "resolution)",
    "gamma_resolution": "largest cube face of the ΓL pyramid",
    "fh": "Fh: 'table' (exact, tabulated) or 'sigmoid' (paper appendix)",
    "visibility_sampling": "SSDF of the directions that do not depend on the view (environment lobes, lights) "
                           "and the diffuse environment sum: 'vertex' (once per vertex, cached, interpolated; "
                           "warp_sg.shading.vertex_visibility) or 'pixel' (one SSDF lookup per lobe and light per pixel)",
    "bounces": "light that bounces between surfaces (warp_sg.shading.bounce): at most this many bounces of "
               "interreflected light from the per-vertex gather, fewer once one adds under 1 %; 0 = the paper's "
               "direct light only. Needs shadows",
    "background": "pixels that see no object show the environment",
    "device": "default device: 'cpu', 'cuda', 'cuda:N' or 'auto'",
}


@dataclass
class RenderSettings:
    """The ``[render]`` table: quality knobs of the SG renderer (rules and meanings:
    :func:`render_table`; ``warp-sg schema``)."""

    shadows: bool = True
    supersampling: int = 1
    antialias: int = 4
    lobes: int = 1
    env_lobes: int = 8
    env_peaks: int = 8
    visibility_budget: int = 20000
    moving_visibility_budget: int = 0
    pca_terms: int = 32
    ssdf_resolution: int = 32
    gamma_levels: int = 0
    gamma_resolution: int = 128
    fh: str = "table"
    visibility_sampling: str = "vertex"
    bounces: int = 4
    background: bool = True
    device: str = "cpu"

    def validate(self, where: str = "[render]") -> None:
        """Check every key with :func:`render_table`: a :class:`SceneError` ``<where> key 'k' ...``
        in the words of the TOML loader for the first key it rejects."""
        from warp_sg.scene.values import check_record

        check_record(render_table(), asdict(self), where)


@cache
def render_table():
    """The pydantic model of ``[render]`` (``RenderTable``): one field per :class:`RenderSettings`
    field, with its default, its rule and its meaning. Built on first use (pydantic loads with it)."""
    from pydantic import create_model

    from warp_sg.scene.values import Table, boolean, choice, integer, number, string

    def rule(k, default):
        doc = RENDER_DOC.get(k, k)
        if k in RENDER_INT_RANGES:
            return integer(*RENDER_INT_RANGES[k], description=doc)
        if k in RENDER_CHOICES:
            return choice(RENDER_CHOICES[k], doc)
        if isinstance(default, bool):
            return boolean(doc)
        if isinstance(default, int):
            return integer(description=doc)
        if isinstance(default, float):
            return number(description=doc)
        return string(doc)

    return create_model("RenderTable", __base__=Table, __doc__="Quality settings of the SG renderer.",
                        **{f.name: (rule(f.name, f.default), f.default) for f in fields(RenderSettings)})


__all__ = ["RenderSettings", "render_table", "uses_sigmoid", "RENDER_INT_RANGES", "RENDER_CHOICES", "RENDER_DOC"]
