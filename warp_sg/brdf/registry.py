r"""The one registry of BRDF models: scene-file name → model class, and model code → class.

A model is one class (a :class:`~warp_sg.brdf.base.BRDF` subclass in a module of
:mod:`warp_sg.brdf.models`) that declares

* ``NAME`` — its scene-file name (``model = "ward"``), ``CODE`` — its kernel code (the
  ``Material.model`` field; a small distinct integer, ``0 ≤ CODE < MAX_CODES``) and ``PARAMS`` —
  its scene-file parameters, ``{name: Param}`` (:mod:`warp_sg.brdf.params`: kind, bound, meaning,
  texture, slider; what the scene-file model and the viewer read);
* its numpy evaluation (``diffuse``, ``mo``, ``ndf``, ``specular``) and its fit hooks
  (``ndf_analytic_lambda``, ``aniso_layout``, ``table_lobes``, ... see
  :mod:`warp_sg.brdf.fitting.fit`);
* ``KERNEL`` — a :class:`Kernel` of its ``@wp.func``\ s: what the kernel switch
  (:mod:`warp_sg.brdf.kernel.material_variants`) calls for a material of this code;
* its capabilities (:class:`~warp_sg.brdf.base.BRDF`): ``is_specular`` (a specular lobe),
  ``ROUGHNESS`` (the name of the lobe-width parameter a texture may set: the albedo table's second
  axis) and ``ENERGY_NORMALISED`` (the energy check), and per texturable number of ``PARAMS`` the
  kernel parameters a texel sets (``Param.kernel``: the texture slots) — what the renderer, the
  albedo table, the texture slots and the energy check ask (:func:`specular_codes`,
  :func:`has_specular`, :func:`textured_lobe_codes`, :func:`roughness_kernel`,
  :func:`energy_normalised`), so no module outside this one compares model codes;

and is registered by :func:`register` (a class decorator). Everything that switches on the model
— the kernel functions ``brdf_eval``, ``brdf_sample``, ``brdf_pdf``, ``slice_lobe`` ..., the
specialised kernel variants, the textured-parameter rule, the material packing and the NDF fits
— is generated from, or asks, this registry; so adding a model is adding its file to
``warp_sg/brdf/models/`` (imported with the package) and a test.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

from .params import check_params

#: model codes are bits of the kernel's model masks (``material_variants``): at most this many
MAX_CODES = 31

#: scene-file name -> model class, in code order
MODELS: dict[str, type] = {}
#: kernel code -> model class
BY_CODE: dict[int, type] = {}


@dataclass(frozen=True)
class Kernel:
    r"""The ``@wp.func``\ s of one model (all optional; local frame, z+ = normal, float32).

    The kernel switch calls a hook for a material of the model's code, else its default:

    * ``ndf(mat, h) -> float`` — ``D(h)`` of ``ρs = Mo · D`` (peak 1), for ``h_z > 0``
      (default 0: no specular lobe);
    * ``mo(mat, o, i) -> vec3`` — ``Mo(o, i)`` without ``ks``, for ``o_z, i_z > 0`` (default 0);
    * ``specular(mat, o, i) -> vec3`` — ``ρs`` without ``ks`` when it is not ``Mo · D(h)``
      (default ``mo(o, i) · ndf(h)``), for ``o_z, i_z > 0``;
    * ``diffuse(mat, o, i) -> vec3`` — the diffuse part, for ``o_z, i_z > 0`` (default ``kd/π``);
    * ``eval(mat, o, i) -> vec3`` — the whole BRDF when it is not ``diffuse + ks ∘ specular``;
    * ``analytic_lobe(mat, k) -> (axis, λ, μ)`` — NDF lobe k from the parameters
      (``mat.analytic == 1``; default: the lobe table);
    * ``table_lobe(mat, k) -> (axis, λ, μ)`` — NDF lobe k from the lobe table (default: as stored);
    * ``slice(mat, o, k) -> (axis, λ, amplitude vec3)`` — lobe k of the slice ``ks ρs(o, ·)``
      when it is not a warped NDF lobe (default: ``slice_of_lobe`` of ``ndf_lobe``);
    * ``slice_of_lobe(mat, o, axis, λ, μ) -> (axis, λ, amplitude vec3)`` — the slice lobe of an
      NDF lobe (default: the spherical warp, paper eq. 17–22);
    * ``sample(mat, o, u) -> vec3`` / ``pdf(mat, o, i) -> float`` — importance sampling of the
      specular part and its solid-angle density (``u`` in [0, 1)²; diffuse-only models default to
      cosine sampling); or ``pdf_h(mat, h) -> float``: the half-vector density, turned into
      ``p(i) = p(h)/(4 |o·h|)``;
    * ``texel_param0(mat, p, v) -> vec4`` — the parameters with the first one set from a texel
      value ``v`` (default ``(max(v, 1e-4), p1, p2, p3)``).
    """

    ndf: Any = None
    mo: Any = None
    specular: Any = None
    diffuse: Any = None
    eval: Any = None
    analytic_lobe: Any = None
    table_lobe: Any = None
    slice: Any = None
    slice_of_lobe: Any = None
    sample: Any = None
    pdf: Any = None
    pdf_h: Any = None
    texel_param0: Any = None

    def hooks(self) -> tuple[str, ...]:
        """The names of the hooks this model defines."""
        return tuple(f.name for f in fields(self) if getattr(self, f.name) is not None)


def register(cls):
    """Class decorator: add the model ``cls`` to :data:`MODELS` and :data:`BY_CODE` (its ``NAME``,
    ``CODE``, ``PARAMS`` and ``KERNEL`` are checked; a name or code taken by another class is refused)."""
    name, code = getattr(cls, "NAME", None), getattr(cls, "CODE", None)
    if not isinstance(name, str) or not name or name == "base":
        raise ValueError(f"{cls.__name__}: a registered model needs a NAME")
    if isinstance(code, bool) or not isinstance(code, int) or not 0 <= code < MAX_CODES:
        raise ValueError(f"{cls.__name__}: CODE must be an integer in [0, {MAX_CODES}), got {code!r}")
    if not isinstance(getattr(cls, "KERNEL", None), Kernel):
        raise ValueError(f"{cls.__name__}: KERNEL must be a warp_sg.brdf.registry.Kernel")
    check_params(cls)
    _check_capabilities(cls)
    for other in (MODELS.get(name), BY_CODE.get(code)):
        if other is not None and other is not cls:
            raise ValueError(f"{cls.__name__}: model name '{name}' or code {code} is taken by {other.__name__}")
    MODELS[name] = cls
    BY_CODE[code] = cls
    order = sorted(MODELS.values(), key=lambda c: c.CODE)
    MODELS.clear()
    MODELS.update((c.NAME, c) for c in order)
    return cls


def _check_capabilities(cls) -> None:
    """``is_specular`` and ``ENERGY_NORMALISED`` are booleans; a model's ``ROUGHNESS`` names a
    texturable number of its ``PARAMS`` that sets kernel parameter 0 (the albedo table reads the
    width there), on a specular model."""
    for flag in ("is_specular", "ENERGY_NORMALISED"):
        if not isinstance(getattr(cls, flag, False), bool):
            raise ValueError(f"{cls.__name__}: {flag} must be True or False")
    r = getattr(cls, "ROUGHNESS", None)
    if r is None:
        return
    p = cls.PARAMS.get(r) if isinstance(r, str) else None
    if p is None or p.kind != "number" or not p.texture or p.kernel[:1] != (0,):
        raise ValueError(f"{cls.__name__}: ROUGHNESS must name a texturable number of PARAMS that sets kernel "
                         f"parameter 0, got {r!r}")
    if not getattr(cls, "is_specular", False):
        raise ValueError(f"{cls.__name__}: ROUGHNESS needs a specular lobe (is_specular)")


def unregister(cls) -> None:
    """Remove a registered model (tests that register a model of their own)."""
    if MODELS.get(cls.NAME) is cls:
        del MODELS[cls.NAME]
    if BY_CODE.get(cls.CODE) is cls:
        del BY_CODE[cls.CODE]


def codes() -> frozenset:
    """Every registered model code."""
    return frozenset(BY_CODE)


def model_of(code: int):
    """The model class of kernel code ``code`` (``KeyError`` if none)."""
    return BY_CODE[int(code)]


def code_of(name: str) -> int:
    """The kernel code of the model called ``name``."""
    return MODELS[name].CODE


def constant_diffuse(model_codes) -> bool:
    """True when every model of ``model_codes`` has the diffuse part ``kd/π`` (no ``diffuse`` hook),
    so ρd does not depend on the directions (the shading's per-vertex diffuse shortcuts)."""
    return all(BY_CODE[int(c)].KERNEL.diffuse is None for c in model_codes)


def analytic_codes() -> frozenset:
    """The codes of the models with in-kernel analytic NDF lobes (``Kernel.analytic_lobe``)."""
    return frozenset(c for c, cls in BY_CODE.items() if cls.KERNEL.analytic_lobe is not None)


def specular_codes() -> frozenset:
    """The codes of the models with a specular lobe (the class's ``is_specular``)."""
    return frozenset(c for c, cls in BY_CODE.items() if getattr(cls, "is_specular", False))


def has_specular(model_codes) -> bool:
    """True when a model of ``model_codes`` has a specular lobe (the kernel variant's specular paths)."""
    return any(int(c) in specular_codes() for c in model_codes)


def roughness_kernel(code: int) -> tuple:
    """The kernel parameters a texel of the lobe width (``ROUGHNESS``) of the model of ``code`` sets:
    ``(0,)``, ``(0, 1)`` (its ``Param.kernel``), or ``()`` for a model without one."""
    cls = BY_CODE[int(code)]
    r = getattr(cls, "ROUGHNESS", None)
    return tuple(cls.PARAMS[r].kernel) if r is not None else ()


def texture_kernel(model_name: str, param: str) -> tuple | None:
    """The kernel parameters a texel of ``param`` of the model called ``model_name`` sets (its
    ``Param.kernel``), or None when a texture may not drive it (colours: ``()``; an unknown model: None)."""
    cls = MODELS.get(model_name)
    p = None if cls is None else cls.PARAMS.get(param)
    return None if p is None or not p.texture else tuple(p.kernel)


def textured_lobe_codes() -> frozenset:
    """The codes of the models whose lobe width may come from a texture (``ROUGHNESS``): its value
    sets ``kernel_params()[0]`` per texel (and ``[1]`` where its ``Param.kernel`` says so), the
    albedo table's second axis (:mod:`warp_sg.brdf.kernel.albedo`)."""
    return frozenset(c for c in BY_CODE if roughness_kernel(c))


def energy_normalised(model) -> bool:
    """True when the model (class or instance) declares its specular lobe normalised
    (``ENERGY_NORMALISED``: :mod:`warp_sg.brdf.energy` checks ``kd + ks·F(0°) <= 1``)."""
    return bool(getattr(model, "ENERGY_NORMALISED", False))


__all__ = ["BY_CODE", "Kernel", "MAX_CODES", "MODELS", "analytic_codes", "code_of", "codes", "constant_diffuse",
           "energy_normalised", "has_specular", "model_of", "register", "roughness_kernel", "specular_codes",
           "texture_kernel", "textured_lobe_codes", "unregister"]
