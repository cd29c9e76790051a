"""The scene-file parameters a BRDF model declares: its ``PARAMS``, ``{name: Param}``.

A :class:`Param` says what kind of value the parameter takes (and its lower bound), what it means,
whether a texture may drive it (the kernel's texture slots, ``warp_sg.shading.surface``), and the
range of the viewer's slider for it. The scene-file model (:mod:`warp_sg.scene.schema`: the
``[materials.NAME]`` tables, ``docs/scene.schema.json``, ``docs/scene-keys.md``), the loader's
texture rule and the viewer's sliders read them, so a model's parameters are declared once, in its
class; the model's constructor checks the values it is given (a test keeps its bounds and the
declared ones equal).
"""
from __future__ import annotations

from dataclasses import dataclass

from .fresnel import PRESETS

#: the kinds of value: RGB or grey (>= 0), a number, an integer, a Fresnel preset or table, a file
#: path, a list of Lafortune lobe tables ``{cx, cy, cz, n}``
KINDS = ("rgb", "number", "integer", "fresnel", "file", "lafortune_lobes")


@dataclass(frozen=True)
class Param:
    """One parameter: ``kind`` (one of :data:`KINDS`) with the lower bound ``lo`` (exclusive when
    ``lo_open``; ``odd`` integers only), ``description``, ``texture`` (a texture may drive it),
    ``slider`` (the viewer's (low, high); None: no slider), ``instead_of`` (the parameter this
    one is given in place of, with the others that name it: ``alpha_x``/``alpha_y`` for ``alpha``)
    and, for a texturable number, ``kernel``: the kernel parameters (indices of the model's
    ``kernel_params()``, 0 or 1: the texture slots of ``warp_sg.shading.surface``) one texel value
    sets — ``(0,)``, ``(1,)``, or ``(0, 1)`` where it stands for two (``alpha`` sets αx and αy)."""

    kind: str
    description: str
    lo: float | None = None
    lo_open: bool = False
    odd: bool = False
    texture: bool = False
    slider: tuple[float, float] | None = None
    instead_of: str | None = None
    kernel: tuple = ()

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"Param kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.kind == "number" and self.texture and tuple(self.kernel) not in ((0,), (1,), (0, 1)):
            raise ValueError(f"a texturable number Param sets kernel parameters (0,), (1,) or (0, 1), "
                             f"got kernel={self.kernel!r}")


KD = Param("rgb", "diffuse albedo (number or RGB)", texture=True, slider=(0.0, 1.0))
KS = Param("rgb", "specular scale (number or RGB)", texture=True, slider=(0.0, 1.0))
FRESNEL = Param("fresnel", "Fresnel: a preset (" + ", ".join(PRESETS) + ") or {schlick}, {eta} or {eta, k}")
#: a roughness given instead of ``alpha`` along the tangent and the bitangent (Ward, GGX)
ALPHA_X = Param("number", "roughness along the tangent", lo=0, lo_open=True, texture=True, slider=(0.02, 0.8),
                instead_of="alpha", kernel=(0,))
ALPHA_Y = Param("number", "roughness along the bitangent", lo=0, lo_open=True, texture=True, slider=(0.02, 0.8),
                instead_of="alpha", kernel=(1,))


def check_params(cls) -> None:
    """``cls.PARAMS`` is a ``{name: Param}`` dict whose ``instead_of`` names one of its parameters
    (``ValueError`` naming the class otherwise)."""
    params = getattr(cls, "PARAMS", None)
    if not isinstance(params, dict) or not all(isinstance(k, str) and isinstance(p, Param) for k, p in params.items()):
        raise ValueError(f"{cls.__name__}: PARAMS must be a dict {{name: warp_sg.brdf.params.Param}}")
    for k, p in params.items():
        if p.instead_of is not None and p.instead_of not in params:
            raise ValueError(f"{cls.__name__}: PARAMS['{k}'] is instead of '{p.instead_of}', which it does not have")


__all__ = ["ALPHA_X", "ALPHA_Y", "FRESNEL", "KD", "KINDS", "KS", "Param", "check_params"]
